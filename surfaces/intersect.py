"""Self-intersection of triangle meshes: which faces cut through other faces.

A vectorised triangle-triangle test with a broad phase. The broad phase hashes
every triangle's bounding box into a grid over two axes and sweeps along the
third (:func:`candidate_pairs`; a few faces are compared pair by pair, a few
hundred swept along one axis), keeping the pairs whose boxes overlap. The
narrow phase decides each candidate pair by segment-triangle tests (Moller &
Trumbore 1997): two triangles in general position intersect exactly when an
edge of one crosses the other. Pairs that share an edge are neighbours and
never count; pairs that share one vertex count when the edge opposite the
shared vertex of one crosses the other. Contacts within a relative tolerance
(a vertex lying on the other face, coplanar touching) do not count,
so a clean mesh welded from patches reads 0.

This is the check of issue 19 ("0 self-intersecting faces"), independent of
the way the surface was built; pymeshlab's per-face test and manifold3d's
booleans are the peers. The fold certificate that spares most of this check on
meshes through stacked contours lives in :mod:`surfaces.folds` (its names stay
importable from here).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from surfaces.validate import as_array, InputError

__all__ = ["SelfIntersections", "candidate_pairs", "self_intersections"]

#: Names that moved to :mod:`surfaces.folds` (issue 30); ``surfaces.intersect.<name>`` still finds them.
MOVED_TO_FOLDS = ("fold_suspects", "folded_faces", "is_fold_free", "layered_radial_graph")

#: Candidate pairs tested per vectorised block (bounds the memory of the narrow phase).
_BLOCK = 200_000

#: Default relative tolerance of :func:`self_intersections`' segment-triangle tests.
_EPS = 1e-9


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
    extent along the sweep axis. Cheaper ways give the same pairs on small
    inputs: up to :data:`SMALL_BROAD_PHASE` triangles every pair of boxes is
    compared; while a sweep along the longest axis alone makes at most
    :data:`SWEEP_PAIRS_PER_FACE` raw pairs a triangle, the grid is left out.

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


#: Most triangles whose boxes :func:`candidate_pairs` compares pair by pair (one block), without the grid.
SMALL_BROAD_PHASE = 96

#: Raw pairs per triangle up to which :func:`candidate_pairs` sweeps along one axis without the grid
#: (one block); beyond, long slivers would make too many, and the grid keeps them apart.
SWEEP_PAIRS_PER_FACE = 64


def _candidate_blocks(c: np.ndarray, box: tuple | None = None) -> Iterator[np.ndarray]:
    """:func:`candidate_pairs` of corners (T >= 2, 3, 3), block after block (P_i, 2) in the same order.

    The sort is global, the pairs are made block by block: a caller that stops at the first
    intersection (:func:`self_intersections` with ``first``) makes only the blocks it tests.
    ``box``: the triangles' :func:`_box` when the caller has it.
    """
    lo, hi = _box(c) if box is None else box
    if len(c) <= SMALL_BROAD_PHASE:
        # every pair's boxes compared at once: cheaper than the grid and the sweep on a few faces
        # as an (n, n) table: broadcasting costs less than gathering both boxes of every pair
        # (the upper triangle by one comparison of indices: np.triu builds a mask and copies)
        # (the six comparisons in one call: lo_a <= hi_b and -hi_a <= -lo_b along each axis, negating exactly,
        # with the boxes' six coordinates along the first axis of the table, contiguous, so that its rows are long)
        low = np.concatenate([lo, -hi], axis=1).T.copy()
        high = np.concatenate([hi, -lo], axis=1).T.copy()
        meet = (low[:, :, None] <= high[:, None, :]).all(axis=0)
        idx = np.arange(len(c))
        meet &= idx[:, None] < idx
        yield _pair_rows(*meet.nonzero())  # np.argwhere's pairs, without its wrapper
        return
    span = hi.max(axis=0) - lo.min(axis=0)
    axis = int(np.argmax(span))
    grid = [k for k in range(3) if k != axis]
    # one sweep along the longest axis, without the grid, while it makes few raw pairs (a few hundred
    # suspect faces of a fold check): each box pairs with the boxes after it whose low end does not pass
    # its high end, then the other two axes are compared
    order = np.argsort(lo[:, axis], kind="stable")
    n_after = np.searchsorted(lo[order, axis], hi[order, axis], side="right") - np.arange(1, len(c) + 1)
    n_after = np.maximum(n_after, 0)
    if int(n_after.sum()) <= min(_BLOCK, SWEEP_PAIRS_PER_FACE * len(c)):
        first = np.repeat(np.arange(len(c)), n_after)
        a = order[first]
        b = order[first + np.arange(1, len(first) + 1) - np.repeat(np.cumsum(n_after) - n_after, n_after)]
        keep = (lo[a, grid[0]] <= hi[b, grid[0]]) & (lo[b, grid[0]] <= hi[a, grid[0]])
        keep &= (lo[a, grid[1]] <= hi[b, grid[1]]) & (lo[b, grid[1]] <= hi[a, grid[1]])
        a, b = a[keep], b[keep]
        yield _pair_rows(a, b, ordered=False)
        return
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
        yield _pair_rows(a, b, ordered=False)
        start = stop


def _pair_rows(a: np.ndarray, b: np.ndarray, ordered: bool = True) -> np.ndarray:
    """Pairs (P, 2) int64 of face indices ``a``, ``b`` (P,); unless ``ordered``, each pair's lower index
    first. Written column by column into one array: cheaper than np.stack on a few hundred pairs."""
    pairs = np.empty((len(a), 2), dtype=np.int64)
    if ordered:
        pairs[:, 0], pairs[:, 1] = a, b
    else:
        np.minimum(a, b, out=pairs[:, 0])
        np.maximum(a, b, out=pairs[:, 1])
    return pairs


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
    # every (corner of a, corner of b) at once, (P, 3, 3); the ors along either short axis written out
    eq = ta[:, :, None] == tb[:, None, :]
    return eq[:, :, 0] | eq[:, :, 1] | eq[:, :, 2], eq[:, 0] | eq[:, 1] | eq[:, 2]


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
    k = (n_shared < 2).nonzero()[0]
    if not len(k):
        return hit
    m = len(k)
    # both ways at once, in one set of rows: a's corners against b's plane (the first m rows), then b's
    # against a's (the sums of the tolerances commute exactly)
    ak, bk = a[k], b[k]
    face, other = np.concatenate([ak, bk]), np.concatenate([bk, ak])
    po = plane[other]
    shared = np.concatenate([in_b[k], in_a[k]])
    apart, side = _one_side(corners, face, po, (tol[face] + tol[other]) * po[:, 4], shared)
    keep = ~(apart[:m] | apart[m:])
    sub = k[keep]
    if len(sub):
        both = np.concatenate([keep, keep])
        hit[sub] = _pairs_intersect_exact(corners, face[both], other[both], shared[both], eps, side[both])
    return hit


def _pairs_intersect_exact(corners: np.ndarray, face: np.ndarray, other: np.ndarray, shared: np.ndarray,
                           eps: float, side: np.ndarray) -> np.ndarray:
    """Segment-triangle tests for N pairs of triangles, both ways: rows ``face`` (2 N,) of ``corners``
    (T, 3, 3) against rows ``other`` (2 N,), the pairs' ``a`` against ``b`` in the first N rows, then ``b``
    against ``a`` in the same order; ``shared`` (2 N, 3) the corners of ``face`` that are corners of
    ``other`` (at most one a pair); the hit of every pair (N,).

    ``side`` (2 N, 3) is the side of the corners of ``face`` of the plane of ``other`` (+1, -1, or 0 on
    it): an edge whose ends lie beyond the plane on one side cannot cross the triangle.
    Pairs without a shared corner test every edge of each triangle against the other; pairs
    sharing one corner the edge opposite it. All the tests of all pairs go through one call of
    :func:`_segment_hits`.
    """
    n = len(face) // 2
    nxt = np.array([1, 2, 0])
    # edge k runs from corner k to corner k + 1; it can cross the other triangle only where its ends do
    # not lie beyond the other's plane on one side, and (a shared corner) only as the edge opposite it,
    # the one that touches no shared corner (pairs share at most one corner here)
    need = side * side[:, nxt] <= 0
    need &= ~(shared | shared[:, nxt])
    r, k = need.nonzero()
    hit = np.zeros(2 * n, dtype=bool)
    if len(r):
        corner = corners.reshape(-1, 3)
        fr = 3 * face[r]
        h = _segment_hits(corner[fr + k], corner[fr + nxt[k]], corners[other[r]], eps)
        hit[r[h]] = True
    return hit[:n] | hit[n:]


def self_intersections(vertices, triangles, *, eps: float = _EPS, first: bool = False) -> SelfIntersections:
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
    return _self_intersections(*_checked(vertices, triangles, empty=True), eps, first)


def _checked(vertices, triangles, empty: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 and triangles (T, 3) int64 of a mesh, validated (one pass for the
    certificate and the exact test, :func:`_exact_on_suspects`); with ``empty``, no triangles in any
    shape are none."""
    v = as_array(vertices, "vertices", shape=(None, 3))
    t = np.asarray(triangles)
    if empty and t.size == 0:
        t = t.reshape(0, 3)
    if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"triangles: expected an integer array of shape (T, 3), got {t.shape} {t.dtype}")
    if t.size and (t.min() < 0 or t.max() >= len(v)):
        raise InputError(f"triangles: indices must lie in [0, {len(v)})")
    return v, t.astype(np.int64, copy=False)


