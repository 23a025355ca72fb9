"""A calibrated near-field rig: LEDs, camera, flat-field gains; ``rig.json`` read and described.

``rig.json`` (format ``"workbench-rig"``, version 1; what ``workbench photometric
reconstruct --rig`` reads and ``workbench photometric calibrate`` writes)::

    {"format": "workbench-rig", "version": 1,
     "lights": {"positions_mm": [[x, y, z], ...], "axes": [[ax, ay, az], ...] or null,
                "mu": [...] or null, "intensities": [...] or null},
     "camera": {"model": "orthographic", "pixel_size_mm": 0.05}
            or {"model": "perspective", "focal_length_px": 2400, "camera_height_mm": 300,
                "principal_point_px": [cx, cy]},
     "image_size": [H, W],
     "flat_field": {"gains": "rig_gains.npz", "albedo": 0.8, "smoothing_px": 2.0} or null,
     "calibration": {"method": "...", "residuals_mm": [...], ...}}

Paths inside are relative to the ``rig.json`` file; the gains file holds one array
``gains`` (N, H, W) float32. With a flat field the LED axes and exponents need not be
known: the measured gains replace the modelled lobe, the falloff on the reference plane,
vignetting and the LED power (:func:`flat_field_gains`).

Writing files is the workbench's job (``workbench.runs.photometric.write_rig``); this
module computes, reads and describes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from photometric.camera import Camera, camera_from_dict, plane_points
from photometric.leds import PointLights, point_lights
from photometric.lights import as_intensities
from photometric.stereo import _check_images, _grey_planes
from surfaces.validate import as_array, InputError, positive, reads_file

__all__ = ["RIG_FORMAT", "RIG_VERSION", "GAINS_FILE", "FLAT_SMOOTHING_PX", "RIG_KEYS", "Rig", "flat_field_gains",
           "rig_to_dict", "read_rig", "check_rig", "loads_unique", "at_camera_height", "position_u_mm"]

#: the keys rig.json may hold: top level, ``lights``, ``flat_field`` and ``camera``
RIG_KEYS = {
    "": ("format", "version", "lights", "camera", "image_size", "flat_field", "calibration", "quality",
         "reflectance"),
    "lights": ("positions_mm", "axes", "mu", "intensities"),
    "flat_field": ("gains", "albedo", "smoothing_px"),
    "camera": ("model", "pixel_size_mm", "focal_length_px", "focal_length_y_px", "camera_height_mm",
               "principal_point_px", "distortion"),
}


def loads_unique(text: str, where: str):
    """Parse JSON text, refusing an object that repeats a key (``json`` would keep the last silently).

    Parameters
    ----------
    text : str
        JSON text.
    where : str
        What it is, for messages (e.g. ``"rig rig.json"``).

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    InputError
        Not valid JSON, or a repeated key (named).

    Examples
    --------
    >>> loads_unique('{"a": 1, "b": {"c": 2}}', "doc")
    {'a': 1, 'b': {'c': 2}}
    >>> loads_unique('{"a": 1, "a": 2}', "spec s.json")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: spec s.json: key 'a' is given twice (JSON keeps only the last; remove one)
    """

    def unique(pairs):
        seen = set()
        for key, _ in pairs:
            if key in seen:
                raise InputError(f"{where}: key {key!r} is given twice (JSON keeps only the last; remove one)")
            seen.add(key)
        return dict(pairs)

    try:
        return json.loads(text, object_pairs_hook=unique)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{where} is not valid JSON ({exc})") from None


def _refuse_unknown(doc: dict, section: str, where: str) -> None:
    unknown = [k for k in doc if k not in RIG_KEYS[section]]
    if unknown:
        name = f"{section} " if section else ""
        raise InputError(f"{where}: unknown {name}key {unknown[0]!r} (known: {', '.join(RIG_KEYS[section])})")

RIG_FORMAT = "workbench-rig"
RIG_VERSION = 1
#: Default name of the gains file beside ``rig.json``.
GAINS_FILE = "rig_gains.npz"
#: Default Gaussian smoothing of the gain maps, pixels (sigma): image noise of the flat
#: images would otherwise add to every reconstruction; falloff, lobe and vignetting are
#: smooth over many pixels.
FLAT_SMOOTHING_PX = 2.0


@dataclass(frozen=True)
class Rig:
    """A near-field rig: what :func:`read_rig` returns and ``calibrate`` produces.

    Attributes
    ----------
    lights : photometric.leds.PointLights
        LED positions (mm), axes and lobe exponents (``mu_known`` False when ``mu`` is null).
    camera : photometric.camera.Orthographic or Perspective
    image_size : tuple of int
        ``(H, W)`` of the images the rig was calibrated for.
    intensities : numpy.ndarray or None, shape (N, 3)
        LED intensities ``e_k`` when known.
    gains : numpy.ndarray or None, shape (N, H, W), float32
        Flat-field gains (:func:`flat_field_gains`).
    flat_albedo : float or None
        Albedo of the flat target the gains were measured on.
    flat_smoothing_px : float
        Gaussian sigma the gains were smoothed with (0: none).
    calibration : dict
        How the positions were found (method, residuals, uncertainties).
    quality : dict or None
        The measurement-validity limits set from a reference part (``rig.json`` key
        ``quality``: ``limits``, a :class:`photometric.quality.QualityLimits` as a dict,
        ``reference_slopes`` ``[p, q]`` of the reference part, ``reference_part`` and
        ``reference_figures``); None: the stated defaults apply.
    """

    lights: PointLights
    camera: Camera
    image_size: tuple[int, int]
    intensities: np.ndarray | None = None
    gains: np.ndarray | None = None
    flat_albedo: float | None = None
    flat_smoothing_px: float = 0.0
    calibration: dict = field(default_factory=dict)
    quality: dict | None = None
    reflectance: dict | None = None


def flat_field_gains(flat_images, lights: PointLights, camera: Camera, albedo: float = 1.0, *,
                     smoothing_px: float = FLAT_SMOOTHING_PX) -> np.ndarray:
    """Per-light gain maps from images of a flat matte target lying in the reference plane.

    Parameters
    ----------
    flat_images : array_like, shape (N, H, W) or (N, H, W, 3)
        One image per light, same camera, exposure and light order as the part images;
        colour is averaged to grey.
    lights : photometric.leds.PointLights
        LED positions (mm).
    camera : photometric.camera.Orthographic or Perspective
    albedo : float, optional
        The target's albedo (1: reconstructed albedos are relative to the target's).
    smoothing_px : float, optional
        Gaussian sigma (pixels) applied to the gains (0: none).

    Returns
    -------
    numpy.ndarray, shape (N, H, W), float32
        ``G_k = F_k / (albedo * l_k(X0) . z)`` with ``X0`` the point of the plane ``z = 0``
        each pixel sees: the irradiance ``E_k(X0)`` times vignetting, as measured (falloff
        on the plane, LED lobe, unequal LED power). The near-field solver carries it off
        the plane with the distance ratio ``(|P_k - X0| / |P_k - X|)^2``.

    Examples
    --------
    An isotropic LED 100 mm above the origin and a target of albedo 0.5: the gain is 1
    under the LED.

    >>> from photometric.camera import make_camera
    >>> from photometric.leds import light_field, point_lights
    >>> lights = point_lights([[0, 0, 100], [100, 0, 100], [0, 100, 100]])
    >>> cam = make_camera("orthographic", pixel_size_mm=1.0)
    >>> flat = 0.5 * light_field(lights, plane_points(cam, (5, 5)))[..., 2]
    >>> round(float(flat_field_gains(flat, lights, cam, 0.5, smoothing_px=0)[0, 2, 2]), 6)
    1.0
    """
    imgs = _check_images(flat_images)
    if not isinstance(lights, PointLights):
        raise InputError("lights: a flat field needs point lights (photometric.leds.point_lights)")
    n = imgs.shape[0]
    if n != len(lights):
        raise InputError(f"flat_field: {n} flat-field image(s) for {len(lights)} lights (one per light, same order)")
    a = positive(albedo, "flat_albedo")
    sigma = positive(smoothing_px, "flat_smoothing_px", allow_zero=True)
    if not np.all(np.isfinite(imgs)) or np.any(imgs < 0):
        raise InputError("flat_field: images must be finite and non-negative")
    planes = _grey_planes(imgs, np.ones((n, 3)))
    X0 = plane_points(camera, imgs.shape[1:3])
    gains = np.empty((n,) + imgs.shape[1:3], np.float32)
    for k in range(n):
        d = lights.positions[k][None, None, :] - X0
        cos = d[..., 2] / np.linalg.norm(d, axis=2)
        gains[k] = planes[k] / (a * cos)
        if sigma > 0:
            cv2.GaussianBlur(gains[k], (0, 0), sigma, dst=gains[k], borderType=cv2.BORDER_REFLECT)
    return gains


def rig_to_dict(rig: Rig, gains_file: str = GAINS_FILE) -> dict:
    """The content of ``rig.json`` (JSON-ready); the gains go to ``gains_file`` beside it.

    Parameters
    ----------
    rig : Rig
    gains_file : str, optional
        Name of the gains file, relative to ``rig.json``.

    Returns
    -------
    dict
    """
    lights = rig.lights
    flat = None
    if rig.gains is not None:
        flat = {"gains": gains_file, "albedo": rig.flat_albedo, "smoothing_px": rig.flat_smoothing_px}
    return {
        "format": RIG_FORMAT,
        "version": RIG_VERSION,
        "lights": {
            "positions_mm": lights.positions.tolist(),
            "axes": lights.axes.tolist() if lights.mu_known else None,
            "mu": lights.mu.tolist() if lights.mu_known else None,
            "intensities": None if rig.intensities is None else rig.intensities.tolist(),
        },
        "camera": rig.camera.to_dict(rig.image_size),
        "image_size": list(rig.image_size),
        "flat_field": flat,
        "calibration": rig.calibration,
        **({} if rig.quality is None else {"quality": rig.quality}),
        **({} if rig.reflectance is None else {"reflectance": rig.reflectance}),
    }


@reads_file("rig file")
def read_rig(path) -> Rig:
    """Read ``rig.json`` and its gains file.

    Parameters
    ----------
    path : str or Path
        The ``rig.json`` file.

    Returns
    -------
    Rig

    Raises
    ------
    FileNotFoundError
        ``rig.json`` or its gains file is missing.
    ValueError
        Not a workbench rig, an unknown version, or invalid content (the message names
        the entry).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"rig: file {p} does not exist")
    try:
        text = p.read_text()
    except UnicodeDecodeError as exc:
        raise InputError(f"rig: {p} is not valid JSON ({exc})") from None
    doc = loads_unique(text, f"rig: {p}")
    if not isinstance(doc, dict) or doc.get("format") != RIG_FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise InputError(f"rig: {p} is not a {RIG_FORMAT!r} file (its 'format' is {found!r})")
    if doc.get("version") != RIG_VERSION:
        raise InputError(f"rig: {p} has version {doc.get('version')!r}; this workbench reads version {RIG_VERSION}")
    for key in ("lights", "camera", "image_size"):
        if key not in doc:
            raise InputError(f"rig: {p} lacks {key!r}")
    _refuse_unknown(doc, "", f"rig: {p}")
    lights_doc = doc["lights"]
    if not isinstance(lights_doc, dict) or "positions_mm" not in lights_doc:
        raise InputError(f"rig: {p} 'lights' needs 'positions_mm'")
    _refuse_unknown(lights_doc, "lights", f"rig: {p}")
    lights = point_lights(lights_doc["positions_mm"], lights_doc.get("axes"), lights_doc.get("mu"),
                          name=f"rig lights.positions_mm ({p.name})")
    n = len(lights)
    intens = lights_doc.get("intensities")
    intens = None if intens is None else as_intensities(intens, n, "rig lights.intensities")
    if isinstance(doc["camera"], dict):
        _refuse_unknown(doc["camera"], "camera", f"rig: {p}")
    camera = camera_from_dict(doc["camera"], f"rig camera ({p.name})")
    size = as_array(doc["image_size"], "rig image_size", shape=(2,))
    if np.any(size < 1) or np.any(size % 1):
        raise InputError(f"rig image_size: expected [H, W] in whole pixels, got {doc['image_size']}")
    shape = (int(size[0]), int(size[1]))
    gains, albedo, smoothing = None, None, 0.0
    flat = doc.get("flat_field")
    if flat is not None:
        if not isinstance(flat, dict) or "gains" not in flat:
            raise InputError(f"rig: {p} 'flat_field' needs 'gains' (a file name) or null")
        _refuse_unknown(flat, "flat_field", f"rig: {p}")
        gfile = p.parent / str(flat["gains"])
        if not gfile.is_file():
            raise FileNotFoundError(f"rig flat_field.gains: file {gfile} does not exist")
        try:
            with np.load(gfile, allow_pickle=False) as npz:
                gains = np.asarray(npz["gains"], np.float32)
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(f"rig flat_field.gains: {gfile} is not an .npz file with 'gains' ({exc})") from None
        if gains.shape != (n,) + shape:
            raise InputError(f"rig flat_field.gains: shape {gains.shape}, expected {(n,) + shape} "
                             "(lights x image_size)")
        albedo = positive(flat.get("albedo", 1.0) if flat.get("albedo") is not None else 1.0, "rig flat_field.albedo")
        smoothing = positive(flat.get("smoothing_px", 0.0) or 0.0, "rig flat_field.smoothing_px", allow_zero=True)
    calibration = doc.get("calibration") or {}
    quality = doc.get("quality")
    if quality is not None:
        quality = _quality_doc(quality, p)
    reflectance = doc.get("reflectance")
    if reflectance is not None:
        reflectance = _reflectance_doc(reflectance, p)
    return Rig(lights, camera, shape, intens, gains, albedo, smoothing, calibration, quality, reflectance)


