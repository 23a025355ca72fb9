"""photometric.nearfield: point lights and perspective cameras, checked on closed-form planes.

A plane under point lights has a closed-form image (written out here, independently of
photometric.leds.light_field); rendered scenes (sphere cap, defect plate) come from
datasets_synthetic in test_nearfield_renders.py.
"""

import numpy as np
import pytest

from photometric.camera import make_camera, pixel_offsets
from photometric.leds import light_field, point_lights
from photometric.nearfield import NotConvergedError, solve_nearfield
from photometric.rig import flat_field_gains

ORTHO = make_camera("orthographic", pixel_size_mm=0.4)
PERSP = make_camera("perspective", focal_length_px=700.0, camera_height_mm=280.0)


def ring(n, slant_deg, distance, azimuth0=90.0):
    a = np.radians(azimuth0 + 360.0 * np.arange(n) / n)
    s = np.radians(slant_deg)
    return distance * np.stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.full(n, np.cos(s))], axis=1)


def plane_points_and_normal(cam, shape, slope):
    """Points of the plane z = slope * x seen by each pixel, and its unit normal."""
    u, v = pixel_offsets(cam, shape)
    if cam.model == "orthographic":
        x, y = np.meshgrid(u, v)
        X = np.stack([x, y, slope * x], axis=-1)
    else:
        f, H = cam.focal_length_px, cam.camera_height_mm
        w = H / (1.0 + slope * u[None, :] / f) * np.ones((shape[0], 1))
        X = np.stack([u[None, :] * w / f, v[:, None] * w / f, H - w], axis=-1)
    return X, np.array([-slope, 0.0, 1.0]) / np.hypot(slope, 1.0)


def plane_images(positions, X, n, albedo=0.8, e=None, mu=0.0, vignetting=None):
    """I_k = albedo e_k (d0 / r)^2 cos_lobe^mu max(0, n . d / r): the contract's model, written out."""
    out = []
    for k, P in enumerate(np.asarray(positions, float)):
        d = P - X
        r = np.linalg.norm(d, axis=-1)
        d0 = np.linalg.norm(P)
        lobe = np.clip((d @ P) / (r * d0), 0, None) ** mu  # axis aimed at the origin
        ek = 1.0 if e is None else e[k]
        img = albedo * ek * (d0 / r) ** 2 * lobe * np.clip(d @ n / r, 0, None)
        out.append(img if vignetting is None else img * vignetting)
    return np.array(out, np.float32)


def test_light_field_is_the_closed_form():
    pos = ring(3, 40, 200.0)
    X, n = plane_points_and_normal(ORTHO, (9, 11), 0.1)
    s = light_field(point_lights(pos, mu=1.5), X, [1.0, 2.0, 0.5])
    np.testing.assert_allclose(s @ n, plane_images(pos, X, n, 1.0, [1.0, 2.0, 0.5], 1.5), rtol=2e-6)


@pytest.mark.parametrize("cam", [ORTHO, PERSP], ids=["orthographic", "perspective"])
@pytest.mark.parametrize("slope", [0.0, 0.12])
def test_plane_recovered(cam, slope):
    shape = (61, 81)
    pos = ring(3, 45, 150.0)
    X, n = plane_points_and_normal(cam, shape, slope)
    images = plane_images(pos, X, n)
    res = solve_nearfield(images, point_lights(pos), cam, tolerance_mm=1e-5)
    assert res.valid.all()
    np.testing.assert_allclose(res.normals, np.broadcast_to(n, res.normals.shape), atol=2e-5)
    np.testing.assert_allclose(res.albedo, 0.8, rtol=2e-5)
    np.testing.assert_allclose(res.p, -n[0] / n[2], atol=3e-5)
    # the median pixel sees z = 0, so the anchor puts the plane where it is
    np.testing.assert_allclose(res.height, X[..., 2], atol=2e-4)
    np.testing.assert_allclose(res.xy, X[..., :2], atol=2e-4)
    assert res.depth_change_mm < 1e-5 and res.iterations == len(res.history) >= 1
    assert res.anchor["reference_height_mm"] == 0.0


