"""Loop-subdivision smoothing of closed meshes (set-operation results, CT surfaces).

Loop (1987) subdivision, then optional Taubin (1995) or Laplacian filtering,
both from open3d; the result is checked to be closed and oriented again.
"""

from __future__ import annotations

import numpy as np

from surfaces.mesh import TriangleMesh, as_mesh, compact
from surfaces.repair import check_solid, require_solid
from surfaces.validate import InputError

__all__ = ["FILTERS", "loop_smooth"]

FILTERS: tuple[str, ...] = ("taubin", "laplacian", "none")


def loop_smooth(
    mesh,
    iterations: int = 1,
    *,
    filter: str = "taubin",
    filter_iterations: int = 10,
):
    """Loop subdivision, then optional Taubin or Laplacian filtering, keeping the mesh closed.

    Loop (1987) subdivision splits every triangle into four and moves the
    vertices by the Loop masks (even vertices ``(1 - n beta) v + beta sum``,
    odd ``3/8 (a + b) + 1/8 (c + d)``), converging to a C2 box-spline surface
    away from extraordinary vertices; Taubin's lambda/mu filter (1995)
    smooths without the shrinkage of plain Laplacian filtering. Both come from
    open3d; connectivity stays closed, which is checked again.

    Parameters
    ----------
    mesh : TriangleMesh
        Closed, oriented mesh (e.g. ``BooleanResult.mesh``).
    iterations : int, optional
        Loop subdivision steps (each multiplies the triangle count by 4); 0
        skips subdivision.
    filter : {"taubin", "laplacian", "none"}, optional
        Filter applied after subdivision.
    filter_iterations : int, optional
        Filter steps.

    Returns
    -------
    TriangleMesh
        The smoothed closed mesh.

    Raises
    ------
    ValueError
        Bad arguments, or an input that is not a solid.
    RuntimeError
        When the smoothed mesh is not closed and oriented.
    """
    iterations, filter_iterations = int(iterations), int(filter_iterations)
    if iterations < 0 or filter_iterations < 0:
        raise InputError(f"iterations, filter_iterations: must be >= 0, got {iterations}, {filter_iterations}")
    if filter not in FILTERS:
        raise InputError(f"filter: must be one of {', '.join(FILTERS)}, got {filter!r}")
    solid = as_mesh(mesh, "mesh")
    require_solid(solid, "mesh")
    import open3d as o3d

    o3 = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(solid.vertices), o3d.utility.Vector3iVector(solid.triangles)
    )
    if iterations:
        o3 = o3.subdivide_loop(number_of_iterations=iterations)
    if filter_iterations and filter == "taubin":
        o3 = o3.filter_smooth_taubin(number_of_iterations=filter_iterations)
    elif filter_iterations and filter == "laplacian":
        o3 = o3.filter_smooth_laplacian(number_of_iterations=filter_iterations)
    out = compact(TriangleMesh(np.asarray(o3.vertices, dtype=np.float64), np.asarray(o3.triangles, dtype=np.int64)))
    info = check_solid(out, "smoothed mesh")
    if not (info["closed"] and info["oriented"]):
        raise RuntimeError("; ".join(info["problems"]))
    return out
