"""Signed distances from points to a reference surface (deviation maps).

The closest point on the reference comes from open3d's ``RaycastingScene``
(an Embree BVH, imported inside the function); the sign from the reference's
face normal there.
"""

from __future__ import annotations

import numpy as np

from surfaces.mesh import as_mesh
from surfaces.validate import as_array

__all__ = ["deviation"]


def deviation(vertices: np.ndarray, reference) -> np.ndarray:
    """Signed distance from points to a reference surface.

    Parameters
    ----------
    vertices : (N, 3) array_like
        Query points (world units).
    reference : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        Reference surface.

    Returns
    -------
    (N,) float64
        Distance to the closest point of the reference, positive on the side its
        face normals point to (outside for an outward-oriented closed surface).

    Examples
    --------
    >>> square = ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> deviation([[0.5, 0.5, 0.25], [0.5, 0.5, -0.5]], square).round(6).tolist()
    [0.25, -0.5]
    """
    import open3d as o3d

    pts = as_array(vertices, "vertices", shape=(None, 3))
    ref = as_mesh(reference, "reference")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(ref.vertices.astype(np.float32)), o3d.core.Tensor(ref.triangles.astype(np.uint32))
    )
    closest = scene.compute_closest_points(o3d.core.Tensor(pts.astype(np.float32)))
    foot = closest["points"].numpy().astype(np.float64)
    normal = closest["primitive_normals"].numpy().astype(np.float64)
    dist = np.linalg.norm(pts - foot, axis=1)
    side = np.einsum("ij,ij->i", pts - foot, normal)
    return np.where(side < 0, -dist, dist)