def _self_intersections(v: np.ndarray, t: np.ndarray, eps: float, first: bool) -> SelfIntersections:
    """:func:`self_intersections` of validated vertices (V, 3) float64 and triangles (T, 3) int64 (:func:`_checked`)."""
    faces = np.zeros(len(t), dtype=bool)
    # the narrow phase compares vertex indices of every candidate pair: half the bytes in int32
    t_pairs = t.astype(np.int32) if len(v) < 2**31 else t
    # degenerate (zero-area) faces cannot be pierced in the interior; they are left out
    corners = v[t]
    # per face: normal, offset, |normal| (the plane test's scale), one (T, 5) table written column by
    # column (numpy's cross, norm and einsum over a last axis of 3 cost more than the arithmetic)
    plane = np.empty((len(t), 5))
    c0 = _columns(corners[:, 0])
    normal = _cross(_minus(_columns(corners[:, 1]), c0), _minus(_columns(corners[:, 2]), c0))
    plane[:, 0], plane[:, 1], plane[:, 2] = normal
    plane[:, 3] = _dot(normal, c0)
    area2 = plane[:, 4]
    np.sqrt(_dot(normal, normal), out=area2)
    lo, hi = _box(corners)
    extent = hi - lo
    size = np.maximum(np.maximum(extent[:, 0], extent[:, 1]), extent[:, 2])
    # a plane-distance tolerance far above rounding, far below any crossing the segment tests accept
    tol = (eps * 1e-3) * size
    good = (area2 > 1e-12 * np.maximum(size, 1e-300) ** 2).nonzero()[0]
    found = []
    n_pairs = 0
    # each block of the broad phase goes through the narrow phase at once: with ``first``, the
    # pairs after the first intersecting block are never made
    for block in _candidate_blocks(corners[good], (lo[good], hi[good])) if len(good) >= 2 else ():
        p = good[block]
        n_pairs += len(p)
        hit = _pairs_intersect(corners, t_pairs, plane, tol, p[:, 0], p[:, 1], eps)
        found.append(p[hit])
        if first and hit.any():
            break
    hits = np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)
    faces[hits.ravel()] = True
    return SelfIntersections(faces, hits, n_pairs)


def __getattr__(name: str):
    # the fold certificate's names, loaded from their home on first use (surfaces.folds imports this module)
    if name in MOVED_TO_FOLDS:
        from surfaces import folds

        return getattr(folds, name)
    raise AttributeError(f"module 'surfaces.intersect' has no attribute {name!r}")
