"""Self-intersection of triangle meshes: which faces cut through other faces.

A vectorised triangle-triangle test with a broad phase. The broad phase hashes
every triangle's bounding box into a grid over two axes and sweeps along the
third (:func:`candidate_pairs`), keeping the pairs whose boxes overlap. The
narrow phase decides each candidate pair by segment-triangle tests (Moller &
Trumbore 1997): two triangles in general position intersect exactly when an
edge of one crosses the other. Pairs that share an edge are neighbours and
never count; pairs that share one vertex count when the edge opposite the
shared vertex of one crosses the other. Contacts within a relative tolerance
(a vertex lying on the other face, coplanar touching) do not count,
so a clean mesh welded from patches reads 0.

This is the check of issue 19 ("0 self-intersecting faces"), independent of
the way the surface was built; pymeshlab's per-face test and manifold3d's
booleans are the peers.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from surfaces.validate import as_array

__all__ = ["SelfIntersections", "self_intersections", "candidate_pairs"]

#: Candidate pairs tested per vectorised block (bounds the memory of the narrow phase).
_BLOCK = 200_000


@dataclass(frozen=True)
class SelfIntersections:
    """Faces of a mesh that cut through other faces.

    Attributes
    ----------
    faces : numpy.ndarray, shape (T,) bool
        True for every face that intersects another, non-neighbouring face.
    pairs : numpy.ndarray, shape (P, 2) int64
        The intersecting pairs of face indices (``a < b``).
    n_candidates : int
        Pairs the broad phase handed to the narrow phase (with ``first``, up to the block
        where the test stopped).
    """

    faces: np.ndarray
    pairs: np.ndarray
    n_candidates: int

    @property
    def n_faces(self) -> int:
        """Number of self-intersecting faces."""
        return int(self.faces.sum())


def _cells_per_box(c0: np.ndarray, c1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid cells ``c0 .. c1`` (inclusive, shape (T, 2)) of every box: (box index, cell key) rows."""
    ext = c1 - c0 + 1
    count = ext[:, 0] * ext[:, 1]
    box = np.repeat(np.arange(len(c0)), count)
    # position of each repeated row inside its box's block of cells
    local = np.arange(len(box)) - np.repeat(np.cumsum(count) - count, count)
    ey = ext[box, 1]
    width = int(c1[:, 1].max()) + 1
    return box, (c0[box, 0] + local // ey) * width + c0[box, 1] + local % ey


def _box(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Low and high corners (T, 3) of the boxes of triangles (T, 3, 3); three-way minimum and maximum
    rather than a reduction over the short middle axis, which numpy does several times slower."""
    return np.minimum(np.minimum(c[:, 0], c[:, 1]), c[:, 2]), np.maximum(np.maximum(c[:, 0], c[:, 1]), c[:, 2])


def candidate_pairs(corners: np.ndarray) -> np.ndarray:
    """Broad phase: pairs of triangles whose bounding boxes overlap.

    The boxes are hashed into a grid over the two axes of smallest span (cells
    of the median box extent), and swept along the third axis inside every
    cell; a pair whose boxes share several cells is kept in the cell of the
    overlap's low corner only. Long flat slivers (fans of planar caps) then
    meet only the triangles beside them, not everything within their box's
    extent along the sweep axis.

    Parameters
    ----------
    corners : array_like, shape (T, 3, 3)
        Corner positions of every triangle.

    Returns
    -------
    numpy.ndarray, shape (P, 2) int64
        Unique pairs ``a < b`` whose boxes overlap.
    """
    c = as_array(corners, "corners", shape=(None, 3, 3))
    found = list(_candidate_blocks(c)) if len(c) >= 2 else []
    return np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)


def _candidate_blocks(c: np.ndarray) -> Iterator[np.ndarray]:
    """:func:`candidate_pairs` of corners (T >= 2, 3, 3), block after block (P_i, 2) in the same order.

    The sort is global, the pairs are made block by block: a caller that stops at the first
    intersection (:func:`self_intersections` with ``first``) makes only the blocks it tests.
    """
    lo, hi = _box(c)
    span = hi.max(axis=0) - lo.min(axis=0)
    axis = int(np.argmax(span))
    grid = [k for k in range(3) if k != axis]
    cell = np.maximum(np.median(hi[:, grid] - lo[:, grid], axis=0), span[grid] * 1e-6 + 1e-300)
    # a few huge triangles would otherwise cover millions of cells: coarsen until bounded
    while np.prod(np.floor(hi[:, grid] / cell) - np.floor(lo[:, grid] / cell) + 1, axis=1).sum() > 8 * len(c) + 1000:
        cell = cell * 2.0
    origin = np.floor(lo[:, grid].min(axis=0) / cell)
    c0 = (np.floor(lo[:, grid] / cell) - origin).astype(np.int64)
    c1 = (np.floor(hi[:, grid] / cell) - origin).astype(np.int64)
    tri, key = _cells_per_box(c0, c1)
    width = int(c1[:, 1].max()) + 1
    # rows sorted by (cell, low end along the sweep axis); a row pairs with the rows after it in its
    # cell whose low end does not pass its high end
    start = lo[:, axis].min()
    length = float(hi[:, axis].max() - start) * (1 + 1e-9) + 1e-300
    rank = np.unique(key, return_inverse=True)[1].astype(np.float64)
    sweep = rank + (lo[tri, axis] - start) / length
    order = np.argsort(sweep, kind="stable")
    tri, key, rank, sweep = tri[order], key[order], rank[order], sweep[order]
    end = np.searchsorted(sweep, rank + (hi[tri, axis] - start) / length, side="right")
    end = np.minimum(end, np.searchsorted(rank, rank, side="right"))
    n_after = np.maximum(end - np.arange(len(key)) - 1, 0)
    # raw pairs are made block by block of rows, so memory stays bounded however many there are
    bounds = np.searchsorted(np.cumsum(n_after), np.arange(_BLOCK, int(n_after.sum()) + _BLOCK, _BLOCK))
    cx, cy = c0[:, 0].copy(), c0[:, 1].copy()
    box = np.ascontiguousarray(np.hstack([lo, hi]))  # one gather per pair side, not six
    start = 0
    for stop in np.unique(np.minimum(np.append(bounds + 1, len(key)), len(key))):
        rows = np.arange(start, stop)
        k = n_after[rows]
        first = np.repeat(rows, k)
        offset = np.arange(len(first)) - np.repeat(np.cumsum(k) - k, k)
        a, b = tri[first], tri[first + 1 + offset]
        # boxes that meet in several cells: the pair is kept once, in the cell of the overlap's low corner
        # (tested first: most raw rows are such repeats, and the test needs two integer columns only)
        keep = np.maximum(cx[a], cx[b]) * width + np.maximum(cy[a], cy[b]) == key[first]
        a, b = a[keep], b[keep]
        ba, bb = box[a], box[b]
        keep = (ba[:, 0] <= bb[:, 3]) & (bb[:, 0] <= ba[:, 3])
        for k in (1, 2):
            keep &= (ba[:, k] <= bb[:, k + 3]) & (bb[:, k] <= ba[:, k + 3])
        a, b = a[keep], b[keep]
        yield np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
        start = stop


def _columns(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The x, y and z columns of points (N, 3)."""
    return x[:, 0], x[:, 1], x[:, 2]


def _minus(x: tuple, y: tuple) -> tuple:
    return x[0] - y[0], x[1] - y[1], x[2] - y[2]


def _cross(x: tuple, y: tuple) -> tuple:
    return x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]


def _dot(x: tuple, y: tuple) -> np.ndarray:
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def _segment_hits(p: np.ndarray, q: np.ndarray, tri: np.ndarray, eps: float) -> np.ndarray:
    """Whether segments ``p -> q`` (N, 3) cross triangles (N, 3, 3) in their interiors.

    Column by column (x, y, z arrays): on millions of short rows, numpy's ``cross`` and
    ``einsum`` over a last axis of 3 cost more than the arithmetic written out.
    """
    p = _columns(p)
    t0 = _columns(tri[:, 0])
    d = _minus(_columns(q), p)
    e1 = _minus(_columns(tri[:, 1]), t0)
    e2 = _minus(_columns(tri[:, 2]), t0)
    h = _cross(d, e2)
    det = _dot(e1, h)
    scale = np.sqrt(_dot(d, d)) * np.sqrt(_dot(e1, e1)) * np.sqrt(_dot(e2, e2))
    ok = np.abs(det) > eps * np.maximum(scale, 1e-300)
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = _minus(p, t0)
    u = _dot(s, h) * inv
    qv = _cross(s, e1)
    v = _dot(d, qv) * inv
    t = _dot(e2, qv) * inv
    return ok & (u > eps) & (v > eps) & (u + v < 1 - eps) & (t > eps) & (t < 1 - eps)


def _one_side(corners: np.ndarray, face: np.ndarray, plane: np.ndarray, tol: np.ndarray,
              shared: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether the corners of ``face`` (P,), the ``shared`` ones (P, 3) aside, lie beyond ``tol`` on one side.

    Also returns the side of every corner (P, 3) int8: +1 or -1 beyond ``tol``, 0 within it.

    ``corners`` (T, 3, 3) are per face; ``plane`` (P, 5: normal of length twice the area, the
    plane's offset along it, the normal's length) and ``tol`` (P,) belong to the other triangle
    of every pair.
    No segment between two such corners crosses the plane, so no edge of ``face`` can pierce the
    other triangle.
    """
    d = np.einsum("pij,pj->pi", corners[face], plane[:, :3]) - plane[:, 3:4]
    above, below = d > tol[:, None], d < -tol[:, None]
    side = above.view(np.int8) - below.view(np.int8)
    # column by column: numpy's any/all along a short axis cost more than the three ands
    pos, neg = above | shared, below | shared
    return (pos[:, 0] & pos[:, 1] & pos[:, 2]) | (neg[:, 0] & neg[:, 1] & neg[:, 2]), side


def _shared_corners(ta: np.ndarray, tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which corners of ``a`` are corners of ``b`` and the other way round (vertex indices (P, 3) each).

    Returns ``in_b`` and ``in_a``, (P, 3) bool each: corner ``i`` of ``a`` is a corner of ``b``;
    corner ``j`` of ``b`` is a corner of ``a``.
    """
    eq = [[ta[:, i] == tb[:, j] for j in range(3)] for i in range(3)]
    in_b = np.stack([eq[i][0] | eq[i][1] | eq[i][2] for i in range(3)], axis=1)
    in_a = np.stack([eq[0][j] | eq[1][j] | eq[2][j] for j in range(3)], axis=1)
    return in_b, in_a


def _pairs_intersect(corners: np.ndarray, t: np.ndarray, plane: np.ndarray, tol: np.ndarray,
                     a: np.ndarray, b: np.ndarray, eps: float) -> np.ndarray:
    """Narrow phase for pairs ``a``, ``b`` (P,) of faces: which intersect.

    ``corners`` (T, 3, 3), ``t`` (T, 3) vertex indices, ``plane`` (T, 5) normals (length twice
    the area), offsets and normal lengths, ``tol`` (T,) relative plane-distance tolerances, all per face.
    """
    in_b, in_a = _shared_corners(t[a], t[b])
    n_shared = in_b[:, 0].view(np.int8) + in_b[:, 1].view(np.int8) + in_b[:, 2].view(np.int8)
    hit = np.zeros(len(a), dtype=bool)
    # plane test first (Moller 1997): two triangles meet beyond a shared corner only if each one's
    # corners (the shared one aside) straddle the other's plane. Apart pairs: a triangle whose corners
    # lie on one side of the other's plane cannot touch it. Pairs sharing corner V: if b's other
    # corners lie on one side of a's plane, b meets that plane in V alone, so a and b meet in V
    # alone. Neighbours across an edge never count.
    k = np.flatnonzero(n_shared < 2)
    if not len(k):
        return hit
    ak, bk = a[k], b[k]
    pa, pb = plane[ak], plane[bk]
    tol_k = tol[ak] + tol[bk]
    a_apart, side_a = _one_side(corners, ak, pb, tol_k * pb[:, 4], in_b[k])
    b_apart, side_b = _one_side(corners, bk, pa, tol_k * pa[:, 4], in_a[k])
    keep = ~(a_apart | b_apart)
    sub = k[keep]
    if len(sub):
        hit[sub] = _pairs_intersect_exact(corners[a[sub]], corners[b[sub]], in_b[sub], in_a[sub], n_shared[sub],
                                          eps, side_a[keep], side_b[keep])
    return hit


def _edge_hits(p: np.ndarray, q: np.ndarray, tri: np.ndarray, crosses: np.ndarray, eps: float) -> np.ndarray:
    """:func:`_segment_hits` on the rows where the segment ``crosses`` (N,) the triangle's plane; False elsewhere."""
    h = np.zeros(len(p), dtype=bool)
    m = np.flatnonzero(crosses)
    if len(m):
        h[m] = _segment_hits(p[m], q[m], tri[m], eps)
    return h


def _pairs_intersect_exact(ta: np.ndarray, tb: np.ndarray, in_b: np.ndarray, in_a: np.ndarray,
                           n_shared: np.ndarray, eps: float, side_a: np.ndarray, side_b: np.ndarray) -> np.ndarray:
    """Segment-triangle tests for pairs of triangles (corners (N, 3, 3); shared corners of a and of b (N, 3)).

    ``side_a`` (N, 3) is the side of a's corners of b's plane (+1, -1, or 0 on it), ``side_b`` the
    other way round: an edge whose ends lie beyond the plane on one side cannot cross the triangle.
    """
    hit = np.zeros(len(ta), dtype=bool)
    free = n_shared == 0
    if free.any():
        a, b, sa, sb = ta[free], tb[free], side_a[free], side_b[free]
        h = np.zeros(len(a), dtype=bool)
        for k in range(3):
            n = (k + 1) % 3
            h |= _edge_hits(a[:, k], a[:, n], b, sa[:, k] * sa[:, n] <= 0, eps)
            h |= _edge_hits(b[:, k], b[:, n], a, sb[:, k] * sb[:, n] <= 0, eps)
        hit[free] = h
    one = n_shared == 1
    if one.any():
        a, b = ta[one], tb[one]
        side1, side2 = side_a[one], side_b[one]
        rows = np.arange(len(a))
        sa = np.argmax(in_b[one], axis=1)  # shared corner of a
        sb = np.argmax(in_a[one], axis=1)  # shared corner of b
        # the edge opposite the shared corner
        a1, a2, b1, b2 = (sa + 1) % 3, (sa + 2) % 3, (sb + 1) % 3, (sb + 2) % 3
        h = _edge_hits(a[rows, a1], a[rows, a2], b, side1[rows, a1] * side1[rows, a2] <= 0, eps)
        h |= _edge_hits(b[rows, b1], b[rows, b2], a, side2[rows, b1] * side2[rows, b2] <= 0, eps)
        hit[one] = h
    return hit


def self_intersections(vertices, triangles, *, eps: float = 1e-9, first: bool = False) -> SelfIntersections:
    """Faces of a triangle mesh that intersect other faces.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Vertex positions (any length unit).
    triangles : array_like, shape (T, 3) int
        Vertex indices.
    eps : float
        Relative tolerance of the segment-triangle tests (barycentric and
        segment parameters); contacts within it do not count.
    first : bool
        Stop at the first block of candidate pairs that holds an intersection
        (whether the mesh folds at all): ``faces`` and ``pairs`` then hold some
        of the intersections, not necessarily all; 0 faces still means none.

    Returns
    -------
    SelfIntersections

    Examples
    --------
    Two triangles that cross, and one far away:

    >>> v = [[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [1, -1, 0.1],
    ...      [9, 9, 9], [10, 9, 9], [9, 10, 9]]
    >>> r = self_intersections(v, [[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    >>> r.faces.tolist(), r.pairs.tolist()
    ([True, True, False], [[0, 1]])
    """
    v = as_array(vertices, "vertices", shape=(None, 3))
    t = np.asarray(triangles)
    if t.size == 0:
        t = t.reshape(0, 3)
    if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"triangles: expected an integer array of shape (T, 3), got {t.shape} {t.dtype}")
    if t.size and (t.min() < 0 or t.max() >= len(v)):
        raise ValueError(f"triangles: indices must lie in [0, {len(v)})")
    t = t.astype(np.int64, copy=False)
    faces = np.zeros(len(t), dtype=bool)
    # the narrow phase compares vertex indices of every candidate pair: half the bytes in int32
    t_pairs = t.astype(np.int32) if len(v) < 2**31 else t
    # degenerate (zero-area) faces cannot be pierced in the interior; they are left out
    corners = v[t]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.linalg.norm(normal, axis=1)
    lo, hi = _box(corners)
    size = (hi - lo).max(axis=1)
    # per face: normal, offset, |normal| (the plane test's scale)
    plane = np.column_stack([normal, np.einsum("ij,ij->i", normal, corners[:, 0]), area2])
    # a plane-distance tolerance far above rounding, far below any crossing the segment tests accept
    tol = (eps * 1e-3) * size
    good = np.flatnonzero(area2 > 1e-12 * np.maximum(size, 1e-300) ** 2)
    found = []
    n_pairs = 0
    # each block of the broad phase goes through the narrow phase at once: with ``first``, the
    # pairs after the first intersecting block are never made
    for block in _candidate_blocks(corners[good]) if len(good) >= 2 else ():
        p = good[block]
        n_pairs += len(p)
        hit = _pairs_intersect(corners, t_pairs, plane, tol, p[:, 0], p[:, 1], eps)
        found.append(p[hit])
        if first and hit.any():
            break
    hits = np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)
    faces[hits.ravel()] = True
    return SelfIntersections(faces, hits, n_pairs)
