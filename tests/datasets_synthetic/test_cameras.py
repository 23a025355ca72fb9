"""Cameras: the contract's pixel rays, projection, vignetting, and the surface points rays meet."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.cameras import (
    intersect,
    orthographic_camera,
    perspective_camera,
    project,
    view_directions,
    vignetting_map,
)
from datasets_synthetic.heightfields import make_scene, plane, sphere_cap, tilted_plane


def _pixel_rays(shape, f, cx, cy):
    """Unit directions of the contract's pinhole rays, ((col - cx) / f, (cy - row) / f, -1) normalised."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    u = np.stack([(cols - cx) / f, (cy - rows) / f, -np.ones(shape)], axis=-1)
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


def test_orthographic_hits_are_the_height_field():
    hf = make_scene("plate", 64, 0.05, seed=3)
    hits = intersect(hf, orthographic_camera(64, 0.05))
    np.testing.assert_array_equal(hits.height, hf.height)
    np.testing.assert_array_equal(hits.normals, hf.normals)
    np.testing.assert_array_equal(hits.inside, hf.defect_mask)
    x, y = np.meshgrid((np.arange(64) - 31.5) * 0.05, (31.5 - np.arange(64)) * 0.05)
    np.testing.assert_array_equal(hits.xy, np.stack([x, y], axis=-1))


@pytest.mark.parametrize("slopes", [(0.0, 0.0), (0.2, -0.1)])
def test_perspective_hits_on_a_plane_are_the_closed_form(slopes):
    """Ray C + t (dx, dy, -1) meets z = sx x + sy y at t = H / (1 + sx dx + sy dy)."""
    h, w, f, height = 30, 40, 50.0, 200.0
    cam = perspective_camera((h, w), f, height, principal_point_px=(18.0, 16.5))
    hits = intersect(tilted_plane(8, 0.1, *slopes), cam)
    rows, cols = np.mgrid[0:h, 0:w].astype(float)
    dx, dy = (cols - 18.0) / f, (16.5 - rows) / f
    t = height / (1.0 + slopes[0] * dx + slopes[1] * dy)
    np.testing.assert_allclose(hits.points, np.stack([t * dx, t * dy, height - t], axis=-1), atol=1e-9)
    assert cam.reference_pixel_mm == height / f
    row, col = project(cam, hits.points)
    np.testing.assert_allclose(row, rows, atol=1e-9)
    np.testing.assert_allclose(col, cols, atol=1e-9)


@pytest.mark.parametrize("cap_mm, f, height", [(5.0, 1000.0, 300.0), (10.0, 150.0, 40.0)],
                         ids=["shallow", "hemisphere-wide-angle"])
def test_perspective_hits_on_a_sphere_cap_are_the_closed_form(cap_mm, f, height):
    """First root of |C + s u - S|^2 = R^2; rays up to 30 deg off axis cross the hemisphere twice (its bracket
    is marched), the shallow cap once."""
    shape, radius = (120, 140), 10.0
    cam = perspective_camera(shape, f, height)
    hits = intersect(sphere_cap(8, 0.1, radius_mm=radius, height_mm=cap_mm), cam)
    u = _pixel_rays(shape, f, (shape[1] - 1) / 2, (shape[0] - 1) / 2)
    oc = np.array([0.0, 0.0, height]) - np.array([0.0, 0.0, cap_mm - radius])
    b = u @ oc
    disc = b * b - (oc @ oc - radius**2)
    s = -b - np.sqrt(np.maximum(disc, 0.0))
    on_sphere = (disc > 0) & (height + s * u[..., 2] > 0)
    on_plane = -height / u[..., 2]
    expected = np.where(on_sphere[..., None], s[..., None] * u, on_plane[..., None] * u) + [0.0, 0.0, height]
    assert on_sphere.sum() > 500 and (~on_sphere).sum() > 500
    np.testing.assert_allclose(hits.points, expected, atol=1e-8)
    centre = np.array([0.0, 0.0, cap_mm - radius])
    normal = (hits.points - centre) / radius
    np.testing.assert_allclose(hits.normals[on_sphere], normal[on_sphere], atol=1e-8)
    np.testing.assert_array_equal(hits.inside, np.hypot(hits.points[..., 0], hits.points[..., 1])
                                  < np.sqrt(2 * radius * cap_mm - cap_mm**2))


