"""The defect stage's lean passes (issue 20): row blocks, bounding boxes, one flood fill, and its memory."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from scipy import ndimage
from skimage.filters import apply_hysteresis_threshold
from skimage.measure import label, regionprops

import photometric.defects as defects
from datasets_synthetic.heightfields import v_crack
from photometric.defects import measure_defects


@pytest.mark.parametrize("seed", range(4))
def test_fill_holes_is_scipys(seed):
    rng = np.random.default_rng(seed)
    mask = ndimage.binary_dilation(rng.random((90, 130)) < 0.08, iterations=2)
    mask[0, :] = rng.random(130) < 0.5  # components touching the border keep their open holes
    np.testing.assert_array_equal(defects._fill_holes(mask), ndimage.binary_fill_holes(mask))


@pytest.mark.parametrize("fraction", [0.2, 0.999])
def test_spread_sample_is_the_linspace_over_every_index(monkeypatch, fraction):
    rng = np.random.default_rng(3)
    ok = rng.random((300, 170)) < fraction
    monkeypatch.setattr(defects, "_BLOCK_PIXELS", 1000)  # many blocks
    flat = np.flatnonzero(ok)
    want = flat[np.linspace(0, flat.size - 1, 5000).astype(np.int64)]
    np.testing.assert_array_equal(defects._spread_sample(ok, 5000), want)
    np.testing.assert_array_equal(defects._spread_sample(ok, flat.size + 1), flat)


def _regionprops_reference(z, h, polarity):
    """The previous whole-image path: full residual, skimage hysteresis and regionprops."""
    bg, sigma = defects.fit_background(z)
    out = []
    for sign in {"depression": (-1.0,), "both": (-1.0, 1.0)}[polarity]:
        depth = sign * (z - bg)
        deepest = float(depth.max())
        high, low = max(6.0 * sigma, 0.05 * deepest), max(2.0 * sigma, 0.005 * deepest)
        regions = apply_hysteresis_threshold(depth, low, high)
        for prop in regionprops(label(regions, connectivity=2), intensity_image=depth):
            if prop.area >= 20:
                d = prop.image_intensity[prop.image]
                out.append((float(d.max()), int(prop.area), float(d.sum() * h * h), [int(v) for v in prop.bbox]))
    return sorted(out, key=lambda r: -r[0])


@pytest.mark.parametrize("polarity", ["depression", "both"])
def test_blocks_and_boxes_measure_what_the_whole_image_measured(monkeypatch, polarity):
    hf = v_crack(240, 0.05, depth_mm=0.2, width_mm=0.8, length_mm=6.0, axis_deg=25.0)
    rng = np.random.default_rng(5)
    x = (np.arange(240) - 119.5) * 0.05
    z = hf.height + 0.03 * x[None, :] - 0.02 * x[:, None] + 2e-3 * rng.standard_normal(hf.height.shape)
    monkeypatch.setattr(defects, "_BLOCK_PIXELS", 2000)  # many row blocks
    found = measure_defects(z, 0.05, polarity=polarity)
    ref = _regionprops_reference(z, 0.05, polarity)
    assert len(found) == len(ref) >= 1
    for got, (depth, area, volume, bbox) in zip(found, ref):
        assert got["max_depth_mm"] == pytest.approx(depth, rel=1e-12)
        assert got["area_px"] == area and got["bbox_px"] == bbox
        assert got["volume_mm3"] == pytest.approx(volume, rel=1e-12)


def test_defect_stage_memory_stays_below_8_bytes_per_pixel():
    """Issue 20: above its inputs (height float64, p and q float32, the mask) the slope-footprint
    path, the pipeline's, allocates at most 8 bytes per pixel at its peak at 4 MP (the background
    fit's subsample, a fixed 250 000 points, is a few MB of it; the whole stage was 27x the input)."""
    hf = v_crack(2048, 0.01, depth_mm=0.1, width_mm=0.3, length_mm=8.0, axis_deg=25.0)
    rng = np.random.default_rng(0)
    z = hf.height + 1e-4 * rng.standard_normal(hf.height.shape)
    p = (hf.p + 1e-3 * rng.standard_normal(z.shape)).astype(np.float32)
    q = (hf.q + 1e-3 * rng.standard_normal(z.shape)).astype(np.float32)
    valid = np.ones(z.shape, bool)
    measure_defects(z, 0.02, valid, p=p, q=q)  # imports and caches outside the measurement
    tracemalloc.start()
    try:
        found = measure_defects(z, 0.02, valid, p=p, q=q)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(found) == 1 and found[0]["max_depth_mm"] == pytest.approx(0.1, rel=0.1)
    assert peak / z.size < 8.0, peak / z.size