def _reflectance_doc(doc, p: Path) -> dict:
    """``rig.json``'s ``reflectance`` entry, checked through :class:`photometric.options.PhotometricOptions`."""
    from photometric.options import PhotometricOptions

    if not isinstance(doc, dict) or "model" not in doc:
        raise InputError(f"rig: {p} 'reflectance' needs 'model' ('lambertian' or 'glossy')")
    try:
        PhotometricOptions(reflectance=doc["model"], gloss_alpha=doc.get("alpha"), gloss_weight=doc.get("weight"))
    except InputError as exc:
        raise InputError(f"rig reflectance: {exc}") from None
    if doc["model"] == "glossy" and (doc.get("alpha") is None or doc.get("weight") is None):
        raise InputError(f"rig: {p} 'reflectance' glossy needs 'alpha' and 'weight'")
    return dict(doc)


def _quality_doc(doc, p: Path) -> dict:
    """``rig.json``'s ``quality`` entry, checked (its limits through :class:`photometric.quality.QualityLimits`)."""
    from photometric.quality import QualityLimits

    if not isinstance(doc, dict) or not isinstance(doc.get("limits"), dict):
        raise InputError(f"rig: {p} 'quality' needs 'limits' (a dict of QualityLimits fields)")
    try:
        QualityLimits(**doc["limits"])
    except TypeError as exc:
        raise InputError(f"rig quality.limits: {exc}") from None
    ref = doc.get("reference_slopes")
    if ref is not None:
        as_array(ref, "rig quality.reference_slopes", shape=(2,))
    return dict(doc)


