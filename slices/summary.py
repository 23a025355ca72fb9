"""The summary of a reconstruction: the figures ``summary.json`` holds, as one dict.

Angles are reported in degrees here (``ray_start``, ``ray_start_deg``), the
unit of the command line; inside the package they are radians.
"""

from __future__ import annotations

import numpy as np

from slices.io import ContourStack
from slices.structure import SENSITIVITY_OFFSET_MM, Reconstruction
from slices.volume import area_uncertainty, volume_uncertainty
from surfaces.mesh import TriangleMesh


def body_table(rec: Reconstruction) -> list[dict]:
    """One row per body: kind, planes, chain ends, caps, volume, area, patches, parameters.

    Parameters
    ----------
    rec : Reconstruction

    Returns
    -------
    list of dict
        ``kind``, planes, ``start``/``stop`` (why the chain ends), ``caps`` (what
        each end got, :func:`slices.caps.end_kinds`), ``subtracted`` (holes),
        ``volume_mm3``, ``area_mm2``, ``n_patches``, ``n_control_points``,
        ``n_turning_points``, ``n_blend_limited`` (tangents the monotone blend
        shortened), ``surface`` and ``self_intersecting_faces`` (which side surface
        was kept and its folded faces, :func:`slices.body.build_body`),
        ``mesh_samples`` (subdivisions per patch around and across the slices,
        :func:`slices.body.mesh_samples`; None without a mesh),
        ``max_control_point_deviation_mm``, ``ray_start_deg``.
    """
    if rec.implicit is not None:
        return implicit_table(rec)
    out = []
    for b in rec.bodies:
        z = b.body.z
        out.append({
            "kind": b.body.kind,
            "z_min_mm": float(z.min()), "z_max_mm": float(z.max()),
            "n_slices": int(len(z)),
            "start": b.body.start, "stop": b.body.stop,
            "caps": list(b.caps_used),
            "subtracted": b.body.kind == "hole",
            "volume_mm3": b.volume_mm3, "area_mm2": b.area_mm2,
            "n_patches": int(b.patches.n_patches),
            "n_control_points": b.n_points, "n_turning_points": b.n_turning,
            "n_blend_limited": b.n_limited,
            "surface": b.surface,
            "surface_path": "coons",
            "self_intersecting_faces": b.self_intersecting_faces,
            "mesh_samples": None if b.mesh_samples is None else list(b.mesh_samples),
            "max_control_point_deviation_mm": b.max_deviation_mm,
            "ray_start_deg": float(np.degrees(b.start_angle)),
        })
    return out


def count_noun(n: int, one: str, many: str | None = None) -> str:
    """``n`` and the noun in the number it takes: ``1 body``, ``2 bodies``, ``0 holes``.

    Parameters
    ----------
    n : int
        The count.
    one : str
        The singular noun.
    many : str, optional
        The plural (default ``one + "s"``).

    Returns
    -------
    str

    Examples
    --------
    >>> count_noun(1, "body", "bodies"), count_noun(3, "body", "bodies"), count_noun(0, "hole")
    ('1 body', '3 bodies', '0 holes')
    """
    return f"{n} {one if n == 1 else (many or one + 's')}"


def implicit_table(rec: Reconstruction) -> list[dict]:
    """One row per connected part (shell) of an implicit surface's mesh.

    Parameters
    ----------
    rec : Reconstruction
        With :attr:`Reconstruction.implicit`.

    Returns
    -------
    list of dict
        ``kind`` (``"outer"``, or ``"hole"`` for a cavity), ``z_min_mm``, ``z_max_mm``, ``volume_mm3``
        (positive), ``area_mm2``, ``n_triangles``, ``surface`` and ``surface_path`` (``"implicit"``),
        ``pixel_mm`` and ``z_samples`` (:class:`slices.implicit.ImplicitSurface`).
    """
    from surfaces.topology import shells

    imp = rec.implicit
    mesh = imp.mesh
    label = shells(mesh.triangles, mesh.n_vertices)
    c = mesh.vertices[mesh.triangles]
    volume = np.bincount(label, np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])) / 6.0)
    area = np.bincount(label, 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1))
    count = np.bincount(label)
    zlo = np.full(len(count), np.inf)
    zhi = np.full(len(count), -np.inf)
    np.minimum.at(zlo, label, c[:, :, 2].min(axis=1))
    np.maximum.at(zhi, label, c[:, :, 2].max(axis=1))
    return [{"kind": "outer" if volume[k] > 0 else "hole", "z_min_mm": float(zlo[k]), "z_max_mm": float(zhi[k]),
             "volume_mm3": float(abs(volume[k])), "area_mm2": float(area[k]), "n_triangles": int(count[k]),
             "subtracted": bool(volume[k] < 0), "surface": "implicit", "surface_path": "implicit",
             "pixel_mm": imp.pixel_mm, "z_samples": imp.z_samples}
            for k in np.argsort(zlo, kind="stable")]


