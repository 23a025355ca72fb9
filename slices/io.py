"""Reading contour stacks: RT structure sets, CT series, mask stacks, NIfTI label volumes, contour JSON.

Everything ends in a :class:`ContourStack`: planar closed contours in mm with
the slice position ``z`` along the slice normal. Contours are validated here
(at least 3 distinct points, no self-intersection, planar and axial), so the
rest of the package can trust them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slices.polygons import clean_contour, repair_contour, signed_area
from surfaces.validate import as_array, InputError, positive, reads_file

#: Relative tolerance on slice spacing (a fraction of the spacing).
SPACING_RTOL = 0.01


@dataclass(frozen=True)
class Contour:
    """One closed planar contour.

    Attributes
    ----------
    z : float
        Slice position in mm.
    points : numpy.ndarray, shape (n, 2)
        Counter-clockwise x, y vertices in mm (seen from +z), ``n >= 3``.
    """

    z: float
    points: np.ndarray


@dataclass
class ContourStack:
    """The planar contours of one structure.

    Attributes
    ----------
    contours : list of Contour
        In increasing ``z``.
    source : str
        Kind of input (``"rtstruct"``, ``"ct"``, ``"mask"``, ``"nifti"``, ``"json"``).
    name : str
        ROI or file name.
    notes : list of str
        What the reader did (resampling, segmentation, ...), for the summary.
    repairs : list of dict
        Contours repaired into simple polygons (:func:`slices.polygons.repair_contour`): ``contour``
        (index in the input), ``z_mm``, ``area_before_mm2``, ``area_after_mm2``, ``area_change_pct``,
        ``parts`` and ``holes``.
    frame : numpy.ndarray, shape (3, 3), or None
        Contours on oblique planes: the rows ``u, v, n`` of their plane frame (patient
        coordinates); the contours' ``x, y, z`` are ``u . p, v . p, n . p`` of the patient
        points ``p``, and a point ``q`` of the reconstruction lies at ``q @ frame``. None: axial.
    thickness_mm : float or None
        Slab thickness the input states for its planes (RTSTRUCT ``ContourSlabThickness``), or None.
    thickness_source : str
        Where :attr:`thickness_mm` comes from.
    """

    contours: list[Contour]
    source: str
    name: str
    notes: list[str] = field(default_factory=list)
    repairs: list[dict] = field(default_factory=list)
    frame: np.ndarray | None = None
    thickness_mm: float | None = None
    thickness_source: str = ""

    @property
    def planes(self) -> np.ndarray:
        """Sorted distinct slice positions in mm, shape (P,)."""
        return np.unique(np.round([c.z for c in self.contours], 6))


#: Vertices closer than this fraction of a contour's extent are one point (a keyhole's zero-width cut).
KEYHOLE_RTOL = 1e-6


def open_keyholes(points) -> list[np.ndarray]:
    """Split a contour at the points it passes twice (keyholes) into simple loops.

    A keyhole contour reaches a hole through a zero-width cut: it runs in along
    the cut, round the hole and back along the cut, so the cut's vertices come
    twice. Cutting the vertex sequence at every such pair (``p[i] == p[j]``,
    not neighbours) gives the loops ``p[i:j]`` and ``p[j:] + p[:i]``, repeated
    until no point comes twice; the cut itself leaves loops of zero area,
    which are dropped. A contour touching itself at one point (two islands
    joined at a corner) opens into its two islands.

    Parameters
    ----------
    points : array_like, shape (n, 2)
        Vertices in mm, in order (a repeated closing vertex is allowed).

    Returns
    -------
    list of numpy.ndarray, each shape (m, 2)
        The loops, largest area first; the contour itself (as given) when no
        vertex comes twice. Orientations as traversed (a hole runs the other way round).

    Examples
    --------
    A 4 mm square with a 2 mm square hole reached along y = 2 from the right:

    >>> keyhole = [[0, 0], [4, 0], [4, 2], [3, 2], [3, 1], [1, 1], [1, 3], [3, 3], [3, 2], [4, 2], [4, 4], [0, 4]]
    >>> [signed_area(loop) for loop in open_keyholes(keyhole)]
    [16.0, -4.0]
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or len(p) < 4:
        return [p]
    tol = KEYHOLE_RTOL * max(float(np.ptp(p, axis=0).max()), 1e-300)

    def dedup(q: np.ndarray) -> np.ndarray:
        keep = np.linalg.norm(q - np.roll(q, 1, axis=0), axis=1) > tol
        return q[keep] if np.any(keep) else q[:1]

    todo, loops, opened = [dedup(p)], [], False
    while todo:
        q = todo.pop()
        pair = _first_close_pair(q, tol) if len(q) > 3 else None
        if pair is None:
            loops.append(q)
            continue
        opened = True
        i, j = pair
        todo += [dedup(q[i:j]), dedup(np.concatenate([q[j:], q[:i]]))]
    if not opened:
        return [p]
    area = np.array([abs(signed_area(q)) if len(q) >= 3 else 0.0 for q in loops])
    order = np.argsort(-area, kind="stable")
    return [loops[k] for k in order if area[k] > 1e-9 * max(float(area.max()), 1e-300)]


def _first_close_pair(q: np.ndarray, tol: float) -> tuple[int, int] | None:
    """The pair ``i < j`` of points of ``q`` (n, 2) at most ``tol`` apart with the smallest ``(i, j)``, or None.

    Points are hashed into square cells of side ``tol``; two points that close lie in
    the same or neighbouring cells, and only those are compared (cells this small
    hold one point each, bar the repeated ones), so the search stays linear after
    one sort, however many points share an x or a y, and needs no k-d tree, whose
    import costs more than the search.
    """
    cell = np.floor((q - q.min(axis=0)) / tol).astype(np.int64)
    width = int(cell[:, 1].max()) + 3
    key = cell[:, 0] * width + cell[:, 1] + 1
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    found = []
    # each pair of neighbouring cells once: the same cell, and the cells above and to the right
    for dx, dy in ((0, 0), (0, 1), (1, -1), (1, 0), (1, 1)):
        target = key + dx * width + dy
        lo = np.searchsorted(sorted_key, target, side="left")
        count = np.searchsorted(sorted_key, target, side="right") - lo
        first = np.repeat(np.arange(len(q)), count)
        other = order[np.repeat(lo, count) + np.arange(len(first)) - np.repeat(np.cumsum(count) - count, count)]
        keep = other != first if (dx, dy) == (0, 0) else np.ones(len(first), dtype=bool)
        found.append(np.stack([first[keep], other[keep]], axis=1))
    pairs = np.concatenate(found)
    pairs = pairs[np.linalg.norm(q[pairs[:, 0]] - q[pairs[:, 1]], axis=1) <= tol]
    if not len(pairs):
        return None
    lo, hi = pairs.min(axis=1), pairs.max(axis=1)
    k = np.lexsort((hi, lo))[0]
    return int(lo[k]), int(hi[k])


