"""Photometric stereo end to end: images and lights in, a measured surface out (no files).

:func:`reconstruct` reads the input, solves normals and albedo
(:mod:`photometric.stereo`), integrates the height (:mod:`photometric.integrate`),
builds the shared surface model and its mesh and measures defects
(:mod:`photometric.defects`); it returns everything as one
:class:`PhotometricReconstruction` and writes nothing. The command line, the demo and
batch jobs write the result files with ``workbench.runs.photometric.reconstruct_to_folder``.

Input is validated once, here where it enters: lights and intensities by their readers
(:mod:`photometric.lights`), images and masks by :mod:`photometric.io`, the options
before any file is read; the solver and integrator then take the checked arrays.

Light model and camera: distant lights and an orthographic camera (the far-field path of
:func:`photometric.stereo.solve`) unless LED positions are known (``light_positions``, a
``rig``, or a folder's ``light_positions.txt``): then the near-field alternation of
:mod:`photometric.nearfield` with point lights, an orthographic or perspective camera
(:mod:`photometric.camera`) and, when given, flat-field gains (:mod:`photometric.rig`).
A perspective camera with distant lights integrates the log-depth once. A near-field solve
that does not converge raises :class:`photometric.nearfield.NotConvergedError` carrying
the summary (nothing else is returned).
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from photometric.camera import Camera, Orthographic, Perspective, make_camera
from photometric.io import PhotometricData, full_scale_of, read_folder, read_images, read_mask
from photometric.lights import (
    PointLights,
    as_intensities,
    load_intensities,
    load_light_positions,
    load_lights,
    point_lights,
    validate_lights,
)
from photometric.nearfield import (
    COARSE_PIXELS,
    DEFAULT_TOLERANCE_MM,
    NearFieldResult,
    NotConvergedError,
    _solve_nearfield,
)
from photometric.rig import FLAT_SMOOTHING_PX, Rig, check_rig, flat_field_gains, read_rig
from photometric.stereo import (
    MAX_CONDITION,
    SATURATED,
    WARN_CONDITION,
    _check_images,
    _check_options,
    _solve,
    _solve_rows,
    check_light_matrix,
    restrict,
    screen_images,
)
from photometric.uncertainty import Tolerances, UncertaintyResult, check_monte_carlo_size
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh
from surfaces.validate import as_array, InputError, positive

__all__ = ["SURFACES", "TARGET_PATCHES", "LIGHT_MODELS", "PhotometricReconstruction", "reconstruct"]

#: Patches per image side aimed at when ``step`` is not given.
TARGET_PATCHES = 64
#: Surface methods: the least-squares fit (:func:`surfaces.fit.fit_height`) and the Coons
#: interpolation of a decimated grid (:func:`photometric.integrate.height_to_patches`).
SURFACES = ("fit", "coons")
#: ``light_model`` choices: from the input (point lights when LED positions are known), or forced.
LIGHT_MODELS = ("auto", "point", "directional")


@dataclass(frozen=True)
class PhotometricReconstruction:
    """Everything :func:`reconstruct` computes.

    Attributes
    ----------
    normals : numpy.ndarray or None, shape (H, W, 3), float32
        Unit normals (:attr:`photometric.stereo.StereoResult.normals`); None when
        :func:`reconstruct` passed them to its ``out`` arrays.
    albedo : numpy.ndarray or None, shape (H, W) or (H, W, 3), float32
        Albedo; None like ``normals``.
    p, q : numpy.ndarray, shape (H, W), float32
        Slopes ``dz/dx``, ``dz/dy`` (y up); zero where not valid.
    valid : numpy.ndarray, shape (H, W), bool
        Pixels with a trustworthy normal.
    mask : numpy.ndarray, shape (H, W), bool
        The object mask of the input.
    height : numpy.ndarray, shape (H, W), float32 (far field) or float64 (near field)
        Height in mm (NaN outside the valid pixels); near-field: ``z`` of the point each
        pixel sees, in the rig frame.
    patches : surfaces.bezier.BezierPatches
        The bicubic surface: patches of mixed sizes fitted to the height and slopes
        (:class:`surfaces.mixed.MixedPatches` from :func:`surfaces.fit.fit_height`,
        ``surface="fit"``) or the Coons grid through the height
        (:func:`photometric.integrate.height_to_patches`, ``surface="coons"``).
    mesh : surfaces.mesh.TriangleMesh
        The tessellated surface, trimmed to the fitted pixels along their sub-pixel outline
        (fit) or to the mask by triangle centroids (coons); coordinates in mm on the
        centred pixel grid of :data:`surfaces.grid.GRID_CONVENTION`.
    defects : list of dict
        Defect measures (:func:`photometric.defects.measure_defects`).
    background : str
        Background removed before measuring the defects.
    summary : dict
        Input, sizes, options, ``light_model`` ("directional" or "point") and ``camera``,
        light condition number, invalid fraction, timings (s) of the stages ``read``,
        ``solve``, ``integrate``, ``surface``, ``defects``, mesh size, the surface method
        with ``surface_tolerance_mm`` and ``surface_patch_sizes_px`` (fit),
        ``surface_max_dev_mm`` and ``surface_rms_dev_mm`` (largest and RMS
        ``|surface - height|`` over the fitted (fit) or valid (coons) pixels), ``n_patches``
        and ``patches`` (the patch grid's shape; ``[n_patches, 1]`` for the fit's flat list
        of patches), number of defects and, with ground truth, ``mean_angular_error_deg``, ``median_angular_error_deg``
        (over the mask) and ``height_rmse_mm`` (over valid pixels, means removed).
        Near-field and perspective solves add ``light_positions_mm``, ``led_mu``,
        ``flat_field``, ``iterations``, ``final_depth_change_mm``, ``converged``,
        ``tolerance_mm``, ``anchor``, ``iteration_history`` and, with ground truth,
        ``height_bias_mm`` (mean height error, the anchor's) and ``xy_rmse_mm``. JSON-ready.
    xy : numpy.ndarray or None, shape (H, W, 2), float64
        ``x, y`` (mm) of the point each pixel sees (near-field and perspective solves;
        None on the far-field orthographic path, whose points are the pixel grid).
    uncertainty : photometric.uncertainty.UncertaintyResult or None
        Per-pixel ``p_u``, ``q_u``, ``height_u`` and the defects' budgets, when
        ``uncertainty`` was given.
    """

    normals: np.ndarray | None
    albedo: np.ndarray | None
    p: np.ndarray
    q: np.ndarray
    valid: np.ndarray
    mask: np.ndarray
    height: np.ndarray
    patches: BezierPatches
    mesh: TriangleMesh
    defects: list
    background: str
    summary: dict
    xy: np.ndarray | None = None
    uncertainty: UncertaintyResult | None = None


def _lights(lights) -> np.ndarray:
    return load_lights(lights) if isinstance(lights, (str, Path)) else validate_lights(lights)


def _intensities(intensities, n: int) -> np.ndarray:
    return load_intensities(intensities, n) if isinstance(intensities, (str, Path)) else as_intensities(intensities, n)


def _mask(mask, shape) -> np.ndarray:
    if isinstance(mask, (str, Path)):
        return read_mask(mask, shape)
    return as_array(mask, "mask", shape=shape, dtype=bool)


def _load_input(source, lights, intensities, mask, select) -> tuple[PhotometricData, dict]:
    """PhotometricData from a folder, a list of image files or an image array."""
    if isinstance(source, PhotometricData):
        return source, {"kind": "data"}
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        data = read_folder(source, select=select)
        folder = Path(source)
        extra = {}
        for truth in ("height_gt", "xy_gt"):
            if (folder / f"{truth}.npy").is_file():
                extra[truth] = np.load(folder / f"{truth}.npy", allow_pickle=False)
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
        images = read_images(list(source))
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


@dataclass(frozen=True)
class _Near:
    """The light model and camera of a near-field or perspective solve (checked)."""

    model: str  # "point" or "directional"
    lights: PointLights | np.ndarray
    camera: Camera
    camera_source: str  # where the camera came from: "option", "rig" or "scene.json"
    gains: np.ndarray | None
    flat: dict | None  # source, albedo, smoothing_px of the gains
    intensities: np.ndarray
    rig: str | None


def _light_positions(value, n: int, led_mu) -> PointLights:
    pos = load_light_positions(value) if isinstance(value, (str, Path)) else value
    lights = point_lights(pos, mu=led_mu)
    if len(lights) != n:
        raise InputError(f"light_positions: {len(lights)} LED positions for {n} images")
    return lights


def _with_mu(lights: PointLights, led_mu) -> PointLights:
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
                pixel_size, scene_h, focal_length_px, camera_height_mm, principal_point_px, rig,
                intensities) -> _Near | None:
    """Decide the light model and camera; None means the far-field orthographic path of today.

    Precedence: the options, then ``rig.json``, then the folder's own files
    (``light_positions.txt``, ``scene.json`` lights and camera, ``flat_*.png``).
    """
    n, shape = data.images.shape[0], data.images.shape[1:3]
    rig_obj = None
    if rig is not None:
        rig_obj = rig if isinstance(rig, Rig) else read_rig(rig)
        check_rig(rig_obj, n, shape)
    if light_positions is not None:
        lights = _light_positions(light_positions, n, led_mu)
    elif rig_obj is not None:
        lights = _with_mu(rig_obj.lights, led_mu)
    elif data.point_lights is not None:
        lights = _with_mu(data.point_lights, led_mu)
    else:
        lights = None
    if led_mu is not None and lights is None:
        raise InputError("led_mu: the LED lobe needs LED positions (--light-positions or --rig)")

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

    if light_model == "directional" or lights is None:
        if light_model == "point":
            raise InputError("light_model: 'point' needs LED positions (--light-positions, --rig or the "
                             "folder's light_positions.txt)")
        if flat_field is not None and flat_field is not False:
            raise InputError("flat_field: flat-field gains need the point-light model (LED positions from "
                             "--light-positions, --rig or the folder, and not --light-model directional)")
        if cam is None or isinstance(cam, Orthographic):
            return None
        return _Near("directional", data.lights, cam, cam_source, None, None, data.intensities, None)
    if cam is None:
        raise InputError("camera: point lights need the camera's scale in mm: --pixel-size (orthographic) or "
                         "--camera perspective --focal-length-px F --camera-height MM")
    gains, flat = None, None
    if flat_field is not None and flat_field is not False:
        albedo = 1.0 if flat_albedo is None else flat_albedo
        gains = flat_field_gains(_flat_images(flat_field, n, shape), lights, cam, albedo)
        flat = {"source": "option", "albedo": float(albedo)}
    elif flat_field is None and rig_obj is not None and rig_obj.gains is not None:
        gains = rig_obj.gains
        flat = {"source": "rig", "albedo": rig_obj.flat_albedo, "smoothing_px": rig_obj.flat_smoothing_px}
    elif flat_field is None and data.flat_images is not None:
        albedo = flat_albedo if flat_albedo is not None else (data.flat_albedo or 1.0)
        gains = flat_field_gains(data.flat_images, lights, cam, albedo)
        flat = {"source": "folder", "albedo": float(albedo)}
    if flat is not None and flat["source"] != "rig":
        flat["smoothing_px"] = FLAT_SMOOTHING_PX
    intens = data.intensities
    if intensities is None and rig_obj is not None and rig_obj.intensities is not None:
        intens = rig_obj.intensities
    rig_name = None if rig is None or isinstance(rig, Rig) else str(rig)
    return _Near("point", lights, cam, cam_source, gains, flat, intens, rig_name)


def _near_summary(near: _Near, res: NearFieldResult, tolerance_mm: float) -> dict:
    """The light model, camera and convergence record of ``summary.json``."""
    out: dict = {"light_model": near.model, "camera": near.camera.to_dict(res.valid.shape)}
    if near.model == "point":
        out["light_positions_mm"] = near.lights.positions.tolist()
        out["led_mu"] = near.lights.mu.tolist() if near.lights.mu_known else None
        out["flat_field"] = near.flat
        out["rig"] = near.rig
    out.update({
        "iterations": res.iterations,
        "final_depth_change_mm": res.depth_change_mm,
        "converged": True,
        "tolerance_mm": tolerance_mm,
        "anchor": res.anchor,
        "iteration_history": list(res.history),
    })
    return out


def _nearfield(data: PhotometricData, near: _Near, *, outliers, dark, saturation, highlight, integrator,
               reference_height_mm, tolerance_mm, max_iterations, base: dict) -> NearFieldResult:
    """The near-field (or perspective) solve; no convergence raises with the summary so far."""
    ref = float(reference_height_mm)
    if isinstance(near.camera, Perspective) and ref >= near.camera.camera_height_mm:
        raise InputError(f"reference_height_mm: {ref:g} mm is not below the camera "
                         f"({near.camera.camera_height_mm:g} mm)")
    if near.model == "point" and np.any(near.lights.positions[:, 2] <= ref):
        raise InputError(f"reference_height_mm: {ref:g} mm is not below every light")
    try:
        return _solve_nearfield(
            data.images, near.lights, near.camera, near.intensities, data.mask, near.gains, outliers, dark,
            saturation, highlight, integrator, float(reference_height_mm), float(tolerance_mm),
            int(max_iterations), COARSE_PIXELS, None,
        )
    except NotConvergedError as exc:
        summary = {**base, "light_model": near.model, "camera": near.camera.to_dict(data.images.shape[1:3]),
                   **exc.summary, "error": str(exc)}
        raise NotConvergedError(str(exc), summary) from None


def _surface_step(method, height, p, q, valid, mask, h, step, samples, tolerance, xy=None):
    """The surface model, its mesh and their summary entries (the ``surface`` stage).

    ``xy`` (H, W, 2), mm: the points a perspective camera's pixels see; the fit then
    places the surface at them instead of on the orthographic grid.
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
        fit = fit_height(height, p, q, mask=valid, pixel_size=h, tolerance=tolerance,
                         step=step if step is not None else default_step(shape), xy=xy, keep_pixels=False)
        step_px = fit.step
        n_samples = int(samples) if samples is not None else min(step_px, 8)
        info = {"surface": "fit", "surface_tolerance_mm": fit.tolerance,
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


def reconstruct(
    source,
    *,
    lights=None,
    intensities=None,
    mask=None,
    select: str | Sequence[str] | None = None,
    integrator: str = "dct",
    pixel_size: float | None = None,
    outliers: bool = False,
    dark: float = 0.1,
    saturation: float = 0.99,
    highlight: float | None = None,
    step: int | None = None,
    samples: int | None = None,
    surface: str = "fit",
    surface_tolerance: float | None = None,
    background: str = "plane",
    light_positions=None,
    led_mu=None,
    flat_field=None,
    flat_albedo: float | None = None,
    camera=None,
    focal_length_px: float | None = None,
    camera_height_mm: float | None = None,
    principal_point_px=None,
    rig=None,
    light_model: str = "auto",
    reference_height_mm: float = 0.0,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    max_iterations: int = 30,
    uncertainty: Tolerances | dict | None = None,
    force: bool = False,
    progress: Callable[[str], None] | None = None,
    out: Callable[[str, tuple[int, ...], np.dtype], object] | None = None,
) -> PhotometricReconstruction:
    """Run photometric stereo end to end and return every result (writes nothing).

    Parameters
    ----------
    source : str, Path, sequence of paths, array_like or PhotometricData
        A DiLiGenT-style folder (:func:`photometric.io.read_folder`), image files, or an
        ``(N, H, W[, 3])`` image array.
    lights : str, Path or array_like, shape (N, 3), optional
        Light directions (file or array); required for files/arrays, overrides a
        folder's own.
    intensities : str, Path, float or array_like, optional
        Light intensities (scalar, (N,) or (N, 3)); overrides a folder's own.
    mask : str, Path or array_like, shape (H, W), optional
        Object mask; overrides a folder's ``mask.png``.
    select : None, "triad" or sequence of str, optional
        Subset of a folder's images (``"triad"``: those in ``triad.txt``).
    integrator : {"dct", "fc", "lsq", "robust"}
        Height integrator (:func:`photometric.integrate.integrate`), near-field solves
        too (:data:`photometric.nearfield.INTEGRATORS`).
    pixel_size : float, optional
        Pixel size in mm (heights, defect measures and the mesh are in mm); default: the
        folder's ``scene.json`` ``pixel_size_mm`` when present, else 1.
    outliers, dark, saturation, highlight :
        Shadow/highlight handling, see :func:`photometric.stereo.solve`.
    step : int, optional
        Pixels per patch of the surface model: the largest patch side of the fit (rounded
        down to a power of two; default :func:`surfaces.fit.default_step`, about 64 patches
        across) or the Coons decimation step (default ``ceil(max(H, W) / 64)``, at least 2).
    samples : int, optional
        Mesh subdivisions per (largest) patch side; default ``min(step, 8)`` (about one
        vertex per pixel). The fit's mesh lies on a lattice of ``step / samples`` pixels.
    surface : {"fit", "coons"}
        ``"fit"``: bicubic patches fitted by least squares to the height and the slopes of
        every pixel, refined where they miss ``surface_tolerance`` (:func:`surfaces.fit.fit_height`);
        ``"coons"``: Coons patches through the decimated height with tangents from single
        pixels' slopes (:func:`photometric.integrate.height_to_patches`).
    surface_tolerance : float, optional
        Largest deviation of the fitted surface from the height, mm (> 0); default 0.5 % of
        the height range (:data:`surfaces.fit.RELATIVE_TOLERANCE`). Fit only.
    background : {"plane", "smooth"}
        Background removed before measuring defects.
    light_positions : str, Path or array_like, shape (N, 3), optional
        LED positions in mm (``light_positions.txt``: ``x y z`` per image); selects the
        near-field model (:mod:`photometric.nearfield`). Default: the rig's, else a
        folder's ``light_positions.txt``.
    led_mu : float or array_like, shape (N,), optional
        LED lobe exponents ``mu`` (0: isotropic); default the rig's or the folder's
        ``scene.json``, else unknown (isotropic; a flat field measures the lobe).
    flat_field : sequence of paths, array_like (N, H, W[, 3]) or False, optional
        Flat-field images (a flat matte target in the reference plane, one per light);
        default the rig's gains, else a folder's ``flat_*.png``; False: none.
    flat_albedo : float, optional
        The flat target's albedo (default the folder's ``scene.json``, else 1).
    camera : {"orthographic", "perspective"} or camera object, optional
        Camera model (:mod:`photometric.camera`); default the rig's or the folder's
        ``scene.json``, else orthographic with ``pixel_size``.
    focal_length_px, camera_height_mm : float, optional
        Perspective focal length (pixels) and camera height above the reference plane
        (mm), both required for a perspective camera.
    principal_point_px : (cx, cy), optional
        Perspective principal point (column, row); default the image centre.
    rig : str, Path or photometric.rig.Rig, optional
        A calibrated rig (``rig.json``): LED positions, camera, flat-field gains; must
        match the images' count and size.
    light_model : {"auto", "point", "directional"}
        ``auto``: point lights when LED positions are known; ``directional``: today's
        far-field model even then (directions from the origin to the LEDs).
    reference_height_mm : float
        Near-field anchor: the median height of the valid pixels, mm
        (:func:`photometric.camera.depth_from_field`).
    tolerance_mm, max_iterations :
        Near-field convergence (:func:`photometric.nearfield.solve_nearfield`).
    uncertainty : photometric.uncertainty.Tolerances or dict, optional
        Input standard uncertainties and the method (:mod:`photometric.uncertainty`); when
        given, the result carries ``uncertainty`` and the summary an ``uncertainty`` key.
    force : bool
        Solve even when the light matrix's condition number is above
        :data:`photometric.stereo.MAX_CONDITION` (100; above
        :data:`photometric.stereo.WARN_CONDITION`, 10, it is a warning).
    progress : callable, optional
        Called with the name of each stage as it starts (``read``, ``normals``,
        ``height``, ``surface``, ``defects``, ``uncertainty`` when asked; the command line's progress bar).
    out : callable, optional
        Where the normals and albedo go instead of the result (bounded memory):
        ``out(name, shape, dtype)`` is called once for ``"normals"`` (H, W, 3) and
        ``"albedo"`` (H, W[, 3]), both float32, and returns an object that takes the
        rows in order by slice assignment, ``obj[rows] = block`` (an array, a memmap or
        :func:`surfaces.io.npy_row_writer`'s writer). The far-field solve without
        ``uncertainty`` runs in blocks of rows (:func:`photometric.stereo.solve`'s
        ``on_block``), the image stack is dropped once solved, and the result's
        ``normals`` and ``albedo`` are None; other solves pass their whole arrays as one block.

    Returns
    -------
    PhotometricReconstruction
        Arrays, surface, mesh, defects and the summary (``warnings``: one line each, also
        issued as ``UserWarning``).

    Notes
    -----
    Inputs that cannot give a result (:func:`photometric.stereo.screen_images`):
    observations at or above :data:`photometric.stereo.SATURATED` (integer image files:
    within half an 8-bit step of full scale 1) or below
    :data:`photometric.stereo.BLACK_FLOOR` are invalid, a pixel with fewer than 3 valid
    observations is invalid (counted in ``invalid_fraction``); an image that is saturated
    or black over the mask is left out with a warning, and fewer than 3 usable images is
    an error. Lights with ``z < 0`` are an error.
    """
    from photometric.defects import measure_defects
    from photometric.integrate import METHODS, integrate
    from photometric.normals import angular_error_deg

    if integrator not in METHODS:
        raise InputError(f"integrator: expected one of {METHODS}, got {integrator!r}")
    if pixel_size is not None:
        positive(pixel_size, "pixel_size")
    if samples is not None and int(samples) < 1:
        raise InputError(f"samples: must be at least 1, got {samples}")
    if step is not None and int(step) < 1:
        raise InputError(f"step: must be at least 1 pixel, got {step}")
    if surface not in SURFACES:
        raise InputError(f"surface: expected one of {SURFACES}, got {surface!r}")
    if surface_tolerance is not None:
        positive(surface_tolerance, "surface_tolerance")
    _check_options(dark, saturation, highlight, 2)
    if light_model not in LIGHT_MODELS:
        raise InputError(f"light_model: expected one of {LIGHT_MODELS}, got {light_model!r}")
    positive(tolerance_mm, "tolerance_mm")
    if int(max_iterations) < 1:
        raise InputError(f"max_iterations: must be at least 1, got {max_iterations}")
    if not np.isfinite(float(reference_height_mm)):
        raise InputError(f"reference_height_mm: must be finite, got {reference_height_mm}")
    if isinstance(uncertainty, dict):
        uncertainty = Tolerances(**uncertainty)
    elif uncertainty is not None and not isinstance(uncertainty, Tolerances):
        raise InputError(f"uncertainty: expected Tolerances, a dict or None, got {type(uncertainty).__name__}")
    say = progress or (lambda _stage: None)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    say("read")
    t0 = time.perf_counter()
    if lights is None and not (isinstance(source, (str, Path)) and Path(source).is_dir()):
        # point lights give the far-field directions (from the origin to each LED)
        if light_positions is not None:
            pos = load_light_positions(light_positions) if isinstance(light_positions, (str, Path)) else light_positions
            lights, name = point_lights(pos).directions, "light_positions"
        elif rig is not None:
            lights, name = (rig if isinstance(rig, Rig) else read_rig(rig)).lights.directions, "rig"
        if lights is not None and isinstance(source, (Sequence, np.ndarray)) and not isinstance(source, str) \
                and len(source) != len(lights):
            raise InputError(f"{name}: {len(lights)} LEDs for {len(source)} images")
    data, input_info = _load_input(source, lights, intensities, mask, select)
    height_gt = input_info.pop("height_gt", None)
    xy_gt = input_info.pop("xy_gt", None)
    scene_h = input_info.pop("scene_pixel_size_mm", None)
    near = _near_setup(data, light_model=light_model, light_positions=light_positions, led_mu=led_mu,
                       flat_field=flat_field, flat_albedo=flat_albedo, camera=camera, pixel_size=pixel_size,
                       scene_h=scene_h, focal_length_px=focal_length_px, camera_height_mm=camera_height_mm,
                       principal_point_px=principal_point_px, rig=rig, intensities=intensities)
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
    timings["read"] = time.perf_counter() - t0
    n_img, rows, cols = data.images.shape[:3]
    channels = data.images.shape[3] if data.images.ndim == 4 else 1
    check_monte_carlo_size(uncertainty, (rows, cols))  # before any solve: the size named

    say("normals")
    t0 = time.perf_counter()
    if not data.mask.any():
        raise InputError("mask: no pixel is selected")
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
    cond, light_notes = check_light_matrix(
        data.lights if near is None or near.model == "directional" else near.lights.directions, force)
    notes += light_notes
    for note in notes:
        warnings.warn(note, UserWarning, stacklevel=2)
    sinks = None
    if out is not None:
        shape3 = (rows, cols, 3)
        sinks = (out("normals", shape3, np.dtype(np.float32)),
                 out("albedo", shape3 if channels == 3 else (rows, cols), np.dtype(np.float32)))
    gt_errors: list[np.ndarray] = []
    if near is None:
        if sinks is not None and uncertainty is None:
            def block(part_rows: slice, part) -> None:
                if data.normal_gt is not None:
                    gt_errors.append(angular_error_deg(part.normals, data.normal_gt[part_rows])[data.mask[part_rows]])
                sinks[0][part_rows] = part.normals
                sinks[1][part_rows] = part.albedo

            res = _solve_rows(data.images, data.lights, data.intensities, data.mask, outliers, dark, saturation,
                              highlight, 2, block)
            # the image stack is not needed after the solve: the later stages fit in its place
            data = replace(data, images=None, flat_images=None)
        else:
            res = _solve(data.images, data.lights, data.intensities, data.mask, outliers, dark, saturation,
                         highlight, 2)
        res = restrict(res, screen.enough)
        del screen
        mean_residual = _mean_residual(res)
        if uncertainty is None:
            res = replace(res, residual=None)  # only its mean is reported
        timings["solve"] = time.perf_counter() - t0

        say("height")
        t0 = time.perf_counter()
        height = integrate(res.p, res.q, integrator, mask=res.valid, pixel_size=h, dtype=np.float32)
        timings["integrate"] = time.perf_counter() - t0
    else:
        base = {"input": input_info, "images": list(data.names),
                "size": {"height": rows, "width": cols, "images": n_img, "channels": channels}}
        res = _nearfield(replace(data, mask=data.mask & screen.enough), near, outliers=outliers, dark=dark,
                         saturation=saturation, highlight=highlight,
                         integrator=integrator, reference_height_mm=reference_height_mm, tolerance_mm=tolerance_mm,
                         max_iterations=max_iterations, base=base)
        say("height")
        height = res.height
        timings["solve"] = res.timings_s["solve"]
        timings["integrate"] = res.timings_s["integrate"]
        mean_residual = _mean_residual(res)
    if sinks is not None and res.normals is not None:
        sinks[0][0:rows] = res.normals
        sinks[1][0:rows] = res.albedo

    say("surface")
    t0 = time.perf_counter()
    patches, mesh, step_px, n_samples, surface_info = _surface_step(
        surface, height, res.p, res.q, res.valid, data.mask, h, step, samples, surface_tolerance,
        xy=None if near is None or isinstance(near.camera, Orthographic) else res.xy)
    timings["surface"] = time.perf_counter() - t0

    say("defects")
    t0 = time.perf_counter()
    on_points = {} if near is None or isinstance(near.camera, Orthographic) else {
        "xy": res.xy, "area": res.footprint_mm2}
    defects = measure_defects(height, h, res.valid, background=background, p=res.p, q=res.q,
                              return_labels=uncertainty is not None, **on_points)
    if uncertainty is not None:
        defects, labels = defects
    timings["defects"] = time.perf_counter() - t0
    unc = None
    if uncertainty is not None:
        say("uncertainty")
        t0 = time.perf_counter()
        unc = _uncertainty(uncertainty, data, near, res, height, defects, labels, h, h_source, integrator,
                           background, outliers, dark, saturation, highlight, reference_height_mm, tolerance_mm,
                           max_iterations)
        timings["uncertainty"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all

    n_mask = int(data.mask.sum())
    summary = {
        "input": input_info,
        "images": list(data.names),
        "size": {"height": rows, "width": cols, "images": n_img, "channels": channels},
        "pixel_size_mm": h,
        "pixel_size_source": h_source,
        "integrator": integrator,
        "outliers": bool(outliers),
        "light_model": "directional",
        "camera": {"model": "orthographic", "pixel_size_mm": h},
        "light_condition_number": cond,
        "light_condition_limits": {"warn": WARN_CONDITION, "refuse_without_force": MAX_CONDITION},
        "lights": (data.lights if near is None or near.model == "directional" else near.lights.directions).tolist(),
        "mask_pixels": n_mask,
        "valid_pixels": int(res.valid.sum()),
        "invalid_fraction": float(1.0 - res.valid[data.mask].sum() / max(n_mask, 1)),
        "mean_residual": mean_residual,
        "height_range_mm": float(np.nanmax(height) - np.nanmin(height)) if res.valid.any() else 0.0,
        "patches": list(patches.shape),
        "patch_step_px": step_px,
        "mesh_samples_per_patch": n_samples,
        "mesh": {"vertices": int(mesh.n_vertices), "triangles": int(mesh.n_triangles)},
        **surface_info,
        "n_defects": len(defects),
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
        "warnings": notes,
    }
    if near is not None:
        summary.update(_near_summary(near, res, float(tolerance_mm)))
    if unc is not None:
        summary["uncertainty"] = unc.summary
    if data.normal_gt is not None:
        err = np.concatenate(gt_errors) if gt_errors else angular_error_deg(res.normals, data.normal_gt)[data.mask]
        summary["mean_angular_error_deg"] = float(err.mean())
        summary["median_angular_error_deg"] = float(np.median(err))
    if height_gt is not None and np.shape(height_gt) == (rows, cols) and res.valid.any():
        v = res.valid & np.isfinite(height)
        hv = height[v].astype(np.float64)
        diff = (hv - hv.mean()) - (height_gt[v] - height_gt[v].mean())
        summary["height_rmse_mm"] = float(np.sqrt(np.mean(diff**2)))
        if near is not None:
            summary["height_bias_mm"] = float(np.mean(hv - height_gt[v]))
            if xy_gt is not None and np.shape(xy_gt) == (rows, cols, 2):
                summary["xy_rmse_mm"] = float(np.sqrt(np.mean(np.sum((res.xy[v] - xy_gt[v]) ** 2, axis=1))))
    return PhotometricReconstruction(
        normals=None if sinks is not None else res.normals,
        albedo=None if sinks is not None else res.albedo,
        p=res.p,
        q=res.q,
        valid=res.valid,
        mask=data.mask,
        height=height,
        patches=patches,
        mesh=mesh,
        defects=defects,
        background=background,
        summary=summary,
        xy=None if near is None else res.xy,
        uncertainty=unc,
    )


def _mean_residual(res) -> float:
    """Mean of a solve's residual over its valid pixels (0 when none is valid)."""
    return float(res.residual[res.valid].mean()) if res.valid.any() else 0.0


def _uncertainty(tol: Tolerances, data: PhotometricData, near, res, height, defects, labels, h, h_source,
                 integrator, background, outliers, dark, saturation, highlight, reference_height_mm, tolerance_mm,
                 max_iterations) -> UncertaintyResult:
    """:func:`photometric.uncertainty.propagate` with this solve's inputs; Monte Carlo re-runs
    the same solve (far-field, or the near-field alternation), integration and defect measures."""
    from photometric.defects import measure_defects
    from photometric.integrate import integrate
    from photometric.uncertainty import PointLightModel, propagate

    point, draw, lights, intensities = None, None, data.lights, data.intensities
    if near is not None:
        if tol.method == "linear" and not (near.model == "point" and isinstance(near.camera, Orthographic)):
            raise InputError("uncertainty: the linear propagation covers distant lights and point lights with an "
                             "orthographic camera; use method 'montecarlo' (--uncertainty montecarlo) here")
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
            r = _solve(images, moved, intens, data.mask, outliers, dark, saturation, highlight, 2)
            z = integrate(r.p, r.q, integrator, mask=r.valid, pixel_size=h)
            found = measure_defects(z, h, r.valid, background=background, p=r.p, q=r.q)
            return r.p, r.q, r.valid, z, found
        r = _solve_nearfield(images, moved, near.camera, intens, data.mask, near.gains, outliers, dark, saturation,
                             highlight, integrator, float(reference_height_mm), float(tolerance_mm),
                             int(max_iterations), COARSE_PIXELS, None)
        on_points = {} if isinstance(near.camera, Orthographic) else {"xy": r.xy, "area": r.footprint_mm2}
        found = measure_defects(r.height, h, r.valid, background=background, p=r.p, q=r.q, **on_points)
        return r.p, r.q, r.valid, r.height, found

    return propagate(
        lights=lights.directions if point is not None else lights, intensities=intensities, albedo=res.albedo,
        p=res.p, q=res.q, valid=res.valid,
        height=height, defects=defects, labels=labels, pixel_size=h, tolerances=tol, integrator=integrator,
        background=background, residual=res.residual,
        channels=data.images.shape[3] if data.images.ndim == 4 else 1, images=data.images,
        pixel_size_given=not h_source.startswith("default"), resolve=resolve, point=point, draw=draw,
    )
