"""A structure's contours as a voxel mask on a planning grid (the CT's, a given image's, or one on the contour planes).

The grid is planned before any reconstruction work (:func:`plan_grid`), so a
mask too large to hold is refused at once, naming its size
(:data:`MASK_VOXEL_LIMIT`). :func:`contour_mask` then fills it from the contours
themselves, as planning systems do:

- a grid plane that holds contours (within :data:`PLANE_TOL` of its spacing) is
  the even-odd fill of all of that plane's contours at the voxel centres
  (:func:`surfaces.voxelize.fill_polygons`): holes are subtracted, and several
  bodies on one plane are all kept;
- a grid plane between two contour planes (no farther apart than 1.5 contour
  spacings) is the shape-based interpolation of their fills (signed distances
  blended linearly in z, inside where the blend is positive);
- a grid plane within half a contour spacing beyond an end contour plane (or a
  gap) takes that end plane's fill: each contour stands for its slab, as in
  the planning systems' slab count.

Grids are in DICOM patient coordinates (LPS, mm); :func:`surfaces.voxelize.lps_to_ras`
turns them into the RAS affine a NIfTI file stores.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from surfaces.validate import InputError, positive
from surfaces.voxelize import VoxelGrid, fill_polygons, grid_affine, lps_to_ras

__all__ = ["MASK_VOXEL_LIMIT", "PLANE_TOL", "check_size", "contour_mask", "find_ct_series", "grid_from_ct",
           "grid_from_nifti", "grid_on_contours", "plan_grid"]

#: Largest mask written (voxels; one byte each in memory and in the file, plus a float plane at a time).
MASK_VOXEL_LIMIT = 2**28

#: A contour plane lies on a grid plane when it is within this fraction of the grid's plane spacing.
PLANE_TOL = 0.1

#: Files looked at when searching the CT series of an RT Structure Set (its folder and sub-folders).
CT_SEARCH_LIMIT = 5000


def check_size(grid: VoxelGrid, label: str = "--export-mask") -> dict:
    """Refuse a mask grid over :data:`MASK_VOXEL_LIMIT` voxels, naming its size.

    Parameters
    ----------
    grid : VoxelGrid
    label : str
        Names the option in the message.

    Returns
    -------
    dict
        ``shape``, ``n_voxels`` and ``bytes`` (uint8, uncompressed).

    Raises
    ------
    InputError
        Over the limit.
    """
    n = grid.n_voxels
    if n > MASK_VOXEL_LIMIT:
        sp = ",".join(f"{s:g}" for s in grid.spacing)
        raise InputError(f"{label}: a mask of {' x '.join(str(int(s)) for s in grid.shape)} voxels ({n:.3g} voxels, "
                         f"{_bytes(n)} as uint8) at {sp} mm is over the limit of {MASK_VOXEL_LIMIT:,} voxels "
                         f"({_bytes(MASK_VOXEL_LIMIT)}); choose a larger --mask-spacing or a reference image")
    return {"shape": [int(s) for s in grid.shape], "n_voxels": n, "bytes": n}


def _bytes(n: int) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} B"


def _triple(text, label: str, kind=float) -> tuple:
    parts = str(text).split(",") if isinstance(text, str) else list(text)
    if len(parts) != 3:
        raise InputError(f"{label}: expected three comma-separated values x,y,z, got {text!r}")
    try:
        values = tuple(kind(float(v)) if kind is int else float(v) for v in parts)
    except (TypeError, ValueError):
        raise InputError(f"{label}: expected numbers x,y,z, got {text!r}") from None
    if not all(np.isfinite(values)):
        raise InputError(f"{label}: must be finite, got {text!r}")
    if kind is int and (any(float(v) != int(float(v)) for v in parts) or min(values) < 1):
        raise InputError(f"{label}: expected positive whole numbers, got {text!r}")
    return values


def contour_spacing(planes) -> float | None:
    """The contours' plane spacing (median step, mm), None for a single plane."""
    planes = np.unique(np.round(np.asarray(planes, float), 6))
    return float(np.median(np.diff(planes))) if len(planes) > 1 else None