def check_rig(rig: Rig, n_images: int, shape) -> None:
    """A rig must match the images it reconstructs: one light per image, the same size.

    Parameters
    ----------
    rig : Rig
    n_images : int
    shape : (H, W)

    Raises
    ------
    ValueError
        ``rig: ...`` saying what differs.
    """
    if len(rig.lights) != n_images:
        raise InputError(f"rig: {len(rig.lights)} lights for {n_images} images (one image per light, same order)")
    if tuple(shape) != tuple(rig.image_size):
        raise InputError(f"rig: calibrated for {rig.image_size[0]} x {rig.image_size[1]} px images, "
                         f"the images are {shape[0]} x {shape[1]} px")


def at_camera_height(rig: Rig, camera_height_mm: float) -> Rig:
    """The same rig with its reference plane moved: the camera ``camera_height_mm`` above it.

    The LEDs are fixed to the camera, so moving the reference plane (the working distance)
    moves every LED's height by the same amount as the camera's; the LED axes and lobes stay.
    The intensities ``e_k`` are irradiances at the reference distance ``d0_k = |P_k|``
    (:mod:`photometric.leds`), so each LED's radiant intensity ``e_k d0_k^2`` is kept.

    Parameters
    ----------
    rig : Rig
        A rig with a perspective camera and no flat field (gains are measured on one plane).
    camera_height_mm : float
        The new camera height above the reference plane, mm (> 0; every LED must stay
        above the plane).

    Returns
    -------
    Rig
        ``calibration["camera_height_mm_moved_from"]`` records the height the rig had.

    Raises
    ------
    InputError
        An orthographic camera (no camera centre), a flat field, or an LED that would
        end at or below the reference plane.

    Examples
    --------
    >>> from photometric.camera import make_camera
    >>> rig = Rig(point_lights([[30.0, 0.0, 120.0], [0.0, 30.0, 120.0], [-30.0, 0.0, 120.0]]),
    ...           make_camera("perspective", focal_length_px=1000, camera_height_mm=200), (10, 10))
    >>> moved = at_camera_height(rig, 250)
    >>> moved.lights.positions[0].tolist(), moved.camera.camera_height_mm
    ([30.0, 0.0, 170.0], 250.0)
    """
    from dataclasses import replace

    from photometric.camera import Perspective

    if not isinstance(rig.camera, Perspective):
        raise InputError("camera_height_mm: moving the reference plane needs a perspective rig (an orthographic "
                         "camera has no camera centre)")
    if rig.gains is not None:
        raise InputError("camera_height_mm: the rig's flat-field gains were measured on its reference plane; "
                         "re-measure them (photometric calibrate --flat-field) instead of moving the plane")
    new = positive(camera_height_mm, "camera_height_mm")
    shift = new - float(rig.camera.camera_height_mm)
    lights = rig.lights
    pos = lights.positions + np.array([0.0, 0.0, shift])
    if np.any(pos[:, 2] <= 0):
        raise InputError(f"camera_height_mm: at {new:g} mm LED(s) {np.flatnonzero(pos[:, 2] <= 0).tolist()} "
                         "would be at or below the reference plane")
    moved = PointLights(pos, lights.axes, lights.mu, lights.mu_known,
                        None if lights.intensities is None else lights.intensities * (lights.d0 ** 2 /
                        np.sum(pos**2, axis=1)).reshape((-1,) + (1,) * (lights.intensities.ndim - 1)))
    intens = rig.intensities
    if intens is not None:
        intens = intens * (lights.d0 ** 2 / np.sum(pos**2, axis=1))[:, None]
    calibration = dict(rig.calibration)
    calibration.setdefault("camera_height_mm_moved_from", float(rig.camera.camera_height_mm))
    return replace(rig, lights=moved, camera=replace(rig.camera, camera_height_mm=new), intensities=intens,
                   calibration=calibration)


