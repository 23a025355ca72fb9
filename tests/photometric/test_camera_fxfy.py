"""A pinhole camera whose pixels are not square (fx != fy): closed forms of a tilted plane."""

import numpy as np
import pytest

from photometric.camera import (camera_from_dict, footprint_area, gradient_field, make_camera, pixel_rays,
                                surface_xy)
from surfaces.validate import InputError

FX, FY, HC, CX, CY = 900.0, 780.0, 200.0, 40.3, 31.7
SHAPE = (64, 90)


def _plane():
    """A tilted plane n . X = d seen by the camera: the exact depth of every pixel (pinhole algebra)."""
    n = np.array([0.2, -0.3, 1.0])
    n /= np.linalg.norm(n)
    d = n @ np.array([0.0, 0.0, 5.0])
    h, w = SHAPE
    u, v = np.meshgrid(np.arange(w) - CX, CY - np.arange(h))
    depth = (d - n[2] * HC) / (n[0] * u / FX + n[1] * v / FY - n[2])
    return n, d, depth


@pytest.fixture
def cam():
    return make_camera("perspective", focal_length_px=(FX, FY), camera_height_mm=HC, principal_point_px=(CX, CY))


def test_surface_points_lie_on_the_plane_and_on_the_pixel_rays(cam):
    n, d, depth = _plane()
    z = HC - depth
    pts = np.concatenate([surface_xy(cam, z), z[..., None]], axis=2)
    assert np.abs(pts @ n - d).max() < 1e-9
    o, ray = pixel_rays(cam, SHAPE, np.array([5.0, 40.0]), np.array([70.0, 3.0]))
    for k, (r, c) in enumerate([(5, 70), (40, 3)]):
        t = (d - n @ o[k]) / (n @ ray[k])
        assert np.allclose(o[k] + t * ray[k], pts[r, c], atol=1e-9)


def test_gradient_field_is_the_log_depth_derivative_per_pixel(cam):
    n, _, depth = _plane()
    p, q, spacing = gradient_field(cam, np.broadcast_to(n, SHAPE + (3,)).copy())
    log_w = np.log(depth)
    inner = (slice(2, -2), slice(2, -2))
    assert spacing == 1.0
    # central differences of a log-depth that is a smooth rational function: agreement to 1e-8 of 4e-4
    assert np.abs(p - np.gradient(log_w, axis=1))[inner].max() < 1e-8
    assert np.abs(q + np.gradient(log_w, axis=0))[inner].max() < 1e-8
    square = make_camera("perspective", focal_length_px=FX, camera_height_mm=HC, principal_point_px=(CX, CY))
    _, q_square, _ = gradient_field(square, np.broadcast_to(n, SHAPE + (3,)).copy())
    assert np.abs(q_square + np.gradient(log_w, axis=0))[inner].max() > 1e-5  # fy matters


def test_footprint_area_is_the_projected_cell(cam):
    n, _, depth = _plane()
    z = HC - depth
    p, q, _ = gradient_field(cam, np.broadcast_to(n, SHAPE + (3,)).copy())
    pts = surface_xy(cam, z)
    dc, dr = np.gradient(pts, axis=1), np.gradient(pts, axis=0)
    cell = np.abs(dc[..., 0] * dr[..., 1] - dc[..., 1] * dr[..., 0])
    assert np.abs(footprint_area(cam, z, p, q) / cell - 1)[2:-2, 2:-2].max() < 1e-5


def test_round_trip_and_errors(cam):
    entry = cam.to_dict(SHAPE)
    assert entry["focal_length_px"] == FX and entry["focal_length_y_px"] == FY
    assert camera_from_dict(entry) == cam
    with pytest.raises(InputError, match="not both"):
        make_camera("perspective", focal_length_px=(FX, FY), focal_length_y_px=FY, camera_height_mm=HC)
    with pytest.raises(InputError, match="focal_length_y_px"):
        make_camera("perspective", focal_length_px=FX, focal_length_y_px=-1.0, camera_height_mm=HC)
