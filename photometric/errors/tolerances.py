"""Operating limits: the worst-case error and its inversion into allowed deviations and ranges.

Every light in ``lights_moved`` deviates by the same angle ``delta``: by ``+-delta`` of
its slant or azimuth (all sign combinations), or turned by ``delta`` in any tangent
direction (:func:`photometric.lights.rotate_lights`). The worst ``max(|dp|, |dq|)`` over
the derivative square ``|p|, |q| <= D`` is inverted by Brent's method into the largest
deviation for a tolerance ``eps`` and the largest range ``D`` for a deviation; the
linearised limits come from the closed form of :mod:`photometric.errors.model`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from photometric.errors.maps import _chunked_stats
from photometric.errors.model import _gc, _nominal, _square
from photometric.lights import _basis, _deviate, _rotate
from surfaces.validate import InputError, positive

__all__ = ["MODES", "Tolerance", "worst_case_error", "max_deviation", "max_derivative_range", "recommendation_table"]

#: Deviation models of the tolerance functions.
MODES = ("any", "slant", "azimuth")


def _mode(mode: str) -> str:
    if mode not in MODES:
        raise InputError(f"mode: expected one of {MODES}, got {mode!r}")
    return mode


def _moved(which, n_lights: int) -> tuple[int, ...]:
    try:
        idx = tuple(sorted({int(i) for i in np.atleast_1d(which)}))
    except (TypeError, ValueError):
        raise InputError(f"lights_moved: expected light indices, got {which!r}") from None
    if not idx or idx[0] < 0 or idx[-1] >= n_lights:
        raise InputError(f"lights_moved: indices must lie in [0, {n_lights}), got {which!r}")
    return idx


def _candidate_lights(L, p, q, moved, mode, delta_deg, n_directions):
    """Deviated light sets to test: shared (G, N, 3) or per normal (K, C, N, 3)."""
    N = L.shape[0]
    if mode in ("slant", "azimuth"):
        col = 0 if mode == "slant" else 1
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(moved))))
        dev = np.zeros((signs.shape[0], N, 2))
        dev[:, list(moved), col] = signs * delta_deg
        return _deviate(L, dev), None
    # "any" direction: the first-order error of light k is (G c_k)(n . u_k) delta, maximal in
    # |dp| (or |dq|) when u_k is along the tangent part of n, signs aligned with (G c_k)_i.
    # Those directions (per normal, output and sign) are evaluated exactly; for one light a
    # ring of directions is added.
    e_s, e_a = _basis(L)
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)  # (K, 3)
    phi_n = np.degrees(np.arctan2(n @ e_a.T, n @ e_s.T))  # (K, N): direction towards n
    g = _gc(L, p, q)  # (K, 2, N)
    mv = list(moved)
    phis = []
    for comp in (0, 1):
        for sign in (-1.0, 1.0):
            flip = np.where(sign * g[:, comp, :] >= 0.0, 0.0, 180.0)  # (K, N)
            phis.append(phi_n + flip)
    phi = np.stack(phis, axis=1)  # (K, 4, N)
    angle = np.zeros(phi.shape)
    angle[:, :, mv] = delta_deg
    per_normal = _rotate(L, angle, phi)  # (K, 4, N, 3)
    shared = None
    if len(mv) == 1 and n_directions > 0:
        ring = np.linspace(0.0, 360.0, int(n_directions), endpoint=False)
        a = np.zeros((ring.size, N))
        a[:, mv[0]] = delta_deg
        d = np.zeros((ring.size, N))
        d[:, mv[0]] = ring
        shared = _rotate(L, a, d)
    return shared, per_normal


def _worst(L, Lp, p, q, moved, mode, delta_deg, n_directions) -> float:
    shared, per_normal = _candidate_lights(L, p, q, moved, mode, delta_deg, n_directions)
    worst = 0.0
    if shared is not None:
        st = _chunked_stats(Lp @ shared, p, q)
        worst = max(float(st["max_dp"].max()), float(st["max_dq"].max()))
    if per_normal is not None:
        M = Lp @ per_normal  # (K, C, 3, 3)
        n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
        m = np.einsum("kcij,kj->kci", M, n)
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = np.abs(-m[..., 0] / m[..., 2] - p[:, None])
            dq = np.abs(-m[..., 1] / m[..., 2] - q[:, None])
        worst = max(worst, float(dp.max()), float(dq.max()))
    return worst


def _first_order_slope(L, p, q, moved, mode) -> float:
    """Worst-case first-order error per radian of deviation (linear in delta)."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    e_s, e_a = _basis(L)
    if mode == "slant":
        w = np.abs(n @ e_s.T)
    elif mode == "azimuth":
        w = np.abs(n @ e_a.T) * np.sqrt(np.clip(1.0 - L[:, 2] ** 2, 0.0, None))[None, :]
    else:
        w = np.sqrt(np.clip(np.sum(n * n, axis=-1)[:, None] - (n @ L.T) ** 2, 0.0, None))
    g = np.abs(_gc(L, p, q))  # (K, 2, N)
    total = np.sum(g[:, :, list(moved)] * w[:, None, list(moved)], axis=-1)  # (K, 2)
    return float(total.max())


