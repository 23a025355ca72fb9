"""Parabolic blending (Overhauser) curves and surfaces, converted exactly to Bezier form.

Seed 000, eqs. 6-19. On the interval ``[u1, u2]`` between the two central
points of four consecutive points ``P0..P3`` with parameters ``u0 < u1 < u2 < u3``::

    C(u) = (u2 - u) / (u2 - u1) * Pa(u) + (u - u1) / (u2 - u1) * Pb(u)      (eq. 6)

with ``Pa`` the parabola through ``(u0, P0), (u1, P1), (u2, P2)`` and ``Pb`` the
parabola through ``(u1, P1), (u2, P2), (u3, P3)`` (eqs. 7-12). ``C`` is a cubic
polynomial with ``C(u1) = P1``, ``C(u2) = P2``, ``C'(u1) = Pa'(u1)`` and
``C'(u2) = Pb'(u2)`` (differentiate eq. 6: the blend terms cancel at the ends),
so it is exactly the cubic Hermite segment with those end tangents, and its
Bezier points are ``P1, P1 + h Pa'(u1) / 3, P2 - h Pb'(u2) / 3, P2`` with
``h = u2 - u1``. The derivative of the parabola through three nodes at the
middle node is the weighted mean of the two chord slopes::

    Pa'(u1) = (P1 - P0) / h0 * h1 / (h0 + h1) + (P2 - P1) / h1 * h0 / (h0 + h1)

For uniform parameters this is the Catmull-Rom curve; for the seed's
non-uniform parameters it is Overhauser's construction (Barry-Goldman pyramid).
At the ends of an open curve the only parabola is the one through the first
(last) three points, so the end segment is that parabola itself.

Across slices (eqs. 13-19) the same blending runs in ``v`` with uniform
parameters, on whole curves instead of points: the surface between slices ``j``
and ``j + 1`` is a linear combination of the curves ``j - 1 .. j + 2`` with
cubic weights in ``v``, so when every curve is given as cubic Bezier segments
on one common set of ``u`` breakpoints the surface is exactly a grid of bicubic
Bezier patches (:func:`blend_curves`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from surfaces.bezier import _JOIN_RTOL, BezierPatches, bernstein
from surfaces.knots import chord_lengths
from surfaces.validate import as_array, InputError


def _chord_parameters(points: np.ndarray, closed: bool, coincide: str) -> np.ndarray:
    """Chord-length parameters along axis 0, the chords averaged over the other axes.

    Open: ``n`` parameters from 0 in units of length. Closed: ``n`` parameters
    in ``[0, 1)``, the period 1 being the whole closed polygon.
    """
    seg = chord_lengths(points, 0, closed)
    seg = seg.reshape(len(seg), -1).mean(axis=1)
    if np.any(seg <= 0):
        raise InputError(f"points: {coincide} (zero chord length)")
    t = np.concatenate([[0.0], seg.cumsum()])
    return t[:-1] / t[-1] if closed else t


def _parameters(points: np.ndarray, params, closed: bool) -> np.ndarray:
    """Validated strictly increasing parameters; chord length when not given."""
    n = len(points)
    if params is None:
        return _chord_parameters(points, closed, "consecutive points coincide")
    t = as_array(params, "params", shape=(n,))
    if np.any(np.diff(t) <= 0):
        raise InputError("params: must increase strictly")
    if closed and not t[-1] - t[0] < 1.0:
        raise InputError("params: a closed curve needs parameters spanning less than one period")
    return t


def overhauser_tangents(points, params=None, closed: bool = False) -> np.ndarray:
    """Tangents of the parabolic-blending curve at its points (seed 000, eqs. 7-12).

    Parameters
    ----------
    points : array_like, shape (n, d)
        Points in order along the curve (``n >= 3``; ``n >= 2`` when open).
    params : array_like, shape (n,), optional
        Strictly increasing parameters. For a closed curve they lie in one
        period ``[t0, t0 + 1)`` and the curve returns to ``points[0]`` at
        ``params[0] + 1``. Chord length when omitted.
    closed : bool
        Closed curve (indices wrap).

    Returns
    -------
    numpy.ndarray, shape (n, d)
        ``dC/du`` at every point: the derivative of the parabola through the
        point and its two neighbours (one-sided parabola at open ends).
    """
    pts = as_array(points, "points", ndim=2)
    n = len(pts)
    if n < (3 if closed else 2):
        raise InputError(f"points: need at least {3 if closed else 2} points, got {n}")
    t = _parameters(pts, params, closed)
    if closed:
        prev_p, next_p = np.roll(pts, 1, axis=0), np.roll(pts, -1, axis=0)
        h0 = t - np.concatenate([[t[-1] - 1.0], t[:-1]])
        h1 = np.concatenate([t[1:], [t[0] + 1.0]]) - t
        return _middle_slope(prev_p, pts, next_p, h0, h1)
    return _open_tangents(pts, t)


def _open_tangents(pts: np.ndarray, t: np.ndarray) -> np.ndarray:
    """:func:`overhauser_tangents` of an open curve's validated points (n, d) and parameters (n,)."""
    n = len(pts)
    if n == 2:
        slope = (pts[1] - pts[0]) / (t[1] - t[0])
        return np.stack([slope, slope])
    h = np.diff(t)
    out = np.empty_like(pts)
    out[1:-1] = _middle_slope(pts[:-2], pts[1:-1], pts[2:], h[:-1], h[1:])
    # end tangents: derivative of the one parabola at its first / last node
    d0, d1 = (pts[1] - pts[0]) / h[0], (pts[2] - pts[1]) / h[1]
    out[0] = d0 - (d1 - d0) * h[0] / (h[0] + h[1])
    e0, e1 = (pts[-2] - pts[-3]) / h[-2], (pts[-1] - pts[-2]) / h[-1]
    out[-1] = e1 + (e1 - e0) * h[-1] / (h[-2] + h[-1])
    return out


