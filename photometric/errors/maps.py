"""Error maps over two light deviations and error curves against one (the paper's figures).

Deviations are slant/azimuth increments ``(d_slant, d_azimuth)`` in degrees
(:func:`photometric.lights.deviate_lights`); every map cell is evaluated with the exact
model of :mod:`photometric.errors.model`, in chunks so the temporaries stay small.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from photometric.errors.model import _apply, _exact, _first_order, _lit, _nominal, _pq
from photometric.lights import _deviate
from surfaces.validate import as_array, InputError, positive

__all__ = ["ErrorMap", "error_map", "error_curves"]

# float64 elements per chunk of the batched evaluations (~48 MB of temporaries)
_CHUNK = 2_000_000


@dataclass(frozen=True)
class ErrorMap:
    """Statistics of the exact derivative error over a grid of two deviations.

    Attributes
    ----------
    axis1, axis2 : tuple[int, str]
        ``(light index, "slant" | "azimuth")`` varied along axis 1 (columns) and
        axis 0 (rows) of the maps.
    dev1_deg, dev2_deg : numpy.ndarray
        ``(G1,)`` and ``(G2,)`` deviation values, degrees.
    max_dp, max_dq, mean_dp, mean_dq, max_angle_deg : numpy.ndarray
        ``(G2, G1)`` float64: max / mean of ``|dp|``, ``|dq|`` over the derivative set,
        and the maximum normal angle error (degrees).
    n_normals : int
        Number of normals the statistics are taken over.
    """

    axis1: tuple[int, str]
    axis2: tuple[int, str]
    dev1_deg: np.ndarray
    dev2_deg: np.ndarray
    max_dp: np.ndarray
    max_dq: np.ndarray
    mean_dp: np.ndarray
    mean_dq: np.ndarray
    max_angle_deg: np.ndarray
    n_normals: int


def _chunked_stats(M: np.ndarray, p: np.ndarray, q: np.ndarray) -> dict[str, np.ndarray]:
    """max/mean |dp|, |dq| and max angle over normals (K,) for matrices M (G, 3, 3)."""
    step = max(1, _CHUNK // max(1, 3 * p.size))
    out = {k: np.empty(M.shape[0]) for k in ("max_dp", "max_dq", "mean_dp", "mean_dq", "max_angle")}
    for start in range(0, M.shape[0], step):
        sl = slice(start, start + step)
        pe, qe, ang = _apply(M[sl], p, q, angles=True)
        adp, adq = np.abs(pe - p), np.abs(qe - q)
        out["max_dp"][sl] = adp.max(axis=1)
        out["max_dq"][sl] = adq.max(axis=1)
        out["mean_dp"][sl] = adp.mean(axis=1)
        out["mean_dq"][sl] = adq.mean(axis=1)
        out["max_angle"][sl] = ang.max(axis=1)
    return out


def _axis(spec, n_lights: int, name: str) -> tuple[int, str]:
    try:
        k, kind = int(spec[0]), str(spec[1])
    except (TypeError, ValueError, IndexError):
        raise InputError(f"{name}: expected (light index, 'slant' | 'azimuth'), got {spec!r}") from None
    if not 0 <= k < n_lights or kind not in ("slant", "azimuth"):
        raise InputError(f"{name}: expected light index in [0, {n_lights}) and 'slant' or 'azimuth', got {spec!r}")
    return k, kind


def error_map(
    lights,
    p,
    q,
    axis1=(0, "slant"),
    axis2=(1, "slant"),
    deviation_max: float = 5.0,
    n: int = 41,
    lit_only: bool = False,
) -> ErrorMap:
    """Exact derivative error over a grid of two light deviations (the paper's error maps).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    p, q : array_like
        The derivative set the statistics run over: a grid of the derivative square
        (:func:`photometric.errors.derivative_square`) or a surface's slopes
        (:func:`photometric.errors.surface_derivatives`).
    axis1, axis2 : (int, str)
        ``(light index, "slant" | "azimuth")`` of the two deviations; the same light may
        appear twice with different angles.
    deviation_max : float
        Deviations run over ``[-deviation_max, deviation_max]`` degrees.
    n : int
        Grid points per deviation axis (>= 2).
    lit_only : bool
        Only normals lit by every nominal light.

    Returns
    -------
    ErrorMap
    """
    L = _nominal(lights)
    a1 = _axis(axis1, L.shape[0], "axis1")
    a2 = _axis(axis2, L.shape[0], "axis2")
    if a1 == a2:
        raise InputError(f"axis1, axis2: must differ, both are {a1}")
    dmax = positive(deviation_max, "deviation_max")
    if int(n) < 2:
        raise InputError(f"n: need at least 2 grid points, got {n}")
    p, q = _pq(p, q)
    pf, qf = p.ravel(), q.ravel()
    if lit_only:
        keep = _lit(L, pf, qf)
        pf, qf = pf[keep], qf[keep]
    if pf.size == 0:
        raise InputError("p, q: no normals to evaluate (all shadowed?)")
    v = np.linspace(-dmax, dmax, int(n))
    d2, d1 = np.meshgrid(v, v, indexing="ij")
    dev = np.zeros((int(n), int(n), L.shape[0], 2))
    dev[:, :, a1[0], 0 if a1[1] == "slant" else 1] += d1
    dev[:, :, a2[0], 0 if a2[1] == "slant" else 1] += d2
    M = np.linalg.pinv(L) @ _deviate(L, dev).reshape(-1, L.shape[0], 3)
    st = _chunked_stats(M, pf, qf)
    shape = (int(n), int(n))
    return ErrorMap(
        axis1=a1,
        axis2=a2,
        dev1_deg=v,
        dev2_deg=v.copy(),
        max_dp=st["max_dp"].reshape(shape),
        max_dq=st["max_dq"].reshape(shape),
        mean_dp=st["mean_dp"].reshape(shape),
        mean_dq=st["mean_dq"].reshape(shape),
        max_angle_deg=st["max_angle"].reshape(shape),
        n_normals=int(pf.size),
    )


def error_curves(
    lights,
    slopes,
    light: int = 0,
    kind: str = "slant",
    deviation_max: float = 5.0,
    n: int = 81,
    slope_direction_deg: float = 0.0,
) -> dict[str, np.ndarray]:
    """Exact and first-order error against one light's deviation, for several slopes.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    slopes : array_like, shape (S,)
        Slope magnitudes; the normals have gradient ``slope * (cos t, sin t)`` with
        ``t = slope_direction_deg``.
    light : int
        Index of the deviated light.
    kind : {"slant", "azimuth"}
        Which angle of that light varies.
    deviation_max : float
        Deviations run over ``[-deviation_max, deviation_max]`` degrees.
    n : int
        Number of deviation values.
    slope_direction_deg : float
        Direction of the gradient in the image plane, degrees from x towards y.

    Returns
    -------
    dict
        ``deviation_deg`` (n,), ``slopes`` (S,), ``dp``, ``dq``, ``dp_first_order``,
        ``dq_first_order`` (n, S) float64.
    """
    L = _nominal(lights)
    k, kind = _axis((light, kind), L.shape[0], "light/kind")
    s = as_array(slopes, "slopes", ndim=1, min_size=1)
    v = np.linspace(-positive(deviation_max, "deviation_max"), deviation_max, int(n))
    t = math.radians(float(slope_direction_deg))
    p, q = s * math.cos(t), s * math.sin(t)
    dev = np.zeros((v.size, L.shape[0], 2))
    dev[:, k, 0 if kind == "slant" else 1] = v
    ex = _exact(L, _deviate(L, dev), p, q)
    fp, fq = _first_order(L, dev, p, q)
    return {
        "deviation_deg": v,
        "slopes": s,
        "dp": ex.dp,
        "dq": ex.dq,
        "dp_first_order": fp,
        "dq_first_order": fq,
    }
