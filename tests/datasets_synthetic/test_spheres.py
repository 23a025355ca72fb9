"""Mirror-sphere calibration images: highlights where the law of reflection puts them, folders, errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import minimize

from datasets_synthetic.cameras import orthographic_camera, perspective_camera
from datasets_synthetic.point_lights import point_lights, ring_point_lights
from datasets_synthetic.spheres import make_sphere_folders, reflection_points, render_mirror_sphere
from photometric.io import read_images

CAMERAS = {
    "orthographic": lambda: orthographic_camera((200, 240), 0.12),
    "perspective": lambda: perspective_camera((200, 240), 2500.0, 300.0),
}
CENTRE = np.array([4.0, -3.0, 10.0])
RADIUS = 10.0


def _fermat_point(camera, led, centre, radius):
    """Independent: the point of the sphere with the shortest light path camera -> X -> LED (Fermat)."""
    def point(angles):
        theta, phi = angles
        return centre + radius * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])

    def path(angles):
        x = point(angles)
        to_camera = -x[2] if camera.model == "orthographic" else np.linalg.norm([0, 0, camera.camera_height_mm] - x)
        return to_camera + np.linalg.norm(led - x)

    guess = led - centre
    guess = guess / np.linalg.norm(guess) + [0.0, 0.0, 1.0]
    start = [np.arccos(guess[2] / np.linalg.norm(guess)), np.arctan2(guess[1], guess[0])]
    best = minimize(path, start, method="Nelder-Mead", options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 4000})
    return point(best.x)


def _pixel(camera, x):
    """The contract's projection, written out."""
    h, w = camera.shape
    if camera.model == "orthographic":
        return (h - 1) / 2 - x[1] / camera.pixel_size_mm, x[0] / camera.pixel_size_mm + (w - 1) / 2
    cx, cy = camera.principal_point_px
    depth = camera.camera_height_mm - x[2]
    return cy - camera.focal_length_px * x[1] / depth, cx + camera.focal_length_px * x[0] / depth


@pytest.mark.parametrize("model", CAMERAS)
def test_reflection_points_obey_fermat_and_bisect(model):
    camera = CAMERAS[model]()
    lights = point_lights([[0.0, 141.4, 141.4], [-120.0, -50.0, 160.0], [30.0, 0.0, 220.0], [5.0, -3.0, 300.0]])
    points = reflection_points(camera, lights, CENTRE, RADIUS)
    for x, led in zip(points, lights.positions):
        np.testing.assert_allclose(x, _fermat_point(camera, led, CENTRE, RADIUS), atol=1e-5)
        normal = (x - CENTRE) / RADIUS
        view = np.array([0, 0, 1.0]) if model == "orthographic" else np.array([0, 0, 300.0]) - x
        bisector = view / np.linalg.norm(view) + (led - x) / np.linalg.norm(led - x)
        np.testing.assert_allclose(normal, bisector / np.linalg.norm(bisector), atol=1e-9)


@pytest.mark.parametrize("model", CAMERAS)
@pytest.mark.parametrize("led_radius", [0.5, 2.0])
def test_highlight_centroid_is_the_reflection_point(model, led_radius):
    """The intensity centroid of each highlight lies within 0.02 px of the law-of-reflection point."""
    camera = CAMERAS[model]()
    lights = ring_point_lights(4, 40.0, 200.0, azimuth0_deg=20.0, mu=1.0)
    out = render_mirror_sphere(camera, lights, CENTRE, RADIUS, led_radius_mm=led_radius, diffuse=0.0)
    rows, cols = np.mgrid[0:200, 0:240]
    for k, led in enumerate(lights.positions):
        img = out.images[k].astype(np.float64)
        assert img.max() > 0.3 and np.count_nonzero(img) < 400  # a small bright blob
        centroid = np.array([(img * rows).sum(), (img * cols).sum()]) / img.sum()
        expected = _pixel(camera, _fermat_point(camera, led, CENTRE, RADIUS))
        np.testing.assert_allclose(centroid, expected, atol=0.02)
        np.testing.assert_allclose(out.highlights_px[k], expected, atol=1e-4)
    assert out.images.max() == pytest.approx(0.9, rel=1e-6)