#: Contour planes closer than this (mm) are one plane: a plane written twice with a rounding difference.
PLANE_MERGE_MM = 0.01

#: Two contours of one plane whose symmetric difference is below this fraction of their area are one
#: contour written twice (an even-odd fill would cancel them out).
DUPLICATE_RTOL = 1e-3


def _degenerate(p: np.ndarray) -> str:
    """Why a contour (n, 2) encloses nothing (fewer than 3 distinct points, zero area), or ``""``."""
    if len(p) >= 2:
        keep = np.any(p != np.roll(p, 1, axis=0), axis=1)
        p = p[keep] if np.any(keep) else p[:1]
    if len(np.unique(p, axis=0)) < 3:
        return f"{len(np.unique(p, axis=0))} distinct point(s)"
    extent = float(np.ptp(p, axis=0).max())
    d, e = p[1:] - p[0], p[-1] - p[0]
    if extent == 0 or np.all(np.abs(d[:, 0] * e[1] - d[:, 1] * e[0]) <= 1e-12 * extent**2):
        return "zero area"
    return ""


def _contours_from_list(items, label: str, notes: list | None = None,
                        repairs: list | None = None) -> list[Contour]:
    """Validated contours from ``(z, points)`` or ``(z, points, index)`` items.

    Keyholes are opened (:func:`open_keyholes`); contours that enclose nothing (fewer than 3
    distinct points, zero area) are skipped; pinched and self-crossing outlines are repaired
    into simple polygons (:func:`slices.polygons.repair_contour`, each in ``repairs``); planes
    closer than :data:`PLANE_MERGE_MM` are merged and duplicated contours of one plane dropped
    (:func:`drop_duplicates`). Each is said in ``notes``.
    """
    out = []
    keyholes = 0
    skipped = []
    repaired = [] if repairs is None else repairs
    for i, item in enumerate(items):
        z, pts = item[0], item[1]
        index = item[2] if len(item) > 2 else i
        name = f"{label} contour {index} at z={z:.2f} mm"
        p = as_array(pts, name, ndim=2)
        why = _degenerate(p) if p.shape[1:] == (2,) else ""
        if why:
            skipped.append(f"{index} at z={z:.2f} mm ({why})")
            continue
        loops = open_keyholes(p)
        keyholes += len(loops) > 1
        for q in loops:
            try:
                out.append(Contour(float(z), clean_contour(q, name)))
                continue
            except InputError as exc:
                if "self-intersecting" not in str(exc):
                    raise
            rings, parts, before, after = repair_contour(q)
            out += [Contour(float(z), clean_contour(r, f"{name} (repaired)")) for r in rings]
            repaired.append({"contour": int(index), "z_mm": float(z), "area_before_mm2": before,
                             "area_after_mm2": after, "area_change_pct": 100.0 * (after - before) / max(before, 1e-300)
                             if before > 0 else None, "parts": parts, "holes": len(rings) - parts})
    out.sort(key=lambda c: c.z)
    if notes is None:
        notes = []
    if keyholes:
        notes.append(f"{keyholes} keyhole contour(s) (a hole reached by a zero-width cut) opened into "
                     "separate outer and inner contours")
    if skipped:
        notes.append(f"skipped {len(skipped)} contour(s) that enclose nothing: " + "; ".join(skipped[:10])
                     + ("; ..." if len(skipped) > 10 else ""))
    if repaired:
        worst = max((abs(r["area_change_pct"]) for r in repaired if r["area_change_pct"] is not None), default=0.0)
        notes.append(f"repaired {len(repaired)} pinched or self-crossing contour(s) into simple polygons "
                     f"(shapely make_valid; largest area change {worst:.3g} %): "
                     + ", ".join(f"{r['contour']} at z={r['z_mm']:.2f} mm" for r in repaired[:10])
                     + (", ..." if len(repaired) > 10 else ""))
    return drop_duplicates(merge_planes(out, notes), notes)


def merge_planes(contours: list[Contour], notes: list | None = None) -> list[Contour]:
    """Contours whose planes lie within :data:`PLANE_MERGE_MM` of each other moved onto one plane.

    Parameters
    ----------
    contours : list of Contour
        Sorted by ``z``.
    notes : list of str, optional
        Gets a note when planes were merged.

    Returns
    -------
    list of Contour
        The same contours, those of a merged plane at its lowest ``z``.
    """
    if len(contours) < 2:
        return contours
    z = np.array([c.z for c in contours])
    gaps = np.diff(z)
    close = (gaps > 1e-6) & (gaps < PLANE_MERGE_MM)
    if not close.any():
        return contours
    # each contour takes the z of the first plane of its run of close planes
    start = np.r_[True, gaps >= PLANE_MERGE_MM]
    base = z[np.maximum.accumulate(np.where(start, np.arange(len(z)), 0))]
    if notes is not None:
        pairs = ", ".join(f"z={a:.4f}/{b:.4f} mm" for a, b in zip(z[:-1][close][:5], z[1:][close][:5]))
        notes.append(f"merged {int(close.sum())} plane(s) within {PLANE_MERGE_MM:g} mm of another ({pairs}): "
                     "one plane written twice")
    return [c if c.z == b else Contour(float(b), c.points) for c, b in zip(contours, base)]


