"""Meshes and patch models as open3d geometry, for interactive windows.

:func:`to_open3d` gives an open3d triangle mesh with vertex normals (from the
patches for a patch model) and optional colours or colour-mapped scalars;
:func:`control_net_lineset` gives seed 001's "carcass", the Bezier control
net, as a line set. open3d is imported inside the functions, so that
``import surfaces`` stays fast.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from surfaces.bezier import control_net_segments
from surfaces.colormap import apply_colormap, vertex_values
from surfaces.mesh import PATCH_SAMPLES, as_mesh, vertex_normals
from surfaces.validate import as_array, InputError

__all__ = ["to_open3d", "control_net_lineset"]


def control_net_lineset(patches, color: Sequence[float] = (0.1, 0.1, 0.1)):
    """The control net as an open3d line set.

    Parameters
    ----------
    patches : BezierPatches
        Patch model.
    color : (3,) float
        RGB in [0, 1] for every line.

    Returns
    -------
    open3d.geometry.LineSet
        One line per control-polygon segment (see :func:`surfaces.bezier.control_net_segments`).
    """
    import open3d as o3d

    seg = control_net_segments(patches)
    col = as_array(color, "color", shape=(3,))
    lines = o3d.geometry.LineSet()
    lines.points = o3d.utility.Vector3dVector(seg.reshape(-1, 3))
    lines.lines = o3d.utility.Vector2iVector(np.arange(2 * len(seg)).reshape(-1, 2))
    lines.colors = o3d.utility.Vector3dVector(np.tile(col, (len(seg), 1)))
    return lines


def to_open3d(
    geometry,
    colors: np.ndarray | None = None,
    scalars: np.ndarray | None = None,
    *,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    samples: int = PATCH_SAMPLES,
):
    """Convert a mesh or a patch model to an open3d triangle mesh for viewing.

    Parameters
    ----------
    geometry : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        What to show. Patches are tessellated with ``samples`` points per patch
        edge; their vertex normals come from the patches (``du x dv``).
    colors : (V, 3) array_like, optional
        Per-vertex RGB in [0, 1] (V counts the tessellated vertices).
    scalars : (V,) array_like, optional
        Per-vertex values (height, deviation, ...) mapped through ``cmap``.
    cmap, vmin, vmax
        Colour map and its value range (see :func:`surfaces.colormap.apply_colormap`).
    samples : int
        Tessellation density for patches.

    Returns
    -------
    open3d.geometry.TriangleMesh
        With vertex normals (from the input, else area-weighted) and vertex
        colours when given or present in the input.
    """
    import open3d as o3d

    source = as_mesh(geometry, "geometry", samples)
    verts, tris = source.vertices, source.triangles
    colors, scalars = vertex_values(len(verts), colors, scalars)
    if colors is not None and (colors.min() < 0 or colors.max() > 1):
        raise InputError("colors: RGB values must lie in [0, 1]")
    if scalars is not None:
        colors = apply_colormap(scalars, cmap, vmin, vmax).astype(np.float64)
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(tris.astype(np.int32))
    )
    normals = source.vertex_normals
    mesh.vertex_normals = o3d.utility.Vector3dVector(normals if normals is not None else vertex_normals(verts, tris))
    if colors is None:
        colors = source.vertex_colors
    if colors is not None:
        mesh.vertex_colors = o3d.utility.Vector3dVector(colors)
    return mesh
