"""Near-field photometric stereo: point lights (LEDs) and an orthographic or perspective camera.

Model
-----
An LED ``k`` at ``P_k`` lights the surface point ``X`` that a pixel sees with the scaled
light vector ``s_k(X) = E_k(X) l_k(X)`` of :func:`photometric.leds.light_field`
(inverse-square falloff, LED lobe ``cos^mu``), so a Lambertian pixel reads
``I_k = albedo * max(0, s_k(X) . n)`` (Mecca et al., "Near field photometric stereo with
point light sources", SIAM J. Imaging Sci. 2014; Queau et al., "LED-based photometric
stereo: modeling, calibration and numerical solution", JMIV 2018). With a flat field
(:func:`photometric.rig.flat_field_gains`) the measured gain ``G_k`` of each pixel
replaces ``e_k``, the lobe on the reference plane, vignetting and unequal LED power:
``E_k(X) = G_k |P_k - X0|^2 / |P_k - X|^2`` (times the lobe ratio
``lobe_k(X) / lobe_k(X0)`` when the exponents are known), ``X0`` the point of the
reference plane that the pixel sees.

Solution (the alternation of the papers above)
----------------------------------------------
1. Start on the reference plane, ``z = reference_height_mm`` everywhere.
2. Normals: per pixel the least-squares ``albedo * n`` over the lights, from the 3 x 3
   normal equations ``(sum_k s_k s_k^T) g = sum_k I_k s_k`` solved in closed form for
   every pixel at once (float32, image blocks on two threads); the outlier mode drops
   dark, saturated (and, optionally, too bright) observations per pixel and re-solves
   from the rest, as :func:`photometric.stereo.solve` does for distant lights.
3. Integrate (:mod:`photometric.integrate`): ``z`` for the orthographic camera, the
   log-depth ``log(H_c - z)`` for the perspective one (:func:`photometric.camera.gradient_field`).
4. Anchor the unknown constant (:func:`photometric.camera.depth_from_field`): the
   median height of the valid pixels is ``reference_height_mm``.
5. Move the points to the new heights and repeat from 2 until the largest height change
   of a pixel valid in both passes is below ``tolerance_mm``. After the first pass at a
   resolution, step 2 re-solves only the pixels whose height moved by more than
   :data:`RESOLVE_FRACTION` of the tolerance since their normal was solved; the others
   keep their normals (a height error ``dz`` turns a light vector by about
   ``dz / |P_k - X|``: 1e-6 rad for 0.1 um at 100 mm); ``resolved_fraction`` in the history
   says how many pixels were re-solved. Every pass integrates the whole image; a
   full-resolution pass that re-solved at most half of the pixels integrates only its slope
   change, on a grid :data:`CORRECTION_STEP` times coarser, and adds it to the previous
   field (integration is linear; kept only while the height change stays below
   :data:`CORRECTION_MARGIN` of the tolerance, so the heights differ from a full-resolution
   integration by less than that).

Light vectors change slowly with depth, so the passes run first on a block-averaged copy
of the images (at most ``coarse_pixels`` pixels) until they converge there, and then at
full resolution from the upsampled depth until the full-resolution change is below the
tolerance too (typically two full passes). Distant (directional) lights need no
alternation: with a perspective camera one far-field solve and one log-depth
integration give the surface.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from photometric.camera import (
    Camera,
    Orthographic,
    Perspective,
    _gradient,
    depth_from_field,
    footprint_area,
    pixel_offsets,
    plane_points,
    surface_xy,
)
from photometric.leds import PointLights, _scaled_vectors
from photometric.lights import as_intensities, validate_lights
from photometric.options import DARK, MAX_ITERATIONS, SATURATION, TOLERANCE_MM
from photometric.stereo import MAX_CONDITION, _check_images, _check_options, _grey_planes, _solve
from surfaces.validate import as_array, InputError, positive

__all__ = [
    "DEFAULT_TOLERANCE_MM",
    "CORRECTION_STEP",
    "COARSE_PIXELS",
    "ANCHOR_RULE",
    "NearFieldResult",
    "NearFieldSetup",
    "NotConvergedError",
    "nearfield_setup",
    "solve_nearfield",
    "INTENSITY_TOLERANCE",
    "INTENSITY_ROUNDS",
    "LEVEL_RULE",
]

#: Default convergence tolerance: largest height change of a pixel between passes, mm.
DEFAULT_TOLERANCE_MM = TOLERANCE_MM
#: Most pixels of the coarse copy the alternation starts on.
COARSE_PIXELS = 1 << 18
#: Pixels per image block of a whole-image pass (fits the CPU cache with its temporaries).
BLOCK_PIXELS = 1 << 15
#: Passes after the first at a level re-solve the normals only of the pixels whose height moved by more
#: than this fraction of the tolerance since their normal was solved (the others keep theirs).
RESOLVE_FRACTION = 0.1
#: Block size of the decimated integration of a partial full-resolution pass (1: every pass integrates the
#: whole image at full resolution). Such a pass re-solved only the normals whose point moved (typically
#: under a fifth of the pixels, each turned by about 1e-6 rad); integration is linear (``dct``, ``fc``), so
#: its heights are the previous pass's field plus the integral of the slope change, here block-averaged,
#: integrated on the r-times coarser grid and upsampled bilinearly. That correction is of the size of the
#: height change the pass measures, and so is its error.
CORRECTION_STEP = 4
#: A decimated correction is kept only when the height change it gives is below this fraction of the
#: tolerance (the pass then converges and the heights differ from a full-resolution integration by about
#: that change at most); otherwise the pass integrates the whole image at full resolution.
CORRECTION_MARGIN = 0.1
#: The anchoring rule, as stated in ``summary.json``.
ANCHOR_RULE = "median height of the valid pixels = reference_height_mm"
INTEGRATORS = ("dct", "fc", "lsq", "robust")
#: Semi-calibrated solve (``estimate_intensities``): stop when no LED's intensity changes by more than this
#: fraction in a round of the alternation between the normals/albedo and the per-LED scales.
INTENSITY_TOLERANCE = 1e-5
#: Most rounds of that alternation.
INTENSITY_ROUNDS = 200
#: The semi-calibrated solve cannot tell a tilt of the whole part from a ramp of the LED powers across
#: the ring of LEDs (exactly for distant lights, nearly for near ones: a plate solved from powers with a
#: 2 deg ramp comes out tilted by 2 deg and bent by a few um). Each round therefore levels the part: the
#: scales take the ramp that makes the mean slope of the valid pixels zero.
LEVEL_PART = True
#: That rule, as ``summary.json`` states it.
LEVEL_RULE = ("the part's mean slope over the valid pixels is taken as level (the reference plane's): a tilt "
              "of the whole part and a ramp of the LED powers across the LEDs are not told apart")


class NotConvergedError(InputError):
    """The alternation stopped before the height change fell below the tolerance.

    An :class:`~surfaces.validate.InputError`: what the user changes is the input or
    its options (``max_iterations``, ``tol``, the lights' positions), so the command
    line reports it as one line with exit code 2.

    Attributes
    ----------
    summary : dict
        What the caller reports (the pipeline's summary with ``converged: false`` and
        the iteration history); nothing else is returned.
    """

    def __init__(self, message: str, summary: dict | None = None):
        super().__init__(message)
        self.summary = summary or {}


@dataclass(frozen=True)
class NearFieldResult:
    """Everything :func:`solve_nearfield` computes.

    Attributes
    ----------
    normals : numpy.ndarray, shape (H, W, 3), float32
        Unit normals; ``(0, 0, 1)`` where no solution exists.
    albedo : numpy.ndarray, shape (H, W) or (H, W, 3), float32
        Albedo (images divided by the irradiance ``E_k``); zero where no solution exists.
    valid : numpy.ndarray, shape (H, W), bool
        In the mask, positive albedo, ``n_z > 0``, enough well-conditioned inliers in
        the outlier mode.
    residual : numpy.ndarray, shape (H, W), float32, or None
        RMS of ``x_k - s_k . (albedo n)`` over the observations used (intensity-divided
        image units); None when the solve was asked not to compute it.
    p, q : numpy.ndarray, shape (H, W), float32
        Surface slopes ``dz/dx = -n_x / n_z``, ``dz/dy = -n_y / n_z`` (y up) in the rig
        frame; zero where not valid.
    height : numpy.ndarray, shape (H, W), float64
        ``z`` (mm) of the point each pixel sees; NaN where not valid.
    xy : numpy.ndarray, shape (H, W, 2), float64
        ``x, y`` (mm) of that point (invalid pixels: at the interpolated height).
    footprint_mm2 : float or numpy.ndarray, shape (H, W)
        Each pixel's footprint projected on the ``x, y`` plane (mm^2,
        :func:`photometric.camera.footprint_area`).
    outliers : numpy.ndarray or None, shape (N, H, W), bool
        Dropped observations (outlier mode).
    depth_change_mm : float or None
        The last pass's largest height change, below the tolerance (None: distant
        lights, no alternation).
    iterations : int
        Passes run (coarse and full resolution).
    history : tuple of dict
        One entry per pass: ``level`` ("coarse"/"full"), ``step`` (pixels per block),
        ``depth_change_mm``, ``valid_fraction``, ``resolved_fraction`` (pixels whose
        normals the pass solved, of the mask).
    anchor : dict
        ``rule`` (:data:`ANCHOR_RULE`) and ``reference_height_mm``.
    timings_s : dict
        ``solve`` (light vectors and normals) and ``integrate`` (integration and
        anchoring), s.
    intensities : dict or None
        With ``estimate_intensities``: the estimated ``e_k`` (``relative``, LED 0 fixed at
        its given value), the radiant intensities they imply relative to LED 0
        (``radiant_relative``, ``e_k d0_k^2 / (e_0 d0_0^2)``), ``rounds`` of the
        estimation, its last largest relative change ``final_change``, ``tolerance``,
        ``converged``, the fewest ``pixels`` an LED's scale used, ``levelling``
        (:data:`LEVEL_RULE`) with ``last_tilt_removed_deg``, and ``level`` ("coarse" or
        "full") with ``block_px``, where it ran; None otherwise.
    """

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    residual: np.ndarray | None
    p: np.ndarray
    q: np.ndarray
    height: np.ndarray
    xy: np.ndarray
    footprint_mm2: float | np.ndarray
    outliers: np.ndarray | None
    depth_change_mm: float | None
    iterations: int
    history: tuple = ()
    anchor: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)
    intensities: dict | None = None


@dataclass
class _Level:
    """One resolution of the alternation: observations and geometry per pixel."""

    planes: np.ndarray  # (N, h, w) float32 intensity-divided grey observations
    strength: list  # N scalars or (h, w) float32 maps: E_k = strength * lobe / r^2
    mask: np.ndarray  # (h, w) bool
    saturated: np.ndarray | None  # (N, h, w) bool, outlier mode
    u: np.ndarray  # (w,) offsets (orthographic: x in mm; perspective: pixels)
    v: np.ndarray  # (h,)
    step: int  # full-resolution pixels per level pixel
    colour: np.ndarray | None = None  # (N, h, w, 3) intensity-divided channels (albedo only)

    @property
    def shape(self) -> tuple[int, int]:
        return self.mask.shape


@dataclass(frozen=True)
class _Options:
    outliers: bool
    dark: float
    saturation: float
    highlight: float | None
    rounds: int
    lobe: bool  # apply the modelled LED lobe to the strength
    residual: bool = True  # compute the fit residual of the final passes


@dataclass(frozen=True)
class NearFieldSetup:
    """What a near-field solve computes from the rig alone, to reuse over many parts.

    The irradiance strengths ``E_k = strength_k lobe_k(X) / |P_k - X|^2`` of the flat
    field depend on the LEDs, the camera, the gains and the image size, not on the
    images: an inspection computes them once per rig (:func:`nearfield_setup`) and hands
    them to every :func:`solve_nearfield` of its parts.

    Attributes
    ----------
    lights : PointLights
    camera : Orthographic or Perspective
    shape : tuple of int
        ``(H, W)`` of the images.
    flat_field : bool
        The strengths come from flat-field gains.
    strength : list
        Per light a scalar ``d0_k^2`` or an ``(H, W)`` float32 map ``G_k |P_k - X0|^2``.
    coarse : dict
        Block size ``r`` of the coarse stage -> the strengths averaged in ``r x r`` blocks.
    """

    lights: PointLights
    camera: Camera
    shape: tuple
    flat_field: bool
    strength: list
    coarse: dict


def nearfield_setup(lights: PointLights, camera, shape, gains=None, *,
                    coarse_pixels: int = COARSE_PIXELS) -> NearFieldSetup:
    """The part-independent set-up of :func:`solve_nearfield` (pass it as ``setup``).

    Parameters
    ----------
    lights : PointLights
        LEDs (:func:`photometric.leds.point_lights`).
    camera : Orthographic or Perspective
    shape : (H, W)
        Image size, pixels.
    gains : array_like, shape (N, H, W), optional
        Flat-field gains (:func:`photometric.rig.flat_field_gains`).
    coarse_pixels : int, optional
        As in :func:`solve_nearfield`: the coarse stage's block size is prepared too.

    Returns
    -------
    NearFieldSetup

    Examples
    --------
    >>> from photometric.camera import make_camera
    >>> from photometric.leds import point_lights
    >>> lights = point_lights([[100.0, 0, 150], [-50, 87, 150], [-50, -87, 150]])
    >>> cam = make_camera("orthographic", pixel_size_mm=0.5)
    >>> s = nearfield_setup(lights, cam, (64, 64), np.ones((3, 64, 64), np.float32), coarse_pixels=256)
    >>> s.strength[0].shape, sorted(s.coarse), s.coarse[4][0].shape
    ((64, 64), [4], (16, 16))
    """
    if not isinstance(lights, PointLights):
        raise InputError(f"lights: expected PointLights (photometric.leds.point_lights), got {type(lights).__name__}")
    camera = _check_camera(camera)
    if len(shape) != 2 or min(int(shape[0]), int(shape[1])) < 1:
        raise InputError(f"shape: expected (H, W) with H, W >= 1, got {shape}")
    shape = (int(shape[0]), int(shape[1]))
    g = None
    if gains is not None:
        g = as_array(gains, "gains", shape=(len(lights),) + shape, dtype=np.float32)
        if np.any(g < 0):
            raise InputError("gains: flat-field gains must be >= 0")
    strength = _strengths(lights, camera, shape, g, None)
    r = _coarse_step(shape, int(coarse_pixels))
    coarse = {} if r == 1 else {r: [s if np.ndim(s) == 0 else _block_mean(s, r) for s in strength]}
    return NearFieldSetup(lights, camera, shape, g is not None, strength, coarse)


def _coarse_step(shape, coarse_pixels: int) -> int:
    """Block size of the coarse stage (1: none)."""
    r = int(np.ceil(np.sqrt(shape[0] * shape[1] / coarse_pixels)))
    return r if r > 1 and min(shape) >= 4 * r else 1


def _check_setup(setup, lights, camera, shape, gains) -> None:
    if not isinstance(setup, NearFieldSetup):
        raise InputError(f"setup: expected NearFieldSetup (nearfield_setup), got {type(setup).__name__}")
    if gains is not None:
        raise InputError("setup: give the flat-field gains to nearfield_setup, not with setup")
    if (tuple(setup.shape) != tuple(shape) or setup.camera != camera or not isinstance(lights, PointLights)
            or len(lights) != len(setup.lights)
            or not np.array_equal(setup.lights.positions, lights.positions)
            or not np.array_equal(setup.lights.axes, lights.axes)
            or not np.array_equal(setup.lights.mu, lights.mu) or setup.lights.mu_known != lights.mu_known):
        raise InputError(f"setup: prepared for other lights, camera or image size ({setup.shape[0]} x "
                         f"{setup.shape[1]} px) than this solve's ({shape[0]} x {shape[1]} px)")


def _check_camera(camera) -> Camera:
    if not isinstance(camera, (Orthographic, Perspective)):
        raise InputError("camera: expected photometric.camera.Orthographic or Perspective "
                         f"(photometric.camera.make_camera), got {type(camera).__name__}")
    return camera


def solve_nearfield(
    images,
    lights,
    camera,
    *,
    intensities=None,
    mask=None,
    gains=None,
    outliers: bool = False,
    dark: float = DARK,
    saturation: float = SATURATION,
    highlight: float | None = None,
    integrator: str = "dct",
    reference_height_mm: float = 0.0,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    max_iterations: int = MAX_ITERATIONS,
    coarse_pixels: int = COARSE_PIXELS,
    threads: int | None = None,
    setup: NearFieldSetup | None = None,
    correction_step: int = CORRECTION_STEP,
    residual: bool = True,
    estimate_intensities: bool = False,
) -> NearFieldResult:
    """Normals, albedo and the surface from images under point lights (or distant ones).

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        Linear images; colour in RGB order (one normal from the channel mean, albedo per
        channel).
    lights : PointLights or array_like, shape (N, 3)
        LEDs (:func:`photometric.leds.point_lights`), or unit directions of distant
        lights (then one solve and one integration, no alternation).
    camera : Orthographic or Perspective
        :func:`photometric.camera.make_camera`.
    intensities : None, float or array_like, shape (N,) or (N, 3), optional
        ``e_k``, divided out per channel; not used with ``gains`` (the flat field
        measures the LED power).
    mask : array_like, shape (H, W), optional
        Pixels to solve.
    gains : array_like, shape (N, H, W), optional
        Flat-field gains ``G_k`` (:func:`photometric.rig.flat_field_gains`); only with
        point lights.
    outliers, dark, saturation, highlight :
        Shadow/highlight handling as in :func:`photometric.stereo.solve`, with the
        observations divided by the irradiance: an observation is dark when
        ``x_k < dark * albedo * E_k``.
    integrator : {"dct", "fc", "lsq", "robust"}
        Normal integrator (:func:`photometric.integrate.integrate`).
    reference_height_mm : float, optional
        The anchor: median height of the valid pixels, mm (see
        :func:`photometric.camera.depth_from_field`); also the start plane.
    tolerance_mm : float, optional
        Convergence: largest height change of a pixel between two passes, mm.
    max_iterations : int, optional
        Most passes at each resolution.
    coarse_pixels : int, optional
        Pixels of the coarse copy the alternation starts on (the images are averaged in
        ``r x r`` blocks, ``r = ceil(sqrt(H W / coarse_pixels))``; ``r = 1``: no coarse
        stage).
    threads : int, optional
        Threads of the whole-image passes (default: the CPU count, at most 4).
    setup : NearFieldSetup, optional
        The rig's strengths prepared once (:func:`nearfield_setup`, with the gains given
        there instead of ``gains``); the result is the same as with ``gains``.
    correction_step : int, optional
        Block size r of the decimated integration of a full-resolution pass that re-solved
        at most half of the pixels (:data:`CORRECTION_STEP`; ``dct`` and ``fc`` only, and
        only while the height change stays below :data:`CORRECTION_MARGIN` of the
        tolerance); 1: integrate every pass at full resolution.
    residual : bool, optional
        Compute :attr:`NearFieldResult.residual` (False: it is None; a caller that does not
        use it, such as an inspection, saves about a tenth of the normal solves).
    estimate_intensities : bool, optional
        Semi-calibrated solve (Queau et al. 2018): the relative LED intensities are
        estimated from the images, alternating the normals/albedo solve (with its height
        passes) with a least-squares fit of one scale per LED over the valid, lit,
        unsaturated pixels, LED 0's scale fixed (``intensities``, when given, are the start
        and LED 0 keeps its value); on the coarse copy of the images when there is one.
        Point lights only. The estimate is :attr:`NearFieldResult.intensities`.

    Returns
    -------
    NearFieldResult

    Raises
    ------
    NotConvergedError
        ``max_iterations`` passes at one level did not bring the height change below
        the tolerance, or the heights diverged; its ``summary`` holds the history.
        Nothing is returned half-way.

    Examples
    --------
    A plate lit by three LEDs 150 mm away, seen by a 0.5 mm-pixel telecentric camera:

    >>> from photometric.camera import make_camera
    >>> from photometric.leds import light_field, point_lights
    >>> lights = point_lights(150 * np.array([[0.7071, 0, 0.7071], [-0.3536, 0.6124, 0.7071],
    ...                                       [-0.3536, -0.6124, 0.7071]]))
    >>> cam = make_camera("orthographic", pixel_size_mm=0.5)
    >>> X = plane_points(cam, (32, 32))
    >>> images = 0.8 * light_field(lights, X)[..., 2]  # a flat plate, n = (0, 0, 1)
    >>> res = solve_nearfield(images, lights, cam)
    >>> float(np.abs(res.height).max()) < 1e-4, round(float(res.albedo.mean()), 4)
    (True, 0.8)
    """
    imgs = _check_images(images)
    n_img, height, width = imgs.shape[:3]
    camera = _check_camera(camera)
    if isinstance(lights, PointLights):
        if len(lights) != n_img:
            raise InputError(f"lights: {len(lights)} LED positions for {n_img} images")
    else:
        lights = validate_lights(lights)
        if lights.shape[0] != n_img:
            raise InputError(f"lights: {lights.shape[0]} directions for {n_img} images")
        if gains is not None:
            raise InputError("gains: a flat field needs point lights (LED positions)")
        if estimate_intensities:
            raise InputError("estimate_intensities: needs point lights (LED positions), not distant lights")
    intens = as_intensities(intensities, n_img)
    m = None if mask is None else as_array(mask, "mask", shape=(height, width), dtype=bool)
    if m is not None and not m.any():
        raise InputError("mask: no pixel is selected")
    g = None
    if setup is not None:
        _check_setup(setup, lights, camera, (height, width), gains)
    elif gains is not None:
        g = as_array(gains, "gains", shape=(n_img, height, width), dtype=np.float32)
        if np.any(g < 0):
            raise InputError("gains: flat-field gains must be >= 0")
    _check_options(dark, saturation, highlight, 2)
    if integrator not in INTEGRATORS:
        raise InputError(f"integrator: expected one of {INTEGRATORS}, got {integrator!r}")
    positive(tolerance_mm, "tolerance_mm")
    if int(max_iterations) < 1:
        raise InputError(f"max_iterations: must be at least 1, got {max_iterations}")
    if int(coarse_pixels) < 1:
        raise InputError(f"coarse_pixels: must be at least 1, got {coarse_pixels}")
    if int(correction_step) != correction_step or correction_step < 1:
        raise InputError(f"correction_step: must be an integer of at least 1, got {correction_step}")
    ref = float(reference_height_mm)
    if not np.isfinite(ref):
        raise InputError(f"reference_height_mm: must be finite, got {reference_height_mm}")
    if isinstance(camera, Perspective) and ref >= camera.camera_height_mm:
        raise InputError(f"reference_height_mm: {ref} mm is not below the camera ({camera.camera_height_mm} mm)")
    if isinstance(lights, PointLights) and np.any(lights.positions[:, 2] <= ref):
        raise InputError(f"reference_height_mm: {ref} mm is not below every light")
    return _solve_nearfield(
        imgs, lights, camera, intens, m, g, outliers, dark, saturation, highlight, integrator, ref,
        float(tolerance_mm), int(max_iterations), int(coarse_pixels), threads, setup=setup,
        correction_step=int(correction_step), residual=bool(residual),
        estimate_intensities=bool(estimate_intensities),
    )


def _solve_nearfield(
    imgs: np.ndarray,
    lights,
    camera: Camera,
    intens: np.ndarray,
    mask: np.ndarray | None,
    gains: np.ndarray | None,
    outliers: bool,
    dark: float,
    saturation: float,
    highlight: float | None,
    integrator: str,
    reference_height_mm: float,
    tolerance_mm: float,
    max_iterations: int,
    coarse_pixels: int,
    threads: int | None,
    *,
    setup: NearFieldSetup | None = None,
    correction_step: int = CORRECTION_STEP,
    residual: bool = True,
    estimate_intensities: bool = False,
) -> NearFieldResult:
    """:func:`solve_nearfield` on checked input (the pipeline calls this)."""
    if not isinstance(lights, PointLights):
        if estimate_intensities:
            raise InputError("estimate_intensities: needs point lights (LED positions), not distant lights")
        res = _directional(imgs, lights, camera, intens, mask, outliers, dark, saturation, highlight,
                           integrator, reference_height_mm)
        return res if residual else replace(res, residual=None)
    n_img, height, width = imgs.shape[:3]
    shape = (height, width)
    m = np.ones(shape, bool) if mask is None else mask
    flat = gains is not None or (setup is not None and setup.flat_field)
    opts = _Options(outliers, dark, saturation, highlight, 2, lights.mu_known or not flat, residual)
    u, v = pixel_offsets(camera, shape)
    divide = np.ones_like(intens) if flat else intens
    own = imgs.ndim == 3 and bool(np.all(divide.mean(axis=1) == 1.0))
    fine = _Level(
        # grey images with unit intensities are their own planes: no copy of the stack
        planes=imgs if own else np.stack(_grey_planes(imgs, divide)),
        strength=setup.strength if setup is not None else _strengths(lights, camera, shape, gains, intens),
        mask=m,
        saturated=_saturated(imgs, saturation) if outliers else None,
        u=u,
        v=v,
        step=1,
        colour=None,
    )
    if imgs.ndim == 4:
        fine.colour = imgs / divide[:, None, None, :].astype(np.float32)
    workers = threads if threads is not None else min(4, os.cpu_count() or 1)
    timings = {"solve": 0.0, "integrate": 0.0}
    history: list[dict] = []
    zt = _z_dtype(camera)
    z = np.full(shape, reference_height_mm, zt)
    r = _coarse_step(shape, coarse_pixels)
    args = (lights, camera, opts, integrator, reference_height_mm, tolerance_mm, max_iterations)
    estimate = None
    with ThreadPoolExecutor(max_workers=max(1, int(workers))) as pool:
        if r > 1:
            coarse = _coarsen(fine, r, None if setup is None else setup.coarse.get(r))
            state = _alternate(coarse, *args, np.full(coarse.shape, reference_height_mm, zt), pool, timings, history)
            if estimate_intensities:
                state, scale, estimate = _estimate_intensities(coarse, state, *args, pool, timings, history)
                _rescale(fine, scale)
            z = _upsample(state["z"], r, shape)
        elif estimate_intensities:
            state = _alternate(fine, *args, z, pool, timings, history)
            state, scale, estimate = _estimate_intensities(fine, state, *args, pool, timings, history)
            z = state["z"]
        state = _alternate(fine, *args, z, pool, timings, history, correction_step)
    if estimate is not None:
        # with a flat field the gains hold the power: the scales are relative to them
        e = (np.ones(n_img) if flat else intens.mean(axis=1)) * scale
        d0 = lights.d0
        estimate.update(relative=e.tolist(), radiant_relative=(e * d0**2 / (e[0] * d0[0] ** 2)).tolist(),
                        level="coarse" if r > 1 else "full", block_px=r)
    sol, z = state["sol"], state["z"]
    valid = sol["valid"]
    normals = cv2.merge(list(sol["normals"]))
    lu, lv = state["grad"]
    if isinstance(camera, Orthographic):
        # the last pass's slopes of the same normals, already zero where not valid: not computed again
        p, q = lu, lv
        if state["record"] is None:
            np.copyto(p, 0.0, where=~valid)
            np.copyto(q, 0.0, where=~valid)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(valid, -sol["normals"][0] / sol["normals"][2], np.float32(0.0)).astype(np.float32)
            q = np.where(valid, -sol["normals"][1] / sol["normals"][2], np.float32(0.0)).astype(np.float32)
    return NearFieldResult(
        normals=normals,
        albedo=sol["albedo"] if sol["albedo"] is not None else sol["rho"],
        valid=valid,
        residual=sol["residual"],
        p=p,
        q=q,
        height=np.where(valid, z, np.float64(np.nan)),  # float64 whatever the alternation's dtype
        xy=surface_xy(camera, z),
        footprint_mm2=footprint_area(camera, z, lu, lv),
        outliers=sol["outliers"],
        depth_change_mm=state["change"],
        iterations=len(history),
        history=tuple(history),
        anchor={"rule": ANCHOR_RULE, "reference_height_mm": reference_height_mm},
        timings_s=timings,
        intensities=estimate,
    )


def _points(level: _Level, camera: Camera, z: np.ndarray):
    """``x, y, z`` (float32 planes, mm) of the points a level's pixels see at heights ``z``."""
    f32 = np.float32
    zz = z.astype(f32)
    x = np.broadcast_to(level.u[None, :], zz.shape).astype(f32)
    y = np.broadcast_to(level.v[:, None], zz.shape).astype(f32)
    if isinstance(camera, Perspective):
        scale = (f32(camera.camera_height_mm) - zz) * f32(1.0 / camera.focal_length_px)
        x, y = x * scale, y * scale
    return x, y, zz


