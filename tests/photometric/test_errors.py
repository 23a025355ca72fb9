"""Tests of photometric.errors: the light-deviation error model of seed 002(a)."""

from __future__ import annotations

import importlib.util
import itertools

import numpy as np
import pytest

from photometric import errors as E

TRIAD45 = E.standard_triad(45.0)
TRIAD60 = E.standard_triad(60.0, azimuth0_deg=10.0)
# an irregular triad (DiLiGenT bear's, rounded) and four lights, to avoid symmetric special cases
BEAR = np.array([[0.6033, -0.2726, 0.7495], [-0.5644, 0.3956, 0.7245], [-0.5094, -0.3824, 0.7709]])
BEAR = BEAR / np.linalg.norm(BEAR, axis=1, keepdims=True)
FOUR = E.lights_from_angles([40.0, 35.0, 50.0, 45.0], [0.0, 100.0, 190.0, 280.0])
CONFIGS = {"triad45": TRIAD45, "triad60": TRIAD60, "bear": BEAR, "four": FOUR}


@pytest.fixture(params=sorted(CONFIGS))
def lights(request):
    return CONFIGS[request.param]


def _square(D=1.0, n=21):
    return E.derivative_square(D, n)


# --------------------------------------------------------------------------- exact model


def test_zero_deviation_gives_zero_error(lights):
    p, q = _square(1.5)
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
    R = E.rotation_matrix(axis, angle)
    true = lights @ R.T  # every true light is R l_k
    p, q = _square(1.0)
    ex = E.exact_error(lights, true, p, q)
    n = E.normals_from_derivatives(p, q)
    n_est = E.normals_from_derivatives(ex.p_est, ex.q_est)
    np.testing.assert_allclose(n_est, n @ R, atol=1e-12)  # row form of R^-1 n = R^T n
    np.testing.assert_allclose(ex.angle_deg, np.degrees(np.arccos(np.clip(np.sum(n * (n @ R), -1), -1, 1))), atol=1e-5)


def test_reconstruction_matrix_is_identity_for_nominal(lights):
    np.testing.assert_allclose(E.reconstruction_matrix(lights, lights), np.eye(3), atol=1e-12)


def test_exact_error_batches_over_light_sets():
    p, q = _square(1.0, 5)
    dev = np.zeros((4, 3, 3, 2))
    dev[..., 0, 0] = np.linspace(-2, 2, 4)[:, None]
    dev[..., 1, 1] = np.linspace(-1, 1, 3)[None, :]
    batch = E.exact_error(TRIAD45, E.deviate_lights(TRIAD45, dev), p, q)
    assert batch.dp.shape == (4, 3, 5, 5)
    one = E.exact_error(TRIAD45, E.deviate_lights(TRIAD45, dev[2, 1]), p, q)
    np.testing.assert_allclose(batch.dp[2, 1], one.dp, atol=1e-15)


# --------------------------------------------------------------------------- lights


def test_light_angles_round_trip():
    s = np.array([0.0, 10.0, 45.0, 80.0])
    a = np.array([0.0, -170.0, 30.0, 120.0])
    s2, a2 = E.light_angles(E.lights_from_angles(s, a))
    np.testing.assert_allclose(s2, s, atol=1e-12)
    np.testing.assert_allclose(a2[1:], a[1:], atol=1e-12)


@pytest.mark.parametrize("delta", [0.5, 3.0, -4.0])
def test_rotate_lights_moves_by_the_angle(lights, delta):
    phi = np.linspace(0, 300, lights.shape[0])
    out = E.rotate_lights(lights, np.full(lights.shape[0], delta), phi)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-14)
    ang = np.degrees(np.arccos(np.clip(np.sum(out * lights, 1), -1, 1)))
    np.testing.assert_allclose(ang, abs(delta), atol=1e-6)
    # direction 0 is the slant increment, direction 90 turns towards increasing azimuth
    dev = np.zeros((lights.shape[0], 2))
    dev[:, 0] = delta
    np.testing.assert_allclose(
        E.rotate_lights(lights, np.full(lights.shape[0], delta), 0.0), E.deviate_lights(lights, dev), atol=1e-14
    )
    turned = E.rotate_lights(lights, np.full(lights.shape[0], abs(delta)), 90.0)
    _, a0 = E.light_angles(lights)
    _, a1 = E.light_angles(turned)
    assert np.all(np.sin(np.radians(a1 - a0)) > 0)