def worst_case_error(
    lights,
    deviation_deg: float,
    derivative_range: float,
    lights_moved=(0,),
    mode: str = "any",
    n_grid: int = 41,
    n_directions: int = 72,
    lit_only: bool = False,
) -> float:
    """Worst ``max(|dp|, |dq|)`` over the derivative square and the deviation directions.

    Every light in ``lights_moved`` deviates by the same angle ``deviation_deg``:
    ``mode="slant"``/``"azimuth"``: by ``+-deviation_deg`` of that angle (all sign
    combinations); ``mode="any"``: turned by ``deviation_deg`` in any tangent direction.
    For ``"any"`` the worst directions are the first-order optimal ones for each normal,
    output and sign (exact maximum up to O(delta^3)), evaluated with the exact model;
    for a single light a ring of ``n_directions`` directions is evaluated as well.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    deviation_deg : float
        Deviation angle, degrees (>= 0).
    derivative_range : float
        ``D``: the square ``|p|, |q| <= D`` (sampled ``n_grid x n_grid``, edges included).
    lights_moved : int or sequence of int
        Indices of the deviated lights.
    mode : {"any", "slant", "azimuth"}
        Deviation model.
    n_grid : int
        Grid points per axis of the derivative square.
    n_directions : int
        Directions of the extra ring (single light, ``"any"`` only; 0 to skip).
    lit_only : bool
        Only normals lit by every nominal light.

    Returns
    -------
    float
        Worst absolute derivative error (dimensionless).
    """
    L = _nominal(lights)
    mode = _mode(mode)
    moved = _moved(lights_moved, L.shape[0])
    delta = positive(deviation_deg, "deviation_deg", allow_zero=True)
    p, q = _square(L, derivative_range, n_grid, lit_only)
    return _worst(L, np.linalg.pinv(L), p, q, moved, mode, delta, int(n_directions))


@dataclass(frozen=True)
class Tolerance:
    """Result of a tolerance inversion.

    Attributes
    ----------
    value : float
        The limit: a deviation (degrees) or a derivative range ``D``.
    error : float
        Worst-case error at ``value`` (equals the tolerance unless ``saturated``).
    first_order : float
        The same limit from the linearised error (closed form).
    saturated : bool
        The error stays below the tolerance over the whole search interval; ``value``
        is its upper end (a lower bound of the true limit). For a derivative range,
        also True with ``value = 0`` when even a flat surface exceeds the tolerance.
    """

    value: float
    error: float
    first_order: float
    saturated: bool


def _brentq(f, lo: float, hi: float) -> float:
    return float(optimize.brentq(f, lo, hi, xtol=1e-13, rtol=4 * np.finfo(float).eps, maxiter=200))


def _max_deviation(L, eps, D, moved, mode, n_grid, n_directions, lit_only, upper) -> Tolerance:
    p, q = _square(L, D, n_grid, lit_only)
    Lp = np.linalg.pinv(L)
    slope = _first_order_slope(L, p, q, moved, mode)
    first = math.degrees(eps / slope) if slope > 0 else math.inf

    def f(delta: float) -> float:
        return _worst(L, Lp, p, q, moved, mode, delta, int(n_directions)) - eps

    hi = min(upper, 1.5 * first) if math.isfinite(first) else upper
    while f(hi) < 0.0:
        if hi >= upper:
            return Tolerance(upper, f(upper) + eps, first, True)
        hi = min(upper, 2.0 * hi)
    lo = 0.0
    if math.isfinite(first) and 0.5 * first < hi and f(0.5 * first) < 0.0:
        lo = 0.5 * first
    root = _brentq(f, lo, hi)
    return Tolerance(root, f(root) + eps, first, False)


