"""A contour input into a result folder: :func:`slices.pipeline.reconstruct`, then its files.

:func:`reconstruct_to_folder` is what ``workbench slices reconstruct``, batch
jobs and the demo call. It takes the options as users type them (the command
line's and the batch manifests' names: ``rays``, ``lattice``, ``ray_start`` in
degrees), converts them once into the library's
(:class:`slices.options.SurfaceOptions`: ``n_rays``, ``lattice_factor``,
``start_angle`` in radians) and writes, in a folder built beside ``out_dir`` and
swapped in whole (:func:`workbench.runs.folder.result_folder`):

``surface.ply``, ``surface.stl`` (the solid), ``patches.npz`` (every body's
control points), ``render.png`` (ray-cast views, unless ``render=False``) and
``summary.json`` (the returned dict).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from slices.pipeline import SlicesReconstruction, reconstruct
from surfaces.io import atomic_path, jsonable, write_json, write_mesh, write_png
from surfaces.validate import InputError
from workbench.runs.folder import result_folder

#: The options :func:`reconstruct_to_folder` accepts (command-line and manifest names).
OPTIONS = frozenset({
    "method", "rays", "caps", "hu_min", "hu_max", "spacing", "resample", "lattice", "samples", "correspondence",
    "ray_start", "union", "minus", "plus", "repair", "render", "reference", "export_mask", "mask_spacing",
    "reference_image", "mask_origin", "mask_size", "slice_thickness", "surface_path",
})

#: Files written into the output folder (``render.png`` only when rendering).
FILES = ("surface.ply", "surface.stl", "patches.npz", "render.png", "summary.json")

#: Views of ``render.png``.
RENDER_VIEWS = ("iso", "front", "top", "side")


def start_angle(value) -> float | None:
    """The ``ray_start`` option (degrees from +x, or "auto"/None) in radians.

    Parameters
    ----------
    value : float, str or None
        Degrees, or ``"auto"``/None for each body's own rotation.

    Returns
    -------
    float or None
        Radians, or None for "auto".

    Examples
    --------
    >>> start_angle("auto") is None, round(start_angle("90"), 6)
    (True, 1.570796)
    """
    if value is None or (isinstance(value, str) and value.strip().lower() == "auto"):
        return None
    try:
        deg = float(value)
    except (TypeError, ValueError):
        raise InputError(f"ray_start: must be an angle in degrees or 'auto', got {value!r}") from None
    if not np.isfinite(deg):
        raise InputError(f"ray_start: must be finite, got {value!r}")
    return float(np.radians(deg))


def library_options(options: dict) -> dict:
    """Options as users name them -> keywords of :func:`slices.pipeline.reconstruct`.

    Parameters
    ----------
    options : dict
        Names of :data:`OPTIONS` except ``render``.

    Returns
    -------
    dict
        ``rays`` as ``n_rays``, ``lattice`` as ``lattice_factor``, ``ray_start``
        (degrees) as ``start_angle`` (radians); the others unchanged.
    """
    out = dict(options)
    if "rays" in out:
        out["n_rays"] = int(out.pop("rays"))
    if "lattice" in out:
        out["lattice_factor"] = float(out.pop("lattice"))
    if "ray_start" in out:
        out["start_angle"] = start_angle(out.pop("ray_start"))
    return out


def save_body_patches(result: SlicesReconstruction, path) -> None:
    """All bodies' patches in one ``.npz``.

    Parameters
    ----------
    result : SlicesReconstruction
    path : str or os.PathLike
        Destination; holds ``body<i>_control`` per body, ``control`` (the
        largest body's; an empty (0, 0, 4, 4, 3) grid for an implicit surface), ``closed_u`` (True),
        ``closed_v`` (False), ``body_kind`` ("outer"/"hole" per body) and ``surface_path``.
    """
    bodies = result.reconstruction.bodies
    arrays = {f"body{i}_control": b.patches.control for i, b in enumerate(bodies)}
    # an implicit surface has no patches (surface_path "implicit"): an empty grid
    arrays["control"] = (max(bodies, key=lambda b: b.patches.n_patches).patches.control if bodies
                         else np.zeros((0, 0, 4, 4, 3)))
    arrays["surface_path"] = np.array(result.reconstruction.surface_path)
    arrays["closed_u"] = np.array(True)
    arrays["closed_v"] = np.array(False)
    arrays["body_kind"] = np.array([b.body.kind for b in bodies])
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)


def export_mask(result: SlicesReconstruction, path, spacing=None, *, grid=None, grid_info=None) -> dict:
    """Write the structure as a NIfTI mask on a planning grid (nibabel), its affine in RAS.

    The mask is the structure's contours rasterised on the grid
    (:func:`slices.mask.contour_mask`: even-odd fill on the planes that hold
    contours, shape-based interpolation between them, half a slab beyond the end
    planes); with ``--minus``/``--plus`` it is the composed solid's voxels (ray
    parity, :func:`surfaces.voxelize.grid_occupancy`). The grid is in DICOM patient
    coordinates (LPS); the file's affine is RAS (x and y negated), as every NIfTI
    reader expects, so the mask overlays its CT.

    Parameters
    ----------
    result : SlicesReconstruction
    path : str or os.PathLike
        ``.nii`` or ``.nii.gz`` file.
    spacing : str or sequence of float, optional
        Voxel size ``x,y,z`` in mm when ``grid`` is not given (a grid on the
        contour planes, :func:`slices.mask.grid_on_contours`).
    grid : surfaces.voxelize.VoxelGrid, optional
        The grid, planned before the reconstruction (:func:`slices.mask.plan_grid`).
    grid_info : dict, optional
        What :func:`slices.mask.plan_grid` said about it (``grid``, ``source``).

    Returns
    -------
    dict
        ``path``, ``shape``, ``spacing_mm``, ``n_voxels`` (inside), ``bytes``,
        ``voxel_volume_mm3`` (voxels x voxel volume, the slab convention;
        ``volume_mm3`` stays the surface's volume), ``grid`` (how it was chosen),
        ``grid_source``, ``affine_ras``, ``orientation`` (nibabel's axis codes) and ``rule``.
    """
    import nibabel

    from slices.io import write_nifti_mask
    from slices.mask import contour_mask, grid_on_contours
    from surfaces.voxelize import grid_occupancy

    path = Path(path)
    if not (path.name.endswith(".nii") or path.name.endswith(".nii.gz")):
        raise InputError(f"--export-mask: must end in .nii or .nii.gz, got {str(path)!r}")
    info = dict(grid_info or {})
    if grid is None:
        grid = grid_on_contours(result.stack.contours, spacing)
        info.setdefault("grid", "planes on the contour planes" if spacing is None else "explicit grid")
        info.setdefault("source", "contour_planes" if spacing is None else "explicit")
    if result.composition is not None:
        mask = grid_occupancy(result.mesh, grid)
        rule = "the composed solid's voxels (ray parity of the written mesh at the voxel centres)"
    else:
        mask, counts = contour_mask(result.stack.contours, grid)
        rule = counts.pop("rule")
        info.update(counts)
    affine = write_nifti_mask(path, mask, grid.affine)
    n = int(mask.sum())
    sp = [float(v) for v in grid.spacing]
    out = {"path": str(path), "shape": list(mask.shape), "spacing_mm": sp, "n_voxels": n,
           "bytes": int(mask.size), "voxel_volume_mm3": n * float(np.prod(sp)),
           "voxel_volume_convention": "each voxel a whole box; on the contour planes this is the planning "
                                      "systems' slab count, end planes with whole slabs",
           "grid": info.pop("grid", ""), "grid_source": info.pop("source", ""),
           "affine_ras": affine.tolist(), "orientation": "".join(nibabel.aff2axcodes(affine)), "rule": rule}
    out.update({k: v for k, v in info.items() if k not in ("shape", "n_voxels", "bytes")})
    return out


def plan_mask_grid(input_path, roi, options: dict, spacing=None, *, reference_image=None, mask_origin=None,
                   mask_size=None):
    """The ``--export-mask`` grid, planned and size-checked before any reconstruction (:func:`slices.mask.plan_grid`).

    Parameters
    ----------
    input_path : str or os.PathLike
    roi : str or int or None
    options : dict
        The reading options (``hu_min``, ``hu_max``, ``spacing``, ``resample``) as users give them.
    spacing, mask_origin, mask_size : optional
        An explicit grid (x,y,z mm; x,y,z mm of voxel (0, 0, 0); voxels along x,y,z).
    reference_image : str or os.PathLike, optional
        CT series folder or NIfTI image whose grid the mask takes.

    Returns
    -------
    grid : surfaces.voxelize.VoxelGrid
    info : dict
        ``grid`` (in words), ``source``, ``shape``, ``n_voxels``, ``bytes``.
    """
    from slices.io import load
    from slices.mask import plan_grid

    contours = None
    if reference_image is None:  # a grid from the contours needs them (read only, nothing reconstructed)
        contours = load(input_path, roi, options.get("hu_min"), options.get("hu_max"), options.get("spacing"),
                        bool(options.get("resample", False))).contours
    grid, source, info = plan_grid(contours, input_path=input_path, reference_image=reference_image,
                                   spacing=spacing, origin=mask_origin, size=mask_size)
    info["source"] = source
    return grid, info


def planning_summary(result: SlicesReconstruction) -> dict:
    """The planning systems' volume beside ours, for ``summary.json`` (``planning_volume_mm3``).

    Parameters
    ----------
    result : SlicesReconstruction

    Returns
    -------
    dict
        ``slab_full_ends`` and ``slab_half_ends`` (mm^3, :func:`slices.chaining.planning_volumes`:
        every contour a slab of one spacing, the end slabs whole or half), ``ours_mm3``
        (the summary's ``volume_mm3``, with the caps asked for), ``ours_over_full_ends``,
        ``n_planes``, ``small_structure`` and ``rule`` (the counting rule in words).
    """
    from slices.chaining import planning_volumes

    rec = result.reconstruction
    out = planning_volumes(result.stack.contours, rec.spacing)
    full = out["slab_full_ends"]
    ours = result.summary.get("volume_mm3", rec.volume_mm3)  # the summary's: whole structure with caps trend
    out.update({
        "ours_mm3": ours,
        "ours_over_full_ends": ours / full if full else None,
        "rule": f"every contour a slab of one slice spacing ({rec.spacing:g} mm), holes subtracted; "
                "slab_full_ends keeps the end contours' whole slabs, slab_half_ends half of them",
    })
    return out


def write_result(result: SlicesReconstruction, out_dir, *, render: bool = True) -> dict:
    """Write a reconstruction's files into ``out_dir`` and return the content of ``summary.json``.

    Parameters
    ----------
    result : SlicesReconstruction
        What :func:`slices.pipeline.reconstruct` returned.
    out_dir : str or os.PathLike
        Output folder (created when missing).
    render : bool
        Write ``render.png`` (ray-cast views of :attr:`SlicesReconstruction.display_mesh`).

    Returns
    -------
    dict
        The library's summary with ``write_time_s``, ``render_time_s`` and the
        total ``time_s`` (s).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t_write = time.perf_counter()
    write_mesh(result.mesh, out / "surface.ply")
    write_mesh(result.mesh, out / "surface.stl")
    save_body_patches(result, out / "patches.npz")
    t_write = time.perf_counter() - t_write
    t_render = time.perf_counter()
    if render:
        from surfaces.render import render as render_views  # loaded only when a picture is drawn

        write_png(out / "render.png",
                  render_views(result.display_mesh, views=RENDER_VIEWS, size=(1024, 768), colorbar=False))
    t_render = time.perf_counter() - t_render
    summary = {}
    for key, value in result.summary.items():
        if key != "time_s":
            summary[key] = value
        # each stage's time beside the library's, in the order they run on the command line
        if key == "union_time_s":
            summary["write_time_s"] = t_write
        elif key == "reference_time_s":
            summary["render_time_s"] = t_render
    summary["time_s"] = result.summary["time_s"] + t_write + t_render
    summary = jsonable(summary)
    write_json(out / "summary.json", summary)
    return summary


def reconstruct_to_folder(input_path, out_dir, *, roi=None, progress=None, atomic: bool = True, **options) -> dict:
    """Reconstruct a contour input and write every output file.

    Parameters
    ----------
    input_path : str or os.PathLike
        RTSTRUCT, CT folder, mask stack or contour JSON (see :func:`slices.io.load`).
    out_dir : str or os.PathLike
        Output folder: replaced whole by the new result (it must be missing, empty,
        or hold only a previous result's files).
    roi : str or int, optional
        ROI name or number for RTSTRUCT input.
    progress : callable, optional
        Called with finished and total bodies.
    atomic : bool
        Build the folder beside ``out_dir`` and swap it in (default). ``False``
        writes straight into ``out_dir``, for callers that already write into a
        temporary folder of their own (batch jobs).
    **options
        As on the command line and in batch manifests: ``method``, ``rays``
        (rays per contour, seed 000 eq. 1), ``caps``, ``hu_min``, ``hu_max``,
        ``spacing`` (z,y,x for mask stacks), ``resample``, ``lattice``
        (lattice values per point of the largest contour), ``samples``,
        ``correspondence``, ``ray_start`` (direction of ray 0 in degrees from
        +x for every body, or "auto" (default): per body the rotation that keeps
        support points steadiest), ``union``, ``minus``, ``plus``, ``repair``,
        ``reference`` (see :func:`slices.pipeline.reconstruct`), ``render``
        (default True), ``export_mask`` (a ``.nii``/``.nii.gz`` path: the structure
        as a mask on a planning grid, :func:`export_mask`), its grid: ``reference_image``
        (a CT series folder or NIfTI image), or ``mask_spacing`` (voxel size x,y,z mm),
        ``mask_origin`` (x,y,z mm of voxel 0) and ``mask_size`` (voxels x,y,z); by default
        the CT series found beside an RT Structure Set, else planes on the contour planes.
        The grid's size is checked before any work (:data:`slices.mask.MASK_VOXEL_LIMIT`).
        ``slice_thickness`` (mm: the slab of a single plane), ``surface_path`` (auto, coons
        or implicit, :class:`slices.options.SurfaceOptions`).
        Defaults are those of :class:`slices.options.SurfaceOptions`
        and :func:`slices.pipeline.reconstruct`.

    Returns
    -------
    dict
        The content of ``summary.json`` (``ray_start`` as given, "auto" when not;
        ``planning_volume_mm3``: :func:`planning_summary`).
    """
    unknown = set(options) - OPTIONS
    if unknown:
        raise InputError(f"options: unknown {sorted(unknown)}")
    render = bool(options.pop("render", True))
    mask_path, mask_spacing = options.pop("export_mask", None), options.pop("mask_spacing", None)
    mask_grid = {k: options.pop(k, None) for k in ("reference_image", "mask_origin", "mask_size")}
    if mask_path is not None and not (str(mask_path).endswith(".nii") or str(mask_path).endswith(".nii.gz")):
        raise InputError(f"--export-mask: must end in .nii or .nii.gz, got {str(mask_path)!r}")
    if mask_path is None and (mask_spacing is not None or any(v is not None for v in mask_grid.values())):
        raise InputError("--mask-spacing/--mask-origin/--mask-size/--reference-image: only with --export-mask")
    grid, grid_info = None, None
    if mask_path is not None:  # the grid and its size before any reconstruction work
        grid, grid_info = plan_mask_grid(input_path, roi, options, mask_spacing, **mask_grid)

    def run():
        result = reconstruct(input_path, roi=roi, progress=progress, **library_options(options))
        result.summary["ray_start"] = options.get("ray_start") or "auto"
        plan = result.summary["planning_volume_mm3"] = planning_summary(result)
        if plan["small_structure"]:
            result.summary["notes"].append(
                f"small structure ({plan['n_planes']} plane(s)): planning systems count "
                f"{plan['slab_full_ends'] / 1000:.3f} ml (whole end slabs) or {plan['slab_half_ends'] / 1000:.3f} ml "
                f"(half end slabs); ours is {plan['ours_mm3'] / 1000:.3f} ml, {result.summary['volume_caps']} "
                "(planning_volume_mm3)")
        if mask_path is not None:
            result.summary["export_mask"] = export_mask(result, mask_path, grid=grid, grid_info=grid_info)
        return result

    if not atomic:
        return write_result(run(), out_dir, render=render)
    # the folder is checked and locked before the work, so a bad --out or a second writer is refused at once
    with result_folder(out_dir, owned=FILES) as tmp:
        return write_result(run(), tmp, render=render)
