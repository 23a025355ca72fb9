"""photometric.errors.configuration: conditioning of light rings and image-noise propagation."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import condition_number, ring_lights
from photometric.normals import normals_from_slopes
from tests.photometric.errors._lights import BEAR


def test_ring_conditioning_optimum():
    assert E.OPTIMAL_SLANT_DEG == pytest.approx(54.7356103, abs=1e-6)
    res = E.ring_conditioning([E.OPTIMAL_SLANT_DEG])
    np.testing.assert_allclose(res["singular_values"][0], res["singular_values"][0, 0], rtol=1e-12)
    assert res["condition_number"][0] == pytest.approx(1.0, abs=1e-12)
    s = np.linspace(5, 85, 1601)
    curve = E.ring_conditioning(s)
    assert abs(s[np.argmin(curve["condition_number"])] - E.OPTIMAL_SLANT_DEG) < 0.05
    # closed form: singular values sqrt(3/2) sin s (twice) and sqrt(3) cos s
    rad = np.radians(s)
    expect = np.sort(np.stack([np.sqrt(1.5) * np.sin(rad)] * 2 + [np.sqrt(3) * np.cos(rad)], -1), -1)[:, ::-1]
    np.testing.assert_allclose(curve["singular_values"], expect, atol=1e-12)
    assert condition_number(ring_lights(3, E.OPTIMAL_SLANT_DEG)) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="slants_deg"):
        E.ring_conditioning([90.0])


def test_noise_propagation_against_monte_carlo():
    rng = np.random.default_rng(0)
    sigma, rho = 0.01, 0.8
    p, q = np.array([0.4]), np.array([-0.3])
    n = normals_from_slopes(p, q)[0]
    images = rho * BEAR @ n + rng.normal(0, sigma, (20000, 3))
    g = images @ np.linalg.inv(BEAR).T
    pe, qe = -g[:, 0] / g[:, 2], -g[:, 1] / g[:, 2]
    res = E.noise_propagation(BEAR, sigma, rho, p, q)
    np.testing.assert_allclose(np.cov(np.stack([pe, qe])), res["covariance_pq"][0], rtol=0.05, atol=1e-7)
    nh = g / np.linalg.norm(g, axis=1, keepdims=True)
    ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(nh, n), axis=1), nh @ n))
    assert np.sqrt(np.mean(ang**2)) == pytest.approx(res["angle_rms_deg"][0], rel=0.03)
    assert res["sigma_normal_bound"] == pytest.approx(sigma * np.linalg.norm(np.linalg.inv(BEAR)) / rho)
