"""nearfield_setup: the rig's flat-field strengths prepared once give the solve that the gains give."""

from __future__ import annotations

import numpy as np
import pytest

from photometric.camera import make_camera
from photometric.leds import point_lights
from photometric.nearfield import nearfield_setup, solve_nearfield
from photometric.rig import flat_field_gains
from tests.photometric.test_nearfield import PERSP, plane_images, plane_points_and_normal, ring

ORTHO = make_camera("orthographic", pixel_size_mm=0.4)


@pytest.mark.parametrize("cam", [ORTHO, PERSP], ids=["orthographic", "perspective"])
@pytest.mark.parametrize("mu", [None, 1.5])
def test_setup_gives_the_solve_of_the_gains(cam, mu):
    shape = (64, 96)
    pos = ring(4, 45, 160.0)
    e = np.array([1.0, 0.8, 1.25, 0.9])
    X0, z_hat = plane_points_and_normal(cam, shape, 0.0)
    flats = plane_images(pos, X0, z_hat, 0.9, e, mu=1.5)
    X, n = plane_points_and_normal(cam, shape, 0.08)
    images = plane_images(pos, X, n, 0.45, e, mu=1.5)
    lights = point_lights(pos, mu=mu)
    gains = flat_field_gains(flats, lights, cam, 0.9, smoothing_px=0)
    setup = nearfield_setup(lights, cam, shape, gains, coarse_pixels=1024)
    assert sorted(setup.coarse) == [3] and setup.flat_field
    a = solve_nearfield(images, lights, cam, gains=gains, coarse_pixels=1024, tolerance_mm=1e-5)
    b = solve_nearfield(images, lights, cam, setup=setup, coarse_pixels=1024, tolerance_mm=1e-5)
    assert a.history == b.history and a.history[0]["level"] == "coarse"
    for key in ("normals", "albedo", "valid", "residual", "height", "xy"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    # another coarse block size than prepared: computed from the full-resolution strengths, same result
    c = solve_nearfield(images, lights, cam, setup=setup, coarse_pixels=600, tolerance_mm=1e-5)
    d = solve_nearfield(images, lights, cam, gains=gains, coarse_pixels=600, tolerance_mm=1e-5)
    np.testing.assert_array_equal(c.height, d.height)


def test_setup_must_match_the_solve():
    shape = (20, 30)
    lights = point_lights(ring(3, 45, 150.0))
    gains = np.ones((3,) + shape, np.float32)
    setup = nearfield_setup(lights, ORTHO, shape, gains)
    images = np.full((3,) + shape, 0.5, np.float32)
    with pytest.raises(ValueError, match="setup: prepared for other lights, camera or image size"):
        solve_nearfield(images[:, :10], lights, ORTHO, setup=setup)
    with pytest.raises(ValueError, match="setup: prepared for other lights"):
        solve_nearfield(images, point_lights(ring(3, 45, 151.0)), ORTHO, setup=setup)
    with pytest.raises(ValueError, match="setup: prepared for other lights"):
        solve_nearfield(images, lights, make_camera("orthographic", pixel_size_mm=0.5), setup=setup)
    with pytest.raises(ValueError, match="setup: give the flat-field gains to nearfield_setup"):
        solve_nearfield(images, lights, ORTHO, setup=setup, gains=gains)
    with pytest.raises(ValueError, match="setup: expected NearFieldSetup"):
        solve_nearfield(images, lights, ORTHO, setup={"strength": 1})
    with pytest.raises(ValueError, match="gains: flat-field gains must be >= 0"):
        nearfield_setup(lights, ORTHO, shape, -gains)
    with pytest.raises(ValueError, match="gains: expected shape"):
        nearfield_setup(lights, ORTHO, (10, 10), gains)
    with pytest.raises(ValueError, match="lights: expected PointLights"):
        nearfield_setup(np.eye(3), ORTHO, shape)
    no_flat = nearfield_setup(lights, ORTHO, shape)
    assert not no_flat.flat_field and np.ndim(no_flat.strength[0]) == 0
