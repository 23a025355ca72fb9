"""Parameters, knot vectors and knot insertion for B-spline interpolation (The NURBS Book ch. 5, 9).

Data parameters by the uniform, chord-length or centripetal rule, averaged
over the lines of a grid (eqs. 9.3-9.6, Algorithm A9.3); clamped knot vectors
by averaging (eq. 9.8) and their periodic counterpart; and the exact Bezier
pieces of a B-spline by inserting every interior knot up to multiplicity ``p``
(Algorithm A5.6), which is how :mod:`surfaces.bspline` enters the shared patch
model.

Parameters of an open direction run over ``[0, 1]``; a closed (periodic)
direction also uses ``[0, 1]`` with period 1, its data given without repeating
the first point.
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import as_array, InputError

__all__ = [
    "METHODS",
    "check_degree",
    "chord_lengths",
    "data_parameters",
    "averaged_knots",
    "periodic_knots",
    "interpolation_knots",
    "to_knot_domain",
    "span_parameters",
    "bezier_pieces",
    "cubic_pieces",
]

METHODS = ("uniform", "chord", "centripetal")
# relative size under which a parameter step counts as zero (coincident points)
_ZERO_STEP = 1e-12


def check_degree(degree, name: str = "degree") -> int:
    """A B-spline degree from 2 to 5, as an int.

    Parameters
    ----------
    degree : int
        The degree.
    name : str, optional
        Argument name used in error messages.

    Returns
    -------
    int

    Examples
    --------
    >>> check_degree(3)
    3
    """
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
        raise InputError(f"{name}: expected an integer from 2 to 5, got {degree!r}")
    if not 2 <= int(degree) <= 5:
        raise InputError(f"{name}: expected an integer from 2 to 5, got {degree}")
    return int(degree)


def chord_lengths(points: np.ndarray, axis: int = 0, closed: bool = False) -> np.ndarray:
    """Distances between consecutive points along one axis of an array of points.

    Parameters
    ----------
    points : (..., d) float array
        Points, coordinates on the last axis (any length unit).
    axis : int, optional
        The axis along which the points follow each other (not the last one).
    closed : bool, optional
        Also the chord from the last point back to the first.

    Returns
    -------
    float64 array
        The shape of ``points`` without its last axis, ``n - 1`` long along
        ``axis`` (``n`` when closed, the wrapping chord last).

    Examples
    --------
    >>> square = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0], [0.0, 4.0]])
    >>> chord_lengths(square).tolist(), chord_lengths(square, closed=True).tolist()
    ([3.0, 4.0, 3.0], [3.0, 4.0, 3.0, 4.0])
    """
    if closed:
        return np.linalg.norm(np.roll(points, -1, axis=axis) - points, axis=-1)
    return np.linalg.norm(np.diff(points, axis=axis), axis=-1)


def data_parameters(
    lines: np.ndarray,
    method: str = "chord",
    closed: bool = False,
    params=None,
    name: str = "params",
    what: str = "points",
) -> np.ndarray:
    """Parameters of the data points: averaged per-line parameters, or given ones checked.

    The NURBS Book eqs. 9.3-9.6 and Algorithm A9.3: every line gets uniform,
    chord-length or centripetal parameters, and the lines' parameters are
    averaged. A line of zero length (a collapsed row at a pole) carries no
    parameter information and is left out of the average.

    Parameters
    ----------
    lines : (L, N, d) array
        ``L`` polylines of ``N`` points each (one line for a curve; a grid's
        rows or columns for a surface).
    method : {"chord", "uniform", "centripetal"}
        Parameterisation.
    closed : bool
        Periodic: the last point's successor is the first point, at parameter 1.
    params : (N,) array_like, optional
        Explicit parameters instead of ``method``: strictly increasing, ``[0, 1]``
        with both ends when open, ``[0, 1)`` starting at 0 when closed.
    name : str
        Name of ``params`` in error messages.
    what : str
        What the ``N`` entries are, in error messages ("points", "rows", "columns").

    Returns
    -------
    (N,) float64
        Strictly increasing parameters in ``[0, 1]`` (``[0, 1)`` when closed).

    Raises
    ------
    ValueError
        Unknown method, bad explicit parameters, or coincident consecutive data
        (a zero parameter step), naming the entries.

    Examples
    --------
    >>> data_parameters(np.array([[[0.0, 0], [1, 0], [3, 0]]])).tolist()
    [0.0, 0.3333333333333333, 1.0]
    """
    if method not in METHODS:
        raise InputError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    n = lines.shape[1]
    if params is not None:
        u = _explicit_parameters(params, n, closed, name)
    else:
        u = _averaged_parameters(lines, method, closed)
    step = np.diff(np.append(u, 1.0) if closed else u)
    bad = np.flatnonzero(step <= _ZERO_STEP)
    if bad.size:
        k = int(bad[0])
        nxt = (k + 1) % u.size
        raise InputError(
            f"points: {what} {k} and {nxt} coincide (zero parameter step); "
            "remove repeated points or pass distinct data"
        )
    return u


def _averaged_parameters(lines: np.ndarray, method: str, closed: bool) -> np.ndarray:
    n = lines.shape[1]
    if method == "uniform":
        steps = np.ones((1, n if closed else n - 1))
    else:
        steps = chord_lengths(lines, axis=1, closed=closed)
        if method == "centripetal":
            steps = np.sqrt(steps)
    total = steps.sum(axis=1)
    scale = max(float(np.max(np.abs(lines))), 1.0) if lines.size else 1.0
    # a line of zero length (a pole) carries no parameter information: leave it out
    keep = total > _ZERO_STEP * scale
    if not np.any(keep):
        raise InputError("points: every line has zero length (all points coincide)")
    cum = np.cumsum(steps[keep], axis=1) / total[keep, None]
    params = np.concatenate([[0.0], cum.mean(axis=0)])
    params = params[:n]
    if not closed:
        params[-1] = 1.0
    return params


def _explicit_parameters(params, n: int, closed: bool, name: str) -> np.ndarray:
    u = as_array(params, name, shape=(n,))
    if closed:
        if u[0] != 0.0 or u[-1] >= 1.0:
            raise InputError(f"{name}: closed parameters must start at 0 and stay below 1")
    elif u[0] != 0.0 or u[-1] != 1.0:
        raise InputError(f"{name}: open parameters must run from 0 to 1")
    if np.any(np.diff(u) <= 0):
        raise InputError(f"{name}: must be strictly increasing")
    return u


def averaged_knots(params: np.ndarray, degree: int) -> np.ndarray:
    """Clamped knot vector by averaging parameters (The NURBS Book eq. 9.8).

    Parameters
    ----------
    params : (N,) array_like of float
        Strictly increasing parameters in ``[0, 1]``, ``params[0] = 0``, ``params[-1] = 1``.
    degree : int
        Degree ``p`` (2 to 5); needs ``N >= p + 1``.

    Returns
    -------
    numpy.ndarray
        ``(N + p + 1,)`` float64 knots: ``p + 1`` zeros, ``u_{j+p} = (1/p) sum_{i=j}^{j+p-1}
        params_i`` for ``j = 1 .. N - p - 1``, ``p + 1`` ones.
    """
    p = check_degree(degree)
    u = as_array(params, "params", ndim=1, min_size=p + 1)
    n = u.size - 1
    inner = np.convolve(u[1:n], np.ones(p) / p, mode="valid") if n > p else np.empty(0)
    return np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])


def periodic_knots(params: np.ndarray, degree: int) -> np.ndarray:
    """Knot vector of a periodic (closed) B-spline through ``N`` data parameters.

    Parameters
    ----------
    params : (N,) array_like of float
        Strictly increasing parameters in ``[0, 1)``, period 1, ``params[0] = 0``.
    degree : int
        Degree ``p`` (2 to 5); needs ``N >= p + 1``.

    Returns
    -------
    numpy.ndarray
        ``(N + 2p + 1,)`` float64 knots of the unwrapped spline with ``N + p``
        control points (the last ``p`` repeat the first ``p``). Period knots
        ``tau_k`` are the parameters (odd ``p``) or the midpoints
        ``(u_{k-1} + u_k) / 2`` (even ``p``); the domain is ``[tau_0, tau_0 + 1]``.
    """
    p = check_degree(degree)
    u = as_array(params, "params", ndim=1, min_size=p + 1)
    tau = u.copy() if p % 2 else 0.5 * (np.concatenate([[u[-1] - 1.0], u[:-1]]) + u)
    return np.concatenate([tau[u.size - p :] - 1.0, tau, tau[: p + 1] + 1.0])


def interpolation_knots(params: np.ndarray, degree: int, closed: bool) -> np.ndarray:
    """:func:`periodic_knots` for a closed direction, :func:`averaged_knots` for an open one.

    Parameters
    ----------
    params : (N,) float array
        Data parameters from :func:`data_parameters`.
    degree : int
        Degree ``p`` (2 to 5).
    closed : bool
        Periodic direction.

    Returns
    -------
    float64 array
        ``(N + 2p + 1,)`` periodic or ``(N + p + 1,)`` clamped knots.

    Examples
    --------
    >>> interpolation_knots(np.array([0.0, 0.25, 0.5, 1.0]), 2, False).tolist()
    [0.0, 0.0, 0.0, 0.375, 1.0, 1.0, 1.0]
    """
    return periodic_knots(params, degree) if closed else averaged_knots(params, degree)


def to_knot_domain(u: np.ndarray, knots: np.ndarray, degree: int) -> np.ndarray:
    """Map periodic parameters (period 1) into the knot domain ``[t_p, t_p + 1]``.

    Parameters
    ----------
    u : (M,) float array
        Parameters of a closed direction, any real value (period 1).
    knots : (K,) float array
        Unwrapped periodic knot vector (:func:`periodic_knots`).
    degree : int
        Degree ``p``.

    Returns
    -------
    (M,) float64

    Examples
    --------
    >>> to_knot_domain(np.array([0.0, 0.5, 1.25]), np.array([-0.25, 0.0, 0.25]), 1).tolist()
    [0.0, 0.5, 0.25]
    """
    start = knots[degree]
    return start + np.mod(u - start, 1.0)


def bezier_pieces(knots: np.ndarray, degree: int, control: np.ndarray) -> np.ndarray:
    """Bezier control points of every non-empty knot span in the domain.

    Piece ``s`` control point ``a`` is the blossom ``f(t_s^(p-a), t_{s+1}^a)``
    (equal to knot insertion up to multiplicity ``p``, The NURBS Book A5.6),
    computed by de Boor's recursion with one blossom argument per level,
    vectorised over spans, Bezier indices and trailing dimensions.

    Parameters
    ----------
    knots : (n + p + 1,) float array
        Full knot vector.
    degree : int
        Degree ``p``.
    control : (n, ...) float array
        Full (unwrapped) control points; trailing dimensions are carried along.

    Returns
    -------
    (S, p + 1, ...) float64
        One Bezier piece per non-empty span.

    Examples
    --------
    A clamped quadratic with one span is its own Bezier piece:

    >>> bezier_pieces(np.array([0.0, 0, 0, 1, 1, 1]), 2, np.array([[0.0], [1.0], [0.0]]))[0, :, 0].tolist()
    [0.0, 1.0, 0.0]
    """
    p = degree
    n = control.shape[0]
    spans = np.arange(p, n)
    spans = spans[knots[spans + 1] > knots[spans]]
    a = np.arange(p + 1)
    rest = control.shape[1:]
    # local control points d[s, a, i] = P_{s-p+i}, copied for every Bezier index a
    local = control[spans[:, None] + np.arange(-p, 1)[None, :]]  # (S, p+1, ...)
    d = np.broadcast_to(local[:, None], (spans.size, p + 1, p + 1, *rest)).copy()
    extra = (1,) * len(rest)
    for r in range(1, p + 1):
        # blossom argument of level r: t_{s+1} for the first a levels, t_s after
        x = np.where(r <= a[None, :], knots[spans + 1][:, None], knots[spans][:, None])
        for i in range(p, r - 1, -1):
            j = spans - p + i
            lo = knots[j][:, None]
            hi = knots[j + p + 1 - r][:, None]
            alpha = ((x - lo) / (hi - lo)).reshape(spans.size, p + 1, *extra)
            d[:, :, i] = (1.0 - alpha) * d[:, :, i - 1] + alpha * d[:, :, i]
    return d[:, :, p]


def _elevate_to_cubic(pieces: np.ndarray, axis: int) -> np.ndarray:
    """Exact degree elevation of quadratic Bezier pieces along ``axis`` (size 3 -> 4)."""
    b = np.moveaxis(pieces, axis, 0)
    out = np.stack([b[0], b[0] / 3.0 + 2.0 * b[1] / 3.0, 2.0 * b[1] / 3.0 + b[2] / 3.0, b[2]])
    return np.moveaxis(out, 0, axis)


def cubic_pieces(knots: np.ndarray, degree: int, control: np.ndarray) -> np.ndarray:
    """Cubic Bezier pieces of a degree 2 or 3 B-spline (degree 2 elevated exactly).

    Parameters
    ----------
    knots, degree, control
        As in :func:`bezier_pieces`.

    Returns
    -------
    (S, 4, ...) float64

    Raises
    ------
    ValueError
        For degrees 4 and 5, which no cubic represents.
    """
    if degree not in (2, 3):
        raise InputError(
            f"degree: conversion to bicubic Bezier patches is exact only for degree 2 "
            f"(elevated) or 3, got degree {degree}; interpolate with degree=3"
        )
    pieces = bezier_pieces(knots, degree, control)
    return _elevate_to_cubic(pieces, 1) if degree == 2 else pieces


def span_parameters(knots: np.ndarray, degree: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Piece index and local parameter in [0, 1] of knot-domain parameters ``x``.

    Parameters
    ----------
    knots : (K,) float array
        Full knot vector.
    degree : int
        Degree ``p``.
    x : (M,) float array
        Parameters in the knot domain ``[t_p, t_{n}]``.

    Returns
    -------
    index : (M,) int
        Non-empty span (Bezier piece of :func:`bezier_pieces`) of every parameter.
    local : (M,) float64
        Parameter inside the piece, in ``[0, 1]``.

    Examples
    --------
    >>> idx, t = span_parameters(np.array([0.0, 0, 0.5, 1, 1]), 1, np.array([0.25, 0.75]))
    >>> idx.tolist(), t.tolist()
    ([0, 1], [0.5, 0.5])
    """
    n = knots.size - degree - 1
    breaks = np.unique(knots[degree : n + 1])
    idx = np.clip(np.searchsorted(breaks, x, side="right") - 1, 0, breaks.size - 2)
    local = (x - breaks[idx]) / (breaks[idx + 1] - breaks[idx])
    return idx, np.clip(local, 0.0, 1.0)
