"""Thread limits for numpy's thin products (one home for every package)."""

from __future__ import annotations

import sys
from contextlib import contextmanager

__all__ = ["one_blas_thread"]

#: threadpoolctl's view of the loaded thread pools and the number of imported modules when it was taken
_CONTROLLER: list = [None, -1]


def _controller():
    """A :class:`threadpoolctl.ThreadpoolController`, taken again whenever modules were imported since.

    Finding the loaded BLAS libraries walks the process's shared objects (~0.1 ms); limiting through a
    kept controller costs ~10 us. New imports may load new libraries (SciPy's own OpenBLAS), so a
    change in the number of imported modules takes a fresh view.
    """
    if _CONTROLLER[0] is None or _CONTROLLER[1] != len(sys.modules):
        from threadpoolctl import ThreadpoolController

        _CONTROLLER[0] = ThreadpoolController()
        _CONTROLLER[1] = len(sys.modules)
    return _CONTROLLER[0]


@contextmanager
def one_blas_thread():
    """Numpy's BLAS products on one thread for the duration (threadpoolctl restores the count).

    Meant for work made of many thin or small products (inner dimensions of a few to a few
    dozen, 3 x 3 normal equations, dot products over a window, a CT body's 16-point Bezier
    products): BLAS threads gain nothing there, and on a busy machine each product waits for a
    descheduled helper thread. Measured under load: the fit's level products took 10 to 30 times
    longer with two threads than with one, the uncertainty's per-defect models about 5 times
    longer, a CT structure's surface (Tumor Bed Block) 1.6 times. SciPy's FFT workers are not
    BLAS threads and are left as they are.

    Examples
    --------
    >>> import numpy as np
    >>> with one_blas_thread():
    ...     float(np.ones(3) @ np.ones(3))
    3.0
    """
    with _controller().limit(limits=1, user_api="blas"):
        yield
