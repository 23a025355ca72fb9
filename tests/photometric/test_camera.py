"""photometric.camera: orthographic and perspective cameras of the near-field rig."""

import numpy as np
import pytest

from photometric.camera import (
    Orthographic,
    Perspective,
    camera_from_dict,
    depth_from_field,
    footprint_area,
    gradient_field,
    make_camera,
    pixel_offsets,
    pixel_rays,
    plane_points,
    surface_xy,
)
from photometric.integrate import dct_poisson
from surfaces.grid import pixel_grid

PERSP = make_camera("perspective", focal_length_px=800.0, camera_height_mm=250.0)


def tilted_plane_perspective(cam, shape, slope):
    """z = slope * x seen by a pinhole: w (1 + slope u / f) = H, so w = H / (1 + slope u / f)."""
    u, v = pixel_offsets(cam, shape)
    w = cam.camera_height_mm / (1.0 + slope * u[None, :] / cam.focal_length_px) * np.ones((shape[0], 1))
    return cam.camera_height_mm - w, w


def test_orthographic_grid_is_the_project_grid():
    cam = make_camera("orthographic", pixel_size_mm=0.25)
    xy = surface_xy(cam, np.full((5, 7), 3.0))
    x, y = pixel_grid((5, 7), 0.25)
    np.testing.assert_array_equal(xy[..., 0], x)
    np.testing.assert_array_equal(xy[..., 1], y)
    X = plane_points(cam, (5, 7))
    assert np.all(X[..., 2] == 0)
    assert footprint_area(cam, np.zeros((5, 7))) == pytest.approx(0.0625)


def test_perspective_rays_and_points():
    """Pixel (row, col) sees the ray from C through ((col - cx) / f, (cy - row) / f, -1)."""
    shape = (41, 61)
    cx, cy = (61 - 1) / 2, (41 - 1) / 2
    z = np.random.default_rng(0).uniform(-2, 2, shape)
    xy = surface_xy(PERSP, z)
    rows, cols = np.mgrid[0:41, 0:61]
    w = 250.0 - z
    np.testing.assert_allclose(xy[..., 0], (cols - cx) / 800.0 * w)
    np.testing.assert_allclose(xy[..., 1], (cy - rows) / 800.0 * w)
    origin, d = pixel_rays(PERSP, shape, [3.25, 20.0], [7.5, 30.0])
    np.testing.assert_allclose(origin, [[0, 0, 250.0]] * 2)
    expect = np.array([[(7.5 - cx) / 800, (cy - 3.25) / 800, -1.0], [0, 0, -1.0]])
    np.testing.assert_allclose(d, expect / np.linalg.norm(expect, axis=1, keepdims=True))
    # the reference plane is seen at H / f mm per pixel at the principal point
    X = plane_points(PERSP, shape)
    assert X[20, 31, 0] - X[20, 30, 0] == pytest.approx(250.0 / 800.0)
    assert PERSP.nominal_pixel_mm() == pytest.approx(250.0 / 800.0)


def test_principal_point_moves_the_axis():
    cam = make_camera("perspective", focal_length_px=500.0, camera_height_mm=100.0, principal_point_px=(2.0, 1.0))
    xy = surface_xy(cam, np.zeros((4, 6)))
    assert xy[1, 2].tolist() == [0.0, 0.0]
    assert cam.to_dict() == {"model": "perspective", "focal_length_px": 500.0, "camera_height_mm": 100.0,
                             "principal_point_px": [2.0, 1.0]}
    assert camera_from_dict(cam.to_dict()) == cam


@pytest.mark.parametrize("slope", [0.0, 0.15, -0.3])
def test_log_depth_gradient_of_a_tilted_plane(slope):
    """The perspective field l = log w of a plane z = slope x has l_u = -(slope / f) / (1 + slope u / f)."""
    shape = (33, 45)
    z, w = tilted_plane_perspective(PERSP, shape, slope)
    n = np.broadcast_to(np.array([-slope, 0.0, 1.0]) / np.hypot(slope, 1.0), shape + (3,))
    p, q, spacing = gradient_field(PERSP, n)
    u, _ = pixel_offsets(PERSP, shape)
    f = PERSP.focal_length_px
    expect = -(slope / f) / (1.0 + slope * u / f)
    np.testing.assert_allclose(p, np.broadcast_to(expect, shape), rtol=2e-5, atol=1e-10)
    np.testing.assert_allclose(q, 0.0, atol=1e-10)
    assert spacing == 1.0
    # integrate log w and anchor: the plane comes back (odd width: the median pixel sees z = 0)
    fld = dct_poisson(p, q, None, spacing)
    z_back, _ = depth_from_field(PERSP, fld)
    np.testing.assert_allclose(z_back, z, atol=2e-4)


