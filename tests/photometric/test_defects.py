import numpy as np
import pytest

from datasets_synthetic.heightfields import inspection_plate, make_scene, v_crack
from datasets_synthetic.render import render
from photometric.lights import ring_lights
from photometric.defects import fit_background, measure_defects
from photometric.integrate import integrate
from photometric.stereo import solve


def _match(found, truth):
    c = np.array(truth["center_px"])
    return min(found, key=lambda d: np.hypot(*(np.array(d["center_px"]) - c)))


def _check(found, truths, keys=(("max_depth_mm", "depth_mm"), ("mean_width_mm", "width_mm"),
                               ("length_mm", "length_mm"))):
    for truth in truths:
        got = _match(found, truth)
        for mine, theirs in keys:
            error = abs(got[mine] - truth[theirs])
            assert error <= 0.10 * truth[theirs], (truth["kind"], mine, got[mine], truth[theirs])


@pytest.mark.parametrize("tilt", [(0.0, 0.0), (0.05, -0.03)])
def test_analytic_crack_on_tilted_plate(tilt):
    hf = v_crack(200, 0.05, depth_mm=0.2, width_mm=0.8, length_mm=6.0, axis_deg=25.0)
    x = (np.arange(200) - 99.5) * 0.05
    z = hf.height + tilt[0] * x[None, :] + tilt[1] * -x[:, None] + 1.0
    found = measure_defects(z, 0.05)
    assert len(found) == 1
    d = found[0]
    _check(found, hf.defects)
    assert abs(d["axis_deg"] - 25.0) < 2.0
    assert abs(d["area_mm2"] - hf.defects[0]["area_mm2"]) < 0.1 * hf.defects[0]["area_mm2"]
    assert abs(d["volume_mm3"] - hf.defects[0]["volume_mm3"]) < 0.1 * hf.defects[0]["volume_mm3"]


@pytest.mark.parametrize("seed", [0, 3])
def test_inspection_plate_exact_height(seed):
    hf = inspection_plate(256, 0.1, seed=seed)
    found = measure_defects(hf.height, hf.pixel_size)
    assert len(found) == 3
    _check(found, hf.defects)


@pytest.mark.parametrize("noise", [0.0, 0.005])
def test_inspection_plate_through_photometric_stereo(noise):
    """Render a triad, solve, integrate (DCT), measure: depth, width, length within 10 %."""
    hf = inspection_plate(384, 0.05 * 512 / 384, seed=1)
    lights = ring_lights(3, 45.0)
    images = render(hf, lights, albedo=0.8, noise=noise, seed=4)
    res = solve(images, lights)
    z = integrate(res.p, res.q, "dct", pixel_size=hf.pixel_size)
    found = measure_defects(z, hf.pixel_size, p=res.p, q=res.q)
    assert len(found) == 3
    _check(found, hf.defects)


def test_bump_polarity_and_smooth_background():
    hf = make_scene("dent", 128, 0.05)
    rows, cols = np.indices(hf.height.shape)
    curved = -hf.height + 1e-5 * (cols - 40.0) ** 2 + 2e-5 * rows * cols / 10  # a bump on a bowl
    assert measure_defects(curved, 0.05, background="smooth", degree=2, polarity="depression") == []
    bumps = measure_defects(curved, 0.05, background="smooth", degree=2, polarity="bump")
    assert len(bumps) == 1 and bumps[0]["kind"] == "bump"
    assert abs(bumps[0]["max_depth_mm"] - hf.defects[0]["depth_mm"]) < 0.05 * hf.defects[0]["depth_mm"]


def test_fit_background_robust_to_defect():
    rows, cols = np.indices((80, 90)).astype(float)
    plane = 0.3 + 0.01 * cols - 0.02 * rows
    z = plane.copy()
    z[30:50, 20:60] -= 0.5
    bg, sigma = fit_background(z)
    assert np.allclose(bg, plane, atol=1e-9) and sigma < 1e-9


def test_bad_input():
    with pytest.raises(ValueError, match="polarity"):
        measure_defects(np.zeros((10, 10)), 1.0, polarity="up")
    with pytest.raises(ValueError, match="background"):
        measure_defects(np.zeros((10, 10)), 1.0, background="sphere")
    with pytest.raises(ValueError, match="pixel_size"):
        measure_defects(np.zeros((10, 10)), -1.0)
    with pytest.raises(ValueError, match="p, q"):
        measure_defects(np.zeros((10, 10)), 1.0, p=np.zeros((10, 10)))


def _grid_xy(shape, h):
    x = (np.arange(shape[1]) - (shape[1] - 1) / 2) * h
    y = ((shape[0] - 1) / 2 - np.arange(shape[0])) * h
    return np.stack(np.broadcast_arrays(x[None, :], y[:, None]), axis=-1)


@pytest.mark.parametrize("method, degree", [("plane", 3), ("smooth", 2), ("smooth", 3)])
def test_fit_background_on_points_matches_the_grid(method, degree):
    """On the pixel grid's own points the point-based fit is the grid fit (a polynomial space
    does not depend on the affine scaling of its coordinates)."""
    rows, cols = np.indices((60, 70)).astype(float)
    z = 0.3 + 0.01 * cols - 0.02 * rows + 1e-5 * (cols - 20) ** 2 - 2e-6 * rows * cols
    z[20:30, 10:40] -= 0.2
    mask = np.ones(z.shape, bool)
    mask[:5] = False  # the point coordinates are scaled over the usable pixels only
    bg_grid, s_grid = fit_background(z, mask, method, degree=degree)
    bg_pts, s_pts = fit_background(z, mask, method, degree=degree, xy=_grid_xy(z.shape, 0.05))
    np.testing.assert_allclose(bg_pts, bg_grid, atol=1e-9)
    assert s_pts == pytest.approx(s_grid, abs=1e-12)


