"""Bounded memory of the defect measures (issue 20), measured with tracemalloc.

Moved from tests/workbench/test_memory.py: it reaches into photometric.defects' private
block size and background fit, which only photometric's own tests may do.
"""

from __future__ import annotations

import tracemalloc

import numpy as np


def test_defect_measures_keep_nothing_per_region_pixel(monkeypatch):
    """Issue 20: one depression over 45 % of the image. Past the background fit (a fixed sample),
    the defect stage's peak stays below 40 bytes per region pixel on both segmentations (the
    former coordinate arrays and float64 copies of the measures: 124 to 133 bytes; now 19 to 26:
    the slope footprint's labels, the depth image and the region's boolean crop)."""
    import photometric.defects as defects
    from datasets_synthetic.heightfields import spherical_dent

    hf = spherical_dent(512, 0.05, depth_mm=0.5, width_mm=0.8 * 512 * 0.05)
    rng = np.random.default_rng(0)
    z = (hf.height + 1e-4 * rng.standard_normal(hf.height.shape)).astype(np.float32)
    p = (hf.p + 1e-3 * rng.standard_normal(z.shape)).astype(np.float32)
    q = (hf.q + 1e-3 * rng.standard_normal(z.shape)).astype(np.float32)
    valid = np.ones(z.shape, bool)
    monkeypatch.setattr(defects, "_BLOCK_PIXELS", 4096)  # block temporaries small beside the image, as at 4 MP
    fit = defects._fit

    def fit_then_reset(*args, **kwargs):
        out = fit(*args, **kwargs)
        tracemalloc.reset_peak()
        return out

    monkeypatch.setattr(defects, "_fit", fit_then_reset)
    for slopes in ({}, {"p": p, "q": q}):
        defects.measure_defects(z, 0.05, valid, **slopes)  # imports and caches outside the measurement
        tracemalloc.start()
        try:
            found = defects.measure_defects(z, 0.05, valid, **slopes)
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        area = sum(d["area_px"] for d in found)
        assert len(found) == 1 and area > 0.4 * z.size
        assert peak / area < 40.0, (sorted(slopes), peak / area)
