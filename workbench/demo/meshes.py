"""Geometry the demo draws besides the pipelines' own outputs: true height fields and contour lines."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from photometric.integrate import height_to_patches
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh, tessellate
from surfaces.validate import as_array, InputError, positive


def heightfield_mesh(height, pixel_size: float, exaggeration: float = 1.0) -> TriangleMesh:
    """Triangle mesh of a complete height field on the centred pixel grid, for display.

    The height field goes through the workbench's one height-to-surface path
    (:func:`photometric.integrate.height_to_patches`, slopes by central
    differences, then :func:`surfaces.mesh.tessellate` with one subdivision per
    patch), so it lands where every other output does
    (:data:`surfaces.grid.GRID_CONVENTION`: origin at the image centre, y up).
    One node per pixel: a decimated grid between pixels would blur sharp
    defects unevenly along their length.

    Parameters
    ----------
    height : (H, W) array_like
        Heights in mm, all finite.
    pixel_size : float
        Pixel size in mm (> 0).
    exaggeration : float
        Vertical scale factor for display (> 0).

    Returns
    -------
    surfaces.mesh.TriangleMesh
        Two triangles per cell of the pixel-centre grid, counter-clockwise seen
        from +z; vertex z is ``exaggeration * height``.

    Examples
    --------
    >>> mesh = heightfield_mesh(np.zeros((3, 5)), 0.5)
    >>> mesh.n_triangles, float(mesh.vertices[:, 0].min()), float(mesh.vertices[:, 1].max())
    (16, -1.0, 0.5)
    """
    z = as_array(height, "height", ndim=2)
    h = positive(pixel_size, "pixel_size")
    scale = positive(exaggeration, "exaggeration")
    if min(z.shape) < 2:
        raise InputError(f"height: needs at least 2 x 2 pixels, got {z.shape}")
    dz_drow, dz_dcol = np.gradient(z, h)
    patches = height_to_patches(z, dz_dcol, -dz_drow, pixel_size=h, step=1)
    shown = BezierPatches(patches.control * np.array([1.0, 1.0, scale]))
    return tessellate(shown, samples=1)


def contour_segments(path: str | os.PathLike) -> np.ndarray:
    """Line segments of every closed contour in a ``contours.json`` file (for drawing).

    Parameters
    ----------
    path : path-like
        Contour file as written by :func:`datasets_synthetic.phantoms.write_phantom`
        (``{"contours": [{"z": mm, "points": [[x, y], ...]}, ...]}``).

    Returns
    -------
    (K, 2, 3) float64 array
        Start and end point (mm) of each segment; each contour is closed (its last
        point joins its first).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     f = Path(folder) / "contours.json"
    ...     _ = f.write_text('{"contours": [{"z": 2.0, "points": [[0, 0], [1, 0], [0, 1]]}]}')
    ...     segments = contour_segments(f)
    >>> segments.shape, segments[2].tolist()
    ((3, 2, 3), [[0.0, 1.0, 2.0], [0.0, 0.0, 2.0]])
    """
    contours = json.loads(Path(path).read_text())["contours"]
    if not contours:
        raise InputError(f"path: {path} holds no contours")
    segs = []
    for c in contours:
        pts = np.asarray(c["points"], float)
        p3 = np.column_stack([pts, np.full(len(pts), float(c["z"]))])
        segs.append(np.stack([p3, np.roll(p3, -1, axis=0)], axis=1))
    return np.concatenate(segs)