@pytest.mark.skipif(importlib.util.find_spec("datasets_synthetic.render") is None, reason="render not written yet")
def test_deviate_lights_agrees_with_renderer():
    from datasets_synthetic.render import deviate_lights

    dev = np.array([[2.0, 0.0], [-1.0, 3.0], [0.5, -2.5]])
    np.testing.assert_allclose(E.deviate_lights(BEAR, dev), deviate_lights(BEAR, dev), atol=1e-9)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.ones((3, 2)), "lights"),
        (np.array([[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]]), "coplanar"),
        (np.array([[0, 0, 2.0], [1, 0, 0], [0, 1, 0]]), "unit"),
        (np.array([[0, 0, 1.0], [1, 0, 0]]), "at least 3"),
    ],
)
def test_bad_lights_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        E.exact_error(bad, bad, 0.0, 0.0)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="p, q"):
        E.exact_error(TRIAD45, TRIAD45, np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="mode"):
        E.max_deviation(TRIAD45, 0.05, 1.0, (0,), "sideways")
    with pytest.raises(ValueError, match="lights_moved"):
        E.worst_case_error(TRIAD45, 1.0, 1.0, (5,))
    with pytest.raises(ValueError, match="tolerance"):
        E.max_deviation(TRIAD45, -0.05, 1.0)
    with pytest.raises(ValueError, match="axis2"):
        E.error_map(TRIAD45, 0.0, 0.0, (0, "slant"), (1, "tilt"))


def test_surface_derivatives_convention():
    # z = 0.3 x + 0.2 y with x along columns and y UP (row 0 is the top row)
    ps = 0.05
    rows, cols = np.mgrid[0:6, 0:7]
    x, y = cols * ps, (5 - rows) * ps
    p, q = E.surface_derivatives(0.3 * x + 0.2 * y, ps)
    np.testing.assert_allclose(p, 0.3, atol=1e-12)
    np.testing.assert_allclose(q, 0.2, atol=1e-12)


# --------------------------------------------------------------------------- first order


@pytest.mark.parametrize("deviation", [0.25, 1.0, 2.0, -2.0])
def test_first_order_matches_exact(lights, deviation):
    p, q = _square(1.0, 21)
    for k, j in itertools.product(range(lights.shape[0]), range(2)):
        dev = np.zeros((lights.shape[0], 2))
        dev[k, j] = deviation
        ex = E.exact_error(lights, E.deviate_lights(lights, dev), p, q)
        fp, fq = E.first_order_error(lights, dev, p, q)
        for exact, lin in ((ex.dp, fp), (ex.dq, fq)):
            scale = np.abs(exact).max()
            if scale < 1e-9:  # e.g. the azimuth of a light on the axis does nothing
                assert np.abs(lin).max() < 1e-9
                continue
            assert np.abs(exact - lin).max() / scale < 0.05


def test_jacobian_against_finite_differences(lights):
    p, q = _square(1.0, 9)
    J = E.sensitivity(lights, p, q)
    h = 1e-6
    for k, j in itertools.product(range(lights.shape[0]), range(2)):
        dev = np.zeros((2, lights.shape[0], 2))
        dev[0, k, j], dev[1, k, j] = np.degrees(h), -np.degrees(h)
        ex = E.exact_error(lights, E.deviate_lights(lights, dev), p, q)
        np.testing.assert_allclose((ex.dp[0] - ex.dp[1]) / (2 * h), J[..., 0, k, j], atol=1e-6)
        np.testing.assert_allclose((ex.dq[0] - ex.dq[1]) / (2 * h), J[..., 1, k, j], atol=1e-6)


def test_first_order_error_is_linear_combination():
    p, q = _square(0.7, 7)
    rng = np.random.default_rng(3)
    d1, d2 = rng.normal(size=(2, 3, 2))
    a1, b1 = E.first_order_error(TRIAD45, d1, p, q)
    a2, b2 = E.first_order_error(TRIAD45, d2, p, q)
    a3, b3 = E.first_order_error(TRIAD45, 2 * d1 - d2, p, q)
    np.testing.assert_allclose(a3, 2 * a1 - a2, atol=1e-14)
    np.testing.assert_allclose(b3, 2 * b1 - b2, atol=1e-14)


