"""One BLAS thread for thin products: the limit holds inside, is restored after, and costs little."""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_info

import surfaces.threads as threads
from slices.io import Contour


def _blas_threads() -> dict:
    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_one_blas_thread_limits_and_restores():
    before = _blas_threads()
    with threads.one_blas_thread():
        assert all(n == 1 for n in _blas_threads().values())
        float(np.ones(4) @ np.ones(4))
    assert _blas_threads() == before


def test_the_controller_is_kept_until_a_compiled_module_is_imported(monkeypatch):
    import importlib.machinery
    import sys
    import types

    with threads.one_blas_thread():
        pass
    kept = threads._controller()
    assert threads._controller() is kept
    # a pure Python module loads no library: the view stands
    monkeypatch.setitem(sys.modules, "_a_python_module_imported_later", types.ModuleType("_a_python_module"))
    assert threads._controller() is kept
    # a compiled one may bring its own BLAS: a fresh view, then kept again
    compiled = types.ModuleType("_a_compiled_module")
    compiled.__file__ = "/somewhere/_a_compiled_module" + importlib.machinery.EXTENSION_SUFFIXES[0]
    monkeypatch.setitem(sys.modules, "_a_compiled_module_imported_later", compiled)
    fresh = threads._controller()
    assert fresh is not kept and threads._controller() is fresh
    # modules removed: the import order says nothing, a fresh view
    monkeypatch.delitem(sys.modules, "_a_compiled_module_imported_later")
    monkeypatch.delitem(sys.modules, "_a_python_module_imported_later")
    assert threads._controller() is not fresh


def test_prepare_takes_the_view_that_the_limit_then_uses(monkeypatch):
    import threadpoolctl

    monkeypatch.setattr(threads, "_CONTROLLER", [None, -1])
    threads.prepare()
    kept = threads._CONTROLLER[0]
    assert kept is not None

    def no_new_view(*args, **kwargs):
        raise AssertionError("the limit took a new view after prepare")

    # the limit uses the view prepare took, without walking the shared objects again
    monkeypatch.setattr(threadpoolctl, "ThreadpoolController", no_new_view)
    with threads.one_blas_thread():
        assert threads._CONTROLLER[0] is kept


def test_reconstruct_contours_builds_its_bodies_on_one_blas_thread(monkeypatch):
    import slices.structure as structure

    seen = []

    def spying(build):
        def spy(*args, **kwargs):
            seen.append(_blas_threads())
            return build(*args, **kwargs)
        return spy

    # a single chain is built once (build_body_once), other chains through the fallbacks (build_stepped)
    for name in ("build_stepped", "build_body_once"):
        monkeypatch.setattr(structure, name, spying(getattr(structure, name)))
    before = _blas_threads()
    t = np.linspace(0, 2 * np.pi, 32, endpoint=False)
    circle = 10 * np.stack([np.cos(t), np.sin(t)], axis=1)
    structure.reconstruct_contours([Contour(z, circle) for z in (0.0, 5.0, 10.0)], caps="flat")
    assert seen and all(n == 1 for s in seen for n in s.values())
    # libraries loaded on the way (SciPy's own BLAS) are new; the ones there before are restored
    after = _blas_threads()
    assert {k: after[k] for k in before} == before
