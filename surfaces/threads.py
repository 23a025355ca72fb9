"""Thread limits for numpy's thin products (one home for every package)."""

from __future__ import annotations

import importlib.machinery
import sys
from contextlib import contextmanager

__all__ = ["one_blas_thread", "prepare"]

#: threadpoolctl's view of the loaded thread pools and the number of imported modules when it was taken
_CONTROLLER: list = [None, -1]
#: File endings of compiled modules on this interpreter
_EXTENSION_SUFFIXES = tuple(importlib.machinery.EXTENSION_SUFFIXES)


def _new_extension(since: int) -> bool:
    """Whether a module imported after the first ``since`` ones (in import order) is compiled.

    Only compiled modules (``.so``) load shared libraries such as a BLAS: pure Python imports
    (a DICOM reader, say) leave the loaded thread pools as they were.
    """
    modules = list(sys.modules.values())
    if len(modules) < since:  # modules were removed: the order says nothing any more
        return True
    return any(str(getattr(m, "__file__", None) or "").endswith(_EXTENSION_SUFFIXES) for m in modules[since:])



def _controller():
    """A :class:`threadpoolctl.ThreadpoolController`, taken again whenever a compiled module was imported since.

    Finding the loaded BLAS libraries walks the process's shared objects (a few ms: a path
    resolved per library); limiting through a kept controller costs ~10 us. New compiled modules
    may load new libraries (SciPy's own OpenBLAS), so one imported since the last view takes a
    fresh one; pure Python imports only move the count.
    """
    n = len(sys.modules)
    if _CONTROLLER[0] is None or (_CONTROLLER[1] != n and _new_extension(_CONTROLLER[1])):
        from threadpoolctl import ThreadpoolController

        _CONTROLLER[0] = ThreadpoolController()
    _CONTROLLER[1] = n
    return _CONTROLLER[0]


def prepare() -> None:
    """Take the view of the loaded thread pools now, so that the next :func:`one_blas_thread` costs ~10 us.

    For a command's start-up, after it has imported what it computes with: the view (a few ms)
    is then not paid inside the first timed stage.

    Examples
    --------
    >>> prepare()
    >>> _controller() is _controller()
    True
    """
    _controller()


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