def test_measure_defects_on_points_matches_the_grid():
    hf = v_crack(200, 0.05, depth_mm=0.2, width_mm=0.8, length_mm=6.0, axis_deg=25.0)
    grid = measure_defects(hf.height, 0.05)
    pts = measure_defects(hf.height, 0.05, xy=_grid_xy(hf.height.shape, 0.05), area=0.05**2)
    assert len(grid) == len(pts) == 1
    for key in ("max_depth_mm", "length_mm", "max_width_mm", "area_mm2", "volume_mm3", "axis_deg"):
        assert pts[0][key] == pytest.approx(grid[0][key], rel=0.02, abs=1e-6), key
    cx, cy = pts[0]["center_mm"]
    assert (cx, cy) == pytest.approx(tuple(hf.defects[0]["center_mm"]), abs=0.05)
    with pytest.raises(ValueError, match="area: per-pixel footprints need xy"):
        measure_defects(hf.height, 0.05, area=0.05**2)


@pytest.mark.parametrize("background", ["plane", "smooth", "none"])
def test_fast_slope_footprint_matches_the_full_image_gradient(monkeypatch, background):
    """The background's slopes from its separable 1-D terms give the figures and labels that
    ``numpy.gradient`` of the whole background image gave (the previous path), on a rendered,
    tilted part: equal to 1e-9 relative (only the rounding of the gradient differs)."""
    import photometric.defects as defects

    hf = inspection_plate(256, 0.08, seed=2)
    images = render(hf, ring_lights(4, 40.0), albedo=0.8, noise=0.003, seed=5)
    res = solve(images, ring_lights(4, 40.0))
    # a tilted, slightly bowed part (every background term has slopes); flat without a background
    rows, cols = np.indices(hf.height.shape)
    x, y = cols * hf.pixel_size, -rows * hf.pixel_size
    bow = 0.0 if background == "none" else 1.0
    z = integrate(res.p, res.q, "dct", pixel_size=hf.pixel_size) + bow * (0.01 * x + 0.006 * y
                                                                          + 2e-4 * (x - 10.0) ** 2)
    p, q = res.p + bow * (0.01 + 4e-4 * (x - 10.0)), res.q + bow * 0.006
    kw = dict(background=background, degree=3, p=p, q=q, return_labels=True)
    fast, fast_labels = measure_defects(z, hf.pixel_size, **kw)
    monkeypatch.setattr(defects, "_background_slopes",
                        lambda bg, terms: np.gradient(sum(np.outer(c, r) for c, r in terms)) if terms else (0.0, 0.0))
    slow, slow_labels = measure_defects(z, hf.pixel_size, **kw)
    assert len(fast) == len(slow) >= 1
    np.testing.assert_array_equal(fast_labels, slow_labels)
    for a, b in zip(fast, slow):
        assert a.keys() == b.keys()
        for key, value in a.items():
            if isinstance(value, str):
                assert value == b[key]
            else:
                np.testing.assert_allclose(value, b[key], rtol=1e-9, atol=1e-12, err_msg=key)


def test_stadium_length_closed_forms():
    from photometric.defects import _stadium_length

    # a continuous stadium's own area and second moment give back its length
    for c, w in ((92.0, 8.0), (10.0, 3.0), (0.0, 6.0)):
        area = c * w + np.pi * w * w / 4.0
        second = w * c**3 / 12.0 + np.pi * w * w * c * c / 16.0 + c * w**3 / 6.0 + np.pi * w**4 / 64.0
        assert _stadium_length(area, second, c + w - 0.5, 1.0) == pytest.approx(c + w, rel=1e-6)
    # a moment below the disc's (lattice sums of a small round region) reads as the disc
    disc = _stadium_length(np.pi * 9.0, 0.5 * np.pi * 81.0 / 4.0, 5.0, 1.0)
    assert disc == pytest.approx(6.0, rel=1e-6)
    # kept within the extent of the centres and two pitches more; vectorised
    out = _stadium_length(np.array([100.0, 100.0]), np.array([1e6, 1.0]), np.array([20.0, 1.0]), 1.0)
    assert out[0] == pytest.approx(22.0) and out[1] == pytest.approx(1.0 + 2.0)


def test_length_is_sub_pixel_on_oblique_scratches():
    """The extent of the centres plus one pixel read about 0.4 pixel long on oblique axes; the
    stadium's length from the area and second moment is unbiased over random axes and places."""
    from datasets_synthetic.heightfields import u_scratch

    rng = np.random.default_rng(5)
    errors = []
    for _ in range(24):
        centre = tuple(59.5 + rng.uniform(-0.5, 0.5, 2))
        hf = u_scratch(120, 0.05, depth_mm=0.05, width_mm=0.4, length_mm=4.0, center_px=centre,
                       axis_deg=rng.uniform(-90.0, 90.0))
        n = hf.normals
        found = measure_defects(hf.height, 0.05, p=-n[..., 0] / n[..., 2], q=-n[..., 1] / n[..., 2])
        assert len(found) == 1
        errors.append(found[0]["length_mm"] / 0.05 - 80.0)
    assert abs(np.mean(errors)) < 0.15, np.mean(errors)
    assert np.max(np.abs(errors)) < 1.0