def position_u_mm(rig: Rig) -> float | None:
    """The rig's LED position standard uncertainty for the budget: the largest per-coordinate u of its LEDs.

    The uncertainty budget takes one standard uncertainty for every LED coordinate
    (``light_position_tolerance_mm``, :class:`photometric.uncertainty.Tolerances`); the rig's
    calibration states one per LED and axis (``calibration.uncertainty_mm``, mirror-sphere
    calibration). The largest is taken, so that no LED is stated better than it was measured.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    float or None
        mm; None when the calibration states none (known positions, imported files).

    Examples
    --------
    >>> from photometric.camera import make_camera
    >>> rig = Rig(point_lights([[30.0, 0.0, 120.0], [0.0, 30.0, 120.0], [-30.0, 0.0, 120.0]]),
    ...           make_camera("orthographic", pixel_size_mm=0.1), (10, 10),
    ...           calibration={"uncertainty_mm": [[0.02, 0.03, 0.25], [0.02, 0.02, 0.1], [0.01, 0.02, 0.2]]})
    >>> position_u_mm(rig)
    0.25
    """
    u = rig.calibration.get("uncertainty_mm") if isinstance(rig.calibration, dict) else None
    if u is None:
        return None
    arr = np.asarray(u, dtype=np.float64)
    if arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise InputError(f"rig calibration.uncertainty_mm: expected non-negative finite values per LED, got {u}")
    return float(arr.max())
