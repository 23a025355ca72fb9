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
``summary.json`` (the returned dict).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from pathlib import Path

from photometric.pipeline import PhotometricReconstruction, reconstruct
from surfaces.io import save_npy, write_json, write_mesh, write_png
from workbench import images
from workbench.runs.folder import result_folder

__all__ = ["FILES", "reconstruct_to_folder", "write_result"]

#: Files written into the output folder (``summary.json`` lists them under ``files``).
FILES = (
    "normals.npy", "albedo.npy", "p.npy", "q.npy", "valid.npy", "height.npy", "normals.png",
    "albedo.png", "height.png", "surface.ply", "defects.json", "summary.json",
)


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
            summary["files"] = sorted(FILES)
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
        ``surface``, ``surface_tolerance``, ``background``).

    Returns
    -------
    dict
        The content of ``summary.json``: input, sizes, options, light condition number,
        invalid fraction, timings (s), files, mesh size, number of defects and, when the
        folder has ground truth, ``mean_angular_error_deg`` (over the mask) and
        ``height_rmse_mm`` (over valid pixels, means removed).
    """
    if not atomic:
        result = reconstruct(source, progress=progress, **options)
        if progress is not None:
            progress("write")
        return write_result(result, out_dir)
    # the folder is checked and locked before the work, so a bad --out or a second writer is refused at once
    with result_folder(out_dir, owned=FILES) as tmp:
        result = reconstruct(source, progress=progress, **options)
        if progress is not None:
            progress("write")
        return write_result(result, tmp)


def _signature() -> inspect.Signature:
    """The library's keyword options, so callers (batch manifests) can check option names."""
    lib = inspect.signature(reconstruct)
    head = [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ("source", "out_dir")]
    options = [p for name, p in lib.parameters.items() if name != "source"]
    return lib.replace(parameters=head + options, return_annotation=dict)


reconstruct_to_folder.__signature__ = _signature()
