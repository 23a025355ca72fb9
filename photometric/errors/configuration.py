"""Light configuration: conditioning of rings of lights and propagation of image noise.

How good a set of nominal lights is before any deviation: the condition number of the
light matrix (:func:`photometric.lights.condition_number`) against the common slant of
a ring of lights, and the normal and slope errors that independent image noise causes.
"""

from __future__ import annotations

import math

import numpy as np

from photometric.errors.model import _nominal
from photometric.lights import _vectors
from photometric.normals import normals_from_slopes
from surfaces.validate import as_array, InputError, positive

__all__ = ["OPTIMAL_SLANT_DEG", "ring_conditioning", "noise_propagation"]

OPTIMAL_SLANT_DEG: float = math.degrees(math.atan(math.sqrt(2.0)))
"""Slant (deg) at which three lights 120 deg apart are best conditioned: tan(s) = sqrt(2)."""


def ring_conditioning(slants_deg, n: int = 3) -> dict[str, np.ndarray]:
    """Conditioning of ``n`` lights equally spaced in azimuth against their common slant.

    For three lights 120 deg apart ``L^T L = diag(3/2 sin^2 s, 3/2 sin^2 s, 3 cos^2 s)``:
    singular values ``sqrt(3/2) sin s`` (twice) and ``sqrt(3) cos s``, all equal when
    ``tan s = sqrt(2)`` (s = 54.74 deg, Drbohlav & Chantler 2005).

    Parameters
    ----------
    slants_deg : array_like, shape (G,)
        Slants, degrees, in (0, 90).
    n : int
        Number of lights (>= 3).

    Returns
    -------
    dict
        ``slant_deg`` (G,), ``singular_values`` (G, 3), ``condition_number`` (G,),
        ``inverse_frobenius`` (G,) = ``||L^+||_F`` (noise gain of :func:`noise_propagation`).

    Examples
    --------
    >>> round(float(ring_conditioning([OPTIMAL_SLANT_DEG])["condition_number"][0]), 12)
    1.0
    """
    s = as_array(slants_deg, "slants_deg", ndim=1, min_size=1)
    if np.any((s <= 0) | (s >= 90)):
        raise InputError("slants_deg: slants must lie strictly between 0 and 90 degrees")
    if int(n) < 3:
        raise InputError(f"n: need at least 3 lights, got {n}")
    az = 90.0 + 360.0 * np.arange(int(n)) / int(n)
    L = _vectors(np.radians(s)[:, None], np.radians(az)[None, :])  # (G, n, 3)
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
    lights : array_like, shape (N, 3)
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
    L = _nominal(lights)
    sig = positive(sigma_image, "sigma_image", allow_zero=True)
    rho = positive(albedo, "albedo")
    p = np.atleast_1d(as_array(p, "p"))
    q = np.atleast_1d(as_array(q, "q"))
    nh = normals_from_slopes(p, q).reshape(-1, 3)
    C = np.linalg.pinv(L)
    cov_g = sig**2 * C @ C.T
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