def _intensity_scales(level: _Level, lights: PointLights, camera: Camera, z: np.ndarray, sol: dict,
                      opts: _Options) -> tuple[np.ndarray, int]:
    """Per LED the least-squares scale ``f_k = sum x_k m_k / sum m_k^2`` of the level's observations
    ``x_k`` over the model ``m_k = rho max(0, s_k . n)`` of the solved normals and albedo, over the valid
    pixels that LED lights well (``m_k > dark rho |s_k|``) and does not saturate. Returns the scales
    (float64, (N,)) and the fewest pixels any LED's scale used."""
    x, y, zz = _points(level, camera, z)
    valid = sol["valid"]
    rho = sol["rho"][valid]
    nrm = [c[valid] for c in sol["normals"]]
    x, y, zz = x[valid], y[valid], zz[valid]
    out = np.ones(len(lights))
    fewest = valid.size
    for k in range(len(lights)):
        strength = level.strength[k]
        if np.ndim(strength):
            strength = strength[valid]
        sx, sy, sz = _scaled_vectors(lights.positions[k], lights.axes[k], float(lights.mu[k]), strength, x, y, zz,
                                     lobe=opts.lobe)
        shade = sx * nrm[0] + sy * nrm[1] + sz * nrm[2]
        e = np.sqrt(sx * sx + sy * sy + sz * sz)
        use = shade > np.float32(opts.dark) * e
        if level.saturated is not None:
            use &= ~level.saturated[k][valid]
        model = (rho * shade)[use].astype(np.float64)
        obs = level.planes[k][valid][use].astype(np.float64)
        fewest = min(fewest, int(use.sum()))
        den = float(model @ model)
        if den > 0:
            out[k] = float(obs @ model) / den
    return out, fewest