def chaining_text(rec: Reconstruction) -> str:
    """How the contours were chained into bodies, in one sentence.

    Parameters
    ----------
    rec : Reconstruction

    Returns
    -------
    str
    """
    if rec.implicit is not None:
        imp = rec.implicit
        rows = implicit_table(rec)
        n_out = sum(r["kind"] == "outer" for r in rows)
        return (f"one implicit surface (branching, several bodies or holes): every plane's contours as a signed "
                f"distance on a {imp.pixel_mm:.2f} mm raster, blended across the planes with the seed's parabolic "
                f"blending ({imp.z_samples} levels per slice gap), marching cubes; {n_out} connected part(s), "
                f"{len(rows) - n_out} cavity(ies); caps {imp.cap_offset_mm:.3g} mm beyond the end planes")
    n_out = sum(b.body.kind == "outer" for b in rec.bodies)
    n_hole = len(rec.bodies) - n_out
    splits = sum(b.body.stop in ("branch", "merge") for b in rec.bodies)
    text = (f"{count_noun(len(rec.bodies), 'body', 'bodies')} chained by overlap of contours on neighbouring "
            f"planes: {n_out} outer, {count_noun(n_hole, 'hole')} (volume subtracted)")
    if splits:
        text += f"; {count_noun(splits, 'chain')} split at a branching or merging contour"
    joined = sum(b.body.start == "split" for b in rec.bodies) + sum(b.body.stop == "split" for b in rec.bodies)
    if joined:
        text += (f"; {count_noun(joined, 'chain end')} joined at a contour divided along the mid-line between its "
                 "branches (flat joints inside the union)")
    steps = sum(b.body.stop == "step" for b in rec.bodies)
    if steps:
        text += (f"; {count_noun(steps, 'slab')} stepped where every fallback surface folded (two half caps meeting "
                 "half-way, ends \"step\")")
    singles = sum(len(b.body.contours) == 1 and b.caps_used == ("half", "half") and rec.options.caps in ("none", "flat")
                  and "step" not in (b.body.start, b.body.stop) for b in rec.bodies)
    if singles:
        text += (f"; {count_noun(singles, 'single-contour body', 'single-contour bodies')} given half caps "
                 f"(no thickness with caps {rec.options.caps})")
    return text


#: The pixel size behind the contour-position terms of the uncertainty budgets.
PIXEL_NOTE = "1 mm pixels assumed for the contour position (the image's own pixel is not passed to the summary)"

def caps_notes(rec: Reconstruction) -> list[str]:
    """What the written surface's ends are, by path, when that differs from the volume's cap model.

    With ``caps="trend"`` the volume always integrates the areas' trend (:mod:`slices.volume`); the
    surface's ends are the trend's shape on the Coons path (rings closing in an apex,
    :func:`slices.caps.trend_rings`; a prism where the trend does not close within a spacing), and
    the implicit path's own closing (:mod:`slices.implicit`).

    Parameters
    ----------
    rec : Reconstruction

    Returns
    -------
    list of str
        At most one note.
    """
    if rec.options.caps != "trend":
        return []
    if rec.implicit is not None:
        return [f"caps: the implicit surface (surface_path implicit) closes its own way, "
                f"{rec.implicit.cap_offset_mm:.3g} mm beyond the end planes, not in the trend's shape; volume_mm3 "
                "is the area trend's, surface_volume_mm3 and area_mm2 are the implicit surface's"]
    ends = [(b.caps_used[i], b.cap_volumes_mm3[i], b.extrusions_mm[i]) for b in rec.bodies for i in (0, 1)]
    shaped = sum(k == "trend" and h == 0 and v > 0 for k, v, h in ends)
    prisms = sum(k == "trend" and h > 0 for k, v, h in ends)
    others = len(ends) - shaped - prisms
    return [f"caps: the surface's trend ends (surface_path {rec.surface_path}) are shaped as the area trend says "
            f"(rings closing in an apex) at {count_noun(shaped, 'end')}, prisms of the trend's volume at {prisms} "
            "(where the trend does not close within one spacing, on single contours, or where no point sees the whole "
            f"end outline); {count_noun(others, 'end')} at branchings or joints (half or flat caps)"]