@pytest.mark.slow
def test_perspective_hits_on_a_defect_plate_agree_with_open3d_ray_casting():
    """An independent implementation: Embree rays against a finely triangulated mesh of the scene."""
    import open3d as o3d

    hf = make_scene("plate", 128, 0.05, seed=2)  # crack, dent and scratch in a 6.4 mm field
    shape, height = (96, 112), 150.0
    f = height / 0.06
    hits = intersect(hf, perspective_camera(shape, f, height))
    step = 0.006
    axis = np.arange(-3.45, 3.45 + step / 2, step)  # the camera sees |x|, |y| < 3.4 mm
    x, y = np.meshgrid(axis, axis)
    z = hf.surface.evaluate(x, y)[0]
    n = axis.size
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    idx = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    tris = np.concatenate([np.column_stack([idx, idx + 1, idx + n]),
                           np.column_stack([idx + 1, idx + n + 1, idx + n])]).astype(np.uint32)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
    u = _pixel_rays(shape, f, (shape[1] - 1) / 2, (shape[0] - 1) / 2)
    start = np.array([0.0, 0.0, height]) + ((height - 1.0) / -u[..., 2])[..., None] * u  # on the ray at z = 1 mm
    rays = np.concatenate([start, u], axis=-1).reshape(-1, 6).astype(np.float32)
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().reshape(shape)
    theirs = start + t[..., None] * u
    dz = np.abs(hits.height - theirs[..., 2])
    assert hits.inside.mean() > 0.02  # the rays do cross the defects
    assert np.median(dz) < 2e-6 and np.quantile(dz, 0.99) < 1e-4
    assert dz.max() < 0.6 * step  # kinks: at most the wall slope times the mesh spacing
    np.testing.assert_allclose(hits.xy, theirs[..., :2], atol=1e-4)


def test_rays_views_and_projection_agree():
    cam = perspective_camera((20, 30), 40.0, 100.0)
    origins, d = cam.rays([0.0, 10.0], [0.0, 29.0])
    np.testing.assert_allclose(origins, [[0, 0, 100.0]] * 2)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0)
    points = origins + 60.0 * d
    row, col = project(cam, points)
    np.testing.assert_allclose(row, [0.0, 10.0], atol=1e-12)
    np.testing.assert_allclose(col, [0.0, 29.0], atol=1e-12)
    np.testing.assert_allclose(view_directions(cam, points), -d, atol=1e-12)
    ortho = orthographic_camera((4, 6), 0.5)
    o, d = ortho.rays(0.0, 0.0)
    np.testing.assert_allclose(o, [-1.25, 0.75, 0.0])
    np.testing.assert_allclose(d, [0, 0, -1.0])
    np.testing.assert_allclose(view_directions(ortho, [[1.0, 2.0, 3.0]]), [[0, 0, 1.0]])
    assert ortho.as_dict() == {"model": "orthographic", "pixel_size_mm": 0.5}
    assert cam.as_dict() == {"model": "perspective", "focal_length_px": 40.0, "camera_height_mm": 100.0,
                             "principal_point_px": [14.5, 9.5]}


def test_vignetting_models():
    cam = perspective_camera((21, 31), 25.0, 100.0)
    v = vignetting_map(cam, {"model": "cos4"})
    rows, cols = np.mgrid[0:21, 0:31]
    cos = 25.0 / np.sqrt(25.0**2 + (cols - 15.0) ** 2 + (rows - 10.0) ** 2)
    np.testing.assert_allclose(v, cos**4, rtol=1e-12)
    radial = vignetting_map(orthographic_camera((21, 31), 0.1), {"model": "radial", "coefficients": [-0.3, 0.05]})
    rho2 = ((cols - 15.0) ** 2 + (rows - 10.0) ** 2) / (15.0**2 + 10.0**2)
    np.testing.assert_allclose(radial, 1 - 0.3 * rho2 + 0.05 * rho2**2, rtol=1e-12)
    assert radial[10, 15] == 1.0 and radial[0, 0] == pytest.approx(0.75)
    np.testing.assert_array_equal(vignetting_map(cam, None), np.ones((21, 31)))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: perspective_camera(8, 0.0, 100.0), "focal_length_px"),
        (lambda: perspective_camera(8, 100.0, -5.0), "camera_height_mm"),
        (lambda: orthographic_camera(8, 0.0), "pixel_size_mm"),
        (lambda: intersect(sphere_cap(8, 1.0, radius_mm=10.0, height_mm=8.0), perspective_camera(8, 10.0, 7.0)),
         "above the part"),
        (lambda: intersect(tilted_plane(8, 0.1, -20.0, 0.0), perspective_camera(32, 10.0, 100.0)), "never meet"),
        (lambda: intersect(np.zeros((4, 4)), orthographic_camera(4, 0.1)), "surface"),
        (lambda: vignetting_map(orthographic_camera(8, 0.1), {"model": "cos4"}), "perspective"),
        (lambda: vignetting_map(orthographic_camera(8, 0.1), {"model": "radial", "coefficients": [-2.0]}),
         "non-positive"),
        (lambda: vignetting_map(orthographic_camera(8, 0.1), {"model": "fisheye"}), "vignetting"),
        (lambda: project(perspective_camera(8, 10.0, 50.0), [[0.0, 0.0, 60.0]]), "above the camera"),
    ],
)
def test_bad_input_is_a_clear_error(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_flat_plane_needs_no_root_finding_but_is_exact():
    hits = intersect(plane(4, 0.1, z0=-2.0), perspective_camera((5, 7), 10.0, 50.0))
    np.testing.assert_array_equal(hits.height, -2.0)
