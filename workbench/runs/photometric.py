"""Photometric stereo into a folder: :func:`photometric.pipeline.reconstruct`, then its files.

:func:`reconstruct_to_folder` is what ``workbench photometric reconstruct``, batch jobs
and the demo call. It builds the folder beside ``out_dir`` and swaps it in whole
(:func:`workbench.runs.folder.result_folder`: locked, previous result kept until the
swap, ``_COMPLETE`` marker last):

``normals.npy`` (H, W, 3) float32 unit, ``albedo.npy`` (H, W[, 3]) float32,
``p.npy``, ``q.npy`` (H, W) float32, ``valid.npy`` (H, W) bool, ``height.npy`` (H, W)
float32 in mm (float64 from near-field solves; NaN outside the solved pixels), ``normals.png``, ``albedo.png``,
``height.png`` (previews of :mod:`workbench.images`), ``surface.ply`` (mm, on the
centred pixel grid of :data:`surfaces.grid.GRID_CONVENTION`), ``defects.json`` and
``summary.json`` (the returned dict); near-field and perspective solves add ``xy.npy``
(H, W, 2) float64, the ``x, y`` (mm) of the point each pixel sees (:data:`NEARFIELD_FILES`).
With ``uncertainty`` (:mod:`photometric.uncertainty`) it adds :data:`UNCERTAINTY_FILES`:
``p_u.npy``, ``q_u.npy`` (H, W) float32 standard uncertainties of the slopes,
``height_u.npy`` (H, W) float32 standard uncertainty of the height in mm, and
``uncertainty.json`` (the GUM budget of every defect figure); each defect in
``defects.json`` then carries ``uncertainty_k2`` (expanded uncertainties, k = 2).

Memory: the normals and albedo are written block by block of rows as they are solved
(the library's ``out`` arrays are :func:`surfaces.io.npy_row_writer` files in the
temporary result folder), and the previews are drawn from blocks of rows, so the
peak is the image stack and a few (H, W) planes, not every result at once.

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
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from photometric.nearfield import NotConvergedError
from photometric.pipeline import PhotometricReconstruction, reconstruct
from photometric.rig import Rig, rig_to_dict
from surfaces.colormap import scalar_range
from surfaces.io import atomic_path, npy_row_writer, read_npy_rows, save_npy, write_json, write_mesh, write_png
from workbench import images
from workbench.runs.folder import result_folder

__all__ = ["FILES", "NEARFIELD_FILES", "UNCERTAINTY_FILES", "reconstruct_to_folder", "write_result", "write_rig",
           "calibrate_to_rig"]

#: Files written into the output folder (``summary.json`` lists them under ``files``).
FILES = (
    "normals.npy", "albedo.npy", "p.npy", "q.npy", "valid.npy", "height.npy", "normals.png",
    "albedo.png", "height.png", "surface.ply", "defects.json", "summary.json",
)
#: Files of a near-field or perspective reconstruction: :data:`FILES` and ``xy.npy``.
NEARFIELD_FILES = (*FILES, "xy.npy")
#: Files added when the reconstruction carries uncertainties.
UNCERTAINTY_FILES = ("p_u.npy", "q_u.npy", "height_u.npy", "uncertainty.json")
#: Pixels per block of rows when the previews are drawn (a few MB of working arrays).
PREVIEW_PIXELS = 1 << 18


def _write_uncertainty(unc, defects: list, pixel: float, out: Path) -> list:
    """``p_u.npy``, ``q_u.npy``, ``height_u.npy``, ``uncertainty.json``; the defects with their
    ``uncertainty_k2``."""
    save_npy(out / "p_u.npy", unc.p_u)
    save_npy(out / "q_u.npy", unc.q_u)
    save_npy(out / "height_u.npy", unc.height_u)
    write_json(out / "uncertainty.json", {
        "units": "mm", "pixel_size_mm": pixel, "guide": "GUM (ISO/IEC Guide 98-3)",
        **unc.summary, "defects": [{"id": d["id"], "budget": d["budget"]} for d in unc.defects]})
    k2 = {d["id"]: d["uncertainty_k2"] for d in unc.defects}
    return [{**rec, "uncertainty_k2": k2[rec["id"]]} if rec["id"] in k2 else rec for rec in defects]


def write_result(result: PhotometricReconstruction, out_dir) -> dict:
    """Write a reconstruction's files into ``out_dir`` and return the content of ``summary.json``.

    Parameters
    ----------
    result : photometric.pipeline.PhotometricReconstruction
        What :func:`photometric.pipeline.reconstruct` returned. When its ``normals``
        and ``albedo`` are None, they were streamed to ``normals.npy`` and
        ``albedo.npy`` in ``out_dir`` already (the ``out`` arrays of
        :func:`reconstruct_to_folder`), and their previews are drawn from those files.
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
    streamed = result.normals is None
    if streamed and not ((out / "normals.npy").is_file() and (out / "albedo.npy").is_file()):
        raise FileNotFoundError(f"out_dir: the result carries no normals and albedo, and {out} has no "
                                "normals.npy and albedo.npy (run reconstruct with out= arrays in this folder)")
    if not streamed:
        save_npy(out / "normals.npy", result.normals)
        save_npy(out / "albedo.npy", result.albedo)
    save_npy(out / "p.npy", result.p)
    save_npy(out / "q.npy", result.q)
    save_npy(out / "valid.npy", result.valid)
    save_npy(out / "height.npy", result.height)
    if result.xy is not None:
        save_npy(out / "xy.npy", result.xy)
    _write_previews(result, out)
    defects = result.defects
    files = list(FILES if result.xy is None else NEARFIELD_FILES)
    if result.uncertainty is not None:
        defects = _write_uncertainty(result.uncertainty, defects, pixel, out)
        files += UNCERTAINTY_FILES
    write_json(
        out / "defects.json",
        {"units": "mm", "pixel_size_mm": pixel, "background": result.background, "defects": defects},
    )
    write = time.perf_counter() - t0
    summary: dict = {}
    for key, value in result.summary.items():
        if key == "timings_s":
            stages = {k: v for k, v in value.items() if k != "total"}
            value = {**stages, "write": round(write, 4), "total": round(value["total"] + write, 4)}
        summary[key] = value
        if key == "timings_s":
            summary["files"] = sorted(files)
    write_json(out / "summary.json", summary)
    return summary


