"""Structure-set composition: ``(base u plus...) - (minus...)`` of reconstructed ROIs (issue 9).

Every named ROI is reconstructed with the same options as the base; each
structure becomes one solid (its bodies united, holes subtracted, see
:meth:`slices.structure.Reconstruction.solid_mesh`) and
:func:`surfaces.boolean.compose` (manifold3d) combines the triangle meshes.
"""

from __future__ import annotations

import time

from slices.io import ContourStack
from slices.options import ReadOptions
from slices.structure import Reconstruction, reconstruct_roi
from surfaces.mesh import TriangleMesh
from surfaces.validate import InputError


def roi_solid(stack: ContourStack, rec: Reconstruction) -> TriangleMesh:
    """One closed solid of a structure for set operations (bodies united, holes subtracted).

    Parameters
    ----------
    stack : ContourStack
        The structure's contours (for its name).
    rec : Reconstruction
        Its reconstruction, with meshes.

    Returns
    -------
    TriangleMesh

    Raises
    ------
    ValueError
        When several bodies cannot be united into one solid.
    """
    mesh, united = rec.solid_mesh()
    if len(rec.bodies) > 1 and not united:
        raise InputError(f"{stack.name}: its {len(rec.bodies)} bodies could not be united into one solid "
                         "for the composition")
    return mesh


def _entry(stack: ContourStack, rec: Reconstruction, mesh: TriangleMesh) -> dict:
    volume = mesh.signed_volume()
    return {"roi": stack.name, "volume_mm3": rec.volume_mm3, "volume_ml": rec.volume_mm3 / 1000.0,
            "mesh_volume_mm3": volume, "mesh_volume_ml": volume / 1000.0, "n_bodies": len(rec.bodies)}


def compose_rois(input_path, base_stack: ContourStack, base_rec: Reconstruction, *, minus=(), plus=(),
                 repair: bool = False, reading: ReadOptions | None = None,
                 progress=None) -> tuple[TriangleMesh, dict]:
    """Compose the base ROI with others of the same input: ``(base u plus...) - (minus...)``.

    Parameters
    ----------
    input_path : str or os.PathLike
        The structure set (or other input) the ROIs come from.
    base_stack : ContourStack
        The base ROI's contours (for its name).
    base_rec : Reconstruction
        The base ROI's reconstruction; the other ROIs are built with its options.
    minus, plus : sequence of str or int
        ROI names or numbers subtracted from / added to the base (added first).
    repair : bool
        Repair every mesh before the set operations (see :func:`surfaces.boolean.repair_mesh`).
    reading : ReadOptions, optional
        How the input is read (as for the base).
    progress : callable, optional
        Called with finished and total bodies of each ROI.

    Returns
    -------
    mesh : TriangleMesh
        The composed solid (closed, outward oriented; possibly empty).
    composition : dict
        ``operation`` (text), ``base``/``minus``/``plus`` entries with ``roi``,
        ``volume_mm3``/``volume_ml`` (patch model), ``mesh_volume_mm3`` (the
        triangles that entered the set operation), ``n_bodies``; and
        ``result_volume_mm3``/``_ml`` (the base's patch volume plus added minus
        removed: never above the minuend), ``result_mesh_volume_mm3``/``_ml`` (the
        result triangles'), ``removed_volume_mm3`` (of base u plus),
        ``added_volume_mm3`` (plus beyond the base), ``area_mm2`` (result
        triangles), ``watertight``, ``oriented``, ``n_triangles``, ``repairs``, ``time_s``. Volumes are
        those of the triangle meshes (inscribed in the patch surfaces).
    """
    from surfaces import boolean

    t0 = time.perf_counter()
    minus, plus = list(minus or ()), list(plus or ())
    if not minus and not plus:
        raise InputError("composition: give at least one ROI to subtract (--minus) or add (--plus)")
    if base_stack.source != "rtstruct":
        # other inputs hold one structure: every "ROI" would be the base itself
        raise InputError(f"composition: {input_path} is a {base_stack.source} input; ROIs are composed "
                         "within an RT structure set")
    base_mesh = roi_solid(base_stack, base_rec)
    entries = {"minus": [], "plus": []}
    meshes = {"minus": [], "plus": []}
    for kind, rois in (("plus", plus), ("minus", minus)):
        for roi in rois:
            stack, rec = reconstruct_roi(input_path, roi, reading=reading, options=base_rec.options,
                                         progress=progress)
            mesh = roi_solid(stack, rec)
            meshes[kind].append(mesh)
            entries[kind].append(_entry(stack, rec, mesh))
    names = {"base": base_stack.name, "minus": [e["roi"] for e in entries["minus"]],
             "plus": [e["roi"] for e in entries["plus"]]}
    mesh, summ = boolean.compose(base_mesh, minus=meshes["minus"], plus=meshes["plus"], repair=bool(repair),
                                 names=names)
    text = " + ".join([repr(base_stack.name)] + [repr(n) for n in names["plus"]])
    if names["minus"]:
        text = (f"({text})" if names["plus"] else text) + " - " + " - ".join(repr(n) for n in names["minus"])
    volume = float(summ["volume"])
    # base u plus as the engine built it (without --plus it is the base, added nothing by definition;
    # the engine's copy can differ from the input mesh in the last digits)
    grown = volume + float(summ["removed_volume"]) if plus else float(summ["volume_base"])
    added = grown - float(summ["volume_base"])
    removed = max(float(summ["removed_volume"]), 0.0)
    # the figure reported next to the base's patch volume: the base's patch volume changed by what the set
    # operation added and removed on the triangle meshes (both at one resolution), so a difference can
    # never exceed its minuend, whatever the meshes' inscribed-volume bias
    result = max(base_rec.volume_mm3 + max(added, 0.0) - removed, 0.0) if volume > 0 else 0.0
    composition = {
        "operation": text,
        "engine": "manifold3d via surfaces.boolean.compose",
        "base": _entry(base_stack, base_rec, base_mesh),
        "minus": entries["minus"],
        "plus": entries["plus"],
        "result_volume_mm3": result,
        "result_volume_ml": result / 1000.0,
        "result_mesh_volume_mm3": volume,
        "result_mesh_volume_ml": volume / 1000.0,
        "removed_volume_mm3": float(summ["removed_volume"]),
        "removed_volume_ml": float(summ["removed_volume"]) / 1000.0,
        "added_volume_mm3": added,
        "added_volume_ml": added / 1000.0,
        "area_mm2": mesh.surface_area(),
        "watertight": bool(summ["watertight"]),
        "oriented": bool(mesh.is_oriented()),
        "n_triangles": int(summ["n_triangles"]),
        "flat_shells_removed": int(summ["flat_shells_removed"]),
        "repairs": summ["repairs"],
        "volume_note": "removed and added volumes are those of the triangle meshes (one resolution for all "
                       "ROIs); result_volume is the base's patch volume plus added minus removed, so a "
                       "difference never exceeds its minuend; result_mesh_volume is the result mesh's own",
        "time_s": time.perf_counter() - t0,
    }
    return mesh, composition