def grid_on_contours(contours, spacing=None, origin=None, size=None) -> VoxelGrid:
    """An axial grid whose planes fall on the contour planes (unless given otherwise).

    Parameters
    ----------
    contours : sequence of slices.io.Contour
        The structure's contours (mm).
    spacing : str or sequence of 3 float, optional
        Voxel size x, y, z (mm); default 1, 1 and the contour spacing.
    origin : str or sequence of 3 float, optional
        Centre of voxel (0, 0, 0) (mm); default one voxel beyond the contours'
        bounding box in x and y, and one plane below the first contour plane.
    size : str or sequence of 3 int, optional
        Voxels along x, y, z; default to cover the contours with one voxel to spare.

    Returns
    -------
    VoxelGrid
    """
    planes = np.unique(np.round([c.z for c in contours], 6))
    dz = contour_spacing(planes)
    if spacing is None:
        if dz is None:
            raise InputError("--export-mask: a single contour plane has no slice spacing; give --mask-spacing x,y,z")
        sp = np.array([1.0, 1.0, dz])
    else:
        sp = np.array([positive(v, "--mask-spacing") for v in _triple(spacing, "--mask-spacing")])
    pts = np.concatenate([c.points for c in contours])
    lo = np.array([*pts.min(axis=0), planes[0]])
    hi = np.array([*pts.max(axis=0), planes[-1]])
    if origin is None:
        first = np.array([np.floor(lo[0] / sp[0]) * sp[0] - sp[0], np.floor(lo[1] / sp[1]) * sp[1] - sp[1],
                          planes[0] - sp[2]])
    else:
        first = np.array(_triple(origin, "--mask-origin"))
    if size is None:
        n = np.floor((hi - first) / sp + 1e-9).astype(np.int64) + 2
        shape = tuple(int(v) for v in np.maximum(n, 1))
    else:
        shape = _triple(size, "--mask-size", int)
    return VoxelGrid(grid_affine(first, sp), shape)


def _dicom_files(folder: Path, limit: int):
    """(path, header) of the DICOM files in ``folder`` and below, at most ``limit`` files looked at
    (walked lazily, so a large parent folder is not listed whole)."""
    import os

    import pydicom

    seen = 0
    for root, dirs, files in os.walk(folder):
        dirs.sort()
        for name in sorted(files):
            seen += 1
            if seen > limit:
                return
            path = Path(root) / name
            try:
                ds = pydicom.dcmread(str(path), stop_before_pixels=True)
            except Exception:  # not DICOM: skipped, as any viewer does
                continue
            yield path, ds


def _ct_slices(folder, label: str = "--reference-image") -> list:
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{label}: no such folder or NIfTI file: {folder}")
    slices = [ds for _, ds in _dicom_files(folder, CT_SEARCH_LIMIT)
              if "ImagePositionPatient" in ds and "ImageOrientationPatient" in ds and "PixelSpacing" in ds]
    if not slices:
        raise InputError(f"{label}: {folder} holds no DICOM image slices")
    series = {str(ds.get("SeriesInstanceUID", "")) for ds in slices}
    if len(series) > 1:
        raise InputError(f"{label}: {folder} holds {len(series)} image series; give the folder of one")
    return slices


