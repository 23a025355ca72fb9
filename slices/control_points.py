"""Planar contours: the seed's control-point parameters (the contour checks are :mod:`slices.polygons`).

Seed 000, section II. Rays are cast from the contour's centroid at equal angles;
where a ray meets the contour is a support point with ``u_k = k / N1`` (eq. 1).
Where the contour folds back (a ray crosses it several times) the polar angle
``phi`` of the contour points about the centroid (eq. 2) turns; such turning
points (eq. 3) get parameters spread evenly between the neighbouring support
points (eq. 4), and every other point gets a chord-length parameter inside its
sub-segment (eq. 5).

Project decisions where the seed is silent:

* The support point of a ray is its outermost crossing with the contour,
  where the ray leaves the outline for the last time. A ray crosses a fold
  when its angle lies between the fold's two turning points. A turning point
  near the ray origin (a kidney's hilum can reach the centroid) has a polar
  angle that swings by degrees with the sampling of the contour; one far out
  (the tip of an arm) has a steady angle. Which crossing is outermost usually
  changes only where a ray passes the far turning point, whereas the first
  crossing along the contour changes at either, and then jumps across the
  whole fold from one slice to the next. Should the outermost crossings not
  follow the contour in the order of the rays (spiral-like outlines), the
  first crossings are used, which always do. The parameter increases
  monotonically also where a ray is tangent to the contour.
* The rays of one body share their rotation: :func:`choose_start_angle`
  tries eight rotations within one ray spacing and keeps the one whose
  support points move least along the contours from slice to slice, so that
  no ray grazes an arm's tip (the seed fixes the spacing of the rays, eq. 1,
  not their rotation).
* Turning points are looked for only in segments that a ray crosses more than
  once (the polar angle leaves the segment's range of ray angles), as the
  seed's step 2 says; small wiggles that no ray crosses twice stay chord-length.
* When the centroid lies outside the contour (strongly bent outlines) the
  rays start from the interior point farthest from the outline instead.
* The parameter of the first support point (ray at ``start_angle``) is 0 on
  every slice, so ``u`` corresponds across slices.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from slices.polygons import _next, interior_point
from surfaces.validate import as_array, InputError, positive


@dataclass(frozen=True)
class ContourParameters:
    """A contour with the seed's control-point parameters.

    Attributes
    ----------
    points : numpy.ndarray, shape (n, 2)
        Counter-clockwise vertices in mm, starting with the first vertex at or
        after support point 0.
    u : numpy.ndarray, shape (n,)
        Strictly increasing parameters in ``[0, 1)``.
    center : numpy.ndarray, shape (2,)
        Origin of the rays (centroid, or an interior point when the centroid is outside).
    support : numpy.ndarray, shape (N1, 2)
        Support points (ray intersections), ``support[k]`` has ``u = k / N1``.
    turning : numpy.ndarray, shape (n,) bool
        Turning points of eq. 3 that received eq. 4 parameters.
    """

    points: np.ndarray
    u: np.ndarray
    center: np.ndarray
    support: np.ndarray
    turning: np.ndarray


def parameterize(points, n_rays: int, start_angle: float = 0.0) -> ContourParameters:
    """Seed 000 control-point parameters of one closed contour (eqs. 1-5).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Contour vertices in mm, counter-clockwise (see :func:`clean_contour`).
    n_rays : int
        Number of rays ``N1 >= 3`` (:attr:`slices.options.SurfaceOptions.n_rays` by default
        in a reconstruction).
    start_angle : float
        Direction of ray 0 in radians from +x (common to all slices).

    Returns
    -------
    ContourParameters

    Raises
    ------
    ValueError
        Too few rays, or a contour that does not wind once around any interior point.

    Examples
    --------
    Four rays from the centre of a square meet it at its edges' midpoints
    (``u = k / 4``); each corner lies half-way between two of them in arc
    length (eq. 5):

    >>> par = parameterize([[-1, -1], [1, -1], [1, 1], [-1, 1]], n_rays=4)
    >>> par.u.tolist(), par.points.tolist()
    ([0.125, 0.375, 0.625, 0.875], [[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    >>> (par.support.round(12) + 0.0).tolist()
    [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
    """
    p = as_array(points, "points", shape=(None, 2))
    n1 = int(n_rays)
    if n1 < 3:
        raise InputError(f"n_rays: need at least 3 rays (seed 000, eq. 1), got {n_rays}")
    if len(p) < 3:
        raise InputError(f"points: needs at least 3 points, got {len(p)}")
    polars = _polars([p])
    return _parameterize_many(polars, n1, start_angle, _support_crossings(polars, n1, start_angle))[0]


def _parameterize_many(polars: _Polars, n1: int, start_angle: float, crossings) -> list:
    """:func:`parameterize` of every contour of ``polars`` at once, given their
    :func:`_support_crossings` for ``start_angle``'s rays; a list of :class:`ContourParameters`.

    Every contour's steps are those of one contour alone, on concatenated arrays.
    """
    return _parameterize_flat(polars, n1, start_angle, crossings)[0]


def _parameterize_flat(polars: _Polars, n1: int, start_angle: float, crossings) -> tuple:
    """:func:`_parameterize_many`, and the contours' points (N, 2) and parameters (N,) one after the
    other (each contour as in its :class:`ContourParameters`) and the support points (C, n1, 2)."""
    pts_all, start, ns, off3 = polars.pts, polars.start, polars.sizes, polars.off3
    n_c = len(ns)
    curve = np.arange(n_c).repeat(ns)
    local = np.arange(len(pts_all)) - start[curve]
    total = polars.arc[off3 + ns]
    delta = 2 * np.pi / n1
    s_arc, support_xy, level_k, ang = crossings
    # each contour's row runs through n1 consecutive levels: the one of ray 0 (a multiple of n1) sits
    # at column (-first level) mod n1, and the rays follow it round the row (no modulo per entry)
    first = (-level_k[:, 0]) % n1
    at = np.arange(n1) + first[:, None]
    at -= n1 * (at >= n1)
    row_at = np.arange(0, n_c * n1, n1)
    at += row_at[:, None]  # flat positions (one index: faster than two)
    ray0 = row_at + first
    s0 = s_arc.reshape(-1)[ray0]
    sigma = np.empty((n_c, n1 + 1))
    sigma[:, :n1] = (s_arc.reshape(-1)[at] - s0[:, None]) % total[:, None]
    sigma[:, n1] = total
    sigma[:, 0] = 0.0
    support_xy = support_xy.reshape(-1, 2).take(at, axis=0)
    # vertex arc positions relative to support 0, in [0, total)
    tot = total[curve]
    a_vert = (polars.arc[off3[curve] + local] - (s0 - total)[curve]) % tot
    a_vert[np.abs(a_vert - tot) <= 1e-12 * tot] = 0.0
    bounds = list(zip(start.tolist(), (start + ns).tolist()))
    # the ragged sort of all contours in one call, on (contour, value) keys: complex numbers compare
    # lexicographically, so each contour's order is its own, exactly (no shifted keys)
    rot = np.argsort(curve + 1j * a_vert, kind="stable")
    a_vert = a_vert[rot]
    local_rot = rot - start[curve]
    # unwrapped polar angle of each vertex on the period that starts at support 0
    periods = np.maximum(np.ceil((s0[curve] - polars.arc[off3[curve] + ns[curve] + local_rot]) / tot - 1e-12), 0.0)
    phi_v = polars.phi[off3[curve] + ns[curve] + local_rot] + 2 * np.pi * periods
    # each contour's vertices in its own segments (a search of n1 + 1 values a contour: cheaper than one
    # search on (contour, value) keys, whose complex comparisons cost several times a float's)
    seg_of = np.empty(len(a_vert), dtype=np.int64)
    for c, (lo, hi) in enumerate(bounds):
        seg_of[lo:hi] = sigma[c].searchsorted(a_vert[lo:hi], side="right")
    seg_of -= 1
    np.minimum(np.maximum(seg_of, 0, out=seg_of), n1 - 1, out=seg_of)  # np.clip without its wrapper
    key = curve * n1 + seg_of
    seg_lo = ang.reshape(-1)[ray0][curve] + seg_of * delta
    folded_vertex = (phi_v < seg_lo - 1e-9) | (phi_v > seg_lo + delta + 1e-9)
    folded_seg = np.zeros(n_c * n1, dtype=bool)
    folded_seg[key[folded_vertex]] = True
    # turning points (eq. 3): the polar angle changes direction at the vertex
    last = start + ns - 1
    prv = np.arange(-1, len(phi_v) - 1)
    prv[start] = last
    nxt = np.arange(1, len(phi_v) + 1)
    nxt[last] = start
    d_in = phi_v - phi_v[prv]
    d_in[start] = phi_v[start] - (phi_v[last] - 2 * np.pi)
    d_out = d_in[nxt]
    sigma_of = _at(sigma, curve, seg_of)
    turning = (np.sign(d_in) * np.sign(d_out) < 0) & folded_seg[key]
    turning &= ~(np.abs(a_vert - sigma_of) <= 1e-9 * tot)
    # eq. 4: turning points spread evenly inside their segment
    t_idx = turning.nonzero()[0]
    t_key = key[t_idx]
    n2 = np.bincount(t_key, minlength=n_c * n1)
    first_in_seg = n2.cumsum() - n2
    rank = np.arange(len(t_idx)) - first_in_seg[t_key] + 1
    u_turn = (seg_of[t_idx] + rank / (n2[t_key] + 1.0)) / n1
    # eq. 5: chord length between consecutive anchors (support and turning points); a turning point lies
    # strictly inside its segment, so the anchors' order follows from the counts: sigma[c, k] after the
    # turning points of the segments before k, a turning point after its segment's sigma
    anchor_arc = np.empty(n_c * (n1 + 1) + len(t_idx))
    anchor_u = np.empty_like(anchor_arc)
    n_before = np.empty((n_c, n1 + 1), dtype=first_in_seg.dtype)
    n_before[:, :n1] = first_in_seg.reshape(n_c, n1)
    n_before[:, n1] = first_in_seg[n1 - 1::n1] + n2[n1 - 1::n1]
    at_sigma = (np.arange(n_c) * (n1 + 1))[:, None] + np.arange(n1 + 1) + n_before
    anchor_arc[at_sigma] = sigma
    anchor_u[at_sigma] = np.arange(n1 + 1) / n1
    at_turn = curve[t_idx] * (n1 + 1) + seg_of[t_idx] + 1 + np.arange(len(t_idx))
    anchor_arc[at_turn] = a_vert[t_idx]
    anchor_u[at_turn] = u_turn
    # np.interp of each vertex on its contour's anchors, its interval known: the vertices run in order
    # of arc, so the last anchor at or before a vertex is its segment's sigma or the segment's latest
    # turning point so far (0 <= a_vert < total: never before the first anchor or at the last)
    passed = turning.cumsum() - first_in_seg[key]  # turning points of the segment up to the vertex
    j = _at(at_sigma, curve, seg_of) + passed
    x_j = anchor_arc[j]
    u = (anchor_u[j + 1] - anchor_u[j]) / (anchor_arc[j + 1] - x_j) * (a_vert - x_j) + anchor_u[j]
    u[a_vert == x_j] = anchor_u[j][a_vert == x_j]
    u[t_idx] = u_turn
    bad = (u[1:] <= u[:-1]) & (curve[1:] == curve[:-1])
    if bad.any() or (u[last] >= 1.0).any():
        raise InputError("points: could not give the contour monotone parameters (degenerate outline)")
    pts = pts_all.take(rot, axis=0)
    params = [ContourParameters(pts[lo:hi], u[lo:hi], cc, ss, turning[lo:hi])
              for (lo, hi), cc, ss in zip(bounds, polars.centers, support_xy)]
    return params, pts, u, support_xy


def _at(a: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``a[rows, cols]`` of a 2-D array by one flat gather (two index arrays cost numpy several times more)."""
    return a.reshape(-1)[rows * a.shape[1] + cols]


class _Polars(NamedTuple):
    """Validated contours one after the other, with their ray origins, polar angles and arc lengths.

    ``pts`` (N, 2) holds contour ``c`` in the ``sizes[c]`` rows from ``start[c]``;
    ``centers`` (C, 2) are the ray origins; ``phi`` and ``arc`` hold, from
    ``off3[c]``, contour ``c``'s unwrapped polar angle (eq. 2) and arc length over
    three periods (``3 n_c + 1`` entries, vertex ``i`` of period ``r`` at ``r n_c + i``).
    """

    pts: np.ndarray
    start: np.ndarray
    sizes: np.ndarray
    centers: np.ndarray
    phi: np.ndarray
    arc: np.ndarray
    off3: np.ndarray


def _polars(ps: list, pts: np.ndarray | None = None) -> _Polars:
    """Ray origin, unwrapped polar angle and arc length of every validated (n_c >= 3, 2) contour at once.

    The origin is the area centroid, or, when the contour does not wind once
    around it, the interior point farthest from the outline (:func:`interior_point`).
    ``pts``: the contours one after the other (N, 2) float64 when the caller has joined them already.
    """
    ns = np.array([len(p) for p in ps], dtype=np.int64)
    n_c = len(ns)
    if pts is None:
        pts = np.concatenate(ps) if n_c > 1 else ps[0]
    start = ns.cumsum() - ns
    curve = np.arange(n_c).repeat(ns)
    nxt = np.arange(1, len(pts) + 1)
    nxt[start + ns - 1] = start
    # x and y apart: operations along all points run faster than on (N, 2) rows
    x, y = np.ascontiguousarray(pts.T)
    qx, qy = x[nxt], y[nxt]
    # area centroids (:func:`_centroid`), the vertex mean of a degenerate zero-area polygon
    cross = x * qy - qx * y
    a = np.add.reduceat(cross, start) / 2.0
    extent = np.maximum(np.maximum.reduceat(x, start) - np.minimum.reduceat(x, start),
                        np.maximum.reduceat(y, start) - np.minimum.reduceat(y, start))
    flat = np.abs(a) < 1e-12 * np.maximum(1.0, extent) ** 2
    area6 = 6.0 * np.where(flat, 1.0, a)
    centers = np.empty((n_c, 2))
    centers[:, 0] = np.add.reduceat((x + qx) * cross, start) / area6
    centers[:, 1] = np.add.reduceat((y + qy) * cross, start) / area6
    if flat.any():
        centers[flat] = (np.add.reduceat(pts, start, axis=0) / ns[:, None])[flat]
    ang = np.arctan2(y - centers[:, 1][curve], x - centers[:, 0][curve])
    dphi = (ang[nxt] - ang + np.pi) % (2 * np.pi) - np.pi
    for c in (np.abs(np.add.reduceat(dphi, start) - 2 * np.pi) > 1e-6).nonzero()[0]:
        # the centroid lies outside (strongly bent outlines): rays from the interior point instead
        sl = slice(start[c], start[c] + ns[c])
        centers[c] = interior_point(pts[sl])
        rel_c = pts[sl] - centers[c]
        ang[sl] = np.arctan2(rel_c[:, 1], rel_c[:, 0])
        dphi[sl] = (_next(ang[sl]) - ang[sl] + np.pi) % (2 * np.pi) - np.pi
        if abs(dphi[sl].sum() - 2 * np.pi) > 1e-6:
            raise InputError("points: contour does not wind once counter-clockwise around its interior")
    dx, dy = qx - x, qy - y
    edge_len = np.sqrt(dx * dx + dy * dy)
    # running sums over three periods, one row per contour so that each starts afresh
    local = np.arange(len(pts)) - start[curve]
    cols = 1 + local + ns[curve] * np.arange(3)[:, None]  # (3, N)
    width = 3 * int(ns.max()) + 1
    acc = np.zeros((2, n_c, width))
    at = curve * width + cols  # flat positions in one contour's row (one index: faster than two)
    acc[0].reshape(-1)[at] = dphi
    acc[1].reshape(-1)[at] = edge_len
    acc.cumsum(axis=2, out=acc)
    size3 = 3 * ns + 1
    off3 = size3.cumsum() - size3
    c3 = np.arange(n_c).repeat(size3)
    i3 = np.arange(len(c3)) - off3[c3]
    at3 = c3 * width + i3
    return _Polars(pts, start, ns, centers, ang[start][c3] + acc[0].reshape(-1)[at3], acc[1].reshape(-1)[at3], off3)


def _support_crossings(polars: _Polars, n1: int, start_angle: float, points: bool = True):
    """Support points of ``n1`` rays: the outermost crossing of each ray with the contour.

    A ray from inside a counter-clockwise contour crosses it alternately going
    out (the polar angle increasing along the contour) and coming back in; the
    support point is where the ray leaves the contour for the last time, its
    crossing farthest from the origin. Should those crossings not follow the
    contour in the order of their rays (possible for spiral-like outlines),
    every ray takes its first outgoing crossing along the contour instead (the
    first time the polar angle reaches the ray's angle as a new record), which
    always does.

    All contours of ``polars`` (:func:`_polars`) at once,
    one array operation over every edge of every contour. Returns, per contour
    (axis 0), the arc positions (unwrapped, increasing in the order of the
    rays, starting with the first ray after the polar-angle record at the
    start of the second period), their points, the rays' levels and angles
    (the points and angles ``None`` unless ``points``): shapes (C, n1), (C, n1, 2), (C, n1), (C, n1).
    """
    cr = _crossings(polars, n1, start_angle)
    return _pick_crossings(cr, cr.outer, cr.first, cr.levels(), polars.arc[polars.off3 + polars.sizes],
                           start_angle, 2 * np.pi / n1, points)


class _Crossings(NamedTuple):
    """Every outgoing crossing of the rays with the contours (:func:`_crossings`).

    ``ie`` and ``level_k`` give each crossing's edge and ray level; per edge,
    its start ``(ax, ay)``, direction ``(sx, sy)``, start relative to the
    origin ``(rx, ry)``, the origin ``(cx, cy)``, arc position at its start and
    length; ``outer`` and ``first`` (C, n1) the crossing farthest from the
    origin and the first along the contour of each ray, in the order of the rays;
    ``single`` when every level is crossed once (then both are ``0, 1, 2, ...`` in
    one array: a gather by them is the identity, and the first is the outermost).
    """

    ie: np.ndarray
    level_k: np.ndarray
    edge: tuple
    outer: np.ndarray
    first: np.ndarray
    single: bool

    def levels(self) -> np.ndarray:
        """The levels (C, n1) of the :attr:`outer` crossings."""
        return self.level_k.reshape(self.outer.shape) if self.single else self.level_k[self.outer]


def _crossing_at(cr: _Crossings, idx: np.ndarray, cos_k: np.ndarray, sin_k: np.ndarray, full: bool) -> tuple:
    """Arc position, then (``full``) point and distance from the origin along the ray, of crossings
    ``idx`` of ``cr`` on rays of direction ``(cos_k, sin_k)``."""
    ax, ay, sx, sy, rx, ry, cx, cy, arc_g, edge_len = cr.edge
    j = cr.ie.reshape(idx.shape) if cr.single and idx is cr.outer else cr.ie[idx]
    sx_j, sy_j = sx[j], sy[j]
    num = rx[j] * sin_k - ry[j] * cos_k
    den = sx_j * sin_k - sy_j * cos_k
    den[den == 0] = 1e-300
    t = np.negative(num, out=num)
    t /= den
    np.maximum(t, 0.0, out=t)  # np.clip's result, without its wrapper
    np.minimum(t, 1.0, out=t)
    if not full:
        return (arc_g[j] + t * edge_len[j],)
    x, y = ax[j] + t * sx_j, ay[j] + t * sy_j
    return arc_g[j] + t * edge_len[j], x, y, (x - cx[j]) * cos_k + (y - cy[j]) * sin_k


def _ray_table(levels: np.ndarray, start_angle: float, delta: float) -> tuple:
    """Directions ``(cos, sin)`` of the rays at integer ``levels``, from a table over the levels
    that occur (the same values as per ray, fewer cosines)."""
    k_min = int(levels.min(initial=0))
    table = start_angle + np.arange(k_min, int(levels.max(initial=0)) + 1) * delta
    lv = levels - k_min
    return np.cos(table)[lv], np.sin(table)[lv], table, lv


def _crossings(polars: _Polars, n1: int, start_angle: float) -> _Crossings:
    """The crossings of :func:`_support_crossings` and each ray's two candidate picks."""
    pts, offp, ns, centers, phi, arc, off3 = polars
    n_c = len(ns)
    # the polar-angle record at the start of the second period: the largest phi up to entry n
    bounds = np.empty(2 * n_c, dtype=np.int64)
    bounds[0::2] = off3
    bounds[1::2] = off3 + ns + 1
    record_n = np.maximum.reduceat(phi, bounds)[::2]  # the odd segments run to the next contour
    delta = 2 * np.pi / n1
    k_base = np.floor((record_n - start_angle) / delta).astype(np.int64)
    # every edge of the second and third periods, contour by contour
    cid = np.arange(n_c).repeat(2 * ns)
    e = np.arange(len(cid)) - ((2 * ns).cumsum() - 3 * ns).repeat(2 * ns)
    g = off3[cid] + e
    # every outgoing crossing of the N1 ray levels after the record at the start of the second period;
    # every entry's level computed once (the edges' starts and ends overlap), then gathered
    level = np.floor((phi - start_angle) / delta).astype(np.int64)
    k_base_e = k_base[cid]
    k_lo = np.maximum(level[g], k_base_e)
    k_hi = np.minimum(level[g + 1], k_base_e + n1)
    count = np.maximum(k_hi - k_lo, 0)
    ie = np.arange(len(cid)).repeat(count)  # the edge of every crossing
    level_k = (k_lo + 1 - (count.cumsum() - count))[ie] + np.arange(len(ie))
    # group the crossings by (contour, level): levels lie in k_base + [1, n1], so one integer key
    # orders them; the input is nearly in that order already, which a stable sort exploits
    key = (cid * (n1 + 1) - k_base_e)[ie] + level_k
    if len(key) == n_c * n1 and bool((key[1:] > key[:-1]).all()):
        # every level crossed once, in order (no fold): nothing to group
        order = starts = np.arange(len(key))
        sizes = None
    else:
        order = np.argsort(key, kind="stable")
        sorted_key = key[order]
        starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
        if len(starts) != n_c * n1:  # a contour has at most n1 levels: one is missing
            found = np.bincount(sorted_key[starts] // (n1 + 1), minlength=n_c)
            bad = int(np.flatnonzero(found != n1)[0])
            where = "points" if n_c == 1 else f"contours[{bad}]"
            raise InputError(f"{where}: found support points for {found[bad]} of {n1} rays")
        sizes = np.diff(np.r_[starts, len(order)])
    # per edge what its crossings share (x and y apart: 1-D gathers are cheap); the geometry is
    # computed only for the crossings that compete (a level crossed more than once) and the picks
    # e lies in [n, 3 n) for a contour of n points: its vertex by subtraction (integer modulo is
    # several times slower than the subtractions and comparisons)
    ns_e = ns[cid]
    e_mod = e - ns_e
    e_mod -= ns_e * (e_mod >= ns_e)
    a_idx = offp[cid] + e_mod
    px, py = pts[:, 0], pts[:, 1]  # gathers of single floats: faster than of (N, 2) rows
    ax, ay = px[a_idx], py[a_idx]
    # each edge ends where the next one of its contour starts; the last of a contour's two periods
    # at the contour's vertex 0
    block_end = (2 * ns).cumsum() - 1
    bx, by = np.empty_like(ax), np.empty_like(ay)
    bx[:-1], by[:-1] = ax[1:], ay[1:]
    bx[block_end], by[block_end] = px[offp], py[offp]
    cx, cy = centers[:, 0][cid], centers[:, 1][cid]
    a_at = off3[cid] + e_mod
    edge = (ax, ay, bx - ax, by - ay, ax - cx, ay - cy, cx, cy, arc[g], arc[a_at + 1] - arc[a_at])
    outer = order[starts] if sizes is not None else order  # a level crossed once: its only crossing
    multi = (sizes > 1).nonzero()[0] if sizes is not None else ()
    first = outer.copy() if len(multi) else outer  # the two picks differ only where a level is crossed again
    cr = _Crossings(ie, level_k, edge, outer.reshape(n_c, n1), first.reshape(n_c, n1), sizes is None)
    if len(multi):
        m_sizes = sizes[multi]
        m_starts = m_sizes.cumsum() - m_sizes
        cand = order[(starts[multi] - m_starts).repeat(m_sizes) + np.arange(int(m_sizes.sum()))]
        cos_k, sin_k, _, _ = _ray_table(level_k[cand], start_angle, delta)
        s_c, _, _, radius = _crossing_at(cr, cand, cos_k, sin_k, True)
        for values, reduce, picks in ((radius, np.maximum, outer), (s_c, np.minimum, first)):
            # per group the crossing of least (or greatest) value, ties to the earliest crossing
            best = reduce.reduceat(values, m_starts).repeat(m_sizes)
            picks[multi] = np.minimum.reduceat(np.where(values == best, cand, len(order)), m_starts)
    return cr


def _pick_crossings(cr: _Crossings, outer: np.ndarray, first: np.ndarray, levels: np.ndarray, total: np.ndarray,
                    start_angle: float, delta: float, points: bool) -> tuple:
    """:func:`_support_crossings` of the rays at ``levels`` (C, R), ray ``k`` at ``start_angle + k
    delta``, whose outermost and first crossings in ``cr`` are ``outer`` and ``first`` (C, R);
    ``total`` (C,) the contours' perimeters."""
    cos_k, sin_k, table, lv = _ray_table(levels, start_angle, delta)
    picked = _crossing_at(cr, outer, cos_k, sin_k, points)
    s_pick = picked[0]
    unordered = (s_pick[:, 1:] <= s_pick[:, :-1]).any(axis=1) | (s_pick[:, -1] - s_pick[:, 0] >= total)
    if unordered.any() and not cr.single:  # then each level's first crossing along the contour (the same when single)
        pick = np.where(unordered[:, None], first, outer)
        picked = _crossing_at(cr, pick, cos_k, sin_k, points)
    if not points:
        return picked[0], None, levels, None
    xy = np.empty(levels.shape + (2,))
    xy[..., 0], xy[..., 1] = picked[1:3]
    return picked[0], xy, levels, table[lv]


def ray_supports(points, n_rays: int, start_angle: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Support points of the seed's rays (eq. 1) and their positions along the contour.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Counter-clockwise contour vertices in mm.
    n_rays : int
        Number of rays (>= 3); ray ``k`` points at ``start_angle + 2 pi k / n_rays``.
    start_angle : float
        Direction of ray 0, radians from +x.

    Returns
    -------
    fraction : numpy.ndarray, shape (n_rays,)
        Arc length from vertex 0 to the support point of ray ``k``, as a fraction
        of the perimeter, in ``[0, 1)``.
    xy : numpy.ndarray, shape (n_rays, 2)
        The support points in mm.
    """
    p = as_array(points, "points", shape=(None, 2))
    n1 = int(n_rays)
    if n1 < 3 or len(p) < 3:
        raise InputError(f"n_rays/points: need at least 3 rays and 3 points, got {n_rays} and {len(p)}")
    frac, xy = _ray_supports(_polars([p]), n1, start_angle)
    return frac[0], xy[0]


def _ray_supports(polars: _Polars, n1: int, start_angle: float,
                  points: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`ray_supports` of the contours of ``polars`` (:func:`_polars`): shapes (C, n1), (C, n1, 2)
    (the points only when ``points``)."""
    s_arc, xy, level_k, _ = _support_crossings(polars, n1, start_angle, points)
    # each contour's row runs through n1 consecutive levels: ray k sits at column (k - first level) mod n1
    order = (np.arange(n1) - level_k[:, :1]) % n1
    total = polars.arc[polars.off3 + polars.sizes][:, None]
    frac = (np.take_along_axis(s_arc, order, axis=1) % total) / total
    return frac, (xy[np.arange(len(total))[:, None], order] if points else None)


#: Rotations of the rays that :func:`choose_start_angle` tries by default, evenly over one ray spacing.
START_CANDIDATES = 8


def choose_start_angle(contours, n_rays: int, candidates: int = START_CANDIDATES) -> float:
    """Direction of ray 0, common to a stack of slices, that keeps support points steady.

    Where a contour folds, the support point of a ray that passes close to the
    tip of the fold jumps between the near and the far side of the fold from
    one slice to the next (the ray's first crossing appears or disappears), and
    with it the correspondence of ``u`` across slices. The seed fixes the rays'
    spacing (eq. 1), not their rotation; this picks, out of ``candidates``
    rotations evenly spread over one ray spacing, the one whose support points
    move least along the contours from slice to slice: for every pair of
    neighbouring slices the largest shift of a support point (fraction of the
    perimeter, after removing the median shift of all rays), summed over the pairs.

    Parameters
    ----------
    contours : sequence of array_like, each shape (n_k, 2)
        Counter-clockwise contours of consecutive slices, mm.
    n_rays : int
        Rays per contour (eq. 1).
    candidates : int
        Rotations tried (``>= 1``); ray 0 at ``2 pi o / (candidates n_rays)``.

    Returns
    -------
    float
        Start angle in radians, in ``[0, 2 pi / n_rays)``; 0 for a single slice.
    """
    r = int(positive(candidates, "candidates"))
    n1 = int(n_rays)
    if len(contours) < 2 or r == 1:
        return 0.0
    ps = [as_array(c, f"contours[{i}]", shape=(None, 2)) for i, c in enumerate(contours)]
    if n1 * r < 3 or min(len(p) for p in ps) < 3:
        raise InputError(f"n_rays/points: need at least 3 rays and 3 points, got {n1 * r} and "
                         f"{min(len(p) for p in ps)}")
    return _start_angle(_polars(ps), n1, r)


def _start_angle(polars: _Polars, n1: int, r: int) -> float:
    """:func:`choose_start_angle` of the contours of ``polars`` (:func:`_polars`, two or more)."""
    return _best_rotation(polars, n1, r)[0]


def _start_angle_crossings(polars: _Polars, n1: int, r: int) -> tuple[float, tuple]:
    """:func:`_start_angle` and :func:`_support_crossings` of its ``n1`` rays, which are every
    ``r``-th of the rays tried: their crossings are picked out of the same pass."""
    angle, o, cr, level_k, total = _best_rotation(polars, n1, r)
    # ray k of the chosen rotation is fine level k r + o; a contour's row of fine levels starts
    # after its polar-angle record, and so does the row of every r-th of them
    col = (o - level_k[:, :1]) % r + r * np.arange(n1)
    rows = np.arange(len(total))[:, None]
    levels = (_at(level_k, rows, col) - o) // r
    return angle, _pick_crossings(cr, _at(cr.outer, rows, col), _at(cr.first, rows, col), levels, total, angle,
                                  2 * np.pi / n1, True)


def _best_rotation(polars: _Polars, n1: int, r: int) -> tuple:
    """The start angle of :func:`_start_angle`, its rotation's index, the crossings of all ``n1 r``
    rays tried, their levels (C, n1 r) and the contours' perimeters (C,)."""
    nf = n1 * r
    cr = _crossings(polars, nf, 0.0)
    total = polars.arc[polars.off3 + polars.sizes]
    s_arc, _, level_k, _ = _pick_crossings(cr, cr.outer, cr.first, cr.levels(), total, 0.0,
                                           2 * np.pi / nf, False)
    # each contour's row runs through nf consecutive levels: ray k sits at column (k - first level) mod nf;
    # gathered as (contour, rotation, ray) so that the median runs along contiguous rows. Only
    # shifts modulo 1 count, so the unwrapped arc positions need no reduction to one period first.
    n_c = len(total)
    frac = s_arc / total[:, None]
    # the row rolled so that column k r + o holds ray k of rotation o, then seen as (contour, rotation, ray):
    # read from the row written twice over, from column (-first level) mod nf on (one index a value, no modulo)
    twice = np.concatenate([frac, frac], axis=1).reshape(-1)
    at = (-level_k[:, 0]) % nf + np.arange(n_c) * (2 * nf)
    frac = twice[at[:, None] + np.arange(nf)].reshape(n_c, n1, r)
    frac = frac.transpose(0, 2, 1)
    shift = np.empty((n_c - 1, r, n1))
    np.subtract(frac[1:], frac[:-1], out=shift)  # (K-1, R, N1)
    shift -= np.rint(shift)  # the shortest way round
    # the median over the rays (np.median's middle value, or mean of the middle pair, without its
    # overhead; a sort of these short rows runs several times faster than a partition at two places)
    half = n1 // 2
    mid = np.sort(shift, axis=2)
    if n1 % 2:
        shift -= mid[:, :, half:half + 1]
    else:
        shift -= (mid[:, :, half - 1:half] + mid[:, :, half:half + 1]) / 2.0
    cost = np.abs(shift).max(axis=2).sum(axis=0)  # (R,)
    o = int(np.argmin(cost))
    return float(2 * np.pi * o / nf), o, cr, level_k, total


def lattice_values(u_list, n_lattice: int) -> np.ndarray:
    """Common lattice of ``u`` values, denser where the slices' parameters crowd.

    Half of the values are uniform (``j / M'``), half are quantiles of all slices'
    parameters pooled, so that the seed's parameters, which pack many points
    into short ranges where a contour folds (eq. 4), keep their order and
    their correspondence across slices when moved onto the lattice.

    Parameters
    ----------
    u_list : sequence of numpy.ndarray
        Parameters in ``[0, 1)`` of every slice.
    n_lattice : int
        Requested size ``M``.

    Returns
    -------
    numpy.ndarray, shape (M',) float64
        Strictly increasing values in ``[0, 1)``, ``M' <= M`` (equal values merged),
        at least as many as the longest slice has points.
    """
    m = int(positive(n_lattice, "n_lattice"))
    pooled = np.sort(np.concatenate([as_array(u, "u", ndim=1) for u in u_list]))
    half = m // 2
    quant = np.quantile(pooled, (np.arange(half) + 0.5) / half)
    values = np.unique(np.concatenate([np.arange(m - half) / (m - half), quant]))
    need = max(len(u) for u in u_list)
    if len(values) < need:
        values = np.arange(m) / m
    return values


def balanced_lattice_values(u_list, arc_list, n_lattice: int) -> np.ndarray:
    """Common lattice of ``u`` values spaced evenly in mean arc length.

    The seed's parameters pack a whole fold of a contour into one ray segment
    (eq. 4), so ``u`` runs much faster along the contour there than elsewhere.
    A lattice uniform in ``u`` then has too few values in such a segment, and
    moving the points onto it shifts them (and the correspondence between
    slices) by many points. Here the lattice values are equally spaced in the
    mean over all slices of the normalised arc length as a function of ``u``,
    so every lattice interval covers about ``1 / M`` of every contour.

    Parameters
    ----------
    u_list : sequence of numpy.ndarray
        Per slice, strictly increasing parameters in ``[0, 1)`` of its points.
    arc_list : sequence of numpy.ndarray
        Per slice, the same points' arc length from ``u = 0`` as a fraction of
        the perimeter, increasing in ``[0, 1)``.
    n_lattice : int
        Requested size ``M``.

    Returns
    -------
    numpy.ndarray, shape (M',) float64
        Strictly increasing values in ``[0, 1)`` starting at 0, ``M' <= M``
        (equal values merged); uniform ``j / M`` if fewer than the longest
        slice's point count would remain.
    """
    m = int(positive(n_lattice, "n_lattice"))
    if len(u_list) != len(arc_list) or not len(u_list):
        raise InputError("u_list, arc_list: need the same, non-zero number of slices")
    us = [as_array(u, "u", ndim=1) for u in u_list]
    arcs = [as_array(a, "arc_list", shape=(len(u),)) for a, u in zip(arc_list, us)]
    return _balanced_values(np.concatenate(us), np.concatenate(arcs), np.array([len(u) for u in us]), m)


def _balanced_values(u_all: np.ndarray, arc_all: np.ndarray, sizes: np.ndarray, m: int) -> np.ndarray:
    """:func:`balanced_lattice_values` of every slice's validated parameters and arcs one after the other."""
    n_c = len(sizes)
    # each slice's (u, arc) between (0, 0) and (1, 1)
    off = (sizes + 2).cumsum() - (sizes + 2)
    xp = np.zeros(len(u_all) + 2 * n_c)
    fp = np.zeros_like(xp)
    inner = np.arange(len(u_all)) + (2 * np.arange(n_c) + 1).repeat(sizes)
    xp[inner] = u_all
    fp[inner] = arc_all
    xp[off + sizes + 1] = 1.0
    fp[off + sizes + 1] = 1.0
    # np.unique(..., return_inverse=True)'s own steps (the same sort), without its wrapper; the
    # parameters are finite (no NaN to hold as one)
    pooled = np.empty(len(u_all) + 2)
    pooled[:2] = 0.0, 1.0
    pooled[2:] = u_all
    perm = pooled.argsort()
    pooled = pooled[perm]
    new_value = np.empty(len(pooled), dtype=bool)
    new_value[0] = True
    np.not_equal(pooled[1:], pooled[:-1], out=new_value[1:])
    grid = pooled[new_value]
    where = np.empty(len(pooled), dtype=np.intp)
    where[perm] = new_value.cumsum() - 1
    # each slice's arc is piecewise linear in u with its breakpoints on the grid, so the slices' sum on
    # the grid is a running sum: of the slopes' changes for the slope on every grid interval, then of
    # slope times width (a jump only where u = 0 repeats the start), one pass instead of one per slice
    at = np.zeros(len(xp), dtype=np.int64)  # each breakpoint's grid index
    at[inner] = where[2:]
    at[off + sizes + 1] = len(grid) - 1
    width, rise = xp[1:] - xp[:-1], fp[1:] - fp[:-1]
    inside = np.ones(len(width), dtype=bool)
    inside[(off + sizes + 1)[:-1]] = False  # from one slice's (1, 1) to the next one's (0, 0)
    sloped = inside & (width > 0)
    jump = inside & (width <= 0)
    slope = rise[sloped] / width[sloped]
    n_g = len(grid)
    change = np.bincount(at[:-1][sloped], slope, minlength=n_g) - np.bincount(at[1:][sloped], slope, minlength=n_g)
    total = np.zeros(n_g)
    total[1:] = (change[:-1].cumsum() * (grid[1:] - grid[:-1])).cumsum()
    if jump.any():
        total += np.bincount(at[1:][jump], rise[jump], minlength=n_g).cumsum()
    total[-1] = n_c  # every slice ends at (1, 1)
    values = np.interp(np.arange(m) / m, total / n_c, grid)
    # increasing (as a rule): its distinct values by one comparison with the previous, else np.unique
    distinct = np.empty(len(values), dtype=bool)
    distinct[0] = True
    np.greater(values[1:], values[:-1], out=distinct[1:])
    values = values[distinct] if (values[1:] >= values[:-1]).all() else np.unique(values)
    values = values[values < 1.0]
    if len(values) < int(sizes.max()):
        values = np.arange(m) / m
    return values


def quantize(u, n_lattice: int, values=None) -> np.ndarray:
    """Move parameters onto a common lattice ``j / M`` keeping them strictly increasing.

    All slices' curves are then cubic on the same breakpoints, so the surface is
    one tensor grid of bicubic patches that still passes through every point.

    Parameters
    ----------
    u : array_like, shape (n,)
        Strictly increasing parameters in ``[0, 1)``.
    n_lattice : int
        Lattice size ``M >= n``.
    values : array_like, shape (M,), optional
        Strictly increasing lattice values in ``[0, 1)`` (see :func:`lattice_values`);
        uniform ``j / M`` when omitted.

    Returns
    -------
    numpy.ndarray, shape (n,) int64
        Lattice indices, strictly increasing, in ``[0, M)``; the nearest lattice
        values where they are free, otherwise the increasing sequence closest to
        them in the least-squares sense.
    """
    uu = as_array(u, "u", ndim=1)
    m = int(positive(n_lattice, "n_lattice"))
    if len(uu) > m:
        raise InputError(f"n_lattice: {m} lattice values cannot hold {len(uu)} distinct parameters")
    lv = None if values is None else as_array(values, "values", shape=(m,))
    return _quantize_many([uu], m, lv)[0]


def _quantize_many(us: list, m: int, values: np.ndarray | None) -> list:
    """:func:`quantize` of every slice's validated parameters (each at most ``m``) in one pass."""
    ns = np.array([len(u) for u in us], dtype=np.int64)
    start = ns.cumsum() - ns
    r = _quantize_flat(np.concatenate(us), start, ns, m, values)
    return [r[lo:lo + n] for lo, n in zip(start.tolist(), ns.tolist())]


def _quantize_flat(uu: np.ndarray, start: np.ndarray, ns: np.ndarray, m: int, values: np.ndarray | None) -> np.ndarray:
    """:func:`_quantize_many` of the slices' parameters one after the other (slice ``c`` the ``ns[c]``
    from ``start[c]``), the lattice indices likewise."""
    slice_of = np.arange(len(ns)).repeat(ns)
    i = np.arange(len(uu)) - start[slice_of]
    if values is None:
        target = np.minimum(np.round(uu * m).astype(np.int64), m - 1)
    else:
        lv = values
        hi = lv.searchsorted(uu)
        np.minimum(np.maximum(hi, 1, out=hi), m - 1, out=hi)  # np.clip without its wrapper
        lo = hi - 1
        # the lower neighbour where it is at least as near (a boolean subtracted: one pass, no np.where)
        target = hi - (np.abs(lv[lo] - uu) <= np.abs(lv[hi] - uu))
        target[uu > lv[-1] + 0.5 * (1.0 + lv[0] - lv[-1])] = m - 1
    # strictly increasing indices closest (least squares) to the targets: isotonic
    # regression of target - i (pool adjacent violators), rounded and clipped
    r = _isotonic_fit_runs((target - i).astype(np.float64), start).round().astype(np.int64)
    np.minimum(np.maximum(r, 0, out=r), (m - ns)[slice_of], out=r)
    r += i
    return r


def isotonic_fit(y) -> np.ndarray:
    """Least-squares non-decreasing fit of a sequence (pool adjacent violators).

    Every pass pools all runs of adjacent blocks whose means decrease, at once;
    pooling adjacent violators in any order gives the one least-squares solution,
    and the passes are few (as many as violations nest), so no loop runs per value.
    ``scipy.optimize.isotonic_regression`` gives the same; importing
    ``scipy.optimize`` costs a command more than all of its contours.

    Parameters
    ----------
    y : array_like, shape (n,)

    Returns
    -------
    numpy.ndarray, shape (n,) float64

    Examples
    --------
    >>> isotonic_fit([1.0, 3.0, 2.0, 2.0, 5.0, 4.0]).tolist()
    [1.0, 2.3333333333333335, 2.3333333333333335, 2.3333333333333335, 4.5, 4.5]
    """
    s = as_array(y, "y", ndim=1)
    return _isotonic_fit_runs(s, np.zeros(min(len(s), 1), dtype=np.int64))


def _isotonic_fit_runs(y: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """:func:`isotonic_fit` of every run ``y[starts[r]:starts[r + 1]]`` on its own, all runs at once.

    Blocks never pool across a run's start; a run without violations keeps its
    blocks (bincount of one value is the value), so each run comes out as
    alone. ``starts`` is increasing and begins at 0 (empty for an empty ``y``).
    """
    s = y.astype(np.float64, copy=False)  # only read: every pass makes new sums
    w = np.ones(len(s))
    inner = np.ones(len(s), dtype=bool)
    inner[starts] = False  # the blocks that do not begin a run
    while len(s) > 1:
        bad = s[:-1] * w[1:] > s[1:] * w[:-1]  # mean of a block above the next one's
        bad &= inner[1:]
        if not bad.any():
            break
        keep = np.empty(len(s), dtype=bool)  # the blocks that begin a pooled block
        keep[0] = True
        np.logical_not(bad, out=keep[1:])
        group = keep.cumsum()
        group -= 1
        s, w = np.bincount(group, s), np.bincount(group, w)
        # a pooled block begins a run where its first block does (bad never pools across a start)
        inner = inner[keep]
    return (s / w).repeat(w.astype(np.int64))
