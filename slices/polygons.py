"""Planar polygons in mm: area, centroid, self-intersections, containment, and the contour check.

The geometry every contour of a structure goes through before it is
parameterised (:mod:`slices.control_points`) or chained across planes
(:mod:`slices.chaining`): the signed (shoelace) area and area centroid, the
crossing edge pairs of an outline, :func:`clean_contour` (finite, large
enough, simple, counter-clockwise), the crossing-number containment test and
an interior point far from the outline.
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import as_array, InputError


def signed_area(points) -> float:
    """Signed area of a closed polygon (shoelace formula).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm, not repeating the first at the end.

    Returns
    -------
    float
        Area in mm^2, positive when the vertices run counter-clockwise (seen from +z).
    """
    p = as_array(points, "points", shape=(None, 2))
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def centroid(points) -> np.ndarray:
    """Area centroid of a closed polygon.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm.

    Returns
    -------
    numpy.ndarray, shape (2,)
        Centroid in mm (the vertex mean for a degenerate zero-area polygon).
    """
    return _centroid(as_array(points, "points", shape=(None, 2)))


def _next(p: np.ndarray) -> np.ndarray:
    """Each vertex's successor along a closed polygon (``np.roll(p, -1, axis=0)`` without its overhead)."""
    return np.concatenate([p[1:], p[:1]])


def _centroid(p: np.ndarray) -> np.ndarray:
    """Area centroid of an already validated (n, 2) float64 polygon."""
    q = _next(p)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    a = cross.sum() / 2.0
    if abs(a) < 1e-12 * max(1.0, float(np.ptp(p, axis=0).max()) ** 2):
        return p.mean(axis=0)
    return ((p + q) * cross[:, None]).sum(axis=0) / (6.0 * a)


def self_intersections(points) -> np.ndarray:
    """Pairs of non-adjacent edges of a closed polygon that cross or touch.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm.

    Returns
    -------
    numpy.ndarray, shape (K, 2) int64
        Edge index pairs ``(i, j)``, ``i < j``; edge ``i`` runs from vertex ``i``
        to vertex ``i + 1`` (wrapping).
    """
    p = as_array(points, "points", shape=(None, 2))
    a, b = p, np.roll(p, -1, axis=0)
    ii, jj = _candidate_pairs(a, b)
    if not len(ii):
        return np.zeros((0, 2), np.int64)
    d1, d2 = b[ii] - a[ii], b[jj] - a[jj]

    def orient(o, d, q):
        return d[:, 0] * (q[:, 1] - o[:, 1]) - d[:, 1] * (q[:, 0] - o[:, 0])

    o1, o2 = orient(a[ii], d1, a[jj]), orient(a[ii], d1, b[jj])
    o3, o4 = orient(a[jj], d2, a[ii]), orient(a[jj], d2, b[ii])
    scale = 1e-12 * (np.abs(d1).sum(axis=1) * np.abs(d2).sum(axis=1) + 1e-300)
    cross = (o1 * o2 <= scale) & (o3 * o4 <= scale)
    # collinear but disjoint segments pass the sign test; keep only real overlaps
    col = (np.abs(o1) <= scale) & (np.abs(o2) <= scale)
    if np.any(col & cross):
        t = np.einsum("ij,ij->i", d1, d1) + 1e-300
        s0 = np.einsum("ij,ij->i", a[jj] - a[ii], d1) / t
        s1 = np.einsum("ij,ij->i", b[jj] - a[ii], d1) / t
        overlap = (np.maximum(s0, s1) >= 0) & (np.minimum(s0, s1) <= 1)
        cross &= ~col | overlap
    return np.stack([ii[cross], jj[cross]], axis=1)


