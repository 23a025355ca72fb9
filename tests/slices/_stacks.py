"""Contour stacks the slices tests share: phantom sections and circles."""

from __future__ import annotations

import numpy as np

from datasets_synthetic.phantoms import make_phantom
from slices.polygons import clean_contour
from slices.io import Contour


def phantom_stack(shape: str, spacing: float = 2.5, n_points: int = 64, **params):
    """``(phantom, contours, truth)`` of a phantom cut every ``spacing`` mm."""
    ph = make_phantom(shape, **params)
    conts = [Contour(c["z"], clean_contour(c["points"])) for c in ph.contours(spacing, n_points=n_points)]
    return ph, conts, ph.truth(spacing)


def circle(cx: float, cy: float, r: float, n: int = 40) -> np.ndarray:
    """``n`` counter-clockwise points of a circle, shape (n, 2)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], 1)


def mesh_distance(mesh, points: np.ndarray) -> np.ndarray:
    """Unsigned distance of points to a triangle mesh (open3d ray-casting scene)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def branching_stack(n: int = 40) -> list[Contour]:
    """One circle on two planes splitting into two circles on the next two (a branching)."""
    return [Contour(0.0, circle(0, 0, 10, n)), Contour(2.0, circle(0, 0, 10, n)),
            Contour(4.0, circle(-5, 0, 4, n)), Contour(4.0, circle(5, 0, 4, n)),
            Contour(6.0, circle(-5, 0, 4, n)), Contour(6.0, circle(5, 0, 4, n))]


def half_disc(side: float, r: float = 10.0, n_arc: int = 48, n_wall: int = 16) -> np.ndarray:
    """Counter-clockwise half disc of radius ``r`` on the ``side`` (+1 right, -1 left) of x = 0, shape (n, 2).

    The two halves share the wall x = 0 (vertices at the same points); each starts mid-arc, so
    its first vertex lies strictly outside the other half (the hole test probes the first vertex).
    """
    t = np.linspace(-np.pi / 2, np.pi / 2, n_arc + 1)
    y = np.linspace(r, -r, n_wall + 1)[1:-1]
    pts = np.vstack([r * np.stack([np.cos(t), np.sin(t)], 1), np.stack([np.zeros_like(y), y], 1)])
    if side < 0:
        pts = (pts * [-1.0, 1.0])[::-1]
    return np.roll(pts, -len(pts) // 4, axis=0)
