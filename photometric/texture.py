"""Areal surface texture (ISO 25178-2) of a measured height map, with its uncertainty.

A height map in mm with its valid pixels goes through the ISO 25178 chain of operators:

1. **F-operator** (:func:`remove_form`): the least-squares plane, or a polynomial of a
   stated degree, over the valid pixels, is subtracted (the primary surface).
2. **S-filter** (:func:`gaussian_filter`, low pass, nesting index ``lambda_s``) removes
   the shortest wavelengths, **L-filter** (same Gaussian, nesting index ``lambda_c``)
   gives the mean line; the S-L surface is the S-filtered surface minus that mean line.
   Both are the Gaussian of ISO 16610-61, weighting function
   ``s(x, y) = exp(-pi (r / (alpha lambda))^2) / (alpha lambda)^2`` with
   ``alpha = sqrt(ln 2 / pi)``: a sinusoid of wavelength ``lambda`` passes the low pass
   at 50 %. They run as FFT convolutions (``scipy.fft``, all cores) with **normalised
   convolution** at the edges of the field and of masked regions: the masked height and
   the mask are filtered alike and divided, so missing pixels carry no weight (the
   ISO 16610-28 "no end effect" idea). ``edge="drop"`` also leaves out a band of
   ``ceil(4 sigma_L)`` pixels (about 0.75 ``lambda_c``) along every edge.
3. **Parameters** (:func:`parameters`) of the S-L surface over its evaluation area, in
   micrometres: height (Sa, Sq, Sp, Sv, Sz, Ssk, Sku), hybrid (Sdq, Sdr), spatial (Sal,
   Str, from the autocorrelation with the threshold s = 0.2), material ratio (Smr(c),
   Sk, Spk, Svk, from the ISO 13565-2 equivalent straight line over 40 % of the material
   ratio curve) and volume (Vmp, Vmc, Vvc, Vvv with p = 10 %, q = 80 %).

The result states the wavelength band that was actually measured: from ``lambda_s``
(never below two pixels, the Nyquist wavelength) up to ``lambda_c`` (never above the
shorter side of the field). Heights integrated from photometric slopes lose amplitude
at short wavelengths in the integrator (:func:`integrator_transfer`, 95 % at 8 pixels
per wavelength for the DCT and least-squares integrators); with ``integrator=`` the
S-filter divides that transfer out. Keep ``lambda_s`` at 12 pixels or more on such
heights and leave out the integrator's boundary layer (``edge="drop"``): at 8 pixels
the residual reaches 1 % of Sq on anisotropic (ground) plates
(``benchmarks/bench_texture.py``).

Definitions follow ISO 25178-2:2021 and match surfalize (the peer of
``tests/photometric/test_texture.py``) where it is explicit: heights are taken about
their mean over the evaluation area; Sdq and Sdr use forward differences (Sdr averages
the two triangulations of each cell, ISO 25178-2 D.15); the autocorrelation is the
unbiased (overlap-normalised) linear estimate; the material ratio curve is sampled at
10 000 equal steps of material ratio. One stated difference: the autocorrelation is
evaluated for lags up to half the field in each direction (the unbiased estimate
beyond rests on fewer than half the pixels); a texture whose autocorrelation does
not decay to s within that window has no Str ("not determined").

Uncertainty (GUM, k = 2) is by Monte Carlo (:func:`texture` with a noise model):
noise realisations are added to the primary surface and the whole filter and
parameter chain is repeated (each repetition vectorised over the pixels; at most
:data:`MAX_MC_SAMPLES` repetitions). The noise is white per pixel (a standard
uncertainty map of the height, or one value), or the integral of white slope noise
(photometric stereo's ``p_u``, ``q_u``: the height error of an integrated gradient
is correlated, dominated by long wavelengths). Noise makes Sq and the other
amplitude parameters read high; the Monte Carlo mean shift estimates that bias, and
each parameter reports the value as measured, the bias, the corrected value and the
expanded uncertainty of each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

from surfaces.validate import InputError

#: alpha of the ISO 16610-61 Gaussian weighting function
ALPHA = math.sqrt(math.log(2.0) / math.pi)
#: ISO 25178-3 default threshold of the autocorrelation for Sal and Str
ACF_THRESHOLD = 0.2
#: samples of the material ratio curve (equal steps of material ratio, 0 ... 100 %)
MR_SAMPLES = 10_000
#: width of the ISO 13565-2 equivalent straight line, % of material ratio
EQUIVALENCE_WIDTH = 40.0
#: most Monte Carlo repetitions of the uncertainty
MAX_MC_SAMPLES = 400
#: default Monte Carlo repetitions
DEFAULT_MC_SAMPLES = 50

#: parameter name -> unit
UNITS: dict[str, str] = {
    "Sa": "um", "Sq": "um", "Sp": "um", "Sv": "um", "Sz": "um", "Ssk": "1", "Sku": "1",
    "Sdq": "1", "Sdr": "%", "Sal": "um", "Str": "1",
    "Smr": "%", "Sk": "um", "Spk": "um", "Svk": "um", "Smr1": "%", "Smr2": "%",
    "Vmp": "mL/m2", "Vmc": "mL/m2", "Vvc": "mL/m2", "Vvv": "mL/m2",
}

#: one line per parameter, for reports
MEANINGS: dict[str, str] = {
    "Sa": "arithmetic mean height (mean |z|)",
    "Sq": "root mean square height",
    "Sp": "maximum peak height",
    "Sv": "maximum pit depth",
    "Sz": "maximum height Sp + Sv",
    "Ssk": "skewness (mean z^3 / Sq^3)",
    "Sku": "kurtosis (mean z^4 / Sq^4)",
    "Sdq": "root mean square gradient",
    "Sdr": "developed interfacial area ratio",
    "Sal": "autocorrelation length (fastest decay to s = 0.2)",
    "Str": "texture aspect ratio (fastest / slowest decay length)",
    "Smr": "areal material ratio at height c",
    "Sk": "core height (equivalent straight line over 40 % of the material ratio curve)",
    "Spk": "reduced peak height",
    "Svk": "reduced dale height",
    "Smr1": "material ratio separating the peaks from the core",
    "Smr2": "material ratio separating the core from the dales",
    "Vmp": "peak material volume at p = 10 %",
    "Vmc": "core material volume between p = 10 % and q = 80 %",
    "Vvc": "core void volume between p = 10 % and q = 80 %",
    "Vvv": "dale void volume at q = 80 %",
}

FORMS = ("none", "plane", "poly2")
#: parameters that grow with added noise as a root of summed variances (bias-corrected in their squares)
QUADRATIC = ("Sa", "Sq", "Sdq")


@dataclass(frozen=True)
class Texture:
    """Areal texture parameters of one height map.

    Attributes
    ----------
    values : dict of str to float
        Every parameter as measured (units in :data:`UNITS`); NaN when it cannot be
        determined (see ``notes``).
    surface : (H, W) float64 array
        The S-L surface in micrometres, NaN outside the evaluation area.
    area : (H, W) bool array
        The evaluation area.
    band : dict
        The wavelengths measured: ``short_mm``, ``long_mm``, ``pixel_size_mm``,
        ``field_mm`` (shorter side of the field).
    filters : dict
        ``s_filter_mm``, ``l_filter_mm`` (None when not applied), ``kind``, ``alpha``,
        ``edge``, ``edge_band_px``.
    form : str
        F-operator: ``"none"``, ``"plane"`` or ``"poly2"``.
    smr_c_um : float
        Height c of Smr(c), micrometres above the mean plane of the S-L surface.
    notes : dict of str to str
        Why a parameter is NaN or how to read it.
    uncertainty : dict, optional
        Per parameter ``{"U", "bias", "corrected", "U_corrected", "sd"}`` and the
        noise model (``None`` without a noise model).
    """

    values: dict[str, float]
    surface: np.ndarray
    area: np.ndarray
    band: dict
    filters: dict
    form: str
    smr_c_um: float
    notes: dict[str, str] = field(default_factory=dict)
    uncertainty: dict | None = None

    def as_dict(self) -> dict:
        """JSON-ready summary: every parameter with value, U (k = 2), unit; band, filters, form.

        Returns
        -------
        dict
            ``{"parameters": {name: {"value", "U", "unit", ...}}, "band", "filters",
            "form", "evaluation_area_px", "notes", "uncertainty"}``.
        """
        unc = self.uncertainty or {}
        per = unc.get("parameters", {})
        params = {}
        for name, value in self.values.items():
            rec = {"value": _num(value), "U": None, "unit": UNITS[name], "meaning": MEANINGS[name]}
            if name in per:
                rec.update({k: _num(v) for k, v in per[name].items()})
            if name == "Smr":
                rec["c_um"] = self.smr_c_um
            if name in self.notes:
                rec["note"] = self.notes[name]
            params[name] = rec
        return {
            "standard": "ISO 25178-2:2021 (filters ISO 16610-61 Gaussian)",
            "parameters": params,
            "band": self.band,
            "filters": self.filters,
            "form": self.form,
            "evaluation_area_px": int(self.area.sum()),
            "notes": {k: v for k, v in self.notes.items() if k not in UNITS},
            "uncertainty": None if not unc else {k: v for k, v in unc.items() if k != "parameters"},
        }


def _num(v):
    """A float for JSON (None for NaN)."""
    v = float(v)
    return None if math.isnan(v) else v


# ------------------------------------------------------------------------------------------------ inputs
def _height_and_mask(height, mask) -> tuple[np.ndarray, np.ndarray]:
    z = np.asarray(height, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 8:
        raise InputError(f"height: expected a 2-D map of at least 8 x 8 pixels, got shape {z.shape}")
    ok = np.isfinite(z)
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != z.shape:
            raise InputError(f"mask: shape {m.shape} differs from the height's {z.shape}")
        ok &= m.astype(bool)
    if ok.sum() < 64:
        raise InputError(f"mask: only {int(ok.sum())} valid pixels; need at least 64")
    return z, ok


def _positive(value, name: str) -> float:
    if value is None:
        return None
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"{name}: must be a positive number of mm, got {value!r}")
    return v


# ------------------------------------------------------------------------------------------------ F-operator
def _form_degree(form) -> int:
    if isinstance(form, (int, np.integer)) and not isinstance(form, bool):
        if not 0 <= form <= 6:
            raise InputError(f"form: polynomial degree must be 0 ... 6, got {form}")
        return int(form)
    degrees = {"none": -1, "plane": 1, "poly2": 2}
    if form not in degrees:
        raise InputError(f"form: expected one of {', '.join(FORMS)} or a degree, got {form!r}")
    return degrees[form]


def remove_form(height, mask=None, form="plane") -> np.ndarray:
    """F-operator: subtract the least-squares polynomial of the valid pixels.

    Parameters
    ----------
    height : (H, W) array_like
        Heights (any unit; NaN pixels are invalid).
    mask : (H, W) array_like of bool, optional
        Valid pixels (default: the finite ones).
    form : {"plane", "poly2", "none"} or int
        The form: a plane, a second-degree polynomial, nothing, or a polynomial of
        this total degree in x and y.

    Returns
    -------
    (H, W) float64 array
        The height minus the form, NaN outside the valid pixels.

    Examples
    --------
    >>> y, x = np.mgrid[:16, :20]
    >>> r = remove_form(0.3 * x - 0.1 * y + 2.0)
    >>> bool(np.abs(r).max() < 1e-12)
    True
    """
    z, ok = _height_and_mask(height, mask)
    degree = _form_degree(form)
    out = np.where(ok, z, np.nan)
    if degree < 0:
        return out
    h, w = z.shape
    # normalised coordinates in [-1, 1] keep the normal equations well conditioned
    x = np.linspace(-1.0, 1.0, w)
    y = np.linspace(-1.0, 1.0, h)
    terms = [(a, t - a) for t in range(degree + 1) for a in range(t + 1)]
    # sums over valid pixels of x^a y^b, as (rows of the mask) @ x^a then . y^b: no (N, terms) design matrix
    xpow = np.stack([x**k for k in range(2 * degree + 1)], axis=1)
    ypow = np.stack([y**k for k in range(2 * degree + 1)], axis=1)
    if ok.all():
        mx = np.broadcast_to(xpow.sum(axis=0), (h, 2 * degree + 1))  # (H, 2d+1): per row, sum of m x^k
        zx = z @ xpow[:, : degree + 1]
    else:
        mx = ok.astype(np.float64) @ xpow
        zx = np.where(ok, z, 0.0) @ xpow[:, : degree + 1]
    gram = np.array([[ypow[:, b1 + b2] @ mx[:, a1 + a2] for (a2, b2) in terms] for (a1, b1) in terms])
    rhs = np.array([ypow[:, b] @ zx[:, a] for (a, b) in terms])
    coef = np.linalg.lstsq(gram, rhs, rcond=None)[0]
    cmat = np.zeros((degree + 1, degree + 1))
    for c, (a, b) in zip(coef, terms):
        cmat[b, a] = c
    out -= ypow[:, : degree + 1] @ cmat @ xpow[:, : degree + 1].T
    return out


# ------------------------------------------------------------------------------------------------ filters
def gaussian_sigma_px(cutoff_mm: float, pixel_size: float) -> float:
    """Standard deviation of the ISO 16610-61 Gaussian in pixels.

    Parameters
    ----------
    cutoff_mm : float
        Nesting index (cut-off wavelength), mm.
    pixel_size : float
        Pixel size, mm.

    Returns
    -------
    float
        ``alpha lambda / sqrt(2 pi) / pixel_size`` (``= lambda sqrt(ln 2 / 2) / pi``).

    Examples
    --------
    >>> round(gaussian_sigma_px(0.8, 0.01), 4)
    14.9913
    """
    return ALPHA * cutoff_mm / math.sqrt(2.0 * math.pi) / pixel_size


def _transfer(shape, pixel_size: float, cutoff_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """ISO 16610-61 Gaussian transfer exp(-pi (alpha lambda f)^2) on an rfft2 grid, as its two 1-D factors."""
    fy = sfft.fftfreq(shape[0], d=pixel_size)
    fx = sfft.rfftfreq(shape[1], d=pixel_size)
    a = math.pi * (ALPHA * cutoff_mm) ** 2
    return np.exp(-a * fy**2).astype(np.float32)[:, None], np.exp(-a * fx**2).astype(np.float32)[None, :]


class _Convolver:
    """FFT convolution of masked fields with Gaussians, zero padded against wrap-around."""

    def __init__(self, ok: np.ndarray, pixel_size: float, cutoffs):
        self.shape = ok.shape
        radius = max(math.ceil(5.0 * gaussian_sigma_px(c, pixel_size)) for c in cutoffs)
        self.pad = tuple(sfft.next_fast_len(n + min(radius, n), real=True) for n in ok.shape)
        self.pixel = pixel_size
        self.full = bool(ok.all())
        self.ok = ok
        self.m = None if self.full else ok.astype(np.float32)
        self._den: dict[float, np.ndarray] = {}
        self._T: dict[float, np.ndarray] = {}
        self._inverse: np.ndarray | None = None

    def inverse_integrator(self) -> np.ndarray:
        """1 / T of :func:`integrator_transfer` on the padded rfft2 grid (single precision)."""
        if self._inverse is None:
            wy = 2.0 * math.pi * sfft.fftfreq(self.pad[0])[:, None]
            wx = 2.0 * math.pi * sfft.rfftfreq(self.pad[1])[None, :]
            self._inverse = (1.0 / np.maximum(integrator_transfer(wx, wy), 1e-6)).astype(np.float32)
        return self._inverse

    def transfer(self, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
        if cutoff not in self._T:
            self._T[cutoff] = _transfer(self.pad, self.pixel, cutoff)
        return self._T[cutoff]

    def spectrum(self, z0: np.ndarray) -> np.ndarray:
        """rfft2 of a field that is zero outside the mask (single precision: 1e-7 of the texture's range)."""
        return sfft.rfft2(np.asarray(z0, dtype=np.float32), s=self.pad, workers=-1)

    def weight(self, cutoff: float) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """The filtered mask (the normaliser); two 1-D factors for a full rectangle."""
        if cutoff not in self._den:
            if self.full:
                # a full rectangle's filtered mask is separable: two 1-D convolutions
                a = math.pi * (ALPHA * cutoff) ** 2
                cols = []
                for n, p in zip(self.shape, self.pad):
                    t = np.exp(-a * sfft.rfftfreq(p, d=self.pixel) ** 2)
                    cols.append(sfft.irfft(sfft.rfft(np.ones(n), n=p) * t, n=p)[:n])
                self._den[cutoff] = (cols[0].astype(np.float32)[:, None], cols[1].astype(np.float32)[None, :])
            else:
                F = self.spectrum(self.m)
                ty, tx = self.transfer(cutoff)
                F *= ty
                F *= tx
                self._den[cutoff] = np.maximum(self.inverse(F), np.float32(1e-12))
        return self._den[cutoff]

    def inverse(self, F: np.ndarray) -> np.ndarray:
        h, w = self.shape
        return sfft.irfft2(F, s=self.pad, workers=-1)[:h, :w]

    def lowpass(self, z0: np.ndarray, cutoff: float, F: np.ndarray | None = None,
                deconvolve: bool = False) -> np.ndarray:
        """Normalised Gaussian low pass of ``z0`` (zero outside the mask); ``F`` (its spectrum) is overwritten.

        ``deconvolve`` also divides out the slope integrator's transfer (:func:`integrator_transfer`).
        """
        if F is None:
            F = self.spectrum(z0)
        ty, tx = self.transfer(cutoff)
        F *= ty
        F *= tx
        if deconvolve:
            F *= self.inverse_integrator()
        num = self.inverse(F)
        den = self.weight(cutoff)
        if isinstance(den, tuple):  # separable (full rectangle)
            num /= den[0]
            num /= den[1]
            return num
        num /= den
        return num


def integrator_transfer(wx, wy) -> np.ndarray:
    """Amplitude transfer of a discrete Poisson integration of sampled slopes (DCT / least squares).

    Photometric stereo measures the slopes at the pixel centres; the Simchony (DCT) and
    least-squares integrators take their divergence by central differences and invert the
    5-point Laplacian, so a sinusoid of angular frequency ``(wx, wy)`` (radians per pixel)
    comes back with the amplitude
    ``T = (wx sin wx + wy sin wy) / (4 sin^2(wx / 2) + 4 sin^2(wy / 2))``, which is
    ``(w / 2) / tan(w / 2)`` along an axis: 0.95 at 8 pixels per wavelength, 0.987 at 16.

    Parameters
    ----------
    wx, wy : array_like
        Angular frequencies, radians per pixel (broadcast together).

    Returns
    -------
    numpy.ndarray
        T (1 at zero frequency, 0 at the Nyquist frequency of an axis).

    Examples
    --------
    >>> round(float(integrator_transfer(2 * np.pi / 8, 0.0)), 4)
    0.9481
    """
    wx = np.asarray(wx, dtype=np.float64)
    wy = np.asarray(wy, dtype=np.float64)
    den = 4.0 * np.sin(wx / 2.0) ** 2 + 4.0 * np.sin(wy / 2.0) ** 2
    num = wx * np.sin(wx) + wy * np.sin(wy)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0)