def drop_duplicates(contours: list[Contour], notes: list | None = None) -> list[Contour]:
    """The contours without the duplicates of one plane (identical, or nearly: see :data:`DUPLICATE_RTOL`).

    A contour given twice would cancel itself in an even-odd fill (a planning system's or a
    rasteriser's) and make a zero-thickness body here; the later copy is dropped.

    Parameters
    ----------
    contours : list of Contour
        Sorted by ``z``.
    notes : list of str, optional
        Gets a note naming the dropped copies.

    Returns
    -------
    list of Contour
    """
    if len(contours) < 2:
        return contours
    z = np.round([c.z for c in contours], 6)
    area = np.array([signed_area(c.points) for c in contours])
    lo = np.array([c.points.min(axis=0) for c in contours])
    hi = np.array([c.points.max(axis=0) for c in contours])
    drop, said = set(), []
    for plane in np.flatnonzero(np.r_[True, z[1:] != z[:-1]]):
        members = np.flatnonzero(z == z[plane])
        if len(members) < 2:
            continue
        for a_i, a in enumerate(members):
            for b in members[a_i + 1:]:
                if a in drop or b in drop:
                    continue
                size = max(abs(area[a]), abs(area[b]))
                extent = float(max(np.ptp(contours[a].points, axis=0).max(), 1e-9))
                if (abs(area[a] - area[b]) > DUPLICATE_RTOL * size
                        or np.abs(lo[a] - lo[b]).max() > DUPLICATE_RTOL * extent
                        or np.abs(hi[a] - hi[b]).max() > DUPLICATE_RTOL * extent):
                    continue
                if _difference_area(contours[a].points, contours[b].points) <= DUPLICATE_RTOL * size:
                    drop.add(int(b))
                    said.append(f"z={z[b]:.2f} mm")
    if not drop:
        return contours
    if notes is not None:
        notes.append(f"dropped {len(drop)} duplicated contour(s) (the same outline twice on one plane, within "
                     f"{100 * DUPLICATE_RTOL:g} % of its area; a fill would cancel them): " + ", ".join(said[:10])
                     + (", ..." if len(said) > 10 else ""))
    return [c for k, c in enumerate(contours) if k not in drop]


def _difference_area(a: np.ndarray, b: np.ndarray) -> float:
    """Area (mm^2) of the symmetric difference of two simple polygons (shapely)."""
    from shapely.geometry import Polygon

    return float(Polygon(a).symmetric_difference(Polygon(b)).area)


def _existing(path, what: str, kind: str = "file") -> Path:
    """``path`` as a Path, checked to be an existing ``"file"``, ``"folder"`` or either (``"any"``)."""
    path = Path(path)
    if kind == "folder":
        if not path.is_dir():
            raise NotADirectoryError(f"{path}: not a {what}")
    elif not (path.is_file() if kind == "file" else path.exists()):
        raise FileNotFoundError(f"{path}: no such {what}")
    return path


# ------------------------------------------------------------------ RTSTRUCT
def _read_dicom(path: Path):
    import pydicom

    try:
        return pydicom.dcmread(str(path))
    except Exception as exc:  # pydicom raises several unrelated types
        raise InputError(f"{path}: not a readable DICOM file ({exc})") from None


_CONTOUR_DATA = 0x30060050
_N_POINTS = 0x30060046


def _contour_array(item) -> np.ndarray:
    """ContourData of one contour item as a flat float64 array.

    Parses the raw DS bytes directly; pydicom's per-value objects cost seconds
    on structure sets with 10^5 points.
    """
    elem = item.get_item(_CONTOUR_DATA) if _CONTOUR_DATA in item else None
    if elem is None:
        return np.zeros(0)
    raw = getattr(elem, "value", None)
    if isinstance(raw, bytes | bytearray):
        text = raw.decode("ascii", "replace").strip(" \x00")
        if not text:
            return np.zeros(0)
        try:
            return np.array(text.split("\\"), dtype=np.float64)
        except ValueError:
            pass
    return np.asarray(item.ContourData, dtype=np.float64)


def _damaged_rtstruct_is_bad_input(read):
    """Report a structure set that pydicom cannot walk (a truncated or damaged file) as a ValueError.

    pydicom reads sequences lazily: a cut file fails only when its items are used,
    with whatever the parser met (missing attributes, short buffers, no tag to read).
    """
    import functools
    import struct

    @functools.wraps(read)
    def wrapper(path, *args, **kwargs):
        try:
            return read(path, *args, **kwargs)
        except (FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError):
            raise
        except (AttributeError, KeyError, IndexError, TypeError, OSError, EOFError, NotImplementedError,
                struct.error) as exc:
            raise InputError(f"{path}: incomplete or damaged RT Structure Set ({exc})") from None

    return wrapper


#: What pydicom raises on a dataset whose elements a truncated file cut off or left garbled.
_INCOMPLETE = (AttributeError, KeyError, TypeError, ValueError, IndexError, EOFError, OSError)


def _open_rtstruct(path, counts: bool = True):
    """Path, dataset and ROI table of an RT Structure Set file (checked: it exists, holds ROIs, is whole).

    With ``counts=False`` the table holds numbers and names only: no ROI's points
    are parsed (most of the reading time when one ROI is wanted); pydicom reads
    every sequence item when the file is opened, so a cut file is still found.
    """
    path = _existing(path, "RT structure set file")
    ds = _read_dicom(path)
    if "StructureSetROISequence" not in ds:
        raise InputError(f"{path}: not an RT Structure Set (no StructureSetROISequence)")
    try:
        table = _roi_table(ds) if counts else _roi_names(ds)
    except _INCOMPLETE as exc:
        raise InputError(f"{path}: the RT Structure Set is truncated or incomplete "
                         f"({type(exc).__name__}: {exc})") from None
    return path, ds, table


@_damaged_rtstruct_is_bad_input
def list_rois(path) -> list[dict]:
    """ROIs of an RT Structure Set.

    Parameters
    ----------
    path : str or os.PathLike
        RTSTRUCT file.

    Returns
    -------
    list of dict
        ``number`` (int), ``name`` (str), ``n_contours`` (int), ``n_planes`` (int),
        ``max_points`` (int) per ROI, in file order.
    """
    return _open_rtstruct(path)[2]


def _roi_names(ds) -> list[dict]:
    """``number`` and ``name`` of every ROI (the contours are left unparsed)."""
    return [{"number": int(roi.ROINumber), "name": str(roi.ROIName)} for roi in ds.StructureSetROISequence]