def _rescale(level: _Level, scale: np.ndarray, base: tuple | None = None) -> None:
    """Divide a level's observations (``base``: its planes and colour before any scale, default its
    own) by per-LED scales (new arrays: the level's planes may be the caller's images)."""
    planes, colour = (level.planes, level.colour) if base is None else base
    level.planes = np.stack([planes[k] / np.float32(scale[k]) for k in range(len(scale))])
    if colour is not None:
        level.colour = colour / scale[:, None, None, None].astype(np.float32)


def _estimate_intensities(level: _Level, state: dict, lights, camera, opts, integrator, ref, tol, max_iterations,
                          pool, timings, history) -> tuple[dict, np.ndarray, dict]:
    """The semi-calibrated alternation on one level (Queau et al. 2018): from a converged ``state``, fit
    one scale per LED (:func:`_intensity_scales`, LED 0 fixed), divide the observations by it and run
    the normal/height passes again, until no scale changes by :data:`INTENSITY_TOLERANCE`. Returns the
    last state, the scales (N,) and the estimation's record."""
    base = (level.planes, level.colour)
    scale = np.ones(len(lights))
    change = np.inf
    rounds = 0
    fewest = 0
    # the LED directions at the field centre: a ramp of the powers across them is what a tilt of the part
    # trades for (the semi-calibrated problem's near-ambiguity), removed by levelling the part
    to_led = lights.positions - np.array([0.0, 0.0, ref])
    ramp = to_led[:, :2] / to_led[:, 2:3]
    tilt = 0.0
    while rounds < INTENSITY_ROUNDS:
        f, fewest = _intensity_scales(level, lights, camera, state["z"], state["sol"], opts)
        if fewest < 3 or not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise InputError("estimate_intensities: too few lit, valid pixels to estimate every LED's intensity "
                             f"(fewest {fewest}); give the intensities or a flat field")
        if LEVEL_PART:
            slope = _mean_slope(state["sol"])
            tilt = float(np.degrees(np.arctan(np.hypot(*slope))))
            f = f * np.maximum(1.0 + ramp @ slope, 1e-3)
        f = f / f[0]
        scale *= f
        rounds += 1
        change = float(np.max(np.abs(f - 1.0)))
        _rescale(level, scale, base)
        state = _alternate(level, lights, camera, opts, integrator, ref, tol, max_iterations, state["z"], pool,
                           timings, history)
        if change < INTENSITY_TOLERANCE:
            break
    record = {"rounds": rounds, "final_change": change, "tolerance": INTENSITY_TOLERANCE,
              "converged": bool(change < INTENSITY_TOLERANCE), "pixels": int(fewest)}
    if LEVEL_PART:
        record.update(levelling=LEVEL_RULE, last_tilt_removed_deg=tilt)
    return state, scale, record


