"""Signed distances to a reference surface (surfaces.distance)."""

from __future__ import annotations

import numpy as np

from surfaces.distance import deviation
from surfaces.mesh import TriangleMesh


def test_deviation_signed(sphere):
    """Points 0.1 outside / inside the unit sphere are at +0.1 / -0.1 (tessellation tolerance)."""
    rng = np.random.default_rng(1)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = deviation(1.1 * d, sphere)
    inn = deviation(0.9 * d, sphere)
    assert np.allclose(out, 0.1, atol=2e-3) and np.allclose(inn, -0.1, atol=2e-3)


def test_deviation_from_a_plane_is_the_height():
    """Against the square z = 0 (normal +z) the signed distance of a point above it is its z."""
    square = TriangleMesh([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], [[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0.5, 3.5, (50, 2)), rng.uniform(-1, 1, 50)])
    assert np.allclose(deviation(pts, square), pts[:, 2], atol=1e-6)