#: slope integrators whose transfer :func:`integrator_transfer` describes (``"fc"``, spectral, passes all)
INTEGRATORS = ("dct", "lsq", "robust", "fc")


def gaussian_filter(height, pixel_size: float, cutoff_mm: float, mask=None) -> np.ndarray:
    """ISO 16610-61 areal Gaussian low pass with normalised convolution over the valid pixels.

    Parameters
    ----------
    height : (H, W) array_like
        Heights (any unit); NaN pixels are invalid.
    pixel_size : float
        Pixel size, mm.
    cutoff_mm : float
        Nesting index (cut-off wavelength), mm: a sinusoid of this wavelength keeps 50 %
        of its amplitude.
    mask : (H, W) array_like of bool, optional
        Valid pixels (default: the finite ones).

    Returns
    -------
    (H, W) float64 array
        The low-pass surface (the mean line of an L-filter), NaN outside the mask.

    Examples
    --------
    >>> x = np.arange(400) * 0.01
    >>> z = np.sin(2 * np.pi * x / 0.8)[None, :].repeat(8, 0)
    >>> lo = gaussian_filter(z, 0.01, 0.8)
    >>> round(float(np.abs(lo[:, 100:300]).max() / np.abs(z[:, 100:300]).max()), 2)
    0.5
    """
    z, ok = _height_and_mask(height, mask)
    pixel_size = _positive(pixel_size, "pixel_size")
    cutoff_mm = _positive(cutoff_mm, "cutoff_mm")
    conv = _Convolver(ok, pixel_size, [cutoff_mm])
    out = conv.lowpass(np.where(ok, z, 0.0), cutoff_mm)
    return np.where(ok, out, np.nan)


