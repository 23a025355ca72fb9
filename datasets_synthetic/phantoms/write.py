"""A phantom's files: contour stack, surface sample, ground truth and optional DICOM series."""

from __future__ import annotations

import os
from pathlib import Path

from datasets_synthetic.io import ensure_dir
from datasets_synthetic.phantoms.base import Phantom
from datasets_synthetic.phantoms.scaled import Kidney
from surfaces.io import save_npy, write_json
from surfaces.validate import InputError, positive


def write_phantom(
    out_dir: str | os.PathLike,
    phantom: Phantom,
    spacing: float,
    pixel: float,
    fmt: str = "json",
    n_points: int = 64,
    noise_mm: float = 0.0,
    seed: int = 0,
    offset_mm: float = 0.0,
    n_surface: int = 20000,
    progress: bool = False,
) -> dict:
    """Write a phantom's contour stack, optional DICOM files and its ground truth.

    Always writes ``contours.json`` (``{"units": "mm", "contours": [{"z", "points"}]}``),
    ``truth.json`` and ``surface_points.npy`` ((n_surface, 3) float64, mm). With
    ``fmt="dicom"`` also a CT series in ``ct/`` (one file per slice, see
    :func:`datasets_synthetic.dicom.write_ct_series`); with ``fmt="rtstruct"`` the CT
    series and ``rtstruct.dcm`` referencing it.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    phantom : Phantom
        The solid.
    spacing : float
        Slice spacing in mm (contour planes and CT slices).
    pixel : float
        In-plane CT pixel size in mm.
    fmt : {"json", "dicom", "rtstruct"}
        Which extra files to write.
    n_points : int
        Points on the longest contour (see :meth:`Phantom.contours`).
    noise_mm : float
        Contour noise, mm.
    seed : int
        Random seed (contours, surface sample, CT noise and UIDs).
    offset_mm : float
        Shift of the slice grid from the phantom's centre plane.
    n_surface : int
        Size of the surface sample.
    progress : bool
        Show tqdm progress bars (command line only).

    Returns
    -------
    dict
        The ``truth.json`` content (see :meth:`Phantom.truth`) plus ``n_contours``,
        ``points_per_contour`` (min, max), ``pixel_mm``, ``noise_mm``, ``seed``,
        ``format`` and ``files``.
    """
    if not isinstance(phantom, Phantom):
        raise InputError(f"phantom: expected a Phantom, got {type(phantom).__name__}")
    if fmt not in ("json", "dicom", "rtstruct"):
        raise InputError(f"fmt: expected 'json', 'dicom' or 'rtstruct', got {fmt!r}")
    spacing = positive(spacing, "spacing")
    pixel = positive(pixel, "pixel")
    out = ensure_dir(out_dir)
    contours = phantom.contours(spacing, n_points=n_points, noise_mm=noise_mm, seed=seed,
                                offset_mm=offset_mm)
    truth = phantom.truth(spacing, offset_mm)
    counts = [len(c["points"]) for c in contours]
    truth.update({"n_contours": len(contours), "points_per_contour": [min(counts), max(counts)],
                  "pixel_mm": pixel, "noise_mm": float(noise_mm), "seed": int(seed), "format": fmt})
    if isinstance(phantom, Kidney):
        truth["area_accuracy_mm2"] = phantom.area_accuracy_mm2
    files = {"contours": "contours.json", "truth": "truth.json", "surface_points": "surface_points.npy"}
    write_json(out / "contours.json", {"units": "mm", "contours": [
        {"z": c["z"], "points": c["points"]} for c in contours]})
    save_npy(out / "surface_points.npy", phantom.surface_points(int(n_surface), seed=seed))
    if fmt in ("dicom", "rtstruct"):
        from datasets_synthetic.dicom import write_ct_series, write_rtstruct

        series = write_ct_series(Path(out) / "ct", phantom, spacing, pixel, offset_mm=offset_mm,
                                 seed=seed, progress=progress)
        files["ct"] = "ct"
        truth["ct"] = {k: v for k, v in series.items() if k != "slices"}
        if fmt == "rtstruct":
            write_rtstruct(Path(out) / "rtstruct.dcm", contours, series, roi_name=phantom.name,
                           seed=seed)
            files["rtstruct"] = "rtstruct.dcm"
    truth["files"] = files
    write_json(out / "truth.json", truth)
    return truth
