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
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photometric.io import PhotometricData, read_folder, read_images, read_mask
from photometric.lights import _condition, as_intensities, load_intensities, load_lights, validate_lights
from photometric.stereo import _check_images, _check_options, _solve
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh
from surfaces.validate import as_array, positive

__all__ = ["SURFACES", "TARGET_PATCHES", "PhotometricReconstruction", "reconstruct"]

#: Patches per image side aimed at when ``step`` is not given.
TARGET_PATCHES = 64
#: Surface methods: the least-squares fit (:func:`surfaces.fit.fit_height`) and the Coons
#: interpolation of a decimated grid (:func:`photometric.integrate.height_to_patches`).
SURFACES = ("fit", "coons")


@dataclass(frozen=True)
class PhotometricReconstruction:
    """Everything :func:`reconstruct` computes.

    Attributes
    ----------
    normals : numpy.ndarray, shape (H, W, 3), float32
        Unit normals (:attr:`photometric.stereo.StereoResult.normals`).
    albedo : numpy.ndarray, shape (H, W) or (H, W, 3), float32
        Albedo.
    p, q : numpy.ndarray, shape (H, W), float32
        Slopes ``dz/dx``, ``dz/dy`` (y up); zero where not valid.
    valid : numpy.ndarray, shape (H, W), bool
        Pixels with a trustworthy normal.
    mask : numpy.ndarray, shape (H, W), bool
        The object mask of the input.
    height : numpy.ndarray, shape (H, W), float64
        Height in mm (NaN outside the valid pixels).
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
        Input, sizes, options, light condition number, invalid fraction, timings (s) of
        the stages ``read``, ``solve``, ``integrate``, ``surface``, ``defects``, mesh
        size, the surface method with ``surface_tolerance_mm`` and ``surface_patch_sizes_px``
        (fit), ``surface_max_dev_mm`` and ``surface_rms_dev_mm`` (largest and RMS
        ``|surface - height|`` over the fitted (fit) or valid (coons) pixels), ``n_patches``
        and ``patches`` (the patch grid's shape; ``[n_patches, 1]`` for the fit's flat list of
        patches), number of defects and, with ground truth, ``mean_angular_error_deg``,
        ``median_angular_error_deg`` (over the mask) and ``height_rmse_mm`` (over valid
        pixels, means removed). JSON-ready.
    """

    normals: np.ndarray
    albedo: np.ndarray
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
        if (folder / "height_gt.npy").is_file():
            extra["height_gt"] = np.load(folder / "height_gt.npy", allow_pickle=False)
        if (folder / "scene.json").is_file():
            # datasets_synthetic folders state their pixel size
            try:
                scene = json.loads((folder / "scene.json").read_text())
            except json.JSONDecodeError as exc:
                raise ValueError(f"input: {folder / 'scene.json'} is not valid JSON ({exc})") from None
            if isinstance(scene, dict) and "pixel_size_mm" in scene:
                extra["scene_pixel_size_mm"] = float(scene["pixel_size_mm"])
        replace = {}
        if lights is not None:
            replace["lights"] = _lights(lights)
            if replace["lights"].shape[0] != len(data.names):
                raise ValueError(f"lights: {replace['lights'].shape[0]} directions for {len(data.names)} images")
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
        raise ValueError("lights: required when the input is a list of images or an array")
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
        raise ValueError(f"lights: {L.shape[0]} directions for {images.shape[0]} images")
    n = images.shape[0]
    shape = images.shape[1:3]
    m = np.ones(shape, bool) if mask is None else _mask(mask, shape)
    return PhotometricData(images, L, _intensities(intensities, n), m, None, names), kind


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


