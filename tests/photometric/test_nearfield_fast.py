"""The inspection's shortcuts for large parts (near-field solve, defect detection) against the exact computation.

A full-resolution pass that re-solved only the pixels whose point moved integrates the slope
change on a decimated grid (``correction_step``); its heights must stay within the stated
margin of a full-resolution integration and the scratch's measures within 0.5 %.
"""

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera, perspective_camera
from datasets_synthetic.heightfields import inspection_part
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import ring_point_lights
from photometric.camera import make_camera
from photometric.defects import measure_defects
from photometric.leds import point_lights
from photometric.nearfield import CORRECTION_MARGIN, DEFAULT_TOLERANCE_MM, solve_nearfield


def _scratch(camera_height):
    shape, px = (384, 448), 60.0 / 1024
    part = inspection_part(shape, px, "scratch", center_mm=(0.0, 0.0))
    if camera_height is None:
        rcam, cam = orthographic_camera(shape, px), make_camera("orthographic", pixel_size_mm=px)
    else:
        f = camera_height / px
        rcam = perspective_camera(shape, f, camera_height)
        cam = make_camera("perspective", focal_length_px=f, camera_height_mm=camera_height)
    lights = ring_point_lights(4, 40.0, 200.0, 90.0, 1.0, None)
    r = render_near_field(part, rcam, lights, 0.8, noise=0.003, bit_depth=16, seed=5)
    return part, cam, r


@pytest.mark.parametrize("camera_height", [None, 300.0], ids=["orthographic", "perspective"])
def test_decimated_correction_matches_full_resolution_integration(camera_height):
    part, cam, r = _scratch(camera_height)
    lights = point_lights(r.lights.positions, mu=1.0)
    kw = {"intensities": r.lights.intensities, "coarse_pixels": 1 << 14}
    exact = solve_nearfield(r.images, lights, cam, correction_step=1, **kw)
    fast = solve_nearfield(r.images, lights, cam, **kw)
    full = [h for h in fast.history if h["level"] == "full"]
    # the shortcut applies: the last full pass re-solved few pixels, and it changed the heights
    assert len(full) >= 2 and full[-1]["resolved_fraction"] < 0.5
    assert [h["resolved_fraction"] for h in fast.history] == [h["resolved_fraction"] for h in exact.history]
    np.testing.assert_array_equal(fast.normals, exact.normals)
    np.testing.assert_array_equal(fast.p, exact.p)
    diff = np.abs(fast.height - exact.height)[exact.valid]
    assert 0 < diff.max() < CORRECTION_MARGIN * DEFAULT_TOLERANCE_MM
    on = lambda res: {} if camera_height is None else {"xy": res.xy, "area": res.footprint_mm2}  # noqa: E731
    a = measure_defects(exact.height, 60.0 / 1024, exact.valid, p=exact.p, q=exact.q, **on(exact))[0]
    b = measure_defects(fast.height, 60.0 / 1024, fast.valid, p=fast.p, q=fast.q, **on(fast))[0]
    assert b["max_depth_mm"] == pytest.approx(a["max_depth_mm"], rel=5e-3)
    assert b["length_mm"] == pytest.approx(a["length_mm"], rel=5e-3)
    assert a["max_depth_mm"] == pytest.approx(part.defects[0]["depth_mm"], rel=0.05)


def test_correction_step_is_checked():
    part, cam, r = _scratch(None)
    lights = point_lights(r.lights.positions, mu=1.0)
    for bad in (0, 2.5, -1):
        with pytest.raises(ValueError, match="correction_step: must be an integer of at least 1"):
            solve_nearfield(r.images[:, :64, :64], lights, cam, correction_step=bad)


@pytest.mark.parametrize("n", [1000, 70_000, 70_001, 1_000_003])
def test_defect_detection_median_is_numpy_median(n):
    """The slope threshold's medians (photometric.defects, the inspection's detection stage) are
    found from a bracket of a sample: exactly numpy's median, ties, infinities and NaN included."""
    from photometric.defects import _median

    rng = np.random.default_rng(n)
    for dtype in (np.float32, np.float64):
        v = (rng.standard_normal(n) ** 2).astype(dtype)
        assert _median(v.copy()) == float(np.median(v))
        v[::97] = np.inf
        v[1::5] = v[0]  # many ties
        assert _median(v.copy()) == float(np.median(v))
        mad = np.abs(v - np.float32(np.median(v)))
        assert _median(mad.copy()) == float(np.median(mad))
        v[3] = np.nan
        assert np.isnan(_median(v.copy()))


@pytest.mark.parametrize("outliers", [False, True], ids=["all-lights", "outliers"])
def test_solve_without_residual_is_the_same_solve(outliers):
    """``residual=False`` (the inspection) leaves out only the residual: every other array bit for bit."""
    part, cam, r = _scratch(None)
    lights = point_lights(r.lights.positions, mu=1.0)
    kw = {"intensities": r.lights.intensities, "coarse_pixels": 1 << 14, "outliers": outliers}
    full = solve_nearfield(r.images, lights, cam, **kw)
    lean = solve_nearfield(r.images, lights, cam, residual=False, **kw)
    assert lean.residual is None and full.residual.shape == full.valid.shape
    assert np.median(full.residual[full.valid]) > 0  # image noise: a residual was computed
    for name in ("normals", "albedo", "valid", "p", "q", "height", "xy"):
        np.testing.assert_array_equal(getattr(lean, name), getattr(full, name), err_msg=name)
    assert [h["resolved_fraction"] for h in lean.history] == [h["resolved_fraction"] for h in full.history]


def test_partial_resolve_equals_a_whole_image_solve():
    """Pixels gathered into image-wide rows (:func:`photometric.nearfield._gather`), solved and scattered
    back, get exactly the normals, albedo, residual and validity of a solve of the whole image."""
    from concurrent.futures import ThreadPoolExecutor

    from photometric.camera import pixel_offsets
    from photometric.nearfield import _gather, _Level, _normals, _Options, _scatter, _strengths, _take

    part, cam, r = _scratch(None)
    lights = point_lights(r.lights.positions, mu=1.0)
    shape = r.images.shape[1:3]
    u, v = pixel_offsets(cam, shape)
    mask = np.ones(shape, bool)
    mask[:5] = False
    level = _Level(planes=r.images.astype(np.float32), strength=_strengths(lights, cam, shape, None, None), mask=mask,
                   saturated=r.images >= 0.99, u=u, v=v, step=1)
    opts = _Options(True, 0.1, 0.99, None, 2, True)
    z = np.random.default_rng(3).uniform(-0.05, 0.05, shape)
    with ThreadPoolExecutor(1) as pool:
        whole = _normals(level, lights, cam, z, opts, pool, final=True)
        # a scattered selection whose count is not a multiple of the width (a padded last row)
        moved = mask & (np.random.default_rng(4).random(shape) < 0.3)
        idx = np.flatnonzero(moved)
        assert idx.size % shape[1]
        sol = _normals(level, lights, cam, np.zeros(shape), opts, pool, final=True)
        part_sol = _normals(_gather(level, idx), lights, cam, _take(z, idx, shape[1]), opts, pool, final=True)
        _scatter(sol, part_sol, idx)
    for key in ("normals", "rho", "valid", "residual", "outliers"):
        np.testing.assert_array_equal(sol[key][..., moved], whole[key][..., moved], err_msg=key)
