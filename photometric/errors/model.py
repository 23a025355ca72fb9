"""The error model: exact and first-order derivative errors, sensitivity, covariance.

The true lights ``L'`` (rows are unit light vectors) make the images, the nominal
lights ``L`` reconstruct them, so the reconstructed (albedo-scaled) normal is
``m = L^+ L' n`` (``L^+`` the pseudo-inverse; ``L^-1`` for a triad) and

    p_est = -m_x / m_z,   q_est = -m_y / m_z.

Because ``p`` and ``q`` do not depend on the length of ``m``, the albedo drops out and
the unnormalised normal ``n = (-p, -q, 1)`` is used directly. The model is the linear
(unclipped) Lambertian one: a normal that faces away from a light (attached shadow) is
still evaluated algebraically; :func:`lit_normals` tells which normals every light
reaches.

First order (derived for this package)
--------------------------------------
With ``c_k`` the k-th column of ``L^+`` and a light perturbation ``dl_k``,
``dm = sum_k c_k (n . dl_k)``; at ``m = n = (-p, -q, 1)``,
``dp = -(dm_x + p dm_z)``, ``dq = -(dm_y + q dm_z)``. With
``dl_k/ds = e_s = (cos s cos a, cos s sin a, -sin s)`` and
``dl_k/da = sin s e_a``, ``e_a = (-sin a, cos a, 0)``, this is the closed-form
Jacobian of :func:`sensitivity`; for random isotropic tangent deviations
``Cov(dp, dq) = J Sigma J^T`` (:func:`first_order_covariance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from photometric.lights import _basis, validate_lights
from photometric.normals import angular_error_deg, normals_from_slopes
from surfaces.validate import as_array, InputError, positive

__all__ = [
    "DerivativeError",
    "derivative_square",
    "lit_normals",
    "reconstruction_matrix",
    "exact_error",
    "sensitivity",
    "first_order_error",
    "first_order_covariance",
    "first_order_angle_rms",
]


# ----------------------------------------------------------------------------- inputs


def _nominal(lights, name: str = "lights") -> np.ndarray:
    """Nominal lights (N, 3): at least three, unit (normalised with a warning), not coplanar."""
    return validate_lights(lights, name)


def _true(lights_true, n: int) -> np.ndarray:
    """True lights (..., N, 3) matching ``n`` nominal ones."""
    Lt = validate_lights(lights_true, "lights_true", min_lights=1, batched=True)
    if Lt.shape[-2] != n:
        raise InputError(f"lights_true: expected {n} lights, got shape {Lt.shape}")
    return Lt


def _pq(p, q) -> tuple[np.ndarray, np.ndarray]:
    p = as_array(p, "p")
    q = as_array(q, "q")
    if p.shape != q.shape:
        raise InputError(f"p, q: shapes differ ({p.shape} vs {q.shape})")
    return p, q


def _deviations(deviations_deg, n: int) -> np.ndarray:
    d = as_array(deviations_deg, "deviations_deg")
    if d.ndim < 2 or d.shape[-2:] != (n, 2):
        raise InputError(f"deviations_deg: expected shape (..., {n}, 2), got {d.shape}")
    return d


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
    p, q : numpy.ndarray, shape (n, n), float64
        ``p`` varies along axis 1, ``q`` along axis 0.

    Examples
    --------
    >>> p, q = derivative_square(1.0, 3)
    >>> p[0].tolist(), q[:, 0].tolist()
    ([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0])
    """
    D = positive(derivative_range, "derivative_range", allow_zero=True)
    if int(n) < 2:
        raise InputError(f"n: need at least 2 grid points, got {n}")
    v = np.linspace(-D, D, int(n))
    p, q = np.meshgrid(v, v)
    return p, q