def _mean_slope(sol: dict) -> np.ndarray:
    """Mean ``(n_x / n_z, n_y / n_z)`` of the valid pixels' normals (minus the part's overall slope):
    a normal tilted by it reads ``1 + l_x n_x / (l_z n_z) + ...`` of a level one's shading."""
    valid = sol["valid"] & (sol["normals"][2] > 0)
    if not valid.any():
        return np.zeros(2)
    nz = sol["normals"][2][valid].astype(np.float64)
    return np.array([float(np.mean(sol["normals"][0][valid] / nz)), float(np.mean(sol["normals"][1][valid] / nz))])


def _z_dtype(camera: Camera):
    """dtype of the heights between passes: float32 for the orthographic camera (``z`` = the field
    plus a constant, rounded by at most ``2**-24 |z|``, 6e-9 mm at 0.1 mm: far below the tolerance,
    and every whole-image pass moves half the bytes); float64 for the perspective one, whose
    ``z = H_c - w`` would lose ``2**-24 H_c`` (1.8e-5 mm at 300 mm) to float32."""
    return np.float32 if isinstance(camera, Orthographic) else np.float64


def _directional(imgs, L, camera, intens, mask, outliers, dark, saturation, highlight, integrator,
                 ref) -> NearFieldResult:
    """Distant lights: the far-field solve (:func:`photometric.stereo.solve`), then one
    integration in the camera's field and the anchor."""
    shape = imgs.shape[1:3]
    t0 = time.perf_counter()
    res = _solve(imgs, L, intens, mask, outliers, dark, saturation, highlight, 2)
    t1 = time.perf_counter()
    u, v = pixel_offsets(camera, shape)
    level = _Level([], [], np.ones(shape, bool) if mask is None else mask, None, u, v, 1)
    if not res.valid.any():
        raise InputError("images: no pixel has a valid normal (check the lights, the mask and the images)")
    planes = np.moveaxis(res.normals, -1, 0)
    z, (lu, lv), _ = _height(level, camera, planes, res.valid, integrator, ref,
                             max(1, int(np.sqrt(res.valid.size / 250_000))))
    t2 = time.perf_counter()
    return NearFieldResult(
        normals=res.normals,
        albedo=res.albedo,
        valid=res.valid,
        residual=res.residual,
        p=res.p,
        q=res.q,
        height=np.where(res.valid, z, np.float64(np.nan)),
        xy=surface_xy(camera, z),
        footprint_mm2=footprint_area(camera, z, lu, lv),
        outliers=res.outliers,
        depth_change_mm=None,
        iterations=1,
        history=({"level": "full", "step": 1, "depth_change_mm": None,
                  "valid_fraction": float(res.valid.sum() / max(int(level.mask.sum()), 1))},),
        anchor={"rule": ANCHOR_RULE, "reference_height_mm": ref},
        timings_s={"solve": t1 - t0, "integrate": t2 - t1},
    )


