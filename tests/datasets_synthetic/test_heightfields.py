"""Analytic height fields: the image convention, exact slopes and exact defect truth."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic import heightfields as hfm
from surfaces.grid import pixel_grid, xy_to_pixel
from datasets_synthetic.heightfields import (
    INSPECTION_DEFECTS,
    SCENES,
    inspection_part,
    inspection_plate,
    make_scene,
    spherical_dent,
    tilted_plane,
    u_scratch,
    v_crack,
)


def test_scenes_follow_the_stated_convention():
    """CONVENTION's numbers, written out: centred pixel centres, y up, n = (-p, -q, 1) / |.|."""
    h, w, ps = 5, 8, 0.2
    hf = tilted_plane((h, w), ps, slope_x=0.3, slope_y=-0.7)
    rows, cols = np.mgrid[0:h, 0:w]
    x = (cols - (w - 1) / 2) * ps
    y = ((h - 1) / 2 - rows) * ps
    np.testing.assert_allclose(hf.height, 0.3 * x - 0.7 * y, atol=1e-15)
    assert hf.height[h // 2, (w - 1) // 2] == pytest.approx(0.3 * -0.5 * ps)  # origin between columns 3 and 4
    np.testing.assert_allclose(hf.normals[2, 3], np.array([-0.3, 0.7, 1.0]) / np.sqrt(1.58), atol=1e-15)
    # a defect placed in mm reports the pixel whose centre is there
    crack = v_crack((21, 31), 0.1, depth_mm=0.1, width_mm=0.4, length_mm=1.0, center_px=(4.0, 25.0))
    assert crack.defects[0]["center_mm"] == pytest.approx([(25 - 15) * 0.1, (10 - 4) * 0.1])
    assert crack.defects[0]["center_px"] == pytest.approx([4.0, 25.0])


def test_surface_rising_to_the_right_has_normals_with_negative_x():
    hf = tilted_plane(16, 0.1, slope_x=0.5, slope_y=0.0)
    assert np.all(np.diff(hf.height, axis=1) > 0)  # rises with the column index
    assert np.all(hf.normals[..., 0] < 0)
    np.testing.assert_allclose(hf.normals[0, 0], np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25))


def test_surface_rising_upwards_is_higher_on_the_top_row():
    hf = tilted_plane(16, 0.1, slope_x=0.0, slope_y=0.3)
    assert np.all(np.diff(hf.height, axis=0) < 0)  # y up: row 0 is highest
    assert np.all(hf.normals[..., 1] < 0)


def test_pixel_grid_round_trip():
    x, y = pixel_grid((5, 7), 0.2)
    assert x[0, 0] < x[0, -1] and y[0, 0] > y[-1, 0]
    row, col = xy_to_pixel(x, y, (5, 7), 0.2)
    np.testing.assert_allclose(row, np.mgrid[0:5, 0:7][0], atol=1e-12)
    np.testing.assert_allclose(col, np.mgrid[0:5, 0:7][1], atol=1e-12)


@pytest.mark.parametrize("name", SCENES)
def test_slopes_are_exact_derivatives(name):
    # the inspection parts' defects are sized in mm and need a field of about 20 mm
    hf = make_scene(name, 96, 0.25 if name.startswith("inspection") else 0.05, seed=1)
    assert hf.height.shape == hf.p.shape == hf.q.shape == (96, 96)
    assert hf.normals.shape == (96, 96, 3)
    np.testing.assert_allclose(np.linalg.norm(hf.normals, axis=2), 1.0, atol=1e-12)
    np.testing.assert_allclose(hf.normals[..., 0] / hf.normals[..., 2], -hf.p, atol=1e-12)
    np.testing.assert_allclose(hf.normals[..., 1] / hf.normals[..., 2], -hf.q, atol=1e-12)
    # central differences agree with the exact slopes except on kinks and steep rims
    dzdr, dzdc = np.gradient(hf.height, hf.pixel_size)
    bad = ((np.abs(dzdc - hf.p) > 0.02 * (1.0 + np.abs(hf.p)))
           | (np.abs(-dzdr - hf.q) > 0.02 * (1.0 + np.abs(hf.q))))
    assert bad[1:-1, 1:-1].mean() < 0.08


def test_wrong_slopes_would_be_caught():
    hf = make_scene("bumps", 96, 0.05, seed=1)
    dzdr, _ = np.gradient(hf.height, hf.pixel_size)
    # the sign convention matters: q with y DOWN fails the same check
    assert (np.abs(dzdr - hf.q) > 0.02 * (1.0 + np.abs(hf.q))).mean() > 0.3