def _identity_tangents(t: np.ndarray) -> np.ndarray:
    """:func:`_open_tangents` of the identity's rows (``n >= 3`` points) at parameters ``t``, from its
    three diagonals: the same operations on the non-zero entries (the zeros add exactly nothing)."""
    n = len(t)
    h = t[1:] - t[:-1]
    h0, h1 = h[:-1], h[1:]
    out = np.zeros((n, n))
    diagonal = out.reshape(-1)[n + 1:n * (n - 1):n + 1]  # entries (i, i) of the inner rows, a view
    # _middle_slope's ((p1 - p0) / h0 * h1 + (p2 - p1) / h1 * h0) / (h0 + h1) at columns i - 1, i, i + 1
    out.reshape(-1)[n:n * (n - 1):n + 1] = (-1.0 / h0 * h1) / (h0 + h1)
    diagonal[:] = (1.0 / h0 * h1 + -1.0 / h1 * h0) / (h0 + h1)
    out.reshape(-1)[n + 2:n * (n - 1) + 2:n + 1] = (1.0 / h1 * h0) / (h0 + h1)
    # the end rows: the one parabola's derivative at its first / last node
    d0, d1 = np.array([-1.0, 1.0, 0.0]) / h[0], np.array([0.0, -1.0, 1.0]) / h[1]
    out[0, :3] = d0 - (d1 - d0) * h[0] / (h[0] + h[1])
    e0, e1 = np.array([-1.0, 1.0, 0.0]) / h[-2], np.array([0.0, -1.0, 1.0]) / h[-1]
    out[-1, -3:] = e1 + (e1 - e0) * h[-1] / (h[-2] + h[-1])
    return out


def _middle_slope(p0, p1, p2, h0, h1) -> np.ndarray:
    """Derivative at the middle node of the parabola through three nodes."""
    h0 = np.asarray(h0)[:, None]
    h1 = np.asarray(h1)[:, None]
    return ((p1 - p0) / h0 * h1 + (p2 - p1) / h1 * h0) / (h0 + h1)