# ------------------------------------------------------------------------------------------------ parameters
def _height_params(v: np.ndarray) -> dict:
    v2 = v * v
    n = len(v)
    sq = math.sqrt(float(v2.sum()) / n)
    top, bottom = float(v.max()), float(v.min())
    return {
        "Sa": float(np.vdot(np.sign(v), v)) / n,
        "Sq": sq,
        "Sp": top,
        "Sv": -bottom,
        "Sz": top - bottom,
        "Ssk": float(np.dot(v2, v)) / n / sq**3 if sq > 0 else math.nan,
        "Sku": float(np.dot(v2, v2)) / n / sq**4 if sq > 0 else math.nan,
    }


def _excess_sum(s: np.ndarray, weight: np.ndarray | None) -> float:
    """Sum of sqrt(1 + s) - 1 (in place, without cancellation), optionally weighted by 0/1."""
    root = s + np.float32(1.0)
    np.sqrt(root, out=root)
    root += np.float32(1.0)
    s /= root
    return float(s.sum(dtype=np.float64)) if weight is None else float(np.vdot(s, weight))


def _hybrid(z: np.ndarray, area: np.ndarray, d: float, full: bool) -> dict:
    """Sdq (forward differences, each direction averaged over its own pairs) and Sdr (D.15)."""
    z32 = np.asarray(z, dtype=np.float32)
    gx = np.diff(z32, axis=1)
    gx *= np.float32(1.0 / d)
    gy = np.diff(z32, axis=0)
    gy *= np.float32(1.0 / d)
    gx *= gx
    gy *= gy
    weight = None
    if full:
        nx, ny = gx.size, gy.size
    else:
        okx = area[:, 1:] & area[:, :-1]
        oky = area[1:, :] & area[:-1, :]
        nx, ny = int(okx.sum()), int(oky.sum())
        if nx == 0 or ny == 0:
            return {"Sdq": math.nan, "Sdr": math.nan}
        gx[~okx] = 0.0
        gy[~oky] = 0.0
        cell = okx[1:, :] & okx[:-1, :] & oky[:, 1:] & oky[:, :-1]
        weight = cell.astype(np.float32)
    sdq = math.sqrt(float(gx.sum(dtype=np.float64)) / nx + float(gy.sum(dtype=np.float64)) / ny)
    cells = gx.shape[1] * gy.shape[0] if weight is None else int(cell.sum())
    if cells == 0:
        return {"Sdq": sdq, "Sdr": math.nan}
    # each corner triangle of a cell has half the area of the cross product of its x and y edges; the cell
    # is the mean of its two triangulations = half the sum of its four corner triangles (ISO 25178-2 D.15),
    # summed as the excess sqrt(1 + gx^2 + gy^2) - 1 over the projected area
    xb, xt = gx[:-1, :], gx[1:, :]
    yl, yr = gy[:, :-1], gy[:, 1:]
    total = sum(_excess_sum(a + b, weight) for a, b in ((xb, yl), (xb, yr), (xt, yr), (xt, yl)))
    return {"Sdq": sdq, "Sdr": 100.0 * 0.25 * total / cells}


