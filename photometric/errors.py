"""Accuracy of photometric stereo against deviated light directions (seed 002(a)).

Seed 002(a) reconstructs a surface from a triad of images under three known
light directions (Lambertian model ``I_k = rho * (l_k . n)``, so
``rho n = L^-1 I``) and asks how much the reconstructed derivatives ``p``, ``q``
suffer when the real light directions deviate from the nominal ones, and
which deviations keep the error below a tolerance over a range of derivatives.

The model used everywhere in this module: the true lights ``L'`` (rows are
unit light vectors) make the images, the nominal lights ``L`` reconstruct them,
so the reconstructed (albedo-scaled) normal is ``m = L^+ L' n`` (``L^+`` the
pseudo-inverse; ``L^-1`` for a triad) and

    p_est = -m_x / m_z,   q_est = -m_y / m_z.

Because ``p`` and ``q`` do not depend on the length of ``m``, the albedo drops
out and the unnormalised normal ``n = (-p, -q, 1)`` is used directly. The
model is the linear (unclipped) Lambertian one: a normal that faces away from
a light (attached shadow) is still evaluated algebraically; ``lit_only``
restricts the statistics to normals lit by every light.

Frame (DiLiGenT): x to the right (image columns), y up (image rows reversed),
z towards the camera. A light with slant ``s`` (angle from the z axis) and
azimuth ``a`` (angle from the x axis towards y) is
``l = (sin s cos a, sin s sin a, cos s)``.

Deviation models
----------------
* slant/azimuth increments ``(d_slant, d_azimuth)`` in degrees
  (:func:`deviate_lights`), the parametrisation of the paper's error maps;
* a rotation of each light by an angle ``delta`` towards a direction ``phi``
  in its tangent plane (:func:`rotate_lights`): ``phi = 0`` is increasing
  slant, ``phi = 90`` increasing azimuth; ``delta`` is the true angle between
  nominal and deviated light. The Monte Carlo study gives each light an
  isotropic Gaussian tangent deviation (components along ``e_s`` and ``e_a``
  independent ``N(0, sigma^2 / 2)``): a uniformly random direction and an angle
  whose RMS (and signed standard deviation) is ``sigma``.

First order (derived for this module)
-------------------------------------
With ``c_k`` the k-th column of ``L^+`` and a light perturbation ``dl_k``,
``dm = sum_k c_k (n . dl_k)``; at ``m = n = (-p, -q, 1)``,
``dp = -(dm_x + p dm_z)``, ``dq = -(dm_y + q dm_z)``. With
``dl_k/ds = e_s = (cos s cos a, cos s sin a, -sin s)`` and
``dl_k/da = sin s e_a``, ``e_a = (-sin a, cos a, 0)``, this is the closed-form
Jacobian of :func:`sensitivity`; for random isotropic tangent deviations
``Cov(dp, dq) = J Sigma J^T`` (:func:`first_order_covariance`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from photometric.lights import condition_number  # noqa: F401  (part of this module's API)
from surfaces.validate import as_array, positive

OPTIMAL_SLANT_DEG: float = math.degrees(math.atan(math.sqrt(2.0)))
"""Slant (deg) at which three lights 120 deg apart are best conditioned: tan(s) = sqrt(2)."""

_UNIT_TOLERANCE = 1e-2
_MODES = ("any", "slant", "azimuth")
# float64 elements per chunk of the batched evaluations (~48 MB of temporaries)
_CHUNK = 2_000_000


# ----------------------------------------------------------------------------- lights


def _unit_lights(lights, name: str, *, nominal: bool = False) -> np.ndarray:
    """Validate light directions (..., N, 3) and renormalise them to unit length."""
    L = as_array(lights, name)
    if L.ndim < 2 or L.shape[-1] != 3:
        raise ValueError(f"{name}: expected shape (..., N, 3), got {L.shape}")
    norms = np.linalg.norm(L, axis=-1)
    if np.any(np.abs(norms - 1.0) > _UNIT_TOLERANCE):
        worst = float(np.max(np.abs(norms - 1.0)))
        raise ValueError(f"{name}: light directions must be unit vectors (|norm - 1| up to {worst:.3g})")
    L = L / norms[..., None]
    if nominal:
        if L.ndim != 2 or L.shape[0] < 3:
            raise ValueError(f"{name}: expected at least 3 nominal lights as (N, 3), got {L.shape}")
        sv = np.linalg.svd(L, compute_uv=False)
        if sv[-1] < 1e-6 * sv[0]:
            raise ValueError(f"{name}: light directions are coplanar (singular values {sv})")
    return L


def lights_from_angles(slant_deg, azimuth_deg) -> np.ndarray:
    """Unit light directions from slant and azimuth angles.

    ``l = (sin s cos a, sin s sin a, cos s)`` in the DiLiGenT frame (x right, y up,
    z towards the camera).

    Parameters
    ----------
    slant_deg, azimuth_deg : array_like
        Slant (angle from the z axis) and azimuth (from x towards y), degrees;
        broadcast against each other.

    Returns
    -------
    numpy.ndarray
        ``(..., 3)`` float64 unit vectors.
    """
    s = np.radians(as_array(slant_deg, "slant_deg"))
    a = np.radians(as_array(azimuth_deg, "azimuth_deg"))
    s, a = np.broadcast_arrays(s, a)
    return np.stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.cos(s)], axis=-1)


def light_angles(lights) -> tuple[np.ndarray, np.ndarray]:
    """Slant and azimuth of unit light directions (inverse of :func:`lights_from_angles`).

    Parameters
    ----------
    lights : array_like, (..., N, 3)
        Unit light directions.

    Returns
    -------
    slant_deg, azimuth_deg : numpy.ndarray
        ``(..., N)`` float64 degrees; the azimuth of a light on the z axis is 0.
    """
    L = _unit_lights(lights, "lights")
    slant = np.degrees(np.arccos(np.clip(L[..., 2], -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(L[..., 1], L[..., 0]))
    return slant, azimuth


def standard_triad(slant_deg: float = 45.0, azimuth0_deg: float = 90.0, n: int = 3) -> np.ndarray:
    """``n`` lights at one slant, equally spaced in azimuth (the standard triad for n = 3).

    Parameters
    ----------
    slant_deg : float
        Common slant, degrees.
    azimuth0_deg : float
        Azimuth of the first light, degrees (90 = straight up the image).
    n : int
        Number of lights (>= 3).

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` float64 unit light directions.
    """
    if int(n) < 3:
        raise ValueError(f"n: need at least 3 lights, got {n}")
    az = float(azimuth0_deg) + 360.0 * np.arange(int(n)) / int(n)
    return lights_from_angles(np.full(int(n), float(slant_deg)), az)


def tangent_basis(lights) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangent vectors of the light directions along slant and azimuth.

    ``e_s = dl/ds = (cos s cos a, cos s sin a, -sin s)`` and
    ``e_a = (-sin a, cos a, 0)`` (``dl/da = sin s e_a``).

    Parameters
    ----------
    lights : array_like, (..., N, 3)
        Unit light directions.

    Returns
    -------
    e_slant, e_azimuth : numpy.ndarray
        ``(..., N, 3)`` float64; together with ``l`` an orthonormal basis.
    """
    s, a = light_angles(lights)
    s, a = np.radians(s), np.radians(a)
    e_s = np.stack([np.cos(s) * np.cos(a), np.cos(s) * np.sin(a), -np.sin(s)], axis=-1)
    e_a = np.stack([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)
    return e_s, e_a


def deviate_lights(lights, deviations_deg) -> np.ndarray:
    """Deviate each light by increments of its slant and azimuth.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit light directions.
    deviations_deg : array_like, (..., N, 2)
        ``[d_slant, d_azimuth]`` per light, degrees; leading dimensions give a batch.

    Returns
    -------
    numpy.ndarray
        ``(..., N, 3)`` float64 deviated unit lights,
        ``l(s + d_slant, a + d_azimuth)``.
    """
    L = _unit_lights(lights, "lights")
    if L.ndim != 2:
        raise ValueError(f"lights: expected shape (N, 3), got {L.shape}")
    d = as_array(deviations_deg, "deviations_deg")
    if d.ndim < 2 or d.shape[-2:] != (L.shape[0], 2):
        raise ValueError(f"deviations_deg: expected shape (..., {L.shape[0]}, 2), got {d.shape}")
    s, a = light_angles(L)
    return lights_from_angles(s + d[..., 0], a + d[..., 1])


def rotate_lights(lights, angle_deg, direction_deg) -> np.ndarray:
    """Turn each light by an angle towards a direction in its tangent plane.

    ``l' = cos(delta) l + sin(delta) (cos(phi) e_s + sin(phi) e_a)``: a rotation
    about the axis ``l x u`` perpendicular to the light, so ``angle(l, l') = |delta|``.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit light directions.
    angle_deg : array_like, broadcastable to (..., N)
        Rotation angle ``delta`` per light, degrees.
    direction_deg : array_like, broadcastable to (..., N)
        Direction ``phi`` of the motion, degrees: 0 = increasing slant,
        90 = increasing azimuth.

    Returns
    -------
    numpy.ndarray
        ``(..., N, 3)`` float64 unit light directions.
    """
    L = _unit_lights(lights, "lights")
    if L.ndim != 2:
        raise ValueError(f"lights: expected shape (N, 3), got {L.shape}")
    delta = np.radians(as_array(angle_deg, "angle_deg"))
    phi = np.radians(as_array(direction_deg, "direction_deg"))
    delta, phi = np.broadcast_arrays(delta, phi)
    if delta.ndim == 0 or delta.shape[-1] not in (1, L.shape[0]):
        raise ValueError(f"angle_deg/direction_deg: last axis must have {L.shape[0]} entries")
    e_s, e_a = tangent_basis(L)
    u = np.cos(phi)[..., None] * e_s + np.sin(phi)[..., None] * e_a
    return np.cos(delta)[..., None] * L + np.sin(delta)[..., None] * u


def rotation_matrix(axis, angle_deg: float) -> np.ndarray:
    """Rotation matrix about an axis (Rodrigues' formula).

    Parameters
    ----------
    axis : array_like, (3,)
        Rotation axis (any non-zero length).
    angle_deg : float
        Right-handed rotation angle, degrees.

    Returns
    -------
    numpy.ndarray
        ``(3, 3)`` float64 orthogonal matrix.
    """
    k = as_array(axis, "axis", shape=(3,))
    norm = np.linalg.norm(k)
    if norm == 0:
        raise ValueError("axis: must be a non-zero vector")
    k = k / norm
    t = math.radians(float(angle_deg))
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(t) * K + (1.0 - math.cos(t)) * (K @ K)


# ----------------------------------------------------------------------------- derivatives


def derivative_square(derivative_range: float, n: int = 41) -> tuple[np.ndarray, np.ndarray]:
    """A regular grid over the derivative square ``|p|, |q| <= D``.

    Parameters
    ----------
    derivative_range : float
        ``D`` (dimensionless slope, dz/dx).
    n : int
        Grid points per axis (>= 2); edges and corners are included.

    Returns
    -------
    p, q : numpy.ndarray
        ``(n, n)`` float64; ``p`` varies along axis 1, ``q`` along axis 0.
    """
    D = positive(derivative_range, "derivative_range", allow_zero=True)
    if int(n) < 2:
        raise ValueError(f"n: need at least 2 grid points, got {n}")
    v = np.linspace(-D, D, int(n))
    p, q = np.meshgrid(v, v)
    return p, q


def surface_derivatives(height, pixel_size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives ``p = dz/dx``, ``q = dz/dy`` of a height field in the DiLiGenT frame.

    x runs along the columns; y runs up, i.e. along the rows reversed, so
    ``q = -dz/d(row)``. Central differences inside, one-sided at the edges.

    Parameters
    ----------
    height : array_like, (H, W)
        Height, same length unit as ``pixel_size`` (mm).
    pixel_size : float
        Pixel pitch (mm).

    Returns
    -------
    p, q : numpy.ndarray
        ``(H, W)`` float64 slopes.
    """
    h = as_array(height, "height", ndim=2)
    if min(h.shape) < 2:
        raise ValueError(f"height: needs at least 2 x 2 pixels, got {h.shape}")
    ps = positive(pixel_size, "pixel_size")
    p = np.gradient(h, ps, axis=1)
    q = -np.gradient(h, ps, axis=0)
    return p, q


def normals_from_derivatives(p, q) -> np.ndarray:
    """Unit normals ``n = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``.

    Parameters
    ----------
    p, q : array_like
        Slopes of one shape ``S``.

    Returns
    -------
    numpy.ndarray
        ``S + (3,)`` float64 unit normals.
    """
    p, q = _pq(p, q)
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _pq(p, q) -> tuple[np.ndarray, np.ndarray]:
    p = as_array(p, "p")
    q = as_array(q, "q")
    if p.shape != q.shape:
        raise ValueError(f"p, q: shapes differ ({p.shape} vs {q.shape})")
    return p, q


# ----------------------------------------------------------------------------- exact error


@dataclass(frozen=True)
class DerivativeError:
    """Exact error of the reconstruction with nominal lights.

    Attributes
    ----------
    dp, dq : numpy.ndarray
        ``p_est - p`` and ``q_est - q``, shape ``B + S`` (batch of light sets, then
        the shape of ``p``), float64, dimensionless.
    angle_deg : numpy.ndarray
        Angle between true and reconstructed normal, degrees, same shape.
    p_est, q_est : numpy.ndarray
        Reconstructed slopes, same shape.
    """

    dp: np.ndarray
    dq: np.ndarray
    angle_deg: np.ndarray
    p_est: np.ndarray
    q_est: np.ndarray


def reconstruction_matrix(lights_nominal, lights_true) -> np.ndarray:
    """``M = L^+ L'``: maps the true normal to the reconstructed albedo-normal.

    Parameters
    ----------
    lights_nominal : array_like, (N, 3)
        Lights used for the reconstruction (``L``), N >= 3, not coplanar.
    lights_true : array_like, (..., N, 3)
        Lights that made the images (``L'``); leading dimensions give a batch.

    Returns
    -------
    numpy.ndarray
        ``(..., 3, 3)`` float64.
    """
    L = _unit_lights(lights_nominal, "lights_nominal", nominal=True)
    Lt = _unit_lights(lights_true, "lights_true")
    if Lt.shape[-2] != L.shape[0]:
        raise ValueError(f"lights_true: expected {L.shape[0]} lights, got shape {Lt.shape}")
    return np.linalg.pinv(L) @ Lt


def _apply(M: np.ndarray, p: np.ndarray, q: np.ndarray, *, angles: bool = False):
    """Reconstructed slopes for matrices M (G, 3, 3) and slopes p, q (K,) -> (G, K) arrays."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=0)  # (3, K)
    m = M @ n  # (G, 3, K)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_est = -m[:, 0] / m[:, 2]
        q_est = -m[:, 1] / m[:, 2]
    if not angles:
        return p_est, q_est, None
    cross = np.cross(n.T[None], np.moveaxis(m, 1, 2))
    dot = np.einsum("ik,gik->gk", n, m)
    return p_est, q_est, np.degrees(np.arctan2(np.linalg.norm(cross, axis=-1), dot))


def exact_error(lights_nominal, lights_true, p, q) -> DerivativeError:
    """Exact derivative and normal errors when ``L'`` makes the images and ``L`` reconstructs.

    ``m = L^+ L' n``, ``p_est = -m_x / m_z``, ``q_est = -m_y / m_z`` (seed 002(a):
    ``rho n = L^-1 I`` with ``I = rho L' n``).

    Parameters
    ----------
    lights_nominal : array_like, (N, 3)
        Nominal unit lights ``L``.
    lights_true : array_like, (..., N, 3)
        True unit lights ``L'``; a leading batch shape ``B`` is allowed.
    p, q : array_like
        True slopes, any common shape ``S``.

    Returns
    -------
    DerivativeError
        Arrays of shape ``B + S``.
    """
    p, q = _pq(p, q)
    M = reconstruction_matrix(lights_nominal, lights_true)
    batch = M.shape[:-2]
    Mf = M.reshape(-1, 3, 3)
    pe, qe, ang = _apply(Mf, p.ravel(), q.ravel(), angles=True)
    shape = batch + p.shape
    return DerivativeError(
        dp=(pe - p.ravel()).reshape(shape),
        dq=(qe - q.ravel()).reshape(shape),
        angle_deg=ang.reshape(shape),
        p_est=pe.reshape(shape),
        q_est=qe.reshape(shape),
    )


# ----------------------------------------------------------------------------- first order


def _gc(L: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``G c_k``: first-order (dp, dq) per unit of ``n . dl_k``; (K, 2, N) for p, q (K,)."""
    C = np.linalg.pinv(L)  # (3, N), column k is c_k
    gp = -(C[0][None, :] + p[:, None] * C[2][None, :])
    gq = -(C[1][None, :] + q[:, None] * C[2][None, :])
    return np.stack([gp, gq], axis=1)


def sensitivity(lights, p, q) -> np.ndarray:
    """Closed-form Jacobian of ``(p, q)`` w.r.t. each light's slant and azimuth.

    ``d(p, q)/d(theta_k) = G(p, q) c_k (n . dl_k/d theta_k)`` with ``n = (-p, -q, 1)``,
    ``G = [[-1, 0, -p], [0, -1, -q]]``, ``c_k`` column k of ``L^+``,
    ``dl/ds = e_s``, ``dl/da = sin(s) e_a`` (derivation in the module docstring).

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray
        ``S + (2, N, 2)`` float64, per radian: ``J[..., i, k, j]`` is the derivative
        of output ``i`` (0 = p, 1 = q) w.r.t. angle ``j`` (0 = slant, 1 = azimuth)
        of light ``k``.
    """
    L = _unit_lights(lights, "lights", nominal=True)
    p, q = _pq(p, q)
    pf, qf = p.ravel(), q.ravel()
    n = np.stack([-pf, -qf, np.ones_like(pf)], axis=-1)  # (K, 3)
    e_s, e_a = tangent_basis(L)
    sin_s = np.sqrt(np.clip(1.0 - L[:, 2] ** 2, 0.0, None))
    ns = n @ e_s.T  # (K, N)
    na = (n @ e_a.T) * sin_s[None, :]
    J = _gc(L, pf, qf)[..., None] * np.stack([ns, na], axis=-1)[:, None, :, :]
    return J.reshape(p.shape + (2, L.shape[0], 2))


def first_order_error(lights, deviations_deg, p, q) -> tuple[np.ndarray, np.ndarray]:
    """First-order prediction of ``(dp, dq)`` for slant/azimuth deviations.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    deviations_deg : array_like, (..., N, 2)
        ``[d_slant, d_azimuth]`` per light, degrees (batch shape ``B``).
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    dp, dq : numpy.ndarray
        ``B + S`` float64, ``J . radians(deviations)``.
    """
    J = sensitivity(lights, p, q)
    shape_s = J.shape[:-3]
    N = J.shape[-2]
    d = as_array(deviations_deg, "deviations_deg")
    if d.ndim < 2 or d.shape[-2:] != (N, 2):
        raise ValueError(f"deviations_deg: expected shape (..., {N}, 2), got {d.shape}")
    Jf = J.reshape(-1, 2, N * 2)
    out = np.einsum("kiz,...z->...ki", Jf, np.radians(d).reshape(d.shape[:-2] + (N * 2,)))
    shape = d.shape[:-2] + shape_s
    return out[..., 0].reshape(shape), out[..., 1].reshape(shape)


def first_order_covariance(lights, sigma_deg: float, p, q) -> np.ndarray:
    """First-order covariance of ``(dp, dq)`` for random isotropic light deviations.

    Each light's tangent displacement is isotropic Gaussian with covariance
    ``(sigma^2 / 2) I_2`` (RMS angle ``sigma``, :func:`random_deviations`), so
    ``E[(n . dl_k)^2] = (sigma^2 / 2)(|n|^2 - (n . l_k)^2)``;
    ``Cov = sum_k (G c_k)(G c_k)^T (sigma^2 / 2)(|n|^2 - (n . l_k)^2)`` (= ``J Sigma J^T``).

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees (model of :func:`random_deviations`).
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray
        ``S + (2, 2)`` float64 covariance (dimensionless slope units squared).
    """
    L = _unit_lights(lights, "lights", nominal=True)
    sigma = math.radians(positive(sigma_deg, "sigma_deg", allow_zero=True))
    p, q = _pq(p, q)
    pf, qf = p.ravel(), q.ravel()
    n = np.stack([-pf, -qf, np.ones_like(pf)], axis=-1)
    w = 0.5 * sigma**2 * (np.sum(n * n, axis=-1)[:, None] - (n @ L.T) ** 2)  # (K, N)
    g = _gc(L, pf, qf)  # (K, 2, N)
    cov = np.einsum("kin,kjn,kn->kij", g, g, w)
    return cov.reshape(p.shape + (2, 2))


def first_order_angle_rms(lights, sigma_deg: float, p, q) -> np.ndarray:
    """First-order RMS angle between true and reconstructed normal (random deviations).

    ``dn = (I - n n^T) dm / |n|`` with ``dm = sum_k c_k (n . dl_k)``; the RMS angle is
    ``sqrt(trace Cov(dn))`` under the model of :func:`first_order_covariance`.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees (model of :func:`random_deviations`).
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray
        ``S`` float64, degrees.
    """
    L = _unit_lights(lights, "lights", nominal=True)
    sigma = math.radians(positive(sigma_deg, "sigma_deg", allow_zero=True))
    p, q = _pq(p, q)
    nh = normals_from_derivatives(p, q).reshape(-1, 3)
    C = np.linalg.pinv(L)  # (3, N)
    # with the unit normal, |n|^2 = 1 and no 1/|n| factor
    w = 0.5 * sigma**2 * (1.0 - (nh @ L.T) ** 2)  # (K, N)
    proj_c = C.T[None, :, :] - (nh @ C)[:, :, None] * nh[:, None, :]  # (K, N, 3)
    var = np.einsum("knj,knj,kn->k", proj_c, proj_c, w)
    return np.degrees(np.sqrt(var)).reshape(p.shape)


# ----------------------------------------------------------------------------- error maps


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


def _lit(L: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Normals lit by every light (n . l_k > 0 for all k); (K,) bool."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    return np.all(n @ L.T > 0.0, axis=-1)


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
        raise ValueError(f"{name}: expected (light index, 'slant' | 'azimuth'), got {spec!r}") from None
    if not 0 <= k < n_lights or kind not in ("slant", "azimuth"):
        raise ValueError(f"{name}: expected light index in [0, {n_lights}) and 'slant' or 'azimuth', got {spec!r}")
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
    lights : array_like, (N, 3)
        Nominal unit lights.
    p, q : array_like
        The derivative set the statistics run over: a grid of the derivative square
        (:func:`derivative_square`) or a surface's slopes (:func:`surface_derivatives`).
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
    L = _unit_lights(lights, "lights", nominal=True)
    a1 = _axis(axis1, L.shape[0], "axis1")
    a2 = _axis(axis2, L.shape[0], "axis2")
    if a1 == a2:
        raise ValueError(f"axis1, axis2: must differ, both are {a1}")
    dmax = positive(deviation_max, "deviation_max")
    if int(n) < 2:
        raise ValueError(f"n: need at least 2 grid points, got {n}")
    p, q = _pq(p, q)
    pf, qf = p.ravel(), q.ravel()
    if lit_only:
        keep = _lit(L, pf, qf)
        pf, qf = pf[keep], qf[keep]
    if pf.size == 0:
        raise ValueError("p, q: no normals to evaluate (all shadowed?)")
    v = np.linspace(-dmax, dmax, int(n))
    d2, d1 = np.meshgrid(v, v, indexing="ij")
    dev = np.zeros((int(n), int(n), L.shape[0], 2))
    dev[:, :, a1[0], 0 if a1[1] == "slant" else 1] += d1
    dev[:, :, a2[0], 0 if a2[1] == "slant" else 1] += d2
    M = np.linalg.pinv(L) @ deviate_lights(L, dev).reshape(-1, L.shape[0], 3)
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
    lights : array_like, (N, 3)
        Nominal unit lights.
    slopes : array_like, (S,)
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
    L = _unit_lights(lights, "lights", nominal=True)
    k, kind = _axis((light, kind), L.shape[0], "light/kind")
    s = as_array(slopes, "slopes", ndim=1, min_size=1)
    v = np.linspace(-positive(deviation_max, "deviation_max"), deviation_max, int(n))
    t = math.radians(float(slope_direction_deg))
    p, q = s * math.cos(t), s * math.sin(t)
    dev = np.zeros((v.size, L.shape[0], 2))
    dev[:, k, 0 if kind == "slant" else 1] = v
    ex = exact_error(L, deviate_lights(L, dev), p, q)
    fp, fq = first_order_error(L, dev, p, q)
    return {
        "deviation_deg": v,
        "slopes": s,
        "dp": ex.dp,
        "dq": ex.dq,
        "dp_first_order": fp,
        "dq_first_order": fq,
    }


# ----------------------------------------------------------------------------- tolerances


def _moved(which, n_lights: int) -> tuple[int, ...]:
    try:
        idx = tuple(sorted({int(i) for i in np.atleast_1d(which)}))
    except (TypeError, ValueError):
        raise ValueError(f"lights_moved: expected light indices, got {which!r}") from None
    if not idx or idx[0] < 0 or idx[-1] >= n_lights:
        raise ValueError(f"lights_moved: indices must lie in [0, {n_lights}), got {which!r}")
    return idx


def _candidate_lights(L, p, q, moved, mode, delta_deg, n_directions):
    """Deviated light sets to test: shared (G, N, 3) or per normal (K, C, N, 3)."""
    N = L.shape[0]
    if mode in ("slant", "azimuth"):
        col = 0 if mode == "slant" else 1
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=len(moved))))
        dev = np.zeros((signs.shape[0], N, 2))
        dev[:, list(moved), col] = signs * delta_deg
        return deviate_lights(L, dev), None
    # "any" direction: the first-order error of light k is (G c_k)(n . u_k) delta, maximal in
    # |dp| (or |dq|) when u_k is along the tangent part of n, signs aligned with (G c_k)_i.
    # Those directions (per normal, output and sign) are evaluated exactly; for one light a
    # ring of directions is added.
    e_s, e_a = tangent_basis(L)
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
    per_normal = rotate_lights(L, angle, phi)  # (K, 4, N, 3)
    shared = None
    if len(mv) == 1 and n_directions > 0:
        ring = np.linspace(0.0, 360.0, int(n_directions), endpoint=False)
        a = np.zeros((ring.size, N))
        a[:, mv[0]] = delta_deg
        d = np.zeros((ring.size, N))
        d[:, mv[0]] = ring
        shared = rotate_lights(L, a, d)
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
    e_s, e_a = tangent_basis(L)
    if mode == "slant":
        w = np.abs(n @ e_s.T)
    elif mode == "azimuth":
        w = np.abs(n @ e_a.T) * np.sqrt(np.clip(1.0 - L[:, 2] ** 2, 0.0, None))[None, :]
    else:
        w = np.sqrt(np.clip(np.sum(n * n, axis=-1)[:, None] - (n @ L.T) ** 2, 0.0, None))
    g = np.abs(_gc(L, p, q))  # (K, 2, N)
    total = np.sum(g[:, :, list(moved)] * w[:, None, list(moved)], axis=-1)  # (K, 2)
    return float(total.max())


def _square(L, derivative_range, n_grid, lit_only):
    p, q = derivative_square(derivative_range, n_grid)
    p, q = p.ravel(), q.ravel()
    if lit_only:
        keep = _lit(L, p, q)
        p, q = p[keep], q[keep]
    if p.size == 0:
        raise ValueError("derivative_range: no lit normals in the derivative square")
    return p, q


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
    lights : array_like, (N, 3)
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
    L = _unit_lights(lights, "lights", nominal=True)
    if mode not in _MODES:
        raise ValueError(f"mode: expected one of {_MODES}, got {mode!r}")
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
    lights : array_like, (N, 3)
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
    L = _unit_lights(lights, "lights", nominal=True)
    if mode not in _MODES:
        raise ValueError(f"mode: expected one of {_MODES}, got {mode!r}")
    eps = positive(tolerance, "tolerance")
    upper = positive(upper_deg, "upper_deg")
    moved = _moved(lights_moved, L.shape[0])
    p, q = _square(L, derivative_range, n_grid, lit_only)
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
    lights : array_like, (N, 3)
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
    L = _unit_lights(lights, "lights", nominal=True)
    if mode not in _MODES:
        raise ValueError(f"mode: expected one of {_MODES}, got {mode!r}")
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
    lights : array_like, (N, 3)
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
    L = _unit_lights(lights, "lights", nominal=True)
    N = L.shape[0]
    groups = {
        "single_light": [(k,) for k in range(N)],
        "pair": list(itertools.combinations(range(N), 2)),
        "all_lights": [tuple(range(N))],
    }
    rows = []
    for D in ranges:
        for eps in tolerances:
            row = {"derivative_range": float(D), "tolerance": float(eps)}
            for key, sets in groups.items():
                res = [
                    max_deviation(L, eps, D, s, "any", n_grid=n_grid, n_directions=0, lit_only=lit_only)
                    for s in sets
                ]
                row[f"{key}_deg"] = min(r.value for r in res)
                row[f"{key}_first_order_deg"] = min(r.first_order for r in res)
            rows.append(row)
    return rows


# ----------------------------------------------------------------------------- Monte Carlo


@dataclass(frozen=True)
class MonteCarloResult:
    """Monte Carlo study of random light deviations.

    Attributes
    ----------
    sigma_deg : float
        RMS deviation angle of each light, degrees.
    p, q : numpy.ndarray
        ``(K,)`` true slopes of the test normals.
    dp, dq, angle_deg : numpy.ndarray
        ``(S, K)`` exact errors per sample and test normal.
    mean : numpy.ndarray
        ``(K, 2)`` sample mean of ``(dp, dq)``.
    covariance : numpy.ndarray
        ``(K, 2, 2)`` sample covariance of ``(dp, dq)``.
    predicted_covariance : numpy.ndarray
        ``(K, 2, 2)`` first-order covariance (:func:`first_order_covariance`).
    angle_rms_deg, predicted_angle_rms_deg : numpy.ndarray
        ``(K,)`` sample and first-order RMS normal angle error, degrees.
    """

    sigma_deg: float
    p: np.ndarray
    q: np.ndarray
    dp: np.ndarray
    dq: np.ndarray
    angle_deg: np.ndarray
    mean: np.ndarray
    covariance: np.ndarray
    predicted_covariance: np.ndarray
    angle_rms_deg: np.ndarray
    predicted_angle_rms_deg: np.ndarray


def random_deviations(n_lights: int, sigma_deg: float, n_samples: int, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """Random deviation angles and directions for the Monte Carlo model.

    The tangent deviation ``(a, b)`` along ``(e_s, e_a)`` has independent components
    ``N(0, sigma^2 / 2)``: the direction ``phi = atan2(b, a)`` is uniform and the angle
    ``delta = hypot(a, b)`` is Rayleigh-distributed with RMS ``sigma``. The deviation is
    then exactly Gaussian in the tangent plane, so the first-order errors are Gaussian.

    Parameters
    ----------
    n_lights : int
        Number of lights.
    sigma_deg : float
        RMS deviation angle, degrees.
    n_samples : int
        Number of samples.
    seed : int or numpy.random.Generator
        Randomness.

    Returns
    -------
    angle_deg, direction_deg : numpy.ndarray
        ``(n_samples, n_lights)``: ``delta >= 0`` and ``phi`` in (-180, 180].
    """
    sigma = positive(sigma_deg, "sigma_deg", allow_zero=True)
    if int(n_samples) < 2:
        raise ValueError(f"n_samples: need at least 2 samples, got {n_samples}")
    rng = np.random.default_rng(seed)
    a, b = rng.normal(0.0, sigma / np.sqrt(2.0), (2, int(n_samples), int(n_lights)))
    return np.hypot(a, b), np.degrees(np.arctan2(b, a))


def monte_carlo(lights, sigma_deg: float, p, q, n_samples: int = 20000, seed=0) -> MonteCarloResult:
    """Monte Carlo distribution of the errors for randomly deviated lights.

    Each light gets an isotropic Gaussian tangent deviation of RMS angle ``sigma``
    (:func:`random_deviations`, :func:`rotate_lights`); the images are reconstructed with the nominal
    lights (exact model). Compared with :func:`first_order_covariance`.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees (model of :func:`random_deviations`).
    p, q : array_like, (K,)
        Test slopes.
    n_samples : int
        Number of random light sets.
    seed : int or numpy.random.Generator
        Randomness.

    Returns
    -------
    MonteCarloResult
    """
    L = _unit_lights(lights, "lights", nominal=True)
    p, q = _pq(p, q)
    p, q = p.ravel(), q.ravel()
    angle, direction = random_deviations(L.shape[0], sigma_deg, n_samples, seed)
    M = np.linalg.pinv(L) @ rotate_lights(L, angle, direction)
    pe, qe, ang = _apply(M, p, q, angles=True)
    dp, dq = pe - p, qe - q
    e = np.stack([dp, dq], axis=-1)  # (S, K, 2)
    mean = e.mean(axis=0)
    centred = e - mean
    cov = np.einsum("ski,skj->kij", centred, centred) / (e.shape[0] - 1)
    return MonteCarloResult(
        sigma_deg=float(sigma_deg),
        p=p,
        q=q,
        dp=dp,
        dq=dq,
        angle_deg=ang,
        mean=mean,
        covariance=cov,
        predicted_covariance=first_order_covariance(L, sigma_deg, p, q),
        angle_rms_deg=np.sqrt(np.mean(ang**2, axis=0)),
        predicted_angle_rms_deg=first_order_angle_rms(L, sigma_deg, p, q),
    )


def exceedance_probability(
    lights,
    sigmas_deg,
    tolerance: float,
    derivative_range: float,
    n_samples: int = 2000,
    n_grid: int = 21,
    seed=0,
) -> np.ndarray:
    """Probability that random deviations push the worst error over the square above ``eps``.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    sigmas_deg : array_like, (G,)
        RMS deviation angles, degrees.
    tolerance : float
        ``eps``.
    derivative_range : float
        ``D``.
    n_samples : int
        Random light sets per sigma.
    n_grid : int
        Grid points per axis of the derivative square.
    seed : int
        Randomness (the same base draws are scaled for every sigma).

    Returns
    -------
    numpy.ndarray
        ``(G,)`` fractions of samples with ``max(|dp|, |dq|) > eps`` somewhere in the square.
    """
    L = _unit_lights(lights, "lights", nominal=True)
    sig = as_array(sigmas_deg, "sigmas_deg", ndim=1, min_size=1)
    if np.any(sig < 0):
        raise ValueError("sigmas_deg: must be non-negative")
    eps = positive(tolerance, "tolerance")
    p, q = _square(L, derivative_range, n_grid, False)
    base, direction = random_deviations(L.shape[0], 1.0, n_samples, seed)
    Lp = np.linalg.pinv(L)
    out = np.empty(sig.size)
    for i, s in enumerate(sig):
        st = _chunked_stats(Lp @ rotate_lights(L, base * s, direction), p, q)
        out[i] = np.mean(np.maximum(st["max_dp"], st["max_dq"]) > eps)
    return out


# ----------------------------------------------------------------------------- configuration


def ring_conditioning(slants_deg, n: int = 3) -> dict[str, np.ndarray]:
    """Conditioning of ``n`` lights equally spaced in azimuth against their common slant.

    For three lights 120 deg apart ``L^T L = diag(3/2 sin^2 s, 3/2 sin^2 s, 3 cos^2 s)``:
    singular values ``sqrt(3/2) sin s`` (twice) and ``sqrt(3) cos s``, all equal when
    ``tan s = sqrt(2)`` (s = 54.74 deg, Drbohlav & Chantler 2005).

    Parameters
    ----------
    slants_deg : array_like, (G,)
        Slants, degrees, in (0, 90).
    n : int
        Number of lights (>= 3).

    Returns
    -------
    dict
        ``slant_deg`` (G,), ``singular_values`` (G, 3), ``condition_number`` (G,),
        ``inverse_frobenius`` (G,) = ``||L^+||_F`` (noise gain of :func:`noise_propagation`).
    """
    s = as_array(slants_deg, "slants_deg", ndim=1, min_size=1)
    if np.any((s <= 0) | (s >= 90)):
        raise ValueError("slants_deg: slants must lie strictly between 0 and 90 degrees")
    if int(n) < 3:
        raise ValueError(f"n: need at least 3 lights, got {n}")
    az = 90.0 + 360.0 * np.arange(int(n)) / int(n)
    L = lights_from_angles(s[:, None], az[None, :])  # (G, n, 3)
    sv = np.linalg.svd(L, compute_uv=False)
    return {
        "slant_deg": s,
        "singular_values": sv,
        "condition_number": sv[:, 0] / sv[:, -1],
        "inverse_frobenius": np.sqrt(np.sum(1.0 / sv**2, axis=-1)),
    }


def noise_propagation(lights, sigma_image: float, albedo: float = 1.0, p=0.0, q=0.0) -> dict:
    """Propagation of independent image noise to the normal and to ``(p, q)``.

    ``g = L^+ I`` with ``Cov(I) = sigma_I^2 I_N`` gives ``Cov(g) = sigma_I^2 L^+ L^+T``;
    the bound on the normal error is ``sigma_n = sigma_I ||L^+||_F / rho``. Per normal,
    the angular part is ``(I - n n^T) Cov(g) (I - n n^T) / rho^2`` and
    ``Cov(p, q) = H Cov(g) H^T`` with ``H = [[-1, 0, -p], [0, -1, -q]] / (rho n_z)``.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Unit lights.
    sigma_image : float
        Standard deviation of the image noise (image intensity units, albedo 1 at
        intensity 1).
    albedo : float
        ``rho``.
    p, q : array_like
        Slopes of the normals of interest (common shape ``S``).

    Returns
    -------
    dict
        ``sigma_normal_bound`` (float), ``covariance_g`` (3, 3),
        ``angle_rms_deg`` (S), ``covariance_pq`` (S + (2, 2)).
    """
    L = _unit_lights(lights, "lights", nominal=True)
    sig = positive(sigma_image, "sigma_image", allow_zero=True)
    rho = positive(albedo, "albedo")
    p, q = _pq(np.atleast_1d(np.asarray(p, dtype=float)), np.atleast_1d(np.asarray(q, dtype=float)))
    C = np.linalg.pinv(L)
    cov_g = sig**2 * C @ C.T
    nh = normals_from_derivatives(p, q).reshape(-1, 3)
    P = np.eye(3)[None] - nh[:, :, None] * nh[:, None, :]
    cov_n = P @ cov_g @ P / rho**2
    pf, qf = p.ravel(), q.ravel()
    zeros = np.zeros_like(pf)
    H = np.stack(
        [np.stack([-np.ones_like(pf), zeros, -pf], -1), np.stack([zeros, -np.ones_like(pf), -qf], -1)],
        axis=1,
    ) / (rho * nh[:, 2])[:, None, None]
    cov_pq = H @ cov_g @ np.swapaxes(H, 1, 2)
    return {
        "sigma_normal_bound": float(sig * np.linalg.norm(C) / rho),
        "covariance_g": cov_g,
        "angle_rms_deg": np.degrees(np.sqrt(np.trace(cov_n, axis1=1, axis2=2))).reshape(p.shape),
        "covariance_pq": cov_pq.reshape(p.shape + (2, 2)),
    }


# ----------------------------------------------------------------------------- height fields


def height_error(lights_nominal, lights_true, height, pixel_size: float = 1.0, mask=None) -> dict:
    """Error of a height field's derivatives and of its integrated height.

    The slopes of ``height`` (:func:`surface_derivatives`) are mapped through the exact
    model; both the true and the erroneous slopes are integrated with
    ``photometric.integrate.integrate(method="dct")`` so that the integration error of
    the method itself cancels; the height error is taken after removing its mean.

    Parameters
    ----------
    lights_nominal : array_like, (N, 3)
        Nominal unit lights.
    lights_true : array_like, (N, 3)
        True unit lights.
    height : array_like, (H, W)
        Height field, mm.
    pixel_size : float
        Pixel pitch, mm.
    mask : array_like of bool, (H, W), optional
        Pixels the statistics run over (default all).

    Returns
    -------
    dict
        ``dp``, ``dq`` (H, W), ``dh`` (H, W) mm, and the scalars ``max_abs_dp``,
        ``max_abs_dq``, ``rms_dp``, ``rms_dq``, ``rms_dh_mm``, ``max_abs_dh_mm``,
        ``max_angle_deg``.
    """
    from photometric.integrate import integrate

    Lt = _unit_lights(lights_true, "lights_true")
    if Lt.ndim != 2:
        raise ValueError(f"lights_true: expected shape (N, 3), got {Lt.shape}")
    p, q = surface_derivatives(height, pixel_size)
    m = np.ones(p.shape, bool) if mask is None else as_array(mask, "mask", shape=p.shape, dtype=bool)
    if not m.any():
        raise ValueError("mask: selects no pixels")
    ex = exact_error(lights_nominal, Lt, p, q)
    h_true = integrate(p, q, method="dct", pixel_size=pixel_size)
    h_est = integrate(ex.p_est, ex.q_est, method="dct", pixel_size=pixel_size)
    dh = h_est - h_true
    dh = dh - dh[m].mean()
    return {
        "dp": ex.dp,
        "dq": ex.dq,
        "dh": dh,
        "max_abs_dp": float(np.abs(ex.dp[m]).max()),
        "max_abs_dq": float(np.abs(ex.dq[m]).max()),
        "rms_dp": float(np.sqrt(np.mean(ex.dp[m] ** 2))),
        "rms_dq": float(np.sqrt(np.mean(ex.dq[m] ** 2))),
        "rms_dh_mm": float(np.sqrt(np.mean(dh[m] ** 2))),
        "max_abs_dh_mm": float(np.abs(dh[m]).max()),
        "max_angle_deg": float(ex.angle_deg[m].max()),
    }


def _plane_depth(height: np.ndarray, defect_mask: np.ndarray) -> float:
    """Depth below the least-squares plane of the sound surface: plane - min inside the defect."""
    rows, cols = np.indices(height.shape)
    sound = ~defect_mask
    A = np.stack([cols[sound], rows[sound], np.ones(int(sound.sum()))], axis=1).astype(float)
    coef, *_ = np.linalg.lstsq(A, height[sound], rcond=None)
    plane = coef[0] * cols + coef[1] * rows + coef[2]
    return float(np.max((plane - height)[defect_mask]))


def crack_study(
    lights,
    deviations_deg,
    size: int = 128,
    pixel_size: float = 0.05,
    scene: str = "crack",
    seed: int = 0,
) -> dict:
    """Render a crack with deviated lights, reconstruct with the nominal ones, compare.

    Seed 002(a)'s test image of a crack: the scene ``datasets_synthetic.heightfields.
    make_scene(scene)`` is rendered (attached shadows, no noise) with the true lights
    ``deviate_lights(lights, d)`` for each ``d``, solved by ``photometric.stereo.solve``
    with the nominal lights, and integrated (``photometric.integrate.integrate``, DCT).
    The measured derivative error ``p_rec - p_true`` is set beside the exact prediction
    :func:`exact_error` and the first-order one, on pixels lit by every light; the crack
    depth is measured below the least-squares plane of the sound surface (and by
    ``photometric.defects.measure_defects``).

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights.
    deviations_deg : array_like, (M, N, 2)
        ``[d_slant, d_azimuth]`` per light for each of the M cases, degrees.
    size : int
        Image side, pixels.
    pixel_size : float
        Pixel pitch, mm.
    scene : str
        Scene name for ``make_scene`` ("crack" or "plate").
    seed : int
        Scene seed.

    Returns
    -------
    dict
        ``true_depth_mm``, ``depth_nominal_mm`` (measured with undeviated lights: the
        discretisation and integration error alone), ``pixel_size_mm``, ``scene``; ``cases``: one dict per
        deviation with ``deviations_deg``, ``max_abs_dp_measured``, ``max_abs_dp_predicted``,
        ``max_abs_dp_first_order`` (and ``dq``), ``rms_dp_measured``, ``rms_dp_predicted``,
        ``max_abs_diff_measured_predicted``, ``depth_mm`` (plane method),
        ``depth_mm_defects`` (``measure_defects``' deepest ``max_depth_mm`` or None),
        ``depth_error_mm`` (against the truth), ``depth_change_mm`` (against
        ``depth_nominal_mm``: the effect of the deviation); and arrays for plotting under ``maps``: ``p_true`` (H, W),
        ``dp_measured``, ``dp_predicted``, ``dq_measured``, ``dq_predicted`` (M, H, W)
        and ``lit`` (H, W) bool.
    """
    from datasets_synthetic.heightfields import make_scene
    from datasets_synthetic.render import render
    from photometric.defects import measure_defects
    from photometric.integrate import integrate
    from photometric.stereo import solve

    L = _unit_lights(lights, "lights", nominal=True)
    dev = as_array(deviations_deg, "deviations_deg")
    if dev.ndim != 3 or dev.shape[1:] != (L.shape[0], 2):
        raise ValueError(f"deviations_deg: expected shape (M, {L.shape[0]}, 2), got {dev.shape}")
    ps = positive(pixel_size, "pixel_size")
    hf = make_scene(scene, int(size), ps, int(seed))
    mask = np.asarray(hf.defect_mask, bool)
    if not mask.any():
        raise ValueError(f"scene: {scene!r} has no defect to measure")
    true_lights = deviate_lights(L, dev)
    lit = _lit(L, hf.p.ravel(), hf.q.ravel()).reshape(hf.p.shape)
    for Lt in true_lights:
        lit &= _lit(Lt, hf.p.ravel(), hf.q.ravel()).reshape(hf.p.shape)
    base = solve(render(hf, L, shadows="attached"), L)
    depth_nominal = _plane_depth(
        integrate(base.p.astype(float), base.q.astype(float), method="dct", pixel_size=ps), mask
    )
    cases = []
    maps = {k: [] for k in ("dp_measured", "dp_predicted", "dq_measured", "dq_predicted")}
    for d, Lt in zip(dev, true_lights):
        res = solve(render(hf, Lt, shadows="attached"), L)
        ok = lit & np.asarray(res.valid, bool)
        dp_m, dq_m = res.p.astype(float) - hf.p, res.q.astype(float) - hf.q
        ex = exact_error(L, Lt, hf.p, hf.q)
        fp, fq = first_order_error(L, d, hf.p, hf.q)
        height = integrate(res.p.astype(float), res.q.astype(float), method="dct", pixel_size=ps)
        found = measure_defects(height, ps)
        depths = [float(f["max_depth_mm"]) for f in found if "max_depth_mm" in f]
        depth = _plane_depth(height, mask)
        cases.append({
            "deviations_deg": d.tolist(),
            "max_abs_dp_measured": float(np.abs(dp_m[ok]).max()),
            "max_abs_dp_predicted": float(np.abs(ex.dp[ok]).max()),
            "max_abs_dp_first_order": float(np.abs(fp[ok]).max()),
            "max_abs_dq_measured": float(np.abs(dq_m[ok]).max()),
            "max_abs_dq_predicted": float(np.abs(ex.dq[ok]).max()),
            "max_abs_dq_first_order": float(np.abs(fq[ok]).max()),
            "rms_dp_measured": float(np.sqrt(np.mean(dp_m[ok] ** 2))),
            "rms_dp_predicted": float(np.sqrt(np.mean(ex.dp[ok] ** 2))),
            "max_abs_diff_measured_predicted": float(
                max(np.abs(dp_m - ex.dp)[ok].max(), np.abs(dq_m - ex.dq)[ok].max())
            ),
            "depth_mm": depth,
            "depth_mm_defects": max(depths) if depths else None,
            "depth_error_mm": depth - float(hf.defects[0]["depth_mm"]),
            "depth_change_mm": depth - depth_nominal,
        })
        maps["dp_measured"].append(np.where(ok, dp_m, np.nan))
        maps["dq_measured"].append(np.where(ok, dq_m, np.nan))
        maps["dp_predicted"].append(ex.dp)
        maps["dq_predicted"].append(ex.dq)
    return {
        "scene": scene,
        "size_px": int(size),
        "pixel_size_mm": ps,
        "true_depth_mm": float(hf.defects[0]["depth_mm"]),
        "depth_nominal_mm": depth_nominal,
        "lit_fraction": float(lit.mean()),
        "cases": cases,
        "maps": {"p_true": hf.p, "q_true": hf.q, "lit": lit, **{k: np.stack(v) for k, v in maps.items()}},
    }