@pytest.mark.parametrize(
    "build",
    [
        lambda: v_crack(400, 0.01, depth_mm=0.2, width_mm=0.5, length_mm=3.0, axis_deg=25.0),
        lambda: u_scratch(400, 0.01, depth_mm=0.05, width_mm=0.4, length_mm=2.5, axis_deg=-40.0),
        lambda: spherical_dent(400, 0.01, depth_mm=0.1, width_mm=2.0),
    ],
    ids=["crack", "scratch", "dent"],
)
def test_defect_truth_matches_the_sampled_surface(build):
    hf = build()
    (d,) = hf.defects
    ps = hf.pixel_size
    for key in ("kind", "depth_mm", "width_mm", "length_mm", "area_mm2", "depth_px", "width_px",
                "length_px", "area_px", "center_px", "axis_deg"):
        assert key in d
    assert d["depth_px"] * ps == pytest.approx(d["depth_mm"])
    assert d["area_px"] * ps**2 == pytest.approx(d["area_mm2"])
    assert d["length_px"] * ps == pytest.approx(d["length_mm"])
    assert -hf.height.min() == pytest.approx(d["depth_mm"], rel=0.02)
    assert hf.defect_mask.sum() == pytest.approx(d["area_px"], rel=0.02)
    assert -hf.height.sum() * ps**2 == pytest.approx(d["volume_mm3"], rel=0.02)
    row, col = np.rint(d["center_px"]).astype(int)
    assert hf.height[row, col] == pytest.approx(-d["depth_mm"], rel=0.05)
    assert not hf.defect_mask[0, 0]


def test_crack_axis_follows_y_up():
    hf = v_crack(200, 0.02, depth_mm=0.1, width_mm=0.2, length_mm=3.0, axis_deg=45.0)
    rows, cols = np.nonzero(hf.defect_mask)
    # axis at +45 deg (towards +x and +y): the crack runs from lower left to upper right,
    # so the row index falls as the column index grows
    assert np.corrcoef(rows, cols)[0, 1] < -0.9


@pytest.mark.parametrize("seed", [0, 3])
def test_inspection_plate_has_three_disjoint_defects(seed):
    hf = inspection_plate(256, 0.1, seed=seed)
    kinds = [d["kind"] for d in hf.defects]
    assert kinds == ["v_crack", "spherical_dent", "u_scratch"]
    assert hf.defect_mask.sum() == pytest.approx(sum(d["area_px"] for d in hf.defects), rel=0.05)
    # each defect's deepest point is at its own centre
    for d in hf.defects:
        row, col = np.rint(d["center_px"]).astype(int)
        assert hf.defect_mask[row, col]
        assert hf.height[row, col] == pytest.approx(-d["depth_mm"], rel=0.1)
    again = inspection_plate(256, 0.1, seed=seed)
    np.testing.assert_array_equal(again.height, hf.height)
    other = inspection_plate(256, 0.1, seed=seed + 1)
    assert not np.array_equal(other.height, hf.height)


def test_plate_tilt_adds_slopes():
    flat = inspection_plate(64, 0.1, jitter=False)
    tilted = inspection_plate(64, 0.1, tilt=(0.02, -0.01), jitter=False)
    np.testing.assert_allclose(tilted.p - flat.p, 0.02, atol=1e-12)
    np.testing.assert_allclose(tilted.q - flat.q, -0.01, atol=1e-12)


def test_vase_lies_on_its_support():
    hf = make_scene("vase", 128, 0.05, seed=0)
    assert np.all(hf.height[hf.defect_mask] > 0)
    assert np.all(hf.height[~hf.defect_mask] == 0) and np.all(hf.p[~hf.defect_mask] == 0)
    # C1: the slope next to the outline is far below the peak slope reached inside
    row = hf.defect_mask[64]
    assert abs(hf.p[64][row][0]) < abs(hf.p[64]).max()


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: make_scene("moon", 64, 0.05, 0), "name"),
        (lambda: make_scene("plane", 1, 0.05, 0), "size"),
        (lambda: make_scene("plane", 64, -1.0, 0), "pixel_size"),
        (lambda: spherical_dent(64, 0.05, depth_mm=2.0, width_mm=1.0), "depth_mm"),
        (lambda: v_crack(64, 0.05, width_mm=2.0, length_mm=1.0), "length_mm"),
        (lambda: inspection_plate(16, 0.05), "size"),
        (lambda: hfm.tilted_plane(8, 0.1, slope_x=np.inf), "slope_x"),
    ],
)
def test_bad_input_names_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def _field_pixel(name):
    """A pixel size whose 64 px field holds the scene (the inspection parts' defects are sized in mm)."""
    return 0.3 if name.startswith("inspection") else 0.05


