"""Vector helpers (surfaces.vectors) against numpy's own products."""

from __future__ import annotations

import numpy as np

from surfaces.vectors import cross, dot, perpendicular, unit


def test_cross_and_dot_match_numpy():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 50, 4, 3))
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), atol=1e-14)
    np.testing.assert_allclose(dot(a, b), np.sum(a * b, axis=-1), atol=1e-14)
    # broadcasting one vector against many
    np.testing.assert_allclose(cross(a, b[0, 0]), np.cross(a, b[0, 0]), atol=1e-14)


def test_unit_keeps_dtype_and_zero_vectors():
    v = np.array([[3.0, 0.0, 4.0], [0.0, 0.0, 0.0]], np.float32)
    u = unit(v)
    assert u.dtype == np.float32
    np.testing.assert_allclose(u, [[0.6, 0.0, 0.8], [0.0, 0.0, 0.0]], atol=1e-7)


def test_perpendicular_is_unit_and_orthogonal():
    rng = np.random.default_rng(1)
    t = unit(rng.normal(size=(200, 3)))
    t[:3] = np.eye(3)  # the axes themselves
    p = perpendicular(t)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.sum(p * t, axis=1), 0.0, atol=1e-12)
