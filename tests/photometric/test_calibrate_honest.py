"""Issue 33 item 2: the highlight from a fitted model, and a sphere calibration whose stated u is honest.

Checked against what the calibration did not write: pixel-integrated Gaussian spots (closed form, scipy's
normal CDF), the independent mirror-sphere renderer of datasets_synthetic (with its lens option, the
distortion of OpenCV's model written out by hand here), and chi2 quantiles from scipy.
"""

import warnings

import numpy as np
import pytest
from scipy.special import ndtr

from datasets_synthetic.cameras import make_camera as synth_camera
from datasets_synthetic.point_lights import rig_lights
from datasets_synthetic.spheres import render_mirror_sphere
from photometric.calibrate import SphereImages, birge_check, calibrate_positions, fit_spot, highlight_centroids
from photometric.camera import make_camera


def _spot(r0, c0, s, n=9):
    """A Gaussian spot of standard deviation ``s`` px integrated over each pixel (pixel centres at integers)."""
    edges = np.arange(n + 1) - 0.5
    return np.outer(np.diff(ndtr((edges - r0) / s)), np.diff(ndtr((edges - c0) / s)))


def test_fitted_peak_is_sub_pixel_exact_at_every_phase():
    rng = np.random.default_rng(3)
    for s in (0.6, 1.0, 1.8):
        for _ in range(20):
            r0, c0 = 4 + rng.uniform(-0.5, 0.5, 2)
            row, col, sigma, width = fit_spot(_spot(r0, c0, s))
            assert abs(row - r0) < 0.01 and abs(col - c0) < 0.01, (s, r0, c0, row, col)
            assert sigma < 0.01  # no noise: only the model's tiny misfit
    # a spot within one pixel cannot be located better than its pixel: no fit, the caller says so
    assert fit_spot(_spot(4.2, 3.9, 0.15)) is None


def test_stated_sigma_matches_the_scatter_under_noise():
    rng = np.random.default_rng(4)
    clean = _spot(4.3, 3.8, 1.0)
    noise = 0.01 * clean.max()
    fits = np.array([fit_spot(clean + rng.normal(0.0, noise, clean.shape), noise) for _ in range(300)])
    scatter = np.sqrt(np.mean((fits[:, :2] - [4.3, 3.8]) ** 2))
    stated = np.sqrt(np.mean(fits[:, 2] ** 2))
    assert 0.7 < stated / scatter < 1.5, (stated, scatter)


def test_birge_bound_is_the_chi2_quantile():
    from scipy.stats import chi2

    out = birge_check(np.full((6, 3), 0.1), np.full((6, 3), 0.01))
    assert out["dof"] == 6 * 3
    assert out["birge_ratio"] == pytest.approx(1.0)
    assert out["bound"] == pytest.approx(np.sqrt(chi2.ppf(0.99, 18) / 18))
    assert not out["exceeds"] and out["scale"] == 1.0


SIZE, F, HC = 192, 480.0, 200.0


@pytest.fixture(scope="module")
def rendered():
    cam = synth_camera("perspective", SIZE, None, F, HC)
    _, true, _ = rig_lights(4, 45.0, 200.0, 90.0, 0.0, None, None)
    rng = np.random.default_rng(5)
    centres = [[-22.0, 12.0, 10.0], [20.0, -14.0, 10.0], [4.0, 22.0, 25.0]]
    renders = [render_mirror_sphere(cam, true, c, 10.0, highlight_samples=24, supersample=2, noise=0.002,
                                    bit_depth=16, seed=rng) for c in centres]
    return cam, true, renders


def _camera():
    return make_camera("perspective", focal_length_px=F, camera_height_mm=HC)


def test_honest_u_and_no_warning_when_the_geometry_is_right(rendered):
    _, true, renders = rendered
    sets = [SphereImages(r.images, r.center_mm, r.radius_mm, f"s{i}") for i, r in enumerate(renders)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        P, info = calibrate_positions(sets, _camera())
    err = np.abs(P - true.positions)
    u = np.array(info["uncertainty_mm"])
    assert np.mean(err <= 2.0 * u) >= 0.75, (err, u)
    assert info["birge_ratio"] <= info["birge_bound"] and info["uncertainty_scale"] >= 1.0
    assert info["dof"] == 4 * (2 * 3 - 3) and not info["warnings"]
    for sens in info["sensitivity"]:  # the triangulation's weak direction is along the ray
        assert sens["along_ray_mm"] >= sens["across_ray_mm"] > 0


def test_a_misplaced_sphere_warns_and_widens_u(rendered):
    """One centre 25 um off: the rays miss by about twice what the noise explains (beyond 3 times the
    calibration refuses)."""
    _, true, renders = rendered
    sets = [SphereImages(r.images, r.center_mm + [0.025 * (i == 0), 0.0, 0.0], r.radius_mm, f"s{i}")
            for i, r in enumerate(renders)]
    with pytest.warns(UserWarning, match="Birge ratio"):
        P, info = calibrate_positions(sets, _camera())
    assert info["birge_ratio"] > info["birge_bound"]
    scaled, raw = np.array(info["uncertainty_mm"]), np.array(info["uncertainty_from_noise_mm"])
    np.testing.assert_allclose(scaled, raw * info["birge_ratio"])
    assert info["warnings"] and "lens distortion" in info["warnings"][0]


def test_close_spheres_get_placement_advice(rendered):
    cam, true, _ = rendered
    near = [render_mirror_sphere(cam, true, c, 10.0, highlight_samples=24, supersample=2, noise=0.002, bit_depth=16)
            for c in ([-4.0, 0.0, 10.0], [4.0, 0.0, 10.0])]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, info = calibrate_positions([SphereImages(r.images, r.center_mm, r.radius_mm) for r in near], _camera())
    assert any("farther apart" in a for a in info["advice"]), info["advice"]
    assert any("third placement" in a for a in info["advice"])


def test_lens_option_moves_highlights_as_opencvs_model(rendered):
    """The renderer's lens (k1 only here): the highlights land at u_d = u (1 + k1 r^2) in normalised
    coordinates, written out by hand, and the fitted spots are found there."""
    cam, true, _ = rendered
    k1 = -0.3
    r = render_mirror_sphere(cam, true, [-22.0, 12.0, 10.0], 10.0, highlight_samples=24, supersample=2,
                             distortion=[k1, 0, 0, 0, 0])
    ideal = render_mirror_sphere(cam, true, [-22.0, 12.0, 10.0], 10.0, highlight_samples=24, supersample=2)
    c0 = (SIZE - 1) / 2.0
    x, y = (ideal.highlights_px[:, 1] - c0) / F, (ideal.highlights_px[:, 0] - c0) / F
    scale = 1.0 + k1 * (x * x + y * y)
    np.testing.assert_allclose(r.highlights_px[:, 1], c0 + F * x * scale, atol=1e-6)
    np.testing.assert_allclose(r.highlights_px[:, 0], c0 + F * y * scale, atol=1e-6)
    assert np.abs(r.highlights_px - ideal.highlights_px).max() > 0.3  # the lens moved them measurably
    rows, cols, _ = highlight_centroids(r.images, _camera(), r.center_mm, r.radius_mm)
    assert np.hypot(rows - r.highlights_px[:, 0], cols - r.highlights_px[:, 1]).max() < 0.05