def grid_from_ct(folder, slices=None, label: str = "--reference-image") -> tuple[VoxelGrid, str]:
    """The voxel grid of a DICOM CT series (the same physical points SimpleITK and planning systems use).

    Voxel ``(i, j, k)`` is column ``i`` and row ``j`` of the ``k``-th slice along
    the slice normal, centred at ``IPP_k + i * dc * row_dir + j * dr * col_dir``
    (DICOM PS3.3 C.7.6.2.1.1).

    Parameters
    ----------
    folder : str or os.PathLike
        Folder of the series' files.
    slices : list of pydicom.Dataset, optional
        The series' headers, when already read.
    label : str
        Names the option in messages.

    Returns
    -------
    grid : VoxelGrid
        In LPS mm. A series of one slice gives a grid of one plane.
    note : str
        What was read.
    """
    slices = _ct_slices(folder, label) if slices is None else slices
    iop = np.asarray(slices[0].ImageOrientationPatient, dtype=np.float64)
    row_dir, col_dir = iop[:3], iop[3:]
    normal = np.cross(row_dir, col_dir)
    for ds in slices:
        if np.abs(np.asarray(ds.ImageOrientationPatient, float) - iop).max() > 1e-4:
            raise InputError(f"{label}: {folder}: slices have different ImageOrientationPatient")
    pos = np.array([float(np.dot(normal, np.asarray(ds.ImagePositionPatient, float))) for ds in slices])
    order = np.argsort(pos)
    slices, pos = [slices[i] for i in order], pos[order]
    dr, dc = (float(v) for v in slices[0].PixelSpacing)  # row spacing (between rows), column spacing
    if len(slices) > 1:
        steps = np.diff(pos)
        dz = float(np.median(steps))
        if dz <= 0 or np.abs(steps - dz).max() > 0.01 * dz:
            raise InputError(f"{label}: {folder}: slice positions are not evenly spaced "
                             f"(steps {np.round(steps.min(), 4)} to {np.round(steps.max(), 4)} mm)")
    else:
        dz = float(slices[0].get("SliceThickness", 0) or 0) or 1.0
    affine = np.eye(4)
    affine[:3, 0], affine[:3, 1], affine[:3, 2] = row_dir * dc, col_dir * dr, normal * dz
    affine[:3, 3] = np.asarray(slices[0].ImagePositionPatient, float)
    grid = VoxelGrid(affine, (int(slices[0].Columns), int(slices[0].Rows), len(slices)))
    return grid, f"CT series {folder} ({len(slices)} slices, {dc:g} x {dr:g} x {dz:g} mm)"




def grid_from_nifti(path) -> tuple[VoxelGrid, str]:
    """The voxel grid of a NIfTI image, in LPS mm (its RAS affine with x and y negated).

    Parameters
    ----------
    path : str or os.PathLike
        ``.nii`` or ``.nii.gz`` file.

    Returns
    -------
    grid : VoxelGrid
    note : str
    """
    import nibabel

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"--reference-image: no such folder or NIfTI file: {path}")
    try:
        img = nibabel.load(str(path))
    except Exception as exc:  # nibabel raises many kinds for damaged files
        raise InputError(f"--reference-image: {path}: not a readable NIfTI file ({type(exc).__name__}: {exc})") \
            from None
    if len(img.shape) < 3 or any(int(s) != 1 for s in img.shape[3:]):
        raise InputError(f"--reference-image: {path}: a 3-D image is needed, got shape {img.shape}")
    return VoxelGrid(lps_to_ras(img.affine), tuple(int(s) for s in img.shape[:3])), f"NIfTI image {path}"


def find_ct_series(rtstruct) -> tuple[Path, list] | None:
    """The CT series an RT Structure Set was drawn on, when it lies in its folder or below.

    A slice belongs when its SeriesInstanceUID is the structure set's referenced
    series, or (when none is referenced) its FrameOfReferenceUID is the
    structure set's.

    Parameters
    ----------
    rtstruct : str or os.PathLike
        RTSTRUCT file.

    Returns
    -------
    (folder, slices) or None
        The folder of the first slice found and the series' headers.
    """
    import pydicom

    path = Path(rtstruct)
    try:
        ds = pydicom.dcmread(str(path), stop_before_pixels=True)
    except Exception:
        return None
    frames, series = set(), set()
    for f in ds.get("ReferencedFrameOfReferenceSequence", []):
        frames.add(str(f.get("FrameOfReferenceUID", "")))
        for st in f.get("RTReferencedStudySequence", []):
            for s in st.get("RTReferencedSeriesSequence", []):
                series.add(str(s.get("SeriesInstanceUID", "")))
    found = []
    for p, d in _dicom_files(path.parent, CT_SEARCH_LIMIT):
        if str(d.get("Modality", "")) != "CT" or "ImagePositionPatient" not in d:
            continue
        if (series and str(d.get("SeriesInstanceUID", "")) in series) or \
                (not series and str(d.get("FrameOfReferenceUID", "")) in frames):
            found.append((p, d))
    if not found:
        return None
    return found[0][0].parent, [d for _, d in found]


