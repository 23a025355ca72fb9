"""The Bezier patch model: evaluation, derivatives, normals, validation."""

import numpy as np
import pytest

from surfaces.bezier import BezierPatches, bernstein


def _random_patches(rows=3, cols=4, seed=0):
    rng = np.random.default_rng(seed)
    return BezierPatches(rng.normal(size=(rows, cols, 4, 4, 3)))


def test_bernstein_partition_of_unity_and_derivatives():
    t = np.linspace(0, 1, 11)
    np.testing.assert_allclose(bernstein(t).sum(axis=1), 1.0)
    h = 1e-6
    np.testing.assert_allclose(bernstein(t, 1), (bernstein(t + h) - bernstein(t - h)) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(bernstein(t, 2), (bernstein(t + h, 1) - bernstein(t - h, 1)) / (2 * h), atol=1e-5)


def test_corners_are_control_points():
    bp = _random_patches()
    pi, pj = np.array([0, 2, 1]), np.array([0, 3, 2])
    u, v = np.array([0.0, 1.0, 0.0]), np.array([0.0, 1.0, 1.0])
    pts = bp.evaluate(pi, pj, u, v)
    np.testing.assert_allclose(pts[0], bp.control[0, 0, 0, 0])
    np.testing.assert_allclose(pts[1], bp.control[2, 3, 3, 3])
    np.testing.assert_allclose(pts[2], bp.control[1, 2, 0, 3])


def test_derivatives_match_finite_differences():
    bp = _random_patches()
    rng = np.random.default_rng(1)
    n = 50
    pi, pj = rng.integers(0, 3, n), rng.integers(0, 4, n)
    u, v = rng.uniform(0.1, 0.9, n), rng.uniform(0.1, 0.9, n)
    d = bp.derivatives(pi, pj, u, v, order=2)
    h = 1e-6
    fu = (bp.evaluate(pi, pj, u + h, v) - bp.evaluate(pi, pj, u - h, v)) / (2 * h)
    fv = (bp.evaluate(pi, pj, u, v + h) - bp.evaluate(pi, pj, u, v - h)) / (2 * h)
    np.testing.assert_allclose(d.du, fu, atol=1e-6)
    np.testing.assert_allclose(d.dv, fv, atol=1e-6)
    fuv = (bp.derivatives(pi, pj, u, v + h).du - bp.derivatives(pi, pj, u, v - h).du) / (2 * h)
    np.testing.assert_allclose(d.duv, fuv, atol=1e-5)
    n_ = bp.normals(pi, pj, u, v)
    np.testing.assert_allclose(np.linalg.norm(n_, axis=1), 1.0)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n_, d.du), 0.0, atol=1e-9)


def test_grid_evaluation_matches_pointwise():
    bp = _random_patches()
    pts, du, dv = bp.evaluate_grid(5, 4, order=1)
    u, v = np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 4), indexing="ij")
    d = bp.derivatives(np.full(20, 2), np.full(20, 1), u.ravel(), v.ravel())
    np.testing.assert_allclose(pts[2, 1].reshape(-1, 3), d.point)
    np.testing.assert_allclose(du[2, 1].reshape(-1, 3), d.du)
    np.testing.assert_allclose(dv[2, 1].reshape(-1, 3), d.dv)


def test_chunked_evaluation_equals_unchunked():
    bp = _random_patches(10, 10)
    rng = np.random.default_rng(2)
    n = 70_000  # more than one chunk
    s, t = rng.uniform(0, 10, n), rng.uniform(0, 10, n)
    whole = bp.evaluate_global(s, t)
    part = bp.evaluate_global(s[-100:], t[-100:])
    np.testing.assert_allclose(whole[-100:], part)


def test_global_parameter_one_is_the_far_edge():
    bp = _random_patches()
    p = bp.evaluate_global(np.array([3.0]), np.array([4.0]))
    np.testing.assert_allclose(p[0], bp.control[2, 3, 3, 3])
    with pytest.raises(ValueError, match="s: global parameters"):
        bp.evaluate_global(np.array([3.5]), np.array([1.0]))


def test_validation_messages():
    with pytest.raises(ValueError, match=r"control: expected shape"):
        BezierPatches(np.zeros((2, 2, 3, 4, 3)))
    bad = np.zeros((2, 2, 4, 4, 3))
    bad[0, 0, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="NaN or infinite"):
        BezierPatches(bad)
    with pytest.raises(ValueError, match="closed_u: the last patch row does not join"):
        BezierPatches(np.random.default_rng(0).normal(size=(2, 2, 4, 4, 3)), closed_u=True)
    bp = _random_patches()
    with pytest.raises(ValueError, match="patch index outside"):
        bp.evaluate(np.array([5]), np.array([0]), np.array([0.5]), np.array([0.5]))


def test_flipped_reverses_normals_and_transform_is_affine():
    bp = _random_patches()
    u = np.array([0.3])
    n1 = bp.normals(np.array([0]), np.array([0]), u, u)
    n2 = bp.flipped().normals(np.array([2]), np.array([0]), 1 - u, u)
    np.testing.assert_allclose(n1, -n2, atol=1e-12)
    rot = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    moved = bp.transformed(rot, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(
        moved.evaluate_global(u, u), bp.evaluate_global(u, u) @ rot.T + [1, 2, 3], atol=1e-12
    )


def test_trusted_patches_are_the_checked_ones_without_a_copy():
    rng = np.random.default_rng(3)
    control = rng.normal(size=(3, 5, 4, 4, 3))
    columns = control[:, 1:4]
    trusted = BezierPatches.unchecked(columns, closed_v=True)
    checked = BezierPatches(columns, closed_u=False, closed_v=False)
    assert np.shares_memory(trusted.control, control) and not trusted.control.flags.writeable
    assert control.flags.writeable  # the caller's array stays as it was
    assert np.array_equal(trusted.control, checked.control) and trusted.shape == checked.shape
    assert (trusted.closed_u, trusted.closed_v) == (False, True)
    u = np.array([0.0, 0.3, 1.0])
    assert np.allclose(trusted.evaluate(np.zeros(3, int), np.ones(3, int), u, u),
                       checked.evaluate(np.zeros(3, int), np.ones(3, int), u, u), rtol=0, atol=0)