def _lit(L: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Normals lit by every light (n . l_k > 0 for all k); shape of ``p``."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    return np.all(n @ L.T > 0.0, axis=-1)


def _square(L, derivative_range, n_grid, lit_only):
    """The derivative square as flat (K,) slopes, optionally only the normals every light reaches."""
    p, q = derivative_square(derivative_range, n_grid)
    p, q = p.ravel(), q.ravel()
    if lit_only:
        keep = _lit(L, p, q)
        p, q = p[keep], q[keep]
    if p.size == 0:
        raise InputError("derivative_range: no lit normals in the derivative square")
    return p, q


def lit_normals(lights, p, q) -> np.ndarray:
    """Which normals every light reaches (no attached shadow): ``n . l_k > 0`` for all k.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Unit lights.
    p, q : array_like, shape S
        Slopes of the normals.

    Returns
    -------
    numpy.ndarray, shape S, bool
    """
    L = validate_lights(lights, min_lights=1)
    p, q = _pq(p, q)
    return _lit(L, p, q)


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
    lights_nominal : array_like, shape (N, 3)
        Lights used for the reconstruction (``L``), N >= 3, not coplanar.
    lights_true : array_like, shape (..., N, 3)
        Lights that made the images (``L'``); leading dimensions give a batch.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3), float64
    """
    L = _nominal(lights_nominal, "lights_nominal")
    return np.linalg.pinv(L) @ _true(lights_true, L.shape[0])


def _apply(M: np.ndarray, p: np.ndarray, q: np.ndarray, *, angles: bool = False):
    """Reconstructed slopes for matrices M (G, 3, 3) and slopes p, q (K,) -> (G, K) arrays."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=0)  # (3, K)
    m = M @ n  # (G, 3, K)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_est = -m[:, 0] / m[:, 2]
        q_est = -m[:, 1] / m[:, 2]
    if not angles:
        return p_est, q_est, None
    return p_est, q_est, angular_error_deg(n.T[None], np.moveaxis(m, 1, 2))


def _exact(L: np.ndarray, Lt: np.ndarray, p: np.ndarray, q: np.ndarray) -> DerivativeError:
    M = np.linalg.pinv(L) @ Lt
    batch = M.shape[:-2]
    pe, qe, ang = _apply(M.reshape(-1, 3, 3), p.ravel(), q.ravel(), angles=True)
    shape = batch + p.shape
    return DerivativeError(
        dp=(pe - p.ravel()).reshape(shape),
        dq=(qe - q.ravel()).reshape(shape),
        angle_deg=ang.reshape(shape),
        p_est=pe.reshape(shape),
        q_est=qe.reshape(shape),
    )


def exact_error(lights_nominal, lights_true, p, q) -> DerivativeError:
    """Exact derivative and normal errors when ``L'`` makes the images and ``L`` reconstructs.

    ``m = L^+ L' n``, ``p_est = -m_x / m_z``, ``q_est = -m_y / m_z`` (seed 002(a):
    ``rho n = L^-1 I`` with ``I = rho L' n``).

    Parameters
    ----------
    lights_nominal : array_like, shape (N, 3)
        Nominal unit lights ``L``.
    lights_true : array_like, shape (..., N, 3)
        True unit lights ``L'``; a leading batch shape ``B`` is allowed.
    p, q : array_like
        True slopes, any common shape ``S``.

    Returns
    -------
    DerivativeError
        Arrays of shape ``B + S``.

    Examples
    --------
    >>> from photometric.lights import deviate_lights, ring_lights
    >>> L = ring_lights(3, 45.0)
    >>> err = exact_error(L, deviate_lights(L, [2.0, 0.0, 0.0]), 0.0, 0.0)
    >>> round(float(err.dq), 5), round(float(err.angle_deg), 4)  # m = n + (cos 47 - cos 45) c_1, q = -m_y / m_z
    (0.02396, 1.3723)
    """
    L = _nominal(lights_nominal, "lights_nominal")
    Lt = _true(lights_true, L.shape[0])
    p, q = _pq(p, q)
    return _exact(L, Lt, p, q)


# ----------------------------------------------------------------------------- first order


def _gc(L: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``G c_k``: first-order (dp, dq) per unit of ``n . dl_k``; (K, 2, N) for p, q (K,)."""
    C = np.linalg.pinv(L)  # (3, N), column k is c_k
    gp = -(C[0][None, :] + p[:, None] * C[2][None, :])
    gq = -(C[1][None, :] + q[:, None] * C[2][None, :])
    return np.stack([gp, gq], axis=1)


def _sensitivity(L: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pf, qf = p.ravel(), q.ravel()
    n = np.stack([-pf, -qf, np.ones_like(pf)], axis=-1)  # (K, 3)
    e_s, e_a = _basis(L)
    sin_s = np.sqrt(np.clip(1.0 - L[:, 2] ** 2, 0.0, None))
    ns = n @ e_s.T  # (K, N)
    na = (n @ e_a.T) * sin_s[None, :]
    J = _gc(L, pf, qf)[..., None] * np.stack([ns, na], axis=-1)[:, None, :, :]
    return J.reshape(p.shape + (2, L.shape[0], 2))


def sensitivity(lights, p, q) -> np.ndarray:
    """Closed-form Jacobian of ``(p, q)`` w.r.t. each light's slant and azimuth.

    ``d(p, q)/d(theta_k) = G(p, q) c_k (n . dl_k/d theta_k)`` with ``n = (-p, -q, 1)``,
    ``G = [[-1, 0, -p], [0, -1, -q]]``, ``c_k`` column k of ``L^+``,
    ``dl/ds = e_s``, ``dl/da = sin(s) e_a`` (derivation in the module docstring).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray, shape S + (2, N, 2), float64
        Per radian: ``J[..., i, k, j]`` is the derivative of output ``i`` (0 = p,
        1 = q) w.r.t. angle ``j`` (0 = slant, 1 = azimuth) of light ``k``.

    Examples
    --------
    A flat surface under the 45 deg triad: a slant error of light 1 (at azimuth
    90 deg, the top of the image) tilts the reconstruction about the x axis only.

    >>> from photometric.lights import ring_lights
    >>> J = sensitivity(ring_lights(3, 45.0), 0.0, 0.0)
    >>> J.shape
    (2, 3, 2)
    >>> np.round(np.radians(1.0) * J[:, 0, 0], 5).tolist()  # per degree of light 1's slant: 2/3 per rad
    [0.0, 0.01164]
    """
    L = _nominal(lights)
    p, q = _pq(p, q)
    return _sensitivity(L, p, q)


def _first_order(L: np.ndarray, d: np.ndarray, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    J = _sensitivity(L, p, q)
    N = L.shape[0]
    Jf = J.reshape(-1, 2, N * 2)
    out = np.einsum("kiz,...z->...ki", Jf, np.radians(d).reshape(d.shape[:-2] + (N * 2,)))
    shape = d.shape[:-2] + p.shape
    return out[..., 0].reshape(shape), out[..., 1].reshape(shape)


def first_order_error(lights, deviations_deg, p, q) -> tuple[np.ndarray, np.ndarray]:
    """First-order prediction of ``(dp, dq)`` for slant/azimuth deviations.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    deviations_deg : array_like, shape (..., N, 2)
        ``[d_slant, d_azimuth]`` per light, degrees (batch shape ``B``).
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    dp, dq : numpy.ndarray, shape B + S, float64
        ``J . radians(deviations)``.
    """
    L = _nominal(lights)
    p, q = _pq(p, q)
    return _first_order(L, _deviations(deviations_deg, L.shape[0]), p, q)


def _covariance(L: np.ndarray, sigma_deg: float, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    sigma = math.radians(sigma_deg)
    pf, qf = p.ravel(), q.ravel()
    n = np.stack([-pf, -qf, np.ones_like(pf)], axis=-1)
    w = 0.5 * sigma**2 * (np.sum(n * n, axis=-1)[:, None] - (n @ L.T) ** 2)  # (K, N)
    g = _gc(L, pf, qf)  # (K, 2, N)
    cov = np.einsum("kin,kjn,kn->kij", g, g, w)
    return cov.reshape(p.shape + (2, 2))


def first_order_covariance(lights, sigma_deg: float, p, q) -> np.ndarray:
    """First-order covariance of ``(dp, dq)`` for random isotropic light deviations.

    Each light's tangent displacement is isotropic Gaussian with covariance
    ``(sigma^2 / 2) I_2`` (RMS angle ``sigma``,
    :func:`photometric.errors.montecarlo.random_deviations`), so
    ``E[(n . dl_k)^2] = (sigma^2 / 2)(|n|^2 - (n . l_k)^2)``;
    ``Cov = sum_k (G c_k)(G c_k)^T (sigma^2 / 2)(|n|^2 - (n . l_k)^2)`` (= ``J Sigma J^T``).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees.
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray, shape S + (2, 2), float64
        Covariance (dimensionless slope units squared).
    """
    L = _nominal(lights)
    sigma = positive(sigma_deg, "sigma_deg", allow_zero=True)
    p, q = _pq(p, q)
    return _covariance(L, sigma, p, q)


def _angle_rms(L: np.ndarray, sigma_deg: float, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    sigma = math.radians(sigma_deg)
    nh = normals_from_slopes(p, q).reshape(-1, 3)
    C = np.linalg.pinv(L)  # (3, N)
    # with the unit normal, |n|^2 = 1 and no 1/|n| factor
    w = 0.5 * sigma**2 * (1.0 - (nh @ L.T) ** 2)  # (K, N)
    proj_c = C.T[None, :, :] - (nh @ C)[:, :, None] * nh[:, None, :]  # (K, N, 3)
    var = np.einsum("knj,knj,kn->k", proj_c, proj_c, w)
    return np.degrees(np.sqrt(var)).reshape(p.shape)


def first_order_angle_rms(lights, sigma_deg: float, p, q) -> np.ndarray:
    """First-order RMS angle between true and reconstructed normal (random deviations).

    ``dn = (I - n n^T) dm / |n|`` with ``dm = sum_k c_k (n . dl_k)``; the RMS angle is
    ``sqrt(trace Cov(dn))`` under the model of :func:`first_order_covariance`.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees.
    p, q : array_like
        Slopes, common shape ``S``.

    Returns
    -------
    numpy.ndarray, shape S, float64
        Degrees.
    """
    L = _nominal(lights)
    sigma = positive(sigma_deg, "sigma_deg", allow_zero=True)
    p, q = _pq(p, q)
    return _angle_rms(L, sigma, p, q)
