"""Slope uncertainty: the noise covariance of ``(p, q)``, the noise estimate from the
residuals, and the slope fields of every light parameter (distant lights and LED
positions)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from photometric.uncertainty.budget import Tolerances
from photometric.uncertainty.heights import _bin
from surfaces.validate import as_array, InputError

#: Pixels per row block of the per-pixel maps (fits the CPU cache with its temporaries).
_BLOCK_PIXELS = 1 << 15


def estimate_noise_sigma(residual, valid, n_lights: int, intensities=None) -> float:
    """Image noise from the least-squares residuals of N >= 4 lights.

    ``E[sum_k r_k^2] = (N - 3) sigma_x^2`` for the intensity-divided observations, so
    ``sigma_x = sqrt(N / (N - 3) mean(residual^2))`` (the residual is the RMS over the N
    observations); it is converted to full-scale units with the RMS intensity.

    Parameters
    ----------
    residual : array_like, shape (H, W)
        RMS residual per pixel (:attr:`photometric.stereo.StereoResult.residual`).
    valid : array_like, shape (H, W), bool
        Pixels to use.
    n_lights : int
        Number of observations per pixel (>= 4).
    intensities : array_like, shape (N,) or (N, 3), optional
        Light intensities (ones by default).

    Returns
    -------
    float
        Noise standard deviation, full scale.
    """
    n = int(n_lights)
    if n < 4:
        raise InputError(f"n_lights: the noise can be estimated from the residuals with 4 or more lights, got {n}")
    r = as_array(residual, "residual", ndim=2)
    v = as_array(valid, "valid", shape=r.shape, dtype=bool)
    if not v.any():
        raise InputError("valid: no pixel to estimate the noise from")
    e = 1.0 if intensities is None else float(np.sqrt(np.mean(np.asarray(intensities, float) ** 2)))
    return float(np.sqrt(n / (n - 3) * np.mean(r[v].astype(np.float64) ** 2)) * e)


def _grey_intensities(intensities, n: int) -> np.ndarray:
    e = np.ones(n) if intensities is None else np.asarray(intensities, float)
    return e.mean(axis=1) if e.ndim == 2 else np.broadcast_to(e, (n,)).astype(float)


def slope_noise_covariance(lights, albedo, p, q, sigma: float, intensities=None, channels: int = 1):
    """Per-pixel covariance of ``(p, q)`` from image noise (closed form, vectorised).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Unit light directions.
    albedo : array_like, shape (H, W) or (H, W, 3)
        Albedo of the solve (intensity-divided units; RGB is averaged).
    p, q : array_like, shape (H, W)
        Slopes.
    sigma : float
        Image noise standard deviation (full scale).
    intensities : array_like, shape (N,) or (N, 3), optional
        Light intensities.
    channels : int
        Colour channels averaged to grey (independent noise: the grey noise is
        ``sigma / sqrt(channels)``).

    Returns
    -------
    var_p, var_q, cov_pq : numpy.ndarray, shape (H, W), float32
        ``sigma^2 (1 + p^2 + q^2) / rho^2 G A G^T`` with ``A = C diag(1 / E^2) C^T``;
        infinite where the albedo is zero.
    """
    L = as_array(lights, "lights", ndim=2)
    C = np.linalg.pinv(L)
    E = _grey_intensities(intensities, L.shape[0])
    A = (C / E**2) @ C.T
    pp = np.asarray(p, np.float32)
    qq = np.asarray(q, np.float32)
    rho = np.asarray(albedo, np.float32)
    if rho.ndim == 3:
        rho = rho.mean(axis=2)
    A = A.astype(np.float32)
    with np.errstate(divide="ignore"):
        s2 = np.float32(sigma**2 / channels) * (1.0 + pp * pp + qq * qq) / (rho * rho)
    var_p = s2 * (A[0, 0] + 2.0 * pp * A[0, 2] + pp * pp * A[2, 2])
    var_q = s2 * (A[1, 1] + 2.0 * qq * A[1, 2] + qq * qq * A[2, 2])
    cov = s2 * (A[0, 1] + pp * A[1, 2] + qq * A[0, 2] + pp * qq * A[2, 2])
    return var_p, var_q, cov


def _tangents(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per light (slant and azimuth directions; any pair at the pole)."""
    from photometric.lights import _basis

    return _basis(L)


