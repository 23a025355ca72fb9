"""Quality figures of a photometric measurement: does the result deserve trust? (issue 32, item 1)

A reconstruction can look converged and still be wrong: on a glossy part the
Lambertian solve bends a flat background by tens of micrometres and hides a
scratch, while every number it reports looks fine. These figures measure what
the model promised, on arrays only (no pipeline state), so that any stage can
compute them:

* **background flatness**: RMS of the height minus a robust background (the
  plane or polynomial of :func:`photometric.defects.fit_background`) over the
  valid pixels outside the defects, mm;
* **Lambertian residual per light**: RMS of ``observed - albedo max(0, s_k . n)``
  over the valid pixels, relative to the mean observed value of that image: how
  far the images are from the model the normals were solved with (gloss, cast
  shadows, wrong LED positions all raise it);
* **slope bias**: mean ``p, q`` over the background minus a reference part's, in
  mrad (a flat reference measured on the same rig gives the expected values);
* **invalid fraction**: pixels of the mask without a trusted normal.

:class:`QualityLimits` holds stated defaults; :func:`check` lists the limits a
measurement fails, with reasons. Per-image dark and saturated fractions and the
exposure belong to :mod:`photometric.frames`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from photometric.defects import fit_background
from photometric.options import BACKGROUND
from surfaces.validate import InputError, as_array, positive

__all__ = [
    "QualityFigures",
    "QualityLimits",
    "background_flatness",
    "check",
    "invalid_fraction",
    "lambertian_residual",
    "mean_slopes",
    "quality_figures",
    "quality_report",
    "reference_limits",
    "slope_bias",
]


def _mask(value, name: str, shape) -> np.ndarray:
    return np.ones(shape, bool) if value is None else as_array(value, name, shape=shape, dtype=bool)


def background_flatness(height, valid=None, exclude=None, method: str = "plane", *, degree: int = 3,
                        xy=None) -> float:
    """RMS of the height about its robust background over the non-defect pixels, mm.

    Parameters
    ----------
    height : (H, W) array_like
        Height in mm (NaN where not measured).
    valid : (H, W) bool array_like, optional
        Pixels with a trusted height (default: the finite ones).
    exclude : (H, W) bool array_like, optional
        Pixels that are not background (the defects found, or a known defect footprint).
    method : {"plane", "smooth"}
        Background model (:func:`photometric.defects.fit_background`): a plane, or a
        polynomial of total degree ``degree``.
    degree : int
        Degree of the smooth background.
    xy : (H, W, 2) array_like, optional
        ``x, y`` (mm) of each pixel's point (perspective camera).

    Returns
    -------
    float
        ``sqrt(mean((height - background)^2))`` over ``valid & ~exclude`` (finite), mm;
        NaN when fewer than 10 pixels remain.

    Examples
    --------
    >>> z = np.add.outer(np.arange(20.0), np.arange(30.0)) * 1e-3  # a tilted plane
    >>> round(background_flatness(z), 12)
    0.0
    >>> z[::2] += 2e-3  # every other row 2 um higher: +-1 um about the fitted plane
    >>> round(background_flatness(z), 4)
    0.001
    """
    z = as_array(height, "height", ndim=2, finite=False)
    use = _mask(valid, "valid", z.shape) & np.isfinite(z)
    if exclude is not None:
        use &= ~_mask(exclude, "exclude", z.shape)
    if np.count_nonzero(use) < 10:
        return float("nan")
    background, _ = fit_background(z, use, method, degree=degree, xy=xy)
    r = (z - background)[use]
    return float(np.sqrt(np.mean(r * r)))


def lambertian_residual(images, albedo, normals, light_vectors, valid=None, usable=None) -> np.ndarray:
    """Relative RMS of each image about the Lambertian prediction of the solved normals and albedo.

    The prediction of image ``k`` is ``albedo max(0, s_k . n)`` with the scaled light
    vectors ``s_k`` the solve used (far field: ``e_k l_k``; near field:
    :func:`photometric.leds.light_field` at the reconstructed points, times any
    flat-field gain), in the units of the images.

    Parameters
    ----------
    images : (N, H, W) array_like
        Observed grey images.
    albedo : (H, W) array_like
        Solved albedo.
    normals : (H, W, 3) array_like
        Solved unit normals.
    light_vectors : (N, 3) or (N, H, W, 3) array_like
        Scaled light vectors per image (the same everywhere, or per pixel).
    valid : (H, W) bool array_like, optional
        Pixels with a solved normal (default: all).
    usable : (N, H, W) bool array_like, optional
        Observations to judge (e.g. not saturated and not black, :mod:`photometric.frames`);
        default: all of the valid pixels.

    Returns
    -------
    (N,) float64 array
        ``sqrt(mean((I_k - prediction_k)^2)) / mean(I_k)`` over the valid, usable pixels
        of image ``k``; NaN for an image without such pixels or without light.

    Examples
    --------
    >>> n = np.zeros((4, 4, 3)); n[..., 2] = 1.0
    >>> s = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    >>> images = np.stack([np.full((4, 4), 0.5), np.full((4, 4), 0.44)])
    >>> lambertian_residual(images, np.full((4, 4), 0.5), n, s).round(4).tolist()
    [0.0, 0.0909]
    """
    imgs = as_array(images, "images", ndim=3)
    n_img, h, w = imgs.shape
    rho = as_array(albedo, "albedo", shape=(h, w))
    nrm = as_array(normals, "normals", shape=(h, w, 3))
    s = as_array(light_vectors, "light_vectors")
    if s.shape not in ((n_img, 3), (n_img, h, w, 3)):
        raise InputError(f"light_vectors: expected ({n_img}, 3) or ({n_img}, {h}, {w}, 3), got {s.shape}")
    ok = _mask(valid, "valid", (h, w))
    use = np.broadcast_to(ok, imgs.shape)
    if usable is not None:
        use = use & as_array(usable, "usable", shape=imgs.shape, dtype=bool)
    out = np.full(n_img, np.nan)
    for k in range(n_img):
        sk = s[k] if s.ndim == 4 else s[k][None, None, :]
        shade = np.maximum(0.0, np.einsum("...i,...i->...", nrm, sk))
        m = use[k]
        if not m.any():
            continue
        obs = imgs[k][m]
        mean = float(obs.mean())
        if mean <= 0:
            continue
        r = obs - (rho * shade)[m]
        out[k] = float(np.sqrt(np.mean(r * r))) / mean
    return out


def mean_slopes(p, q, valid=None, exclude=None) -> tuple[float, float]:
    """Mean slopes ``p = dz/dx``, ``q = dz/dy`` (y up) over the background pixels.

    Parameters
    ----------
    p, q : (H, W) array_like
        Slopes.
    valid : (H, W) bool array_like, optional
        Pixels with a trusted normal (default: the finite ones).
    exclude : (H, W) bool array_like, optional
        Pixels that are not background (the defects).

    Returns
    -------
    (float, float)
        Means of ``p`` and ``q`` (NaN without a background pixel).
    """
    pp = as_array(p, "p", ndim=2, finite=False)
    qq = as_array(q, "q", shape=pp.shape, finite=False)
    use = _mask(valid, "valid", pp.shape) & np.isfinite(pp) & np.isfinite(qq)
    if exclude is not None:
        use &= ~_mask(exclude, "exclude", pp.shape)
    if not use.any():
        return float("nan"), float("nan")
    return float(pp[use].mean()), float(qq[use].mean())


def slope_bias(p, q, valid=None, exclude=None, reference=(0.0, 0.0)) -> tuple[float, float, float]:
    """Mean background slope against a reference part's, in mrad.

    Parameters
    ----------
    p, q, valid, exclude
        See :func:`mean_slopes`.
    reference : (float, float)
        The reference part's mean slopes (:func:`mean_slopes` of a flat reference on the
        same rig), or ``(0, 0)`` for a part known to lie level.

    Returns
    -------
    (float, float, float)
        Bias along x and y and its magnitude, mrad (``1e3 * (atan(p) - atan(p_ref))``, ...).

    Examples
    --------
    >>> p = np.full((8, 8), 0.011); q = np.zeros((8, 8))
    >>> [round(v, 3) for v in slope_bias(p, q, reference=(0.001, 0.0))]
    [10.0, 0.0, 10.0]
    """
    ref = as_array(reference, "reference", shape=(2,))
    mp, mq = mean_slopes(p, q, valid, exclude)
    bx = 1e3 * (np.arctan(mp) - np.arctan(ref[0]))
    by = 1e3 * (np.arctan(mq) - np.arctan(ref[1]))
    return float(bx), float(by), float(np.hypot(bx, by))


def invalid_fraction(valid, mask=None) -> float:
    """Fraction of the mask's pixels without a trusted normal.

    Parameters
    ----------
    valid : (H, W) bool array_like
        Pixels with a trusted normal.
    mask : (H, W) bool array_like, optional
        The object mask (default: every pixel).

    Returns
    -------
    float
        In [0, 1] (1 for an empty mask: nothing was measured).

    Examples
    --------
    >>> invalid_fraction(np.array([[True, False], [True, True]]))
    0.25
    """
    v = as_array(valid, "valid", ndim=2, dtype=bool)
    m = _mask(mask, "mask", v.shape)
    total = int(np.count_nonzero(m))
    return 1.0 if total == 0 else 1.0 - int(np.count_nonzero(v & m)) / total


@dataclass(frozen=True)
class QualityFigures:
    """The quality figures of one measurement (see the module docstring).

    Attributes
    ----------
    background_rms_mm : float
        :func:`background_flatness`, mm (NaN: not measured).
    background_model : str
        ``"plane"`` or ``"smooth"``.
    lambertian_residual : tuple of float
        :func:`lambertian_residual` per light (relative); empty when not measured.
    slope_bias_mrad : tuple of float or None
        :func:`slope_bias` ``(x, y, magnitude)``; None without a reference.
    invalid_fraction : float
        :func:`invalid_fraction`.
    """

    background_rms_mm: float
    background_model: str
    lambertian_residual: tuple = ()
    slope_bias_mrad: tuple | None = None
    invalid_fraction: float = 0.0

    @property
    def worst_lambertian_residual(self) -> float:
        """The largest per-light residual (NaN when none was measured)."""
        r = np.asarray(self.lambertian_residual, float)
        return float(np.nanmax(r)) if r.size and np.isfinite(r).any() else float("nan")

    def as_dict(self) -> dict:
        """JSON-ready figures (NaN becomes None: not measured)."""
        def clean(v):
            if isinstance(v, (tuple, list)):
                return [clean(x) for x in v]
            if isinstance(v, float) and not np.isfinite(v):
                return None
            return v

        out = {k: clean(v) for k, v in asdict(self).items()}
        out["worst_lambertian_residual"] = clean(self.worst_lambertian_residual)
        return out


def quality_figures(height, valid, *, p=None, q=None, exclude=None, mask=None, background: str = BACKGROUND,
                    xy=None, images=None, albedo=None, normals=None, light_vectors=None, usable=None,
                    reference_slopes=None) -> QualityFigures:
    """Every quality figure the inputs allow (see the module docstring).

    Parameters
    ----------
    height : (H, W) array_like
        Height in mm.
    valid : (H, W) bool array_like
        Pixels with a trusted normal and height.
    p, q : (H, W) array_like, optional
        Slopes, for the slope bias (with ``reference_slopes``).
    exclude : (H, W) bool array_like, optional
        Defect pixels (left out of the background figures).
    mask : (H, W) bool array_like, optional
        Object mask of the invalid fraction.
    background : {"plane", "smooth"}
        Background model of the flatness.
    xy : (H, W, 2) array_like, optional
        Pixel points in mm (perspective camera).
    images, albedo, normals, light_vectors, usable : optional
        For the Lambertian residual (all four of the first are needed); see
        :func:`lambertian_residual`.
    reference_slopes : (float, float), optional
        A reference part's mean slopes (:func:`mean_slopes`); without it no slope bias.

    Returns
    -------
    QualityFigures
    """
    rms = background_flatness(height, valid, exclude, background, xy=xy)
    resid = ()
    if images is not None:
        if albedo is None or normals is None or light_vectors is None:
            raise InputError("images: the Lambertian residual also needs albedo, normals and light_vectors")
        resid = tuple(float(v) for v in lambertian_residual(images, albedo, normals, light_vectors, valid, usable))
    bias = None
    if reference_slopes is not None:
        if p is None or q is None:
            raise InputError("reference_slopes: the slope bias needs p and q")
        bias = slope_bias(p, q, valid, exclude, reference_slopes)
    return QualityFigures(background_rms_mm=rms, background_model=background, lambertian_residual=resid,
                          slope_bias_mrad=bias, invalid_fraction=invalid_fraction(valid, mask))


@dataclass(frozen=True)
class QualityLimits:
    """Limits a measurement must meet to be trusted; defaults stated for a machined, matte-to-satin part.

    Attributes
    ----------
    background_rms_mm : float
        Largest background flatness (default 0.005 mm): the issue's target for a clean
        background after plane removal; matte renders reach 0.0003 mm, glossy ones
        0.02-0.08 mm.
    lambertian_residual : float
        Largest relative residual of any light (default 0.05): sensor noise leaves
        0.002-0.01 on a matte part. Sharp highlights, cast shadows, a dark or
        misplaced LED exceed it; a BROAD gloss lobe (GGX alpha 0.3, 0.3 of the
        diffuse) does not: the solve tilts the normals to absorb it and the residual
        only doubles (0.0025 -> 0.005 on Mitsuba renders), while the heights bend by
        0.2-0.3 mm. The background flatness catches that case.
    slope_bias_mrad : float
        Largest background slope bias against the reference (default 2 mrad: a
        0.1 mm height change across 50 mm).
    invalid_fraction : float
        Largest fraction of the mask without a trusted normal (default 0.05).

    A calibration may set them from a reference part (``rig.json``); these are the
    fall-back values.
    """

    background_rms_mm: float = 0.005
    lambertian_residual: float = 0.05
    slope_bias_mrad: float = 2.0
    invalid_fraction: float = 0.05

    def __post_init__(self):
        for name, value in asdict(self).items():
            positive(value, name)

    def as_dict(self) -> dict:
        """The limits as written in ``rig.json`` and ``summary.json``."""
        return asdict(self)


_REASONS = {
    "background_rms_mm": "the background is {value:.4g} mm RMS about its {model} model (limit {limit:.4g} mm): the "
                         "heights are distorted (gloss, interreflection, wrong light model)",
    "lambertian_residual": "light {light} departs from the Lambertian model by {value:.3g} of its mean (limit "
                           "{limit:.3g}): the images hold what the model does not (gloss, shadows, wrong LED data)",
    "slope_bias_mrad": "the background slopes are biased by {value:.3g} mrad against the reference part (limit "
                       "{limit:.3g} mrad)",
    "invalid_fraction": "{value:.1%} of the part has no trusted normal (limit {limit:.1%})",
}


def check(figures: QualityFigures, limits: QualityLimits | None = None) -> list[dict]:
    """The limits a measurement fails, each with its reason.

    A figure that could not be computed (NaN) where its inputs were given fails too: an
    unmeasured background or residual is no reason for trust. Figures that were not
    asked for (no images, no reference) are skipped.

    Parameters
    ----------
    figures : QualityFigures
        From :func:`quality_figures`.
    limits : QualityLimits, optional
        Default: :class:`QualityLimits` ().

    Returns
    -------
    list of dict
        One entry per failed limit: ``figure``, ``value`` (None when not measured),
        ``limit`` and ``reason``; empty when the measurement may be trusted.

    Examples
    --------
    >>> fig = QualityFigures(0.02, "plane", (0.01, 0.12), (0.5, 0.0, 0.5), 0.0)
    >>> [f["figure"] for f in check(fig)]
    ['background_rms_mm', 'lambertian_residual']
    """
    if not isinstance(figures, QualityFigures):
        raise InputError(f"figures: expected QualityFigures, got {type(figures).__name__}")
    lim = QualityLimits() if limits is None else limits
    if not isinstance(lim, QualityLimits):
        raise InputError(f"limits: expected QualityLimits, got {type(lim).__name__}")
    failed = []

    def fail(name, value, limit, **extra):
        if value is None or not np.isfinite(value):
            reason = f"{name} could not be measured, so the result cannot be trusted"
            value = None
        else:
            reason = _REASONS[name].format(value=value, limit=limit, **extra)
        failed.append({"figure": name, "value": value, "limit": limit, "reason": reason, **extra})

    rms = figures.background_rms_mm
    if not np.isfinite(rms) or rms > lim.background_rms_mm:
        fail("background_rms_mm", rms, lim.background_rms_mm, model=figures.background_model)
    if figures.lambertian_residual:
        r = np.asarray(figures.lambertian_residual, float)
        worst = int(np.nanargmax(r)) if np.isfinite(r).any() else 0
        if not np.isfinite(r).all() or r[worst] > lim.lambertian_residual:
            bad = int(np.flatnonzero(~np.isfinite(r))[0]) if not np.isfinite(r).all() else worst
            fail("lambertian_residual", float(r[bad]), lim.lambertian_residual, light=bad + 1)
    if figures.slope_bias_mrad is not None:
        b = figures.slope_bias_mrad[2]
        if not np.isfinite(b) or b > lim.slope_bias_mrad:
            fail("slope_bias_mrad", b, lim.slope_bias_mrad)
    if not np.isfinite(figures.invalid_fraction) or figures.invalid_fraction > lim.invalid_fraction:
        fail("invalid_fraction", figures.invalid_fraction, lim.invalid_fraction)
    return failed


#: How :func:`reference_limits` widens a reference part's figures into limits: a part of the same
#: kind measured on the same rig may be this many times worse than the reference before it is
#: distrusted (noise, texture and placement vary from part to part).
REFERENCE_FACTOR = 4.0
#: The smallest limits :func:`reference_limits` sets (a reference that is nearly perfect must
#: not make every later part fail on noise): 1 um background, 0.01 residual, 1 mrad, 1 %.
REFERENCE_FLOORS = {"background_rms_mm": 0.001, "lambertian_residual": 0.01, "slope_bias_mrad": 1.0,
                    "invalid_fraction": 0.01}


def reference_limits(figures: QualityFigures, defaults: QualityLimits | None = None) -> QualityLimits:
    """Quality limits set from a reference part measured on the rig (``inspect calibrate --reference-part``).

    Each limit is ``REFERENCE_FACTOR`` x the reference's figure (the invalid fraction:
    the reference's plus the floor), at least :data:`REFERENCE_FLOORS` and never looser
    than ``defaults``: a reference tightens the stated limits, it cannot excuse a rig
    whose measurements are not trusted (:func:`check` of the reference against
    ``defaults`` must pass first, which the caller enforces).

    Parameters
    ----------
    figures : QualityFigures
        The reference part's figures.
    defaults : QualityLimits, optional
        The stated limits (default :class:`QualityLimits` ()).

    Returns
    -------
    QualityLimits

    Examples
    --------
    >>> ref = QualityFigures(0.0003, "plane", (0.004, 0.006), (0.1, 0.0, 0.1), 0.0)
    >>> reference_limits(ref)
    QualityLimits(background_rms_mm=0.0012, lambertian_residual=0.024, slope_bias_mrad=2.0, invalid_fraction=0.01)
    """
    lim = QualityLimits() if defaults is None else defaults

    def widen(name, value):
        if value is None or not np.isfinite(value):
            return getattr(lim, name)
        return float(min(getattr(lim, name), max(REFERENCE_FLOORS[name], REFERENCE_FACTOR * value)))

    return QualityLimits(
        background_rms_mm=widen("background_rms_mm", figures.background_rms_mm),
        lambertian_residual=widen("lambertian_residual", figures.worst_lambertian_residual),
        # the bias is measured against the reference itself (0 there): the stated limit stays
        slope_bias_mrad=lim.slope_bias_mrad,
        invalid_fraction=float(min(lim.invalid_fraction,
                                   figures.invalid_fraction + REFERENCE_FLOORS["invalid_fraction"])),
    )


def quality_report(figures: QualityFigures, limits: QualityLimits | None = None, source: str = "default") -> dict:
    """The JSON-ready ``quality`` entry of ``summary.json`` and ``result.json``.

    Parameters
    ----------
    figures : QualityFigures
    limits : QualityLimits, optional
        Default: :class:`QualityLimits` ().
    source : str
        Where the limits came from (``"default"``, ``"rig"``, ``"option"``).

    Returns
    -------
    dict
        ``figures`` (:meth:`QualityFigures.as_dict`), ``limits``, ``limits_source``,
        ``failed`` (:func:`check`) and ``trusted`` (no limit failed).
    """
    lim = QualityLimits() if limits is None else limits
    failed = check(figures, lim)
    return {"figures": figures.as_dict(), "limits": lim.as_dict(), "limits_source": source, "failed": failed,
            "trusted": not failed}