def autocorrelation(surface, mask=None) -> tuple[np.ndarray, tuple[int, int]]:
    """Unbiased linear autocorrelation of a surface for lags up to half the field.

    Parameters
    ----------
    surface : (H, W) array_like
        Heights about their mean (any unit); NaN pixels are invalid.
    mask : (H, W) array_like of bool, optional
        Valid pixels (default: the finite ones).

    Returns
    -------
    acf : (2 (H // 2) + 1, 2 (W // 2) + 1) float32 array
        ``sum z(x) z(x + t) / (number of valid pairs at lag t)``, squared units (FFT in
        single precision); NaN at lags without valid pairs.
    center : (int, int)
        Index of lag zero.

    Examples
    --------
    >>> z = np.random.default_rng(0).standard_normal((32, 40))
    >>> acf, c = autocorrelation(z)
    >>> acf.shape, c, bool(np.isclose(acf[c], np.mean(z * z), rtol=1e-5))
    ((33, 41), (16, 20), True)
    """
    z, ok = _height_and_mask(surface, mask)
    return _acf(np.where(ok, z, 0.0), ok, bool(ok.all()))


def _acf(z0: np.ndarray, ok: np.ndarray, full: bool, divisor: int = 2) -> tuple[np.ndarray, tuple[int, int]]:
    h, w = z0.shape
    ly, lx = h // divisor, w // divisor
    # zero padding by the largest lag: no lag wraps around
    pad = (sfft.next_fast_len(h + ly, real=True), sfft.next_fast_len(w + lx, real=True))
    rows = np.r_[pad[0] - ly: pad[0], 0: ly + 1]
    cols = np.r_[pad[1] - lx: pad[1], 0: lx + 1]

    def corr(a):
        F = sfft.rfft2(np.asarray(a, dtype=np.float32), s=pad, workers=-1)
        F = F.real * F.real + F.imag * F.imag
        out = sfft.irfft2(F, s=pad, workers=-1)
        return out[rows][:, cols]

    num = corr(z0)
    if full:
        ty = np.arange(-ly, ly + 1)
        tx = np.arange(-lx, lx + 1)
        num /= (h - np.abs(ty)).astype(np.float32)[:, None]
        num /= (w - np.abs(tx)).astype(np.float32)[None, :]
        return num, (ly, lx)
    count = np.rint(corr(ok))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0.5, num / count, np.nan).astype(np.float32), (ly, lx)


