"""The budget's vocabulary: sources, figures, the tolerances, the result and how a value
with its expanded uncertainty is written (GUM, k = 2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from surfaces.validate import InputError, positive

#: ``method`` choices.
METHODS = ("linear", "montecarlo")


#: Budget sources, in the order of ``uncertainty.json``.
SOURCES = ("image_noise", "light_direction", "light_position", "light_intensity", "montecarlo", "pixel_size",
           "discretisation", "method_bias")


#: Defect figures that get an uncertainty.
FIGURES = ("max_depth_mm", "mean_width_mm", "length_mm", "area_mm2", "volume_mm3")


#: Coverage factor of the expanded uncertainty (about 95 %).
COVERAGE_FACTOR = 2.0
#: Monte Carlo work allowed before any is done: samples x image pixels (1e10 is 200 samples of a 50 MP
#: image, about an hour of solves on one core); :func:`check_monte_carlo_size` refuses more
MC_PIXEL_SAMPLES_LIMIT = 1e10


def check_monte_carlo_size(tolerances, shape, name: str = "--mc-samples") -> None:
    """Refuse Monte Carlo work above :data:`MC_PIXEL_SAMPLES_LIMIT` before any of it is done.

    Parameters
    ----------
    tolerances : Tolerances
        Its ``method`` and ``mc_samples`` (only ``montecarlo`` is checked).
    shape : (H, W)
        Image size, pixels.
    name : str
        The option, for the message.

    Raises
    ------
    InputError
        Naming the size: samples x H x W pixel solves and the largest sample count allowed.

    Examples
    --------
    >>> check_monte_carlo_size(Tolerances(method="montecarlo", mc_samples=100), (1944, 2592))
    >>> check_monte_carlo_size(Tolerances(method="montecarlo", mc_samples=10**8), (224, 224))
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: --mc-samples 100000000: 100000000 samples x 224 x 224 px = 5.02e+12 pixel \
solves, above the limit of 1e+10; give at most 199298 samples
    """
    if tolerances is None or tolerances.method != "montecarlo":
        return
    h, w = int(shape[0]), int(shape[1])
    n = int(tolerances.mc_samples)
    work = float(n) * h * w
    if work > MC_PIXEL_SAMPLES_LIMIT:
        raise InputError(f"{name} {n}: {n} samples x {h} x {w} px = {work:.3g} pixel solves, above the limit of "
                         f"{MC_PIXEL_SAMPLES_LIMIT:.0e}; give at most {int(MC_PIXEL_SAMPLES_LIMIT // (h * w))} samples")


#: Powers of the pixel size in each figure (heights scale with ``h`` like lengths).
_H_POWER = {"max_depth_mm": 1, "mean_width_mm": 1, "length_mm": 1, "area_mm2": 2, "volume_mm3": 3}


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
    blur_px : float
        Gaussian standard deviation of the images' optical blur, pixels (the lens's point
        spread; the pixel's own area is ``pixel_area``). Narrow grooves read
        shallower, wider and longer under blur; the depth's grid model blurs the groove's
        slopes by it, and the outline's budget states the footprint's widening as a bias.
        0: no optical blur.
    pixel_area : bool
        Whether each pixel integrates the light over its area (a camera; a render with several
        samples per pixel, as Mitsuba's) rather than sampling its centre (our renderer): the
        footprint reads about a pixel wider and longer and narrow grooves shallower; the groove
        model then averages its slopes over each pixel and the outline's budget states the
        widening (as with ``blur_px``).
    """

    noise_sigma: float | None = None
    light_tolerance_deg: float = 0.0
    light_position_tolerance_mm: float = 0.0
    intensity_tolerance: float = 0.0
    pixel_size_tolerance: float = 0.0
    method: str = "linear"
    mc_samples: int = 50
    seed: int = 0
    blur_px: float = 0.0
    pixel_area: bool = False

    def __post_init__(self):
        if self.noise_sigma is not None:
            positive(self.noise_sigma, "noise_sigma", allow_zero=True)
        for name in ("light_tolerance_deg", "light_position_tolerance_mm", "intensity_tolerance",
                     "pixel_size_tolerance", "blur_px"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name}: must be a non-negative number (a standard uncertainty), got {value}")
        if not isinstance(self.pixel_area, (bool, np.bool_)):
            raise InputError(f"pixel_area: expected true or false, got {self.pixel_area!r}")
        if self.method not in METHODS:
            raise InputError(f"method: expected one of {METHODS}, got {self.method!r}")
        if int(self.mc_samples) < 2:
            raise InputError(f"mc_samples: need at least 2 Monte Carlo samples, got {self.mc_samples}")

    def to_dict(self) -> dict:
        """The tolerances as a JSON-ready dict."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


@dataclass(frozen=True)
class UncertaintyResult:
    """What :func:`photometric.uncertainty.propagate` returns.

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
        Method, tolerances, the noise sigma used and where it came from, timings (s),
        the median ``p_u``, ``q_u``, ``height_u`` and ``pixel_size_mm``, the pixel spacing
        the budget used (a perspective camera: the median footprint's side at the part).
        JSON-ready.
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