def test_far_field_model_bends_the_plane():
    """What the model buys: the same images solved with directions from the origin give a bowl."""
    shape = (61, 81)
    pos = ring(3, 45, 150.0)
    X, n = plane_points_and_normal(ORTHO, shape, 0.0)
    images = plane_images(pos, X, n)
    far = solve_nearfield(images, pos / np.linalg.norm(pos, axis=1, keepdims=True), ORTHO)
    near = solve_nearfield(images, point_lights(pos), ORTHO)
    bowl = np.nanmax(far.height) - np.nanmin(far.height)
    assert bowl > 0.5 and far.depth_change_mm is None and far.iterations == 1
    assert np.nanmax(np.abs(near.height)) < 1e-3


def test_lobe_and_intensities_and_colour():
    shape = (41, 41)
    cam = make_camera("orthographic", pixel_size_mm=1.5)
    pos = ring(4, 35, 180.0)
    X, n = plane_points_and_normal(cam, shape, -0.1)
    e = np.array([1.0, 1.3, 0.7, 1.1])
    grey = plane_images(pos, X, n, 0.6, e, mu=2.0)
    rgb = np.stack([grey, 0.5 * grey, 0.25 * grey], axis=-1)  # albedo (0.6, 0.3, 0.15)
    res = solve_nearfield(rgb, point_lights(pos, mu=2.0), cam, intensities=e, tolerance_mm=1e-5)
    np.testing.assert_allclose(res.normals, np.broadcast_to(n, res.normals.shape), atol=3e-5)
    assert res.albedo.shape == shape + (3,)
    np.testing.assert_allclose(res.albedo, np.broadcast_to([0.6, 0.3, 0.15], res.albedo.shape), rtol=1e-4)
    # the wrong lobe tilts the normals
    wrong = solve_nearfield(grey, point_lights(pos), cam, intensities=e)
    assert np.abs(wrong.normals - n).max() > 5e-3


@pytest.mark.parametrize("cam", [ORTHO, PERSP], ids=["orthographic", "perspective"])
def test_flat_field_round_trip(cam):
    """Gains from a flat target measure lobe, vignetting and unequal power; mu need not be known."""
    shape = (51, 71)
    pos = ring(3, 45, 160.0)
    e = np.array([1.0, 0.8, 1.25])
    rr, cc = np.mgrid[0:shape[0], 0:shape[1]]
    vignetting = 1.0 - 0.3 * (((rr - 25) / 50.0) ** 2 + ((cc - 35) / 70.0) ** 2)
    X0, z_hat = plane_points_and_normal(cam, shape, 0.0)
    flats = plane_images(pos, X0, z_hat, 0.9, e, mu=1.5, vignetting=vignetting)
    X, n = plane_points_and_normal(cam, shape, 0.08)
    images = plane_images(pos, X, n, 0.45, e, mu=1.5, vignetting=vignetting)
    unknown_mu = point_lights(pos)
    gains = flat_field_gains(flats, unknown_mu, cam, 0.9, smoothing_px=0)
    res = solve_nearfield(images, unknown_mu, cam, gains=gains, tolerance_mm=1e-5)
    # off the plane only the lobe ratio is not modelled: a fraction of a degree over 6 mm of height
    assert np.degrees(np.arccos(np.clip(res.normals @ n, -1, 1))).max() < 0.05
    np.testing.assert_allclose(res.albedo, 0.45, rtol=3e-3)
    np.testing.assert_allclose(res.height, X[..., 2], atol=0.01)
    # mu known: the lobe ratio is carried too, exact
    known = solve_nearfield(images, point_lights(pos, mu=1.5), cam, gains=gains, tolerance_mm=1e-5)
    np.testing.assert_allclose(known.normals, np.broadcast_to(n, known.normals.shape), atol=3e-5)
    # without the flat field the unequal powers and vignetting are wrong
    plain = solve_nearfield(images, point_lights(pos, mu=1.5), cam)
    assert np.degrees(np.arccos(np.clip(plain.normals @ n, -1, 1))).max() > 1.0