def _strengths(lights: PointLights, camera: Camera, shape, gains, intens) -> list:
    """``E_k = strength_k * lobe_k(X) / |P_k - X|^2``: ``d0_k^2`` (intensities divided out), or
    with a flat field ``G_k |P_k - X0|^2`` (divided by the lobe at ``X0`` when it is known)."""
    if gains is None:
        return [float(d * d) for d in lights.d0]
    X0 = plane_points(camera, shape)
    # one contiguous float32 plane per coordinate: elementwise sums instead of an einsum and a
    # matrix product over an interleaved (H, W, 3) array per light
    planes = [np.ascontiguousarray(X0[..., c], dtype=np.float32) for c in range(3)]
    del X0
    out = []
    for k in range(len(lights)):
        pos = lights.positions[k].astype(np.float32)
        d = [pos[c] - planes[c] for c in range(3)]
        r2 = d[0] * d[0]
        r2 += d[1] * d[1]
        r2 += d[2] * d[2]
        q = gains[k] * r2
        if lights.mu_known and lights.mu[k] > 0:
            axis = lights.axes[k].astype(np.float32)
            cos = d[0] * axis[0]
            cos += d[1] * axis[1]
            cos += d[2] * axis[2]
            cos /= np.sqrt(r2)
            np.negative(cos, out=cos)
            lobe = np.maximum(cos, 0.0, out=cos) ** np.float32(lights.mu[k])
            q = np.divide(q, lobe, out=np.zeros_like(q), where=lobe > 0)
        out.append(q.astype(np.float32, copy=False))
    return out