def max_deviation(
    lights,
    tolerance: float,
    derivative_range: float,
    lights_moved=(0,),
    mode: str = "any",
    n_grid: int = 41,
    n_directions: int = 72,
    lit_only: bool = False,
    upper_deg: float = 30.0,
) -> Tolerance:
    """Largest deviation of the given lights keeping ``|dp|, |dq| <= eps`` over ``|p|, |q| <= D``.

    Solves ``worst_case_error(delta) = eps`` by Brent's method (bracketed by the
    first-order limit ``eps / (worst error per radian)``).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    tolerance : float
        ``eps``, the allowed absolute derivative error.
    derivative_range : float
        ``D``.
    lights_moved, mode, n_grid, n_directions, lit_only
        As in :func:`worst_case_error`.
    upper_deg : float
        Search limit, degrees.

    Returns
    -------
    Tolerance
        ``value`` in degrees.
    """
    L = _nominal(lights)
    mode = _mode(mode)
    eps = positive(tolerance, "tolerance")
    upper = positive(upper_deg, "upper_deg")
    moved = _moved(lights_moved, L.shape[0])
    return _max_deviation(L, eps, derivative_range, moved, mode, n_grid, n_directions, lit_only, upper)


def max_derivative_range(
    lights,
    tolerance: float,
    deviation_deg: float,
    lights_moved=(0,),
    mode: str = "any",
    n_grid: int = 41,
    n_directions: int = 72,
    lit_only: bool = False,
    upper: float = 10.0,
) -> Tolerance:
    """Largest derivative range ``D`` whose worst-case error stays within ``eps`` for a deviation.

    Solves ``worst_case_error(D) = eps`` by Brent's method over ``D`` in ``[0, upper]``.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    tolerance : float
        ``eps``.
    deviation_deg : float
        Deviation of each moved light, degrees.
    lights_moved, mode, n_grid, n_directions, lit_only
        As in :func:`worst_case_error`.
    upper : float
        Largest range searched.

    Returns
    -------
    Tolerance
        ``value`` is ``D``; ``first_order`` the linearised limit (bisection of the closed
        form); ``saturated`` when the limit is 0 or ``upper``.
    """
    L = _nominal(lights)
    mode = _mode(mode)
    eps = positive(tolerance, "tolerance")
    delta = positive(deviation_deg, "deviation_deg")
    hi = positive(upper, "upper")
    moved = _moved(lights_moved, L.shape[0])
    Lp = np.linalg.pinv(L)

    def f(D: float) -> float:
        p, q = _square(L, D, n_grid, lit_only)
        return _worst(L, Lp, p, q, moved, mode, delta, int(n_directions)) - eps

    def f_lin(D: float) -> float:
        p, q = _square(L, D, n_grid, lit_only)
        return math.radians(delta) * _first_order_slope(L, p, q, moved, mode) - eps

    first = _range_root(f_lin, hi, lambda lo, h: optimize.bisect(f_lin, lo, h, xtol=1e-10))
    f0, fhi = f(0.0), f(hi)
    if f0 >= 0.0:
        return Tolerance(0.0, f0 + eps, first, True)
    if fhi < 0.0:
        return Tolerance(hi, fhi + eps, first, True)
    root = _brentq(f, 0.0, hi)
    return Tolerance(root, f(root) + eps, first, False)


def _range_root(f, hi: float, solver) -> float:
    if f(0.0) >= 0.0:
        return 0.0
    if f(hi) < 0.0:
        return hi
    return float(solver(0.0, hi))


def recommendation_table(
    lights,
    tolerances=(0.01, 0.02, 0.05, 0.1),
    ranges=(0.5, 1.0, 2.0),
    n_grid: int = 21,
    lit_only: bool = False,
) -> list[dict]:
    """Operating limits of the angular deviations per derivative range and accuracy.

    For every ``(D, eps)``: the largest deviation (any direction) allowed for one light
    (the smallest over the lights), for each pair of lights deviating together (the
    smallest over the pairs) and for all lights at once; the paper's "operating limits
    of angular deviations and necessary ranges of derivative reconstruction".

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    tolerances : sequence of float
        Accuracies ``eps``.
    ranges : sequence of float
        Derivative ranges ``D``.
    n_grid : int
        Grid points per axis of each derivative square.
    lit_only : bool
        Only normals lit by every nominal light.

    Returns
    -------
    list of dict
        One row per ``(D, eps)``: ``derivative_range``, ``tolerance``,
        ``single_light_deg``, ``pair_deg``, ``all_lights_deg`` (degrees) and the
        matching ``*_first_order_deg``.
    """
    L = _nominal(lights)
    N = L.shape[0]
    groups = {
        "single_light": [(k,) for k in range(N)],
        "pair": list(itertools.combinations(range(N), 2)),
        "all_lights": [tuple(range(N))],
    }
    rows = []
    for D in ranges:
        for eps in tolerances:
            eps_ = positive(eps, "tolerances")
            row = {"derivative_range": float(D), "tolerance": float(eps)}
            for key, sets in groups.items():
                res = [_max_deviation(L, eps_, D, s, "any", n_grid, 0, lit_only, 30.0) for s in sets]
                row[f"{key}_deg"] = min(r.value for r in res)
                row[f"{key}_first_order_deg"] = min(r.first_order for r in res)
            rows.append(row)
    return rows