def _write_previews(result: PhotometricReconstruction, out: Path) -> None:
    """``normals.png``, ``albedo.png``, ``height.png``: the pictures of :mod:`workbench.images`, drawn in
    blocks of rows.

    Each picture is what its :mod:`workbench.images` function gives for the whole image: the
    scale (albedo percentile, height percentiles) is taken over the whole image first, and
    the per-pixel drawing then runs on blocks of rows (the whole-image functions hold a few
    float64 copies of the image, 24 bytes per pixel for the normals).
    """
    from surfaces.fit import percentiles

    rows, cols = result.valid.shape
    step = max(1, PREVIEW_PIXELS // cols)

    def blocks(name: str, array):
        for r0 in range(0, rows, step):
            r1 = min(r0 + step, rows)
            yield slice(r0, r1), (read_npy_rows(out / f"{name}.npy", r0, r1) if array is None else array[r0:r1])

    # filled in RGB through a view of a BGR buffer: the PNG encoder's BGR copy is then this buffer itself
    bgr = np.empty((rows, cols, 3), np.uint8)
    pic = bgr[..., ::-1]
    for r, block in blocks("normals", result.normals):
        pic[r] = images.normal_map(block, result.valid[r])
    write_png(out / "normals.png", pic)

    # images.albedo_image: white at the 99.5th percentile of the finite albedo inside the mask (float64)
    vals = _gather(lambda: blocks("albedo", result.albedo), lambda r: result.mask[r])
    top = float(percentiles(vals, (99.5,))[0]) if vals.size else 1.0
    del vals
    for r, block in blocks("albedo", result.albedo):
        pic[r] = images.to_uint8(block.astype(np.float64), vmax=top if top > 0 else 1.0)
        pic[r][~result.mask[r]] = 0
    write_png(out / "albedo.png", pic)

    # images.scalar_image(height, valid, percentile=99.5): its colour range over the valid finite heights
    vals = _gather(lambda: blocks("height", result.height), lambda r: result.valid[r])
    vmin = vmax = None
    if vals.size:
        vmin, vmax = (float(v) for v in percentiles(vals, (0.5, 99.5)))
    del vals
    # the ends are known whenever a value is (scalar_range would copy the values only to find them)
    lo, hi = scalar_range(np.empty(0), vmin, vmax)
    for r, block in blocks("height", result.height):
        pic[r] = images.scalar_image(block, result.valid[r], cmap="viridis", vmin=lo, vmax=hi, colorbar=False,
                                     min_height=1, background=(0.0, 0.0, 0.0))
    write_png(out / "height.png", pic)


def _gather(blocks: Callable, select: Callable) -> np.ndarray:
    """The finite values ``block[select(rows)]`` of all blocks, in order, as one array in the blocks'
    float type (float32 maps stay float32: :func:`surfaces.fit.percentiles` gives their float64
    percentiles without a float64 copy).

    Two passes over ``blocks()`` (a fresh iterator of ``(rows, block)`` each call), so only
    the result is the size of the selection.
    """
    count, dtype = 0, np.dtype(np.float32)
    for r, b in blocks():
        count += int(np.count_nonzero(np.isfinite(b[select(r)])))
        dtype = np.promote_types(dtype, b.dtype)
    vals = np.empty(count, dtype)
    at = 0
    for r, b in blocks():
        part = b[select(r)]
        part = part[np.isfinite(part)]
        vals[at : at + part.size] = part
        at += part.size
    return vals


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
        ``normals``, ``height``, ``surface``, ``defects`` (and ``uncertainty``), then ``write``.
    atomic : bool
        Build the folder beside ``out_dir`` and swap it in (default). ``False``
        writes straight into ``out_dir``, for callers that already write into a
        temporary folder of their own (batch jobs).
    **options
        Keyword options of :func:`photometric.pipeline.reconstruct` (``lights``,
        ``intensities``, ``mask``, ``select``, ``integrator``, ``pixel_size``,
        ``outliers``, ``dark``, ``saturation``, ``highlight``, ``step``, ``samples``,
        ``surface``, ``surface_tolerance``, ``background``, ``uncertainty``: a
        :class:`photometric.uncertainty.Tolerances` or its dict, which adds
        :data:`UNCERTAINTY_FILES`).

    Returns
    -------
    dict
        The content of ``summary.json``: input, sizes, options, light model and camera,
        light condition number, invalid fraction, timings (s), files, mesh size, number
        of defects and, when the folder has ground truth, ``mean_angular_error_deg``
        (over the mask) and ``height_rmse_mm`` (over valid pixels, means removed;
        :func:`datasets_synthetic.truth.height_errors`, with ``height_bias_mm`` and
        ``xy_rmse_mm`` for near-field solves).

    Raises
    ------
    photometric.nearfield.NotConvergedError
        After writing only ``summary.json`` (``converged: false``).
    """
    if not atomic:
        out = Path(out_dir)
        if out.exists() and not out.is_dir():
            raise NotADirectoryError(f"out_dir: {out} exists and is not a folder")
        out.mkdir(parents=True, exist_ok=True)
        result = _reconstruct_or_summary(source, out, progress, options)
        return write_result(result, out)
    # the folder is checked and locked before the work, so a bad --out or a second writer is refused at once;
    # a run that does not converge swaps in a folder that holds only its summary.json
    failure = None
    with result_folder(out_dir, owned=(*NEARFIELD_FILES, *UNCERTAINTY_FILES)) as tmp:
        try:
            result = _reconstruct_or_summary(source, tmp, progress, options)
        except NotConvergedError as exc:
            failure = exc
        else:
            summary = write_result(result, tmp)
    if failure is not None:
        where = Path(out_dir) / "summary.json"
        raise NotConvergedError(f"{failure} (nothing else written; see {where})", failure.summary) from None
    return summary


def _reconstruct_or_summary(source, out: Path, progress, options) -> PhotometricReconstruction:
    """Run the reconstruction, its normals and albedo streamed into ``out``; when it does not converge,
    write only ``summary.json`` into ``out`` and re-raise."""
    try:
        # each file appears (renamed into place) once all its rows are written; a failure removes it
        with ExitStack() as files:
            def stream(name: str, shape: tuple[int, ...], dtype) -> object:
                return files.enter_context(npy_row_writer(out / f"{name}.npy", shape, dtype))

            result = reconstruct(source, progress=progress, out=stream, **options)
    except NotConvergedError as exc:
        write_json(out / "summary.json", {**exc.summary, "files": ["summary.json"]})
        raise
    if isinstance(source, (str, Path)) and Path(source).is_dir():
        # a synthetic folder's height_gt.npy / xy_gt.npy: the errors go into summary.json
        from datasets_synthetic.truth import height_errors, read_truth

        result.summary.update(height_errors(result.height, result.valid, read_truth(source), xy=result.xy,
                                            anchored=result.xy is not None))
    if progress is not None:
        progress("write")
    return result


def _signature() -> inspect.Signature:
    """The library's keyword options, so callers (batch manifests) can check option names."""
    lib = inspect.signature(reconstruct)
    head = [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ("source", "out_dir")]
    options = [p for name, p in lib.parameters.items() if name not in ("source", "out")]
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
