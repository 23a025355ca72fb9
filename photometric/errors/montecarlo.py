"""Monte Carlo study of random light deviations, against the first-order covariance.

Each light gets an isotropic Gaussian tangent deviation: components along ``e_s`` and
``e_a`` independent ``N(0, sigma^2 / 2)``, i.e. a uniformly random direction and an
angle whose RMS (and signed standard deviation) is ``sigma``
(:func:`random_deviations`, applied by :func:`photometric.lights.rotate_lights`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photometric.errors.maps import _chunked_stats
from photometric.errors.model import _angle_rms, _apply, _covariance, _nominal, _pq, _square
from photometric.lights import _rotate
from surfaces.validate import as_array, InputError, positive

__all__ = ["MonteCarloResult", "random_deviations", "monte_carlo", "exceedance_probability"]


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
        ``(K, 2, 2)`` first-order covariance
        (:func:`photometric.errors.model.first_order_covariance`).
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
    angle_deg, direction_deg : numpy.ndarray, shape (n_samples, n_lights)
        ``delta >= 0`` and ``phi`` in (-180, 180].
    """
    sigma = positive(sigma_deg, "sigma_deg", allow_zero=True)
    if int(n_samples) < 2:
        raise InputError(f"n_samples: need at least 2 samples, got {n_samples}")
    rng = np.random.default_rng(seed)
    a, b = rng.normal(0.0, sigma / np.sqrt(2.0), (2, int(n_samples), int(n_lights)))
    return np.hypot(a, b), np.degrees(np.arctan2(b, a))


def monte_carlo(lights, sigma_deg: float, p, q, n_samples: int = 20000, seed=0) -> MonteCarloResult:
    """Monte Carlo distribution of the errors for randomly deviated lights.

    Each light gets an isotropic Gaussian tangent deviation of RMS angle ``sigma``
    (:func:`random_deviations`); the images are reconstructed with the nominal lights
    (exact model). Compared with the first-order covariance and RMS angle.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    sigma_deg : float
        RMS deviation angle of each light, degrees (model of :func:`random_deviations`).
    p, q : array_like, shape (K,)
        Test slopes.
    n_samples : int
        Number of random light sets.
    seed : int or numpy.random.Generator
        Randomness.

    Returns
    -------
    MonteCarloResult
    """
    L = _nominal(lights)
    p, q = _pq(p, q)
    p, q = p.ravel(), q.ravel()
    angle, direction = random_deviations(L.shape[0], sigma_deg, n_samples, seed)
    sigma = float(sigma_deg)
    M = np.linalg.pinv(L) @ _rotate(L, angle, direction)
    pe, qe, ang = _apply(M, p, q, angles=True)
    dp, dq = pe - p, qe - q
    e = np.stack([dp, dq], axis=-1)  # (S, K, 2)
    mean = e.mean(axis=0)
    centred = e - mean
    cov = np.einsum("ski,skj->kij", centred, centred) / (e.shape[0] - 1)
    return MonteCarloResult(
        sigma_deg=sigma,
        p=p,
        q=q,
        dp=dp,
        dq=dq,
        angle_deg=ang,
        mean=mean,
        covariance=cov,
        predicted_covariance=_covariance(L, sigma, p, q),
        angle_rms_deg=np.sqrt(np.mean(ang**2, axis=0)),
        predicted_angle_rms_deg=_angle_rms(L, sigma, p, q),
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
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    sigmas_deg : array_like, shape (G,)
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
    numpy.ndarray, shape (G,)
        Fractions of samples with ``max(|dp|, |dq|) > eps`` somewhere in the square.
    """
    L = _nominal(lights)
    sig = as_array(sigmas_deg, "sigmas_deg", ndim=1, min_size=1)
    if np.any(sig < 0):
        raise InputError("sigmas_deg: must be non-negative")
    eps = positive(tolerance, "tolerance")
    p, q = _square(L, derivative_range, n_grid, False)
    base, direction = random_deviations(L.shape[0], 1.0, n_samples, seed)
    Lp = np.linalg.pinv(L)
    out = np.empty(sig.size)
    for i, s in enumerate(sig):
        st = _chunked_stats(Lp @ _rotate(L, base * s, direction), p, q)
        out[i] = np.mean(np.maximum(st["max_dp"], st["max_dq"]) > eps)
    return out
