"""Thread limits for numpy's thin products (one home for every package)."""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["one_blas_thread"]


@contextmanager
def one_blas_thread():
    """Numpy's BLAS products on one thread for the duration (threadpoolctl restores the count).

    Meant for work made of many thin or small products (inner dimensions of a few to a few
    dozen, 3 x 3 normal equations, dot products over a window): BLAS threads gain nothing
    there, and on a busy machine each product waits for a descheduled helper thread.
    Measured under load: the fit's level products took 10 to 30 times longer with two
    threads than with one, the uncertainty's per-defect models about 5 times longer.
    SciPy's FFT workers are not BLAS threads and are left as they are.

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     float(np.ones(3) @ np.ones(3))
    3.0
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