def _roi_table(ds) -> list[dict]:
    contours = {}
    for rc in ds.get("ROIContourSequence", []):
        seq = rc.get("ContourSequence", [])
        data = [_contour_array(c) for c in seq]
        zs = {round(float(d[2]), 3) for d in data if len(d) >= 3}
        npts = max((len(d) // 3 for d in data), default=0)
        contours[int(rc.ReferencedROINumber)] = (len(seq), len(zs), npts)
    out = []
    for roi in ds.StructureSetROISequence:
        n, planes, npts = contours.get(int(roi.ROINumber), (0, 0, 0))
        out.append(
            {"number": int(roi.ROINumber), "name": str(roi.ROIName), "n_contours": n,
             "n_planes": planes, "max_points": npts}
        )
    return out


@_damaged_rtstruct_is_bad_input
def read_rtstruct(path, roi) -> ContourStack:
    """Closed planar contours of one ROI of an RT Structure Set.

    Contours that are not CLOSED_PLANAR (OPEN_PLANAR, POINT, ...) and contours that enclose
    nothing are skipped and named in the notes; pinched outlines are repaired
    (:func:`_contours_from_list`). Contours on oblique planes are taken into their plane frame
    (``frame``, as SlicerRT does).

    Parameters
    ----------
    path : str or os.PathLike
        RTSTRUCT file.
    roi : str or int
        ROI name (case-insensitive) or number; an ``int`` is always a number (``--roi-number``),
        a string of digits a number when no ROI has it as its name.

    Returns
    -------
    ContourStack
        Contours in patient coordinates (mm), ``z`` the patient z of each plane (or the plane
        frame's, see :attr:`ContourStack.frame`).

    Raises
    ------
    ValueError
        Unknown ROI (the message lists the existing ones), a name that several ROIs carry
        (the message lists their numbers), an ROI without closed contours, non-planar
        contours, planes of different orientations.
    """
    path, ds, rois = _open_rtstruct(path, counts=False)
    if roi is None:
        raise InputError(
            f"{path}: choose an ROI with --roi; existing: " + ", ".join(r["name"] for r in rois)
        )
    key = str(roi).strip()
    by_number = isinstance(roi, int | np.integer) and not isinstance(roi, bool)
    match = [] if by_number else [r for r in rois if r["name"].lower() == key.lower()]
    if len(match) > 1:
        raise InputError(f"{path}: {len(match)} ROIs are named {match[0]['name']!r} (ROI numbers "
                         f"{', '.join(str(r['number']) for r in match)}); choose one with --roi-number N")
    if not match and (by_number or key.isdigit()):
        match = [r for r in rois if r["number"] == int(key)]
    if not match:
        names = ", ".join(f"{r['number']}: {r['name']}" for r in rois)
        what = f"number {roi}" if by_number else f"named {roi!r}"
        raise InputError(f"{path}: no ROI {what}; existing ROIs are {names}")
    number, name = match[0]["number"], match[0]["name"]
    try:
        items, skipped, thickness = _roi_contours(ds, number, name)
    except _INCOMPLETE as exc:
        if isinstance(exc, ValueError) and str(exc).startswith("ROI "):
            raise
        raise InputError(f"{path}: the RT Structure Set is truncated or incomplete in ROI {name!r} "
                         f"({type(exc).__name__}: {exc})") from None
    notes: list[str] = []
    if skipped:
        kinds = {}
        for kind, i, z in skipped:
            kinds.setdefault(kind, []).append(f"{i}" + ("" if z is None else f" at z={z:.2f} mm"))
        notes.append("skipped contour(s) that enclose no area: " + "; ".join(
            f"{len(v)} {k} ({', '.join(v[:6])}{', ...' if len(v) > 6 else ''})" for k, v in kinds.items())
            + " (only CLOSED_PLANAR contours bound a volume)")
    if not items:
        raise InputError(f"{path}: ROI {name!r} has no CLOSED_PLANAR contours" + (f" ({notes[0]})" if notes else ""))
    items, frame = _plane_frame(items, name)
    if frame is not None:
        notes.append("contours on oblique planes (normal "
                     f"{np.round(frame[2], 4).tolist()}): reconstructed in their plane frame and the solid "
                     "turned back into patient coordinates (as SlicerRT does); patches.npz and the contours' "
                     "z are in the plane frame")
    repairs: list[dict] = []
    stack = ContourStack(_contours_from_list(items, f"ROI {name!r}", notes, repairs), "rtstruct", name, notes,
                         repairs, frame)
    if not stack.contours:
        raise InputError(f"{path}: ROI {name!r} has no closed contour that encloses an area ({'; '.join(notes)})")
    if thickness:
        stack.thickness_mm, stack.thickness_source = thickness, "the structure set's ContourSlabThickness"
    return stack


def _roi_contours(ds, number: int, name: str) -> tuple[list, list, float | None]:
    """(z, xyz points, index) of every CLOSED_PLANAR contour of one ROI, the skipped ones and the slab thickness.

    Returns
    -------
    items : list of (float, numpy.ndarray (n, 3), int)
    skipped : list of (kind, index, z or None)
        Contours that are not CLOSED_PLANAR, or have fewer than 3 points.
    thickness : float or None
        The contours' ``ContourSlabThickness`` (mm) when the file gives one.
    """
    items = []
    skipped = []
    thickness = []
    for rc in ds.get("ROIContourSequence", []):
        if int(rc.ReferencedROINumber) != number:
            continue
        for i, c in enumerate(rc.get("ContourSequence", [])):
            kind = str(c.get("ContourGeometricType", "CLOSED_PLANAR"))
            data = _contour_array(c)
            z = float(data[2]) if data.size >= 3 else None
            if kind != "CLOSED_PLANAR":
                skipped.append((kind, i, z))
                continue
            if data.size % 3:
                raise InputError(f"ROI {name!r} contour {i}: its ContourData holds {data.size} values, "
                                 "not x, y, z triples")
            if data.size < 9:
                skipped.append((f"CLOSED_PLANAR with {data.size // 3} point(s)", i, z))
                continue
            if "ContourSlabThickness" in c:
                thickness.append(float(c.ContourSlabThickness))
            xyz = data.reshape(-1, 3)
            items.append((float(xyz[:, 2].mean()), xyz, i))
    slab = float(np.median(thickness)) if thickness and np.median(thickness) > 0 else None
    return items, skipped, slab


#: Largest distance of a contour point from its plane, as a fraction of the contour's extent (planarity).
PLANAR_RTOL = 1e-3


def _plane_frame(items: list, name: str) -> tuple[list, np.ndarray | None]:
    """Contours (z, xyz (n, 3), index) as (z, xy (n, 2), index) in the frame of their common plane orientation.

    Axial contours (z spans at most 1e-3 mm) keep patient x, y and z; otherwise every contour's plane
    (least squares) must share one normal ``n``, and the frame's rows are ``u`` (patient x projected
    on the plane, or y when ``n`` is along x), ``v = n x u`` and ``n``.
    """
    if all(np.ptp(xyz[:, 2]) <= 1e-3 for _, xyz, _ in items):
        return [(z, xyz[:, :2], i) for z, xyz, i in items], None
    normals = []
    for _, xyz, i in items:
        centred = xyz - xyz.mean(axis=0)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        extent = float(np.ptp(xyz, axis=0).max())
        if len(xyz) >= 3 and sv[-1] / np.sqrt(len(xyz)) > PLANAR_RTOL * max(extent, 1e-9) * 2:
            raise InputError(f"ROI {name!r} contour {i}: not planar (points up to ~{sv[-1] / np.sqrt(len(xyz)):.3f} "
                             "mm off their plane)")
        n = vt[-1]
        normals.append(n if n[np.argmax(np.abs(n))] > 0 else -n)
    normals = np.asarray(normals)
    n = normals[0]
    off = np.abs(np.abs(normals @ n) - 1.0)
    if np.any(off > 1e-4):
        k = int(np.argmax(off))
        raise InputError(f"ROI {name!r}: contours lie on planes of different orientations (contour {items[k][2]} "
                         f"normal {np.round(normals[k], 4).tolist()} against {np.round(n, 4).tolist()})")
    n = np.mean(normals * np.sign(normals @ n)[:, None], axis=0)
    n /= np.linalg.norm(n)
    axis = np.eye(3)[0] if abs(n[0]) < 0.9 else np.eye(3)[1]
    u = axis - (axis @ n) * n
    u /= np.linalg.norm(u)
    frame = np.stack([u, np.cross(n, u), n])
    out = []
    for _, xyz, i in items:
        q = xyz @ frame.T
        out.append((float(q[:, 2].mean()), q[:, :2], i))
    return out, frame


def referenced_slice_thickness(path) -> tuple[float | None, str]:
    """SliceThickness of the CT images beside an RT Structure Set (its folder and the folders in it).

    Parameters
    ----------
    path : str or os.PathLike
        RTSTRUCT file.

    Returns
    -------
    thickness : float or None
        The median SliceThickness (mm) of the CT images that share the structure set's frame of
        reference (all CT images when it names none); None when there are none.
    source : str
        Where it was found.
    """
    import pydicom

    path = Path(path)
    ds = pydicom.dcmread(str(path), stop_before_pixels=True, specific_tags=["ReferencedFrameOfReferenceSequence"])
    frames = {str(f.get("FrameOfReferenceUID", "")) for f in ds.get("ReferencedFrameOfReferenceSequence", [])} - {""}
    folders = [path.parent] + sorted(p for p in path.parent.iterdir() if p.is_dir())
    found = []
    for folder in folders:
        for f in sorted(folder.iterdir())[:2000]:
            if not f.is_file() or f == path:
                continue
            try:
                im = pydicom.dcmread(str(f), stop_before_pixels=True,
                                     specific_tags=["Modality", "SliceThickness", "FrameOfReferenceUID"])
            except Exception:  # not DICOM: pydicom raises several unrelated types
                continue
            if str(im.get("Modality", "")) in ("CT", "MR", "PT") and im.get("SliceThickness") not in (None, ""):
                if not frames or str(im.get("FrameOfReferenceUID", "")) in frames:
                    found.append(float(im.SliceThickness))
        if found:
            return float(np.median(found)), f"SliceThickness of {len(found)} image(s) in {folder}"
    return None, ""


# ------------------------------------------------------------------ volumes
def _segment(values: np.ndarray, hu_min, hu_max, label: str) -> tuple[np.ndarray, str]:
    """The object of a volume (window or mask, largest component) and a note saying how."""
    mask, how = _mask_from_values(values, hu_min, hu_max, label)
    return largest_component(mask), f"segmented by {how}, largest connected component"


def _mask_from_values(values: np.ndarray, hu_min, hu_max, label: str) -> tuple[np.ndarray, str]:
    if hu_min is not None or hu_max is not None:
        lo = -np.inf if hu_min is None else float(hu_min)
        hi = np.inf if hu_max is None else float(hu_max)
        if lo > hi:
            raise InputError(f"--hu-min {lo} is above --hu-max {hi}")
        return (values >= lo) & (values <= hi), f"window [{lo:g}, {hi:g}]"
    uniq = np.unique(values[:: max(1, values.size // 1_000_000)])
    if len(uniq) <= 2 or values.dtype == bool:
        return values > 0, "non-zero voxels (mask input)"
    raise InputError(
        f"{label}: values are not a binary mask ({len(uniq)}+ distinct values); "
        "give an intensity window with --hu-min/--hu-max"
    )


def largest_component(mask) -> np.ndarray:
    """Largest 26-connected component of a 3-D mask.

    Parameters
    ----------
    mask : array_like, shape (Z, Y, X) bool

    Returns
    -------
    numpy.ndarray, shape (Z, Y, X) bool
    """
    from scipy import ndimage

    m = np.asarray(mask, dtype=bool)
    labels, n = ndimage.label(m, structure=np.ones((3, 3, 3)))
    if n == 0:
        raise InputError("mask: is empty (no voxel selected)")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == int(np.argmax(sizes))


def contours_from_mask(mask, z, spacing_yx, origin_yx=(0.0, 0.0), label: str = "mask") -> list[Contour]:
    """Sub-pixel contours of every slice of a 3-D mask (scikit-image ``find_contours``).

    Parameters
    ----------
    mask : array_like, shape (Z, Y, X) bool
        Object voxels.
    z : array_like, shape (Z,)
        Slice positions in mm.
    spacing_yx : (float, float)
        Row and column spacing in mm.
    origin_yx : (float, float)
        Position of voxel (0, 0) in mm (y, x).
    label : str
        Name used in error messages.

    Returns
    -------
    list of Contour
        Outer contours and holes (their orientation is normalised later), in mm;
        ``x = origin_x + column * dx``, ``y = origin_y + row * dy``.
    """
    from skimage.measure import find_contours

    m = np.asarray(mask, dtype=bool)
    zz = as_array(z, "z", shape=(m.shape[0],))
    dy, dx = (positive(s, "spacing") for s in spacing_yx)
    items = []
    for k in range(m.shape[0]):
        if not m[k].any():
            continue
        padded = np.pad(m[k].astype(np.float64), 1)
        for c in find_contours(padded, 0.5):
            rows, cols = c[:-1, 0] - 1.0, c[:-1, 1] - 1.0
            if len(rows) < 3:
                continue
            pts = np.stack([origin_yx[1] + cols * dx, origin_yx[0] + rows * dy], axis=1)
            items.append((float(zz[k]), pts))
    if not items:
        raise InputError(f"{label}: no contour found")
    return _contours_from_list(items, label)


def _resample_volume(values: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Linear interpolation of a volume onto uniform slices with the median spacing."""
    d = float(np.median(np.diff(z)))
    n = int(np.floor((z[-1] - z[0]) / d + 1e-6)) + 1
    zu = z[0] + d * np.arange(n)
    k = np.clip(np.searchsorted(z, zu, side="right") - 1, 0, len(z) - 2)
    w = ((zu - z[k]) / (z[k + 1] - z[k]))[:, None, None]
    vals = values[k] * (1 - w) + values[k + 1] * w
    return vals, zu, d


def check_spacing(z, label: str, allow_gaps: bool = False) -> float:
    """Slice spacing of sorted positions; error when it is not uniform.

    Parameters
    ----------
    z : array_like, shape (P,)
        Sorted distinct slice positions in mm.
    label : str
        Input name for the message.
    allow_gaps : bool
        Accept spacings that are whole multiples of the common spacing (missing
        planes between separate bodies of a structure set).

    Returns
    -------
    float
        The spacing in mm (0 for a single slice).

    Raises
    ------
    ValueError
        When consecutive spacings differ by more than 1 % (names them, and
        suggests ``--resample``).
    """
    zz = as_array(z, "z", ndim=1)
    if len(zz) < 2:
        return 0.0
    d = np.diff(zz)
    if np.any(d <= 0):
        raise InputError(f"{label}: two slices at the same position (z={zz[np.argmin(d)]:.3f} mm)")
    ref = float(np.min(d)) if allow_gaps else float(np.median(d))
    ratio = d / ref
    step = np.maximum(np.round(ratio), 1.0) if allow_gaps else np.ones_like(ratio)
    bad = np.flatnonzero(np.abs(ratio - step) > SPACING_RTOL)
    if len(bad):
        i = int(bad[0])
        raise InputError(
            f"{label}: unequal slice spacing ({d[i]:.3f} mm between z={zz[i]:.3f} and "
            f"z={zz[i + 1]:.3f} mm, {ref:.3f} mm elsewhere); use --resample to resample "
            "images onto uniform slices, or to blend contours at their true positions"
        )
    return ref


@reads_file("CT series")
def read_ct_series(folder, hu_min=None, hu_max=None, resample: bool = False) -> ContourStack:
    """Segment a DICOM CT (or label) series and extract its contours.

    Slices are sorted by their position along the slice normal
    ``n = row_dir x col_dir`` from ImageOrientationPatient, ``s = n . IPP``
    (never by file name or InstanceNumber); HU = pixel * RescaleSlope +
    RescaleIntercept; the object is the largest connected component of the HU
    window (or the non-zero voxels of a label series).

    Parameters
    ----------
    folder : str or os.PathLike
        Folder with the series' files.
    hu_min, hu_max : float, optional
        HU window.
    resample : bool
        Resample unequal slice spacing linearly instead of failing.

    Returns
    -------
    ContourStack
    """
    folder = _existing(folder, "folder of DICOM files", "folder")
    import pydicom

    slices = []
    for f in sorted(p for p in folder.iterdir() if p.is_file()):
        try:
            ds = pydicom.dcmread(str(f))
        except Exception:
            continue
        if "ImagePositionPatient" in ds and "PixelData" in ds:
            slices.append(ds)
    if not slices:
        raise InputError(f"{folder}: no DICOM image slices found")
    iop = np.asarray(slices[0].ImageOrientationPatient, dtype=np.float64)
    row_dir, col_dir = iop[:3], iop[3:]
    normal = np.cross(row_dir, col_dir)
    if abs(abs(normal[2]) - 1.0) > 1e-3 or abs(row_dir[2]) > 1e-3 or abs(col_dir[2]) > 1e-3:
        raise InputError(
            f"{folder}: slices are not axial (ImageOrientationPatient {iop.round(4).tolist()}); "
            "non-axial planes are not supported"
        )
    for ds in slices:
        if np.abs(np.asarray(ds.ImageOrientationPatient, float) - iop).max() > 1e-4:
            raise InputError(f"{folder}: slices have different ImageOrientationPatient")
    pos = np.array([float(np.dot(normal, np.asarray(ds.ImagePositionPatient, float))) for ds in slices])
    order = np.argsort(pos)
    slices = [slices[i] for i in order]
    pos = pos[order]
    z = np.array([float(ds.ImagePositionPatient[2]) for ds in slices])
    values = np.stack(
        [ds.pixel_array * float(ds.get("RescaleSlope", 1)) + float(ds.get("RescaleIntercept", 0))
         for ds in slices]
    ).astype(np.float64)
    notes = [f"{len(slices)} CT slices sorted by position along the slice normal"]
    sign = 1.0 if normal[2] > 0 else -1.0
    if sign < 0:
        values, z = values[::-1], z[::-1]
    try:
        check_spacing(z, str(folder))
    except ValueError:
        if not resample:
            raise
        values, z, d = _resample_volume(values, z)
        notes.append(f"resampled to uniform {d:.3f} mm slices")
    mask, note = _segment(values, hu_min, hu_max, str(folder))
    notes.append(note)
    ps = [float(s) for s in slices[0].PixelSpacing]  # row spacing, column spacing
    ipp = np.asarray(slices[0].ImagePositionPatient, float)
    # axial: x follows the row direction (columns), y the column direction (rows); flip the
    # array where a direction points to -x / -y so that spacings stay positive
    x0, y0 = ipp[0], ipp[1]
    if row_dir[0] < 0:
        mask = mask[:, :, ::-1]
        x0 -= (mask.shape[2] - 1) * ps[1]
    if col_dir[1] < 0:
        mask = mask[:, ::-1, :]
        y0 -= (mask.shape[1] - 1) * ps[0]
    contours = contours_from_mask(mask, z, (ps[0], ps[1]), (y0, x0), str(folder))
    return ContourStack(contours, "ct", folder.name, notes)


def _first_channel(images) -> list[np.ndarray]:
    return [im if im.ndim == 2 else im[..., 0] for im in images]


def _read_image_stack(path: Path) -> np.ndarray:
    import cv2

    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".png")
        if not files:
            raise InputError(f"{path}: folder holds no PNG images")
        images = [cv2.imread(str(f), cv2.IMREAD_UNCHANGED) for f in files]
        if any(im is None for im in images):
            raise InputError(f"{path}: an image could not be read")
        images = _first_channel(images)
        if len({im.shape for im in images}) != 1:
            raise InputError(f"{path}: images have different sizes")
        return np.stack(images)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        arr = np.load(path, allow_pickle=False)
        if arr.ndim != 3:
            raise InputError(f"{path}: expected a 3-D (Z, Y, X) array, got shape {arr.shape}")
        return arr
    if suffix in (".tif", ".tiff"):
        ok, pages = cv2.imreadmulti(str(path), flags=cv2.IMREAD_UNCHANGED)
        if not ok or not pages:
            raise InputError(f"{path}: not a readable multi-page TIFF")
        return np.stack(_first_channel(pages))
    raise InputError(f"{path}: unknown stack format (use .npy, .tif or a folder of PNGs)")


def parse_spacing(text) -> tuple[float, float, float]:
    """Parse ``--spacing z,y,x`` (mm).

    Parameters
    ----------
    text : str or sequence of 3 floats

    Returns
    -------
    (float, float, float)
    """
    if isinstance(text, str):
        parts = text.replace(" ", "").split(",")
    else:
        parts = list(text)
    if len(parts) != 3:
        raise InputError(f"--spacing: expected z,y,x in mm, got {text!r}")
    return tuple(positive(p, "--spacing") for p in parts)


@reads_file("mask stack")
def read_mask_stack(path, spacing, hu_min=None, hu_max=None) -> ContourStack:
    """Contours of a mask or image stack (``.npy``, multi-page ``.tif``, folder of PNGs).

    Parameters
    ----------
    path : str or os.PathLike
        The stack; slice ``k`` lies at ``z = k * dz``.
    spacing : str or (float, float, float)
        ``z, y, x`` voxel spacing in mm.
    hu_min, hu_max : float, optional
        Intensity window for grey images (binary masks need none).

    Returns
    -------
    ContourStack
    """
    path = _existing(path, "mask stack", "any")
    if spacing is None:
        raise InputError(f"{path}: a mask stack needs --spacing z,y,x (mm)")
    dz, dy, dx = parse_spacing(spacing)
    mask, note = _segment(_read_image_stack(path), hu_min, hu_max, str(path))
    z = dz * np.arange(mask.shape[0])
    contours = contours_from_mask(mask, z, (dy, dx), label=str(path))
    return ContourStack(contours, "mask", path.name, [note])


def is_nifti(path) -> bool:
    """Whether a path names a NIfTI file (``.nii`` or ``.nii.gz``).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    bool
    """
    name = Path(path).name.lower()
    return name.endswith(".nii") or name.endswith(".nii.gz")


def _nifti_volume(path: Path):
    """Data (3-D) and affine of a NIfTI file, with a clear error for unreadable or non-3-D files."""
    import nibabel

    try:
        img = nibabel.load(str(path))
        data = np.asanyarray(img.dataobj)
    except Exception as exc:  # nibabel raises many kinds for damaged files
        raise InputError(f"{path}: not a readable NIfTI file ({type(exc).__name__}: {exc})") from None
    if data.ndim == 4 and data.shape[3] == 1:
        data = data[..., 0]
    if data.ndim != 3:
        raise InputError(f"{path}: a label or mask volume must be 3-D, got shape {data.shape}")
    return data, np.asarray(img.affine, dtype=np.float64)


def nifti_labels(path) -> list[dict]:
    """The labels of a NIfTI label or mask volume.

    Parameters
    ----------
    path : str or os.PathLike
        ``.nii`` or ``.nii.gz`` file.

    Returns
    -------
    list of dict
        ``label`` (the voxel value, int when integral), ``n_voxels`` and
        ``n_planes`` (axial planes it occupies) per non-zero value, in increasing order.
    """
    path = _existing(path, "NIfTI file")
    data, affine = _nifti_volume(path)
    axis = _slice_axis(affine, path)
    values, counts = np.unique(data[data != 0], return_counts=True)
    out = []
    for v, n in zip(values, counts):
        planes = int(np.any(np.moveaxis(data == v, axis, 0), axis=(1, 2)).sum())
        label = int(v) if float(v).is_integer() else float(v)
        out.append({"label": label, "n_voxels": int(n), "n_planes": planes})
    return out


def _slice_axis(affine: np.ndarray, path) -> int:
    """The voxel axis along world z; the other two must lie in axial planes."""
    columns = affine[:3, :3]
    axis = int(np.argmax(np.abs(columns[2])))
    others = [a for a in range(3) if a != axis]
    scale = float(np.abs(columns).max())
    if np.any(np.abs(columns[2, others]) > 1e-6 * scale) or np.any(np.abs(columns[:2, axis]) > 1e-6 * scale):
        raise InputError(f"{path}: the volume's slices are not axial (affine {columns.round(6).tolist()}); "
                         "resample it onto an axial grid first")
    return axis


def read_nifti(path, label=None) -> ContourStack:
    """Contours of a NIfTI label or mask volume, one set per axial slice (nibabel).

    Every axial slice of the chosen voxels is contoured at sub-pixel
    precision (:func:`skimage.measure.find_contours` at level 0.5, the
    boundary half-way between voxel centres) and mapped to mm through the
    file's affine, which NIfTI defines in RAS, turned into DICOM patient
    coordinates (LPS: x and y negated, :func:`surfaces.voxelize.lps_to_ras`), the
    frame of RT Structure Sets and of ``--export-mask``'s grid. All components are
    kept (a structure may have several bodies); holes come out as inner contours.

    Parameters
    ----------
    path : str or os.PathLike
        ``.nii`` or ``.nii.gz`` file.
    label : int, str or None
        Voxel value of the structure; None for every non-zero voxel.

    Returns
    -------
    ContourStack
        ``source`` is ``"nifti"``; ``name`` the file name with the label.
    """
    from skimage.measure import find_contours

    path = _existing(path, "NIfTI file")
    from surfaces.voxelize import lps_to_ras

    data, affine = _nifti_volume(path)
    axis = _slice_axis(affine, path)
    affine = lps_to_ras(affine)  # RAS -> LPS (the flip is its own inverse)
    if label is None:
        mask, what = data != 0, "non-zero voxels"
    else:
        try:
            value = float(label)
        except (TypeError, ValueError):
            raise InputError(f"--label: must be a number (a voxel value), got {label!r}") from None
        mask, what = data == value, f"label {value:g}"
        if not mask.any():
            present = np.unique(data[data != 0])
            raise InputError(f"--label: no voxel of {path.name} has the value {value:g} "
                             f"(labels present: {[float(v) for v in present[:20]]})")
    if not mask.any():
        raise InputError(f"{path}: the mask is empty (no non-zero voxel)")
    rows_axis, cols_axis = (a for a in range(3) if a != axis)
    stack = np.moveaxis(mask, (axis, rows_axis, cols_axis), (0, 1, 2))
    items = []
    for k in np.flatnonzero(stack.any(axis=(1, 2))):
        for c in find_contours(np.pad(stack[k].astype(np.float64), 1), 0.5):
            if len(c) < 4:
                continue
            index = np.empty((len(c) - 1, 4))
            index[:, axis], index[:, rows_axis], index[:, cols_axis] = k, c[:-1, 0] - 1.0, c[:-1, 1] - 1.0
            index[:, 3] = 1.0
            world = index @ affine[:3].T
            items.append((float(world[0, 2]), world[:, :2]))
    contours = _contours_from_list(items, str(path))
    name = path.name if label is None else f"{path.name} label {label}"
    note = f"NIfTI {what}: contoured per axial slice at sub-pixel precision (find_contours at 0.5)"
    return ContourStack(contours, "nifti", name, [note])


def write_nifti_mask(path, mask, affine_lps) -> np.ndarray:
    """Write a mask as NIfTI (nibabel, atomically) with its affine in RAS, as NIfTI defines it.

    Parameters
    ----------
    path : str or os.PathLike
        ``.nii`` or ``.nii.gz`` file.
    mask : numpy.ndarray, shape (ni, nj, nk)
        Voxel values (array axes i, j, k).
    affine_lps : array_like, shape (4, 4)
        Voxel indices to DICOM patient mm (LPS); stored with x and y negated
        (:func:`surfaces.voxelize.lps_to_ras`), as qform and sform (code 1, scanner).

    Returns
    -------
    numpy.ndarray, shape (4, 4)
        The RAS affine written.
    """
    import nibabel

    from surfaces.io import atomic_path
    from surfaces.voxelize import lps_to_ras

    path = Path(path)
    if not is_nifti(path):
        raise InputError(f"--export-mask: must end in .nii or .nii.gz, got {str(path)!r}")
    affine = lps_to_ras(affine_lps)
    img = nibabel.Nifti1Image(np.asarray(mask), affine)
    img.set_qform(affine, code=1)
    img.set_sform(affine, code=1)
    with atomic_path(path, suffix=".nii.gz" if path.name.lower().endswith(".gz") else ".nii") as tmp:
        nibabel.save(img, str(tmp))
    return affine


@reads_file("contour JSON file")
def read_contour_json(path) -> ContourStack:
    """Contours from ``{"units": "mm", "contours": [{"z": mm, "points": [[x, y], ...]}, ...]}``.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    ContourStack
    """
    path = _existing(path, "contour file")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("contours"), list):
        raise InputError(f"{path}: expected an object with a 'contours' list")
    units = data.get("units", "mm")
    if units != "mm":
        raise InputError(f"{path}: units must be 'mm', got {units!r}")
    items = []
    for i, c in enumerate(data["contours"]):
        if not isinstance(c, dict) or "z" not in c or "points" not in c:
            raise InputError(f"{path}: contour {i} needs 'z' and 'points'")
        pts = np.asarray(c["points"], dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 1:
            raise InputError(
                f"{path}: contour {i} at z={c['z']} needs [x, y] points, got shape {pts.shape}"
            )
        if pts.shape[1] == 3 and np.ptp(pts[:, 2]) > 1e-3:
            raise InputError(f"{path}: contour {i} is not in an axial plane (its z values differ)")
        items.append((float(c["z"]), pts[:, :2]))
    if not items:
        raise InputError(f"{path}: holds no contours")
    notes: list[str] = []
    repairs: list[dict] = []
    stack = ContourStack(_contours_from_list(items, path.name, notes, repairs), "json", path.stem, notes, repairs)
    if not stack.contours:
        raise InputError(f"{path}: no contour encloses an area ({'; '.join(notes)})")
    return stack


def load(path, roi=None, hu_min=None, hu_max=None, spacing=None, resample: bool = False) -> ContourStack:
    """Read any supported input into a :class:`ContourStack`.

    Parameters
    ----------
    path : str or os.PathLike
        RTSTRUCT ``.dcm``, CT series folder, ``.npy``/``.tif``/PNG-folder mask
        stack, NIfTI label or mask volume (``.nii``/``.nii.gz``), or contour ``.json``.
    roi : str or int, optional
        ROI name or number (RTSTRUCT); the label, a voxel value (NIfTI; None:
        every non-zero voxel).
    hu_min, hu_max : float, optional
        Intensity window (CT series, grey image stacks).
    spacing : str or (float, float, float), optional
        ``z, y, x`` spacing in mm (mask stacks).
    resample : bool
        Resample unequal slice spacing instead of failing.

    Returns
    -------
    ContourStack
    """
    path = _existing(path, "file or folder", "any")
    suffix = path.suffix.lower()
    if is_nifti(path):
        return read_nifti(path, roi)
    if suffix == ".json":
        return read_contour_json(path)
    if suffix in (".npy", ".tif", ".tiff"):
        return read_mask_stack(path, spacing, hu_min, hu_max)
    if path.is_dir():
        if any(p.suffix.lower() == ".png" for p in path.iterdir()):
            return read_mask_stack(path, spacing, hu_min, hu_max)
        return read_ct_series(path, hu_min, hu_max, resample)
    ds = _read_dicom(path)
    if str(ds.get("Modality", "")) == "RTSTRUCT" or "StructureSetROISequence" in ds:
        return read_rtstruct(path, roi)
    raise InputError(f"{path}: a single DICOM file must be an RT Structure Set (Modality RTSTRUCT)")
