"""The trimmed triangle mesh of a hierarchical surface fit (:func:`fit_mesh`).

A lattice of parameter points over the fit's pixel grid, evaluated on its patches
(:attr:`surfaces.fit.SurfaceFit.patches`), cut along the region's smoothed outline by
marching squares. :func:`surfaces.fit.fit_height` makes the fit; this module only meshes it.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from surfaces.fit import BLOCK_PIXELS, SurfaceFit
from surfaces.validate import InputError, positive


def _marching_table() -> dict:
    """Triangles (cycle positions 0..7) of the inside polygon of every marching-squares case.

    Around a lattice cell the cycle runs corner 0 ``(i, j)``, edge 0, corner 1
    ``(i + 1, j)``, edge 1, corner 2 ``(i + 1, j + 1)``, edge 2, corner 3 ``(i, j + 1)``,
    edge 3: counter-clockwise about ``S_u x S_v``. Keys ``(case, joined)``; ``joined``
    only matters for the saddles (corners 0 and 2, or 1 and 3, inside) and says whether
    the centre is inside (one hexagon) or not (two triangles).
    """
    table = {}
    for case in range(16):
        inside = [(case >> c) & 1 for c in range(4)]
        ring = []
        for c in range(4):
            if inside[c]:
                ring.append(2 * c)
            if inside[c] != inside[(c + 1) % 4]:
                ring.append(2 * c + 1)
        for joined in (False, True):
            if case in (5, 10) and not joined:
                # two separate corners: the triangle (edge before, corner, edge after) of each
                first = 0 if case == 5 else 2
                polys = [[(first + 7) % 8, first, first + 1], [(first + 3) % 8, first + 4, first + 5]]
            else:
                polys = [ring] if ring else []
            table[case, joined] = [(poly[0], poly[i], poly[i + 1]) for poly in polys for i in range(1, len(poly) - 1)]
    return table


_MARCHING = _marching_table()


def _lattice_field(mask: np.ndarray, sigma: float, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The mask smoothed by a Gaussian (zero outside the image) at the lattice ``s x t``, interpolated linearly.

    What ``map_coordinates(gaussian_filter(mask, sigma, mode="constant"), ..., order=1,
    mode="constant")`` gives on the lattice (to rounding; nodes outside the pixel centres'
    range are 0), without a whole-image float64 field: both the filter and the bilinear
    interpolation are separable, so the columns are filtered and interpolated to the
    lattice rows a block at a time, and only those rows are filtered along the columns.
    """

    def linear(x: np.ndarray, n: int):
        ok = (x >= 0) & (x <= n - 1)
        i0 = np.clip(np.floor(x).astype(np.intp), 0, n - 1)
        return ok, i0, np.minimum(i0 + 1, n - 1), np.where(ok, x - i0, 0.0)

    H, W = mask.shape
    ok, r0, r1, a = linear(np.asarray(s, float), H)
    rows = np.zeros((len(s), W))
    span = max(1, BLOCK_PIXELS // H)
    for c0 in range(0, W, span):
        block = mask[:, c0:c0 + span].astype(np.float64)
        if sigma:
            block = ndimage.gaussian_filter1d(block, sigma, axis=0, mode="constant")
        rows[ok, c0:c0 + span] = ((1.0 - a[ok, None]) * block[r0[ok]] + a[ok, None] * block[r1[ok]])
    if sigma:
        rows = ndimage.gaussian_filter1d(rows, sigma, axis=1, mode="constant")
    ok, c0, c1, b = linear(np.asarray(t, float), W)
    out = np.zeros((len(s), len(t)))
    out[:, ok] = (1.0 - b[ok]) * rows[:, c0[ok]] + b[ok] * rows[:, c1[ok]]
    return out


def fit_mesh(fit: SurfaceFit, spacing: float = 1.0, smoothing: float = 0.7):
    """Triangle mesh of a fit on a lattice of parameter points, trimmed along the region's outline.

    The vertices lie on the lattice ``s, t = 0, spacing, 2 spacing, ...`` of pixel
    coordinates (pixel centres for ``spacing = 1``) and on the trimming line; each is
    evaluated on the patches (:attr:`SurfaceFit.patches`), so the mesh has no cracks
    where patches of different sizes meet.

    Trimming: the region mask is smoothed (Gaussian, ``smoothing`` pixels) and every
    lattice cell keeps the part of itself where the bilinear interpolant of that field is
    at least 0.5 (marching squares, saddles decided by the cell centre), with the cut
    points interpolated linearly along the lattice edges: the boundary is the level line
    that :func:`skimage.measure.find_contours` draws at 0.5, which follows the mask's
    pixel outline to a fraction of a pixel without stair steps.

    Parameters
    ----------
    fit : SurfaceFit
        A result of :func:`fit_height`.
    spacing : float
        Lattice spacing in pixels (> 0); 1 puts a vertex on every pixel centre.
    smoothing : float
        Standard deviation (pixels, >= 0) of the Gaussian smoothing of the region mask
        before trimming; 0 trims along the raw 0.5 line of the mask.

    Returns
    -------
    surfaces.mesh.TriangleMesh
        Vertices in the unit of the fit, vertex normals from the patches, triangles
        counter-clockwise about ``S_u x S_v`` (upwards for a height field).
    """
    from surfaces.mesh import TriangleMesh
    from surfaces.vectors import cross, unit

    if not isinstance(fit, SurfaceFit):
        raise InputError(f"fit: expected a SurfaceFit, got {type(fit).__name__}")
    step = positive(spacing, "spacing")
    sigma = float(smoothing)
    if not np.isfinite(sigma) or sigma < 0:
        raise InputError(f"smoothing: must be a finite number >= 0, got {smoothing!r}")
    H, W = fit.shape
    # lattice nodes one spacing beyond the pixel centres on every side, so the outline
    # reaches the image edges
    s = np.arange(-1, int(np.ceil((H - 1) / step)) + 2) * step
    t = np.arange(-1, int(np.ceil((W - 1) / step)) + 2) * step
    f = _lattice_field(fit.region & fit.covered, sigma, s, t)
    inside = f >= 0.5
    # vertices: inside nodes, then the crossings on vertical (along s) and horizontal edges; their
    # ids in int32 while they fit (the cells' rings of eight ids are the mesh step's largest arrays),
    # their lattice coordinates from s and t (no whole-lattice coordinate planes)
    ids_type = np.int32 if 3 * inside.size < 2**31 else np.int64
    node_id = np.full(inside.shape, -1, ids_type)
    n_vert = int(np.count_nonzero(inside))
    node_id[inside] = np.arange(n_vert, dtype=ids_type)
    i, j = np.nonzero(inside)
    params = [np.stack([s[i], t[j]], axis=1)]
    edge_ids = []
    for axis in (0, 1):
        a = (slice(None, -1), slice(None)) if axis == 0 else (slice(None), slice(None, -1))
        b = (slice(1, None), slice(None)) if axis == 0 else (slice(None), slice(1, None))
        cut = inside[a] != inside[b]
        ids = np.full(cut.shape, -1, ids_type)
        n_cut = int(np.count_nonzero(cut))
        ids[cut] = n_vert + np.arange(n_cut, dtype=ids_type)
        n_vert += n_cut
        frac = (0.5 - f[a][cut]) / (f[b][cut] - f[a][cut])
        i, j = np.nonzero(cut)
        s_a, t_a = s[i], t[j]
        s_b, t_b = (s[i + 1], t_a) if axis == 0 else (s_a, t[j + 1])
        s_cut = s_a + frac * (s_b - s_a)
        t_cut = t_a + frac * (t_b - t_a)
        params.append(np.stack([s_cut, t_cut], axis=1))
        edge_ids.append(ids)
    del i, j, s_a, s_b, t_a, t_b, frac, cut
    along_s, along_t = edge_ids
    # the eight cycle positions of every lattice cell
    ring = np.stack([
        node_id[:-1, :-1], along_s[:, :-1], node_id[1:, :-1], along_t[1:, :],
        node_id[1:, 1:], along_s[:, 1:], node_id[:-1, 1:], along_t[:-1, :],
    ], axis=-1).reshape(-1, 8)
    one = np.uint8(1)
    case = (inside[:-1, :-1] * one + inside[1:, :-1] * (2 * one) + inside[1:, 1:] * (4 * one)
            + inside[:-1, 1:] * (8 * one)).ravel()
    centre = (0.25 * (f[:-1, :-1] + f[1:, :-1] + f[1:, 1:] + f[:-1, 1:])).ravel() >= 0.5
    del f, inside, node_id, edge_ids, along_s, along_t
    tris = []
    for (c, joined), triangles in _MARCHING.items():
        if not triangles:
            continue
        sel = case == c
        if c in (5, 10):
            sel &= centre == joined
        elif joined:
            continue
        cells = ring[sel]
        for tri in triangles:
            tris.append(cells[:, list(tri)])
    del ring, case, centre
    tri = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
    del tris
    st = np.concatenate(params)
    del params
    # points and normals evaluated per block of vertices: no whole-mesh derivative temporaries
    n = len(st)
    points, normals = np.empty((n, 3)), np.empty((n, 3))
    lost = np.zeros(n, bool)
    span = max(1, BLOCK_PIXELS // 64)  # the patches' derivatives take about 800 bytes per vertex
    for a in range(0, n, span):
        b = min(a + span, n)
        patch, u, v = fit.patches.locate_lattice(st[a:b, 0] + 0.5, st[a:b, 1] + 0.5)
        lost[a:b] = patch < 0
        d = fit.patches.derivatives(np.maximum(patch, 0), 0, u, v)
        points[a:b] = d.point
        normals[a:b] = unit(cross(d.du, d.dv))
    del st
    if lost.any():
        # a cut beyond the patches: drop its triangles, then every vertex no triangle uses, numbered
        # as surfaces.mesh.compact does (here, without a second whole mesh beside this one)
        tri = tri[~lost[tri].any(axis=1)]
        used = np.zeros(n, bool)
        used[tri.ravel()] = True
        tri = (np.cumsum(used) - 1)[tri]
        points = points[used]
        normals = normals[used]
    return TriangleMesh(points, tri, normals)
