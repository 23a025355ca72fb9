"""Photometric stereo into a folder: :func:`photometric.pipeline.reconstruct`, then its files.

:func:`reconstruct_to_folder` is what ``workbench photometric reconstruct``, batch jobs
and the demo call. It builds the folder beside ``out_dir`` and swaps it in whole
(:func:`workbench.runs.folder.result_folder`: locked, previous result kept until the
swap, ``_COMPLETE`` marker last):

``normals.npy`` (H, W, 3) float32 unit, ``albedo.npy`` (H, W[, 3]) float32,
``p.npy``, ``q.npy`` (H, W) float32, ``valid.npy`` (H, W) bool, ``height.npy`` (H, W)
float64 in mm (NaN outside the solved pixels), ``normals.png``, ``albedo.png``,
``height.png`` (previews of :mod:`workbench.images`), ``surface.ply`` (mm, on the
centred pixel grid of :data:`surfaces.grid.GRID_CONVENTION`), ``defects.json`` and
``summary.json`` (the returned dict); near-field and perspective solves add ``xy.npy``
(H, W, 2) float64, the ``x, y`` (mm) of the point each pixel sees (:data:`NEARFIELD_FILES`).

A near-field solve that does not converge writes only ``summary.json`` (with
``converged: false``, the iteration history and the error) and raises the
:class:`photometric.nearfield.NotConvergedError` on: no result file is written from an
unconverged solve, and the command line ends with one line on stderr and exit code 2.

:func:`write_rig` writes a calibrated rig (``rig.json`` and its gains file) and
:func:`calibrate_to_rig` is what ``workbench photometric calibrate`` calls.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from photometric.nearfield import NotConvergedError
from photometric.pipeline import PhotometricReconstruction, reconstruct
from photometric.rig import Rig, rig_to_dict
from surfaces.io import atomic_path, save_npy, write_json, write_mesh, write_png
from workbench import images
from workbench.runs.folder import result_folder

__all__ = ["FILES", "NEARFIELD_FILES", "reconstruct_to_folder", "write_result", "write_rig", "calibrate_to_rig"]

#: Files written into the output folder (``summary.json`` lists them under ``files``).
FILES = (
    "normals.npy", "albedo.npy", "p.npy", "q.npy", "valid.npy", "height.npy", "normals.png",
    "albedo.png", "height.png", "surface.ply", "defects.json", "summary.json",
)
#: Files of a near-field or perspective reconstruction: :data:`FILES` and ``xy.npy``.
NEARFIELD_FILES = (*FILES, "xy.npy")


def write_result(result: PhotometricReconstruction, out_dir) -> dict:
    """Write a reconstruction's files into ``out_dir`` and return the content of ``summary.json``.

    Parameters
    ----------
    result : photometric.pipeline.PhotometricReconstruction
        What :func:`photometric.pipeline.reconstruct` returned.
    out_dir : str or Path
        Output folder (created when missing).

    Returns
    -------
    dict
        The library's summary with the ``write`` and ``total`` timings (s) and the
        sorted list of ``files``.
    """
    t0 = time.perf_counter()
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    pixel = result.summary["pixel_size_mm"]
    write_mesh(result.mesh, out / "surface.ply")
    save_npy(out / "normals.npy", result.normals)
    save_npy(out / "albedo.npy", result.albedo)
    save_npy(out / "p.npy", result.p)
    save_npy(out / "q.npy", result.q)
    save_npy(out / "valid.npy", result.valid)
    save_npy(out / "height.npy", result.height)
    if result.xy is not None:
        save_npy(out / "xy.npy", result.xy)
    write_png(out / "normals.png", images.normal_map(result.normals, result.valid))
    write_png(out / "albedo.png", images.albedo_image(result.albedo, result.mask))
    write_png(out / "height.png", images.scalar_image(
        result.height, result.valid, cmap="viridis", percentile=99.5, colorbar=False, min_height=1,
        background=(0.0, 0.0, 0.0)))
    write_json(
        out / "defects.json",
        {"units": "mm", "pixel_size_mm": pixel, "background": result.background, "defects": result.defects},
    )
    write = time.perf_counter() - t0
    summary: dict = {}
    for key, value in result.summary.items():
        if key == "timings_s":
            stages = {k: v for k, v in value.items() if k != "total"}
            value = {**stages, "write": round(write, 4), "total": round(value["total"] + write, 4)}
        summary[key] = value
        if key == "timings_s":
            summary["files"] = sorted(FILES if result.xy is None else NEARFIELD_FILES)
    write_json(out / "summary.json", summary)
    return summary


def reconstruct_to_folder(
    source, out_dir, *, progress: Callable[[str], None] | None = None, atomic: bool = True, **options
) -> dict:
    """Run :func:`photometric.pipeline.reconstruct` and write its result files into ``out_dir``.

    Parameters
    ----------
    source : str, Path, sequence of paths, array_like or PhotometricData
        Input of :func:`photometric.pipeline.reconstruct`.
    out_dir : str or Path
        Output folder: replaced whole by the new result (it must be missing, empty,
        or hold only a previous result's files).
    progress : callable, optional
        Called with the name of each stage as it starts: the library's ``read``,
        ``normals``, ``height``, ``surface``, ``defects``, then ``write``.
    atomic : bool
        Build the folder beside ``out_dir`` and swap it in (default). ``False``
        writes straight into ``out_dir``, for callers that already write into a
        temporary folder of their own (batch jobs).
    **options
        Keyword options of :func:`photometric.pipeline.reconstruct` (``lights``,
        ``intensities``, ``mask``, ``select``, ``integrator``, ``pixel_size``,
        ``outliers``, ``dark``, ``saturation``, ``highlight``, ``step``, ``samples``,
        ``background``).

    Returns
    -------
    dict
        The content of ``summary.json``: input, sizes, options, light model and camera,
        light condition number, invalid fraction, timings (s), files, mesh size, number
        of defects and, when the folder has ground truth, ``mean_angular_error_deg``
        (over the mask) and ``height_rmse_mm`` (over valid pixels, means removed).

    Raises
    ------
    photometric.nearfield.NotConvergedError
        After writing only ``summary.json`` (``converged: false``).
    """
    if not atomic:
        out = Path(out_dir)
        if out.exists() and not out.is_dir():
            raise NotADirectoryError(f"out_dir: {out} exists and is not a folder")
        return _reconstruct_into(source, out, out, progress, options)
    # the folder is checked and locked before the work, so a bad --out or a second writer is refused at once
    with result_folder(out_dir, owned=NEARFIELD_FILES) as tmp:
        summary = _reconstruct_into(source, tmp, Path(out_dir), progress, options)
    if "_message" in summary:
        raise NotConvergedError(summary.pop("_message"), summary)
    return summary


def _reconstruct_into(source, folder: Path, out: Path, progress, options) -> dict:
    """Reconstruct and write into ``folder``; a solver that did not converge leaves only ``summary.json``."""
    try:
        result = reconstruct(source, progress=progress, **options)
    except NotConvergedError as exc:
        # the summary of a failed solve is kept (swapped in) so the user can see why it failed
        folder.mkdir(parents=True, exist_ok=True)
        write_json(folder / "summary.json", {**exc.summary, "files": ["summary.json"]})
        message = f"{exc} (nothing else written; see {out / 'summary.json'})"
        if folder == out:
            raise NotConvergedError(message, exc.summary) from None
        return {**exc.summary, "_message": message}
    if progress is not None:
        progress("write")
    return write_result(result, folder)


def _signature() -> inspect.Signature:
    """The library's keyword options, so callers (batch manifests) can check option names."""
    lib = inspect.signature(reconstruct)
    head = [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ("source", "out_dir")]
    options = [p for name, p in lib.parameters.items() if name != "source"]
    return lib.replace(parameters=head + options, return_annotation=dict)


reconstruct_to_folder.__signature__ = _signature()


def write_rig(rig: Rig, path) -> dict:
    """Write ``rig.json`` and, with a flat field, its gains file ``<stem>_gains.npz`` beside it.

    Parameters
    ----------
    rig : photometric.rig.Rig
    path : str or Path
        The ``rig.json`` file (its folder is created when missing).

    Returns
    -------
    dict
        The content of ``rig.json`` (:func:`photometric.rig.rig_to_dict`).
    """
    target = Path(path)
    if target.exists() and target.is_dir():
        raise IsADirectoryError(f"--out: {target} is a folder; give the rig.json file name")
    target.parent.mkdir(parents=True, exist_ok=True)
    gains_file = f"{target.stem}_gains.npz"
    content = rig_to_dict(rig, gains_file)
    if rig.gains is not None:
        with atomic_path(target.parent / gains_file, suffix=".npz") as tmp:
            np.savez(tmp, gains=np.asarray(rig.gains, np.float32))
    write_json(target, content)
    return content


def calibrate_to_rig(out, *, spheres=None, light_positions=None, camera=None, flat_field=None,
                     flat_albedo: float | None = None, led_mu=None, intensities=None,
                     window_px: int | None = None) -> dict:
    """Calibrate a near-field rig and write it (``rig.json`` + gains): what ``calibrate`` runs.

    Parameters
    ----------
    out : str or Path
        The ``rig.json`` to write.
    spheres : sequence of str or Path, optional
        Two or more mirror-sphere folders (:func:`photometric.calibrate.read_sphere_set`).
    light_positions : str, Path or array_like, shape (N, 3), optional
        Known LED positions instead of spheres (mm).
    camera : photometric.camera camera, optional
        Default: the first sphere folder's ``scene.json`` camera.
    flat_field : sequence of paths, optional
        Flat-field images, one per light (:func:`photometric.rig.flat_field_gains`).
    flat_albedo : float, optional
        The flat target's albedo (default 1).
    led_mu : float or sequence, optional
        LED lobe exponents to store (unknown when omitted).
    intensities : str, Path, float or array_like, optional
        LED intensities to store.
    window_px : int, optional
        Highlight centroid window (:func:`photometric.calibrate.highlight_centroids`).

    Returns
    -------
    dict
        The content of ``rig.json``.
    """
    from photometric.calibrate import calibrate_rig

    rig = calibrate_rig(spheres=spheres, light_positions=light_positions, camera=camera, flat_field=flat_field,
                        flat_albedo=flat_albedo, led_mu=led_mu, intensities=intensities, window_px=window_px)
    return write_rig(rig, out)