def _region(above: np.ndarray, center) -> tuple[np.ndarray, tuple[int, int]]:
    """The connected region of ``above`` around ``center``, labelled in the smallest window that holds it."""
    half = [max(16, n // 16) for n in above.shape]
    while True:
        r0, r1 = max(center[0] - half[0], 0), min(center[0] + half[0] + 1, above.shape[0])
        c0, c1 = max(center[1] - half[1], 0), min(center[1] + half[1] + 1, above.shape[1])
        labels, _ = ndimage.label(above[r0:r1, c0:c1])
        region = labels == labels[center[0] - r0, center[1] - c0]
        whole = r0 == 0 and c0 == 0 and r1 == above.shape[0] and c1 == above.shape[1]
        inner_edge = ((r0 > 0 and region[0].any()) or (r1 < above.shape[0] and region[-1].any())
                      or (c0 > 0 and region[:, 0].any()) or (c1 < above.shape[1] and region[:, -1].any()))
        if whole or not inner_edge:
            return region, (r0, c0)
        half = [2 * x for x in half]


def _crossings(acf: np.ndarray, center, ends: np.ndarray, thr: float) -> np.ndarray:
    """Fraction t of each centre -> end ray where the cubic-spline ACF first falls to ``thr``."""
    c = np.asarray(center, dtype=np.float64)
    vec = ends - c

    def along(t0, t1, n):
        t = t0[:, None] + (t1 - t0)[:, None] * np.linspace(0.0, 1.0, n)[None, :]
        pts = c[None, None, :] + vec[:, None, :] * t[..., None]
        vals = ndimage.map_coordinates(acf, pts.reshape(-1, 2).T, order=3, mode="nearest").reshape(t.shape)
        return t, vals

    t, vals = along(np.zeros(len(ends)), np.ones(len(ends)), 64)
    below = vals < thr
    below[:, -1] = True
    j = np.maximum(np.argmax(below, axis=1), 1)
    r = np.arange(len(ends))
    t, vals = along(t[r, j - 1], t[r, j], 33)
    below = vals < thr
    below[:, -1] = True
    k = np.maximum(np.argmax(below, axis=1), 1)
    v0, v1 = vals[r, k - 1], vals[r, k]
    frac = np.clip((v0 - thr) / np.where(v0 != v1, v0 - v1, 1.0), 0.0, 1.0)
    return t[r, k - 1] + frac * (t[r, k] - t[r, k - 1])


def _spatial(z0: np.ndarray, area: np.ndarray, full: bool, d: float, s: float) -> tuple[dict, dict]:
    # the region above s: first within a quarter of the field (a smaller FFT), within half of it when it
    # (or the spline's margin around it) reaches that window's border
    margin = 12
    for divisor in (4, 2):
        acf, center = _acf(z0, area, full, divisor)
        thr = s * float(acf[center])
        above = acf > thr  # NaN lags (no valid pairs) are not above
        region, (w0, v0) = _region(above, center)
        sl = ndimage.find_objects(region.astype(np.int8))[0]
        inside = (w0 + sl[0].start > margin and v0 + sl[1].start > margin
                  and w0 + sl[0].stop < acf.shape[0] - margin and v0 + sl[1].stop < acf.shape[1] - margin)
        if inside:
            break
    notes = {}
    r0, r1 = max(w0 + sl[0].start - margin, 0), min(w0 + sl[0].stop + margin, acf.shape[0])
    c0, c1 = max(v0 + sl[1].start - margin, 0), min(v0 + sl[1].stop + margin, acf.shape[1])
    sub = np.zeros((r1 - r0, c1 - c0), bool)
    sub[w0 + sl[0].start - r0: w0 + sl[0].stop - r0, v0 + sl[1].start - c0: v0 + sl[1].stop - c0] = region[sl]
    edge = ndimage.binary_dilation(sub) & ~sub
    ends = np.argwhere(edge).astype(np.float64)
    if len(ends) == 0:
        notes["Sal"] = notes["Str"] = (f"not determined: the autocorrelation stays above s = {s} over every "
                                       "lag up to half the field")
        return {"Sal": math.nan, "Str": math.nan}, notes
    local = np.nan_to_num(acf[r0:r1, c0:c1].astype(np.float64), nan=0.0)
    cen = (center[0] - r0, center[1] - c0)
    t = _crossings(local, cen, ends, thr)
    lengths = t * np.hypot(ends[:, 0] - cen[0], ends[:, 1] - cen[1]) * d
    sal, slow = float(lengths.min()), float(lengths.max())
    top, left = w0 + sl[0].start, v0 + sl[1].start
    touches = top == 0 or left == 0 or w0 + sl[0].stop == acf.shape[0] or v0 + sl[1].stop == acf.shape[1]
    # lags without valid pairs (masked fields) bound the region like the window's border does
    touches = touches or bool(np.isnan(acf[r0:r1, c0:c1][edge]).any())
    if touches:
        notes["Str"] = (f"not determined: in some direction the autocorrelation does not decay to s = {s} "
                        "within half the field (slowest decay longer than the field allows)")
        return {"Sal": sal, "Str": math.nan}, notes
    return {"Sal": sal, "Str": sal / slow}, notes


def material_ratio_curve(values) -> tuple[np.ndarray, np.ndarray]:
    """The areal material ratio curve, sampled at :data:`MR_SAMPLES` equal steps of material ratio.

    Parameters
    ----------
    values : (N,) array_like
        Heights of the evaluation area (any unit).

    Returns
    -------
    mr : (MR_SAMPLES,) float64 array
        Material ratio, % (0 ... 100).
    height : (MR_SAMPLES,) float64 array
        Height c at which the material ratio is ``mr`` (the ``1 - mr / 100`` quantile,
        linear interpolation; decreasing).
    """
    v = np.sort(np.asarray(values, dtype=np.float64).ravel())
    mr = np.linspace(0.0, 100.0, MR_SAMPLES)
    pos = (1.0 - mr / 100.0) * (len(v) - 1)
    i = np.clip(np.floor(pos).astype(np.int64), 0, len(v) - 1)
    j = np.minimum(i + 1, len(v) - 1)
    return mr, v[i] + (pos - i) * (v[j] - v[i])


def _material(v: np.ndarray, c: float, p: float, q: float) -> dict:
    mr, hgt = material_ratio_curve(v)
    w = EQUIVALENCE_WIDTH
    # secant of every 40 % window; the central region is the flattest one (first on ties, ISO 13565-2)
    starts = mr[mr <= 100.0 - w]
    secant = (np.interp(starts + w, mr, hgt) - hgt[: len(starts)]) / w
    i0 = int(np.argmax(secant))
    i1 = int(np.searchsorted(mr, mr[i0] + w, side="right"))
    slope, intercept = np.polyfit(mr[i0:i1], hgt[i0:i1], 1)
    upper, lower = intercept, slope * 100.0 + intercept
    inc_h, inc_mr = hgt[::-1], mr[::-1]

    def smr(level: float) -> float:
        return float(np.interp(level, inc_h, inc_mr))

    def trap(y: np.ndarray, x: np.ndarray) -> float:
        return abs(float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))) if len(x) > 1 else 0.0

    def closest(level: float) -> int:
        return int(np.argmin(np.abs(hgt - level)))

    smr1, smr2 = smr(upper), smr(lower)
    a1 = trap(mr[: closest(upper)], hgt[: closest(upper)])
    a2 = trap(100.0 - mr[closest(lower):], hgt[closest(lower):])

    def vm(ratio):
        k = closest(float(np.interp(ratio, mr, hgt)))
        return trap(mr[:k], hgt[:k]) / 100.0

    def vv(ratio):
        k = closest(float(np.interp(ratio, mr, hgt)))
        return trap(100.0 - mr[k:], hgt[k:]) / 100.0

    return {
        "Smr": smr(c),
        "Sk": float(upper - lower),
        "Spk": 2.0 * a1 / smr1 if a1 > 0 else 0.0,
        "Svk": 2.0 * a2 / (100.0 - smr2) if a2 > 0 else 0.0,
        "Smr1": smr1,
        "Smr2": smr2,
        "Vmp": vm(p),
        "Vmc": vm(q) - vm(p),
        "Vvc": vv(p) - vv(q),
        "Vvv": vv(q),
    }