def _saturated(imgs: np.ndarray, saturation: float) -> np.ndarray:
    src = imgs.max(axis=3) if imgs.ndim == 4 else imgs
    return src >= saturation


def _block_mean(a: np.ndarray, r: int) -> np.ndarray:
    h, w = a.shape[0] // r, a.shape[1] // r
    return a[: h * r, : w * r].reshape(h, r, w, r, *a.shape[2:]).mean(axis=(1, 3), dtype=np.float32)


def _coarsen(fine: _Level, r: int, strength: list | None = None) -> _Level:
    """The level averaged in ``r x r`` blocks (trailing rows/columns dropped); a block is in
    the mask when all its pixels are, saturated when any is (``strength``: the block-averaged
    strengths when prepared, :class:`NearFieldSetup`)."""
    h, w = fine.shape[0] // r, fine.shape[1] // r
    # a whole-image mask (the usual inspection) needs no block reduction
    mask = (np.ones((h, w), bool) if fine.mask.all()
            else fine.mask[: h * r, : w * r].reshape(h, r, w, r).all(axis=(1, 3)))
    sat = None
    if fine.saturated is not None:
        sat = fine.saturated[:, : h * r, : w * r].reshape(-1, h, r, w, r).any(axis=(2, 4))
    planes = np.empty((len(fine.planes), h, w), np.float32)
    for k, pl in enumerate(fine.planes):
        # block means by OpenCV's area resampling (an integer factor on the cropped image): one
        # pass, where numpy's mean over two axes of a reshaped copy takes several
        planes[k] = cv2.resize(pl[: h * r, : w * r], (w, h), interpolation=cv2.INTER_AREA)
    return _Level(
        planes=planes,
        strength=strength if strength is not None else [s if np.ndim(s) == 0 else _block_mean(s, r)
                                                        for s in fine.strength],
        mask=mask,
        saturated=sat,
        u=fine.u[: w * r].reshape(w, r).mean(axis=1),
        v=fine.v[: h * r].reshape(h, r).mean(axis=1),
        step=r,
    )


def _upsample(z: np.ndarray, r: int, shape) -> np.ndarray:
    """Bilinear from block centres to pixel centres (cv2 maps ``(i + 0.5) / r - 0.5``),
    edge values carried into the dropped rows and columns."""
    up = cv2.resize(z, (z.shape[1] * r, z.shape[0] * r), interpolation=cv2.INTER_LINEAR)
    if up.shape == tuple(shape):
        return up
    return cv2.copyMakeBorder(up, 0, shape[0] - up.shape[0], 0, shape[1] - up.shape[1], cv2.BORDER_REPLICATE)