# --------------------------------------------------------------------------- Monte Carlo


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


def test_exceedance_probability_grows_with_sigma():
    prob = E.exceedance_probability(TRIAD45, [0.0, 0.3, 3.0], 0.05, 1.0, n_samples=400, n_grid=11)
    assert prob[0] == 0.0 and prob[-1] > 0.9 and np.all(np.diff(prob) >= 0)


# --------------------------------------------------------------------------- tolerances


@pytest.mark.parametrize("moved", [(0,), (1,), (0, 1), (0, 1, 2)])
@pytest.mark.parametrize("mode", ["any", "slant", "azimuth"])
def test_tolerance_inversion_round_trips(moved, mode):
    eps, D = 0.05, 1.0
    tol = E.max_deviation(BEAR, eps, D, moved, mode, n_grid=21)
    assert not tol.saturated
    err = E.worst_case_error(BEAR, tol.value, D, moved, mode, n_grid=21)
    assert abs(err - eps) / eps < 1e-6
    # the linearised limit is close for these small angles
    assert abs(tol.first_order - tol.value) / tol.value < 0.05
    # beyond the limit the tolerance is violated, inside it is kept
    assert E.worst_case_error(BEAR, 1.01 * tol.value, D, moved, mode, n_grid=21) > eps
    assert E.worst_case_error(BEAR, 0.99 * tol.value, D, moved, mode, n_grid=21) < eps


@pytest.mark.parametrize("moved", [(0,), (1, 2)])
def test_derivative_range_inversion_round_trips(moved):
    eps, delta = 0.05, 0.7
    res = E.max_derivative_range(TRIAD45, eps, delta, moved, "any", n_grid=21)
    assert not res.saturated and res.value > 0
    err = E.worst_case_error(TRIAD45, delta, res.value, moved, "any", n_grid=21)
    assert abs(err - eps) / eps < 1e-6
    # the two inversions agree: at range D the allowed deviation is delta
    back = E.max_deviation(TRIAD45, eps, res.value, moved, "any", n_grid=21)
    assert abs(back.value - delta) / delta < 1e-6


def test_derivative_range_saturates_when_flat_surface_already_fails():
    res = E.max_derivative_range(TRIAD45, 1e-4, 5.0, (0,), "any", n_grid=11)
    assert res.saturated and res.value == 0.0


def test_worst_direction_candidates_beat_a_fine_ring():
    # single light: the exact worst case over a fine ring of directions may not exceed the
    # first-order-optimal candidates by more than O(delta^3)
    p, q = _square(1.0, 21)
    delta = 3.0
    ring = np.linspace(0, 360, 720, endpoint=False)
    angle = np.zeros((ring.size, 3))
    angle[:, 1] = delta
    direction = np.zeros((ring.size, 3))
    direction[:, 1] = ring
    ex = E.exact_error(TRIAD45, E.rotate_lights(TRIAD45, angle, direction), p, q)
    brute = max(np.abs(ex.dp).max(), np.abs(ex.dq).max())
    cand = E.worst_case_error(TRIAD45, delta, 1.0, (1,), "any", n_grid=21, n_directions=0)
    assert brute <= cand * (1 + 1e-3)
    assert cand <= brute * (1 + 1e-3)


def test_pair_is_stricter_than_single():
    rows = E.recommendation_table(TRIAD45, tolerances=(0.05,), ranges=(1.0,), n_grid=11)
    r = rows[0]
    assert r["all_lights_deg"] < r["pair_deg"] < r["single_light_deg"]
    tighter = E.recommendation_table(TRIAD45, tolerances=(0.02,), ranges=(2.0,), n_grid=11)[0]
    assert tighter["single_light_deg"] < r["single_light_deg"]


# --------------------------------------------------------------------------- maps and curves