def parameters(surface, pixel_size: float, mask=None, *, smr_c_um: float = 0.0, acf_threshold: float = ACF_THRESHOLD,
               p: float = 10.0, q: float = 80.0) -> tuple[dict, dict]:
    """ISO 25178-2 parameters of an (already filtered) surface in micrometres.

    Parameters
    ----------
    surface : (H, W) array_like
        Heights in micrometres (the S-L or S-F surface); NaN pixels are outside the
        evaluation area.
    pixel_size : float
        Pixel size, mm.
    mask : (H, W) array_like of bool, optional
        Evaluation area (default: the finite pixels).
    smr_c_um : float
        Height c of Smr(c), micrometres above the mean of the evaluation area.
    acf_threshold : float
        s of Sal and Str (0 < s < 1; ISO 25178-3 default 0.2).
    p, q : float
        Material ratios of the volume parameters, % (defaults 10 and 80).

    Returns
    -------
    values : dict of str to float
        Every parameter of :data:`UNITS` (NaN where not determined).
    notes : dict of str to str
        Why a parameter is NaN.

    Examples
    --------
    >>> x = np.arange(200) * 0.001
    >>> z = 2.0 * np.sin(2 * np.pi * x / 0.05)[None, :].repeat(50, 0)
    >>> v, _ = parameters(z, 0.001)
    >>> round(v["Sq"], 6), round(v["Sku"], 6)
    (1.414214, 1.5)
    """
    z, ok = _height_and_mask(surface, mask)
    d = _positive(pixel_size, "pixel_size") * 1000.0  # um
    if not 0.0 < acf_threshold < 1.0:
        raise InputError(f"acf_threshold: must lie in (0, 1), got {acf_threshold}")
    if not 0.0 <= p < q <= 100.0:
        raise InputError(f"p, q: need 0 <= p < q <= 100 %, got p = {p}, q = {q}")
    return _parameters(np.where(ok, z, 0.0), ok, d, float(smr_c_um), acf_threshold, p, q)


def _parameters(z0: np.ndarray, ok: np.ndarray, d: float, c: float, s: float, p: float = 10.0,
                q: float = 80.0) -> tuple[dict, dict]:
    """Every parameter of a surface that is zero outside the evaluation area ``ok`` (d: pixel, um)."""
    full = bool(ok.all())
    if not full:
        # the bounding box of the evaluation area is the field (its size bounds the autocorrelation's lags)
        box = ndimage.find_objects(ok.astype(np.int8))[0]
        z0, ok = z0[box], ok[box]
        full = bool(ok.all())
    v = (z0.ravel() if full else z0[ok]).astype(np.float64)
    mean = float(v.mean())
    v = v - mean
    zc = np.where(ok, z0 - mean, 0.0) if not full else z0 - mean
    values = _height_params(v)
    values.update(_hybrid(zc, ok, d, full))
    spatial, notes = _spatial(zc, ok, full, d, s)
    values.update(spatial)
    values.update(_material(v, c, p, q))
    return {k: values[k] for k in UNITS}, notes