#: What each ``caps`` choice counts beyond the end planes (named beside every printed volume).
CAPS_TEXT = {
    "trend": "whole structure: areas integrated between the planes, caps from the areas' trend beyond the end planes",
    "flat": "between the end planes only (flat caps in the end planes)",
    "half": "end slabs half a spacing beyond the end planes (as planning systems count)",
    "dome": "dome caps of half a spacing beyond the end planes",
    "none": "between the end planes only (open surface, closed flat for the volume)",
}


def volume_caps_text(caps: str, composed: bool = False) -> str:
    """The cap convention of a printed volume, in words.

    Parameters
    ----------
    caps : str
        :data:`slices.caps.CAP_KINDS`.
    composed : bool
        The volume is a composition's (its meshes' caps).

    Returns
    -------
    str
    """
    if composed:
        return f"caps {caps}: the composition of the ROIs' meshes, each capped {caps} (the written solid's volume)"
    return f"caps {caps}: {CAPS_TEXT.get(caps, caps)}"


def summarize(input_path, stack: ContourStack, rec: Reconstruction, mesh: TriangleMesh, union: bool,
              composition: dict | None, reference: dict | None, timings: dict, *,
              checks: dict | None = None) -> dict:
    """The summary of a reconstruction.

    Parameters
    ----------
    input_path : str or os.PathLike
        What was read.
    stack : ContourStack
        The base ROI's contours (its notes end up in ``notes``).
    rec : Reconstruction
        The base ROI's reconstruction.
    mesh : TriangleMesh
        The result's solid (united, concatenated or composed).
    union : bool
        Whether the bodies were united.
    composition : dict or None
        :func:`slices.compose.compose_rois`'s record.
    reference : dict or None
        :func:`slices.reference.compare`'s record.
    timings : dict
        Seconds per stage: ``read_time_s`` (reading the input into contours),
        ``surface_time_s`` (from the contours in memory to the bodies' meshes: chaining, bodies,
        fold checks), ``union_time_s`` (the bodies united, or the composition with the
        other ROIs: their reading included) and ``reference_time_s``. The libraries the surface
        and union stages call are loaded before the clocks start
        (:data:`slices.pipeline.STAGE_MODULES`): the stages time their work, not imports.
    checks : dict, optional
        ``watertight`` and ``oriented`` of ``mesh`` when the caller has checked them
        already (:meth:`surfaces.mesh.TriangleMesh.is_watertight`, ``is_oriented``);
        checked here otherwise.

    Returns
    -------
    dict
        Input, options, volume, area, slab volume, the volume under each end-slice
        convention (``volume_by_caps_mm3``: none, flat, half, slab) and their range
        (``volume_range_mm3``), the volume's sensitivity to a 0.5 mm contour offset
        (``volume_sensitivity_mm3_per_0.5mm`` and its method), counts, mesh checks,
        bodies (``surface_path`` of the structure and of every body row: ``"coons"``, the seed's
        patches, or ``"implicit"``, :mod:`slices.implicit`, whose rows are the connected parts),
        chaining, notes, ``contour_repairs`` (the contours repaired into simple polygons, each
        with its area change, :attr:`slices.io.ContourStack.repairs`), timings; ``composition`` and
        ``reference_bspline`` when given.
        ``area_mm2`` is the area of the solid's true surface (``area_source`` says which):
        the patches' (Gauss-Legendre) for one body or bodies left side by side; the
        written triangle mesh's when the bodies were united (``union``), so walls where
        bodies touch no longer count, while the walls of cavities (holes inside the
        solid) do, being surface of the solid. ``bodies_area_mm2`` is always the sum
        over the bodies' patches (shared caps and walls counted on both sides).
        With a composition, ``volume_mm3``, ``volume_ml`` and ``area_mm2`` are the
        composed solid's (``volume_source`` says which); the base ROI's own figures
        are under ``composition.base``.
    """
    opts = rec.options
    if checks is None:
        checks = {"watertight": mesh.is_watertight(), "oriented": mesh.is_oriented()}
    table = body_table(rec)
    n_out = sum(b["kind"] == "outer" for b in table)
    by_caps = rec.volume_by_caps()
    whole = volume_uncertainty(stack.contours, rec.spacing)
    by_caps["trend"] = whole["volume_mm3"]
    trend = opts.caps == "trend" and composition is None
    volume = rec.volume_mm3 if composition is None else composition["result_volume_mm3"]
    if trend:
        volume = whole["volume_mm3"]
    if composition is not None:
        area, area_source = composition["area_mm2"], "composition"
    elif rec.implicit is not None:
        area, area_source = rec.area_mm2, "implicit surface"
    elif union:
        area, area_source = mesh.surface_area(), "united solid"
    else:
        area, area_source = rec.area_mm2, "patches"
    summary = {
        "input": str(input_path),
        "source": stack.source,
        "roi": stack.name,
        "method": opts.method,
        "caps": opts.caps,
        "rays": opts.n_rays,
        "correspondence": opts.correspondence,
        "ray_start": "auto" if opts.start_angle is None else float(np.degrees(opts.start_angle)),
        "volume_mm3": volume,
        "volume_ml": volume / 1000.0,
        "area_mm2": area,
        "area_source": area_source,
        "bodies_area_mm2": rec.area_mm2,
        "volume_source": ("composition" if composition is not None else "area trend" if trend else
                          "implicit surface" if rec.implicit is not None else "patches"),
        "surface_path": rec.surface_path,
        "volume_caps": volume_caps_text(opts.caps, composition is not None),
        "surface_volume_mm3": rec.volume_mm3,
        "volume_U_mm3": whole["U_mm3"] if trend else None,
        "volume_k": 2,
        "volume_uncertainty": {**{k: v for k, v in whole.items() if k != "model"}, "model": whole["model"],
                               "applies_to": "the area-trend volume (volume_by_caps_mm3.trend)",
                               "pixel_note": PIXEL_NOTE},
        "area_U_mm2": None,
        "area_uncertainty": None,
        "slab_volume_mm3": rec.slab_volume_mm3,
        "slab_volume_ml": rec.slab_volume_mm3 / 1000.0,
        "volume_by_caps_mm3": by_caps,
        "volume_range_mm3": [min(by_caps.values()), max(by_caps.values())],
        f"volume_sensitivity_mm3_per_{SENSITIVITY_OFFSET_MM:g}mm": rec.sensitivity_mm3,
        "volume_sensitivity_method": (
            f"every contour offset outward by {SENSITIVITY_OFFSET_MM:g} mm (holes shrink): per contour "
            "perimeter x offset + pi x offset^2 (Steiner's formula), planes summed as the slab volume counts "
            "them (end planes half)"),
        "spacing_mm": rec.spacing,
        "n_slices": int(len(stack.planes)),
        "n_contours": len(stack.contours),
        "n_bodies": len(table),
        "n_outer_bodies": int(n_out),
        "n_hole_bodies": int(len(table) - n_out),
        "n_patches": int(sum(b.patches.n_patches for b in rec.bodies)),
        "n_control_points": int(sum(b.n_points for b in rec.bodies)),
        "max_control_point_deviation_mm": rec.max_deviation_mm,
        "mesh_vertices": int(mesh.n_vertices),
        "mesh_triangles": int(mesh.n_triangles),
        "mesh_watertight": bool(checks["watertight"]),
        "mesh_oriented": bool(checks["oriented"]),
        "mesh_union": union,
        "bodies": table,
        "chaining": chaining_text(rec),
        "notes": list(stack.notes) + (list(whole["model"]["notes"]) if trend else []) + caps_notes(rec),
        "contour_repairs": list(stack.repairs),
        **timings,
    }
    if composition is None:
        ua = area_uncertainty(stack.contours, area, rec.spacing)
        summary["area_U_mm2"], summary["area_uncertainty"] = ua["U_mm2"], {**ua, "pixel_note": PIXEL_NOTE}
    if composition is not None:
        summary["composition"] = composition
        summary["notes"].append(
            f"surface.ply/.stl, volume_mm3, volume_ml and area_mm2 are the composition {composition['operation']} "
            "(triangle meshes); slab volume, counts, chaining and patches.npz are the base ROI's")
    if reference is not None:
        summary["reference_bspline"] = reference
    return summary