def test_depth_anchor_rule_median_at_the_reference_height():
    cam = make_camera("orthographic", pixel_size_mm=0.1)
    fld = np.zeros((10, 10))
    fld[:3] = -5.0  # a deep groove over 30 % of the pixels does not move the median
    z, c = depth_from_field(cam, fld, reference_height_mm=1.5)
    assert np.median(z) == pytest.approx(1.5) and c == pytest.approx(1.5)
    valid = np.zeros((10, 10), bool)
    valid[:3] = True
    z, _ = depth_from_field(cam, fld, valid=valid)
    assert z[0, 0] == pytest.approx(0.0)
    zp, _ = depth_from_field(PERSP, np.log(np.full((4, 4), 7.0)), reference_height_mm=-2.0)
    np.testing.assert_allclose(zp, -2.0)



@pytest.mark.parametrize("cam", [make_camera("orthographic", pixel_size_mm=0.1), PERSP], ids=["ortho", "persp"])
def test_depth_from_field_float32_is_the_float64_heights_rounded_once(cam):
    """A float32 field gives the heights of its float64 copy (same constant, same sampled median);
    ``dtype=float32`` rounds each of them once."""
    rng = np.random.default_rng(2)
    fld = rng.normal(0.0, 0.05, (41, 37)).astype(np.float32)
    if isinstance(cam, Perspective):
        fld += np.float32(np.log(250.0))
    fld[3, 4] = np.nan
    valid = rng.random(fld.shape) > 0.2
    z64, c64 = depth_from_field(cam, fld.astype(np.float64), valid=valid, reference_height_mm=0.3, sample_step=3)
    z, c = depth_from_field(cam, fld, valid=valid, reference_height_mm=0.3, sample_step=3)
    z32, c32 = depth_from_field(cam, fld, valid=valid, reference_height_mm=0.3, sample_step=3, dtype=np.float32)
    assert c == c64 == c32 and z.dtype == np.float64 and z32.dtype == np.float32
    np.testing.assert_array_equal(z, z64)
    np.testing.assert_array_equal(z32, z64.astype(np.float32))
    assert np.isnan(z32[3, 4])
    with pytest.raises(ValueError, match="dtype"):
        depth_from_field(cam, fld, dtype=np.int32)

def test_footprint_area_is_the_jacobian_of_the_points():
    shape = (21, 31)
    z, w = tilted_plane_perspective(PERSP, shape, 0.2)
    n = np.broadcast_to(np.array([-0.2, 0.0, 1.0]) / np.hypot(0.2, 1.0), shape + (3,))
    lu, lv, _ = gradient_field(PERSP, n)
    area = footprint_area(PERSP, z, lu, lv)
    xy = surface_xy(PERSP, z)
    dx = np.gradient(xy[..., 0], axis=1)
    dy = -np.gradient(xy[..., 1], axis=0)
    np.testing.assert_allclose(area[:, 1:-1], (dx * dy)[:, 1:-1], rtol=1e-4)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"model": "perspective", "focal_length_px": 800.0}, "missing: camera-height"),
        ({"model": "perspective", "camera_height_mm": 300.0}, "missing: focal-length-px"),
        ({"model": "perspective"}, "needs --focal-length-px and --camera-height"),
        ({"model": "orthographic"}, "needs --pixel-size"),
        ({"model": "orthographic", "pixel_size_mm": 0.1, "focal_length_px": 10.0}, "need --camera perspective"),
        ({"model": "perspective", "focal_length_px": -1.0, "camera_height_mm": 300.0}, "focal_length_px"),
        ({"model": "fisheye"}, "expected one of"),
    ],
)
def test_camera_errors(kwargs, message):
    model = kwargs.pop("model")
    with pytest.raises(ValueError, match=message):
        make_camera(model, **kwargs)


def test_camera_from_dict_errors():
    assert isinstance(camera_from_dict({"model": "orthographic", "pixel_size_mm": 0.05}), Orthographic)
    assert isinstance(camera_from_dict({"model": "perspective", "focal_length_px": 2400,
                                        "camera_height_mm": 300}), Perspective)
    with pytest.raises(ValueError, match="rig camera: camera: a perspective camera needs"):
        camera_from_dict({"model": "perspective", "focal_length_px": 2400}, "rig camera")
    with pytest.raises(ValueError, match="'model'"):
        camera_from_dict({"pixel_size_mm": 0.05})