def test_a_larger_led_gives_a_larger_highlight_and_the_outline_shows():
    close = orthographic_camera((120, 120), 0.01)  # 1.2 mm of the sphere's top
    top = ring_point_lights(3, 5.0, 200.0)
    small = render_mirror_sphere(close, top, [0, 0, 10], RADIUS, led_radius_mm=0.5, psf_sigma_px=0.0, diffuse=0.0)
    large = render_mirror_sphere(close, top, [0, 0, 10], RADIUS, led_radius_mm=3.0, psf_sigma_px=0.0, diffuse=0.0)
    # the highlight is the LED seen in a convex mirror: about R rho / (2 D) = 0.075 mm across for rho = 3 mm
    area = np.count_nonzero(large.images[0]) * 0.01**2
    assert area == pytest.approx(np.pi * (10.0 * 3.0 / 400.0) ** 2, rel=0.35)
    assert np.count_nonzero(large.images[0]) > 10 * np.count_nonzero(small.images[0])  # area ratio 36
    camera = CAMERAS["perspective"]()
    lights = ring_point_lights(3, 45.0, 200.0)
    shaded = render_mirror_sphere(camera, lights, CENTRE, RADIUS, diffuse=0.05, background=0.0)
    rows, cols = np.mgrid[0:200, 0:240]
    seen = np.zeros((200, 240, 3))
    seen[..., 0] = (cols - 119.5) * 300.0 / 2500.0
    seen[..., 1] = (99.5 - rows) * 300.0 / 2500.0
    # pixels whose ray meets the sphere: distance of the ray from the centre below R
    u = np.stack([(cols - 119.5) / 2500.0, (99.5 - rows) / 2500.0, -np.ones((200, 240))], axis=-1)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    oc = np.array([0.0, 0.0, 300.0]) - CENTRE
    miss = np.linalg.norm(np.cross(u, oc), axis=-1)
    on = miss < RADIUS - 0.2
    off = miss > RADIUS + 0.2
    lit_face = on & (shaded.images.max(axis=0) > 0)
    assert lit_face.sum() > 0.5 * on.sum() and np.all(shaded.images[:, off] == 0)
    assert 0.9 < shaded.images.max() < 1.0  # the highlight term is 0.9, the weak diffuse term adds to it
    assert 0 < np.median(shaded.images[0][lit_face]) < 0.1  # the diffuse term is weak


def test_background_plane_is_shadowed_by_the_sphere():
    camera = orthographic_camera((120, 120), 0.4)
    lights = point_lights([[100.0, 0.0, 60.0]])
    out = render_mirror_sphere(camera, lights, [0.0, 0.0, 10.0], 10.0, background=0.3, diffuse=0.05)
    img = out.images[0]
    # far from the sphere on the LED's side the plane is lit; behind the sphere (x < -12 mm, y = 0) it is dark
    assert img[60, 110] > 0.05 and img[60, 20] == 0.0 and img[10, 20] > 0.05


def test_sphere_folders_layout(tmp_path):
    scene = make_sphere_folders(tmp_path, [[-15.0, 10.0, 10.0], [15.0, -10.0, 10.0], [0.0, 0.0, 30.0]], 10.0,
                                size=(96, 128), lights=4, light_distance=200.0, camera="perspective",
                                focal_length_px=600.0, camera_height=300.0, deviate=[1.0, 0.0, 0.0, 0.0],
                                noise=0.001, supersample=2, highlight_samples=32)
    assert [s["folder"] for s in scene["spheres"]] == ["sphere_01", "sphere_02", "sphere_03"]
    top = json.loads((tmp_path / "scene.json").read_text())
    assert top["camera"] == {"model": "perspective", "focal_length_px": 600.0, "camera_height_mm": 300.0,
                             "principal_point_px": [63.5, 47.5]}
    true = np.asarray(top["lights"]["positions_mm"])
    assert np.degrees(np.arccos(true[0, 2] / 200.0)) == pytest.approx(46.0)
    np.testing.assert_allclose(top["light_positions_nominal_mm"], ring_point_lights(4, 45.0, 200.0).positions)
    for m, centre in enumerate([[-15.0, 10.0, 10.0], [15.0, -10.0, 10.0], [0.0, 0.0, 30.0]]):
        folder = tmp_path / f"sphere_{m + 1:02d}"
        names = (folder / "filenames.txt").read_text().split()
        assert names == ["001.png", "002.png", "003.png", "004.png"]
        assert json.loads((folder / "sphere.json").read_text()) == {"radius_mm": 10.0, "center_mm": centre}
        inner = json.loads((folder / "scene.json").read_text())
        assert inner["camera"] == top["camera"] and inner["led_radius_mm"] == 1.0
        images = read_images([folder / n for n in names])
        assert images.shape == (4, 96, 128) and images.max() > 0.5
        for k, (row, col) in enumerate(inner["highlights_px"]):
            r, c = int(round(row)), int(round(col))
            assert images[k, r - 1:r + 2, c - 1:c + 2].max() == images[k].max()  # the brightest spot


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: render_mirror_sphere(orthographic_camera(32, 1.0), ring_point_lights(3, 45, 100), [0, 0, 5], 10.0),
         "cuts the reference plane"),
        (lambda: render_mirror_sphere(perspective_camera(32, 100.0, 15.0), ring_point_lights(3, 45, 100),
                                      [0, 0, 10], 10.0), "above the sphere"),
        (lambda: render_mirror_sphere(orthographic_camera(32, 1.0), point_lights([[0, 0, 15.0]]), [0, 0, 10], 10.0),
         "inside the sphere"),
        (lambda: render_mirror_sphere(orthographic_camera(32, 1.0), ring_point_lights(3, 45, 100), [0, 0, 10], 10.0,
                                      supersample=0), "supersample"),
        (lambda: render_mirror_sphere(orthographic_camera(32, 1.0), ring_point_lights(3, 45, 100), [500, 0, 10],
                                      10.0), "no LED highlight falls inside the image"),
        (lambda: make_sphere_folders("/tmp/unused", [[0, 0, 10]], 10.0, size=32, camera="perspective"),
         "focal_length_px"),
        (lambda: make_sphere_folders("/tmp/unused", [0, 0, 10], 10.0, size=32), "centers"),
    ],
)
def test_bad_input_is_a_clear_error(call, message):
    with pytest.raises(ValueError, match=message):
        call()