# ------------------------------------------------------------------------------------------------ the chain
@dataclass(frozen=True)
class _Chain:
    """Filter settings shared by the measurement and every Monte Carlo repetition."""

    ok: np.ndarray
    pixel: float
    s_mm: float | None
    l_mm: float | None
    area: np.ndarray
    conv: _Convolver | None
    deconvolve: bool = False


def _chain(ok, pixel, s_mm, l_mm, edge, deconvolve=False) -> tuple[_Chain, int]:
    cutoffs = [c for c in (s_mm, l_mm) if c is not None]
    conv = _Convolver(ok, pixel, cutoffs) if cutoffs else None
    area = ok
    band = 0
    if edge == "drop" and l_mm is not None:
        band = math.ceil(4.0 * gaussian_sigma_px(l_mm, pixel))
        padded = np.pad(ok, band, constant_values=False)
        area = ndimage.minimum_filter(padded, size=2 * band + 1)[band:-band, band:-band]
        if area.sum() < 64:
            raise InputError(f"edge: dropping a {band} px band along the edges leaves {int(area.sum())} pixels; "
                             "use a shorter L-filter, edge='normalised' or a larger field")
    return _Chain(ok, pixel, s_mm, l_mm, area, conv, deconvolve), band


def _filtered(chain: _Chain, primary_um: np.ndarray) -> np.ndarray:
    """S-L surface (um) of a primary surface that is zero outside the mask."""
    z = primary_um
    if chain.s_mm is not None:
        z = np.where(chain.ok, chain.conv.lowpass(z, chain.s_mm, deconvolve=chain.deconvolve), 0.0)
    if chain.l_mm is not None:
        z = np.where(chain.ok, z - chain.conv.lowpass(z, chain.l_mm), 0.0)
    return z