def plan_grid(contours, *, input_path=None, reference_image=None, spacing=None, origin=None,
              size=None) -> tuple[VoxelGrid, str, dict]:
    """The mask's grid, chosen before any reconstruction and checked against :data:`MASK_VOXEL_LIMIT`.

    Parameters
    ----------
    contours : sequence of slices.io.Contour
    input_path : str or os.PathLike, optional
        The input: a CT series folder or a NIfTI image gives its own grid, an RT
        Structure Set's CT series found beside it gives the default grid.
    reference_image : str or os.PathLike, optional
        A CT series folder or a NIfTI image whose grid the mask takes.
    spacing, origin, size : optional
        An explicit grid (:func:`grid_on_contours`); not with ``reference_image``.

    Returns
    -------
    grid : VoxelGrid
        Axial, in LPS mm.
    source : str
        ``"reference_image"``, ``"input_image"``, ``"ct_series"``, ``"explicit"`` or ``"contour_planes"``.
    info : dict
        ``grid`` (in words), ``shape``, ``n_voxels``, ``bytes``.
    """
    explicit = spacing is not None or origin is not None or size is not None
    if reference_image is not None:
        if explicit:
            raise InputError("--reference-image and --mask-spacing/--mask-origin/--mask-size: give one grid")
        ref = Path(reference_image)
        name = ref.name.lower()
        if name.endswith(".nii") or name.endswith(".nii.gz"):
            grid, note = grid_from_nifti(ref)
        else:
            grid, note = grid_from_ct(ref)
        source = "reference_image"
    elif explicit:
        grid, source = grid_on_contours(contours, spacing, origin, size), "explicit"
        note = "explicit grid"
    elif input_path is not None and _is_nifti_name(input_path):  # a NIfTI input: its own grid
        grid, note = grid_from_nifti(input_path)
        source, note = "input_image", note.replace("NIfTI image", "the input NIfTI image")
    elif input_path is not None and Path(input_path).is_dir() and not any(
            p.suffix.lower() == ".png" for p in Path(input_path).iterdir()):  # a CT series input: its own grid
        grid, note = grid_from_ct(input_path, label="--export-mask (the input CT series' grid)")
        source = "input_image"
    else:
        found = None
        if input_path is not None and Path(input_path).is_file():
            found = find_ct_series(input_path)
        if found is not None:
            grid, note = grid_from_ct(found[0], found[1])
            source = "ct_series"
            if grid.shape[2] == 1:  # one slice: its pixels, the contours' planes
                planes = grid_on_contours(contours, (1.0, 1.0, contour_spacing([c.z for c in contours]) or 1.0))
                affine = grid.affine.copy()
                affine[:3, 2] = [0.0, 0.0, planes.affine[2, 2]]
                affine[2, 3] = planes.affine[2, 3]
                grid = VoxelGrid(affine, (grid.shape[0], grid.shape[1], planes.shape[2]))
                note += "; one slice only: its pixel grid on the contour planes"
        else:
            grid, source, note = grid_on_contours(contours), "contour_planes", "planes on the contour planes"
    grid.check_axial("--export-mask grid")
    info = check_size(grid)
    info["grid"] = note
    return grid, source, info