@pytest.mark.parametrize("name", SCENES)
def test_the_grid_is_the_analytic_surface_at_the_pixel_centres(name):
    hf = make_scene(name, (48, 64), _field_pixel(name), seed=2)
    x, y = pixel_grid(hf.shape, hf.pixel_size)
    z, p, q, inside = hf.surface.evaluate(x, y)
    np.testing.assert_array_equal(z, hf.height)
    np.testing.assert_array_equal(p, hf.p)
    np.testing.assert_array_equal(q, hf.q)
    np.testing.assert_array_equal(inside, hf.defect_mask)


@pytest.mark.parametrize("name", SCENES)
def test_the_surface_anywhere_has_exact_slopes_within_its_bounds(name):
    hf = make_scene(name, 64, _field_pixel(name), seed=1)
    s = hf.surface
    half = 0.6 * 64 * hf.pixel_size  # beyond the image too: the scene is defined everywhere
    rng = np.random.default_rng(7)
    x, y = rng.uniform(-half, half, (2, 20000))
    z, p, q, inside = s.evaluate(x, y)
    eps = 1e-6
    zx = (s.evaluate(x + eps, y)[0] - s.evaluate(x - eps, y)[0]) / (2 * eps)
    zy = (s.evaluate(x, y + eps)[0] - s.evaluate(x, y - eps)[0]) / (2 * eps)
    bad = (np.abs(zx - p) > 1e-5 * (1 + np.abs(p))) | (np.abs(zy - q) > 1e-5 * (1 + np.abs(q)))
    assert bad.mean() < 1e-3  # only samples within 1e-6 mm of a kink
    z0, sx, sy = s.plane
    lo, hi = s.relief_bounds
    relief = z - sx * x - sy * y
    assert relief.min() >= lo - 1e-12 and relief.max() <= hi + 1e-12
    assert np.hypot(p - sx, q - sy).max() <= s.relief_max_slope * (1 + 1e-9) + 1e-15


@pytest.mark.parametrize("name, reached", [("crack", 1.0), ("dent", 0.8), ("scratch", 0.8)])
def test_slope_bounds_are_tight_for_one_feature(name, reached):
    hf = make_scene(name, 256, 0.05)
    steepest = np.hypot(hf.p, hf.q).max()
    assert reached * hf.surface.relief_max_slope * (1 - 1e-12) <= steepest <= hf.surface.relief_max_slope * (1 + 1e-12)


@pytest.mark.parametrize("defect, kind", [("scratch", "u_scratch"), ("crack", "v_crack"), ("dent", "spherical_dent")])
def test_inspection_part_is_a_60_mm_plate_with_one_defect_in_mm(defect, kind):
    hf = inspection_part(600, 0.1, defect=defect)
    (d,) = hf.defects
    spec = INSPECTION_DEFECTS[defect]
    assert d["kind"] == kind and d["depth_mm"] == pytest.approx(0.10)
    assert d["center_mm"] == pytest.approx(list(spec["center_mm"]))
    assert d["width_mm"] == spec["width_mm"] and d["length_mm"] == spec["length_mm"]
    cx, cy = spec["center_mm"]
    z = hf.surface.evaluate(cx, cy)[0]
    assert float(z) == pytest.approx(-0.10, abs=1e-12)  # deepest at the centre, in mm, at any resolution
    assert hf.params["plate_mm"] == 60.0
    # the same part on another grid: the defect does not scale with the image
    finer = inspection_part(500, 0.05, defect=defect)
    assert finer.defects[0]["area_mm2"] == pytest.approx(d["area_mm2"])
    assert make_scene(f"inspection_{defect}", 600, 0.1).defects == hf.defects


def test_inspection_part_options_and_errors():
    hf = inspection_part(200, 0.1, depth_mm=0.05, width_mm=0.8, length_mm=5.0, center_mm=(0.0, 0.0),
                         axis_deg=0.0, tilt=(0.01, 0.0))
    assert hf.defects[0]["depth_mm"] == 0.05 and hf.defects[0]["length_mm"] == 5.0
    np.testing.assert_allclose(hf.p[0, 0], 0.01)
    with pytest.raises(ValueError, match="does not contain the scratch"):
        inspection_part(64, 0.05)
    with pytest.raises(ValueError, match="defect"):
        inspection_part(200, 0.1, defect="hole")