def texture(
    height,
    pixel_size: float,
    mask=None,
    *,
    s_filter_mm: float | None = None,
    l_filter_mm: float | None = None,
    form="plane",
    edge: str = "normalised",
    smr_c_um: float = 0.0,
    acf_threshold: float = ACF_THRESHOLD,
    integrator: str | None = None,
    height_u=None,
    slope_u=None,
    mc_samples: int = DEFAULT_MC_SAMPLES,
    seed: int | np.random.Generator = 0,
) -> Texture:
    """Areal texture of a height map: F-operator, S- and L-filter, every ISO 25178-2 parameter, U (k = 2).

    Parameters
    ----------
    height : (H, W) array_like
        Heights in mm (NaN pixels are invalid).
    pixel_size : float
        Pixel size, mm.
    mask : (H, W) array_like of bool, optional
        Valid pixels (default: the finite ones).
    s_filter_mm : float, optional
        S-filter nesting index lambda_s, mm (default: none; the band then starts at the
        Nyquist wavelength, two pixels).
    l_filter_mm : float, optional
        L-filter nesting index lambda_c, mm (default: none; the band then ends at the
        field size, after the form removal).
    form : {"plane", "poly2", "none"} or int
        F-operator (:func:`remove_form`).
    edge : {"normalised", "drop"}
        Edge handling: normalised convolution only, or also leave out a band of
        ``ceil(4 sigma_L)`` pixels along every edge of the valid region.
    smr_c_um : float
        Height c of Smr(c), micrometres above the mean plane.
    acf_threshold : float
        s of Sal and Str.
    integrator : {"dct", "lsq", "robust", "fc"}, optional
        The heights were integrated from sampled slopes with this integrator
        (:func:`photometric.integrate.integrate`): the S-filter also divides out its
        transfer :func:`integrator_transfer` (dct, lsq, robust; fc passes every
        wavelength), so that wavelengths down to the S-filter keep their amplitude.
        Needs an S-filter.
    height_u : float or (H, W) array_like, optional
        Standard uncertainty of each height, mm, taken as independent per pixel.
    slope_u : tuple of two float or (H, W) arrays, optional
        Standard uncertainties of the slopes ``p = dz/dx`` and ``q = dz/dy``
        (photometric stereo's ``p_u``, ``q_u``), independent per pixel; their height
        error is the integral (``photometric.integrate.integrate``, DCT).
    mc_samples : int
        Monte Carlo repetitions when a noise model is given (2 ... :data:`MAX_MC_SAMPLES`).
    seed : int or numpy.random.Generator
        Seed of the Monte Carlo noise.

    Returns
    -------
    Texture
        Values, the S-L surface, the evaluation area, band, filters, form, notes and,
        with a noise model, the uncertainty of every parameter.

    Examples
    --------
    >>> y, x = np.mgrid[:128, :128] * 0.005
    >>> z = 0.002 * np.sin(2 * np.pi * x / 0.08) + 0.01 * y
    >>> t = texture(z, 0.005, s_filter_mm=0.0025, l_filter_mm=0.25)
    >>> t.band["short_mm"], t.band["long_mm"]
    (0.01, 0.25)
    """
    z, ok = _height_and_mask(height, mask)
    pixel = _positive(pixel_size, "pixel_size")
    s_mm = _positive(s_filter_mm, "s_filter_mm")
    l_mm = _positive(l_filter_mm, "l_filter_mm")
    if s_mm is not None and l_mm is not None and not s_mm < l_mm:
        raise InputError(f"s_filter_mm: must be shorter than l_filter_mm ({s_mm} >= {l_mm})")
    if edge not in ("normalised", "drop"):
        raise InputError(f"edge: expected 'normalised' or 'drop', got {edge!r}")
    if integrator is not None and integrator not in INTEGRATORS:
        raise InputError(f"integrator: expected one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    deconvolve = integrator in ("dct", "lsq", "robust")
    if deconvolve and s_mm is None:
        raise InputError(f"integrator: correcting the {integrator} integrator's transfer needs an S-filter "
                         "(its inverse grows without bound towards two pixels per wavelength)")
    if not 0.0 < acf_threshold < 1.0:
        raise InputError(f"acf_threshold: must lie in (0, 1), got {acf_threshold}")
    form_name = form if isinstance(form, str) else f"poly{int(form)}"
    primary = np.where(ok, remove_form(z, ok, form) * 1000.0, 0.0)
    chain, band_px = _chain(ok, pixel, s_mm, l_mm, edge, deconvolve)
    sl = _filtered(chain, primary)
    values, notes = _parameters(sl if chain.area is ok else np.where(chain.area, sl, 0.0), chain.area,
                                pixel * 1000.0, float(smr_c_um), acf_threshold)
    field_mm = min(z.shape) * pixel
    short = max(s_mm or 0.0, 2.0 * pixel)
    band = {"short_mm": short, "long_mm": min(l_mm, field_mm) if l_mm is not None else field_mm,
            "pixel_size_mm": pixel, "field_mm": field_mm,
            "short_limit": "S-filter" if s_mm is not None and s_mm >= 2.0 * pixel else "Nyquist (2 pixels)",
            "long_limit": "L-filter" if l_mm is not None and l_mm <= field_mm else "field size"}
    if s_mm is not None and s_mm < 2.0 * pixel:
        notes["band"] = f"S-filter {s_mm} mm is shorter than two pixels; the pixel pitch bounds the band"
    filters = {"kind": "Gaussian ISO 16610-61", "alpha": ALPHA, "s_filter_mm": s_mm, "l_filter_mm": l_mm,
               "edge": edge, "edge_band_px": band_px, "convolution": "FFT, normalised over the valid pixels",
               "integrator_transfer": ("divided out (" + integrator + ")") if deconvolve else "not corrected"}
    unc = None
    if height_u is not None or slope_u is not None:
        unc = _monte_carlo(chain, primary, values, z.shape, pixel, height_u, slope_u, mc_samples, seed,
                           smr_c_um, acf_threshold)
    surface = np.where(chain.area, sl, np.nan).astype(np.float64)
    return Texture(values=values, surface=surface, area=chain.area, band=band, filters=filters, form=form_name,
                   smr_c_um=float(smr_c_um), notes=notes, uncertainty=unc)


# ------------------------------------------------------------------------------------------------ uncertainty
def _field(value, shape, name: str) -> np.ndarray:
    """One value or an (H, W) map of standard uncertainties."""
    try:
        return np.broadcast_to(np.asarray(value, dtype=np.float64), shape)
    except (ValueError, TypeError):
        raise InputError(f"{name}: expected one value or a map of shape {shape}, got "
                         f"{np.shape(value)}") from None


def _noise_model(shape, ok, pixel, height_u, slope_u):
    """A function rng -> one noise field in um (zero outside the mask), and its description."""
    if height_u is not None:
        u = _field(height_u, shape, "height_u")
        if not np.all(np.isfinite(u[ok])) or np.any(u[ok] < 0):
            raise InputError("height_u: standard uncertainties must be finite and >= 0 on the valid pixels")
        u_um = np.where(ok, u, 0.0) * 1000.0

        def white(rng):
            return u_um * rng.standard_normal(shape)

        return white, {"model": "white height noise (independent per pixel)",
                       "median_u_um": float(np.median(u_um[ok]))}
    from photometric.integrate import integrate

    if len(slope_u) != 2:
        raise InputError("slope_u: expected (p_u, q_u)")
    pu, qu = (_field(a, shape, "slope_u") for a in slope_u)
    for name, a in (("p_u", pu), ("q_u", qu)):
        if not np.all(np.isfinite(a[ok])) or np.any(a[ok] < 0):
            raise InputError(f"slope_u: {name} must be finite and >= 0 on the valid pixels")
    pu, qu = np.where(ok, pu, 0.0), np.where(ok, qu, 0.0)

    def slopes(rng):
        dp = pu * rng.standard_normal(shape)
        dq = qu * rng.standard_normal(shape)
        e = integrate(dp, dq, "dct" if ok.all() else "lsq", mask=None if ok.all() else ok, pixel_size=pixel)
        return np.where(ok, np.nan_to_num(e), 0.0) * 1000.0

    return slopes, {"model": "integrated white slope noise (p_u, q_u; DCT/least-squares integral)",
                    "median_p_u": float(np.median(pu[ok])), "median_q_u": float(np.median(qu[ok]))}


def _monte_carlo(chain, primary, values, shape, pixel, height_u, slope_u, n, seed, smr_c_um, s) -> dict:
    n = int(n)
    if not 2 <= n <= MAX_MC_SAMPLES:
        raise InputError(f"mc_samples: need 2 ... {MAX_MC_SAMPLES} repetitions, got {n}")
    draw, model = _noise_model(shape, chain.ok, pixel, height_u, slope_u)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    names = list(values)
    out = np.empty((n, len(names)))
    for k in range(n):
        sl = _filtered(chain, primary + draw(rng))
        vals, _ = _parameters(np.where(chain.area, sl, 0.0), chain.area, pixel * 1000.0, float(smr_c_um), s)
        out[k] = [vals[name] for name in names]
    per = {}
    for j, name in enumerate(names):
        col = out[:, j]
        col = col[np.isfinite(col)]
        v = values[name]
        if len(col) < 2 or not math.isfinite(v):
            per[name] = {"U": math.nan, "bias": math.nan, "corrected": math.nan, "U_corrected": math.nan,
                         "sd": math.nan}
            continue
        sd = float(np.std(col, ddof=1))
        # adding noise to the measured surface shifts the parameter as the measurement noise shifted the
        # true surface's: the mean shift is the noise bias; the value as measured carries it, the corrected
        # value carries the uncertainty of its estimate (sd / sqrt(n)). Noise adds variance, so the
        # root-mean-square parameters are corrected in their squares (additive), the others linearly.
        if name in QUADRATIC:
            shift = float(np.mean(col * col)) - v * v
            corrected = math.sqrt(max(v * v - shift, 0.0))
        else:
            corrected = 2.0 * v - float(np.mean(col))
        bias = v - corrected
        per[name] = {"U": 2.0 * math.hypot(sd, bias), "bias": bias, "corrected": corrected,
                     "U_corrected": 2.0 * sd * math.sqrt(1.0 + 1.0 / len(col)), "sd": sd}
    return {"method": "Monte Carlo", "samples": n, "k": 2, **model, "parameters": per}