def _far_parameters(L: np.ndarray, tol: Tolerances) -> list:
    """``(source, name, u, k, e)`` per systematic parameter of distant lights: light ``k`` moves
    by ``e`` per unit (a tangent for the direction, ``l_k`` itself for the intensity)."""
    e_s, e_a = _tangents(L)
    u_dir = math.radians(tol.light_tolerance_deg)
    out = []
    for k in range(L.shape[0]):
        if u_dir > 0:
            out += [("light_direction", f"light {k} slant", u_dir, k, e_s[k]),
                    ("light_direction", f"light {k} azimuth", u_dir, k, e_a[k])]
        if tol.intensity_tolerance > 0:
            out.append(("light_intensity", f"light {k} intensity", tol.intensity_tolerance, k, L[k]))
    return out


def _far_field(C: np.ndarray, k: int, e: np.ndarray, base: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(dp, dq) = G c_k (n . e)`` from the base fields ``1, p, q, p^2, pq, q^2`` (``base``):
    the fields are linear in them, so block means of the base fields give the block means
    of the fields exactly."""
    f = np.float32
    c0, c1, c2 = (f(v) for v in C[:, k])
    ex, ey, ez = (f(v) for v in e)
    one, p, q, pp, pq, qq = (base[key] for key in ("1", "p", "q", "pp", "pq", "qq"))
    # n . e = ez - p ex - q ey;  dp = -(c0 + c2 p)(n . e),  dq = -(c1 + c2 q)(n . e)
    dp = -(c0 * ez * one + (c2 * ez - c0 * ex) * p - c0 * ey * q - c2 * ex * pp - c2 * ey * pq)
    dq = -(c1 * ez * one - c1 * ex * p + (c2 * ez - c1 * ey) * q - c2 * ex * pq - c2 * ey * qq)
    return dp, dq


def _far_systematic(L: np.ndarray, tol: Tolerances, p: np.ndarray, q: np.ndarray, okf: np.ndarray, r: int):
    """``(source, u, dp, dq)`` of every distant-light parameter on blocks of ``r x r`` pixels."""
    params = _far_parameters(L, tol)
    if not params:
        return
    C = np.linalg.pinv(L)
    p0, q0 = p * okf, q * okf
    base = {"1": okf, "p": p0, "q": q0, "pp": p0 * p0, "pq": p0 * q0, "qq": q0 * q0}
    if r > 1:
        base = {key: _bin(v, r) for key, v in base.items()}
    for source, _name, u, k, e in params:
        dp, dq = _far_field(C, k, e, base)
        yield source, u, dp, dq


def slope_sensitivities(lights, p, q, tolerances: Tolerances):
    """The systematic light parameters and their slope fields (distant lights).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit light directions.
    p, q : array_like, shape (H, W)
        Slopes.
    tolerances : Tolerances
        ``light_tolerance_deg`` and ``intensity_tolerance`` select the parameters.

    Yields
    ------
    source : str
        ``"light_direction"`` or ``"light_intensity"``.
    name : str
        ``"light k slant"``, ``"light k azimuth"`` or ``"light k intensity"``.
    u : float
        Standard uncertainty of the parameter (rad or relative).
    dp, dq : numpy.ndarray, shape (H, W), float32
        Change of ``p``, ``q`` per unit of the parameter: ``G c_k (n . dl_k)`` with
        ``n = (-p, -q, 1)``, ``G = [[-1, 0, -p], [0, -1, -q]]`` and ``c_k`` column k of
        ``L^+`` (an intensity error ``delta`` acts as ``dl_k = delta l_k``).
    """
    L = as_array(lights, "lights", ndim=2)
    C = np.linalg.pinv(L)
    pp = np.asarray(p, np.float32)
    qq = np.asarray(q, np.float32)
    base = {"1": np.ones_like(pp), "p": pp, "q": qq, "pp": pp * pp, "pq": pp * qq, "qq": qq * qq}
    for source, name, u, k, e in _far_parameters(L, tolerances):
        dp, dq = _far_field(C, k, e, base)
        yield source, name, u, dp, dq


def slope_systematic_variance(lights, p, q, tolerances: Tolerances) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel variance of ``p`` and ``q`` from the light directions and intensities.

    Per light ``w_k = u_l^2 ((n . e_s)^2 + (n . e_a)^2) + u_E^2 (n . l_k)^2
    = u_l^2 (|n|^2 - (n . l_k)^2) + u_E^2 (n . l_k)^2`` and ``var = sum_k w_k (G c_k)^2``
    (:func:`slope_sensitivities`, summed in closed form).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    p, q : array_like, shape (H, W)
        Slopes.
    tolerances : Tolerances
        ``light_tolerance_deg``, ``intensity_tolerance``.

    Returns
    -------
    var_p, var_q : numpy.ndarray, shape (H, W), float32
    """
    L = as_array(lights, "lights", ndim=2)
    C = np.linalg.pinv(L).astype(np.float32)
    pp = np.asarray(p, np.float32)
    qq = np.asarray(q, np.float32)
    u_dir2 = np.float32(math.radians(tolerances.light_tolerance_deg) ** 2)
    u_int2 = np.float32(tolerances.intensity_tolerance**2)
    var_p = np.zeros(pp.shape, np.float32)
    var_q = np.zeros(pp.shape, np.float32)
    if u_dir2 == 0 and u_int2 == 0:
        return var_p, var_q
    # e_s, e_a and l_k are orthonormal: (n . e_s)^2 + (n . e_a)^2 = |n|^2 - (n . l_k)^2
    n2 = 1.0 + pp * pp + qq * qq
    for k in range(L.shape[0]):
        lx, ly, lz = (np.float32(v) for v in L[k])
        ndl = lz - pp * lx - qq * ly
        w = u_dir2 * n2 + (u_int2 - u_dir2) * ndl * ndl
        gp = C[0, k] + pp * C[2, k]
        gq = C[1, k] + qq * C[2, k]
        var_p += w * gp * gp
        var_q += w * gq * gq
    return var_p, var_q


@dataclass(frozen=True)
class PointLightModel:
    """The point-light (near-field) model of a solve, as the position Jacobian needs it.

    Attributes
    ----------
    lights : photometric.leds.PointLights
        Nominal LED positions, axes and lobe exponents.
    camera : photometric.camera.Orthographic or Perspective
        The camera (the flat field's reference-plane points).
    gains : numpy.ndarray or None, shape (N, H, W)
        Flat-field gains, or None.
    lobe : bool
        Whether the modelled LED lobe multiplies the strength.
    xy : numpy.ndarray, shape (H, W, 2)
        ``x, y`` (mm) of the point each pixel sees.
    plane_scale : numpy.ndarray, shape (N,)
        What divides each image plane before the solve (the intensities; ones with a flat
        field): the noise of a plane is ``sigma / plane_scale``.
    """

    lights: object
    camera: object
    gains: np.ndarray | None
    lobe: bool
    xy: np.ndarray
    plane_scale: np.ndarray


def _point_fields(model: PointLightModel, albedo, p, q, ok, z, sigma, tol, channels):
    """Slope fields of every LED coordinate (and intensity), ``p_u``, ``q_u`` and the mean
    noise variances, from the per-pixel light vectors ``s_k(X)`` at the solved points.

    ``m = M^-1 sum_k x_k s_k`` with ``M = sum_k s_k s_k^T``; a change ``ds_k`` of light
    ``k``'s vector moves the slopes by ``G c_k (n . ds_k)`` with ``c_k = M^-1 s_k``
    (the feedback of the changed heights on the light vectors is second order and left
    out); ``ds_k / dP_kj`` by central differences of the light model, whose strength
    follows the position as the model defines it (the intensity is stated at the origin,
    ``e d0^2``, or measured by the flat field on the reference plane,
    ``G |P - X0|^2``); noise: ``Cov(m) = sum_k w_k c_k c_k^T``,
    ``w_k = sigma^2 / (channels * plane_scale_k^2)``.
    """
    from dataclasses import replace

    from photometric.leds import _scaled_vectors
    from photometric.nearfield import _strengths

    lights = model.lights
    shape = p.shape
    ones = np.ones((len(lights), 3))

    def strength(k, position):
        # light k alone, moved by a small step (nothing new to check): its strength map, not every light's
        one = replace(lights.subset([k]), positions=np.asarray(position, float)[None])
        gains = None if model.gains is None else model.gains[k:k + 1]
        return _strengths(one, model.camera, shape, gains, ones[k:k + 1])[0]
    n = len(lights)
    x = model.xy[..., 0].astype(np.float64)
    y = model.xy[..., 1].astype(np.float64)
    zz = np.where(ok & np.isfinite(z), z, np.median(z[ok & np.isfinite(z)]) if ok.any() else 0.0)
    pp = p.astype(np.float64)
    qq = q.astype(np.float64)

    def vectors(k, position):
        return np.stack(_scaled_vectors(position, lights.axes[k], float(lights.mu[k]), strength(k, position), x, y,
                                        zz, lobe=model.lobe))

    S = [vectors(k, lights.positions[k]) for k in range(n)]
    M = sum(np.einsum("ihw,jhw->ijhw", s, s) for s in S)
    Minv = np.linalg.inv(np.where(ok[..., None, None], M.transpose(2, 3, 0, 1), np.eye(3))).transpose(2, 3, 0, 1)
    C = [np.einsum("ijhw,jhw->ihw", Minv, s) for s in S]
    rho = np.asarray(albedo, np.float64)
    if rho.ndim == 3:
        rho = rho.mean(axis=2)
    n2 = 1.0 + pp * pp + qq * qq
    scale = np.asarray(model.plane_scale, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        noise = np.where(ok, sigma**2 / channels * n2 / (rho * rho), 0.0)
    var_p = np.zeros(p.shape)
    var_q = np.zeros(p.shape)
    sys_p = np.zeros(p.shape)
    sys_q = np.zeros(p.shape)
    fields = []
    step = 1e-3
    for k in range(n):
        gp = -(C[k][0] + pp * C[k][2])
        gq = -(C[k][1] + qq * C[k][2])
        var_p += noise / scale[k] ** 2 * gp * gp
        var_q += noise / scale[k] ** 2 * gq * gq
        moves = []
        if tol.light_position_tolerance_mm > 0:
            for j, axis in enumerate("xyz"):
                e = np.zeros(3)
                e[j] = step
                ds = (vectors(k, lights.positions[k] + e) - vectors(k, lights.positions[k] - e)) / (2 * step)
                moves.append(("light_position", f"light {k} {axis}", tol.light_position_tolerance_mm, ds))
        if tol.intensity_tolerance > 0:
            moves.append(("light_intensity", f"light {k} intensity", tol.intensity_tolerance, S[k]))
        for source, name, u, ds in moves:
            ndl = ds[2] - pp * ds[0] - qq * ds[1]
            dp = np.where(ok, gp * ndl, 0.0).astype(np.float32)
            dq = np.where(ok, gq * ndl, 0.0).astype(np.float32)
            sys_p += (u * dp) ** 2
            sys_q += (u * dq) ** 2
            fields.append((source, name, u, dp, dq))
    count = max(int(np.count_nonzero(ok)), 1)
    p_u = np.where(ok, np.sqrt(var_p + sys_p), 0.0).astype(np.float32)
    q_u = np.where(ok, np.sqrt(var_q + sys_q), 0.0).astype(np.float32)
    return fields, p_u, q_u, float(var_p.sum() / count), float(var_q.sum() / count)


def _slope_maps(L, E, albedo, p, q, ok, sigma, tol, channels):
    """``p_u``, ``q_u`` (noise and light parameters) and the mean noise variances of ``p``
    and ``q`` over ``ok``; row blocks that stay in the CPU cache."""
    p_u = np.zeros(p.shape, np.float32)
    q_u = np.zeros(p.shape, np.float32)
    sums = np.zeros(2)
    rows = max(1, _BLOCK_PIXELS // p.shape[1])
    for r0 in range(0, p.shape[0], rows):
        sl = slice(r0, r0 + rows)
        vp, vq, _ = slope_noise_covariance(L, albedo[sl], p[sl], q[sl], sigma, E, channels)
        m = ok[sl]
        sums += (vp.sum(where=m, dtype=np.float64), vq.sum(where=m, dtype=np.float64))
        sp, sq = slope_systematic_variance(L, p[sl], q[sl], tol)
        np.sqrt(vp + sp, out=p_u[sl])
        np.sqrt(vq + sq, out=q_u[sl])
    p_u[~ok] = 0.0
    q_u[~ok] = 0.0
    count = max(int(np.count_nonzero(ok)), 1)
    return p_u, q_u, float(sums[0] / count), float(sums[1] / count)
