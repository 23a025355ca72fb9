"""photometric.errors.montecarlo: random deviations against the first-order model."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from tests.photometric.errors._lights import TRIAD45


@pytest.mark.parametrize("sigma", [0.05, 0.2])
def test_monte_carlo_converges_to_first_order(lights, sigma):
    p = np.array([0.0, 0.5, 1.0, -0.8])
    q = np.array([0.0, 0.3, -1.0, 0.6])
    mc = E.monte_carlo(lights, sigma, p, q, n_samples=20000, seed=1)
    rel = np.linalg.norm(mc.covariance - mc.predicted_covariance, axis=(1, 2)) / np.linalg.norm(
        mc.predicted_covariance, axis=(1, 2)
    )
    assert rel.max() < 0.05
    np.testing.assert_allclose(mc.angle_rms_deg, mc.predicted_angle_rms_deg, rtol=0.03)
    # the tangent deviations are Gaussian, so for small sigma the errors are too (kurtosis 3)
    z = (mc.dp - mc.dp.mean(0)) / mc.dp.std(0)
    np.testing.assert_allclose(np.mean(z**4, axis=0), 3.0, atol=0.2)
    # RMS deviation angle is sigma
    angle, _ = E.random_deviations(3, sigma, 20000, seed=2)
    assert np.sqrt(np.mean(angle**2)) == pytest.approx(sigma, rel=0.02)
    # the mean (a second-order effect) is small against the spread
    assert np.all(np.abs(mc.mean) < 0.1 * np.sqrt(np.diagonal(mc.predicted_covariance, axis1=1, axis2=2)))


def test_monte_carlo_departs_from_first_order_for_large_sigma():
    # a check that the comparison can fail: at 10 deg the linear model is visibly off
    p, q = np.array([2.0]), np.array([2.0])
    mc = E.monte_carlo(TRIAD45, 10.0, p, q, n_samples=20000, seed=1)
    ratio = np.trace(mc.covariance[0]) / np.trace(mc.predicted_covariance[0])
    assert abs(ratio - 1.0) > 0.1


def test_random_deviations_are_uniform_in_direction_and_reproducible():
    angle, direction = E.random_deviations(4, 1.0, 40000, seed=5)
    assert angle.shape == direction.shape == (40000, 4) and np.all(angle >= 0)
    hist, _ = np.histogram(direction, bins=8, range=(-180, 180))
    np.testing.assert_allclose(hist / hist.sum(), 1 / 8, atol=0.01)
    again, _ = E.random_deviations(4, 1.0, 40000, seed=5)
    np.testing.assert_array_equal(again, angle)
    with pytest.raises(ValueError, match="n_samples"):
        E.random_deviations(3, 1.0, 1)


def test_exceedance_probability_grows_with_sigma():
    prob = E.exceedance_probability(TRIAD45, [0.0, 0.3, 3.0], 0.05, 1.0, n_samples=400, n_grid=11)
    assert prob[0] == 0.0 and prob[-1] > 0.9 and np.all(np.diff(prob) >= 0)
    with pytest.raises(ValueError, match="sigmas_deg"):
        E.exceedance_probability(TRIAD45, [-1.0], 0.05, 1.0)