def _alternate(level, lights, camera, opts, integrator, ref, tol, max_iterations, z, pool, timings,
               history, correction_step: int = 1) -> dict:
    """Passes at one level from heights ``z`` until the largest change of a pixel valid in both
    passes is below ``tol``; :class:`NotConvergedError` after ``max_iterations`` passes, or
    when the heights are no longer finite or reach a light."""
    name = "full" if level.step == 1 else "coarse"
    prev_valid = None
    sample = max(1, int(np.sqrt(level.mask.size / 250_000)))
    top = float(lights.positions[:, 2].min())
    sol = z_solved = None  # the normals and the heights they were solved at
    last = None  # the previous pass's integration (:func:`_height`)
    since = None  # |z - z_solved| when the last pass computed it
    in_mask = max(np.count_nonzero(level.mask), 1)
    for _ in range(max_iterations):
        t0 = time.perf_counter()
        if z_solved is not None:
            gap = since if since is not None else cv2.absdiff(z, z_solved)
            moved = level.mask & (gap > RESOLVE_FRACTION * tol)
        else:
            moved = None
        n_moved = in_mask if moved is None else np.count_nonzero(moved)
        if moved is None or n_moved > in_mask // 2:
            sol = _normals(level, lights, camera, z, opts, pool, final=name == "full")
            z_solved = z
        elif n_moved:
            idx = np.flatnonzero(moved)
            part = _normals(_gather(level, idx), lights, camera, _take(z, idx, level.shape[1]), opts, pool,
                            final=name == "full")
            _scatter(sol, part, idx)
            z_solved = np.where(moved, z, z_solved)
        timings["solve"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        valid = sol["valid"]
        if not valid.any():
            raise InputError("images: no pixel has a valid normal (check the lights, the mask and the images)")
        # a partial re-solve at full resolution changes the slopes of few pixels by little: its
        # correction is integrated on a decimated grid, unless it comes near the tolerance
        correct = last is not None and name == "full" and n_moved <= in_mask // 2 and correction_step > 1
        z_new, grad, record = _height(level, camera, sol["normals"], valid, integrator, ref, sample,
                                      last if correct else None, correction_step)
        both = valid if prev_valid is None else valid & prev_valid
        if not both.any():
            both = valid
        step = cv2.absdiff(z_new, z)
        change = _largest(step, both)
        if correct and not change < CORRECTION_MARGIN * tol:
            z_new, grad, record = _height(level, camera, sol["normals"], valid, integrator, ref, sample)
            step = cv2.absdiff(z_new, z)
            change = _largest(step, both)
        # after a whole-level solve the next pass's height moves since the solve are this step
        since = step if z_solved is z else None
        last = record
        timings["integrate"] += time.perf_counter() - t0
        history.append({"level": name, "step": level.step, "depth_change_mm": change,
                        "valid_fraction": float(np.count_nonzero(valid) / in_mask),
                        "resolved_fraction": float(n_moved / in_mask)})
        z, prev_valid = z_new, valid.copy()  # the next pass updates sol in place
        highest = float(z.max())  # NaN when any height is not finite
        if not (np.isfinite(change) and np.isfinite(highest)) or highest >= top:
            raise NotConvergedError(
                f"near-field solve diverged at pass {len(history)} ({name} level): the heights "
                + ("reach a light" if np.isfinite(highest) else "are not finite"),
                _history_summary(history, tol, False),
            )
        if change < tol:
            return {"z": z, "sol": sol, "grad": grad, "change": change, "record": record}
    raise NotConvergedError(
        f"near-field solve did not converge: height change {change:.3g} mm after {max_iterations} passes "
        f"at the {name} level (tolerance {tol:g} mm)",
        _history_summary(history, tol, False),
    )


def _take(a: np.ndarray, idx: np.ndarray, width: int) -> np.ndarray:
    """The pixels ``idx`` (flat indices into the trailing (h, w) of ``a``, leading axes kept) laid out
    in rows of ``width``; the last row is padded with the last pixel (:func:`_gather`)."""
    lead = a.shape[:-2]
    rows = -(-idx.size // width)
    flat = a.reshape((-1, a.shape[-2] * a.shape[-1]))
    out = np.empty((flat.shape[0], rows * width), a.dtype)
    # one 1-D take per plane: several times faster than a take along the last axis of the stack
    for src, dst in zip(flat, out):
        np.take(src, idx, out=dst[: idx.size], mode="clip")  # the indices are valid: no bounds buffer
        dst[idx.size :] = src[idx[-1]]
    return out.reshape(lead + (rows, width))


def _largest(step: np.ndarray, where: np.ndarray) -> float:
    """The largest of ``step`` (>= 0) where ``where`` holds (0 when nowhere); a plain maximum when it holds
    everywhere (a masked reduction is four times slower)."""
    if where.all():
        return float(step.max())
    return float(np.max(step, where=where, initial=0.0))


def _gather(level: _Level, idx: np.ndarray) -> _Level:
    """The pixels ``idx`` (flat indices, all in the mask: they were selected from it) as a level of
    rows as wide as ``level`` with per-pixel offsets, so that :func:`_normals` solves them in
    cache-sized blocks as it does a whole image; the padding at the end is outside its mask."""
    w = level.shape[1]
    rows = -(-idx.size // w)
    mask = np.zeros(rows * w, bool)
    mask[: idx.size] = True
    pix_r, pix_c = np.divmod(idx, w)
    return _Level(
        planes=_take(level.planes, idx, w),
        strength=[s if np.ndim(s) == 0 else _take(s, idx, w) for s in level.strength],
        mask=mask.reshape(rows, w),
        saturated=None if level.saturated is None else _take(level.saturated, idx, w),
        u=_take(level.u[None, :], pix_c, w),
        v=_take(level.v[None, :], pix_r, w),
        step=level.step,
        colour=None if level.colour is None else np.stack([_take(level.colour[..., c], idx, w) for c in range(3)],
                                                          axis=-1),
    )


def _scatter(sol: dict, part: dict, idx: np.ndarray) -> None:
    """Write the solve of gathered pixels (:func:`_gather`) back into a whole-level solve."""
    n = idx.size
    for key, value in part.items():
        if value is None:
            continue
        if key in ("normals", "outliers"):
            target = sol[key].reshape(sol[key].shape[0], -1)
            target[:, idx] = value.reshape(value.shape[0], -1)[:, :n]
        else:
            trail = value.shape[2:]
            target = sol[key].reshape((-1,) + trail)
            target[idx] = value.reshape((-1,) + trail)[:n]


def _history_summary(history: list, tol: float, converged: bool) -> dict:
    """The convergence record of ``summary.json``."""
    return {
        "converged": converged,
        "iterations": len(history),
        "final_depth_change_mm": history[-1]["depth_change_mm"] if history else None,
        "tolerance_mm": tol,
        "history": list(history),
    }


def _height(level: _Level, camera: Camera, normals: np.ndarray, valid: np.ndarray, integrator: str, ref: float,
            sample: int, last: dict | None = None, correction_step: int = 1):
    """Integrate the normals of a level and anchor the heights (filled where not valid).

    Returns ``z``, the slopes ``(p, q)`` and, for the spectral integrators (``dct``, ``fc``),
    what a later pass needs to integrate only its change (``{"pz", "qz", "field"}``, else
    None). With ``last`` (that record of the previous pass) and ``correction_step`` r > 1 the
    slope change since ``last`` is block-averaged in r x r blocks, integrated on that grid and
    upsampled onto the previous field (see :data:`CORRECTION_STEP`).
    """
    from photometric.integrate import dct_poisson, frankot_chellappa, least_squares, robust_least_squares

    p, q, spacing = _gradient(camera, normals[0], normals[1], normals[2], level.u, level.v)
    spacing *= level.step
    keep = None
    if integrator in ("lsq", "robust"):
        fld = (least_squares if integrator == "lsq" else robust_least_squares)(p, q, valid, spacing)
    else:
        if isinstance(camera, Orthographic):
            # the slopes themselves, zero where not valid: masked in place (they are the solve's p, q)
            off = ~valid
            np.copyto(p, 0.0, where=off)
            np.copyto(q, 0.0, where=off)
            del off
            pz, qz = p, q
        else:
            # the perspective log-depth derivatives stay unmasked for the footprint
            zero = np.float32(0.0)
            pz = np.where(valid, p, zero)
            qz = np.where(valid, q, zero)

        def solve(a, b, h):
            if integrator == "dct":
                # float32 in, float32 out: the solve runs in place in blocks (no float64 copy of the field)
                return dct_poisson(a, b, None, h, dtype=np.float32, result_dtype=np.float32)
            return frankot_chellappa(a, b, None, h)

        r = int(correction_step)
        if last is not None and r > 1:
            h, w = pz.shape[0] // r, pz.shape[1] // r
            # block means by OpenCV's area resampling (an integer factor on the cropped image)
            dp, dq = (cv2.resize(np.subtract(a[: h * r, : w * r], b[: h * r, : w * r]), (w, h),
                                 interpolation=cv2.INTER_AREA) for a, b in ((pz, last["pz"]), (qz, last["qz"])))
            fld = last["field"]  # the previous pass's field is not used again: corrected in place
            fld += _upsample(solve(dp, dq, spacing * r).astype(np.float32), r, pz.shape)
        else:
            fld = solve(pz, qz, spacing)
        keep = {"pz": pz, "qz": qz, "field": fld}
    z, _ = depth_from_field(camera, fld, valid=valid, reference_height_mm=ref, sample_step=sample,
                            dtype=_z_dtype(camera))
    if integrator in ("lsq", "robust"):
        z = np.where(np.isfinite(z), z, ref)
    return z, (p, q), keep


def _normals(level: _Level, lights: PointLights, camera: Camera, z: np.ndarray, opts: _Options, pool,
             final: bool) -> dict:
    """One whole-image solve at the points of heights ``z``: blocks of rows on the pool."""
    h, w = level.shape
    n = len(lights)
    out = {
        "normals": np.empty((3, h, w), np.float32),
        "rho": np.empty((h, w), np.float32),
        "valid": np.empty((h, w), bool),
        "residual": np.zeros((h, w), np.float32) if (final and opts.residual) else None,
        "outliers": np.zeros((n, h, w), bool) if (final and opts.outliers) else None,
        "albedo": np.empty((h, w, 3), np.float32) if (final and level.colour is not None) else None,
    }
    rows = max(1, BLOCK_PIXELS // w)
    blocks = [(r0, min(h, r0 + rows)) for r0 in range(0, h, rows)]
    list(pool.map(lambda b: _block(level, lights, camera, z, opts, b[0], b[1], out, final), blocks))
    return out


def _block(level: _Level, lights: PointLights, camera: Camera, z: np.ndarray, opts: _Options, r0: int, r1: int,
           out: dict, final: bool) -> None:
    """Light vectors, normal equations and the closed-form 3 x 3 solve for rows ``r0:r1``.

    The light vectors stay one (h, w) plane per light and component as
    :func:`photometric.leds._scaled_vectors` returns them (an ``(N, 3, h, w)`` array only in
    the outlier mode, which indexes them by pixel), and the normals, albedo and validity are
    written straight into ``out``: every pass over the block is arithmetic.
    """
    f32 = np.float32
    zz = z[r0:r1].astype(f32)
    # offsets per column and row, or per pixel for a gathered level (:func:`_gather`)
    u = level.u[None, :] if level.u.ndim == 1 else level.u[r0:r1]
    v = level.v[r0:r1, None] if level.v.ndim == 1 else level.v[r0:r1]
    x, y = u.astype(f32), v.astype(f32)
    if isinstance(camera, Perspective):
        scale = (f32(camera.camera_height_mm) - zz) * f32(1.0 / camera.focal_length_px)
        x, y = x * scale, y * scale
    n = len(lights)
    vecs = []
    for k in range(n):
        strength = level.strength[k]
        if np.ndim(strength):
            strength = strength[r0:r1]
        vecs.append(_scaled_vectors(lights.positions[k], lights.axes[k], float(lights.mu[k]), strength, x, y, zz,
                                    lobe=opts.lobe))
    S = np.array(vecs, f32) if opts.outliers else None
    sx, sy, sz = ([vk[c] for vk in vecs] for c in range(3))
    del vecs
    X = level.planes[:, r0:r1]
    mask = level.mask[r0:r1]
    g_all, ok_all = _solve3(sx, sy, sz, X, None)
    g, ok = g_all, ok_all & mask
    weights = None
    if opts.outliers:
        E = np.sqrt(_kdot(S, S, axis=1))
        sat = level.saturated[:, r0:r1]
        for _ in range(opts.rounds):
            rho = np.sqrt(_kdot(g, g))
            bad = (X < f32(opts.dark) * rho * E) | sat
            if opts.highlight is not None:
                bad |= (X - _kdot(S, g[None], axis=1)) > f32(opts.highlight) * rho * E
            if n == 3:
                ok = ok_all & mask & ~bad.any(axis=0)
                break
            weights = (~bad).astype(f32)
            g_new, ok_new = _solve3(sx, sy, sz, X, weights)
            ok = ok_new & mask & (weights.sum(axis=0) >= 3)
            some = ok & bad.any(axis=0)
            if some.any():
                ok[some] = _conditioned(S[:, :, some], E[:, some], weights[:, some])
            # pixels left without a trustworthy re-solve keep the all-lights normal (marked invalid)
            g = np.where(ok[None], g_new, g_all)
        if out["outliers"] is not None:
            out["outliers"][:, r0:r1] = bad & mask[None]
    rho = out["rho"][r0:r1]
    np.sqrt(_kdot(g, g), out=rho)
    # a normal needs a positive, finite length (NaN fails both comparisons)
    blank = ~(mask & (rho > 0) & (rho < np.inf))
    nrm = out["normals"][:, r0:r1]
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(g, rho[None], out=nrm)
    nrm[:, blank] = 0.0
    nrm[2, blank] = 1.0
    rho[blank] = 0.0
    ok &= ~blank & (nrm[2] > 0)
    out["valid"][r0:r1] = ok
    if not final:
        return
    if out["residual"] is not None:
        _residual(sx, sy, sz, X, nrm * rho[None], weights, blank, out["residual"][r0:r1])
    if out["albedo"] is not None:
        shade = np.empty((n,) + nrm.shape[1:], f32)
        for k in range(n):
            np.multiply(sx[k], nrm[0], out=shade[k])
            shade[k] += sy[k] * nrm[1]
            shade[k] += sz[k] * nrm[2]
        if weights is not None:
            shade *= weights
        num = np.einsum("khwc,khw->hwc", level.colour[:, r0:r1], shade)
        den = _kdot(shade, shade)
        alb = np.divide(num, den[..., None], out=np.zeros_like(num), where=den[..., None] > 0)
        alb[blank] = 0.0
        out["albedo"][r0:r1] = alb


def _residual(sx, sy, sz, X: np.ndarray, g: np.ndarray, weights: np.ndarray | None, blank: np.ndarray,
              res: np.ndarray) -> None:
    """RMS over the lights used of ``x_k - s_k . g`` into ``res`` (0 where ``blank``), accumulated per
    light in light order."""
    sq = None
    for k in range(len(sx)):
        e = sx[k] * g[0]
        e += sy[k] * g[1]
        e += sz[k] * g[2]
        np.subtract(X[k], e, out=e)
        if weights is not None:
            e *= weights[k]
        if sq is None:
            sq = np.multiply(e, e)
        else:
            sq += np.multiply(e, e, out=e)
    count = np.maximum(weights.sum(axis=0), 1.0) if weights is not None else np.float32(len(sx))
    np.sqrt(np.divide(sq, count, out=sq), out=res)
    res[blank] = 0.0


def _solve3(sx, sy, sz, X: np.ndarray, weights: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel ``g`` of ``(sum_k w_k s_k s_k^T) g = sum_k w_k x_k s_k`` (cofactors; float32).

    ``sx, sy, sz``: per light the (h, w) components of ``s_k`` (sequences or (N, h, w) arrays),
    ``X`` (N, h, w), ``weights`` (N, h, w) or None. Returns ``g`` (3, h, w) and where the
    system is regular (positive determinant).
    """
    if weights is not None:
        wx, wy, wz = ([s[k] * weights[k] for k in range(len(s))] for s in (sx, sy, sz))
    else:
        wx, wy, wz = sx, sy, sz
    a00 = _kdot(wx, sx)
    a01 = _kdot(wx, sy)
    a02 = _kdot(wx, sz)
    a11 = _kdot(wy, sy)
    a12 = _kdot(wy, sz)
    a22 = _kdot(wz, sz)
    b0 = _kdot(wx, X)
    b1 = _kdot(wy, X)
    b2 = _kdot(wz, X)
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    trace = a00 + a11 + a22
    ok = det > np.float32(1e-9) * trace * trace * trace
    inv = np.divide(np.float32(1.0), det, out=np.zeros_like(det), where=ok)
    g = np.empty((3,) + det.shape, np.float32)
    np.multiply(c00 * b0 + c01 * b1 + c02 * b2, inv, out=g[0])
    np.multiply(c01 * b0 + c11 * b1 + c12 * b2, inv, out=g[1])
    np.multiply(c02 * b0 + c12 * b1 + c22 * b2, inv, out=g[2])
    return g, ok


def _kdot(a, b, axis: int = 0) -> np.ndarray:
    """``sum(a * b, axis)`` over a short axis (lights or components), accumulated in place:
    twice as fast as ``einsum`` on float32 image blocks. ``a`` and ``b`` may be sequences of
    equal-shape planes (``axis`` 0)."""
    if axis:
        a, b = np.moveaxis(a, axis, 0), np.moveaxis(b, axis, 0)
    out = np.multiply(a[0], b[0])
    tmp = np.empty_like(out)
    for i in range(1, max(len(a), len(b))):
        out += np.multiply(a[i if len(a) > 1 else 0], b[i if len(b) > 1 else 0], out=tmp)
    return out


def _conditioned(S: np.ndarray, E: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Inlier light directions of each pixel conditioned as :data:`photometric.stereo.MAX_CONDITION`
    asks (singular values of the unit directions used). ``S`` (N, 3, P), ``E``, ``weights`` (N, P)."""
    unit = S / np.where(E > 0, E, 1.0)[:, None]
    M = np.einsum("kp,kip,kjp->pij", weights, unit, unit).astype(np.float64)
    lam = np.linalg.eigvalsh(M)
    return (lam[:, 0] > 0) & (lam[:, 2] <= MAX_CONDITION**2 * lam[:, 0])
