"""Measurement uncertainty of photometric stereo (GUM, ISO/IEC Guide 98-3): per-pixel slope and
height uncertainty and the budget of every defect figure.

Sources (:class:`Tolerances`, standard uncertainties):

* image noise ``sigma`` (full scale 0-1; with N >= 4 lights estimated from the residuals);
* each light's direction (``light_tolerance_deg``, isotropic: each of the two tangent
  components of the unit light vector has standard uncertainty ``sigma_l``);
* each light's intensity (``intensity_tolerance``, relative);
* each LED's position (``light_position_tolerance_mm``, near-field rigs: each of x, y, z);
* the pixel size (``pixel_size_tolerance``, relative).

Linear propagation (the default)
--------------------------------
The far-field solve is ``m = C x`` with ``C = L^+`` (3, N), ``x_k = I_k / E_k`` and
``m = rho n``; the slopes are ``p = -m_x / m_z``, ``q = -m_y / m_z``, so
``d(p, q) = G dm / m_z`` with ``G = [[-1, 0, -p], [0, -1, -q]]`` and
``m_z = rho / sqrt(1 + p^2 + q^2)``.

* Noise: ``Cov(dm) = sigma^2 C diag(1 / E_k^2) C^T``, hence per pixel
  ``Cov(p, q) = sigma^2 (1 + p^2 + q^2) / rho^2 G C W C^T G^T`` (closed form, vectorised).
* A light parameter ``theta_j`` moving light ``k`` by ``dl_k`` gives
  ``d(p, q) = G c_k (n . dl_k)`` with ``n = (-p, -q, 1)`` (:mod:`photometric.errors.model`);
  an intensity error ``delta_k`` gives ``G c_k (n . l_k) delta_k``. These errors are
  systematic: the same parameter moves every pixel, so each parameter's slope field is
  integrated once (the integration is linear) and ``u_z^2 = sum_j (dz/dtheta_j)^2 u_j^2``.
* The noise part is white in the slopes but not after integration. For the free-boundary
  least-squares (DCT) integrator the covariance of the height is diagonal in the DCT-II
  basis: with ``s_k^2 = 4 sin^2(pi k / 2H)`` and ``c_k^2 = cos^2(pi k / 2H)`` (rows, ``l``
  and ``W`` for columns) the mode variance is
  ``T_kl = h^2 (sigma_p^2 s_l^2 c_l^2 + sigma_q^2 s_k^2 c_k^2) / (s_k^2 + s_l^2)^2``
  (derived here: ``z = (A^T A)^+ A^T M g`` with the edge difference ``A`` and the
  trapezoidal average ``M``, and ``A^T M M^T A`` is diagonal in the same basis). The
  per-pixel variance ``sum_kl a_k(r)^2 b_l(c)^2 T_kl`` takes one DCT-III per axis
  (``cos^2 = (1 + cos 2x) / 2``), and the variance of any linear figure ``w . z`` (a depth
  against a fitted background, a volume) is ``sum_kl T_kl DCT(w)_kl^2``. ``sigma_p``,
  ``sigma_q`` are the mean slope variances over the valid pixels (stationary model).
* Point lights (near-field rigs, orthographic camera): per pixel the light vectors
  ``s_k(X)`` at the solved points give ``m = M^-1 sum_k x_k s_k`` (``M = sum_k s_k s_k^T``);
  an LED coordinate moves the slopes by ``G c_k (n . ds_k/dP)`` with ``c_k = M^-1 s_k``
  (:class:`PointLightModel`); the noise covariance is ``sum_k w_k c_k c_k^T``.
* Images above 0.26 MP integrate the systematic fields on blocks of ``r x r`` pixels (the
  far-field fields are linear in ``1, p, q, p^2, pq, q^2``, so the block means are exact;
  the blocks must resolve the narrowest defect) and the noise figures on block sums
  plus the peak pixel's own fine-scale variance.
* Defect depth and volume are linear in the height after a least-squares background fit:
  each systematic field's effect is taken on the *measured depth* (field minus its
  background fit), so a light error that only tilts the plate adds nothing.
* Width, length and area depend on the segmentation: their budget holds the pixel size,
  the pixel quantisation of the outline (the spread of the same measures over the
  measured outline, a stadium, rasterised at random sub-pixel offsets) and the measures'
  own bias found the same way (``method_bias``: e.g. the ``+ 1`` pixel of the extent,
  stated as the standard uncertainty whose k = 2 interval holds 95 % of the biased
  spread). The depth gets its sampling term (the deepest point lies up to half a pixel
  from the deepest pixel) and the volume the place of its outline.

Monte Carlo (``method="montecarlo"``) repeats the fast solve (normals, integration,
defects) with perturbed lights, intensities and noise added to the images, and reports
the spread; the quantisation terms are added as in the linear method (the pixel grid is
the same in every repetition).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

from photometric.nearfield import _upsample
from surfaces.validate import as_array, positive

__all__ = [
    "METHODS",
    "SOURCES",
    "FIGURES",
    "COVERAGE_FACTOR",
    "Tolerances",
    "UncertaintyResult",
    "PointLightModel",
    "estimate_noise_sigma",
    "slope_noise_covariance",
    "slope_sensitivities",
    "slope_systematic_variance",
    "height_noise_variance",
    "linear_variance",
    "propagate",
    "format_value",
]

#: ``method`` choices.
METHODS = ("linear", "montecarlo")
#: Budget sources, in the order of ``uncertainty.json``.
SOURCES = ("image_noise", "light_direction", "light_position", "light_intensity", "montecarlo", "pixel_size",
           "discretisation", "method_bias")
#: Defect figures that get an uncertainty.
FIGURES = ("max_depth_mm", "mean_width_mm", "length_mm", "area_mm2", "volume_mm3")
#: Coverage factor of the expanded uncertainty (about 95 %).
COVERAGE_FACTOR = 2.0
#: Powers of the pixel size in each figure (heights scale with ``h`` like lengths).
_H_POWER = {"max_depth_mm": 1, "mean_width_mm": 1, "length_mm": 1, "area_mm2": 2, "volume_mm3": 3}
_QUANTISATION_OFFSETS = 96
#: Pixel-stadium evaluations of the quantisation of one defect, at most (bounds its cost).
_QUANTISATION_WORK = 1 << 20
_MAX_FIT_POINTS = 200_000
#: Largest image on which the systematic fields are integrated pixel by pixel; larger
#: images integrate them on blocks of r x r pixels (the fields are smooth at that scale).
_SYSTEMATIC_PIXELS = 1 << 18
#: Blocks across the narrowest defect at least, when the fields are integrated on blocks.
_RESOLVE = 8
#: Pixels per row block of the per-pixel maps (fits the CPU cache with its temporaries).
_BLOCK_PIXELS = 1 << 15


@dataclass(frozen=True)
class Tolerances:
    """Standard uncertainties of the inputs and how to propagate them.

    Attributes
    ----------
    noise_sigma : float or None
        Image noise, standard deviation in full-scale units (0-1); None: estimated from
        the residuals with N >= 4 lights, no noise term with a triad.
    light_tolerance_deg : float
        Standard uncertainty of each light's direction, degrees (each of the two tangent
        components; isotropic).
    light_position_tolerance_mm : float
        Standard uncertainty of each LED coordinate (x, y, z), mm (near-field rigs).
    intensity_tolerance : float
        Relative standard uncertainty of each light's intensity.
    pixel_size_tolerance : float
        Relative standard uncertainty of the pixel size.
    method : {"linear", "montecarlo"}
        Linear propagation or Monte Carlo over the fast solve.
    mc_samples : int
        Monte Carlo repetitions (at least 2).
    seed : int
        Seed of the Monte Carlo draws.
    """

    noise_sigma: float | None = None
    light_tolerance_deg: float = 0.0
    light_position_tolerance_mm: float = 0.0
    intensity_tolerance: float = 0.0
    pixel_size_tolerance: float = 0.0
    method: str = "linear"
    mc_samples: int = 50
    seed: int = 0

    def __post_init__(self):
        if self.noise_sigma is not None:
            positive(self.noise_sigma, "noise_sigma", allow_zero=True)
        for name in ("light_tolerance_deg", "light_position_tolerance_mm", "intensity_tolerance",
                     "pixel_size_tolerance"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name}: must be a non-negative number (a standard uncertainty), got {value}")
        if self.method not in METHODS:
            raise ValueError(f"method: expected one of {METHODS}, got {self.method!r}")
        if int(self.mc_samples) < 2:
            raise ValueError(f"mc_samples: need at least 2 Monte Carlo samples, got {self.mc_samples}")

    def to_dict(self) -> dict:
        """The tolerances as a JSON-ready dict."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class UncertaintyResult:
    """What :func:`propagate` returns.

    Attributes
    ----------
    p_u, q_u : numpy.ndarray, shape (H, W), float32
        Standard uncertainty of ``p`` and ``q`` (0 outside the valid pixels).
    height_u : numpy.ndarray, shape (H, W), float32
        Standard uncertainty of the height, mm (NaN outside the valid pixels); the height's
        datum is the integrator's (zero mean over the valid pixels).
    defects : list of dict
        Per defect: ``id``, ``uncertainty_k2`` (expanded uncertainty of every figure of
        :data:`FIGURES`) and ``budget`` (per figure: value, per source standard
        uncertainty, sensitivity and contribution, combined, k, expanded).
    summary : dict
        Method, tolerances, the noise sigma used and where it came from, timings (s) and
        the median ``p_u``, ``q_u``, ``height_u``. JSON-ready.
    """

    p_u: np.ndarray
    q_u: np.ndarray
    height_u: np.ndarray
    defects: list
    summary: dict


