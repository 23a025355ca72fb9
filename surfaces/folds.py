"""The fold certificate of layered meshes: which faces could possibly cross another.

:func:`fold_suspects` is a certificate that spares most of the exact
self-intersection test (:func:`surfaces.intersect.self_intersections`) on the
meshes that surfaces through stacked contours give: closed meshes whose
vertices lie on horizontal levels, every band between two levels a radial
graph about a vertical axis but for a few faces. It proves, in a few vectorised
operations, that no face outside a small set of suspects crosses anything, and
:func:`is_fold_free` runs the exact test on the suspects alone.
"""

from __future__ import annotations

import numpy as np

from surfaces.intersect import _EPS, _checked, _self_intersections
from surfaces.mesh import _KEPT_LATTICE, _grid_triangles, _kept_triangles

__all__ = ["fold_suspects", "folded_faces", "is_fold_free", "layered_radial_graph"]


def _closed_and_oriented(t: np.ndarray, n_vertices: int) -> bool:
    """Whether every directed edge of triangles ``t`` (T, 3) occurs once and its reverse once."""
    # half the bytes to sort where the codes fit
    t = t.astype(np.int32) if 2 * n_vertices * n_vertices + 2 < 2**31 else t
    b = np.empty_like(t)
    b[:, :2], b[:, 2] = t[:, 1:], t[:, 0]
    return _edges_paired(t.ravel(), b.ravel(), n_vertices)


def _edges_paired(a: np.ndarray, b: np.ndarray, n_vertices: int) -> bool:
    """Whether every directed edge ``a -> b`` (E,) occurs once and its reverse once."""
    # one sort: each undirected edge must come exactly twice, once each way (codes 2 key and 2 key + 1)
    code = np.minimum(a, b)
    code *= 2 * n_vertices
    high = np.maximum(a, b)
    high *= 2
    code += high
    code += a > b
    code.sort()
    if len(code) % 2:
        return False
    first, second = code[0::2], code[1::2]
    first += 1
    return bool((second == first).all() and (second & 1).all())


#: Relative spread of ``z`` (of the largest ``|z|``) within one level of :func:`fold_suspects`.
LEVEL_RTOL = 1e-13

#: Angular bins of a band's circle in :func:`fold_suspects` (arcs are widened to whole bins and one more;
#: a power of two).
ANGLE_BINS = 1024

#: From this many faces on, :func:`fold_suspects` takes the lattice form where it applies (on fewer, its
#: fixed cost outweighs the gathers it spares; both forms give the same suspects).
LATTICE_MIN_FACES = 5000

#: Up to this many (arc, bad arc) pairs, :func:`fold_suspects` compares every arc with the bad faces' arcs
#: directly, without the table of taken bins (both give the same suspects; beyond, the table is cheaper).
DIRECT_ARC_PAIRS = 1 << 15

#: Above this many bands with faces turning back, :func:`fold_suspects` gives up (the exact test is as cheap).
MAX_WORRIED_BANDS = 1024