def _candidate_pairs(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Non-adjacent edge pairs whose bounding boxes share a cell of a uniform grid.

    A spatial hash keeps the exact test to O(n) pairs for the dense contours of
    CT data instead of all n^2 / 2.
    """
    n = len(a)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    length = np.linalg.norm(b - a, axis=1)
    cell = max(2.0 * float(np.median(length)), 1e-9)
    c_lo = np.floor((lo - lo.min(axis=0)) / cell).astype(np.int64)
    c_hi = np.floor((hi - lo.min(axis=0)) / cell).astype(np.int64)
    span = c_hi - c_lo + 1
    count = span[:, 0] * span[:, 1]
    edge = np.repeat(np.arange(n), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    cx = c_lo[edge, 0] + k % span[edge, 0]
    cy = c_lo[edge, 1] + k // span[edge, 0]
    key = cx * (int(c_hi[:, 1].max()) + 1) + cy
    order = np.argsort(key, kind="stable")
    key, edge = key[order], edge[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    size = np.diff(np.r_[start, len(key)])
    g_start = np.repeat(start, size)
    g_size = np.repeat(size, size)
    total = int(g_size.sum())
    if total > 50_000_000:
        raise InputError("points: contour too degenerate for the self-intersection test")
    first = np.repeat(np.arange(len(key)), g_size)
    partner = np.repeat(g_start, g_size) + (np.arange(total) - np.repeat(np.cumsum(g_size) - g_size, g_size))
    i, j = edge[first], edge[partner]
    gap = np.abs(i - j)
    keep = (i < j) & (gap > 1) & (gap != n - 1)
    i, j = i[keep], j[keep]
    if not len(i):
        return i, j
    pair = np.unique(i * n + j)
    i, j = pair // n, pair % n
    box = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    return i[box], j[box]


#: Largest |coordinate| of a contour point in mm: beyond it, float64 cannot resolve a contour's shape
#: against its offset, and it is no patient coordinate (a wrong unit or origin).
MAX_COORDINATE_MM = 1e6

#: Smallest extent of a contour in mm: below it, a contour is a unit mistake (metres, not mm).
MIN_EXTENT_MM = 1e-3


def clean_contour(points, name: str = "contour") -> np.ndarray:
    """Validate a closed planar contour and orient it counter-clockwise.

    Drops a repeated closing vertex and consecutive duplicates, then checks.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm.
    name : str
        Used in error messages (e.g. ``"ROI 'Heart' contour 12 at z=-30.0 mm"``).

    Returns
    -------
    numpy.ndarray, shape (m, 2) float64
        Counter-clockwise vertices (seen from +z), ``m >= 3``.

    Raises
    ------
    ValueError
        Fewer than 3 distinct points, coordinates beyond :data:`MAX_COORDINATE_MM`,
        an extent below :data:`MIN_EXTENT_MM`, zero area, or self-intersecting edges.

    Examples
    --------
    A clockwise square with its first vertex repeated at the end comes back
    counter-clockwise, without the repeat, enclosing its area of 4:

    >>> square = clean_contour([[0, 0], [0, 2], [2, 2], [2, 0], [0, 0]])
    >>> square.tolist(), signed_area(square)
    ([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]], 4.0)
    >>> clean_contour([[0, 0], [1, 1], [2, 2]], name="ROI 'Heart' contour 3")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: ROI 'Heart' contour 3: has zero area (all points on one line)
    """
    p = as_array(points, name, ndim=2)
    if p.shape[1] != 2:
        raise InputError(f"{name}: expected (n, 2) x/y points, got shape {p.shape}")
    if len(p) >= 2:
        keep = np.any(p != np.roll(p, 1, axis=0), axis=1)
        p = p[keep] if np.any(keep) else p[:1]
    if len(p) < 3:
        raise InputError(f"{name}: needs at least 3 distinct points, got {len(p)}")
    extent = float(np.ptp(p, axis=0).max())
    far = float(np.abs(p).max())
    if far > MAX_COORDINATE_MM:
        raise InputError(f"{name}: coordinates reach {far:.3g} mm, beyond +-{MAX_COORDINATE_MM:g} mm; these "
                         "are not patient coordinates in mm (check the units and the origin)")
    if 0 < extent < MIN_EXTENT_MM:
        raise InputError(f"{name}: spans only {extent:.3g} mm, less than {MIN_EXTENT_MM:g} mm; contours are "
                         "read in mm (check the units)")
    area = signed_area(p)
    d, e = p[1:] - p[0], p[-1] - p[0]
    if extent == 0 or np.all(np.abs(d[:, 0] * e[1] - d[:, 1] * e[0]) <= 1e-12 * extent**2):
        raise InputError(f"{name}: has zero area (all points on one line)")
    bad = self_intersections(p)
    if len(bad):
        i, j = bad[0]
        raise InputError(
            f"{name}: is self-intersecting ({len(bad)} crossing edge pair(s), "
            f"e.g. edges {i} and {j} near ({p[i, 0]:.2f}, {p[i, 1]:.2f}) mm)"
        )
    return p if area > 0 else p[::-1].copy()


def points_in_polygon(points, polygon) -> np.ndarray:
    """Crossing-number test of many points against one polygon.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        Query points in mm.
    polygon : array_like, shape (n, 2)
        Closed polygon.

    Returns
    -------
    numpy.ndarray, shape (N,) bool
        True for points inside.
    """
    q = as_array(points, "points", shape=(None, 2))
    p = as_array(polygon, "polygon", shape=(None, 2))
    a, b = p, np.roll(p, -1, axis=0)
    inside = np.zeros(len(q), dtype=bool)
    block = max(1, 4_000_000 // max(len(p), 1))
    for s in range(0, len(q), block):
        x, y = q[s : s + block, 0:1], q[s : s + block, 1:2]
        straddle = (a[None, :, 1] > y) != (b[None, :, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (
                b[None, :, 1] - a[None, :, 1]
            )
        inside[s : s + block] = (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1
    return inside


def interior_point(points) -> np.ndarray:
    """The point inside a polygon farthest from its outline (raster approximation).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Closed polygon in mm.

    Returns
    -------
    numpy.ndarray, shape (2,)
        A point strictly inside, on a 256 x 256 raster of the bounding box.
    """
    import cv2

    p = as_array(points, "points", shape=(None, 2))
    lo, hi = p.min(axis=0), p.max(axis=0)
    size = 256
    scale = (size - 3) / max(float((hi - lo).max()), 1e-12)
    pix = ((p - lo) * scale + 1.0) * 16.0
    img = np.zeros((size, size), np.uint8)
    cv2.fillPoly(img, [np.round(pix).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    dist = cv2.distanceTransform(img, cv2.DIST_L2, 5)
    r, c = np.unravel_index(int(np.argmax(dist)), dist.shape)
    return np.array([c, r], float) / scale - 1.0 / scale + lo


def repair_contour(points) -> tuple[list[np.ndarray], int, float, float]:
    """Simple polygons of a pinched or self-crossing outline (shapely ``make_valid``).

    A contour derived from a mask often touches itself at a pinch point, or runs
    twice along a few edges; a hand-drawn one may cross itself. Shapely's
    ``make_valid`` (GEOS, the "structure" method) splits such an outline into the
    simple polygons it encloses, with their holes; pieces of zero area (lines,
    points) are dropped.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm (n >= 3).

    Returns
    -------
    rings : list of numpy.ndarray, each shape (m, 2)
        The outlines of the parts and of their holes (holes inside their part),
        each without a repeated closing vertex, largest area first.
    parts : int
        How many of the rings are parts (the others are holes).
    area_before : float
        The outline's shoelace area before the repair (mm^2, unsigned; crossing
        loops count with their winding).
    area_after : float
        The repaired region's area (mm^2: parts minus holes).

    Examples
    --------
    A bow tie (a 2 mm square's outline drawn with two sides crossed) becomes
    its two triangles; its shoelace area was 0 (the two loops cancel):

    >>> rings, parts, before, after = repair_contour([[0, 0], [2, 2], [2, 0], [0, 2]])
    >>> len(rings), parts, before, after
    (2, 2, 0.0, 2.0)
    """
    import shapely
    from shapely.geometry import Polygon

    p = as_array(points, "points", shape=(None, 2))
    before = abs(signed_area(p))
    geom = shapely.make_valid(Polygon(p))
    polys = [g for g in getattr(geom, "geoms", [geom]) if g.geom_type in ("Polygon", "MultiPolygon")]
    parts = [q for g in polys for q in getattr(g, "geoms", [g])]
    rings, areas, outer = [], [], []
    for q in parts:
        if q.area <= 0:
            continue
        for k, ring in enumerate([q.exterior, *q.interiors]):
            xy = np.asarray(ring.coords, dtype=np.float64)[:-1]
            if len(xy) >= 3 and abs(signed_area(xy)) > 0:
                rings.append(xy)
                areas.append(abs(signed_area(xy)))
                outer.append(k == 0)
    order = np.argsort(-np.asarray(areas), kind="stable")
    after = float(sum(q.area for q in parts))
    return [rings[k] for k in order], int(sum(outer)), float(before), after