@pytest.mark.parametrize("seed", range(6))
def test_hysteresis_is_skimages(seed):
    rng = np.random.default_rng(seed)
    img = ndimage.gaussian_filter(rng.standard_normal((70, 90)), 2.0).astype(np.float32 if seed % 2 else np.float64)
    low, high = sorted(rng.uniform(-0.1, 0.3, 2))
    if seed == 4:
        low = high + 0.1  # clipped to high, as skimage does
    np.testing.assert_array_equal(defects._hysteresis(img, low, high), apply_hysteresis_threshold(img, low, high))


def _reference_measures(z, h, labels, sign, bg):
    """The former per-region measures on whole coordinate arrays (np.cov, float64 copies)."""
    out = []
    for k in range(1, labels.max() + 1):
        rows, cols = np.nonzero(labels == k)
        depth = sign * (z[rows, cols] - bg[rows, cols])
        rows, cols = rows.astype(float), cols.astype(float)
        x, y = cols - cols.mean(), -(rows - rows.mean())
        axis = np.linalg.eigh(np.cov(np.stack([x, y])))[1][:, 1]
        s, t = x * axis[0] + y * axis[1], -x * axis[1] + y * axis[0]
        length = defects._stadium_length(float(rows.size), float(s @ s), float(s.max() - s.min()), 1.0)
        central = np.abs(s - 0.5 * (s.max() + s.min())) <= 0.25 * length
        out.append({"max_depth_mm": depth.max(), "length_mm": length * h, "max_width_mm": (np.ptp(t) + 1.0) * h,
                    "mean_width_mm": central.sum() / max(0.5 * length, 1.0) * h, "volume_mm3": depth.sum() * h * h,
                    "center_px": [(rows * depth).sum() / depth.sum(), (cols * depth).sum() / depth.sum()]})
    return out


@pytest.mark.parametrize("axis_deg", [0.0, 30.0, 90.0, -50.0])
def test_block_sums_measure_what_the_coordinate_arrays_measured(monkeypatch, axis_deg):
    """Three passes over row blocks with exact integer moments give the figures of the whole
    coordinate arrays (float32 height, as the pipeline passes it), and the labels paint each
    measured region."""
    hf = v_crack(200, 0.05, depth_mm=0.2, width_mm=0.7, length_mm=5.0, axis_deg=axis_deg)
    rng = np.random.default_rng(2)
    z = (hf.height + 1e-3 * rng.standard_normal(hf.height.shape)).astype(np.float32)
    monkeypatch.setattr(defects, "_BLOCK_PIXELS", 1500)  # a region spans many blocks
    found, labels = measure_defects(z, 0.05, return_labels=True)
    bg, _ = defects.fit_background(z)
    ref = _reference_measures(z, 0.05, labels, -1.0, bg)
    assert len(found) == len(ref) >= 1
    for got, want in zip(found, ref):
        for key, value in want.items():
            np.testing.assert_allclose(got[key], value, rtol=1e-9, err_msg=key)
        assert got["area_px"] == np.count_nonzero(labels == got["id"] + 1)
        rows, cols = np.nonzero(labels == got["id"] + 1)
        assert got["bbox_px"] == [rows.min(), cols.min(), rows.max() + 1, cols.max() + 1]