def test_error_map_matches_direct_evaluation():
    p, q = _square(1.0, 11)
    m = E.error_map(TRIAD45, p, q, (0, "slant"), (2, "azimuth"), deviation_max=4.0, n=9)
    assert m.max_dp.shape == (9, 9)
    assert m.max_dp[4, 4] < 1e-13 and m.max_dq[4, 4] < 1e-13  # centre: no deviation
    i, j = 7, 2  # row i -> axis2 value, column j -> axis1 value
    dev = np.zeros((3, 2))
    dev[0, 0], dev[2, 1] = m.dev1_deg[j], m.dev2_deg[i]
    ex = E.exact_error(TRIAD45, E.deviate_lights(TRIAD45, dev), p, q)
    assert m.max_dp[i, j] == pytest.approx(np.abs(ex.dp).max(), rel=1e-12)
    assert m.mean_dq[i, j] == pytest.approx(np.abs(ex.dq).mean(), rel=1e-12)
    assert m.max_angle_deg[i, j] == pytest.approx(ex.angle_deg.max(), rel=1e-9)


def test_error_map_lit_only_uses_fewer_normals():
    p, q = _square(2.0, 21)
    full = E.error_map(TRIAD45, p, q, n=5)
    lit = E.error_map(TRIAD45, p, q, n=5, lit_only=True)
    assert lit.n_normals < full.n_normals
    assert np.all(lit.max_dp <= full.max_dp + 1e-15)


def test_error_curves_first_order_tangent():
    c = E.error_curves(TRIAD45, [0.0, 1.0], light=0, deviation_max=2.0, n=41)
    assert c["dp"].shape == (41, 2)
    mid = 20
    assert np.abs(c["dp"][mid]).max() < 1e-14
    slope_exact = (c["dq"][mid + 1] - c["dq"][mid - 1]) / (c["deviation_deg"][mid + 1] - c["deviation_deg"][mid - 1])
    slope_lin = (c["dq_first_order"][mid + 1] - c["dq_first_order"][mid - 1]) / (
        c["deviation_deg"][mid + 1] - c["deviation_deg"][mid - 1]
    )
    np.testing.assert_allclose(slope_exact, slope_lin, rtol=1e-3)


# --------------------------------------------------------------------------- configuration


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
    assert E.condition_number(E.standard_triad(E.OPTIMAL_SLANT_DEG)) == pytest.approx(1.0, abs=1e-12)


def test_noise_propagation_against_monte_carlo():
    rng = np.random.default_rng(0)
    sigma, rho = 0.01, 0.8
    p, q = np.array([0.4]), np.array([-0.3])
    n = E.normals_from_derivatives(p, q)[0]
    images = rho * BEAR @ n + rng.normal(0, sigma, (20000, 3))
    g = images @ np.linalg.inv(BEAR).T
    pe, qe = -g[:, 0] / g[:, 2], -g[:, 1] / g[:, 2]
    res = E.noise_propagation(BEAR, sigma, rho, p, q)
    np.testing.assert_allclose(np.cov(np.stack([pe, qe])), res["covariance_pq"][0], rtol=0.05, atol=1e-7)
    nh = g / np.linalg.norm(g, axis=1, keepdims=True)
    ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(nh, n), axis=1), nh @ n))
    assert np.sqrt(np.mean(ang**2)) == pytest.approx(res["angle_rms_deg"][0], rel=0.03)
    assert res["sigma_normal_bound"] == pytest.approx(sigma * np.linalg.norm(np.linalg.inv(BEAR)) / rho)


# --------------------------------------------------------------------------- height fields


@pytest.mark.skipif(importlib.util.find_spec("photometric.integrate") is None, reason="integrate not written yet")
def test_height_error_of_a_plane_is_a_plane():
    ps = 0.1
    rows, cols = np.mgrid[0:32, 0:40]
    h = 0.2 * cols * ps - 0.1 * (31 - rows) * ps
    dev = np.zeros((3, 2))
    res = E.height_error(TRIAD45, TRIAD45, h, ps)
    assert res["max_abs_dh_mm"] < 1e-9 and res["max_abs_dp"] < 1e-12
    dev[0, 0] = 2.0
    res = E.height_error(TRIAD45, E.deviate_lights(TRIAD45, dev), h, ps)
    # a plane maps to a plane: the height error is the plane of the slope errors
    ex = E.exact_error(TRIAD45, E.deviate_lights(TRIAD45, dev), 0.2, -0.1)
    expect = ex.dp * cols * ps + ex.dq * (31 - rows) * ps
    expect = expect - expect.mean()
    np.testing.assert_allclose(res["dh"], expect, atol=1e-6)
