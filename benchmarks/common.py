"""Helpers shared by the benchmark scripts (run from this folder or through run_all.py)."""

from __future__ import annotations

import time


def best_of(fn, repeat: int = 3):
    """Call ``fn`` ``repeat`` times; return the shortest wall time (s) and the last result."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out
