"""Shared test fixtures.

Real public data lives in ``../shared/data`` beside the repository (CI has it;
a user's clone does not). Tests that need it take the ``shared_data`` fixture,
which skips them with a clear reason when the folder is absent.

Every test runs in a fresh temporary working directory, so that a command's
default output folder (``photometric_out``, ``slices_out``, ``demo_out``, ...)
or a file an example writes never lands in the repository.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("WORKBENCH_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ``../shared/data``; skips the test when it is not there."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent (it lies beside the repository in CI)")
    return SHARED_DATA


@pytest.fixture(scope="session", autouse=True)
def _session_working_directory(tmp_path_factory):
    """Session- and module-scoped fixtures run before the per-test directory below exists (and the
    Dask workers of the ``cluster`` fixture keep the directory they start in): they run here, so that
    nothing a test run starts writes a default output folder into the repository."""
    before = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("session_cwd"))
    yield
    os.chdir(before)


@pytest.fixture(autouse=True)
def _fresh_working_directory(tmp_path_factory, monkeypatch) -> None:
    """Run the test in its own empty working directory (not the test's ``tmp_path``, which stays empty)."""
    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))
