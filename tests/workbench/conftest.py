"""Fixtures shared by the workbench tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def cluster():
    """One local Dask cluster of two worker processes, shared through its tcp:// address.

    A task whose worker dies is not retried on another (allowed_failures=0), so that the
    worker-death test costs one worker restart.
    """
    from distributed import LocalCluster

    local = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        scheduler_kwargs={"allowed_failures": 0},
    )
    yield local.scheduler_address
    local.close()
