"""photometric.errors.model: the exact error m = L^+ L' n and its first-order form."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import deviate_lights, rotation_matrix
from photometric.normals import normals_from_slopes
from tests.photometric.errors._lights import BEAR, TRIAD45, square


def test_derivative_square_includes_edges():
    p, q = E.derivative_square(1.5, 7)
    assert p.shape == q.shape == (7, 7)
    assert p[0, 0] == -1.5 and p[0, -1] == 1.5 and q[-1, 0] == 1.5
    np.testing.assert_array_equal(p[0], p[-1])  # p along axis 1, q along axis 0
    with pytest.raises(ValueError, match="n"):
        E.derivative_square(1.0, 1)


def test_zero_deviation_gives_zero_error(lights):
    p, q = square(1.5)
    ex = E.exact_error(lights, lights, p, q)
    assert np.abs(ex.dp).max() < 1e-13
    assert np.abs(ex.dq).max() < 1e-13
    assert ex.angle_deg.max() < 1e-10
    dev = np.zeros((lights.shape[0], 2))
    fp, fq = E.first_order_error(lights, dev, p, q)
    assert np.abs(fp).max() == 0.0 and np.abs(fq).max() == 0.0


@pytest.mark.parametrize(
    "axis, angle", [((0, 0, 1), 10.0), ((1, 0, 0), -3.0), ((0.3, -0.5, 0.8), 7.0), ((1, 1, 0), 25.0)]
)
def test_common_rotation_turns_normals_by_inverse(lights, axis, angle):
    R = rotation_matrix(axis, angle)
    true = lights @ R.T  # every true light is R l_k
    p, q = square(1.0)
    ex = E.exact_error(lights, true, p, q)
    n = normals_from_slopes(p, q)
    n_est = normals_from_slopes(ex.p_est, ex.q_est)
    np.testing.assert_allclose(n_est, n @ R, atol=1e-12)  # row form of R^-1 n = R^T n
    np.testing.assert_allclose(ex.angle_deg, np.degrees(np.arccos(np.clip(np.sum(n * (n @ R), -1), -1, 1))), atol=1e-5)


def test_reconstruction_matrix_is_identity_for_nominal(lights):
    np.testing.assert_allclose(E.reconstruction_matrix(lights, lights), np.eye(3), atol=1e-12)


def test_exact_error_batches_over_light_sets():
    p, q = square(1.0, 5)
    dev = np.zeros((4, 3, 3, 2))
    dev[..., 0, 0] = np.linspace(-2, 2, 4)[:, None]
    dev[..., 1, 1] = np.linspace(-1, 1, 3)[None, :]
    batch = E.exact_error(TRIAD45, deviate_lights(TRIAD45, dev), p, q)
    assert batch.dp.shape == (4, 3, 5, 5)
    one = E.exact_error(TRIAD45, deviate_lights(TRIAD45, dev[2, 1]), p, q)
    np.testing.assert_allclose(batch.dp[2, 1], one.dp, atol=1e-15)


def test_flat_surface_closed_form():
    # m = n + (cos 47 - cos 45) c_1 with c_1 = (0, 2 / (3 sin 45), 1 / (3 cos 45)) for the 45 deg triad
    ex = E.exact_error(TRIAD45, deviate_lights(TRIAD45, [2.0, 0.0, 0.0]), 0.0, 0.0)
    d = np.cos(np.radians(47.0)) - np.cos(np.radians(45.0))
    s = np.sin(np.radians(45.0))
    m = np.array([0.0, d * 2 / (3 * s), 1 + d / (3 * s)])
    assert float(ex.dp) == pytest.approx(0.0, abs=1e-15)
    assert float(ex.dq) == pytest.approx(-m[1] / m[2], rel=1e-12)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.ones((3, 2)), "lights"),
        (np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]]), "coplanar"),
        (np.array([[0, 0, 1.0], [1, 0, 0]]), "at least 3"),
        (np.array([[0, 0, 1.0], [1, 0, np.nan], [0, 1, 0]]), "NaN"),
    ],
)
def test_bad_lights_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        E.exact_error(bad, bad, 0.0, 0.0)


def test_non_unit_lights_are_normalised_with_a_warning():
    long = np.array([[0, 0, 2.0], [1, 0, 0], [0, 1, 0]])
    with pytest.warns(UserWarning, match="not unit"):
        ex = E.exact_error(long, long, 0.3, -0.2)
    assert abs(float(ex.dp)) < 1e-14


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="p, q"):
        E.exact_error(TRIAD45, TRIAD45, np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="lights_true"):
        E.exact_error(TRIAD45, TRIAD45[:2], 0.0, 0.0)
    with pytest.raises(ValueError, match="deviations_deg"):
        E.first_order_error(TRIAD45, np.zeros((2, 2)), 0.0, 0.0)


def test_lit_normals():
    # the 45 deg triad reaches a flat surface; a surface rising upwards steeper than 45 deg
    # (q = 1.5, normal (0, -1.5, 1)) turns away from light 1 at the top (n . l_1 < 0)
    lit = E.lit_normals(TRIAD45, np.array([0.0, 0.0, 0.0]), np.array([0.0, 1.5, 0.9]))
    assert lit.tolist() == [True, False, True]


@pytest.mark.parametrize("deviation", [0.25, 1.0, 2.0, -2.0])
def test_first_order_matches_exact(lights, deviation):
    p, q = square(1.0, 21)
    for k, j in itertools.product(range(lights.shape[0]), range(2)):
        dev = np.zeros((lights.shape[0], 2))
        dev[k, j] = deviation
        ex = E.exact_error(lights, deviate_lights(lights, dev), p, q)
        fp, fq = E.first_order_error(lights, dev, p, q)
        for exact, lin in ((ex.dp, fp), (ex.dq, fq)):
            scale = np.abs(exact).max()
            if scale < 1e-9:  # e.g. the azimuth of a light on the axis does nothing
                assert np.abs(lin).max() < 1e-9
                continue
            assert np.abs(exact - lin).max() / scale < 0.05


def test_jacobian_against_finite_differences(lights):
    p, q = square(1.0, 9)
    J = E.sensitivity(lights, p, q)
    h = 1e-6
    for k, j in itertools.product(range(lights.shape[0]), range(2)):
        dev = np.zeros((2, lights.shape[0], 2))
        dev[0, k, j], dev[1, k, j] = np.degrees(h), -np.degrees(h)
        ex = E.exact_error(lights, deviate_lights(lights, dev), p, q)
        np.testing.assert_allclose((ex.dp[0] - ex.dp[1]) / (2 * h), J[..., 0, k, j], atol=1e-6)
        np.testing.assert_allclose((ex.dq[0] - ex.dq[1]) / (2 * h), J[..., 1, k, j], atol=1e-6)


def test_first_order_error_is_linear_combination():
    p, q = square(0.7, 7)
    rng = np.random.default_rng(3)
    d1, d2 = rng.normal(size=(2, 3, 2))
    a1, b1 = E.first_order_error(TRIAD45, d1, p, q)
    a2, b2 = E.first_order_error(TRIAD45, d2, p, q)
    a3, b3 = E.first_order_error(TRIAD45, 2 * d1 - d2, p, q)
    np.testing.assert_allclose(a3, 2 * a1 - a2, atol=1e-14)
    np.testing.assert_allclose(b3, 2 * b1 - b2, atol=1e-14)


def test_first_order_covariance_is_j_sigma_jt():
    p, q = np.array([0.0, 0.4, -0.9]), np.array([0.0, -0.3, 0.8])
    sigma = 0.7
    cov = E.first_order_covariance(BEAR, sigma, p, q)
    J = E.sensitivity(BEAR, p, q)  # (K, 2, N, 2) per radian of slant / azimuth
    # isotropic tangent deviation of variance sigma^2 / 2 per axis: along e_s (slant) and
    # e_a, where an azimuth change da moves the light by sin(s) da
    s = np.sqrt(1.0 - BEAR[:, 2] ** 2)
    var = 0.5 * np.radians(sigma) ** 2
    scale = np.stack([np.ones_like(s), 1.0 / s], axis=-1) ** 2 * var  # (N, 2)
    expect = np.einsum("kinj,kmnj,nj->kim", J, J, scale)
    np.testing.assert_allclose(cov, expect, rtol=1e-10, atol=1e-18)
    rms = E.first_order_angle_rms(BEAR, sigma, p, q)
    assert rms.shape == (3,) and np.all(rms > 0)
    assert np.all(E.first_order_angle_rms(BEAR, 0.0, p, q) == 0.0)
