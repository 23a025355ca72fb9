"""Closed test solids with known volumes, shared by the mesh, repair and set-operation tests."""

from __future__ import annotations

import numpy as np

from surfaces.coons import from_grid
from surfaces.mesh import TriangleMesh, tessellate


def box(lo, hi) -> TriangleMesh:
    """Outward oriented box mesh (12 triangles)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    tris = np.array(
        [
            [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
            [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
        ]
    )  # fmt: skip
    return TriangleMesh(corners, tris)


def icosphere(radius=1.0, centre=(0.0, 0.0, 0.0), level=3) -> TriangleMesh:
    """Subdivided icosahedron, outward oriented."""
    t = (1 + 5**0.5) / 2
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float
    )  # fmt: skip
    f = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    )  # fmt: skip
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        mid = v[uniq].mean(axis=1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(v) + inv.ravel().reshape(3, -1).T  # midpoints of edges 01, 12, 20
        v = np.vstack([v, mid])
        f = np.concatenate(
            [
                np.column_stack([f[:, 0], m[:, 0], m[:, 2]]),
                np.column_stack([f[:, 1], m[:, 1], m[:, 0]]),
                np.column_stack([f[:, 2], m[:, 2], m[:, 1]]),
                m,
            ]
        )
    return TriangleMesh(v * radius + np.asarray(centre, float), f)


def bezier_ellipsoid(axes, centre, n_u=9, n_v=12, samples=4) -> TriangleMesh:
    """Tessellated bicubic Coons/Bezier ellipsoid of the shared patch model."""
    th = np.linspace(0, np.pi, n_u)
    ph = np.linspace(0, 2 * np.pi, n_v, endpoint=False)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    pts = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    return tessellate(from_grid(pts * axes + centre, closed_v=True), samples=samples)