def _surface_step(method, height, p, q, valid, mask, h, step, samples, tolerance):
    """The surface model, its mesh and their summary entries (the ``surface`` stage)."""
    shape = height.shape
    if method == "coons":
        from photometric.integrate import height_to_patches

        step_px = int(step) if step is not None else max(2, int(np.ceil(max(shape) / TARGET_PATCHES)))
        patches = height_to_patches(height, p, q, pixel_size=h, step=step_px)
        n_samples = int(samples) if samples is not None else min(step_px, 8)
        mesh = _trimmed_mesh(patches, mask, h, n_samples)
        dev = _coons_deviation(patches, height, valid)
        info = {"surface": "coons"}
    else:
        from surfaces.fit import default_step, fit_height, fit_mesh

        fit = fit_height(height, p, q, mask=valid, pixel_size=h, tolerance=tolerance,
                         step=step if step is not None else default_step(shape))
        step_px = fit.step
        n_samples = int(samples) if samples is not None else min(step_px, 8)
        mesh = fit_mesh(fit, spacing=step_px / n_samples)
        patches = fit.patches
        dev = np.abs(fit.deviation[fit.region])
        info = {"surface": "fit", "surface_tolerance_mm": fit.tolerance,
                "surface_patch_sizes_px": {str(k): v for k, v in fit.patch_sizes().items()}}
    info.update(surface_max_dev_mm=float(dev.max()), surface_rms_dev_mm=float(np.sqrt(np.mean(dev**2))),
                n_patches=int(patches.n_patches))
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
    progress: Callable[[str], None] | None = None,
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
    integrator : {"dct", "fc", "lsq"}
        Height integrator (:func:`photometric.integrate.integrate`).
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
    progress : callable, optional
        Called with the name of each stage as it starts (``read``, ``normals``,
        ``height``, ``surface``, ``defects``; the command line's progress bar).

    Returns
    -------
    PhotometricReconstruction
        Arrays, surface, mesh, defects and the summary.
    """
    from photometric.defects import measure_defects
    from photometric.integrate import METHODS, integrate
    from photometric.normals import angular_error_deg

    if integrator not in METHODS:
        raise ValueError(f"integrator: expected one of {METHODS}, got {integrator!r}")
    if pixel_size is not None:
        positive(pixel_size, "pixel_size")
    if samples is not None and int(samples) < 1:
        raise ValueError(f"samples: must be at least 1, got {samples}")
    if step is not None and int(step) < 1:
        raise ValueError(f"step: must be at least 1 pixel, got {step}")
    if surface not in SURFACES:
        raise ValueError(f"surface: expected one of {SURFACES}, got {surface!r}")
    if surface_tolerance is not None:
        positive(surface_tolerance, "surface_tolerance")
    _check_options(dark, saturation, highlight, 2)
    say = progress or (lambda _stage: None)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()

    say("read")
    t0 = time.perf_counter()
    data, input_info = _load_input(source, lights, intensities, mask, select)
    height_gt = input_info.pop("height_gt", None)
    scene_h = input_info.pop("scene_pixel_size_mm", None)
    if pixel_size is not None:
        h, h_source = float(pixel_size), "option"
    elif scene_h is not None:
        h, h_source = positive(scene_h, "scene.json pixel_size_mm"), "scene.json"
    else:
        h, h_source = 1.0, "default (1 unit per pixel)"
    timings["read"] = time.perf_counter() - t0
    n_img, rows, cols = data.images.shape[:3]
    channels = data.images.shape[3] if data.images.ndim == 4 else 1

    say("normals")
    t0 = time.perf_counter()
    if not data.mask.any():
        raise ValueError("mask: no pixel is selected")
    res = _solve(data.images, data.lights, data.intensities, data.mask, outliers, dark, saturation, highlight, 2)
    timings["solve"] = time.perf_counter() - t0

    say("height")
    t0 = time.perf_counter()
    height = integrate(res.p, res.q, integrator, mask=res.valid, pixel_size=h)
    timings["integrate"] = time.perf_counter() - t0

    say("surface")
    t0 = time.perf_counter()
    patches, mesh, step_px, n_samples, surface_info = _surface_step(
        surface, height, res.p, res.q, res.valid, data.mask, h, step, samples, surface_tolerance)
    timings["surface"] = time.perf_counter() - t0

    say("defects")
    t0 = time.perf_counter()
    defects = measure_defects(height, h, res.valid, background=background, p=res.p, q=res.q)
    timings["defects"] = time.perf_counter() - t0
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
        "light_condition_number": _condition(data.lights),
        "lights": data.lights.tolist(),
        "mask_pixels": n_mask,
        "valid_pixels": int(res.valid.sum()),
        "invalid_fraction": float(1.0 - res.valid[data.mask].sum() / max(n_mask, 1)),
        "mean_residual": float(res.residual[res.valid].mean()) if res.valid.any() else 0.0,
        "height_range_mm": float(np.nanmax(height) - np.nanmin(height)) if res.valid.any() else 0.0,
        "patches": list(patches.shape),
        "patch_step_px": step_px,
        "mesh_samples_per_patch": n_samples,
        "mesh": {"vertices": int(mesh.n_vertices), "triangles": int(mesh.n_triangles)},
        **surface_info,
        "n_defects": len(defects),
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
    }
    if data.normal_gt is not None:
        err = angular_error_deg(res.normals, data.normal_gt)[data.mask]
        summary["mean_angular_error_deg"] = float(err.mean())
        summary["median_angular_error_deg"] = float(np.median(err))
    if height_gt is not None and np.shape(height_gt) == (rows, cols) and res.valid.any():
        v = res.valid & np.isfinite(height)
        diff = (height[v] - height[v].mean()) - (height_gt[v] - height_gt[v].mean())
        summary["height_rmse_mm"] = float(np.sqrt(np.mean(diff**2)))
    return PhotometricReconstruction(
        normals=res.normals,
        albedo=res.albedo,
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
    )