def format_value(value: float, expanded: float | None, unit: str = "mm") -> str:
    """A value with its expanded uncertainty as metrology writes it: ``0.100 ± 0.006 mm (k = 2)``.

    ``U`` keeps two significant digits when its first digit is 1 or 2, else one; the value
    is rounded to the same decimal place.

    Parameters
    ----------
    value : float
        The measured value.
    expanded : float or None
        Expanded uncertainty ``U`` (k = 2); None gives the value alone (4 significant digits).
    unit : str
        Unit written after the numbers.

    Returns
    -------
    str

    Examples
    --------
    >>> format_value(0.1004, 0.00612)
    '0.100 ± 0.006 mm (k = 2)'
    >>> format_value(5.0213, 0.0238)
    '5.021 ± 0.024 mm (k = 2)'
    """
    if expanded is None or not np.isfinite(expanded) or expanded <= 0:
        return f"{value:.4g} {unit}"
    first = math.floor(math.log10(expanded))
    lead = int(expanded / 10.0**first)
    digits = max(0, -(first - (1 if lead < 3 else 0)))
    return f"{value:.{digits}f} ± {expanded:.{digits}f} {unit} (k = {COVERAGE_FACTOR:g})"


# ----------------------------------------------------------------------------- slopes


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
        raise ValueError(f"n_lights: the noise can be estimated from the residuals with 4 or more lights, got {n}")
    r = as_array(residual, "residual", ndim=2)
    v = as_array(valid, "valid", shape=r.shape, dtype=bool)
    if not v.any():
        raise ValueError("valid: no pixel to estimate the noise from")
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
    lights : photometric.lights.PointLights
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
    from photometric.lights import _scaled_vectors, point_lights
    from photometric.nearfield import _strengths

    lights = model.lights
    shape = p.shape
    ones = np.ones((len(lights), 3))

    def strength(k, position):
        moved = lights.positions.copy()
        moved[k] = position
        one = point_lights(moved, lights.axes, lights.mu if lights.mu_known else None)
        return _strengths(one, model.camera, shape, model.gains, ones)[k]
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


# ----------------------------------------------------------------------------- heights


def _mode_variance(shape, var_p: float, var_q: float, h: float) -> np.ndarray:
    """``T_kl``: variance of each DCT-II mode of the integrated height (module docstring), float32."""
    rows, cols = shape
    ar = np.pi * np.arange(rows) / (2 * rows)
    ac = np.pi * np.arange(cols) / (2 * cols)
    sr = 4.0 * np.sin(ar) ** 2
    sc = 4.0 * np.sin(ac) ** 2
    num_r = (h * h * var_q * sr * np.cos(ar) ** 2).astype(np.float32)[:, None]
    num_c = (h * h * var_p * sc * np.cos(ac) ** 2).astype(np.float32)[None, :]
    den = sr.astype(np.float32)[:, None] + sc.astype(np.float32)[None, :]
    den[0, 0] = 1.0
    np.square(den, out=den)
    T = num_r + num_c
    T /= den
    T[0, 0] = 0.0
    return T


