"""The options of a photometric reconstruction, each default held once.

:class:`PhotometricOptions` says how images become normals, height, surface, defects and
their uncertainty; it is checked once, when it is made, and the stages
(:mod:`photometric.pipeline`) trust it. The command line (``workbench photometric
reconstruct``, ``workbench inspect run|watch``, batch manifests) reads its defaults from
here. :data:`READ_KEYWORDS` are the other keywords of
:func:`photometric.pipeline.reconstruct`: what the input is (lights, mask, LED positions,
camera, rig), read by :func:`photometric.stages.read`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from surfaces.validate import InputError, positive

__all__ = ["PhotometricOptions", "READ_KEYWORDS", "SURFACES", "LIGHT_MODELS", "BACKGROUNDS", "DARK", "SATURATION",
           "TOLERANCE_MM", "MAX_ITERATIONS", "U_NAMES", "OUTLIER_MIN_IMAGES", "MASKED_INTEGRATOR", "INTEGRATOR",
           "BACKGROUND", "REFLECTANCES",
           "photometric_options", "split_keywords"]

# The numbers are held here, where nothing heavy is imported (the command line reads them at start-up);
# the solvers' own keyword defaults are these names (photometric.stereo, photometric.nearfield).
#: Outlier mode's shadow threshold: an observation below ``DARK`` x albedo is a shadow.
DARK = 0.1
#: Outlier mode's saturation: input values (full scale 1) at or above this are saturated.
SATURATION = 0.99
#: Near-field convergence: largest height change between passes, mm.
TOLERANCE_MM = 1e-3
#: Near-field passes per resolution.
MAX_ITERATIONS = 30
#: ``outliers=None`` (the default) turns the shadow/highlight mode on from this many images: real captures
#: have shadows and highlights, and with 6 or more images enough remain after dropping them (DiLiGenT,
#: 14 images: bear 9.60 -> 7.74 deg, cat 9.11 -> 7.17 deg mean error).
OUTLIER_MIN_IMAGES = 6
#: ``integrator="auto"``: ``dct`` on a full rectangle, this masked-domain method when a mask cuts the
#: rectangle (the DCT's free boundary runs across the background there). Not the default yet: the masked
#: least-squares multigrid fails ("Factor is exactly singular") on some masked domains, e.g. a sphere's
#: valid pixels inside an off-centre rectangle (tests/photometric/test_pipeline.py's trimmed-mesh scene).
MASKED_INTEGRATOR = "lsq"
#: The default integrator (:func:`photometric.integrate.integrate`'s and the pipeline's).
INTEGRATOR = "dct"
#: The default background model (:func:`photometric.defects.measure_defects`'s and the pipeline's).
BACKGROUND = "plane"

#: Surface methods: the least-squares fit (:func:`surfaces.fit.fit_height`) and the Coons
#: interpolation of a decimated grid (:func:`photometric.integrate.height_to_patches`); ``"none"``: no
#: surface model and no mesh (a normals-and-height run, for big captures).
SURFACES = ("fit", "coons", "none")
#: ``light_model`` choices: from the input (point lights when LED positions are known), or forced.
LIGHT_MODELS = ("auto", "point", "directional")
#: Backgrounds removed before the defects are measured (:func:`photometric.defects.fit_background`).
BACKGROUNDS = ("plane", "smooth")
#: Reflectance models of the near-field solve: Lambert's law, or a Lambertian albedo plus a GGX lobe
#: (:mod:`photometric.glossy`) whose normals refine the Lambertian solve's.
REFLECTANCES = ("lambertian", "glossy")
#: Names of the input standard uncertainties that say ``u`` (a ``tolerance`` is a limit): accepted in an
#: ``uncertainty`` dict beside the older :class:`photometric.uncertainty.Tolerances` field names they map to.
U_NAMES = {"light_u_deg": "light_tolerance_deg", "light_position_u_mm": "light_position_tolerance_mm",
           "intensity_u": "intensity_tolerance", "pixel_size_u": "pixel_size_tolerance"}
#: Keywords of :func:`photometric.stages.read` (the input), beside the options.
READ_KEYWORDS = ("lights", "intensities", "mask", "select", "pixel_size", "light_positions", "led_mu",
                 "flat_field", "flat_albedo", "camera", "focal_length_px", "camera_height_mm",
                 "principal_point_px", "rig", "ambient", "bayer", "led_axes", "distortion")


def _choice(value, name: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise InputError(f"{name}: expected one of {allowed}, got {value!r}")


def _flag(value, name: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise InputError(f"{name}: must be True or False, got {value!r}")
    return bool(value)


def _count(value, name: str, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer | float) or value != int(value) \
            or int(value) < 1:
        raise InputError(f"{name}: must be at least 1 {what}, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class PhotometricOptions:
    """How a photometric reconstruction computes (not what its input is).

    Attributes
    ----------
    integrator : {"auto", "dct", "fc", "lsq", "robust"}
        Height integrator (:func:`photometric.integrate.integrate`), near-field solves too
        (:data:`photometric.nearfield.INTEGRATORS`); default ``dct``. ``"auto"``: ``dct`` when
        the mask is the whole rectangle, :data:`MASKED_INTEGRATOR` when it cuts it
        (:meth:`resolved`).
    outliers : bool or None
        Shadow/highlight mode of the solve (:func:`photometric.stereo.solve`); None: on with
        :data:`OUTLIER_MIN_IMAGES` or more images (:meth:`resolved`).
    dark : float
        Outlier mode: an observation below ``dark`` x albedo is a shadow (> 0).
    saturation : float
        Outlier mode: input values (full scale 1) at or above this are saturated (> 0).
    highlight : float or None
        Outlier mode: also drop observations brighter than the Lambertian prediction by
        more than ``highlight`` x albedo (None: off).
    force : bool
        Solve even when the light matrix's condition number is above
        :data:`photometric.stereo.MAX_CONDITION` (100; above
        :data:`photometric.stereo.WARN_CONDITION`, 10, it is a warning).
    light_model : {"auto", "point", "directional"}
        ``auto``: point lights when LED positions are known; ``directional``: the
        far-field model even then (directions from the origin to the LEDs).
    reference_height_mm : float
        Near-field anchor: the median height of the valid pixels, mm
        (:func:`photometric.camera.depth_from_field`).
    tolerance_mm : float
        Near-field convergence: largest height change between passes, mm (> 0;
        :func:`photometric.nearfield.solve_nearfield`).
    max_iterations : int
        Near-field passes per resolution (at least 1).
    surface : {"fit", "coons", "none"}
        ``"fit"``: bicubic patches fitted by least squares to the height and the slopes of
        every pixel, refined where they miss ``surface_tolerance``
        (:func:`surfaces.fit.fit_height`); ``"coons"``: Coons patches through the
        decimated height (:func:`photometric.integrate.height_to_patches`); ``"none"``: no
        surface model and no mesh.
    step : int or None
        Pixels per patch of the surface model: the largest patch side of the fit
        (default :func:`surfaces.fit.default_step`, about 64 patches across) or the
        Coons decimation step (default ``ceil(max(H, W) / 64)``, at least 2).
    samples : int or None
        Mesh subdivisions per (largest) patch side; default ``min(step, 8)``.
    surface_tolerance : float or None
        Largest deviation of the fitted surface from the height, mm (> 0); default
        :data:`surfaces.fit.RELATIVE_TOLERANCE` of the height range. Fit only.
    background : {"plane", "smooth"}
        Background removed before measuring defects.
    uncertainty : photometric.uncertainty.Tolerances or None
        Input standard uncertainties and the method (:mod:`photometric.uncertainty`); a
        dict is turned into ``Tolerances`` and may use the ``u`` names of :data:`U_NAMES`
        (``light_u_deg`` for ``light_tolerance_deg``, ...). None: no uncertainty stage.
    reflectance : {"lambertian", "glossy"} or None
        None: the rig's model (``rig.json`` ``reflectance``), else ``lambertian``.
        ``glossy``: the near-field solve's normals are refined per pixel under a
        Lambertian albedo plus a GGX lobe (:func:`photometric.glossy.fit_glossy`, from the
        Lambertian solve) and integrated again; point lights, an orthographic camera and
        4 or more lights. Valid for a dielectric with a broad lobe (GGX ``alpha`` about
        0.2-0.6) of known roughness and weight; ``lambertian`` for matte parts.
    gloss_alpha : float or None
        GGX roughness of the part's material (0 < alpha <= 1); default: the rig's
        (``rig.json`` ``reflectance``).
    gloss_weight : float or None
        Lobe weight ``c`` (>= 0, :func:`photometric.glossy.lobe_weight` on a reference
        part); default: the rig's.
    max_patches : int or None
        Patch budget of the fit (``surfaces.fit.fit_height``'s ``max_patches``). None: without
        a mask (every pixel solved) :func:`photometric.stages.patch_budget` of the image size,
        with a mask no budget.
    estimate_intensities : bool
        Near field (point lights) only: estimate the relative LED intensities from the
        images (semi-calibrated solve, :func:`photometric.nearfield.solve_nearfield`),
        reported in ``summary.json`` (``intensities``). False: the given intensities, the
        flat field's gains, or the stated assumption (equal irradiance ``e_k`` at the
        field centre).

    Examples
    --------
    >>> PhotometricOptions().integrator, PhotometricOptions().dark, PhotometricOptions().max_iterations
    ('dct', 0.1, 30)
    >>> PhotometricOptions(integrator="spline")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: integrator: expected one of ('auto', 'dct', 'fc', 'lsq', 'robust'), got 'spline'
    >>> r = PhotometricOptions(integrator="auto").resolved(n_images=14, masked=True)
    >>> r.outliers, r.integrator, PhotometricOptions().resolved(n_images=4, masked=True).outliers
    (True, 'lsq', False)
    """

    integrator: str = INTEGRATOR
    outliers: bool | None = None
    dark: float = DARK
    saturation: float = SATURATION
    highlight: float | None = None
    force: bool = False
    light_model: str = "auto"
    reference_height_mm: float = 0.0
    tolerance_mm: float = TOLERANCE_MM
    max_iterations: int = MAX_ITERATIONS
    surface: str = "fit"
    step: int | None = None
    samples: int | None = None
    surface_tolerance: float | None = None
    background: str = BACKGROUND
    uncertainty: object = None
    reflectance: str | None = None
    gloss_alpha: float | None = None
    gloss_weight: float | None = None
    estimate_intensities: bool = False
    max_patches: int | None = None

    def __post_init__(self) -> None:
        from photometric.integrate import METHODS
        from photometric.stereo import _check_options
        from photometric.uncertainty import Tolerances

        _choice(self.integrator, "integrator", ("auto",) + tuple(METHODS))
        _choice(self.light_model, "light_model", LIGHT_MODELS)
        _choice(self.surface, "surface", SURFACES)
        _choice(self.background, "background", BACKGROUNDS)
        if self.reflectance is not None:
            _choice(self.reflectance, "reflectance", REFLECTANCES)
        if self.gloss_alpha is not None:
            a = positive(self.gloss_alpha, "gloss_alpha")
            if a > 1.0:
                raise InputError(f"gloss_alpha: a GGX roughness is at most 1, got {a}")
            object.__setattr__(self, "gloss_alpha", a)
        if self.gloss_weight is not None:
            object.__setattr__(self, "gloss_weight", positive(self.gloss_weight, "gloss_weight", allow_zero=True))
        for name in ("outliers", "force", "estimate_intensities"):
            if name == "outliers" and self.outliers is None:
                continue
            object.__setattr__(self, name, _flag(getattr(self, name), name))
        _check_options(self.dark, self.saturation, self.highlight, 2)
        object.__setattr__(self, "tolerance_mm", positive(self.tolerance_mm, "tolerance_mm"))
        object.__setattr__(self, "max_iterations", _count(self.max_iterations, "max_iterations", "pass"))
        if not np.isfinite(float(self.reference_height_mm)):
            raise InputError(f"reference_height_mm: must be finite, got {self.reference_height_mm}")
        object.__setattr__(self, "reference_height_mm", float(self.reference_height_mm))
        for name, what in (("step", "pixel"), ("samples", "subdivision"), ("max_patches", "patch")):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _count(getattr(self, name), name, what))
        if self.surface_tolerance is not None:
            object.__setattr__(self, "surface_tolerance", positive(self.surface_tolerance, "surface_tolerance"))
        unc = self.uncertainty
        if isinstance(unc, dict):
            both = sorted(k for k in unc if k in U_NAMES and U_NAMES[k] in unc)
            if both:
                raise InputError(f"uncertainty: {both[0]} and {U_NAMES[both[0]]} name the same standard uncertainty")
            object.__setattr__(self, "uncertainty", Tolerances(**{U_NAMES.get(k, k): v for k, v in unc.items()}))
        elif unc is not None and not isinstance(unc, Tolerances):
            raise InputError(f"uncertainty: expected Tolerances, a dict or None, got {type(unc).__name__}")


    def resolved(self, *, n_images: int, masked: bool) -> PhotometricOptions:
        """The options with the data-dependent defaults decided (``outliers`` None, ``integrator`` "auto").

        Parameters
        ----------
        n_images : int
            Images of the input.
        masked : bool
            True when the mask leaves out part of the image rectangle.

        Returns
        -------
        PhotometricOptions
            ``outliers`` a bool, ``integrator`` a method of :data:`photometric.integrate.METHODS`.
        """
        changes = {}
        if self.outliers is None:
            changes["outliers"] = int(n_images) >= OUTLIER_MIN_IMAGES
        if self.integrator == "auto":
            changes["integrator"] = MASKED_INTEGRATOR if masked else "dct"
        return replace(self, **changes) if changes else self


def _names() -> tuple[str, ...]:
    return tuple(f.name for f in fields(PhotometricOptions))


def photometric_options(options: PhotometricOptions | None = None, **keywords) -> PhotometricOptions:
    """Options object from an optional base and keyword overrides.

    Parameters
    ----------
    options : PhotometricOptions, optional
        Base options (the defaults when omitted).
    **keywords
        Fields of :class:`PhotometricOptions` to override.

    Returns
    -------
    PhotometricOptions

    Raises
    ------
    InputError
        Unknown names, or values the options do not accept.

    Examples
    --------
    >>> opts = photometric_options(outliers=True, integrator="lsq")
    >>> opts.outliers, opts.integrator, opts.saturation
    (True, 'lsq', 0.99)
    """
    unknown = set(keywords) - set(_names())
    if unknown:
        raise InputError(f"options: unknown {sorted(unknown)}")
    base = PhotometricOptions() if options is None else options
    return replace(base, **keywords) if keywords else base


def split_keywords(keywords: dict, options: PhotometricOptions | None = None) -> tuple[dict, PhotometricOptions]:
    """Sort keywords into the input's (:data:`READ_KEYWORDS`) and the options.

    Parameters
    ----------
    keywords : dict
        Keywords of :func:`photometric.pipeline.reconstruct`.
    options : PhotometricOptions, optional
        Base options.

    Returns
    -------
    (dict, PhotometricOptions)

    Raises
    ------
    TypeError
        A name that is neither (like a Python call with an unknown keyword).

    Examples
    --------
    >>> read, opts = split_keywords({"pixel_size": 0.1, "background": "smooth"})
    >>> read, opts.background
    ({'pixel_size': 0.1}, 'smooth')
    """
    unknown = set(keywords) - set(READ_KEYWORDS) - set(_names())
    if unknown:
        raise TypeError(f"unexpected keyword argument(s) {sorted(unknown)}; options are {list(_names())}, "
                        f"input keywords {list(READ_KEYWORDS)}")
    read = {k: v for k, v in keywords.items() if k in READ_KEYWORDS}
    return read, photometric_options(options, **{k: v for k, v in keywords.items() if k not in READ_KEYWORDS})