def overhauser_curve(points, params=None, closed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Parabolic-blending curve through every point, as cubic Bezier segments.

    Seed 000, eq. 6: each segment between consecutive points is the linear blend
    of the two overlapping parabolas, a cubic that is converted exactly.

    Parameters
    ----------
    points : array_like, shape (n, d)
        Points along the curve, float64, any dimension ``d``.
    params : array_like, shape (n,), optional
        Strictly increasing parameters (chord length when omitted); see
        :func:`overhauser_tangents` for closed curves.
    closed : bool
        Closed curve: ``n`` segments, the last from ``points[-1]`` back to ``points[0]``.

    Returns
    -------
    control : numpy.ndarray, shape (S, 4, d)
        Bezier points of the ``S`` segments (``S = n`` closed, ``n - 1`` open).
    knots : numpy.ndarray, shape (S + 1,)
        Parameter at the start of each segment and the end of the last.
    """
    pts = as_array(points, "points", ndim=2)
    t = _parameters(pts, params, closed)
    if closed:
        if len(pts) < 3:
            raise InputError(f"points: need at least 3 points, got {len(pts)}")
        return _overhauser_closed(pts, t, np.zeros(1, np.int64), np.array([len(pts)]))
    tan = overhauser_tangents(pts, t, closed)
    h = np.diff(t)[:, None]
    ctrl = np.stack([pts[:-1], pts[:-1] + h * tan[:-1] / 3.0, pts[1:] - h * tan[1:] / 3.0, pts[1:]], axis=1)
    return ctrl, t


def overhauser_closed_curves(points, params, sizes) -> tuple[np.ndarray, np.ndarray]:
    """Closed parabolic-blending curves of many point lists at once, as cubic Bezier segments.

    The same curves as :func:`overhauser_curve` with ``closed=True`` for each
    list, computed in one array pass over the concatenated points (the lists
    may differ in length).

    Parameters
    ----------
    points : array_like, shape (N, d)
        The curves' points one after the other: curve ``c`` is the ``sizes[c]``
        rows starting at ``sum(sizes[:c])``.
    params : array_like, shape (N,)
        Per curve, strictly increasing parameters spanning less than one period.
    sizes : array_like of int, shape (C,)
        Points per curve, each at least 3, summing to ``N``.

    Returns
    -------
    control : numpy.ndarray, shape (N, 4, d)
        Bezier points: row ``sum(sizes[:c]) + i`` is segment ``i`` of curve ``c``
        (from its point ``i`` to the next, the last back to its first point).
    knots : numpy.ndarray, shape (N + C,)
        Per curve its ``sizes[c] + 1`` knots (its parameters, then the first plus
        one), starting at ``sum(sizes[:c]) + c``.

    Examples
    --------
    >>> sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> t = np.r_[np.arange(4) / 4, np.arange(3) / 3]
    >>> ctrl, knots = overhauser_closed_curves(np.vstack([sq, sq[:3]]), t, [4, 3])
    >>> ctrl.shape, knots.round(3).tolist()
    ((7, 4, 2), [0.0, 0.25, 0.5, 0.75, 1.0, 0.0, 0.333, 0.667, 1.0])
    >>> bool(np.allclose(ctrl[4:], overhauser_curve(sq[:3], np.arange(3) / 3, closed=True)[0]))
    True
    """
    pts = as_array(points, "points", ndim=2)
    t, start, ns = closed_curve_parameters(pts, params, sizes)
    return _overhauser_closed(pts, t, start, ns)


def closed_curve_parameters(pts: np.ndarray, params, sizes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check the parameters of several closed curves stacked in one array, and find where each starts.

    The validation of :func:`overhauser_closed_curves`, public for callers that go on
    with the kernels (:func:`overhauser_closed_by_coordinate`, :func:`restrict_closed_rows`).

    Parameters
    ----------
    pts : numpy.ndarray, shape (N, d)
        The curves' points, curve after curve (only ``len(pts)`` is used).
    params : array_like, shape (N,)
        Each point's parameter: strictly increasing along every curve, each curve
        spanning less than one period (1.0).
    sizes : array_like of int, shape (K,)
        Points per curve, each at least 3, summing to ``N``.

    Returns
    -------
    t : numpy.ndarray, shape (N,), float64
        The parameters.
    start : numpy.ndarray, shape (K,), int64
        Row of each curve's first point.
    ns : numpy.ndarray, shape (K,), int64
        The sizes.

    Raises
    ------
    InputError
        On sizes that do not add up or parameters that do not increase or span a period.

    Examples
    --------
    >>> t, start, ns = closed_curve_parameters(np.zeros((7, 2)), [0, 0.3, 0.6, 0, 0.2, 0.5, 0.7], [3, 4])
    >>> start.tolist(), ns.tolist()
    ([0, 3], [3, 4])
    """
    t = as_array(params, "params", shape=(len(pts),))
    ns = np.asarray(sizes)
    if ns.ndim != 1 or not len(ns) or ns.dtype.kind not in "iu" or ns.min() < 3 or int(ns.sum()) != len(pts):
        raise InputError(f"sizes: need integer counts of at least 3 points summing to {len(pts)}, got {sizes!r}")
    ns = ns.astype(np.int64)
    start = ns.cumsum() - ns
    inner = np.ones(len(pts), dtype=bool)
    inner[start] = False
    if (t[1:] <= t[:-1])[inner[1:]].any():
        raise InputError("params: must increase strictly along every curve")
    if not (t[start + ns - 1] - t[start] < 1.0).all():
        raise InputError("params: a closed curve needs parameters spanning less than one period")
    return t, start, ns


def _overhauser_closed(pts: np.ndarray, t: np.ndarray, start: np.ndarray,
                       ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`overhauser_closed_curves` of validated arrays, the curves starting at rows ``start``."""
    by_coordinate, knots = overhauser_closed_by_coordinate(np.ascontiguousarray(pts.T), t, start, ns)
    return np.ascontiguousarray(by_coordinate.transpose(2, 0, 1)), knots


def overhauser_closed_by_coordinate(p: np.ndarray, t: np.ndarray, start: np.ndarray,
                                     ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed Overhauser curves of checked arrays, coordinate by coordinate (the kernel of
    :func:`overhauser_closed_curves`).

    Every operation runs along all ``N`` points of all curves at once.

    Parameters
    ----------
    p : numpy.ndarray, shape (d, N), float64
        The points' coordinates, one row per coordinate (mm).
    t, start, ns : numpy.ndarray
        As :func:`closed_curve_parameters` returns them (not checked again).

    Returns
    -------
    ctrl : numpy.ndarray, shape (4, d, N)
        Bezier points of the segment that starts at each point.
    knots : numpy.ndarray, shape (N + K,)
        Each curve's parameters followed by its first parameter plus one period.
    """
    last = start + ns - 1
    n = p.shape[1]
    nxt = np.arange(1, n + 1)
    nxt[last] = start
    prv = np.arange(-1, n - 1)
    prv[start] = last
    t_next = t[nxt]
    t_next[last] += 1.0
    t_prev = t[prv]
    t_prev[start] -= 1.0
    h1 = t_next - t
    h0 = t - t_prev
    p_end = p.take(nxt, axis=1)
    # the derivative at the middle node of the parabola through three nodes (as _middle_slope)
    tan = ((p - p.take(prv, axis=1)) / h0 * h1 + (p_end - p) / h1 * h0) / (h0 + h1)
    ctrl = np.empty((4,) + p.shape)
    ctrl[0] = p
    ctrl[3] = p_end
    np.multiply(h1, tan / 3.0, out=ctrl[1])
    ctrl[1] += p
    np.multiply(h1, tan.take(nxt, axis=1) / 3.0, out=ctrl[2])
    np.subtract(p_end, ctrl[2], out=ctrl[2])
    knots = np.empty(n + len(ns))
    curve = np.arange(len(ns)).repeat(ns)
    knots[np.arange(n) + curve] = t
    knots[last + np.arange(1, len(ns) + 1)] = t[start] + 1.0
    return ctrl, knots




def evaluate_curve(control, knots, u, derivative: int = 0) -> np.ndarray:
    """Points (or first derivatives) of a piecewise cubic Bezier curve.

    Parameters
    ----------
    control : array_like, shape (S, 4, d)
        Bezier segments, e.g. from :func:`overhauser_curve`.
    knots : array_like, shape (S + 1,)
        Strictly increasing segment breakpoints.
    u : array_like, shape (N,)
        Parameters in ``[knots[0], knots[-1]]``.
    derivative : {0, 1}
        0 for points, 1 for ``dC/du`` (per unit of ``u``, not of segment parameter).

    Returns
    -------
    numpy.ndarray, shape (N, d)
    """
    ctrl = as_array(control, "control", ndim=3)
    k = as_array(knots, "knots", shape=(len(ctrl) + 1,))
    uu = as_array(u, "u", ndim=1)
    if derivative not in (0, 1):
        raise InputError(f"derivative: must be 0 or 1, got {derivative!r}")
    tol = 1e-12 * max(1.0, float(k[-1] - k[0]))
    if len(uu) and (uu.min() < k[0] - tol or uu.max() > k[-1] + tol):
        raise InputError(f"u: outside the curve's parameter range [{k[0]}, {k[-1]}]")
    seg = np.clip(np.searchsorted(k, uu, side="right") - 1, 0, len(ctrl) - 1)
    h = k[seg + 1] - k[seg]
    s = np.clip((uu - k[seg]) / h, 0.0, 1.0)
    return _segment_values(ctrl[seg], s, h, derivative)


def _segment_values(c: np.ndarray, s: np.ndarray, h: np.ndarray, derivative: int) -> np.ndarray:
    """Points (0) or ``d/du`` (1) of cubic Bezier segments ``c`` (N, 4, d) at local ``s`` (N,), lengths ``h``."""
    value = np.einsum("na,nad->nd", bernstein(s, derivative), c)
    return value / h[:, None] if derivative else value


def restrict_curve(control, knots, breakpoints) -> np.ndarray:
    """Exact Bezier segments of a piecewise cubic on a finer set of breakpoints.

    Every interval ``[breakpoints[m], breakpoints[m + 1]]`` must lie inside one
    segment of the curve (the breakpoints include all knots); there the curve is
    one cubic, given exactly by its end points and end derivatives (Hermite form).

    Parameters
    ----------
    control : array_like, shape (S, 4, d)
        Bezier segments.
    knots : array_like, shape (S + 1,)
        Their breakpoints.
    breakpoints : array_like, shape (M + 1,)
        Strictly increasing, containing every knot, spanning ``[knots[0], knots[-1]]``.

    Returns
    -------
    numpy.ndarray, shape (M, 4, d)
        Bezier segments on the new breakpoints.
    """
    ctrl = as_array(control, "control", ndim=3)
    b = as_array(breakpoints, "breakpoints", ndim=1, min_size=2)
    return restrict_curves(ctrl, knots, [len(ctrl)], b[None])[0]


def restrict_curves(control, knots, sizes, breakpoints) -> np.ndarray:
    """:func:`restrict_curve` of many piecewise cubics at once, each on its own breakpoints.

    Parameters
    ----------
    control : array_like, shape (S, 4, d)
        Bezier segments of all curves one after the other: curve ``c`` is the
        ``sizes[c]`` rows starting at ``sum(sizes[:c])``.
    knots : array_like, shape (S + C,)
        Per curve its ``sizes[c] + 1`` strictly increasing knots, starting at
        ``sum(sizes[:c]) + c`` (as :func:`overhauser_closed_curves` returns them).
    sizes : array_like of int, shape (C,)
        Segments per curve, each at least 1.
    breakpoints : array_like, shape (C, M + 1)
        Per curve, strictly increasing, containing every knot of the curve and
        spanning ``[first knot, last knot]``.

    Returns
    -------
    numpy.ndarray, shape (C, M, 4, d)
        Bezier segments of every curve on its breakpoints.

    Examples
    --------
    The cubic ``u^3`` as one segment on ``[0, 1]`` and the line ``u`` as two on
    ``[0, 2]``, each cut in two:

    >>> cubic = np.array([[[0.0], [0.0], [0.0], [1.0]]])
    >>> line = np.array([[[0.0], [1 / 3], [2 / 3], [1.0]], [[1.0], [4 / 3], [5 / 3], [2.0]]])
    >>> out = restrict_curves(np.vstack([cubic, line]), [0, 1, 0, 1, 2], [1, 2], [[0, 0.5, 1], [0, 1, 2]])
    >>> out[0, 0, :, 0].tolist(), out[1, 1, :, 0].round(12).tolist()
    ([0.0, 0.0, 0.0, 0.125], [1.0, 1.333333333333, 1.666666666667, 2.0])
    """
    ctrl = as_array(control, "control", ndim=3)
    ns = np.asarray(sizes)
    if ns.ndim != 1 or not len(ns) or ns.dtype.kind not in "iu" or ns.min() < 1 or int(ns.sum()) != len(ctrl):
        raise InputError(f"sizes: need integer counts of at least 1 segment summing to {len(ctrl)}, got {sizes!r}")
    ns = ns.astype(np.int64)
    n_c = len(ns)
    k = as_array(knots, "knots", shape=(len(ctrl) + n_c,))
    b = as_array(breakpoints, "breakpoints", shape=(n_c, None))
    if b.shape[1] < 2:
        raise InputError(f"breakpoints: need at least 2 per curve, got {b.shape[1]}")
    if np.any(np.diff(b, axis=1) <= 0):
        raise InputError("breakpoints: must increase strictly")
    kstart = (ns + 1).cumsum() - (ns + 1)
    curve = np.arange(n_c).repeat(ns + 1)
    lo, hi = k[kstart], k[kstart + ns]
    if np.any(np.diff(k)[(curve[1:] == curve[:-1])] <= 0):
        raise InputError("knots: must increase strictly along every curve")
    # shift every curve's knots and breakpoints by its own offset so that the curves never interleave
    step = 2.0 * float(np.max(hi - lo)) + 1.0
    shift = np.arange(n_c) * step - lo
    key = k + shift[curve]
    keyed_b = b + shift[:, None]
    scale = np.maximum(1.0, hi - lo)[curve]
    pos = np.clip(np.searchsorted(keyed_b.ravel(), key), 0, b.size - 1)
    if np.max(np.abs(b.ravel()[pos] - k) / scale) > 1e-12:
        raise InputError("breakpoints: must contain every knot of the curve")
    # evaluate each interval's ends inside the segment that contains the interval's midpoint
    mid = (0.5 * (keyed_b[:, :-1] + keyed_b[:, 1:])).ravel()
    g = np.searchsorted(key, mid, side="right") - 1
    local = np.clip(g - kstart[np.arange(n_c).repeat(b.shape[1] - 1)], 0, (ns - 1).repeat(b.shape[1] - 1))
    first_knot = kstart.repeat(b.shape[1] - 1) + local
    seg = first_knot - np.arange(n_c).repeat(b.shape[1] - 1)
    out = restrict_segments(ctrl[seg], k[first_knot], k[first_knot + 1], b[:, :-1].ravel(), b[:, 1:].ravel())
    return out.reshape(n_c, b.shape[1] - 1, 4, ctrl.shape[2])


def restrict_segments(control, start, end, lo, hi) -> np.ndarray:
    """Bezier points of cubic segments on sub-intervals of their parameter ranges.

    Parameters
    ----------
    control : array_like, shape (P, 4, d)
        Bezier points of ``P`` cubic segments, segment ``p`` running over
        ``[start[p], end[p]]``.
    start, end : array_like, shape (P,)
        Each segment's parameter range (``start < end``).
    lo, hi : array_like, shape (P,)
        The sub-interval wanted of each segment (``lo < hi``, usually inside
        ``[start, end]``; outside it the cubic is extrapolated).

    Returns
    -------
    numpy.ndarray, shape (P, 4, d)
        Bezier points of each cubic on ``[lo, hi]`` (Hermite form: end points and
        end derivatives per unit of the parameter).

    Examples
    --------
    >>> restrict_segments([[[0.0], [0.0], [0.0], [1.0]]], [0.0], [2.0], [0.0], [1.0])[0, :, 0].tolist()
    [0.0, 0.0, 0.0, 0.125]
    """
    c = as_array(control, "control", shape=(None, 4, None))
    k0 = as_array(start, "start", shape=(len(c),))
    k1 = as_array(end, "end", shape=(len(c),))
    b0 = as_array(lo, "lo", shape=(len(c),))
    b1 = as_array(hi, "hi", shape=(len(c),))
    if np.any(k1 <= k0) or np.any(b1 <= b0):
        raise InputError("start/end, lo/hi: every range must increase strictly")
    return _restrict_segments(c, k0, k1, b0, b1, np.empty_like(c))


def _restrict_segments(c: np.ndarray, k0: np.ndarray, k1: np.ndarray, b0: np.ndarray, b1: np.ndarray,
                       out: np.ndarray) -> np.ndarray:
    """:func:`restrict_segments` of validated arrays, written into ``out`` (P, 4, d), which may be a view."""
    h = k1 - k0
    t = np.empty((len(c), 2))
    t[:, 0] = (b0 - k0) / h
    t[:, 1] = (b1 - k0) / h
    # the cubic Bernstein basis and its derivative at both ends (as surfaces.bezier.bernstein), so
    # one product gives the end points and end derivatives of every piece
    r = 1.0 - t
    basis = np.empty((len(c), 2, 2, 4))
    for b, value in enumerate((r * r * r, 3.0 * t * r * r, 3.0 * t * t * r, t * t * t)):
        basis[:, :, 0, b] = value
    for b, value in enumerate((-3.0 * r * r, 3.0 * r * (r - 2.0 * t), 3.0 * t * (2.0 * r - t), 3.0 * t * t)):
        basis[:, :, 1, b] = value
    ends = (basis.reshape(len(c), 4, 4) @ c).reshape(len(c), 2, 2, -1)  # (P, end, order, d)
    w = ((b1 - b0) / (3.0 * h))[:, None]
    out[:, 0] = ends[:, 0, 0]
    out[:, 3] = ends[:, 1, 0]
    np.multiply(ends[:, 0, 1], w, out=out[:, 1])
    out[:, 1] += ends[:, 0, 0]
    np.multiply(ends[:, 1, 1], w, out=out[:, 2])
    np.subtract(ends[:, 1, 0], out[:, 2], out=out[:, 2])
    return out


def restrict_closed_rows(c: np.ndarray, k0: np.ndarray, k1: np.ndarray, b0: np.ndarray, b1: np.ndarray,
                   n_row: int, out: np.ndarray) -> np.ndarray:
    """:func:`restrict_segments` of pieces that tile closed curves, each breakpoint evaluated once (a kernel).

    The ``P`` pieces form rows of ``n_row``, each row one closed curve: piece
    ``i`` ends where the next one in its row starts (the last where the first
    starts). Where that next piece lies on the same segment (the same ``k0``,
    ``k1`` and ``c``), its start's point and derivative are the piece's end's;
    otherwise the piece ends at its segment's end ``k1``. ``c`` (4, d, P) holds
    each piece's segment, coordinate by coordinate (so that every operation runs
    along ``P``); the Bezier points go into ``out`` (P, 4, d).

    Parameters
    ----------
    c : numpy.ndarray, shape (4, d, P), float64
        Bezier points of each piece's segment, coordinate by coordinate.
    k0, k1 : numpy.ndarray, shape (P,)
        Parameter of each segment's start and end (``k1 > k0``).
    b0, b1 : numpy.ndarray, shape (P,)
        Parameter of each piece's start and end, inside ``[k0, k1]``.
    n_row : int
        Pieces per closed curve (``P`` is a multiple of it).
    out : numpy.ndarray, shape (P, 4, d), float64
        Receives the pieces' Bezier points.

    Returns
    -------
    numpy.ndarray
        ``out``.
    """
    h = k1 - k0
    s = (b0 - k0) / h
    # de Casteljau at every piece's start, each level one operation over all pieces and coordinates
    # (the same roundings as point by point: s (p1 - p0) + p0, ...)
    a = c[1:] - c[:-1]
    a *= s
    a += c[:-1]
    e = a[1:] - a[:-1]
    e *= s
    e += a[:-1]
    # the derivative per unit of the segment's parameter and the point, one block for the next pieces
    start = np.empty((2,) + c.shape[1:])
    tangent, point = start
    np.subtract(e[1], e[0], out=tangent)
    np.multiply(s, tangent, out=point)
    point += e[0]
    tangent *= 3.0
    # the next piece in the row by slices of the (rows, n_row) view (a gather costs more)
    rows = len(s) // n_row
    k0r, k1r = k0.reshape(rows, n_row), k1.reshape(rows, n_row)
    same = np.empty((rows, n_row), dtype=bool)
    np.equal(k0r[:, 1:], k0r[:, :-1], out=same[:, :-1])
    same[:, :-1] &= k1r[:, 1:] == k1r[:, :-1]
    same[:, -1] = (k0r[:, 0] == k0r[:, -1]) & (k1r[:, 0] == k1r[:, -1])
    w = (b1 - b0) / (3.0 * h)
    ends = np.empty((4,) + point.shape)
    ends[0] = point
    np.multiply(w, tangent, out=ends[1])
    ends[1] += point
    np.subtract(c[3], c[2], out=ends[2])
    ends[2] *= 3.0
    ends[3] = c[3]
    # where the next piece lies on the same segment, its start's derivative and point are this one's end's
    by_row, start_by_row = ends[2:].reshape(2, -1, rows, n_row), start.reshape(2, -1, rows, n_row)
    np.copyto(by_row[..., :-1], start_by_row[..., 1:], where=same[:, :-1])
    np.copyto(by_row[..., -1], start_by_row[..., 0], where=same[:, -1])
    ends[2] *= w
    np.subtract(ends[3], ends[2], out=ends[2])
    out[...] = ends.transpose(2, 0, 1)
    return out


def blend_weights(n_curves: int, params=None) -> np.ndarray:
    """Bezier weights of the uniform parabolic blending across curves (seed 000, eqs. 13-19).

    Parameters
    ----------
    n_curves : int
        Number of curves (slices), at least 2.
    params : array_like, shape (n_curves,), optional
        Strictly increasing ``v`` of the curves (e.g. slice positions in mm) for
        unequally spaced slices; uniform when omitted (the seed's case). Tangents
        are then those of the non-uniform parabolas (as in ``u``), per unit of
        each piece's own parameter.

    Returns
    -------
    numpy.ndarray, shape (n_curves - 1, 4, n_curves)
        ``W[j, b, k]``: Bezier point ``b`` (along ``v``) of the surface piece
        between curves ``j`` and ``j + 1`` is ``sum_k W[j, b, k] * curve_k``.
        With ``v = -1, 0, 1, 2`` at curves ``j - 1 .. j + 2`` the tangent at a
        curve is ``(C_{j+1} - C_{j-1}) / 2``; at the first and last curve it is
        the derivative of the one parabola there, ``(-3 C_0 + 4 C_1 - C_2) / 2``;
        with two curves the surface is ruled.
    """
    n = int(n_curves)
    if n < 2:
        raise InputError(f"n_curves: need at least 2 curves, got {n_curves}")
    if params is not None:
        v = as_array(params, "params", shape=(n,))
        if np.any(np.diff(v) <= 0):
            raise InputError("params: must increase strictly")
    return _blend_weights(n, None if params is None else v)


def _blend_weights(n: int, v: np.ndarray | None) -> np.ndarray:
    """:func:`blend_weights` of ``n >= 2`` curves at validated, strictly increasing ``v`` (or uniform)."""
    if v is not None:
        # tangent rows (dC/dv) are the Overhauser tangents of the identity "points"
        tangent = _open_tangents(np.eye(n), v) if n < 3 else _identity_tangents(v)
        h = (v[1:] - v[:-1])[:, None]
        # rows [e_j, e_j + h t_j / 3, e_{j+1} - h t_{j+1} / 3, e_{j+1}] written in place: the same
        # operations on every entry (0 + x, 0 - x and 1 + x, 1 - x where e has its one)
        out = np.zeros((n - 1, 4, n))
        np.divide(h * tangent[:-1], 3.0, out=out[:, 1])
        np.subtract(0.0, h * tangent[1:] / 3.0, out=out[:, 2])
        # entry (j, b, j) or (j, b, j + 1) lies at j (4 n + 1) + b n (+ 1): a strided view each
        flat = out.reshape(-1)
        step = 4 * n + 1
        flat[0::step] = 1.0
        flat[n::step] += 1.0
        flat[2 * n + 1::step] += 1.0
        flat[3 * n + 1::step] = 1.0
        return out
    tangent = np.zeros((n, n))
    if n == 2:
        tangent[:, 0], tangent[:, 1] = -1.0, 1.0
    else:
        idx = np.arange(1, n - 1)
        tangent[idx, idx + 1] = 0.5
        tangent[idx, idx - 1] = -0.5
        tangent[0, :3] = (-1.5, 2.0, -0.5)
        tangent[-1, -3:] = (0.5, -2.0, 1.5)
    eye = np.eye(n)
    j = np.arange(n - 1)
    return np.stack(
        [eye[j], eye[j] + tangent[j] / 3.0, eye[j + 1] - tangent[j + 1] / 3.0, eye[j + 1]], axis=1
    )


def blend_curves(curves, closed_u: bool = True, params=None, monotone: bool = False) -> BezierPatches:
    """Surface through a stack of curves by uniform parabolic blending in ``v``.

    Seed 000, eqs. 13-19: ``S(u, v) = (1 - v) Pc(v) + v Pd(v)`` between
    neighbouring curves, ``Pc``/``Pd`` the parabolas through three consecutive
    curves at the same ``u``. Because the blend is linear in the curves, Bezier
    curves on common breakpoints give bicubic Bezier patches exactly.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        ``K >= 2`` curves, each as ``M`` cubic Bezier segments on the same
        ``u`` breakpoints (see :func:`restrict_curve`).
    closed_u : bool
        The curves are closed (segment ``M - 1`` ends where segment 0 starts).
    params : array_like, shape (K,), optional
        ``v`` of the curves for unequal spacing (see :func:`blend_weights`).
    monotone : bool
        Limit the blend in ``v`` so it never overshoots between curves
        (:func:`limit_monotone`, per control point and coordinate); the
        surface still passes through every curve.

    Returns
    -------
    BezierPatches
        ``M x (K - 1)`` patches; patch row ``i`` follows curve segment ``i``,
        patch column ``j`` spans curves ``j`` to ``j + 1``.
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    if len(c) < 2:
        raise InputError(f"curves: need at least 2 curves, got {len(c)}")
    return blend_validated(c, closed_u, params, monotone)[0]


def monotone_blend(curves, closed_u: bool = True, params=None) -> tuple[BezierPatches, np.ndarray]:
    """:func:`blend_curves` with ``monotone=True``, and which tangents the limit shortened.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        ``K >= 2`` curves on common ``u`` breakpoints (as for :func:`blend_curves`).
    closed_u : bool
        The curves are closed.
    params : array_like, shape (K,), optional
        ``v`` of the curves (see :func:`blend_weights`).

    Returns
    -------
    patches : BezierPatches
        ``M x (K - 1)`` patches, the same as ``blend_curves(curves, closed_u, params, monotone=True)``.
    limited : numpy.ndarray, shape (K, M, 4, 3) bool
        Per curve, Bezier point and coordinate: the tangent in ``v`` there was
        shortened or zeroed (:attr:`LimitedBlend.limited`).
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    if len(c) < 2:
        raise InputError(f"curves: need at least 2 curves, got {len(c)}")
    return blend_validated(c, closed_u, params, True)


def blend_validated(c: np.ndarray, closed_u: bool, params, monotone: bool,
           trusted: bool = False, out: np.ndarray | None = None) -> tuple[BezierPatches, np.ndarray | None]:
    """:func:`blend_curves` of validated curves, with the limited tangents when ``monotone`` (the kernel).

    Parameters
    ----------
    c : numpy.ndarray, shape (K, M, 4, 3), float64
        ``K`` validated cubic Bezier curves of ``M`` segments each (mm).
    closed_u : bool
        Whether the curves close on themselves.
    params : array_like, shape (K,), optional
        The curves' parameters along ``v`` (default: uniform).
    monotone : bool
        Limit the tangents along ``v`` so that every coordinate stays monotone
        between curves (:func:`monotone_blend`).
    trusted : bool
        ``c`` is finite and ``params`` (or None) validated, strictly increasing, as
        :func:`slices.surface.side_surface` checks them; the patches then skip their
        finiteness check (a blend of finite curves is finite), only the closing of
        ``u`` is checked.
    out : numpy.ndarray, shape (M, K - 1, 4, 4, 3), float64, optional
        With its last three axes contiguous (such as the side columns of a capped
        grid): the control points are written there and the patches are a view of it.

    Returns
    -------
    patches : BezierPatches
        ``M`` x ``K - 1`` patches.
    limited : numpy.ndarray, shape (K, M, 4, 3) bool, or None
        The tangents that were limited (``monotone``), else None.
    """
    k, m = c.shape[:2]
    w = blend_weights(k, params) if not trusted else _blend_weights(k, None if params is None else params)
    # moved as whole 3-vectors (one 24-byte item each), which numpy copies faster than single floats
    item = np.dtype((np.void, 8 * 3))
    limited = None
    control = np.empty((m, k - 1, 4, 4, 3)) if out is None else out
    # the patches' points as whole 3-vectors (indexed, not reshaped: a view of a strided ``out`` too)
    into = control.view(item)[..., 0]  # (M, K - 1, 4, 4)
    if monotone:
        # one matrix product over all curves (faster than einsum's batched path), the rows ordered by
        # Bezier point along v first, so that each of the four is one contiguous block for the limit
        mixed = (w.transpose(1, 0, 2).reshape(-1, k) @ c.reshape(k, -1)).reshape(4, k - 1, m, 4, 3)
        q = mixed.reshape(4, k - 1, -1)
        limited = (_limit_parts(q[0], q[1], q[2], q[3], _tiny(q)) < 1.0).reshape(c.shape)
        into[...] = mixed.view(item).reshape(4, k - 1, m, 4).transpose(2, 1, 3, 0)
    else:
        # the first and last Bezier points along v are the curves themselves (weight rows of the
        # identity): copied, and only the inner two come from a matrix product; all four are laid
        # out by Bezier point along v first (contiguous blocks), then scattered into the patches'
        # layout in one pass (faster than one scatter per Bezier point)
        cc = np.ascontiguousarray(c)
        by_b = np.empty((4, k - 1, m, 4, 3))
        by_b[0] = cc[:-1]
        np.matmul(w[:, 1:3].transpose(1, 0, 2).reshape(-1, k), cc.reshape(k, -1),
                  out=by_b[1:3].reshape(2 * (k - 1), -1))
        by_b[3] = cc[1:]
        into[...] = by_b.view(item).reshape(4, k - 1, m, 4).transpose(2, 1, 3, 0)
    if not trusted:
        return BezierPatches(control, closed_u=closed_u), limited
    if closed_u:  # BezierPatches' test of the closing, on the two rows it compares
        ends = control[::max(m - 1, 1)]
        gap = float(np.abs(control[-1, :, 3] - control[0, :, 0]).max())
        if gap > _JOIN_RTOL * max(float(ends.max()), -float(ends.min()), 1.0):
            raise InputError(f"closed_u: the last patch row does not join the first (gap {gap:.3g})")
    return BezierPatches.unchecked(control, closed_u=closed_u), limited


@dataclass(frozen=True)
class LimitedBlend:
    """Cubic pieces in ``v`` with their tangents limited to stay monotone (:func:`limit_monotone`).

    Attributes
    ----------
    control : numpy.ndarray, shape (K - 1, 4, F)
        Bezier points of the ``K - 1`` pieces along ``v``, every column one coordinate.
    limited : numpy.ndarray, shape (K, F) bool
        Tangents (node ``k``, coordinate) that were shortened or zeroed.
    """

    control: np.ndarray
    limited: np.ndarray


def limit_monotone(pieces) -> LimitedBlend:
    """Shape-preserving limit of a C1 chain of cubic pieces (Fritsch & Carlson 1980, per coordinate).

    Between two nodes the parabolic blend overshoots where the data turn (a
    protrusion present on one slice only, a sharp turn): its inner Bezier
    points leave the interval of the piece's end values. Each node's tangent
    is scaled, per coordinate, so that both inner Bezier points next to it
    stay between the end values of their piece; where the neighbouring
    differences change sign (a local extremum of the data) the tangent
    becomes zero. The same factor applies on both sides of the node, so the
    chain stays C1 and passes through every node; each piece is then
    monotone in every coordinate (its Bezier points are), and so never
    leaves the box spanned by its two nodes.

    Parameters
    ----------
    pieces : array_like, shape (K - 1, 4, F)
        Bezier points ``P_k, P_k + a_k, P_{k+1} - b_k, P_{k+1}`` of consecutive
        pieces (piece ``k`` ends where piece ``k + 1`` starts), any number ``F``
        of coordinates.

    Returns
    -------
    LimitedBlend

    Examples
    --------
    A step 0, 0, 1: the parabolic blend dips below 0 on the flat piece and
    overshoots nowhere else; the limit flattens the first piece:

    >>> w = blend_weights(3)
    >>> pieces = (w.reshape(-1, 3) @ np.array([[0.0], [0.0], [1.0]])).reshape(2, 4, 1)
    >>> pieces[0, :, 0].round(3).tolist()
    [0.0, -0.167, -0.167, 0.0]
    >>> r = limit_monotone(pieces)
    >>> r.control[:, :, 0].round(3).tolist(), r.limited[:, 0].tolist()
    ([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.5, 1.0]], [True, True, False])
    """
    return _limit_monotone(as_array(pieces, "pieces", shape=(None, 4, None)))


def _limit_monotone(p: np.ndarray, in_place: bool = False) -> LimitedBlend:
    """:func:`limit_monotone` of validated pieces (written into ``p`` itself when ``in_place``)."""
    q = p if in_place else p.copy()
    scale = _limit_parts(q[:, 0], q[:, 1], q[:, 2], q[:, 3], _tiny(q))
    return LimitedBlend(q, scale < 1.0)


def _tiny(p: np.ndarray) -> float:
    """What counts as no rise in :func:`limit_monotone` of pieces ``p``: 1e-12 of their size."""
    return 1e-12 * (max(float(p.max()), -float(p.min())) + 1.0)


def _limit_parts(q0: np.ndarray, q1: np.ndarray, q2: np.ndarray, q3: np.ndarray, tiny: float) -> np.ndarray:
    """:func:`limit_monotone` of the pieces' four Bezier points ``q0..q3`` (each (K - 1, F)), the inner
    two limited in place; returns the tangents' scale factors (K, F).

    The result's own rows hold the tangents while they are limited, and the
    buffers are reused from step to step: on a body's few hundred thousand
    coordinates each fresh temporary costs as much in page faults as its
    arithmetic (and contiguous ``q0..q3`` about half as much time as strided ones).
    """
    d = q3 - q0
    np.subtract(q1, q0, out=q1)  # a_k: leaves node k into piece k
    np.subtract(q3, q2, out=q2)  # b_k: enters node k + 1 from piece k
    scale = np.empty((len(q0) + 1,) + d.shape[1:])
    scale[-1] = 1.0
    np.abs(d, out=scale[:-1])
    flat = np.flatnonzero(scale[:-1] <= tiny)  # few: pieces that do not rise in a coordinate
    d_flat = d.ravel()[flat]
    with np.errstate(divide="ignore", invalid="ignore"):
        # the last side's ratio overwrites d, which it reads first
        for side, ratio in ((q1, scale[:-1]), (q2, d)):
            # rise over tangent: negative (a tangent against the piece's own direction) gives 0, and
            # beyond 1 (not longer than the rise) nothing to shorten
            np.divide(d, side, out=ratio)
            np.clip(ratio, 0.0, 1.0, out=ratio)
            ratio.ravel()[np.flatnonzero(side == 0.0)] = 1.0  # a zero tangent needs no shortening
            if len(flat):  # a tangent along a piece that does not rise (even against it) overshoots
                s_flat = side.ravel()[flat]
                keep = (np.abs(s_flat) <= tiny) & (s_flat * d_flat >= 0.0)
                ratio.ravel()[flat] = np.where(keep, np.fmin(np.abs(d_flat) / np.abs(s_flat), 1.0), 0.0)
    np.minimum(scale[1:], d, out=scale[1:])
    q1 *= scale[:-1]
    q1 += q0
    q2 *= scale[1:]
    np.subtract(q3, q2, out=q2)
    return scale


def from_grid(points, u_params=None, closed_u: bool = False, closed_v: bool = False) -> BezierPatches:
    """Parabolic-blending surface through every point of a grid (seed 000, eqs. 6-19).

    Rows of the grid (axis 0 runs along ``u``) are first blended into curves in
    ``u`` with the given (or chord-length, averaged over columns) parameters,
    then the curves are blended uniformly in ``v``.

    Parameters
    ----------
    points : array_like, shape (R, C, 3)
        Grid points; ``points[:, j]`` is curve ``j``.
    u_params : array_like, shape (R,), optional
        Strictly increasing common ``u`` parameters (one period when
        ``closed_u``); default averaged normalised chord length.
    closed_u : bool
        Close the ``u`` direction.
    closed_v : bool
        Close the ``v`` direction (blending wraps around the curves).

    Returns
    -------
    BezierPatches
        ``(R or R - 1) x (C or C - 1)`` patches through every grid point.
    """
    pts = as_array(points, "points", shape=(None, None, 3))
    rows, cols = pts.shape[:2]
    if rows < (3 if closed_u else 2) or cols < (3 if closed_v else 2):
        raise InputError(f"points: grid of {rows}x{cols} is too small")
    if u_params is None:
        u_params = _chord_parameters(pts, closed_u, "coincident grid rows")
    # curves along u for every column at once: treat the column index as extra coordinates
    flat = pts.reshape(rows, cols * 3)
    ctrl, _ = overhauser_curve(flat, u_params, closed=closed_u)
    curves = ctrl.reshape(len(ctrl), 4, cols, 3).transpose(2, 0, 1, 3)
    if closed_v:
        curves = np.concatenate([curves[-1:], curves, curves[:2]])
        patches = blend_curves(curves, closed_u=closed_u)
        control = patches.control[:, 1 : cols + 1]
        return BezierPatches(control, closed_u=closed_u, closed_v=True)
    return blend_curves(curves, closed_u=closed_u)