def _squared_basis_sum(T: np.ndarray, axis: int) -> np.ndarray:
    """``sum_k a_k(r)^2 T_k`` along ``axis`` for the orthonormal DCT-II basis ``a_k``.

    ``a_k(r)^2 = c_k^2 (1 + cos(pi 2k (2 r + 1) / 2n)) / 2``: a constant plus a cosine sum at
    the even frequencies ``j = 2k``; those with ``j >= n`` fold back to ``2n - j`` with a
    minus sign (``cos(pi (2r + 1) - x) = -cos x``), so the sum is one DCT-III of length
    ``n``.
    """
    n = T.shape[axis]
    c2 = np.full(n, 2.0 / n, np.float32)
    c2[0] = 1.0 / n
    shape = [1, 1]
    shape[axis] = n
    Y = np.moveaxis(T * c2.reshape(shape), axis, 0)
    const = 0.5 * Y.sum(axis=0, keepdims=True)
    folded = np.zeros_like(Y)
    low = np.arange(0, (n + 1) // 2)  # j = 2k < n
    folded[2 * low] += Y[low]
    high = np.arange((n + 2) // 2, n)  # j = 2n - 2k, 0 < j < n (j = n: cos = 0)
    folded[2 * n - 2 * high] -= Y[high]
    folded[1:] *= 0.5  # scipy's DCT-III doubles every term but the first
    S = sfft.dct(folded, type=3, axis=0, workers=-1, overwrite_x=True)
    return np.moveaxis(const + 0.5 * S, 0, axis)


def height_noise_variance(shape, var_p: float, var_q: float, pixel_size: float = 1.0) -> np.ndarray:
    """Per-pixel variance of the DCT-integrated height for white slope noise.

    Parameters
    ----------
    shape : (H, W)
        Image size.
    var_p, var_q : float
        Variances of the slope noise (independent between pixels).
    pixel_size : float
        Pixel size (mm); the variance is in mm^2.

    Returns
    -------
    numpy.ndarray, shape (H, W), float64
        ``sum_kl a_k(r)^2 b_l(c)^2 T_kl`` (module docstring); the height's zero mean over
        the image is the datum, as :func:`photometric.integrate.dct_poisson` returns it.
    """
    T = _mode_variance(shape, float(var_p), float(var_q), float(pixel_size))
    return np.maximum(_squared_basis_sum(_squared_basis_sum(T, 0), 1), 0.0).astype(np.float64)


def linear_variance(weights, var_p: float, var_q: float, pixel_size: float = 1.0) -> float:
    """Variance of ``sum_i w_i z_i`` (a linear figure of the DCT-integrated height).

    Parameters
    ----------
    weights : array_like, shape (H, W)
        ``w`` (e.g. +1 at a defect's deepest pixel and minus the background fit's weights).
    var_p, var_q, pixel_size :
        As :func:`height_noise_variance`.

    Returns
    -------
    float
        ``sum_kl T_kl DCT(w)_kl^2`` (mm^2 times the unit of ``w`` squared).
    """
    w = as_array(weights, "weights", ndim=2)
    return _linear_variance(w, _mode_variance(w.shape, float(var_p), float(var_q), float(pixel_size)))


def _linear_variance(w: np.ndarray, T: np.ndarray) -> float:
    W = sfft.dctn(w.astype(np.float32), type=2, norm="ortho", workers=-1)
    return float(np.sum(T * W * W, dtype=np.float64))


def _bin(a: np.ndarray, r: int) -> np.ndarray:
    """Means of ``r x r`` blocks (trailing rows and columns dropped, as
    :func:`photometric.nearfield._upsample` expects); OpenCV's area resampling."""
    import cv2

    h, w = a.shape[0] // r, a.shape[1] // r
    return cv2.resize(a[: h * r, : w * r], (w, h), interpolation=cv2.INTER_AREA)


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


def _integrate_field(dp: np.ndarray, dq: np.ndarray, integrator: str, ok: np.ndarray, h: float) -> np.ndarray:
    """A systematic slope field (zero outside ``ok``) integrated like the height: float32 DCT
    for ``dct`` (uncertainties need no more digits), zero mean over ``ok``, zero outside."""
    from photometric.integrate import dct_poisson, integrate

    if integrator == "dct":
        z = dct_poisson(dp, dq, None, h, dtype=np.float32).astype(np.float32)
    else:
        z = np.nan_to_num(integrate(dp, dq, integrator, mask=ok, pixel_size=h)).astype(np.float32)
    if not ok.all():
        z -= np.float32(z[ok].mean())
        z[~ok] = 0.0
    return z


# ----------------------------------------------------------------------------- defects


@dataclass
class _Figures:
    """The linear functionals of one defect: depth and volume against the background fit."""

    sign: float
    peak: tuple[int, int]
    region: np.ndarray  # (n, 2) pixel indices
    d_peak: np.ndarray  # design row at the peak (terms,)
    d_region: np.ndarray  # summed design rows over the region (terms,)


class _Background:
    """A least-squares background (plane or polynomial) over fixed pixels: a linear projector."""

    def __init__(self, usable: np.ndarray, degree: int, shape):
        from photometric.defects import _design

        rows, cols = np.nonzero(usable)
        if rows.size > _MAX_FIT_POINTS:
            pick = np.linspace(0, rows.size - 1, _MAX_FIT_POINTS).astype(np.int64)
            rows, cols = rows[pick], cols[pick]
        self.rows, self.cols, self.shape, self.degree = rows, cols, shape, degree
        self.A = _design(rows, cols, shape, degree)
        self.gram_inv = np.linalg.pinv(self.A.T @ self.A)

    def design(self, rows, cols) -> np.ndarray:
        from photometric.defects import _design

        return _design(np.atleast_1d(rows), np.atleast_1d(cols), self.shape, self.degree)

    def coef(self, z: np.ndarray) -> np.ndarray:
        return self.gram_inv @ (self.A.T @ z[self.rows, self.cols])

    def weights(self, d: np.ndarray) -> np.ndarray:
        """Image of the weights with which the fit's value ``d . coef`` takes each pixel."""
        w = np.zeros(self.shape, np.float32)
        w[self.rows, self.cols] = self.A @ (self.gram_inv @ d)  # the fit's pixels are distinct
        return w


def _grown(labels: np.ndarray, defects: list, margin: int) -> np.ndarray:
    """The defects' pixels grown by ``margin`` pixels (dilated within each bounding box)."""
    out = np.zeros(labels.shape, bool)
    for rec in defects:
        r0, c0, r1, c1 = rec["bbox_px"]
        r0, c0 = max(r0 - margin, 0), max(c0 - margin, 0)
        r1, c1 = min(r1 + margin, labels.shape[0]), min(c1 + margin, labels.shape[1])
        window = labels[r0:r1, c0:c1] == rec["id"] + 1
        out[r0:r1, c0:c1] |= ndimage.binary_dilation(window, iterations=margin)
    return out


def _figures(labels: np.ndarray, defects: list, height: np.ndarray, bg: _Background) -> list[_Figures]:
    coef = bg.coef(np.nan_to_num(height))
    out = []
    for rec in defects:
        region = np.argwhere(labels == rec["id"] + 1)
        sign = -1.0 if rec.get("kind", "depression") == "depression" else 1.0
        design = bg.design(region[:, 0], region[:, 1])
        depth = sign * (height[region[:, 0], region[:, 1]] - design @ coef)
        i = int(np.argmax(depth))
        out.append(_Figures(sign, (int(region[i, 0]), int(region[i, 1])), region, design[i], design.sum(axis=0)))
    return out


def _points(bg: _Background, figs: list) -> tuple[np.ndarray, np.ndarray, list]:
    """Every pixel a systematic field is read at: the background's, then per defect its peak
    and its region; with the slices of each defect's part."""
    rows, cols, parts = [bg.rows], [bg.cols], []
    start = bg.rows.size
    for fig in figs:
        rows += [np.array([fig.peak[0]]), fig.region[:, 0]]
        cols += [np.array([fig.peak[1]]), fig.region[:, 1]]
        parts.append((start, start + 1 + fig.region.shape[0]))
        start = parts[-1][1]
    return np.concatenate(rows), np.concatenate(cols), parts


def _sampler(rows: np.ndarray, cols: np.ndarray, r: int, coarse_shape) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices (n, 4) and weights (n, 4) that read a field of ``r x r`` block means at
    full-resolution pixels bilinearly, as :func:`photometric.nearfield._upsample` does."""
    hc, wc = coarse_shape
    out_i, out_w = [], []
    for pix, n in ((rows, hc), (cols, wc)):
        x = np.clip((pix + 0.5) / r - 0.5, 0.0, n - 1)
        i0 = np.floor(x).astype(np.int64)
        i1 = np.minimum(i0 + 1, n - 1)
        f = x - i0
        out_i.append((i0, i1))
        out_w.append((1.0 - f, f))
    (r0, r1), (c0, c1) = out_i
    (wr0, wr1), (wc0, wc1) = out_w
    idx = np.stack([r0 * wc + c0, r0 * wc + c1, r1 * wc + c0, r1 * wc + c1], axis=1)
    w = np.stack([wr0 * wc0, wr0 * wc1, wr1 * wc0, wr1 * wc1], axis=1)
    return idx, w


def _systematic(fig: _Figures, values: np.ndarray, part: tuple, coef: np.ndarray, h: float) -> tuple[float, float]:
    """Change of (depth, volume) for a systematic height field read at the defect's pixels
    (``values[part]``: peak, then region) with background ``coef``."""
    v = values[part[0]:part[1]]
    depth = fig.sign * (v[0] - fig.d_peak @ coef)
    volume = fig.sign * h * h * (v[1:].sum() - fig.d_region @ coef)
    return float(depth), float(volume)


def _noise_weights(fig: _Figures, bg: _Background, h: float) -> tuple[np.ndarray, np.ndarray]:
    w_depth = -fig.sign * bg.weights(fig.d_peak)
    w_depth[fig.peak] += fig.sign
    w_vol = -fig.sign * h * h * bg.weights(fig.d_region)
    w_vol[fig.region[:, 0], fig.region[:, 1]] += fig.sign * h * h  # distinct pixels
    return w_depth, w_vol


def _point_variance(T: np.ndarray, row: int, col: int) -> float:
    """Variance of the integrated height at one pixel: ``a(row)^2 . T . b(col)^2``."""
    h, w = T.shape
    a = np.cos(np.pi * np.arange(h) * (2 * row + 1) / (2 * h)) ** 2 * (2.0 / h)
    a[0] = 1.0 / h
    b = np.cos(np.pi * np.arange(w) * (2 * col + 1) / (2 * w)) ** 2 * (2.0 / w)
    b[0] = 1.0 / w
    return float(a.astype(np.float32) @ T @ b.astype(np.float32))


def _noise_functionals(fig: _Figures, bg: _Background, h: float, r: int, T: np.ndarray, var_p: float,
                       var_q: float, cache: dict) -> tuple[float, float]:
    """Noise variance of a defect's depth and volume against the background fit.

    ``r = 1``: exact (:func:`linear_variance` of the weights). Large images (``r > 1``):
    the weights summed over ``r x r`` blocks against the mode variances of the block-mean
    slopes (variance ``/ r^2`` on pixels ``r h``), which hold every scale of the
    background fit and the region; the depth adds the peak pixel's own variance at full
    resolution minus its block's (:func:`_point_variance`).
    """
    if r == 1:
        w_depth, w_vol = _noise_weights(fig, bg, h)
        return _linear_variance(w_depth, T), _linear_variance(w_vol, T)
    shape = (T.shape[0] // r, T.shape[1] // r)
    if "T" not in cache:
        cache["T"] = _mode_variance(shape, var_p / r**2, var_q / r**2, h * r)
    Tc = cache["T"]
    hc, wc = shape
    # block of each weighted pixel (trailing rows and columns belong to the last blocks)
    bg_block = np.minimum(bg.rows // r, hc - 1) * wc + np.minimum(bg.cols // r, wc - 1)
    region_block = (np.minimum(fig.region[:, 0] // r, hc - 1) * wc + np.minimum(fig.region[:, 1] // r, wc - 1))

    def blocks(fit_weights, own_blocks, own_weight):
        out = np.bincount(bg_block, weights=fit_weights, minlength=hc * wc)
        out += np.bincount(own_blocks, minlength=hc * wc) * own_weight
        return out.reshape(hc, wc)

    pr, pc = fig.peak
    peak_block = np.array([min(pr // r, hc - 1) * wc + min(pc // r, wc - 1)])
    b_depth = blocks(-fig.sign * (bg.A @ (bg.gram_inv @ fig.d_peak)), peak_block, fig.sign)
    b_vol = blocks(-fig.sign * h * h * (bg.A @ (bg.gram_inv @ fig.d_region)), region_block, fig.sign * h * h)
    rc, cc = min(pr // r, shape[0] - 1), min(pc // r, shape[1] - 1)
    vd = _linear_variance(b_depth, Tc) + _point_variance(T, pr, pc) - _point_variance(Tc, rc, cc)
    return max(vd, 0.0), _linear_variance(b_vol, Tc)


def _rasterised(width: float, length: float, axis_deg: float, h: float, offsets: np.ndarray) -> dict:
    """Width, length and area (as :func:`photometric.defects.measure_defects` measures them)
    of stadiums (``width``, ``length`` in pixels, axis in degrees) rasterised at sub-pixel
    offsets: the pixel centres inside a stadium are its region, measured as
    :func:`photometric.defects._measure` does (principal axis, extent along it plus one
    pixel, pixels of the central half per pixel of half the length), all stadiums at once.

    ``offsets`` is (n, 2) (``dx, dy``, pixels) or (n, 4) (also ``dwidth, dlength`` added to
    the stadium's width and length, pixels). Returns lists of the measures (mm, mm^2) and,
    under ``"model"``, each stadium's own ``(width, length, area)``; stadiums with fewer than
    two pixels are left out."""
    offsets = np.asarray(offsets, float)
    if offsets.shape[1] == 2:
        offsets = np.concatenate([offsets, np.zeros_like(offsets)], axis=1)
    widths = np.maximum(width + offsets[:, 2], 1.0)
    lengths = np.maximum(length + offsets[:, 3], widths)
    a = math.radians(axis_deg)
    ux, uy = math.cos(a), math.sin(a)
    reach = 0.5 * float(lengths.max()) + 2.0
    half_x = int(math.ceil(abs(ux) * reach + 0.5 * widths.max())) + 2
    half_y = int(math.ceil(abs(uy) * reach + 0.5 * widths.max())) + 2
    y0, x0 = np.meshgrid(-np.arange(-half_y, half_y + 1.0), np.arange(-half_x, half_x + 1.0),
                         indexing="ij")  # y up, rows down
    # only the pixels near the axis can be inside at any offset
    near = (np.abs(-x0 * uy + y0 * ux) < 0.5 * widths.max() + 1.0) & (np.abs(x0 * ux + y0 * uy) < reach)
    xs, ys = x0[near].astype(np.float32), y0[near].astype(np.float32)
    dx, dy = offsets[:, :1].astype(np.float32), offsets[:, 1:2].astype(np.float32)
    half = (0.5 * (lengths - widths)).astype(np.float32)[:, None]
    x, y = xs - dx, ys - dy
    along = np.clip(x * np.float32(ux) + y * np.float32(uy), -half, half)
    radius = (0.5 * widths).astype(np.float32)[:, None]
    inside = np.hypot(x - along * np.float32(ux), y - along * np.float32(uy)) < radius
    n = inside.sum(axis=1)
    keep = n >= 2
    inside, n, widths, lengths = inside[keep], n[keep], widths[keep], lengths[keep]
    values = {"mean_width_mm": [], "length_mm": [], "area_mm2": [], "model": []}
    if not keep.any():
        return values
    # the region's own principal axis (rows, cols of the pixel grid, as _measure takes them)
    w = inside.astype(np.float64)
    X, Y = xs.astype(np.float64), ys.astype(np.float64)
    mx, my = w @ X / n, w @ Y / n
    cxx = w @ (X * X) / n - mx * mx
    cyy = w @ (Y * Y) / n - my * my
    cxy = w @ (X * Y) / n - mx * my
    angle = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    s = np.cos(angle)[:, None] * X + np.sin(angle)[:, None] * Y
    s_max = np.where(inside, s, -np.inf).max(axis=1)
    s_min = np.where(inside, s, np.inf).min(axis=1)
    length_px = s_max - s_min + 1.0
    central = inside & (np.abs(s - 0.5 * (s_max + s_min)[:, None]) <= 0.25 * length_px[:, None])
    values["mean_width_mm"] = list(central.sum(axis=1) / np.maximum(0.5 * length_px, 1.0) * h)
    values["length_mm"] = list(length_px * h)
    values["area_mm2"] = list(n * h * h)
    areas = ((lengths - widths) * widths + 0.25 * math.pi * widths**2) * h * h
    values["model"] = list(zip(widths * h, lengths * h, areas))
    return values


def _quantisation(rec: dict, h: float, rng: np.random.Generator) -> dict:
    """Pixel quantisation of the outline: width, length and area measured (as
    :func:`photometric.defects.measure_defects` does) on a stadium of the defect's axis
    rasterised at random sub-pixel offsets.

    The stadium stands for the true outline, so its width and length are first set so that
    their mean measures over a few offsets equal the defect's (one correction: the extent
    along the axis adds up to a pixel, the mean width of a round dent is below its
    diameter). The measures' errors over the offsets are discrete and skewed (the extent
    moves in steps of the pixel pitch projected on the axis), so the 95 % half-width is
    their 95th percentile of ``|measure - stadium|``, not twice a standard deviation.

    Returns ``{figure: (spread, half95)}``: the standard deviation of the measures over the
    offsets and the 95th percentile of their absolute error.
    """
    width = max(float(rec["mean_width_mm"]) / h, 1.0)
    length = max(float(rec["length_mm"]) / h, width)
    axis = float(rec["axis_deg"])
    first = _rasterised(width, length, axis, h, rng.uniform(-0.5, 0.5, (16, 4)))
    if len(first["mean_width_mm"]) > 2:
        bias_w, bias_l, _ = np.mean(np.asarray([first["mean_width_mm"], first["length_mm"], first["area_mm2"]]).T
                                    - np.asarray(first["model"]), axis=0)
        width = min(max(width - bias_w / h, 1.0), length)
        length = max(length - bias_l / h, width)
    # the true width and length are known to about a pixel only, and how the outline
    # falls on the grid depends on their fractions of a pixel: each stadium draws them
    # large outlines (many pixels) quantise finely: fewer stadiums bound the work
    count = int(np.clip(_QUANTISATION_WORK / ((length + 4.0) * (width + 3.0)), _QUANTISATION_OFFSETS // 3,
                        _QUANTISATION_OFFSETS))
    values = _rasterised(width, length, axis, h, rng.uniform(-0.5, 0.5, (count, 4)))
    model = dict(zip(("mean_width_mm", "length_mm", "area_mm2"), np.asarray(values.pop("model")).T))
    out = {}
    for key, v in values.items():
        if len(v) > 2:
            err = np.asarray(v) - model[key]
            out[key] = (float(np.std(err, ddof=1)), float(np.percentile(np.abs(err), 95.0)))
        else:
            out[key] = (0.5 * h ** _H_POWER[key], h ** _H_POWER[key])
    return out


def _bias_term(spread: float, bias: float) -> float:
    """Standard uncertainty of an uncorrected bias ``b`` next to a spread ``s``: the ``u_b`` for
    which ``2 sqrt(s^2 + u_b^2)`` is the half-width that holds 95 % of ``Normal(b, s)``."""
    b, s = abs(bias), spread
    if b == 0.0:
        return 0.0
    if s <= 0.0:
        return 0.5 * b

    def held(U):
        return 0.5 * (math.erf((U - b) / (s * math.sqrt(2.0))) - math.erf((-U - b) / (s * math.sqrt(2.0))))

    lo, hi = 0.0, b + 10.0 * s
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if held(mid) < 0.95 else (lo, mid)
    return float(math.sqrt(max((0.25 * (lo + hi)) ** 2 - s * s, 0.0)))


def _depth_sampling(z: np.ndarray, fig: _Figures, bg: _Background, coef: np.ndarray, labels: np.ndarray,
                    label: int) -> float:
    """Standard uncertainty of the depth's pixel sampling and integration on the pixel grid:
    ``a / sqrt(3)`` with ``a`` half the mean depth drop to the two row or column neighbours
    of the deepest pixel (the larger), i.e. the drop over half a pixel (rectangular)."""
    r, c = fig.peak

    def depth(rr, cc):
        return fig.sign * (z[rr, cc] - float((bg.design(rr, cc) @ coef)[0]))

    top = depth(r, c)
    drops = []
    for dr, dc in ((0, 1), (1, 0)):
        pair = []
        for sgn in (-1, 1):
            rr, cc = r + sgn * dr, c + sgn * dc
            if 0 <= rr < z.shape[0] and 0 <= cc < z.shape[1] and labels[rr, cc] == label:
                pair.append(top - depth(rr, cc))
        if pair:
            drops.append(np.mean(pair))
    if not drops:
        return 0.0
    return float(0.5 * max(max(drops), 0.0) / math.sqrt(3.0))


def _stage_times(t0: float, marks: dict) -> dict:
    """Seconds of each stage between the marks, and the total."""
    out, last = {}, t0
    for name, t in marks.items():
        out[name] = round(t - last, 4)
        last = t
    out["defects"] = round(time.perf_counter() - last, 4)
    out["total"] = round(time.perf_counter() - t0, 4)
    return out


def _median(values: np.ndarray, where: np.ndarray) -> float:
    """Median over ``where`` (of at most ~250 000 evenly spread pixels: a summary figure)."""
    step = max(1, int(math.sqrt(values.size / 250_000)))
    v = values[::step, ::step][where[::step, ::step]]
    return float(np.median(v)) if v.size else 0.0


def _volume_edge(z: np.ndarray, fig: _Figures, bg: _Background, coef: np.ndarray, h: float) -> float:
    """Standard uncertainty of the volume from the outline's place: the outline moves together
    by up to a quarter of a pixel (rectangular; it is where the slope crosses its
    threshold, inside a pixel), each outline pixel's volume with it:
    ``h^2 sum(depth) / (4 sqrt(3))`` over the outline pixels, mm^3."""
    rows, cols = fig.region[:, 0], fig.region[:, 1]
    r0, c0 = rows.min() - 1, cols.min() - 1
    inside = np.zeros((rows.max() - r0 + 2, cols.max() - c0 + 2), bool)
    inside[rows - r0, cols - c0] = True
    edge = inside & ~ndimage.binary_erosion(inside)
    er, ec = np.nonzero(edge)
    er, ec = er + r0, ec + c0
    depth = fig.sign * (z[er, ec] - bg.design(er, ec) @ coef)
    return float(0.25 * h * h * np.clip(np.nan_to_num(depth), 0.0, None).sum() / math.sqrt(3.0))


def _entry(u_input: float, sensitivity: float) -> dict:
    return {"standard_uncertainty": float(u_input), "sensitivity": float(sensitivity),
            "contribution": float(abs(sensitivity) * u_input)}


def _budget(rec: dict, terms: dict) -> tuple[dict, dict]:
    """Per figure: value, sources, combined, k, expanded. ``terms[figure][source] = entry``."""
    budget, expanded = {}, {}
    for fig in FIGURES:
        sources = terms.get(fig, {})
        uc = math.sqrt(sum(e["contribution"] ** 2 for e in sources.values()))
        budget[fig] = {
            "value": float(rec[fig]),
            "sources": {s: sources[s] for s in SOURCES if s in sources},
            "combined_standard_uncertainty": uc,
            "k": COVERAGE_FACTOR,
            "expanded_uncertainty": COVERAGE_FACTOR * uc,
        }
        expanded[fig] = COVERAGE_FACTOR * uc
    return budget, expanded


# ----------------------------------------------------------------------------- propagation


def propagate(
    *,
    lights,
    intensities,
    albedo,
    p,
    q,
    valid,
    height,
    defects: list,
    labels,
    pixel_size: float,
    tolerances: Tolerances,
    integrator: str = "dct",
    background: str = "plane",
    residual=None,
    channels: int = 1,
    images=None,
    pixel_size_given: bool = True,
    resolve=None,
    point: PointLightModel | None = None,
    draw=None,
) -> UncertaintyResult:
    """Uncertainty of the slopes, heights and defect figures of a far-field reconstruction.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights of the solve.
    intensities : array_like, shape (N,) or (N, 3)
        Light intensities.
    albedo : array_like, shape (H, W) or (H, W, 3)
        Albedo of the solve.
    p, q : array_like, shape (H, W)
        Slopes.
    valid : array_like, shape (H, W), bool
        Solved pixels.
    height : array_like, shape (H, W)
        Height, mm (NaN outside ``valid``).
    defects : list of dict
        :func:`photometric.defects.measure_defects` records.
    labels : array_like, shape (H, W), int
        Their label image (``return_labels=True``).
    pixel_size : float
        Pixel size, mm.
    tolerances : Tolerances
        Sources and method.
    integrator : {"dct", "fc", "lsq"}
        The integrator of the reconstruction (the systematic fields go through it).
    background : {"plane", "smooth", "none"}
        The defects' background.
    residual : array_like, shape (H, W), optional
        RMS residual of the solve (noise estimate with N >= 4 when ``noise_sigma`` is None).
    channels : int
        Colour channels of the images.
    images : array_like, shape (N, H, W[, 3]), optional
        The images (Monte Carlo adds noise to them).
    pixel_size_given : bool
        False when the pixel size is the default 1 unit per pixel: an error (the
        uncertainties are stated in mm).
    resolve : callable, optional
        Monte Carlo: ``resolve(images, lights, intensities) -> (p, q, valid, height,
        defects)`` re-runs the fast solve (the pipeline passes its own).
    point : PointLightModel, optional
        Point lights (near-field rig, orthographic camera): the LED position Jacobian
        replaces the direction sensitivities; ``lights`` are then their directions.
    draw : callable, optional
        Monte Carlo: ``draw(rng) -> lights`` for ``resolve`` (default: the directions
        deviated by ``light_tolerance_deg``).

    Returns
    -------
    UncertaintyResult
    """
    tol = tolerances
    t0 = time.perf_counter()
    h = positive(pixel_size, "pixel_size")
    if not pixel_size_given:
        raise ValueError("pixel_size: uncertainties are stated in mm and need the pixel size (--pixel-size or the "
                         "folder's scene.json); without it the heights are in pixel units")
    L = as_array(lights, "lights", ndim=2)
    n = L.shape[0]
    E = np.ones(n) if intensities is None else np.asarray(intensities, float)
    pp = as_array(p, "p", ndim=2, dtype=np.float32, finite=False)
    qq = as_array(q, "q", shape=pp.shape, dtype=np.float32, finite=False)
    ok = as_array(valid, "valid", shape=pp.shape, dtype=bool)
    z = as_array(height, "height", shape=pp.shape, finite=False)
    lab = as_array(labels, "labels", shape=pp.shape, dtype=np.int64)
    shape = pp.shape

    sigma, sigma_source = tol.noise_sigma, "option"
    if sigma is None:
        if n >= 4 and residual is not None:
            sigma, sigma_source = estimate_noise_sigma(residual, ok, n, E), "estimated from the residuals"
        else:
            sigma, sigma_source = 0.0, "not given (a triad has no residual to estimate it from)"

    point_fields = []
    if point is None:
        if tol.light_position_tolerance_mm > 0:
            raise ValueError("light_position_tolerance_mm: applies to point lights (LED positions); distant lights "
                             "are directions (use light_tolerance_deg)")
        p_u, q_u, mean_vp, mean_vq = _slope_maps(L, E, albedo, pp, qq, ok, sigma, tol, channels)
    else:
        if tol.light_tolerance_deg > 0:
            raise ValueError("light_tolerance_deg: point lights (LED positions) take light_position_tolerance_mm")
        point_fields, p_u, q_u, mean_vp, mean_vq = _point_fields(point, albedo, pp, qq, ok, z, sigma, tol,
                                                                 channels)

    near = ok & np.isfinite(z)
    grown = _grown(lab, defects, 3)
    deg = 1 if background in ("plane", "none") else 3
    bg = _Background(near & ~grown, deg, shape) if defects else None
    figs = _figures(lab, defects, z, bg) if defects else []

    marks = {"setup": time.perf_counter()}
    # systematic parameters: one slope field each, integrated once (on blocks of r x r
    # pixels for large images: the fields are linear in 1, p, q, p^2, pq, q^2, whose block
    # means give the fields' block means exactly)
    dterms = [{"max_depth_mm": {}, "volume_mm3": {}} for _ in defects]
    sys_var = np.zeros(shape, np.float32)
    r = max(1, int(math.ceil(math.sqrt(pp.size / _SYSTEMATIC_PIXELS))))
    if defects:
        # the blocks must resolve the narrowest defect (at least _RESOLVE blocks across)
        r = min(r, max(1, int(min(d["mean_width_mm"] for d in defects) / h // _RESOLVE)))
    if min(shape) < 8 * r:
        r = 1
    coarse_T: dict = {}
    okf = ok.astype(np.float32)
    ok_c = (_bin(okf, r) if r > 1 else okf) > 0
    if tol.method != "linear":
        fields = iter(())
    elif point is None:
        fields = _far_systematic(L, tol, pp, qq, okf, r)
    else:
        fields = ((src, u, _bin(dp, r) if r > 1 else dp, _bin(dq, r) if r > 1 else dq)
                  for src, _name, u, dp, dq in point_fields)
    var_c = np.zeros(ok_c.shape, np.float32)
    if figs:
        rows, cols, parts = _points(bg, figs)
        idx, wts = _sampler(rows, cols, r, ok_c.shape)
        n_bg = bg.rows.size
    for source, u, dp, dq in fields:
        zj = _integrate_field(dp, dq, integrator, ok_c, h * r)
        var_c += (zj * np.float32(u)) ** 2
        if figs:
            # constants cancel in depth and volume against the fitted background
            values = np.einsum("nk,nk->n", zj.ravel()[idx], wts)
            coef = bg.gram_inv @ (bg.A.T @ values[:n_bg])
            for i, fig in enumerate(figs):
                c_depth, c_vol = _systematic(fig, values, parts[i], coef, h)
                for figname, c in (("max_depth_mm", c_depth), ("volume_mm3", c_vol)):
                    acc = dterms[i][figname].setdefault(source, [0.0, u])
                    acc[0] += c * c
    sys_var = _upsample(var_c, r, shape) if r > 1 else var_c
    marks["systematic"] = time.perf_counter()

    T = _mode_variance(shape, mean_vp, mean_vq, h) if sigma > 0 else None
    height_var = sys_var
    if T is not None:
        height_var = height_var + _squared_basis_sum(_squared_basis_sum(T, 0), 1).astype(np.float32)
    if tol.pixel_size_tolerance > 0:
        zc = np.where(near, z - (z[near].mean() if near.any() else 0.0), 0.0)
        height_var = height_var + ((tol.pixel_size_tolerance * zc) ** 2).astype(np.float32)
    height_u = np.sqrt(np.maximum(height_var, 0.0))
    height_u[~near] = np.nan

    marks["maps"] = time.perf_counter()
    rng = np.random.default_rng(tol.seed)
    coef0 = bg.coef(np.nan_to_num(z)) if figs else None

    mc = None
    if tol.method == "montecarlo":
        if resolve is None or images is None:
            raise ValueError("method: 'montecarlo' needs the images and the solver (use the pipeline)")
        mc = _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng, draw)
        p_u, q_u, height_u = mc["p_u"], mc["q_u"], mc["height_u"]

    out_defects = []
    for i, (rec, fig) in enumerate(zip(defects, figs)):
        terms: dict = {f: {} for f in FIGURES}
        if mc is None:
            for figname in ("max_depth_mm", "volume_mm3"):
                for source, (c2, u) in dterms[i][figname].items():
                    terms[figname][source] = _entry(u, math.sqrt(c2))
            if sigma > 0:
                vd, vv = _noise_functionals(fig, bg, h, r, T, mean_vp, mean_vq, coarse_T)
                terms["max_depth_mm"]["image_noise"] = _entry(sigma, math.sqrt(vd) / sigma)
                terms["volume_mm3"]["image_noise"] = _entry(sigma, math.sqrt(vv) / sigma)
        else:
            for figname, spread in mc["defects"][i].items():
                terms[figname]["montecarlo"] = _entry(spread, 1.0)
        if tol.pixel_size_tolerance > 0:
            for figname in FIGURES:
                terms[figname]["pixel_size"] = _entry(tol.pixel_size_tolerance, _H_POWER[figname] * rec[figname])
        for figname, (spread, half95) in _quantisation(rec, h, rng).items():
            # the outline's 95 % half-width stands for 2 u of the quantisation: its spread,
            # and the rest (bias, skew) as the method's term
            terms[figname]["discretisation"] = _entry(spread, 1.0)
            terms[figname]["method_bias"] = _entry(math.sqrt(max(0.25 * half95**2 - spread**2, 0.0)), 1.0)
        terms["max_depth_mm"]["discretisation"] = _entry(
            _depth_sampling(z, fig, bg, coef0, lab, rec["id"] + 1), 1.0)
        terms["volume_mm3"]["discretisation"] = _entry(_volume_edge(z, fig, bg, coef0, h), 1.0)
        budget, expanded = _budget(rec, terms)
        out_defects.append({"id": rec["id"], "uncertainty_k2": expanded, "budget": budget})

    summary = {
        "method": tol.method,
        "tolerances": tol.to_dict(),
        "noise_sigma": float(sigma),
        "noise_sigma_source": sigma_source,
        "coverage_factor": COVERAGE_FACTOR,
        "median_p_u": _median(p_u, ok),
        "median_q_u": _median(q_u, ok),
        "median_height_u_mm": _median(height_u, near),
        "timings_s": _stage_times(t0, marks),
    }
    if mc is not None:
        summary["mc_samples"] = int(tol.mc_samples)
        summary["mc_missing"] = mc["missing"]
    return UncertaintyResult(p_u=p_u, q_u=q_u, height_u=height_u, defects=out_defects, summary=summary)


def _perturbed_lights(L: np.ndarray, u_rad: float, rng: np.random.Generator) -> np.ndarray:
    """Lights moved by independent tangent deviations of standard uncertainty ``u_rad`` per axis."""
    e_s, e_a = _tangents(L)
    d = rng.normal(0.0, u_rad, (L.shape[0], 2))
    moved = L + d[:, :1] * e_s + d[:, 1:] * e_a
    return moved / np.linalg.norm(moved, axis=1, keepdims=True)


def _match(defects: list, found: list) -> list:
    """For each nominal defect the found defect of its kind nearest to its centre, when that
    lies within half the nominal defect's bounding box (at least 3 pixels); else None."""
    out = []
    for rec in defects:
        r0, c0, r1, c1 = rec["bbox_px"]
        reach = max(3.0, 0.5 * max(r1 - r0, c1 - c0))
        dist = [math.dist(rec["center_px"], f["center_px"]) if f["kind"] == rec["kind"] else np.inf for f in found]
        best = int(np.argmin(dist)) if dist else -1
        out.append(found[best] if best >= 0 and dist[best] <= reach else None)
    return out


def _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng, draw=None) -> dict:
    """Repeat the fast solve with perturbed inputs; spreads of slopes, heights and figures."""
    imgs = np.asarray(images, np.float32)
    n = tol.mc_samples
    s1 = {k: np.zeros(shape) for k in ("p", "q", "z")}
    s2 = {k: np.zeros(shape) for k in ("p", "q", "z")}
    count = np.zeros(shape)
    values = [{f: [] for f in FIGURES} for _ in defects]
    missing = 0
    u_dir = math.radians(tol.light_tolerance_deg)
    for _ in range(n):
        Lm = draw(rng) if draw is not None else _perturbed_lights(L, u_dir, rng) if u_dir > 0 else L
        Em = E * (1.0 + tol.intensity_tolerance * rng.standard_normal(E.shape[0]).reshape(
            (-1,) + (1,) * (E.ndim - 1))) if tol.intensity_tolerance > 0 else E
        im = imgs + rng.normal(0.0, sigma, imgs.shape).astype(np.float32) if sigma > 0 else imgs
        scale = 1.0 + tol.pixel_size_tolerance * rng.standard_normal() if tol.pixel_size_tolerance > 0 else 1.0
        p, q, ok, z, found = resolve(im, Lm, Em)
        zz = np.where(ok & np.isfinite(z), z, 0.0) * scale
        for key, arr in (("p", p), ("q", q), ("z", zz)):
            a = np.where(ok, arr, 0.0)
            s1[key] += a
            s2[key] += a * a
        count += ok
        for i, m in enumerate(_match(defects, found)):
            if m is None:
                missing += 1
                continue
            for f in FIGURES:
                values[i][f].append(m[f] * scale ** _H_POWER[f])
    c = np.maximum(count, 2)

    def spread(key):
        mean = s1[key] / c
        return np.sqrt(np.maximum(s2[key] / c - mean * mean, 0.0) * c / (c - 1))

    good = count >= 2
    return {
        "p_u": np.where(good, spread("p"), 0.0).astype(np.float32),
        "q_u": np.where(good, spread("q"), 0.0).astype(np.float32),
        "height_u": np.where(good, spread("z"), np.nan).astype(np.float32),
        "defects": [{f: float(np.std(v[f], ddof=1)) if len(v[f]) > 1 else float("inf") for f in FIGURES}
                    for v in values],
        "missing": missing,
    }