def _is_nifti_name(path) -> bool:
    name = Path(path).name.lower()
    return name.endswith(".nii") or name.endswith(".nii.gz")


def _signed_distance(fill: np.ndarray, sampling) -> np.ndarray:
    """Signed distance (mm, > 0 inside) of a 2-D fill, half a pixel at the boundary."""
    from scipy.ndimage import distance_transform_edt

    if not fill.any():
        return np.full(fill.shape, -1e9)
    inside = distance_transform_edt(fill, sampling=sampling)
    outside = distance_transform_edt(~fill, sampling=sampling)
    return np.where(fill, inside - 0.5 * min(sampling), 0.5 * min(sampling) - outside)


def contour_mask(contours, grid: VoxelGrid) -> tuple[np.ndarray, dict]:
    """Rasterise a structure's contours onto an axial grid (see the module text for the rule).

    Parameters
    ----------
    contours : sequence of slices.io.Contour
        All contours of the structure (several bodies and holes per plane allowed).
    grid : VoxelGrid
        Axial grid in the contours' frame (mm), e.g. from :func:`plan_grid`.

    Returns
    -------
    mask : numpy.ndarray, shape grid.shape, uint8
        1 inside.
    info : dict
        ``n_planes_on_contours`` (grid planes filled from a contour plane),
        ``n_planes_interpolated``, ``n_planes_end_slab`` and ``rule`` (in words).
    """
    grid.check_axial("--export-mask grid")
    check_size(grid)
    planes = np.unique(np.round([c.z for c in contours], 6))
    dz_c = contour_spacing(planes)
    inv = np.linalg.inv(grid.affine)
    shape2 = (int(grid.shape[0]), int(grid.shape[1]))
    by_plane: dict[float, list] = {}
    for c in contours:
        by_plane.setdefault(float(np.round(c.z, 6)), []).append(c.points)

    fills: dict[float, np.ndarray] = {}

    def fill_of(z: float) -> np.ndarray:
        if z not in fills:
            rings = []
            for pts in by_plane[z]:
                idx = np.column_stack([pts, np.full(len(pts), z), np.ones(len(pts))]) @ inv[:2].T
                rings.append(idx)
            fills[z] = fill_polygons(rings, shape2)
        return fills[z]

    gz = grid.planes
    step = abs(float(grid.affine[2, 2]))
    sampling = grid.spacing[:2]
    mask = np.zeros(tuple(int(s) for s in grid.shape), dtype=np.uint8)
    counts = {"n_planes_on_contours": 0, "n_planes_interpolated": 0, "n_planes_end_slab": 0}
    half = 0.5 * (dz_c if dz_c is not None else step)
    for k, z in enumerate(gz):
        d = np.abs(planes - z)
        near = int(np.argmin(d))
        if d[near] <= PLANE_TOL * step + 1e-6:
            mask[:, :, k] = fill_of(float(planes[near]))
            counts["n_planes_on_contours"] += 1
            continue
        below = planes[planes < z]
        above = planes[planes > z]
        za = float(below[-1]) if len(below) else None
        zb = float(above[0]) if len(above) else None
        if za is not None and zb is not None and dz_c is not None and zb - za <= 1.5 * dz_c + 1e-6:
            t = (z - za) / (zb - za)
            blend = (1 - t) * _signed_distance(fill_of(za), sampling) + t * _signed_distance(fill_of(zb), sampling)
            mask[:, :, k] = blend > 0
            counts["n_planes_interpolated"] += 1
            continue
        # beyond an end plane (or across a gap): the nearest plane's slab, half a contour spacing deep
        if d[near] < half - 1e-6:
            mask[:, :, k] = fill_of(float(planes[near]))
            counts["n_planes_end_slab"] += 1
    counts["rule"] = ("even-odd fill of the contours at the voxel centres on planes that hold contours; between "
                      "contour planes shape-based interpolation (signed distances blended in z); within half a "
                      "contour spacing beyond an end plane that plane's fill")
    return mask, counts
