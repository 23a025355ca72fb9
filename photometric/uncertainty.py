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
  per-pixel variance ``sum_kl a_k(r)^2 b_l(c)^2 T_kl`` is evaluated with FFTs
  (``cos^2 = (1 + cos 2x) / 2``), and the variance of any linear figure ``w . z`` (a depth
  against a fitted background, a volume) is ``sum_kl T_kl DCT(w)_kl^2``. ``sigma_p``,
  ``sigma_q`` are the mean slope variances over the valid pixels (stationary model).
* Defect depth and volume are linear in the height after a least-squares background fit:
  each systematic field's effect is taken on the *measured depth* (field minus its
  background fit), so a light error that only tilts the plate adds nothing.
* Width, length and area depend on the segmentation: their budget holds the pixel size
  and the pixel quantisation of the outline (the spread of the same measures over the
  fitted outline rasterised at random sub-pixel offsets); the depth also gets its
  sampling term (the true deepest point lies up to half a pixel from the deepest pixel).

Monte Carlo (``method="montecarlo"``) repeats the fast solve (normals, integration,
defects) with perturbed lights, intensities and noise added to the images, and reports
the spread; the quantisation terms are added as in the linear method (the pixel grid is
the same in every repetition).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

from surfaces.validate import as_array, positive

__all__ = [
    "METHODS",
    "SOURCES",
    "FIGURES",
    "COVERAGE_FACTOR",
    "Tolerances",
    "UncertaintyResult",
    "estimate_noise_sigma",
    "slope_noise_covariance",
    "slope_sensitivities",
    "height_noise_variance",
    "linear_variance",
    "propagate",
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
_QUANTISATION_OFFSETS = 48
_MAX_FIT_POINTS = 200_000


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
    var_p, var_q, cov_pq : numpy.ndarray, shape (H, W), float64
        ``sigma^2 (1 + p^2 + q^2) / rho^2 G A G^T`` with ``A = C diag(1 / E^2) C^T``;
        infinite where the albedo is zero.
    """
    L = as_array(lights, "lights", ndim=2)
    C = np.linalg.pinv(L)
    E = _grey_intensities(intensities, L.shape[0])
    A = (C / E**2) @ C.T
    pp = np.asarray(p, np.float64)
    qq = np.asarray(q, np.float64)
    rho = np.asarray(albedo, np.float64)
    if rho.ndim == 3:
        rho = rho.mean(axis=2)
    with np.errstate(divide="ignore"):
        s2 = (sigma**2 / channels) * (1.0 + pp * pp + qq * qq) / (rho * rho)
    var_p = s2 * (A[0, 0] + 2.0 * pp * A[0, 2] + pp * pp * A[2, 2])
    var_q = s2 * (A[1, 1] + 2.0 * qq * A[1, 2] + qq * qq * A[2, 2])
    cov = s2 * (A[0, 1] + pp * A[1, 2] + qq * A[0, 2] + pp * qq * A[2, 2])
    return var_p, var_q, cov


def _tangents(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents per light (slant and azimuth directions; any pair at the pole)."""
    from photometric.lights import _basis

    return _basis(L)


def slope_sensitivities(lights, p, q, tolerances: Tolerances, intensities=None):
    """The systematic light parameters and their slope fields (far-field lights).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit light directions.
    p, q : array_like, shape (H, W)
        Slopes.
    tolerances : Tolerances
        ``light_tolerance_deg`` and ``intensity_tolerance`` select the parameters.
    intensities : array_like, optional
        Unused by the first-order model (the intensities divide out); kept for the
        signature of the near-field variant.

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
        ``n = (-p, -q, 1)``.
    """
    L = as_array(lights, "lights", ndim=2)
    C = np.linalg.pinv(L)
    pp = np.asarray(p, np.float32)
    qq = np.asarray(q, np.float32)
    e_s, e_a = _tangents(L)
    u_dir = math.radians(tolerances.light_tolerance_deg)
    for k in range(L.shape[0]):
        gp = -(np.float32(C[0, k]) + pp * np.float32(C[2, k]))
        gq = -(np.float32(C[1, k]) + qq * np.float32(C[2, k]))
        vectors = []
        if u_dir > 0:
            vectors += [("light_direction", f"light {k} slant", u_dir, e_s[k]),
                        ("light_direction", f"light {k} azimuth", u_dir, e_a[k])]
        if tolerances.intensity_tolerance > 0:
            vectors.append(("light_intensity", f"light {k} intensity", tolerances.intensity_tolerance, L[k]))
        for source, name, u, e in vectors:
            ndl = np.float32(e[2]) - pp * np.float32(e[0]) - qq * np.float32(e[1])
            yield source, name, u, gp * ndl, gq * ndl


# ----------------------------------------------------------------------------- heights


def _mode_variance(shape, var_p: float, var_q: float, h: float) -> np.ndarray:
    """``T_kl``: variance of each DCT-II mode of the integrated height (module docstring)."""
    rows, cols = shape
    ar = np.pi * np.arange(rows) / (2 * rows)
    ac = np.pi * np.arange(cols) / (2 * cols)
    sr = 4.0 * np.sin(ar) ** 2
    sc = 4.0 * np.sin(ac) ** 2
    num = var_p * (sc * np.cos(ac) ** 2)[None, :] + var_q * (sr * np.cos(ar) ** 2)[:, None]
    den = (sr[:, None] + sc[None, :]) ** 2
    den[0, 0] = 1.0
    T = h * h * num / den
    T[0, 0] = 0.0
    return T


def _squared_basis_sum(T: np.ndarray, axis: int) -> np.ndarray:
    """``sum_k a_k(r)^2 T_k`` along ``axis`` for the orthonormal DCT-II basis ``a_k``.

    ``a_k(r)^2 = c_k^2 (1 + cos(pi k (2 r + 1) / n)) / 2``: a constant plus a cosine sum,
    evaluated as the real part of a zero-padded inverse FFT of length ``2 n``.
    """
    n = T.shape[axis]
    c2 = np.full(n, 2.0 / n)
    c2[0] = 1.0 / n
    shape = [1, 1]
    shape[axis] = n
    Y = T * c2.reshape(shape)
    const = 0.5 * Y.sum(axis=axis, keepdims=True)
    F = sfft.ifft(Y, n=2 * n, axis=axis, workers=-1) * (2 * n)
    odd = np.take(F.real, np.arange(1, 2 * n, 2), axis=axis)
    return const + 0.5 * odd


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
    return np.maximum(_squared_basis_sum(_squared_basis_sum(T, 0), 1), 0.0)


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
    T = _mode_variance(w.shape, float(var_p), float(var_q), float(pixel_size))
    W = sfft.dctn(w, type=2, norm="ortho", workers=-1)
    return float(np.sum(T * W * W))


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
        w = np.zeros(self.shape)
        np.add.at(w, (self.rows, self.cols), self.A @ (self.gram_inv @ d))
        return w


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


def _systematic(fig: _Figures, z: np.ndarray, coef: np.ndarray, h: float) -> tuple[float, float]:
    """Change of (depth, volume) for a systematic height field ``z`` with background ``coef``."""
    r, c = fig.peak
    depth = fig.sign * (z[r, c] - fig.d_peak @ coef)
    volume = fig.sign * h * h * (z[fig.region[:, 0], fig.region[:, 1]].sum() - fig.d_region @ coef)
    return float(depth), float(volume)


def _noise_weights(fig: _Figures, bg: _Background, h: float) -> tuple[np.ndarray, np.ndarray]:
    w_depth = -fig.sign * bg.weights(fig.d_peak)
    w_depth[fig.peak] += fig.sign
    w_vol = -fig.sign * h * h * bg.weights(fig.d_region)
    np.add.at(w_vol, (fig.region[:, 0], fig.region[:, 1]), fig.sign * h * h)
    return w_depth, w_vol


def _quantisation(rec: dict, h: float, rng: np.random.Generator) -> dict:
    """Pixel quantisation of the outline: width, length and area measured (as
    :func:`photometric.defects.measure_defects` does) on the measured outline, a stadium
    of the measured width, length and axis, rasterised at random sub-pixel offsets.

    Returns ``{figure: (spread, bias)}``: the standard deviation over the offsets and the
    mean minus the stadium's own value (the measure's bias, e.g. the ``+ 1`` pixel of the
    extent along the axis).
    """
    from skimage.measure import regionprops

    from photometric.defects import _measure

    width = max(float(rec["mean_width_mm"]) / h, 1.0)
    length = max(float(rec["length_mm"]) / h, width)
    a = math.radians(float(rec["axis_deg"]))
    ux, uy = math.cos(a), math.sin(a)
    half = int(math.ceil(0.5 * length + width)) + 2
    grid = np.arange(-half, half + 1, dtype=float)
    y0, x0 = np.meshgrid(-grid, grid, indexing="ij")  # y up, rows down
    values = {"mean_width_mm": [], "length_mm": [], "area_mm2": []}
    for off in rng.uniform(-0.5, 0.5, (_QUANTISATION_OFFSETS, 2)):
        x, y = x0 - off[0], y0 - off[1]
        s = np.clip(x * ux + y * uy, -0.5 * (length - width), 0.5 * (length - width))
        inside = np.hypot(x - s * ux, y - s * uy) < 0.5 * width
        if inside.sum() < 2:
            continue
        prop = regionprops(inside.astype(np.int32), intensity_image=np.ones(inside.shape))[0]
        m = _measure(prop, h, "depression", 0.0, 0.0, 0.0)
        for key in values:
            values[key].append(m[key])
    model = {"mean_width_mm": width * h, "length_mm": length * h,
             "area_mm2": ((length - width) * width + 0.25 * math.pi * width * width) * h * h}
    out = {}
    for key, v in values.items():
        if len(v) > 2:
            out[key] = (float(np.std(v, ddof=1)), float(np.mean(v) - model[key]))
        else:
            out[key] = (0.5 * h ** _H_POWER[key], 0.0)
    return out


def _bias_term(spread: float, bias: float) -> float:
    """Standard uncertainty of an uncorrected bias ``b`` next to a spread ``s``: the ``u_b`` for
    which ``2 sqrt(s^2 + u_b^2)`` is the half-width that holds 95 % of ``Normal(b, s)``."""
    from scipy import optimize, stats

    b, s = abs(bias), max(spread, 1e-300)
    if b < 1e-12 * max(s, 1e-300) or b == 0.0:
        return 0.0

    def miss(U):
        return stats.norm.cdf((U - b) / s) - stats.norm.cdf((-U - b) / s) - 0.95

    U = optimize.brentq(miss, 0.0, b + 10.0 * s)
    return float(math.sqrt(max((0.5 * U) ** 2 - s * s, 0.0)))


def _depth_sampling(depth_map: np.ndarray, peak: tuple[int, int], inside: np.ndarray) -> float:
    """Standard uncertainty of taking the deepest pixel for the deepest point: the depth
    falls by ``a`` over half a pixel (a quarter of the drop to the shallower of the two
    neighbours along the steepest direction's mean), rectangular: ``a / sqrt(3)``."""
    r, c = peak
    drops = []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        pair = []
        for sgn in (-1, 1):
            rr, cc = r + sgn * dr, c + sgn * dc
            if 0 <= rr < depth_map.shape[0] and 0 <= cc < depth_map.shape[1] and inside[rr, cc]:
                pair.append(depth_map[r, c] - depth_map[rr, cc])
        if pair:
            drops.append(np.mean(pair))
    if not drops:
        return 0.0
    return float(0.5 * max(max(drops), 0.0) / math.sqrt(3.0))


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
    mask=None,
    pixel_size_given: bool = True,
    resolve=None,
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
    mask : array_like, shape (H, W), optional
        Object mask of the solve (Monte Carlo).
    pixel_size_given : bool
        False when the pixel size is the default 1 unit per pixel: a pixel size tolerance
        is then an error (mm outputs need a pixel size).
    resolve : callable, optional
        Monte Carlo: ``resolve(images, lights, intensities) -> (p, q, valid, height,
        defects)`` re-runs the fast solve (the pipeline passes its own).

    Returns
    -------
    UncertaintyResult
    """
    import time

    from photometric.integrate import integrate

    tol = tolerances
    t0 = time.perf_counter()
    h = positive(pixel_size, "pixel_size")
    if not pixel_size_given and (tol.pixel_size_tolerance > 0 or tol.light_position_tolerance_mm > 0):
        raise ValueError("pixel_size: tolerances of mm outputs (pixel size, light positions) need the pixel size "
                         "(--pixel-size or the folder's scene.json)")
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

    var_p, var_q, cov_pq = slope_noise_covariance(L, albedo, pp, qq, sigma, E, channels)
    var_p = np.where(ok, var_p, 0.0)
    var_q = np.where(ok, var_q, 0.0)
    mean_vp = float(var_p[ok].mean()) if ok.any() else 0.0
    mean_vq = float(var_q[ok].mean()) if ok.any() else 0.0

    near = ok & np.isfinite(z)
    grown = ndimage.binary_dilation(lab > 0, iterations=3) if defects else np.zeros(shape, bool)
    deg = 1 if background in ("plane", "none") else 3
    bg = _Background(near & ~grown, deg, shape) if defects else None
    figs = _figures(lab, defects, z, bg) if defects else []

    # systematic parameters: one slope field each, integrated once
    sys_var = np.zeros(shape)
    slope_sys_p = np.zeros(shape)
    slope_sys_q = np.zeros(shape)
    dterms = [{"max_depth_mm": {}, "volume_mm3": {}} for _ in defects]
    for source, _name, u, dp, dq in slope_sensitivities(L, pp, qq, tol, E):
        dp = np.where(ok, dp, 0.0)
        dq = np.where(ok, dq, 0.0)
        slope_sys_p += (dp * u) ** 2
        slope_sys_q += (dq * u) ** 2
        zj = integrate(dp, dq, integrator, mask=ok, pixel_size=h)
        zj = np.nan_to_num(zj)
        sys_var += (zj * u) ** 2
        if figs:
            coef = bg.coef(zj)
            for i, fig in enumerate(figs):
                c_depth, c_vol = _systematic(fig, zj, coef, h)
                for figname, c in (("max_depth_mm", c_depth), ("volume_mm3", c_vol)):
                    acc = dterms[i][figname].setdefault(source, [0.0, u])
                    acc[0] += c * c
    t_sys = time.perf_counter() - t0

    noise_var = height_noise_variance(shape, mean_vp, mean_vq, h) if sigma > 0 else np.zeros(shape)
    zc = np.where(near, z - (z[near].mean() if near.any() else 0.0), 0.0)
    height_var = sys_var + noise_var + (tol.pixel_size_tolerance * zc) ** 2
    height_u = np.where(near, np.sqrt(height_var), np.nan).astype(np.float32)
    p_u = np.where(ok, np.sqrt(var_p + slope_sys_p), 0.0).astype(np.float32)
    q_u = np.where(ok, np.sqrt(var_q + slope_sys_q), 0.0).astype(np.float32)

    rng = np.random.default_rng(tol.seed)
    depth_map = None
    if figs:
        coef0 = bg.coef(np.nan_to_num(z))
        rows, cols = np.indices(shape)
        depth_map = np.nan_to_num(z) - (bg.design(rows.ravel(), cols.ravel()) @ coef0).reshape(shape)

    mc = None
    if tol.method == "montecarlo":
        if resolve is None or images is None:
            raise ValueError("method: 'montecarlo' needs the images and the solver (use the pipeline)")
        mc = _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng)
        p_u, q_u, height_u = mc["p_u"], mc["q_u"], mc["height_u"]

    out_defects = []
    for i, (rec, fig) in enumerate(zip(defects, figs)):
        terms: dict = {f: {} for f in FIGURES}
        if mc is None:
            for figname in ("max_depth_mm", "volume_mm3"):
                for source, (c2, u) in dterms[i][figname].items():
                    terms[figname][source] = _entry(u, math.sqrt(c2))
            if sigma > 0:
                w_depth, w_vol = _noise_weights(fig, bg, h)
                vd = linear_variance(w_depth, mean_vp, mean_vq, h)
                vv = linear_variance(w_vol, mean_vp, mean_vq, h)
                terms["max_depth_mm"]["image_noise"] = _entry(sigma, math.sqrt(vd) / sigma)
                terms["volume_mm3"]["image_noise"] = _entry(sigma, math.sqrt(vv) / sigma)
        else:
            for figname, spread in mc["defects"][i].items():
                terms[figname]["montecarlo"] = _entry(spread, 1.0)
        if tol.pixel_size_tolerance > 0:
            for figname in FIGURES:
                terms[figname]["pixel_size"] = _entry(tol.pixel_size_tolerance, _H_POWER[figname] * rec[figname])
        for figname, (spread, bias) in _quantisation(rec, h, rng).items():
            terms[figname]["discretisation"] = _entry(spread, 1.0)
            others = math.sqrt(sum(e["contribution"] ** 2 for e in terms[figname].values()))
            terms[figname]["method_bias"] = _entry(_bias_term(others, bias), 1.0)
        terms["max_depth_mm"]["discretisation"] = _entry(
            _depth_sampling(fig.sign * depth_map, fig.peak, lab == rec["id"] + 1), 1.0)
        budget, expanded = _budget(rec, terms)
        out_defects.append({"id": rec["id"], "uncertainty_k2": expanded, "budget": budget})

    summary = {
        "method": tol.method,
        "tolerances": tol.to_dict(),
        "noise_sigma": float(sigma),
        "noise_sigma_source": sigma_source,
        "coverage_factor": COVERAGE_FACTOR,
        "median_p_u": float(np.median(p_u[ok])) if ok.any() else 0.0,
        "median_q_u": float(np.median(q_u[ok])) if ok.any() else 0.0,
        "median_height_u_mm": float(np.nanmedian(height_u[near])) if near.any() else 0.0,
        "timings_s": {"systematic": round(t_sys, 4), "total": round(time.perf_counter() - t0, 4)},
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


def _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng) -> dict:
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
        Lm = _perturbed_lights(L, u_dir, rng) if u_dir > 0 else L
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
