"""photometric.calibrate: the geometry of mirror-sphere LED calibration, on closed forms.

Calibration from rendered mirror spheres (datasets_synthetic) is in test_nearfield_renders.py.
"""

import numpy as np
import pytest

from photometric.calibrate import (
    SphereImages,
    calibrate_positions,
    highlight_centroids,
    nearest_point,
    reflected_rays,
    sphere_from_outline,
)
from photometric.camera import make_camera, pixel_rays

ORTHO = make_camera("orthographic", pixel_size_mm=0.1)
PERSP = make_camera("perspective", focal_length_px=1200.0, camera_height_mm=300.0)


@pytest.mark.parametrize("cam", [ORTHO, PERSP], ids=["orthographic", "perspective"])
def test_reflected_rays_obey_the_law_of_reflection(cam):
    shape = (201, 241)
    centre, radius = np.array([1.0, -2.0, 6.0]), 6.0
    rows, cols = np.array([95.0, 100.3, 104.0]), np.array([120.0, 118.7, 126.2])
    S, r = reflected_rays(cam, shape, rows, cols, centre, radius)
    np.testing.assert_allclose(np.linalg.norm(S - centre, axis=1), radius)
    n = (S - centre) / radius
    _, d = pixel_rays(cam, shape, rows, cols)
    v = -d
    np.testing.assert_allclose(np.einsum("ki,ki->k", n, v), np.einsum("ki,ki->k", n, r))  # equal angles
    np.testing.assert_allclose(np.einsum("ki,ki->k", np.cross(n, v), r), 0.0, atol=1e-12)  # coplanar
    assert np.all(np.einsum("ki,ki->k", n, v) > 0)  # the visible side
    with pytest.raises(ValueError, match="misses the sphere"):
        reflected_rays(cam, shape, [0.0], [0.0], centre, radius)


def test_nearest_point_of_rays():
    P = np.array([30.0, -40.0, 150.0])
    S = np.array([[0.0, 0.0, 5.0], [10.0, 3.0, 4.0], [-8.0, 2.0, 6.0]])
    r = (P - S) / np.linalg.norm(P - S, axis=1, keepdims=True)
    est, dist = nearest_point(S, r)
    np.testing.assert_allclose(est, P, atol=1e-9)
    np.testing.assert_allclose(dist, 0.0, atol=1e-9)
    # a ray moved sideways by 1 mm leaves residuals and a point between
    est, dist = nearest_point(S[:2] + [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], r[:2])
    assert 0.3 < dist.max() < 1.0
    with pytest.raises(ValueError, match="parallel"):
        nearest_point(S[:2], [[0, 0, 1.0], [0, 0, 1.0]])


def _blob_images(shape, centres, sigma=1.2, level=0.8, noise=0.002, seed=0):
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    out = []
    for r0, c0 in centres:
        img = 0.05 + 0.02 * cols / shape[1]  # a weak diffuse slope
        img = img + level * np.exp(-((rows - r0) ** 2 + (cols - c0) ** 2) / (2 * sigma**2))
        out.append(img + rng.normal(0, noise, shape))
    return np.array(out, np.float32)


def test_highlight_centroids_are_sub_pixel():
    shape = (120, 140)
    truth = [(50.3, 62.7), (71.55, 80.1), (59.0, 55.25)]
    images = _blob_images(shape, truth)
    # sphere of radius 4 mm centred at the image centre: disc radius 40 px
    rows, cols, sigma = highlight_centroids(images, ORTHO, [0.0, 0.0, 4.0], 4.0)
    np.testing.assert_allclose(np.stack([rows, cols], 1), truth, atol=0.03)
    assert np.all(sigma > 0) and np.all(sigma < 0.1)
    with pytest.raises(ValueError, match="no highlight"):
        highlight_centroids(np.zeros((1,) + shape, np.float32), ORTHO, [0.0, 0.0, 4.0], 4.0)


def test_calibrate_positions_from_exact_highlights(monkeypatch):
    """Centroids placed where two spheres reflect known LEDs give those LEDs back."""
    from photometric import calibrate as cal

    leds = np.array([[100.0, 0.0, 180.0], [-60.0, 90.0, 170.0], [-60.0, -90.0, 190.0]])
    spheres = [(np.array([-12.0, 0.0, 5.0]), 5.0), (np.array([12.0, 4.0, 5.0]), 5.0)]
    shape = (301, 361)

    def miss(rr, cc, centre, radius, led):
        origins, d = pixel_rays(ORTHO, shape, rr, cc)
        oc = origins - centre
        b = np.einsum("ki,ki->k", d, oc)
        hit = b * b - (np.einsum("ki,ki->k", oc, oc) - radius**2) > 0
        out = np.full(rr.shape, np.inf)
        S, r = reflected_rays(ORTHO, shape, rr[hit], cc[hit], centre, radius)
        out[hit] = np.linalg.norm(np.cross(led - S, r), axis=1)
        return out

    def specular_pixel(centre, radius, led):
        """The point of the sphere whose reflected ray hits the LED (grid search, then refined)."""
        r0, c0, step, half = 150.0 - centre[1] / 0.1, 180.0 + centre[0] / 0.1, 0.5, radius / 0.1
        for _ in range(4):
            rr, cc = np.mgrid[r0 - half : r0 + half : step, c0 - half : c0 + half : step]
            best = np.argmin(miss(rr.ravel(), cc.ravel(), centre, radius, led))
            r0, c0, half, step = rr.ravel()[best], cc.ravel()[best], 2 * step, step / 10
        return r0, c0

    pix = np.array([[specular_pixel(c, R, led) for led in leds] for c, R in spheres])  # (2, 3, 2)
    monkeypatch.setattr(cal, "highlight_centroids",
                        lambda images, camera, centre, radius, window_px: (
                            pix[int(centre[0] > 0), :, 0], pix[int(centre[0] > 0), :, 1], np.full(3, 0.05)))
    sets = [SphereImages(np.zeros((3,) + shape, np.float32), c, R, f"s{i}") for i, (c, R) in enumerate(spheres)]
    positions, info = calibrate_positions(sets, ORTHO)
    np.testing.assert_allclose(positions, leds, atol=0.05)
    assert np.max(info["residuals_mm"]) < 0.01
    assert len(info["uncertainty_mm"]) == 3 and all(len(u) == 3 for u in info["uncertainty_mm"])
    with pytest.raises(ValueError, match="at least 2 calibration sets"):
        calibrate_positions(sets[:1], ORTHO)


@pytest.mark.parametrize("cam", [ORTHO, PERSP], ids=["orthographic", "perspective"])
def test_sphere_from_outline(cam):
    shape = (161, 181)
    centre, radius = np.array([1.5, -0.8, 5.0]), 5.0
    rr, cc = np.mgrid[0 : shape[0], 0 : shape[1]]
    origins, d = pixel_rays(cam, shape, rr.ravel().astype(float), cc.ravel().astype(float))
    oc = origins - centre
    b = np.einsum("ki,ki->k", d, oc)
    inside = (b * b - (np.einsum("ki,ki->k", oc, oc) - radius**2) > 0).reshape(shape)
    images = np.where(inside, 0.4, 0.02)[None].repeat(3, axis=0).astype(np.float32)
    c, r = sphere_from_outline(images, cam)
    assert r == pytest.approx(radius, rel=0.02)
    np.testing.assert_allclose(c, centre, atol=0.1 * (1 if cam is ORTHO else 3))
    with pytest.raises(ValueError, match="sphere.json"):
        sphere_from_outline(np.zeros((3, 20, 20), np.float32), cam)
