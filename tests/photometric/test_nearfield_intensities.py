"""The semi-calibrated near-field solve (issue 33 item 3): LED power without a flat field.

Images come from the independent near-field renderer (datasets_synthetic.nearfield) of a
rig whose 8 LEDs stand 205-215 mm from the field centre with unequal power. The solve is
given the LED positions only; with ``estimate_intensities`` it must find the flat plate
again (after plane removal: a tilt of the whole field is the semi-calibrated problem's
near-ambiguity) and the LEDs' relative power, where the assumed equal power gives a bowl.
"""

import warnings

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera, perspective_camera
from datasets_synthetic.heightfields import AnalyticSurface
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import point_lights as render_lights
from photometric.camera import make_camera
from photometric.leds import point_lights
from photometric.nearfield import solve_nearfield
from photometric.options import PhotometricOptions
from photometric.pipeline import reconstruct
from surfaces.validate import InputError

N = 8
SIZE = 96
PIXEL_MM = 60.0 / SIZE


def _rig(seed: int = 1):
    """8 LEDs at 45 deg slant, 205-215 mm from the origin, and powers (irradiance at the origin)."""
    az = np.radians(np.arange(N) * 360.0 / N + 10.0)
    d = np.linspace(205.0, 215.0, N)
    s = np.radians(45.0)
    pos = np.stack([d * np.sin(s) * np.cos(az), d * np.sin(s) * np.sin(az), d * np.cos(s)], axis=1)
    power = 1.0 + np.random.default_rng(seed).uniform(-0.1, 0.1, N)
    return pos, power



def _untilted_error(estimated, truth, positions) -> float:
    """Largest relative error of estimated LED powers after removing what a tilt of the whole field
    trades for: a factor ``exp(a + b x_k + c y_k)`` over the LEDs' directions (the semi-calibrated
    problem's near-ambiguity, fitted by least squares in the log)."""
    u = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    A = np.column_stack([np.ones(len(u)), u[:, 0], u[:, 1]])
    r = np.log(np.asarray(estimated, float) / np.asarray(truth, float))
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    return float(np.max(np.abs(np.expm1(r - A @ coef))))

def _plane_rms_um(height, use) -> float:
    rows, cols = np.nonzero(use)
    A = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(float)
    z = height[use]
    coef, *_ = np.linalg.lstsq(A, z, rcond=None)
    return 1e3 * float(np.sqrt(np.mean((z - A @ coef) ** 2)))


@pytest.mark.parametrize("perspective", [False, True])
def test_estimated_intensities_flatten_the_plate(perspective):
    pos, power = _rig()
    shape = (SIZE, SIZE)
    if perspective:
        f = 300.0 / PIXEL_MM
        rcam, cam = perspective_camera(shape, f, 300.0), make_camera("perspective", focal_length_px=f,
                                                                        camera_height_mm=300.0)
    else:
        rcam, cam = orthographic_camera(shape, PIXEL_MM), make_camera("orthographic", pixel_size_mm=PIXEL_MM)
    r = render_near_field(AnalyticSurface(), rcam, render_lights(pos, None, 0.0, power), 0.8, noise=0.001,
                          bit_depth=16, seed=2)
    lights = point_lights(pos)
    assumed = solve_nearfield(r.images, lights, cam)
    est = solve_nearfield(r.images, lights, cam, estimate_intensities=True)
    bowl = _plane_rms_um(assumed.height, assumed.valid)
    flat = _plane_rms_um(est.height, est.valid)
    assert bowl > 10.0  # the assumed equal power bends the plate
    assert flat < 2.0 and flat < bowl / 10
    rel = np.asarray(est.intensities["relative"])
    assert rel[0] == 1.0  # LED 0's scale is the fixed one
    # the relative powers, up to the tilt near-ambiguity (a ramp over the ring of LEDs)
    assert _untilted_error(rel, power, pos) < 0.01
    # levelled: the powers themselves (the rendered plate is level)
    assert np.max(np.abs(rel / rel[0] / (power / power[0]) - 1.0)) < 0.01
    assert est.intensities["converged"]
    d0 = lights.d0
    np.testing.assert_allclose(est.intensities["radiant_relative"], rel * d0**2 / (rel[0] * d0[0] ** 2))


def test_pipeline_states_and_warns_about_assumed_power():
    pos, power = _rig(seed=4)
    r = render_near_field(AnalyticSurface(), orthographic_camera((64, 64), PIXEL_MM),
                          render_lights(pos, None, 0.0, power), 0.8, bit_depth=16, seed=1)
    kw = dict(lights=pos / np.linalg.norm(pos, axis=1)[:, None], light_positions=pos, pixel_size=PIXEL_MM)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = reconstruct(r.images, **kw)
    assert plain.summary["intensities"]["source"] == "assumed"
    assert "equal irradiance" in plain.summary["intensities"]["assumption"]
    assert any("205.0-215.0 mm" in w for w in plain.summary["warnings"])
    assert any("205.0-215.0 mm" in str(w.message) for w in caught)
    est = reconstruct(r.images, estimate_intensities=True, **kw)
    assert est.summary["intensities"]["source"] == "estimated"
    assert not any("intensities:" in w for w in est.summary["warnings"])
    given = reconstruct(r.images, intensities=power, **kw)
    assert given.summary["intensities"]["source"] == "given"


def test_estimate_needs_point_lights():
    pos, _ = _rig()
    lights = pos / np.linalg.norm(pos, axis=1)[:, None]
    images = np.full((N, 16, 16), 0.5, np.float32)
    with pytest.raises(InputError, match="estimate_intensities"):
        solve_nearfield(images, lights, make_camera("orthographic", pixel_size_mm=1.0), estimate_intensities=True)
    with pytest.raises(InputError, match="estimate_intensities"):
        reconstruct(images, lights=lights, estimate_intensities=True)
    with pytest.raises(InputError, match="estimate_intensities"):
        PhotometricOptions(estimate_intensities="yes")
