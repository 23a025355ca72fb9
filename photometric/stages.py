"""The stages of photometric stereo, each public, with the options and a typed result.

:func:`read` (images, lights, mask, light model and camera: :class:`PhotometricInput`),
:func:`solve` (normals and albedo, far field or near field by the input's light model:
:class:`Solution`), :func:`integrate` (the height: :class:`Height`), :func:`surface`
(optional: the shared surface model and its mesh, :class:`Surface`), :func:`measure` (the
defects: :class:`Defects`) and :func:`uncertainty` (from the height and the defects, no
surface: :class:`photometric.uncertainty.UncertaintyResult`). Every stage takes the same
:class:`photometric.options.PhotometricOptions`, checked once when it is made;
:func:`photometric.pipeline.reconstruct` is their composition, and the inspection of a part
(``workbench.inspect.part``) composes the same stages without the surface.

Input is validated once, in :func:`read`, where it enters: lights and intensities by their
readers, images and masks by :mod:`photometric.io`; the later stages take the checked arrays.

Light model and camera: distant lights and an orthographic camera (the far-field path of
:func:`photometric.stereo.solve`) unless LED positions are known (``light_positions``, a
``rig``, or a folder's ``light_positions.txt``): then the near-field alternation of
:mod:`photometric.nearfield` with point lights, an orthographic or perspective camera
(:mod:`photometric.camera`) and, when given, flat-field gains (:mod:`photometric.rig`).
A perspective camera with distant lights integrates the log-depth once. A near-field solve
that does not converge raises :class:`photometric.nearfield.NotConvergedError` carrying
the summary so far.
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from photometric.camera import Camera, Orthographic, Perspective, make_camera, undistort_images
from photometric.io import (PhotometricData, exposure_note, full_scale_of, read_ambient, read_folder, read_images,
                            read_mask, subtract_ambient)
from photometric.io import load_intensities, load_light_positions, load_lights
from photometric.leds import PointLights, point_lights
from photometric.lights import as_intensities, validate_lights
from photometric.nearfield import COARSE_PIXELS, NearFieldResult, NotConvergedError, _check_setup, _solve_nearfield
from photometric.options import PhotometricOptions
from photometric.rig import FLAT_SMOOTHING_PX, Rig, check_rig, flat_field_gains, read_rig
from photometric.stereo import (
    MAX_CONDITION,
    SATURATED,
    WARN_CONDITION,
    StereoResult,
    _check_images,
    _light_matrix,
    _solve,
    _solve_rows,
    restrict,
    screen_images,
)
from photometric.uncertainty import Tolerances, UncertaintyResult, check_monte_carlo_size
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh
from surfaces.validate import InputError, as_array, positive

__all__ = ["TARGET_PATCHES", "LightSetup", "PhotometricInput", "Solution", "Height", "Surface", "Defects",
           "read", "solve", "integrate", "surface", "patch_budget", "measure", "uncertainty", "quality",
           "summarize"]

#: Patches per image side aimed at when ``step`` is not given (Coons surface).
TARGET_PATCHES = 64


@dataclass(frozen=True)
class LightSetup:
    """The light model and camera of a near-field or perspective solve (checked by :func:`read`).

    Attributes
    ----------
    model : {"point", "directional"}
        Point lights (LED positions) or distant lights seen by a perspective camera.
    lights : photometric.leds.PointLights or numpy.ndarray, shape (N, 3)
        The LEDs, or the unit directions.
    camera : photometric.camera.Orthographic or Perspective
    camera_source : str
        Where the camera came from: ``"option"``, ``"rig"`` or ``"scene.json"``.
    gains : numpy.ndarray or None, shape (N, H, W)
        Flat-field gains.
    flat : dict or None
        ``source``, ``albedo`` and ``smoothing_px`` of the gains.
    intensities : numpy.ndarray, shape (N, 3)
    rig : str or None
        The rig file, when one was read.
    quality : dict or None
        The rig's ``quality`` entry (limits and reference slopes set from a reference part,
        :attr:`photometric.rig.Rig.quality`), when the rig has one.
    reflectance : dict or None
        The rig's ``reflectance`` entry (:attr:`photometric.rig.Rig.reflectance`).
    """

    model: str
    lights: PointLights | np.ndarray
    camera: Camera
    camera_source: str
    gains: np.ndarray | None
    flat: dict | None
    intensities: np.ndarray
    rig: str | None
    quality: dict | None = None
    reflectance: dict | None = None


@dataclass(frozen=True)
class PhotometricInput:
    """What :func:`read` returns: the checked input of a solve.

    Attributes
    ----------
    data : photometric.io.PhotometricData
        Images (N, H, W[, 3]) float32 in [0, 1], unit lights, intensities, mask, ...
    setup : LightSetup or None
        The near-field (point lights) or perspective set-up; None: distant lights and an
        orthographic camera (the far-field path).
    pixel_size_mm : float
        Size of a pixel in mm (at the reference plane for a perspective camera).
    pixel_size_source : str
        Where it came from (``"option"``, ``"scene.json"``, ``"rig"``, ``"default (1 unit per pixel)"``, ...).
    info : dict
        The input's kind and path(s), JSON-ready (``summary["input"]``).
    size : dict
        ``height``, ``width`` (pixels), ``images`` (as read, before any is left out), ``channels``.
    seconds : float
        Wall time of the stage.
    """

    data: PhotometricData
    setup: LightSetup | None
    pixel_size_mm: float
    pixel_size_source: str
    info: dict
    size: dict
    seconds: float = 0.0

    @property
    def orthographic(self) -> bool:
        """True when every pixel sees the point on its own grid position (no ``xy`` needed)."""
        return self.setup is None or isinstance(self.setup.camera, Orthographic)


@dataclass(frozen=True)
class Solution:
    """What :func:`solve` returns.

    Attributes
    ----------
    fit : photometric.stereo.StereoResult or photometric.nearfield.NearFieldResult
        Normals (H, W, 3), albedo, slopes ``p``, ``q`` (H, W) float32, ``valid`` (H, W)
        bool and, near field, ``height`` (mm), ``xy`` (H, W, 2) and ``footprint_mm2``.
        Its normals and albedo are None when :func:`solve` streamed them to ``out`` in
        blocks of rows (far field without uncertainty).
    data : photometric.io.PhotometricData
        The input as solved: the images left out by the screen dropped (far field), the
        image stack None when it was streamed.
    condition_number : float
        Condition number of the light matrix.
    lights : numpy.ndarray, shape (N, 3)
        The unit light directions solved with (far field; towards the LEDs for point lights).
    warnings : list of str
        One line each (also issued as ``UserWarning``).
    mean_residual : float or None
        Mean fit residual over the valid pixels (None when ``residual=False``).
    angular_errors_deg : numpy.ndarray or None, shape (M,)
        Angular error against the folder's ``normal_gt`` over the mask, degrees.
    timings_s : dict
        Wall seconds: ``screen`` (images and light matrix), ``solve`` (the normals; near
        field without its integrations), ``integrate`` (near field: its integrations) and
        ``total`` (the stage).
    """

    fit: StereoResult | NearFieldResult
    data: PhotometricData
    condition_number: float
    lights: np.ndarray
    warnings: list
    mean_residual: float | None
    angular_errors_deg: np.ndarray | None = None
    timings_s: dict | None = None


@dataclass(frozen=True)
class Height:
    """What :func:`integrate` returns.

    Attributes
    ----------
    height : numpy.ndarray, shape (H, W), float32 (far field) or float64 (near field)
        Height in mm, NaN outside the valid pixels; near field: ``z`` of the point each
        pixel sees, in the rig frame.
    seconds : float
        Wall time of the integration (near field: of its integrations inside the solve).
    """

    height: np.ndarray
    seconds: float = 0.0


@dataclass(frozen=True)
class Surface:
    """What :func:`surface` returns.

    Attributes
    ----------
    patches : surfaces.bezier.BezierPatches
        The bicubic surface (the fit's :class:`surfaces.mixed.MixedPatches`, or the Coons grid).
    mesh : surfaces.mesh.TriangleMesh
        The tessellated surface trimmed to the fitted pixels (fit) or to the mask (coons), mm.
    step_px, samples : int
        Pixels per (largest) patch side, mesh subdivisions per patch side.
    info : dict
        ``surface``, ``surface_max_dev_mm``, ``surface_rms_dev_mm``, ``n_patches`` and, fit,
        ``surface_tolerance_mm`` and ``surface_patch_sizes_px``.
    seconds : float
    """

    patches: BezierPatches
    mesh: TriangleMesh
    step_px: int
    samples: int
    info: dict
    seconds: float = 0.0


@dataclass(frozen=True)
class Defects:
    """What :func:`measure` returns.

    Attributes
    ----------
    defects : list of dict
        :func:`photometric.defects.measure_defects`' records.
    labels : numpy.ndarray or None, shape (H, W), int
        The defects' label image (when ``labels=True``; the uncertainty stage needs it).
    background : str
        Background removed before measuring.
    seconds : float
    """

    defects: list
    labels: np.ndarray | None
    background: str
    seconds: float = 0.0


def _lights(lights) -> np.ndarray:
    if isinstance(lights, _Checked):
        return lights.directions
    return load_lights(lights) if isinstance(lights, (str, Path)) else validate_lights(lights)


@dataclass(frozen=True)
class _Checked:
    """Unit light directions checked already (towards LEDs that :func:`point_lights` or the rig checked)."""

    directions: np.ndarray

    def __len__(self) -> int:
        return len(self.directions)


def _intensities(intensities, n: int) -> np.ndarray:
    return load_intensities(intensities, n) if isinstance(intensities, (str, Path)) else as_intensities(intensities, n)


def _mask(mask, shape) -> np.ndarray:
    if isinstance(mask, (str, Path)):
        return read_mask(mask, shape)
    return as_array(mask, "mask", shape=shape, dtype=bool)


def _load_input(source, lights, intensities, mask, select, bayer=None) -> tuple[PhotometricData, dict]:
    """PhotometricData from a folder, a list of image files or an image array."""
    if isinstance(source, PhotometricData):
        return source, {"kind": "data"}
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        data = read_folder(source, select=select, bayer=bayer)
        folder = Path(source)
        extra = {}
        if (folder / "scene.json").is_file():
            # datasets_synthetic folders state their pixel size
            try:
                scene = json.loads((folder / "scene.json").read_text())
            except json.JSONDecodeError as exc:
                raise InputError(f"input: {folder / 'scene.json'} is not valid JSON ({exc})") from None
            if isinstance(scene, dict) and "pixel_size_mm" in scene:
                extra["scene_pixel_size_mm"] = float(scene["pixel_size_mm"])
        replace = {}
        if lights is not None:
            replace["lights"] = _lights(lights)
            if replace["lights"].shape[0] != len(data.names):
                raise InputError(f"lights: {replace['lights'].shape[0]} directions for {len(data.names)} images")
        if intensities is not None:
            replace["intensities"] = _intensities(intensities, len(data.names))
        if mask is not None:
            replace["mask"] = _mask(mask, data.images.shape[1:3])
        if replace:
            fields = {k: getattr(data, k) for k in PhotometricData.__dataclass_fields__}
            fields.update(replace)
            data = PhotometricData(**fields)
        return data, {"kind": "folder", "path": str(folder), **extra}
    if isinstance(source, (str, Path)):
        raise NotADirectoryError(f"input: {source} is not a folder (give --images and --lights for files)")
    if lights is None:
        raise InputError("lights: required when the input is a list of images or an array")
    if isinstance(source, Sequence) and all(isinstance(s, (str, Path)) for s in source):
        images = read_images(list(source), bayer=bayer)
        names = tuple(Path(s).name for s in source)
        kind = {"kind": "files", "paths": [str(s) for s in source]}
    else:
        images = _check_images(source)
        names = tuple(f"image{k:03d}" for k in range(images.shape[0]))
        kind = {"kind": "array"}
    L = _lights(lights)
    if L.shape[0] != images.shape[0]:
        raise InputError(f"lights: {L.shape[0]} directions for {images.shape[0]} images")
    n = images.shape[0]
    shape = images.shape[1:3]
    m = np.ones(shape, bool) if mask is None else _mask(mask, shape)
    full_scale = full_scale_of(source) if kind["kind"] == "files" else None
    return PhotometricData(images, L, _intensities(intensities, n), m, None, names, full_scale=full_scale), kind


def _trimmed_mesh(patches, region: np.ndarray, pixel_size: float, samples: int):
    """Tessellate and drop triangles whose centroid falls outside ``region``."""
    from surfaces.grid import xy_to_pixel
    from surfaces.mesh import tessellate

    mesh = tessellate(patches, samples=samples)
    if region.all():
        return mesh
    centroid = mesh.vertices[mesh.triangles].mean(axis=1)
    row, col = xy_to_pixel(centroid[:, 0], centroid[:, 1], region.shape, pixel_size)
    row = np.clip(np.rint(row), 0, region.shape[0] - 1).astype(np.int64)
    col = np.clip(np.rint(col), 0, region.shape[1] - 1).astype(np.int64)
    tri = mesh.triangles[region[row, col]]
    used = np.unique(tri)
    remap = np.full(len(mesh.vertices), -1, np.int64)
    remap[used] = np.arange(used.size)
    normals = None if mesh.vertex_normals is None else mesh.vertex_normals[used]
    return TriangleMesh(mesh.vertices[used], remap[tri], normals)


def _light_positions(value, n: int, led_mu, led_axes=None) -> PointLights:
    pos = load_light_positions(value) if isinstance(value, (str, Path)) else value
    lights = point_lights(pos, _axes(led_axes), led_mu)
    if len(lights) != n:
        raise InputError(f"light_positions: {len(lights)} LED positions for {n} images")
    return lights


def _axes(led_axes):
    if isinstance(led_axes, (str, Path)):
        from photometric.importers import load_axes

        return load_axes(led_axes)
    return led_axes


def _with_mu(lights: PointLights, led_mu, led_axes=None) -> PointLights:
    if led_axes is not None:
        mu = led_mu if led_mu is not None else (lights.mu if lights.mu_known else None)
        return point_lights(lights.positions, _axes(led_axes), mu)
    return lights if led_mu is None else point_lights(lights.positions, lights.axes, led_mu)


def _flat_images(flat_field, n: int, shape) -> np.ndarray:
    """Flat-field images from files or an array: one per light, the images' size."""
    if isinstance(flat_field, (str, Path)):
        flat_field = [flat_field]
    if isinstance(flat_field, Sequence) and all(isinstance(f, (str, Path)) for f in flat_field):
        if len(flat_field) != n:
            raise InputError(f"flat_field: {len(flat_field)} flat-field image(s) for {n} lights (one per light)")
        flats = read_images(list(flat_field))
    else:
        flats = _check_images(flat_field)
        if flats.shape[0] != n:
            raise InputError(f"flat_field: {flats.shape[0]} flat-field image(s) for {n} lights (one per light)")
    if flats.shape[1:3] != tuple(shape):
        raise InputError(f"flat_field: flat-field images are {flats.shape[1]} x {flats.shape[2]} px, the images "
                         f"{shape[0]} x {shape[1]} px")
    return flats


def _near_setup(data: PhotometricData, *, light_model, light_positions, led_mu, flat_field, flat_albedo, camera,
                pixel_size, scene_h, focal_length_px, camera_height_mm, principal_point_px, rig, rig_obj,
                intensities, led_axes=None, distortion=None) -> LightSetup | None:
    """Decide the light model and camera; None means the far-field orthographic path of today.

    Precedence: the options, then ``rig.json``, then the folder's own files
    (``light_positions.txt``, ``scene.json`` lights and camera, ``flat_*.png``).
    """
    n, shape = data.images.shape[0], data.images.shape[1:3]
    if rig_obj is not None:
        check_rig(rig_obj, n, shape)
    if light_positions is not None:
        lights = _light_positions(light_positions, n, led_mu, led_axes)
    elif rig_obj is not None:
        lights = _with_mu(rig_obj.lights, led_mu, led_axes)
    elif data.point_lights is not None:
        lights = _with_mu(data.point_lights, led_mu, led_axes)
    else:
        lights = None
    if (led_mu is not None or led_axes is not None) and lights is None:
        raise InputError(f"{'led_mu' if led_mu is not None else 'led_axes'}: the LED lobe needs LED positions "
                         "(--light-positions or --rig)")

    explicit = [v is not None for v in (camera, focal_length_px, camera_height_mm, principal_point_px)]
    cam_source = "option"
    if isinstance(camera, (Orthographic, Perspective)):
        cam = camera
    elif any(explicit):
        model = camera or ("perspective" if any(explicit[1:]) else "orthographic")
        ortho = model == "orthographic"
        cam = make_camera(model, pixel_size_mm=(pixel_size if pixel_size is not None else scene_h) if ortho
                          else pixel_size, focal_length_px=focal_length_px, camera_height_mm=camera_height_mm,
                          principal_point_px=principal_point_px)
    elif pixel_size is not None and (lights is not None or rig_obj is not None):
        cam = make_camera("orthographic", pixel_size_mm=pixel_size)
    elif rig_obj is not None:
        cam, cam_source = rig_obj.camera, "rig"
    elif data.camera is not None:
        cam, cam_source = data.camera, "scene.json"
    elif scene_h is not None and lights is not None:
        cam, cam_source = make_camera("orthographic", pixel_size_mm=scene_h), "scene.json"
    else:
        cam = None

    if distortion is not None:
        if not isinstance(cam, Perspective):
            raise InputError("distortion: lens distortion needs a perspective camera (--camera perspective, or a "
                             "perspective rig)")
        cam = make_camera("perspective", focal_length_px=(cam.focal_length_px, cam.fy),
                          camera_height_mm=cam.camera_height_mm, principal_point_px=cam.principal_point_px,
                          distortion=distortion)
    if light_model == "directional" or lights is None:
        if light_model == "point":
            raise InputError("light_model: 'point' needs LED positions (--light-positions, --rig or the "
                             "folder's light_positions.txt)")
        if flat_field is not None and flat_field is not False:
            raise InputError("flat_field: flat-field gains need the point-light model (LED positions from "
                             "--light-positions, --rig or the folder, and not --light-model directional)")
        if cam is None or isinstance(cam, Orthographic):
            return None
        return LightSetup("directional", data.lights, cam, cam_source, None, None, data.intensities, None)
    if cam is None:
        raise InputError("camera: point lights need the camera's scale in mm: --pixel-size (orthographic) or "
                         "--camera perspective --focal-length-px F --camera-height MM")
    gains, flat = None, None
    if flat_field is not None and flat_field is not False:
        albedo = 1.0 if flat_albedo is None else flat_albedo
        gains = flat_field_gains(undistort_images(cam, _flat_images(flat_field, n, shape))[0], lights, cam, albedo)
        flat = {"source": "option", "albedo": float(albedo)}
    elif flat_field is None and rig_obj is not None and rig_obj.gains is not None:
        gains = rig_obj.gains
        flat = {"source": "rig", "albedo": rig_obj.flat_albedo, "smoothing_px": rig_obj.flat_smoothing_px}
    elif flat_field is None and data.flat_images is not None:
        albedo = flat_albedo if flat_albedo is not None else (data.flat_albedo or 1.0)
        gains = flat_field_gains(undistort_images(cam, data.flat_images)[0], lights, cam, albedo)
        flat = {"source": "folder", "albedo": float(albedo)}
    if flat is not None and flat["source"] != "rig":
        flat["smoothing_px"] = FLAT_SMOOTHING_PX
    intens = data.intensities
    if intensities is None and rig_obj is not None and rig_obj.intensities is not None:
        intens = rig_obj.intensities
    rig_name = None if rig is None or isinstance(rig, Rig) else str(rig)
    return LightSetup("point", lights, cam, cam_source, gains, flat, intens, rig_name,
                      None if rig_obj is None else rig_obj.quality, None if rig_obj is None else rig_obj.reflectance)


def _near_summary(near: LightSetup, res: NearFieldResult, tolerance_mm: float) -> dict:
    """The light model, camera and convergence record of ``summary.json``."""
    out: dict = {"light_model": near.model, "camera": near.camera.to_dict(res.valid.shape)}
    if near.model == "point":
        out["light_positions_mm"] = near.lights.positions.tolist()
        out["led_mu"] = near.lights.mu.tolist() if near.lights.mu_known else None
        out["flat_field"] = near.flat
        out["rig"] = near.rig
        out["intensities"] = _intensity_summary(near, res)
    out.update({
        "iterations": res.iterations,
        "final_depth_change_mm": res.depth_change_mm,
        "converged": True,
        "tolerance_mm": tolerance_mm,
        "anchor": res.anchor,
        "iteration_history": list(res.history),
    })
    return out


#: Spread of the LEDs' distances to the field centre (``max d0^2 / min d0^2 - 1``) above which an
#: assumed equal irradiance at the centre means LEDs of unequal radiant intensity, and a warning says so.
D0_SPREAD = 0.01


def _intensity_summary(near: LightSetup, res: NearFieldResult) -> dict:
    """How the LED power entered the near-field solve (``summary["intensities"]``): ``source``
    (``"flat field"``, ``"estimated"``, ``"given"`` or ``"assumed"``), the ``assumption`` when nothing
    was measured or estimated, the ``e_k`` used and the radiant intensities they imply relative to LED 0."""
    d0 = near.lights.d0
    if res.intensities is not None:
        out = {"source": "estimated", "method": "semi-calibrated alternation (Queau et al., JMIV 2018), "
               "LED 0's intensity fixed", **res.intensities}
        if near.gains is not None:
            out["note"] = "scales on top of the flat-field gains"
        return out
    if near.gains is not None:
        return {"source": "flat field", "note": "the flat-field gains measure each LED's power per pixel"}
    e = np.asarray(near.intensities, float).mean(axis=1)
    out = {"source": "given", "relative": e.tolist(),
           "radiant_relative": (e * d0**2 / (e[0] * d0[0] ** 2)).tolist()}
    if np.allclose(e, e[0]):
        out["source"] = "assumed"
        out["assumption"] = ("equal irradiance e_k at the field centre (equal radiant intensity only when the "
                             "LEDs stand equally far from it); estimate_intensities or a flat field measures it")
    return out


def _intensity_note(near: LightSetup | None, opts: PhotometricOptions) -> str | None:
    """The warning of an assumed LED power in a rig whose LEDs stand at unequal distances from the field
    centre (None when it does not apply)."""
    if near is None or near.model != "point" or near.gains is not None or opts.estimate_intensities:
        return None
    e = np.asarray(near.intensities, float).mean(axis=1)
    if not np.allclose(e, e[0]):
        return None
    d0 = near.lights.d0
    spread = float((d0.max() / d0.min()) ** 2 - 1.0)
    if spread <= D0_SPREAD:
        return None
    return (f"intensities: none given and no flat field: the solve assumes equal irradiance at the field centre; "
            f"the LEDs stand {d0.min():.1f}-{d0.max():.1f} mm from it, so LEDs of equal radiant intensity would "
            f"differ there by up to {100 * spread:.1f} % and bend a flat part; give the intensities, a flat field "
            "or --estimate-intensities")


def _nearfield(data: PhotometricData, near: LightSetup, opts: PhotometricOptions, base: dict, *, threads=None,
               setup=None, residual: bool = True) -> NearFieldResult:
    """The near-field (or perspective) solve; no convergence raises with the summary so far."""
    ref = opts.reference_height_mm
    if isinstance(near.camera, Perspective) and ref >= near.camera.camera_height_mm:
        raise InputError(f"reference_height_mm: {ref:g} mm is not below the camera "
                         f"({near.camera.camera_height_mm:g} mm)")
    if near.model == "point" and np.any(near.lights.positions[:, 2] <= ref):
        raise InputError(f"reference_height_mm: {ref:g} mm is not below every light")
    gains = near.gains
    if setup is not None:
        # the strengths were prepared once with the gains (nearfield_setup)
        _check_setup(setup, near.lights, near.camera, data.images.shape[1:3], None)
        gains = None
    try:
        return _solve_nearfield(
            data.images, near.lights, near.camera, near.intensities, data.mask, gains, opts.outliers, opts.dark,
            opts.saturation, opts.highlight, opts.integrator, ref, opts.tolerance_mm, opts.max_iterations,
            COARSE_PIXELS, threads, setup=setup, residual=residual,
            estimate_intensities=opts.estimate_intensities,
        )
    except NotConvergedError as exc:
        summary = {**base, "light_model": near.model, "camera": near.camera.to_dict(data.images.shape[1:3]),
                   **exc.summary, "error": str(exc)}
        raise NotConvergedError(str(exc), summary) from None


#: Default patch budget of the fit without a mask: one patch per this many pixels ...
PIXELS_PER_PATCH = 256
#: ... and never fewer than this many patches (small images keep their full refinement).
MIN_PATCH_BUDGET = 1 << 14


def patch_budget(shape) -> int:
    """The fit's default patch budget for an image without a mask (:data:`PIXELS_PER_PATCH`,
    :data:`MIN_PATCH_BUDGET`): a big capture's fit stays a few times the normal solve's time.

    Parameters
    ----------
    shape : (H, W)
        Image size, pixels.

    Returns
    -------
    int

    Examples
    --------
    >>> patch_budget((2040, 2720)), patch_budget((512, 512))
    (21675, 16384)
    """
    return max(MIN_PATCH_BUDGET, int(shape[0]) * int(shape[1]) // PIXELS_PER_PATCH)


def _surface_step(method, height, p, q, valid, mask, h, step, samples, tolerance, xy=None, max_patches=None):
    """The surface model, its mesh and their summary entries (the ``surface`` stage).

    ``xy`` (H, W, 2), mm: the points a perspective camera's pixels see; the fit then
    places the surface at them instead of on the orthographic grid. ``max_patches``: the
    fit's budget (None: :func:`patch_budget` when ``mask`` covers the image, else none).
    """
    shape = height.shape
    if method == "coons":
        from photometric.integrate import height_to_patches

        step_px = int(step) if step is not None else max(2, int(np.ceil(max(shape) / TARGET_PATCHES)))
        patches = height_to_patches(height, p, q, pixel_size=h, step=step_px)
        n_samples = int(samples) if samples is not None else min(step_px, 8)
        mesh = _trimmed_mesh(patches, mask, h, n_samples)
        dev = _coons_deviation(patches, height, valid)
        info = {"surface": "coons", "surface_max_dev_mm": float(dev.max()),
                "surface_rms_dev_mm": float(np.sqrt(np.mean(dev**2)))}
    else:
        from surfaces.fit import default_step, fit_height
        from surfaces.fit_mesh import fit_mesh

        # the mesh needs only the patches and the fitted region: no per-pixel surface or
        # deviation map is kept (16 bytes per pixel for float32 heights)
        budget = max_patches if max_patches is not None else (patch_budget(shape) if mask.all() else None)
        fit = fit_height(height, p, q, mask=valid, pixel_size=h, tolerance=tolerance,
                         step=step if step is not None else default_step(shape), xy=xy, keep_pixels=False,
                         max_patches=budget)
        step_px = fit.step
        n_samples = int(samples) if samples is not None else min(step_px, 8)
        info = {"surface": "fit", "surface_tolerance_mm": fit.tolerance,
                "surface_max_patches": fit.max_patches, "surface_budget_reached": fit.budget_reached,
                "surface_patch_sizes_px": {str(k): v for k, v in fit.patch_sizes().items()},
                "surface_max_dev_mm": fit.max_deviation, "surface_rms_dev_mm": fit.rms_deviation}
        mesh = fit_mesh(fit, spacing=step_px / n_samples)
        patches = fit.patches
    info.update(n_patches=int(patches.n_patches))
    return patches, mesh, step_px, n_samples, info


def _coons_deviation(patches, height: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``|surface - height|`` at the valid pixel centres of :func:`height_to_patches`' grid.

    Its grid spans the image with equal steps, so pixel ``(r, c)`` is at the global patch
    parameters ``(r R / (H - 1), c C / (W - 1))``.
    """
    rows, cols = np.nonzero(valid)
    H, W = height.shape
    R, C = patches.shape
    pts = patches.evaluate_global(rows * (R / (H - 1)), cols * (C / (W - 1)))
    return np.abs(pts[:, 2] - height[rows, cols])


def _options(options) -> PhotometricOptions:
    if options is None:
        return PhotometricOptions()
    if not isinstance(options, PhotometricOptions):
        raise InputError(f"options: expected photometric.options.PhotometricOptions, got {type(options).__name__}")
    return options


def _resolved(inp: PhotometricInput, options) -> PhotometricOptions:
    """The options with the input's defaults decided: outliers from the image count, the integrator from the
    mask (:meth:`photometric.options.PhotometricOptions.resolved`)."""
    return _options(options).resolved(n_images=inp.size["images"], masked=not bool(inp.data.mask.all()))


def read(source, options: PhotometricOptions | None = None, *, lights=None, intensities=None, mask=None,
         select: str | Sequence[str] | None = None, pixel_size: float | None = None, light_positions=None,
         led_mu=None, flat_field=None, flat_albedo: float | None = None, camera=None,
         focal_length_px: float | None = None, camera_height_mm: float | None = None, principal_point_px=None,
         rig=None, ambient=None, bayer: str | None = None, led_axes=None, distortion=None) -> PhotometricInput:
    """Read and check the input of a solve: images, lights, mask, light model and camera.

    Parameters
    ----------
    source : str, Path, sequence of paths, array_like or PhotometricData
        A DiLiGenT-style folder (:func:`photometric.io.read_folder`), image files, or an
        ``(N, H, W[, 3])`` image array.
    options : PhotometricOptions, optional
        Its ``light_model`` decides between point and distant lights.
    lights : str, Path or array_like, shape (N, 3), optional
        Light directions (file or array); required for files/arrays (unless LED positions or
        a rig give them), overrides a folder's own.
    intensities : str, Path, float or array_like, optional
        Light intensities (scalar, (N,) or (N, 3)); overrides a folder's own.
    mask : str, Path or array_like, shape (H, W), optional
        Object mask; overrides a folder's ``mask.png``.
    select : None, "triad" or sequence of str, optional
        Subset of a folder's images (``"triad"``: those in ``triad.txt``).
    pixel_size : float, optional
        Pixel size in mm; default: the rig's or the folder's ``scene.json`` camera or
        ``pixel_size_mm``, else 1 (heights in pixel units).
    light_positions : str, Path or array_like, shape (N, 3), optional
        LED positions in mm (``x y z`` per image): the near-field model. Default: the rig's,
        else a folder's ``light_positions.txt``.
    led_mu : float or array_like, shape (N,), optional
        LED lobe exponents (0: isotropic); default the rig's or the folder's, else unknown.
    flat_field : sequence of paths, array_like (N, H, W[, 3]) or False, optional
        Flat-field images (a flat matte target in the reference plane, one per light);
        default the rig's gains, else a folder's ``flat_*.png``; False: none.
    flat_albedo : float, optional
        The flat target's albedo (default the folder's ``scene.json``, else 1).
    camera : {"orthographic", "perspective"} or camera object, optional
        Camera model (:mod:`photometric.camera`); default the rig's or the folder's
        ``scene.json``, else orthographic with ``pixel_size``.
    focal_length_px, camera_height_mm : float, optional
        Perspective focal length (pixels) and camera height above the reference plane (mm).
    principal_point_px : (cx, cy), optional
        Perspective principal point (column, row); default the image centre.
    rig : str, Path or photometric.rig.Rig, optional
        A calibrated rig (``rig.json``): LED positions, camera, flat-field gains; must match
        the images' count and size.
    ambient : str, Path, sequence of them or array_like, optional
        Dark frame(s) (all LEDs off, same exposure): one for every image or one per image,
        subtracted and clipped at 0 (:func:`photometric.io.subtract_ambient`).
    bayer : {"RGGB", "BGGR", "GRBG", "GBRG"}, optional
        Image files (and dark frames) are Bayer mosaics of this layout, demosaiced when read.
    led_axes : str, Path or array_like, shape (N, 3), optional
        LED axes in the rig frame (from the LED into the scene; a text file ``x y z`` per
        LED), replacing the default aim at the origin or the rig's; needs the lobes ``mu``
        (``led_mu``, or the rig's).
    distortion : sequence of float, optional
        OpenCV's lens distortion ``(k1, k2, p1, p2, k3)`` of the perspective camera (default the
        rig's or none): the images, mask and flat fields are resampled to the pinhole camera
        (:func:`photometric.camera.undistort_images`).

    Returns
    -------
    PhotometricInput

    Raises
    ------
    InputError, FileNotFoundError, NotADirectoryError
        Input that cannot be read or does not fit together (counts, sizes, options).
    """
    t0 = time.perf_counter()
    opts = _options(options)
    if pixel_size is not None:
        positive(pixel_size, "pixel_size")
    rig_obj = None if rig is None else (rig if isinstance(rig, Rig) else read_rig(rig))
    if lights is None and not (isinstance(source, (str, Path)) and Path(source).is_dir()):
        # point lights give the far-field directions (from the origin to each LED)
        if light_positions is not None:
            pos = load_light_positions(light_positions) if isinstance(light_positions, (str, Path)) else light_positions
            lights, name = _Checked(point_lights(pos).directions), "light_positions"
        elif rig_obj is not None:
            lights, name = _Checked(rig_obj.lights.directions), "rig"
        if lights is not None and isinstance(source, (Sequence, np.ndarray)) and not isinstance(source, str) \
                and len(source) != len(lights):
            raise InputError(f"{name}: {len(lights)} LEDs for {len(source)} images")
    data, info = _load_input(source, lights, intensities, mask, select, bayer)
    if bayer is not None and info["kind"] not in ("files", "folder"):
        raise InputError("bayer: only image files are read as mosaics (an array is already demosaiced)")
    if ambient is not None:
        if info["kind"] not in ("files", "folder"):  # the caller's array stays as it was
            data = replace(data, images=np.array(data.images, np.float32))
        if isinstance(ambient, (str, Path)) or (isinstance(ambient, Sequence) and ambient
                                                and all(isinstance(a, (str, Path)) for a in ambient)):
            read_ambient(ambient, data.images, bayer)
            info["ambient"] = [str(a) for a in ([ambient] if isinstance(ambient, (str, Path)) else ambient)]
        else:
            subtract_ambient(data.images, ambient)
            info["ambient"] = "array"
    if bayer is not None:
        info["bayer"] = bayer
    scene_h = info.pop("scene_pixel_size_mm", None)
    near = _near_setup(data, light_model=opts.light_model, light_positions=light_positions, led_mu=led_mu,
                       flat_field=flat_field, flat_albedo=flat_albedo, camera=camera, pixel_size=pixel_size,
                       scene_h=scene_h, focal_length_px=focal_length_px, camera_height_mm=camera_height_mm,
                       principal_point_px=principal_point_px, rig=rig, rig_obj=rig_obj, intensities=intensities,
                       led_axes=led_axes, distortion=distortion)
    if near is not None and getattr(near.camera, "distortion", None) is not None:
        # through the lens: the images (and mask) resampled to the pinhole camera every formula assumes
        imgs, m = undistort_images(near.camera, data.images, data.mask)
        data = replace(data, images=imgs, mask=m)
        info["undistorted"] = list(near.camera.distortion)
    if near is not None:
        h = near.camera.nominal_pixel_mm()
        h_source = near.camera_source
        if isinstance(near.camera, Perspective):
            h_source = f"camera_height_mm / focal_length_px at the reference plane ({near.camera_source})"
    elif pixel_size is not None:
        h, h_source = float(pixel_size), "option"
    elif scene_h is not None:
        h, h_source = positive(scene_h, "scene.json pixel_size_mm"), "scene.json"
    elif isinstance(data.camera, Orthographic):
        h, h_source = data.camera.pixel_size_mm, "scene.json"
    else:
        h, h_source = 1.0, "default (1 unit per pixel)"
    if not data.mask.any():
        raise InputError("mask: no pixel is selected")
    if opts.uncertainty is not None:  # before any solve: the size named
        check_monte_carlo_size(opts.uncertainty, data.images.shape[1:3])
    return PhotometricInput(data, near, float(h), h_source, info, _size(data), time.perf_counter() - t0)


def _size(data: PhotometricData) -> dict:
    n_img, rows, cols = data.images.shape[:3]
    return {"height": rows, "width": cols, "images": n_img,
            "channels": data.images.shape[3] if data.images.ndim == 4 else 1}


def solve(inp: PhotometricInput, options: PhotometricOptions | None = None, *,
          out: Callable[[str, tuple[int, ...], np.dtype], object] | None = None, residual: bool = True,
          threads: int | None = None, setup=None) -> Solution:
    """Normals and albedo (and, near field, the height): far or near field by the input's light model.

    Screens the images (:func:`photometric.stereo.screen_images`: a saturated or black image
    is left out with a warning, fewer than 3 usable is an error), checks the light matrix
    (:func:`photometric.stereo.check_light_matrix`), then solves with
    :func:`photometric.stereo.solve`'s kernels (distant lights, orthographic camera) or
    :func:`photometric.nearfield.solve_nearfield`'s alternation.

    Parameters
    ----------
    inp : PhotometricInput
        :func:`read`'s result.
    options : PhotometricOptions, optional
        ``outliers``, ``dark``, ``saturation``, ``highlight``, ``force`` and, near field,
        ``integrator``, ``reference_height_mm``, ``tolerance_mm``, ``max_iterations``.
    out : callable, optional
        Where the normals and albedo go instead of the result (bounded memory):
        ``out(name, shape, dtype)`` is called once for ``"normals"`` (H, W, 3) and
        ``"albedo"`` (H, W[, 3]), both float32, and returns an object that takes the rows
        in order by slice assignment (an array, a memmap or
        :func:`surfaces.io.npy_row_writer`'s writer). The far-field solve without
        ``options.uncertainty`` then runs in blocks of rows and drops the image stack.
    residual : bool
        Compute the fit residual (its mean is reported; the uncertainty stage estimates
        the noise from it). False saves about a tenth of a near-field solve.
    threads : int, optional
        Threads of the near-field solve (default: the CPU count up to 4).
    setup : photometric.nearfield.NearFieldSetup, optional
        The rig's strengths prepared once (:func:`photometric.nearfield.nearfield_setup`,
        with the rig's gains); near field only.

    Returns
    -------
    Solution

    Raises
    ------
    InputError
        Too few usable images, a light matrix above the condition limit without ``force``.
    photometric.nearfield.NotConvergedError
        A near-field solve that does not converge (carrying the summary so far).
    """
    from photometric.normals import angular_error_deg

    opts = _resolved(inp, options)
    t0 = time.perf_counter()
    data, near = inp.data, inp.setup
    n_img, rows, cols = data.images.shape[:3]
    notes = []
    # float input has no known full scale: only black pixels are screened there
    screen = screen_images(data.images, data.mask, SATURATED if data.full_scale else np.inf)
    if not screen.usable.all():
        bad = "; ".join(screen.problems(data.names))
        if screen.usable.sum() < 3:
            raise InputError(f"images: only {int(screen.usable.sum())} of {n_img} images are usable ({bad}); "
                             "photometric stereo needs 3")
        notes.append(f"images: {bad}: left out of the solve")
        if near is None:
            data = data.subset(screen.usable)
    directions = data.lights if near is None or near.model == "directional" else near.lights.directions
    cond, light_notes = _light_matrix(directions, opts.force)  # the lights were checked by read
    notes += light_notes
    dark = exposure_note(data.images, data.mask, data.full_scale)
    if dark is not None:
        notes.append(dark)
    if opts.estimate_intensities and (near is None or near.model != "point"):
        raise InputError("estimate_intensities: needs point lights (LED positions from --light-positions, --rig "
                         "or the folder)")
    intensity_note = _intensity_note(near, opts)
    if intensity_note is not None:
        notes.append(intensity_note)
    for note in notes:
        warnings.warn(note, UserWarning, stacklevel=3)
    timings = {"screen": time.perf_counter() - t0}
    sinks = None
    if out is not None:
        channels = data.images.shape[3] if data.images.ndim == 4 else 1
        sinks = (out("normals", (rows, cols, 3), np.dtype(np.float32)),
                 out("albedo", (rows, cols, 3) if channels == 3 else (rows, cols), np.dtype(np.float32)))
    gt_errors: list[np.ndarray] = []
    args = (opts.outliers, opts.dark, opts.saturation, opts.highlight, 2)
    if near is None:
        if sinks is not None and opts.uncertainty is None:
            def block(part_rows: slice, part) -> None:
                if data.normal_gt is not None:
                    gt_errors.append(angular_error_deg(part.normals, data.normal_gt[part_rows])[data.mask[part_rows]])
                sinks[0][part_rows] = part.normals
                sinks[1][part_rows] = part.albedo

            fit = _solve_rows(data.images, data.lights, data.intensities, data.mask, *args, block)
            # the image stack is not needed after the solve: the later stages fit in its place
            data = replace(data, images=None, flat_images=None)
        else:
            fit = _solve(data.images, data.lights, data.intensities, data.mask, *args)
        fit = restrict(fit, screen.enough)
        timings["solve"] = time.perf_counter() - t0 - timings["screen"]
    else:
        base = {"input": inp.info, "images": list(data.names), "size": inp.size}
        fit = _nearfield(replace(data, mask=data.mask & screen.enough), near, opts, base, threads=threads,
                         setup=setup, residual=residual)
        timings.update(solve=fit.timings_s["solve"], integrate=fit.timings_s["integrate"])
        model, alpha, weight = reflectance(inp, opts)
        if model == "glossy":
            t1 = time.perf_counter()
            fit = _refine_glossy(data, near, fit, opts, alpha, weight, inp.pixel_size_mm)
            timings["glossy"] = time.perf_counter() - t1
    del screen
    mean_residual = None
    if fit.residual is not None:
        mean_residual = float(fit.residual[fit.valid].mean()) if fit.valid.any() else 0.0
    if not residual or (near is None and opts.uncertainty is None):
        fit = replace(fit, residual=None)  # only its mean is reported
    if sinks is not None and fit.normals is not None:
        sinks[0][0:rows] = fit.normals
        sinks[1][0:rows] = fit.albedo
    errors = None
    if data.normal_gt is not None:
        errors = np.concatenate(gt_errors) if gt_errors else None
        if errors is None and fit.normals is not None:
            errors = angular_error_deg(fit.normals, data.normal_gt)[data.mask]
    timings["total"] = time.perf_counter() - t0
    return Solution(fit, data, float(cond), np.asarray(directions), notes, mean_residual, errors, timings)


def reflectance(inp: PhotometricInput, options: PhotometricOptions | None = None) -> tuple[str, float, float]:
    """The reflectance model of the solve and its parameters: the options', else the rig's, else Lambertian.

    Parameters
    ----------
    inp : PhotometricInput
    options : PhotometricOptions, optional
        ``reflectance``, ``gloss_alpha``, ``gloss_weight``.

    Returns
    -------
    (str, float, float)
        ``"lambertian"`` or ``"glossy"``, the GGX roughness ``alpha`` and the lobe weight
        (NaN for Lambertian).

    Raises
    ------
    InputError
        ``glossy`` without point lights and an orthographic camera, with fewer than 4
        lights, or without a roughness and a lobe weight (options or rig).
    """
    opts = _options(options)
    rig = inp.setup.reflectance if inp.setup is not None and inp.setup.reflectance else {}
    model = opts.reflectance or rig.get("model") or "lambertian"
    if model == "lambertian":
        return "lambertian", float("nan"), float("nan")
    alpha = opts.gloss_alpha if opts.gloss_alpha is not None else rig.get("alpha")
    weight = opts.gloss_weight if opts.gloss_weight is not None else rig.get("weight")
    if inp.setup is None or inp.setup.model != "point" or not isinstance(inp.setup.camera, Orthographic):
        raise InputError("reflectance: 'glossy' refines the near-field solve: it needs point lights (LED "
                         "positions or a rig) and an orthographic camera")
    if len(inp.setup.lights) < 4:
        raise InputError(f"reflectance: 'glossy' needs at least 4 lights, got {len(inp.setup.lights)}")
    if alpha is None or weight is None:
        raise InputError("reflectance: 'glossy' needs the material's roughness and lobe weight: --gloss-alpha and "
                         "--gloss-weight, or a rig calibrated on a reference part (workbench inspect calibrate "
                         "--reference-part DIR --reflectance glossy --gloss-alpha A)")
    return "glossy", float(alpha), float(weight)


def glossy_light_vectors(data: PhotometricData, near: LightSetup, points) -> tuple[np.ndarray, np.ndarray]:
    """The grey observations and the scaled light vectors the near-field solve uses, at given points.

    The same model as :func:`photometric.nearfield.solve_nearfield`: ``E_k = strength_k
    lobe_k(X) / |P_k - X|^2`` with the flat-field strengths when the set-up has gains
    (intensities then not divided out), ``e_k d0_k^2`` otherwise.

    Parameters
    ----------
    data : photometric.io.PhotometricData
        Images (N, H, W[, 3]).
    near : LightSetup
        Point lights.
    points : (H, W, 3) array_like
        ``x, y, z`` of each pixel's point, mm.

    Returns
    -------
    grey : (N, H, W) float32 array
    light_vectors : (N, H, W, 3) float64 array
    """
    from photometric.leds import _scaled_vectors
    from photometric.nearfield import _strengths
    from photometric.stereo import _grey_planes

    lights, cam = near.lights, near.camera
    shape = data.images.shape[1:3]
    flat = near.gains is not None
    divide = np.ones_like(near.intensities) if flat else near.intensities
    grey = np.stack(_grey_planes(data.images, divide)).astype(np.float32, copy=False)
    strength = _strengths(lights, cam, shape, near.gains, near.intensities)
    X = np.asarray(points, np.float64)
    lobe = lights.mu_known or not flat
    S = np.empty((len(lights),) + tuple(shape) + (3,))
    for k in range(len(lights)):
        comps = _scaled_vectors(lights.positions[k], lights.axes[k], float(lights.mu[k]),
                                np.asarray(strength[k], np.float64), X[..., 0], X[..., 1], X[..., 2], lobe=lobe)
        for c in range(3):
            S[k, ..., c] = comps[c]
    return grey, S


def _refine_glossy(data: PhotometricData, near: LightSetup, fit, opts: PhotometricOptions, alpha: float,
                   weight: float, h: float, passes: int = 2):
    """Refine the near-field solve's normals and albedo under the Lambertian + GGX model and integrate again.

    Each pass evaluates the light vectors at the current points, fits
    :func:`photometric.glossy.fit_glossy` from the current normals and integrates the
    slopes (the options' integrator, the median height of the valid pixels at
    ``reference_height_mm``: the near-field anchor).
    """
    from photometric.glossy import fit_glossy
    from photometric.integrate import integrate as integrate_slopes

    valid = fit.valid
    if not valid.any():
        return fit
    height, normals = fit.height, fit.normals.astype(np.float64)
    albedo = fit.albedo if fit.albedo.ndim == 2 else fit.albedo.mean(axis=-1)
    view = np.array([0.0, 0.0, 1.0])
    for _ in range(passes):
        points = np.concatenate([fit.xy, np.nan_to_num(height)[..., None]], axis=-1)
        grey, S = glossy_light_vectors(data, near, points)
        normals, albedo, _ = fit_glossy(grey, S, view, alpha, weight, normals, albedo, valid)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.where(valid, -normals[..., 0] / normals[..., 2], 0.0)
            q = np.where(valid, -normals[..., 1] / normals[..., 2], 0.0)
        z = integrate_slopes(p, q, opts.integrator, mask=valid, pixel_size=h)
        height = np.where(valid, z - np.median(z[valid]) + opts.reference_height_mm, np.nan)
    alb = albedo.astype(fit.albedo.dtype)
    if fit.albedo.ndim == 3:  # the colour albedo scaled by the grey refinement
        grey0 = fit.albedo.mean(axis=-1)
        ratio = np.divide(albedo, grey0, out=np.ones_like(albedo), where=grey0 > 0)
        alb = (fit.albedo * ratio[..., None]).astype(fit.albedo.dtype)
    return replace(fit, normals=normals.astype(fit.normals.dtype), albedo=alb, p=p.astype(fit.p.dtype),
                   q=q.astype(fit.q.dtype), height=height.astype(fit.height.dtype))


def integrate(inp: PhotometricInput, sol: Solution, options: PhotometricOptions | None = None) -> Height:
    """The height from the slopes (far field); the near-field solve's own height otherwise.

    Parameters
    ----------
    inp : PhotometricInput
    sol : Solution
    options : PhotometricOptions, optional
        ``integrator`` (:func:`photometric.integrate.integrate`).

    Returns
    -------
    Height
        Height in mm (float32 far field), NaN outside ``sol.fit.valid``.
    """
    from photometric.integrate import integrate as integrate_slopes

    if inp.setup is not None:
        return Height(sol.fit.height, sol.fit.timings_s["integrate"])
    t0 = time.perf_counter()
    fit = sol.fit
    height = integrate_slopes(fit.p, fit.q, _resolved(inp, options).integrator, mask=fit.valid,
                              pixel_size=inp.pixel_size_mm, dtype=np.float32)
    return Height(height, time.perf_counter() - t0)


def surface(inp: PhotometricInput, sol: Solution, height: Height,
            options: PhotometricOptions | None = None) -> Surface:
    """The shared surface model (bicubic patches) through the height, and its mesh.

    Parameters
    ----------
    inp : PhotometricInput
    sol : Solution
    height : Height
    options : PhotometricOptions, optional
        ``surface``, ``step``, ``samples``, ``surface_tolerance``.

    Returns
    -------
    Surface
    """
    opts = _options(options)
    t0 = time.perf_counter()
    fit = sol.fit
    patches, mesh, step_px, n_samples, info = _surface_step(
        opts.surface, height.height, fit.p, fit.q, fit.valid, sol.data.mask, inp.pixel_size_mm, opts.step,
        opts.samples, opts.surface_tolerance, xy=None if inp.orthographic else fit.xy, max_patches=opts.max_patches)
    return Surface(patches, mesh, step_px, n_samples, info, time.perf_counter() - t0)


def measure(inp: PhotometricInput, sol: Solution, height: Height, options: PhotometricOptions | None = None, *,
            labels: bool | None = None) -> Defects:
    """The defects (cracks, dents) of the height over its background.

    Parameters
    ----------
    inp : PhotometricInput
    sol : Solution
    height : Height
    options : PhotometricOptions, optional
        ``background``.
    labels : bool, optional
        Also return the label image; default: when ``options.uncertainty`` is given.

    Returns
    -------
    Defects
    """
    from photometric.defects import measure_defects

    opts = _options(options)
    t0 = time.perf_counter()
    fit = sol.fit
    want = opts.uncertainty is not None if labels is None else bool(labels)
    on_points = {} if inp.orthographic else {"xy": fit.xy, "area": fit.footprint_mm2}
    found = measure_defects(height.height, inp.pixel_size_mm, fit.valid, background=opts.background, p=fit.p,
                            q=fit.q, return_labels=want, **on_points)
    found, label_image = found if want else (found, None)
    return Defects(found, label_image, opts.background, time.perf_counter() - t0)


def uncertainty(inp: PhotometricInput, sol: Solution, height: Height, defects: Defects,
                options: PhotometricOptions) -> UncertaintyResult:
    """GUM uncertainty of the slopes, the height and every defect figure (no surface needed).

    :func:`photometric.uncertainty.propagate` with this solve's inputs; Monte Carlo re-runs
    the same solve (far field, or the near-field alternation), integration and defect measures.

    Parameters
    ----------
    inp : PhotometricInput
    sol : Solution
        With its images and residual (:func:`solve` keeps them when ``options.uncertainty``
        is given and ``residual`` is True).
    height : Height
    defects : Defects
        With ``labels`` (:func:`measure` gives them when ``options.uncertainty`` is given).
    options : PhotometricOptions
        ``uncertainty`` (the input standard uncertainties and the method) and the solve's options.

    Returns
    -------
    photometric.uncertainty.UncertaintyResult
    """
    opts = _resolved(inp, options)
    if opts.uncertainty is None:
        raise InputError("uncertainty: the options state no input uncertainties (options.uncertainty is None)")
    if defects.labels is None:
        raise InputError("defects: the uncertainty stage needs the defects' labels (measure(..., labels=True))")
    if sol.data.images is None:
        raise InputError("solution: the uncertainty stage needs the images (solve without streaming them)")
    return _uncertainty(opts.uncertainty, sol.data, inp.setup, sol.fit, height.height, defects.defects,
                        defects.labels, inp.pixel_size_mm, inp.pixel_size_source, opts)


#: Pixels above which :func:`quality` takes its figures from every s-th pixel of every s-th row.
QUALITY_PIXELS = 2_000_000


def quality(inp: PhotometricInput, sol: Solution, height: Height, defects: Defects,
            options: PhotometricOptions | None = None, *, limits=None, reference_slopes=None) -> dict:
    """Does the measurement deserve trust? Its quality figures against their limits (issue 32).

    :func:`photometric.quality.quality_figures` of the height (flatness about the options'
    background model, outside the defects found), the slopes (bias against a reference
    part's) and the valid pixels; :func:`photometric.quality.check` against the limits.
    Above :data:`QUALITY_PIXELS` pixels the figures come from every s-th pixel of every s-th
    row (``sample_step_px`` in the report).
    The per-light Lambertian residual is not computed here (it needs the solve's light
    vectors at every point, flat-field gains included): ``figures.lambertian_residual`` is
    empty, which :func:`~photometric.quality.check` skips; the per-frame dark, saturated and
    exposure checks are :mod:`photometric.frames`'.

    Parameters
    ----------
    inp, sol, height, defects :
        The stages' results (each defect's bounding box, grown by 3 pixels, is left out of
        the background figures).
    options : PhotometricOptions, optional
        ``background``.
    limits : photometric.quality.QualityLimits or dict, optional
        Default: the rig's (``rig.json`` ``quality.limits``) when the input has a rig with
        them, the stated :class:`photometric.quality.QualityLimits` defaults otherwise.
    reference_slopes : (float, float), optional
        A reference part's mean slopes ``p, q``; default the rig's; without one no slope bias.

    Returns
    -------
    dict
        :func:`photometric.quality.quality_report`: ``figures``, ``limits``,
        ``limits_source`` (``"option"``, ``"rig"`` or ``"default"``), ``failed`` (each with
        its ``reason``), ``trusted``, ``mean_slopes`` (``p, q`` over the background: what a
        reference part stores) and ``reference_slopes`` (None without a reference).
    """
    from photometric.quality import QualityLimits, mean_slopes, quality_figures, quality_report

    opts = _options(options)
    fit = sol.fit
    rig_q = inp.setup.quality if inp.setup is not None else None
    source = "default"
    if limits is not None:
        source = "option"
        limits = limits if isinstance(limits, QualityLimits) else QualityLimits(**dict(limits))
    elif rig_q is not None:
        source, limits = "rig", QualityLimits(**rig_q["limits"])
    if reference_slopes is None and rig_q is not None and rig_q.get("reference_slopes") is not None:
        reference_slopes = tuple(float(v) for v in rig_q["reference_slopes"])
    exclude = _defect_pixels(defects, fit.valid.shape)
    # statistical figures (an RMS, means, a fraction): on a large image every s-th pixel of every s-th
    # row gives them without full-size float64 copies (the stage's memory stays that of the defects')
    s = max(1, int(np.ceil(np.sqrt(fit.valid.size / QUALITY_PIXELS))))
    cut = (slice(None, None, s), slice(None, None, s))
    xy = None if inp.orthographic else fit.xy[cut]
    figures = quality_figures(height.height[cut], fit.valid[cut], p=fit.p[cut], q=fit.q[cut], exclude=exclude[cut],
                              mask=sol.data.mask[cut], background=opts.background, xy=xy,
                              reference_slopes=reference_slopes)
    report = quality_report(figures, limits, source)
    report["sample_step_px"] = s
    slopes = mean_slopes(fit.p[cut], fit.q[cut], fit.valid[cut], exclude[cut])
    report["mean_slopes"] = [v if np.isfinite(v) else None for v in slopes]
    report["reference_slopes"] = None if reference_slopes is None else [float(v) for v in reference_slopes]
    return report


def _defect_pixels(defects: Defects, shape, margin: int = 3) -> np.ndarray:
    """Each defect's bounding box grown by ``margin`` pixels (the same whether or not the labels were kept)."""
    out = np.zeros(shape, bool)
    for d in defects.defects:
        box = d.get("bbox_px")
        if box is not None:
            r0, c0, r1, c1 = (int(v) for v in box)
            out[max(r0 - margin, 0):r1 + margin, max(c0 - margin, 0):c1 + margin] = True
    return out


def summarize(inp: PhotometricInput, sol: Solution, height: Height, defects: Defects,
              options: PhotometricOptions | None = None, *, surf: Surface | None = None,
              unc: UncertaintyResult | None = None, timings: dict | None = None,
              quality_report: dict | None = None) -> dict:
    """The JSON-ready summary of the stages' results (``summary.json`` of a reconstruction).

    Parameters
    ----------
    inp, sol, height, defects :
        The stages' results.
    options : PhotometricOptions, optional
    surf : Surface, optional
        Adds the surface's entries (``patches``, ``mesh``, ``surface_max_dev_mm``, ...).
    unc : photometric.uncertainty.UncertaintyResult, optional
        Adds ``uncertainty``.
    timings : dict, optional
        Stage wall times in seconds (``timings_s``).
    quality_report : dict, optional
        :func:`quality`'s result when already computed (default: computed here).

    Returns
    -------
    dict
        ``quality`` (:func:`quality`: figures, limits, failed limits with reasons, ``trusted``;
        each failed limit is also a line of ``warnings`` for a near-field or perspective
        solve, while a far-field solve only states them with a ``note``), input, sizes,
        options, ``light_model`` and ``camera``, light condition number, invalid fraction,
        mean residual, height range, timings, number of defects,
        ``warnings`` and, with ``normal_gt``, ``mean_angular_error_deg`` and
        ``median_angular_error_deg`` (over the mask). Near-field and perspective solves add
        ``light_positions_mm``, ``led_mu``, ``flat_field``, ``iterations``,
        ``final_depth_change_mm``, ``converged``, ``tolerance_mm``, ``anchor`` and
        ``iteration_history``.
    """
    opts = _resolved(inp, options)
    fit, data, h = sol.fit, sol.data, inp.pixel_size_mm
    mask = data.mask
    n_mask = int(mask.sum())
    z = height.height
    summary = {
        "input": inp.info,
        "images": list(data.names),
        "size": inp.size,
        "pixel_size_mm": h,
        "pixel_size_source": inp.pixel_size_source,
        "integrator": opts.integrator,
        "outliers": bool(opts.outliers),
        "light_model": "directional",
        "camera": {"model": "orthographic", "pixel_size_mm": h},
        "light_condition_number": sol.condition_number,
        "light_condition_limits": {"warn": WARN_CONDITION, "refuse_without_force": MAX_CONDITION},
        "lights": sol.lights.tolist(),
        "mask_pixels": n_mask,
        "valid_pixels": int(fit.valid.sum()),
        "invalid_fraction": float(1.0 - fit.valid[mask].sum() / max(n_mask, 1)),
        "mean_residual": sol.mean_residual,
        "height_range_mm": float(np.nanmax(z) - np.nanmin(z)) if fit.valid.any() else 0.0,
    }
    if surf is None:
        summary["surface"] = "none"
    else:
        summary.update({
            "patches": list(surf.patches.shape),
            "patch_step_px": surf.step_px,
            "mesh_samples_per_patch": surf.samples,
            "mesh": {"vertices": int(surf.mesh.n_vertices), "triangles": int(surf.mesh.n_triangles)},
            **surf.info,
        })
    summary["n_defects"] = len(defects.defects)
    summary["timings_s"] = {k: round(v, 4) for k, v in (timings or {}).items()}
    summary["warnings"] = list(sol.warnings)
    if inp.setup is not None:
        summary.update(_near_summary(inp.setup, fit, opts.tolerance_mm))
        model, alpha, weight = reflectance(inp, opts)
        summary["reflectance"] = {"model": model} if model == "lambertian" else {
            "model": model, "alpha": alpha, "weight": weight,
            "source": "option" if opts.gloss_alpha is not None and opts.gloss_weight is not None else "rig"}
    if unc is not None:
        summary["uncertainty"] = unc.summary
    if sol.angular_errors_deg is not None:
        summary["mean_angular_error_deg"] = float(sol.angular_errors_deg.mean())
        summary["median_angular_error_deg"] = float(np.median(sol.angular_errors_deg))
    report = quality_report if quality_report is not None else quality(inp, sol, height, defects, opts)
    summary["quality"] = report
    if inp.setup is None:
        # a far-field object (a sculpture, a ball) is no flat part: its flatness is a shape, not an error
        report["note"] = ("far-field solve: the limits assume a flat part on an inspection rig (near field); "
                          "the figures are stated, no warning is raised")
        return summary
    for failed in report["failed"]:
        line = f"quality: {failed['reason']}"
        if line not in summary["warnings"]:
            summary["warnings"].append(line)
    return summary


def _uncertainty(tol: Tolerances, data: PhotometricData, near, res, height, defects, labels, h, h_source,
                 opts: PhotometricOptions) -> UncertaintyResult:
    """:func:`photometric.uncertainty.propagate` with this solve's inputs; Monte Carlo re-runs
    the same solve (far-field, or the near-field alternation), integration and defect measures."""
    from photometric.defects import measure_defects
    from photometric.integrate import integrate as integrate_slopes
    from photometric.uncertainty import PointLightModel, propagate

    integrator, background = opts.integrator, opts.background
    point, draw, lights, intensities = None, None, data.lights, data.intensities
    if near is not None:
        if tol.method == "linear" and near.model != "point":
            raise InputError("uncertainty: the linear propagation covers distant lights with an orthographic camera "
                             "and point lights with either camera; use method 'montecarlo' (--uncertainty "
                             "montecarlo) for distant lights seen by a perspective camera")
        lights, intensities = near.lights, near.intensities
        if near.model == "point":
            point = PointLightModel(
                near.lights, near.camera, near.gains, near.lights.mu_known or near.gains is None, res.xy,
                np.ones(len(near.lights)) if near.gains is not None else near.intensities.mean(axis=1))
            if tol.light_tolerance_deg > 0:
                raise InputError("light_tolerance_deg: point lights (LED positions) take light_position_tolerance_mm")
            u_pos = tol.light_position_tolerance_mm

            def draw(rng):
                moved = near.lights.positions + rng.normal(0.0, u_pos, near.lights.positions.shape)
                return point_lights(moved, near.lights.axes, near.lights.mu if near.lights.mu_known else None)

    def resolve(images, moved, intens):
        if near is None:
            r = _solve(images, moved, intens, data.mask, opts.outliers, opts.dark, opts.saturation, opts.highlight, 2)
            z = integrate_slopes(r.p, r.q, integrator, mask=r.valid, pixel_size=h)
            found = measure_defects(z, h, r.valid, background=background, p=r.p, q=r.q)
            return r.p, r.q, r.valid, z, found
        r = _solve_nearfield(images, moved, near.camera, intens, data.mask, near.gains, opts.outliers, opts.dark,
                             opts.saturation, opts.highlight, integrator, opts.reference_height_mm,
                             opts.tolerance_mm, opts.max_iterations, COARSE_PIXELS, None)
        on_points = {} if isinstance(near.camera, Orthographic) else {"xy": r.xy, "area": r.footprint_mm2}
        found = measure_defects(r.height, h, r.valid, background=background, p=r.p, q=r.q, **on_points)
        return r.p, r.q, r.valid, r.height, found

    h_u = h
    if near is not None and not isinstance(near.camera, Orthographic) and res.valid.any():
        # a perspective pixel covers its footprint at the part's height, not the reference-plane pixel:
        # the slope fields integrate, and the grid terms sample, at that spacing
        h_u = float(np.sqrt(np.median(np.broadcast_to(res.footprint_mm2, res.valid.shape)[res.valid])))
    return propagate(
        lights=lights.directions if point is not None else lights, intensities=intensities, albedo=res.albedo,
        p=res.p, q=res.q, valid=res.valid,
        height=height, defects=defects, labels=labels, pixel_size=h_u, tolerances=tol, integrator=integrator,
        background=background, residual=res.residual,
        channels=data.images.shape[3] if data.images.ndim == 4 else 1, images=data.images,
        pixel_size_given=not h_source.startswith("default"), resolve=resolve, point=point, draw=draw,
    )