def test_coarse_stage_reaches_the_same_surface():
    shape = (96, 128)
    pos = ring(4, 45, 150.0)
    X, n = plane_points_and_normal(PERSP, shape, 0.1)
    images = plane_images(pos, X, n)
    direct = solve_nearfield(images, point_lights(pos), PERSP, tolerance_mm=1e-5)
    staged = solve_nearfield(images, point_lights(pos), PERSP, tolerance_mm=1e-5, coarse_pixels=768)
    assert [h["level"] for h in staged.history][0] == "coarse" and staged.history[-1]["level"] == "full"
    assert {h["step"] for h in staged.history} == {1, 4}
    np.testing.assert_allclose(staged.height, direct.height, atol=1e-4)


def test_outliers_are_dropped_with_four_lights_and_invalid_with_three():
    shape = (40, 40)
    pos = ring(4, 45, 150.0)
    X, n = plane_points_and_normal(ORTHO, shape, 0.05)
    images = plane_images(pos, X, n)
    images[1, 10:20, 10:20] = 0.0  # a cast shadow in image 1
    images[2, 25:30, 25:35] = 1.0  # saturation in image 2
    res = solve_nearfield(images, point_lights(pos), ORTHO, outliers=True)
    assert res.valid.all()
    np.testing.assert_allclose(res.normals, np.broadcast_to(n, res.normals.shape), atol=5e-5)
    assert res.outliers[1, 10:20, 10:20].all() and res.outliers[2, 25:30, 25:35].all()
    assert res.outliers.sum() == 100 + 50
    plain = solve_nearfield(images, point_lights(pos), ORTHO)
    assert np.abs(plain.normals[12, 12] - n).max() > 0.05
    triad = solve_nearfield(images[:3], point_lights(pos[:3]), ORTHO, outliers=True)
    assert not triad.valid[10:20, 10:20].any() and triad.valid[0:5].all()


def test_mask_and_residual():
    shape = (30, 30)
    pos = ring(5, 45, 150.0)
    X, n = plane_points_and_normal(ORTHO, shape, 0.0)
    images = plane_images(pos, X, n)
    mask = np.zeros(shape, bool)
    mask[5:25, 3:28] = True
    res = solve_nearfield(images, point_lights(pos), ORTHO, mask=mask)
    assert np.array_equal(res.valid, mask)
    assert np.isnan(res.height[~mask]).all() and np.all(res.albedo[~mask] == 0)
    assert np.all(res.normals[~mask] == (0, 0, 1))
    assert res.residual[mask].max() < 1e-5


def test_no_convergence_raises_with_the_history():
    shape = (40, 40)
    pos = ring(3, 45, 60.0)
    X, n = plane_points_and_normal(ORTHO, shape, 0.3)
    images = plane_images(pos, X, n)
    with pytest.raises(NotConvergedError, match="did not converge") as info:
        solve_nearfield(images, point_lights(pos), ORTHO, max_iterations=2, tolerance_mm=1e-9)
    summary = info.value.summary
    assert summary["converged"] is False and summary["iterations"] == 2
    assert len(summary["history"]) == 2 and summary["final_depth_change_mm"] > 1e-9


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"gains": np.ones((3, 10, 12))}, "gains: a flat field needs point lights"),
        ({"integrator": "magic"}, "integrator"),
        ({"tolerance_mm": 0.0}, "tolerance_mm"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"mask": np.zeros((10, 12), bool)}, "no pixel"),
    ],
)
def test_bad_input(kwargs, message):
    images = np.ones((3, 10, 12), np.float32)
    lights = ring(3, 45, 1.0)
    with pytest.raises(ValueError, match=message):
        solve_nearfield(images, lights, ORTHO, **kwargs)


def test_bad_point_light_input():
    images = np.ones((3, 10, 12), np.float32)
    with pytest.raises(ValueError, match="4 LED positions for 3 images"):
        solve_nearfield(images, point_lights(ring(4, 45, 100.0)), ORTHO)
    with pytest.raises(ValueError, match="gains: expected shape"):
        solve_nearfield(images, point_lights(ring(3, 45, 100.0)), ORTHO, gains=np.ones((3, 10, 10)))
    with pytest.raises(ValueError, match="not below every light"):
        solve_nearfield(images, point_lights(ring(3, 45, 100.0)), ORTHO, reference_height_mm=80.0)
    with pytest.raises(ValueError, match="not below the camera"):
        solve_nearfield(images, point_lights(ring(3, 45, 100.0)), PERSP, reference_height_mm=300.0)