def _arcs(px: np.ndarray, py: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angular range about ``(cx, cy)`` (F,) of triangles with corners ``(px, py)`` (F, 3): low end and length (rad).

    Lengths of pi and more mean the triangle may hold ``c`` (then every direction is taken).
    """
    return _angle_arcs(np.arctan2(py - cy[:, None], px - cx[:, None]))


def _angle_arcs(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_arcs` from the corners' angles ``phi`` (..., 3) (rad)."""
    return _steps_arcs(phi[..., 0], phi[..., 1] - phi[..., 0], phi[..., 2] - phi[..., 0])


def _wrap(d: np.ndarray) -> np.ndarray:
    """Angle differences ``d`` of angles in [-pi, pi] brought into [-pi, pi), in place."""
    # one turn at most either way: a masked subtraction, several times cheaper than a float modulo
    np.subtract(d, 2 * np.pi, out=d, where=d >= np.pi)
    np.add(d, 2 * np.pi, out=d, where=d < -np.pi)
    return d


def _steps_arcs(phi0: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_arcs` of triangles from the angle of one corner and the differences to the other two's
    (fresh arrays, wrapped in place), all of one shape (rad)."""
    return _wrapped_arcs(phi0, _wrap(d1), _wrap(d2))


def _wrapped_arcs(phi0: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_steps_arcs` of differences ``d1``, ``d2`` already in [-pi, pi) (rad)."""
    low = np.minimum(d1, d2)
    np.minimum(low, 0.0, out=low)
    high = np.maximum(d1, d2)
    np.maximum(high, 0.0, out=high)
    high -= low
    low += phi0
    return low, high


def _bins(low: np.ndarray, length: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First bin and bin count (F,) of arcs, widened by one bin each side (rounding of the angles).

    ``low`` and ``length`` are fresh arrays (of :func:`_wrapped_arcs`), overwritten: the operations run in
    place, the same ones in the same order as ``(low + pi) / (2 pi) * bins``.
    """
    full = length >= np.pi * (1 - 1e-9)
    low += np.pi
    low /= 2 * np.pi
    low *= ANGLE_BINS
    first = np.floor(low, out=low).astype(np.int64)
    first -= 1
    length /= 2 * np.pi
    length *= ANGLE_BINS
    count = np.ceil(length).astype(np.int64)
    count += 3
    # the bins a power of two: the modulo of a two's complement integer is its low bits (no division)
    np.bitwise_and(first, ANGLE_BINS - 1, out=first)
    return np.where(full, 0, first), np.where(full, ANGLE_BINS, np.minimum(count, ANGLE_BINS))


def _arc_suspects(t: np.ndarray, X: np.ndarray, Y: np.ndarray, group: np.ndarray, bad_face: np.ndarray,
                  once: np.ndarray, worried: np.ndarray, cx: np.ndarray, cy: np.ndarray,
                  rings: np.ndarray | None = None) -> np.ndarray | None:
    """The suspects of :func:`fold_suspects` from its per-face groups and bad faces and its per-band axes.

    ``rings``: the ``x`` and ``y`` (2, R + 1, C) of a mesh of :func:`_lattice_shape` (its first ring repeated
    last), whose side faces are then
    seen from the axes through the angles of their rings' vertices (each once per ring and axis, not
    once per corner; the same angles).
    """
    n_bands = len(once)
    suspect = np.zeros(len(t), dtype=bool)
    worry = worried.nonzero()[0]
    if len(worry) > MAX_WORRIED_BANDS:
        return None
    # every face is looked at from the axis of each worried band within one of its group, all (face,
    # band) pairs at once
    slot = np.full(n_bands, -1)
    slot[worry] = np.arange(len(worry))
    near = worried.copy()  # bands within one of a worried band
    near[1:] |= worried[:-1]
    near[:-1] |= worried[1:]
    n_side = 0 if rings is None else 2 * (rings.shape[1] - 1) * n_bands
    seen = n_side + near[group[n_side:]].nonzero()[0]
    if len(seen) or rings is None:
        faces, bands = [], []
        for step in (-1, 0, 1):
            k = group[seen] + step
            ok = ((k >= 0) & (k < n_bands)).nonzero()[0]
            ok = ok[slot[k[ok]] >= 0]
            faces.append(seen[ok])
            bands.append(k[ok])
        f, k = np.concatenate(faces), np.concatenate(bands)
        tf = t[f]
        first, count = _bins(*_arcs(X[tf], Y[tf], cx[k], cy[k]))
    if rings is not None:
        f_side, k_side, first_side, count_side = _lattice_arcs(rings, worry, cx, cy)
        if len(seen):
            f, k = np.concatenate([f_side, f]), np.concatenate([k_side, k])
            first, count = np.concatenate([first_side, first]), np.concatenate([count_side, count])
        else:
            # no cap face lies near a worried band (the worried bands are inner ones): the side faces alone,
            # without some thirty calls on empty arrays
            f, k, first, count = f_side, k_side, first_side, count_side
    w = slot[k]
    # a bad face marks the bins of its arc about its own band's axis (a full arc: all of them)
    bad = (bad_face[f] & (group[f] == k)).nonzero()[0]
    if len(bad) * len(f) <= DIRECT_ARC_PAIRS:
        # a few bad arcs: each (face, band) arc compared with the bad arcs of its band at once. Two arcs of
        # whole bins on the circle share a bin exactly when one starts within the other: the same answer as
        # the table of taken bins below
        # ((B, F) tables: the long axis last; the bins in int16, a quarter of the bytes to write)
        first16, count16 = first.astype(np.int16), count.astype(np.int16)
        bw, bf, bc = w[bad, None], first16[bad, None], count16[bad, None]
        meet = ((bf - first16) & (ANGLE_BINS - 1)) < count16
        meet |= ((first16 - bf) & (ANGLE_BINS - 1)) < bc
        meet &= w == bw
        hit = meet.any(axis=0)
    else:
        cover = np.zeros((len(worry), 2 * ANGLE_BINS + 1), dtype=np.int32)
        np.add.at(cover, (w[bad], first[bad]), 1)
        np.add.at(cover, (w[bad], first[bad] + count[bad]), -1)
        cover = cover.cumsum(axis=1)[:, :2 * ANGLE_BINS]
        taken = (cover[:, :ANGLE_BINS] + cover[:, ANGLE_BINS:]) > 0
        # the taken bins counted over two turns: the second turn's counts are the first's plus a whole turn's
        prefix = np.zeros((len(worry), 2 * ANGLE_BINS + 1), dtype=np.int32)
        turn = prefix[:, 1:ANGLE_BINS + 1]
        taken.cumsum(axis=1, out=turn)
        np.add(turn, turn[:, -1:], out=prefix[:, ANGLE_BINS + 1:])
        # gathered from the flat table (one index a pick, not (row, column) pairs)
        at = w * (2 * ANGLE_BINS + 1) + first
        flat = prefix.reshape(-1)
        hit = flat[at + count] - flat[at] > 0
    hit |= ~once[k]
    suspect[f[hit]] = True
    return suspect


def _lattice_arcs(xy: np.ndarray, worry: np.ndarray, cx: np.ndarray,
                  cy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (face, band) pairs of :func:`_arc_suspects` for the side faces of a lattice (x and y (2, R + 1, C),
    the first ring repeated last).

    Each band ``j`` within one of a worried band ``k``, its faces seen from ``k``'s axis: their
    indices, ``k``, and their arcs' first bin and bin count (as :func:`_bins` of :func:`_arcs`), all
    (2 R P,) for the P pairs.
    """
    rows, cols = xy.shape[1] - 1, xy.shape[2]
    j = (worry[:, None] + np.arange(-1, 2)).ravel()
    k = np.repeat(worry, 3)
    ok = (j >= 0) & (j < cols - 1)
    j, k = j[ok], k[ok]
    n_pairs = len(j)
    # the angles of rings j (first P columns) and j + 1 (last P) about k's axis, (R + 1, 2 P), in one pass
    pick = np.concatenate([j, j + 1])
    at = np.concatenate([k, k])
    angle = np.arctan2(xy[1][:, pick] - cy[at], xy[0][:, pick] - cx[at])
    low, high = angle[:, :n_pairs], angle[:, n_pairs:]
    a = low[:-1]
    # cell g's faces (a, b, c) = ((g, j), (g + 1, j), (g + 1, j + 1)), (a, c, d) = ((g, j), (g + 1, j + 1), (g, j + 1)):
    # the angles of b, c, d less a's, c's shared by both; both faces' two steps in one (2, 2, R, P) block,
    # so that each step of _steps_arcs is one call for both faces
    step = np.empty((2, 2, rows, n_pairs))
    np.subtract(low[1:], a, out=step[0, 0])
    np.subtract(high[1:], a, out=step[0, 1])
    step[1, 0] = step[0, 1]
    np.subtract(high[:-1], a, out=step[1, 1])
    first, count = _bins(*_wrapped_arcs(a, *_wrap(step).swapaxes(0, 1)))
    face = np.empty((2, rows, n_pairs), dtype=np.int64)
    np.add(np.arange(0, rows * (cols - 1), cols - 1)[:, None], j, out=face[0])
    np.add(face[0], rows * (cols - 1), out=face[1])
    band = np.empty((2 * rows, n_pairs), dtype=k.dtype)
    band[:] = k
    return face.reshape(-1), band.reshape(-1), first.reshape(-1), count.reshape(-1)


def _lattice_shape(t: np.ndarray, n_vertices: int) -> tuple[int, int] | None:
    """Rings and levels ``(R, C)`` when ``t`` begins with the triangles of a lattice, else None.

    The lattice is :func:`surfaces.mesh.tessellate`'s of a side closed along its rings: vertex ``g C + h``
    is sample ``g`` of ring ``h``, and the first ``2 R (C - 1)`` triangles are its cells' (all ``(a, b, c)``
    first, then all ``(a, c, d)``). Recognised from the first triangle and the first one that wraps, then
    compared whole.
    """
    cols = int(t[0, 1])
    if cols < 2 or t[0, 0] != 0 or t[0, 2] != cols + 1:
        return None
    # the cells of the last level (every cols - 1-th triangle from cols - 2): the first that wraps is on the last ring
    last = t[cols - 2::cols - 1]
    rows = int(np.argmax(last[:, 1] < last[:, 0])) + 1
    if rows < 3 or rows * cols > n_vertices or 2 * rows * (cols - 1) > len(t):
        return None
    # compared with the lattice's triangles as surfaces.mesh keeps them per shape (read-only; no copy to make)
    lattice = (_kept_triangles(rows, cols, True, False) if rows * cols <= _KEPT_LATTICE
               else _grid_triangles(rows, cols, True, False))
    if not (t[:2 * rows * (cols - 1)] == lattice).all():
        return None
    return rows, cols


def _beyond(way: int, sign: np.ndarray, e: np.ndarray, bound: float | None) -> np.ndarray:
    """``sign * e > bound`` (``>= 0`` for None) for band signs ``sign`` (C,) of ``e`` (R, C), without the products
    when every band turns one way (``way`` +1 or -1, else 0; negating is exact)."""
    if way > 0:
        return e >= 0 if bound is None else e > bound
    if way < 0:
        return e <= 0 if bound is None else e < -bound
    return sign * e >= 0 if bound is None else sign * e > bound


def _crossings(px: np.ndarray, py: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> tuple[tuple, np.ndarray]:
    """Signed crossings of the half-line ``y = 0, x > 0`` by edges ``p -> q`` (points relative to the
    half-line's origin, arrays of one shape): the index tuple of the edges that cross ``y = 0`` and each
    one's count, +1 upward with the origin on its left, -1 downward with it on its right, else 0 (int8).

    Summed over a closed chain: its winding number about the origin, the same integer as its angle
    steps summed over 2 pi wherever no edge passes through the origin, without an arctangent a vertex;
    the turns are taken only on the few edges that cross ``y = 0``.
    """
    up = py <= 0
    at = np.nonzero(up != (qy <= 0))
    turn = px[at] * qy[at] - py[at] * qx[at]
    up = up[at]
    return at, (up & (turn > 0)).view(np.int8) - (~up & (turn < 0)).view(np.int8)


def _winds_once(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Whether the closed chains of points ``(x, y)`` (N + 1, B) (relative to their column's axis, one chain per
    column running down its rows, the last row the first again) wind once about the axis, either way
    (:func:`_crossings`); (B,) bool."""
    n_bands = x.shape[1]
    # on the flat rows (contiguous): one index an edge, cheaper to find and gather than (row, band) pairs
    (at,), step = _crossings(x[:-1].reshape(-1), y[:-1].reshape(-1), x[1:].reshape(-1), y[1:].reshape(-1))
    return np.abs(np.bincount(at % n_bands, step, n_bands)) == 1


def _lattice_suspects(v: np.ndarray, t: np.ndarray, rows: int, cols: int, margin: float) -> np.ndarray | None:
    """:func:`fold_suspects` on a mesh of :func:`_lattice_shape` when it clears every face, else None.

    The same proof and the same per-face quantities, taken along the lattice's rings instead of
    gathered face by face: each ring's steps ``p_{g+1} - p_g`` serve the two bands it borders, the
    mid-height cut of a band is the ring of midpoints ``M_g`` of its columns and of its diagonals
    ``D_g``, each shared by two faces' cuts. Only the band axes' centroid sums run in another order
    (a rounding apart). None when anything is not as the lattice form needs (the levels are not the
    lattice's columns, a face is not good, a winding is not one): then the general form decides.
    """
    n, n_side = rows * cols, 2 * rows * (cols - 1)
    z = v[:, 2]
    zs = z[:n].reshape(rows, cols)
    lo, hi = zs.min(axis=0), zs.max(axis=0)
    zc = z[n:]
    tol = LEVEL_RTOL * max(float(max(hi.max(), -lo.min(), *(zc.max(), -zc.min()) if len(zc) else ())), 1e-300)
    cap_low = zc < (hi[0] + lo[1]) / 2
    for end, on in ((0, cap_low), (-1, ~cap_low)):
        if on.any():
            lo[end], hi[end] = min(lo[end], zc[on].min()), max(hi[end], zc[on].max())
    # each column (with the cap vertices of its end) one level of the general form: its values within
    # tol of each other, apart by more than tol from the next column's
    if (hi - lo > tol).any() or (lo[1:] - hi[:-1] <= tol).any():
        return None
    level = np.empty(len(v), dtype=np.int64)
    level[:n].reshape(rows, cols)[:] = np.arange(cols)
    level[n:] = np.where(cap_low, 0, cols - 1)
    tc = t[n_side:]
    lc = level[tc]
    if (lc[:, 0] != lc[:, 1]).any() or (lc[:, 0] != lc[:, 2]).any():
        return None
    # closed and oriented: the lattice's inner edges pair by construction, its two boundary rings and
    # the caps' (flat, so on the end levels where the lattice has boundary edges only) must pair up
    g = np.arange(rows) * cols
    gn = g + cols  # the next ring's first vertex, the last ring's the first ring's
    gn[-1] = 0
    top = cols - 1
    # half the bytes to sort where the codes fit (as in _closed_and_oriented)
    small = 2 * len(v) * len(v) + 2 < 2**31
    a = np.concatenate([g, gn + top, tc.ravel()], dtype=np.int32 if small else np.int64)
    b = np.empty_like(tc, dtype=a.dtype)
    b[:, :2], b[:, 2] = tc[:, 1:], tc[:, 0]
    if not _edges_paired(a, np.concatenate([gn, g + top, b.ravel()], dtype=a.dtype), len(v)):
        return None
    X, Y = v[:, 0] - v[:, 0].mean(), v[:, 1] - v[:, 1].mean()
    tiny = margin * (2.0 * max(float(np.abs(X).max()), float(np.abs(Y).max()))) ** 2
    # every cap face's turn at once (the same products per face), then each end level's apart
    c0, c1, c2 = tc[:, 0], tc[:, 1], tc[:, 2]
    x0, y0 = X[c0], Y[c0]
    turn = (X[c1] - x0) * (Y[c2] - y0) - (Y[c1] - y0) * (X[c2] - x0)
    cap_face_low = lc[:, 0] == 0
    for on in (cap_face_low, lc[:, 0] == top):
        area = turn[on]
        if len(area) and not ((area > tiny).all() or (area < -tiny).all()):
            return None
    # the rings with the first repeated last, x and y stacked (2, R + 1, C): each ring's next is a view, not a
    # rolled copy, and one call serves both coordinates wherever they are treated alike
    xy = np.empty((2, rows + 1, cols))
    xy[0, :rows], xy[1, :rows] = X[:n].reshape(rows, cols), Y[:n].reshape(rows, cols)
    xy[:, rows] = xy[:, 0]
    xs, ys, xn, yn = xy[0, :-1], xy[1, :-1], xy[0, 1:], xy[1, 1:]
    # the cut of band h at mid-height: M_g -> D_g (face (a, c, d) of cell g), D_g -> M_{g+1} (face (a, b, c)),
    # one closed chain a column, M_g in the even rows and D_g in the odd ones (2, 2 R + 1, C - 1), so that its
    # edges are consecutive rows; written in place, in a buffer that then takes the rings seen from the axes
    # (a few large arrays fewer: fresh ones cost page faults)
    buffer = np.empty((2, 2 * rows + 2, cols - 1))
    chain = buffer[:, :-1]
    me, d = chain[:, 0::2], chain[:, 1::2]
    np.add(xy[:, :, 1:], xy[:, :, :-1], out=me)
    np.add(xy[:, :-1, :-1], xy[:, 1:, 1:], out=d)
    chain /= 2.0
    mx, my, mnx, mny = me[0, :-1], me[1, :-1], me[0, 1:], me[1, 1:]
    dx, dy = d[0], d[1]
    w0 = dx * mny - dy * mnx
    w1 = mx * dy - my * dx
    area = w0.sum(axis=0) + w1.sum(axis=0)
    if (area == 0).any():
        return None
    # the band axes written into one (2, 1, C - 1) array, which the rings are then seen from at once
    axis = np.empty((2, 1, cols - 1))
    cx, cy = axis[0, 0], axis[1, 0]
    np.divide(((dx + mnx) * w0).sum(axis=0) + ((mx + dx) * w1).sum(axis=0), 3.0 * area, out=cx)
    np.divide(((dy + mny) * w0).sum(axis=0) + ((my + dy) * w1).sum(axis=0), 3.0 * area, out=cy)
    sign = np.sign(area)
    way = 1 if (sign > 0).all() else -1 if (sign < 0).all() else 0
    # the cut's winding about the axis: its points seen from it
    chain -= axis
    once = _winds_once(chain[0], chain[1])
    # the rings seen from the axes of the bands below (q1) and above (q0) them, (2, R + 1, C - 1) each, in the
    # chain's buffer
    qe = buffer.reshape(2, 2, rows + 1, cols - 1)
    qe0, qe1 = qe
    np.subtract(xy[:, :, :-1], axis, out=qe0)
    np.subtract(xy[:, :, 1:], axis, out=qe1)
    q0x, q0y, q0nx, q0ny = qe0[0, :-1], qe0[1, :-1], qe0[0, 1:], qe0[1, 1:]
    q1x, q1y, q1nx, q1ny = qe1[0, :-1], qe1[1, :-1], qe1[0, 1:], qe1[1, 1:]
    ex, ey = xn - xs, yn - ys
    # face (a, b, c): edge on ring h, lone corner (g + 1, h + 1); face (a, c, d): edge on ring h + 1, lone (g, h)
    good0 = _beyond(way, sign, q0x * q0ny - q0y * q0nx, tiny)
    good0 &= _beyond(way, sign, q1nx * ey[:, :-1] - q1ny * ex[:, :-1], None)
    good1 = _beyond(way, sign, q1x * q1ny - q1y * q1nx, tiny)
    good1 &= _beyond(way, sign, q0x * ey[:, 1:] - q0y * ex[:, 1:], None)
    worried = ~once | ~good0.all(axis=0) | ~good1.all(axis=0)
    if not worried.any():
        return np.zeros(len(t), dtype=bool)
    group = np.empty(len(t), dtype=np.int32)  # half the bytes of a fresh array (the bands fit)
    group[:n_side].reshape(2 * rows, cols - 1)[:] = np.arange(cols - 1)
    group[n_side:] = np.where(cap_face_low, 0, cols - 2)
    bad_face = np.zeros(len(t), dtype=bool)
    bad_face[:n_side // 2] = ~good0.ravel()
    bad_face[n_side // 2:n_side] = ~good1.ravel()
    return _arc_suspects(t, X, Y, group, bad_face, once, worried, cx, cy, xy)


def fold_suspects(vertices, triangles, *, margin: float = 1e-12) -> np.ndarray | None:
    """Faces of a closed mesh of stacked bands that may cross another; every other face provably does not.

    Every pair of faces that intersect (as :func:`self_intersections` counts them)
    has both its faces in the mask, so the exact test on the suspects alone
    (``self_intersections(vertices, triangles[mask])``) decides the whole mesh; an
    empty mask proves it free of self-intersections without any test. None when
    the mesh is not of the kind below (then only the exact test decides).

    The mesh must be closed and consistently oriented (every directed edge once,
    its reverse once), its vertices on horizontal levels ``z_0 < z_1 < ...``
    (``z`` values apart by at most :data:`LEVEL_RTOL` times the largest ``|z|``
    along the sorted values are one level, spread over at most four times that:
    the rounding of evaluating patches,
    which the proof treats as exact and which lies far below the contacts
    :func:`self_intersections` counts), every face spanning two consecutive
    levels (a band face) or lying on the lowest or highest level (a cap face),
    and the cap faces of a level, seen from above, all turning one way.

    The proof. In a band, the cut of a face at relative height ``s`` in (0, 1)
    is a segment ``A(s) B(s)`` whose ends move linearly with ``s``; seen from the
    band's vertical axis ``c`` it sweeps ``cross(A - c, B - c)``, which is
    ``(1 - s) g(s)`` for a face with one corner above and ``s g(s)`` for one with
    one corner below, ``g`` linear. A face is good when ``g`` has the band's sign
    beyond ``margin`` times the squared extent at the end where the cut is a
    segment and is not of the other sign where it shrinks to the lone corner:
    its cut then turns the band's way at every height, its edge on the level too.
    The cuts of the band's faces form closed chains (the mesh is closed and
    oriented) that wind about ``c`` once in all (checked at mid-height; the
    winding cannot change with ``s`` unless a cut passes through ``c``, which no
    good face's does and a bad face's arc then covers every direction). So every
    direction from ``c`` outside the arcs of the bad faces is crossed by the cut
    exactly once, at every height and, in the limit, on the two level rings: two
    faces can meet at a point of such a direction only on an edge or vertex they
    share, between the levels as on the rings (a ring edge whose two faces lie in
    one band would pass twice, the second time turning back, which makes its face
    bad). Faces of bands two levels apart never meet. So two faces that cross
    both lie at directions of a bad face's arc of their band or of a band next to
    theirs: those faces are the suspects (all faces of a band and its neighbours
    when its winding is not one or a bad face may hold its axis). Cap faces that
    turn one way with a simple ring as boundary cover its inside once and meet
    the band on the ring only; they are suspects in the arcs of the band they
    close.

    ``c`` is the lone vertex of a band that narrows to one point (a fan to an
    apex), otherwise the area centroid of the band's cut at mid-height. Arcs are
    compared on :data:`ANGLE_BINS` bins, widened to whole bins and one more.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        Vertex positions (any length unit; ``z`` is the stacking axis).
    triangles : array_like, shape (T, 3) int
        Vertex indices.
    margin : float
        Relative margin of the strict signs (of the squared extent of the mesh, twice its largest |x| or |y|
        from the mean vertex).

    Returns
    -------
    numpy.ndarray, shape (T,) bool, or None
        The suspects; None when the mesh is not closed, oriented and layered as
        above, or more than :data:`MAX_WORRIED_BANDS` bands hold faces that turn back.

    Examples
    --------
    A closed square prism of two bands, and the same with one vertex of the
    middle ring pushed across to the other side (its faces turn back):

    >>> sq = [[0, 0], [1, 0], [1, 1], [0, 1]]
    >>> v = np.array([[x, y, z] for z in (0, 1, 2) for x, y in sq], float)
    >>> band = [[4 * k + i, 4 * k + (i + 1) % 4, 4 * k + 4 + (i + 1) % 4] for k in (0, 1) for i in range(4)]
    >>> band += [[4 * k + i, 4 * k + 4 + (i + 1) % 4, 4 * k + 4 + i] for k in (0, 1) for i in range(4)]
    >>> caps = [[0, 2, 1], [0, 3, 2], [8, 9, 10], [8, 10, 11]]
    >>> int(fold_suspects(v, band + caps).sum())
    0
    >>> v[5] = [-0.5, 0.5, 1]
    >>> int(fold_suspects(v, band + caps).sum()) > 0
    True
    """
    return _fold_suspects(*_checked(vertices, triangles), margin)


def _fold_suspects(v: np.ndarray, t: np.ndarray, margin: float = 1e-12) -> np.ndarray | None:
    """:func:`fold_suspects` of validated vertices (V, 3) float64 and triangles (T, 3) int64 (:func:`_checked`)."""
    if len(t) < 4:
        return None
    shape = _lattice_shape(t, len(v)) if len(t) >= LATTICE_MIN_FACES else None
    if shape is not None:
        suspect = _lattice_suspects(v, t, *shape, margin)
        if suspect is not None:
            return suspect
    if not _closed_and_oriented(t, len(v)):
        return None
    z = v[:, 2]
    zs = np.sort(z)
    tol = LEVEL_RTOL * max(float(max(zs[-1], -zs[0])), 1e-300)
    new_level = np.empty(len(zs), dtype=bool)
    new_level[0] = True
    np.greater(zs[1:] - zs[:-1], tol, out=new_level[1:])
    starts = new_level.nonzero()[0]
    # a chain of small steps must not make one level of a slope
    if (np.append(zs[starts[1:] - 1], zs[-1]) - zs[starts] > 4 * tol).any():
        return None
    # a vertex's level: the last level starting at or below its z (levels are apart by more than tol)
    level = np.searchsorted(zs[starts], z, side="right") - 1
    # column by column (x and y of the vertices, the three corners of the faces): numpy's reductions,
    # gathers and products along a short last axis cost more than the arithmetic written out
    t0, t1, t2 = t[:, 0], t[:, 1], t[:, 2]
    l0, l1, l2 = level[t0], level[t1], level[t2]
    low = np.minimum(np.minimum(l0, l1), l2)
    high = np.maximum(np.maximum(l0, l1), l2)
    top = int(level.max())
    flat = high == low
    if top < 1 or (high - low > 1).any() or (flat & (low != 0) & (low != top)).any():
        return None
    X, Y = v[:, 0] - v[:, 0].mean(), v[:, 1] - v[:, 1].mean()
    tiny = margin * (2.0 * max(float(np.abs(X).max()), float(np.abs(Y).max()))) ** 2
    for lvl in (0, top):
        on = (flat & (low == lvl)).nonzero()[0]
        if len(on):
            c0, c1, c2 = t0[on], t1[on], t2[on]
            x0, y0 = X[c0], Y[c0]
            area = (X[c1] - x0) * (Y[c2] - y0) - (Y[c1] - y0) * (X[c2] - x0)
            if not ((area > tiny).all() or (area < -tiny).all()):
                return None
    n_bands = top
    band = (~flat).nonzero()[0]
    base = low[band]
    u0, u1, u2 = l0[band] > base, l1[band] > base, l2[band] > base
    n_up = u0.view(np.int8) + u1.view(np.int8) + u2.view(np.int8)
    one_up = n_up == 1
    # the lone corner (the one on its own level) last, the other two in the face's order before it
    lone = (u1 == one_up).view(np.int8) + 2 * (u2 == one_up).view(np.int8)
    corner = 3 * band
    corner += lone
    flat_t = t.ravel()
    r2 = flat_t[corner]
    to_p1, to_p2 = np.where(lone == 2, -2, 1), np.where(lone == 0, 2, -1)
    # the cut runs along p1 -> p2 below a lone upper corner and along p2 -> p1 above a lone lower one:
    # the corners taken in the cut's order (a, b), so the turns below need no sign per face (swapping
    # the two negates a cross product exactly)
    ra = flat_t[corner + np.where(one_up, to_p1, to_p2)]
    rb = flat_t[corner + np.where(one_up, to_p2, to_p1)]
    pax, pay, pbx, pby, xx, xy = X[ra], Y[ra], X[rb], Y[rb], X[r2], Y[r2]
    ax, ay = (pax + xx) / 2.0, (pay + xy) / 2.0
    bx, by = (pbx + xx) / 2.0, (pby + xy) / 2.0
    w = ax * by - ay * bx
    area = np.bincount(base, w, n_bands)
    denominator = 3.0 * np.where(area == 0, 1.0, area)
    cx = np.bincount(base, (ax + bx) * w, n_bands) / denominator
    cy = np.bincount(base, (ay + by) * w, n_bands) / denominator
    # a band whose faces are all of one kind (lone corner above, or all below) and share their lone
    # corner is a fan to it
    n_faces = np.bincount(base, minlength=n_bands)
    n_one_up = np.bincount(base, one_up, n_bands)
    apex = np.full(n_bands, -1)
    apex[base] = r2
    fan = (n_faces > 0) & ((n_one_up == 0) | (n_one_up == n_faces))
    fan &= np.bincount(base, r2 != apex[base], n_bands) == 0
    cx[fan], cy[fan] = X[apex[fan]], Y[apex[fan]]
    ccx, ccy = cx[base], cy[base]
    sign = np.sign(area)[base]
    good = sign * ((pax - ccx) * (pby - ccy) - (pay - ccy) * (pbx - ccx)) > tiny
    good &= sign * ((xx - ccx) * (pby - pay) - (xy - ccy) * (pbx - pax)) >= 0
    ax -= ccx
    ay -= ccy
    bx -= ccx
    by -= ccy
    (edge,), step = _crossings(ax, ay, bx, by)
    once = (np.abs(np.bincount(base[edge], step, n_bands)) == 1) & (area != 0)
    worried = ~once
    worried[base[~good]] = True
    # each face's group: its band, or the band its cap closes
    group = np.where(flat, np.where(low == 0, 0, top - 1), low)
    bad_face = np.zeros(len(t), dtype=bool)
    bad_face[band[~good]] = True
    return _arc_suspects(t, X, Y, group, bad_face, once, worried, cx, cy)


def layered_radial_graph(vertices, triangles, *, margin: float = 1e-12) -> bool:
    """Whether :func:`fold_suspects` proves a closed layered mesh free of self-intersections on its own.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    triangles : array_like, shape (T, 3) int
    margin : float
        See :func:`fold_suspects`.

    Returns
    -------
    bool
        True when every band is a radial graph about its axis (no suspect face);
        False means "not proven", not "folded".
    """
    suspects = fold_suspects(vertices, triangles, margin=margin)
    return suspects is not None and not suspects.any()


def folded_faces(vertices, triangles) -> np.ndarray:
    """The faces that cross another: ``self_intersections(vertices, triangles).faces``, tested on the suspects only.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    triangles : array_like, shape (T, 3) int

    Returns
    -------
    numpy.ndarray, shape (T,) bool
        The same mask as :func:`self_intersections` gives: every crossing pair lies
        among the suspects of :func:`fold_suspects`.
    """
    return _exact_on_suspects(vertices, np.asarray(triangles), first=False)


def _exact_on_suspects(vertices, t: np.ndarray, first: bool) -> np.ndarray:
    """Crossing faces (T,) bool by :func:`self_intersections` on the suspects of :func:`fold_suspects` only
    (on every face where the certificate does not apply); ``first`` stops at the first crossing found."""
    v, t = _checked(vertices, t)
    suspects = _fold_suspects(v, t)
    if suspects is None:
        return _self_intersections(v, t, _EPS, first).faces
    out = np.zeros(len(t), dtype=bool)
    if suspects.any():
        out[suspects] = _self_intersections(v, t[suspects], _EPS, first).faces
    return out


def is_fold_free(vertices, triangles) -> bool:
    """Whether no face of a triangle mesh crosses another, with the exact test on the suspects only.

    The same answer as ``self_intersections(vertices, triangles).n_faces == 0``:
    :func:`fold_suspects` leaves out the faces that provably cross nothing, and
    :func:`self_intersections` tests the pairs among the others (all of them when
    the mesh is not closed and layered).

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    triangles : array_like, shape (T, 3) int

    Returns
    -------
    bool
    """
    return not _exact_on_suspects(vertices, np.asarray(triangles), first=True).any()
