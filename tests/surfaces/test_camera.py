"""Cameras (surfaces.camera): rays, projection and fitted standard views against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.camera import STANDARD_VIEWS, Camera, fit_camera


def test_bad_camera():
    with pytest.raises(ValueError, match="coincide"):
        Camera((0, 0, 0), (0, 0, 0), (0, 1, 0))
    with pytest.raises(ValueError, match="parallel"):
        Camera((0, 0, 1), (0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="fov"):
        Camera((0, 0, 1), (0, 0, 0), (0, 1, 0), fov_deg=200)


def test_fit_camera_frames_box():
    box = np.array([[-1.0, -2.0, 0.0], [3.0, 1.0, 0.5]])
    corners = np.array(np.meshgrid(*box.T, indexing="ij")).reshape(3, -1).T
    for name in STANDARD_VIEWS:
        for fov in (None, 30.0):
            cam = fit_camera(box, name, 4 / 3, fov_deg=fov)
            px, depth = cam.project(corners, 400, 300)
            assert np.all(depth > 0)
            assert np.all((px >= 0) & (px <= [400, 300]))


@pytest.mark.parametrize("fov", [None, 40.0])
def test_rays_and_projection_are_inverse(fov):
    """Every pixel-centre ray projects back onto its own pixel centre, in front of the camera."""
    cam = Camera((3.0, -4.0, 2.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), fov_deg=fov, ortho_height=3.0)
    w, h = 16, 12
    rays = cam.rays(w, h).reshape(-1, 6).astype(float)
    assert np.allclose(np.linalg.norm(rays[:, 3:], axis=1), 1.0, atol=1e-6)
    points = rays[:, :3] + 2.5 * rays[:, 3:]
    px, depth = cam.project(points, w, h)
    rows, cols = np.divmod(np.arange(w * h), w)
    assert np.allclose(px[:, 0], cols + 0.5, atol=1e-4) and np.allclose(px[:, 1], rows + 0.5, atol=1e-4)
    assert np.all(depth > 0)


def test_orthographic_basis_and_window():
    """Top view: x right, y up, z to the viewer; the window is ortho_height tall."""
    cam = Camera((0, 0, 5), (0, 0, 0), (0, 1, 0), None, ortho_height=2.0)
    right, up, back = cam.basis()
    assert np.allclose(right, [1, 0, 0]) and np.allclose(up, [0, 1, 0]) and np.allclose(back, [0, 0, 1])
    px, _ = cam.project(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]), 200, 100)
    # the top edge of the window (y = 1) is row 0; x = 1 lies at half the height right of centre
    assert np.allclose(px, [[100.0, 0.0], [150.0, 50.0]])
