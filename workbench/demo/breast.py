"""Demo section 4b: structures of the real breast RT structure set beside other systems' volumes."""

from __future__ import annotations

import numpy as np

from slices.summary import count_noun
from surfaces.io import read_mesh
from surfaces.mesh import TriangleMesh, merge_meshes
from surfaces.render import render
from workbench.demo.context import Context
from workbench.demo.figures import Source, drawer
from workbench.runs.slices import reconstruct_to_folder

#: the Heart's volume (cc) by other systems, from the same contours
HEART_REFERENCE_CC = {"dicompyler-core (polygon areas, end planes half)": 432.84,
                      "treatment planning system DVH": 437.46,
                      "dicompyler-core (rasterised on dose grid)": 440.23}
#: the Lt Lung's volume (cc) by dicompyler-core
LUNG_REFERENCE_CC = {"dicompyler-core (polygon areas, holes subtracted)": 1995.18}
REFERENCES_CC = {"Heart": HEART_REFERENCE_CC, "Lt Lung": LUNG_REFERENCE_CC}
#: display colour of each structure (RGB in [0, 1])
PALETTE = {"Heart": (0.85, 0.35, 0.35), "Lt Lung": (0.55, 0.7, 0.9)}


def roi_folder(ctx: Context, roi: str):
    """Output folder of one structure: ``ctx.out/ct/<roi in lower case, spaces as _>``."""
    return ctx.out / "ct" / roi.lower().replace(" ", "_")


def _outline_facts(rtss, roi: str, folder) -> dict:
    """What the caption says about a structure's shape: bodies and holes, contours cut along one x plane."""
    import json

    from slices.io import read_rtstruct

    bodies = json.loads((folder / "summary.json").read_text()).get("bodies", [])
    stack = read_rtstruct(rtss, roi)
    x_min = min(float(c.points[:, 0].min()) for c in stack.contours)
    # a contour with a run of >= 5 vertices within 1 mm of the structure's smallest x: a straight cut
    straight = sum(int(np.sum(np.abs(c.points[:, 0] - x_min) < 1.0) >= 5) for c in stack.contours)
    return {"n_outer": sum(b.get("kind") == "outer" for b in bodies),
            "n_holes": sum(b.get("kind") == "hole" for b in bodies),
            "straight_wall_contours": straight, "straight_wall_x_mm": x_min}


@drawer
def breast_view(src: Source, meshes: list, colors: list) -> np.ndarray:
    """The structures' surfaces in their colours, front and left views."""
    parts, rgb = [], []
    for path, color in zip(meshes, colors):
        m = read_mesh(src.path(path))
        parts.append(TriangleMesh(m.vertices, m.triangles, m.vertex_normals, None))
        rgb.append(np.broadcast_to(np.asarray(color, float), m.vertices.shape))
    return render(merge_meshes(parts), ["front", "left"], (1000, 520), colors=np.concatenate(rgb))


def section_breast(ctx: Context) -> None:
    """The breast structure set's Heart (and Lt Lung) against the reference volumes.

    Parameters
    ----------
    ctx : Context
        The run; reads ``ctx.shared/rtstruct_breast/rtss.dcm`` (reported as not
        available when absent), numbers go to ``ctx.numbers["ct"][roi]``.
    """
    rep = ctx.report
    nums = ctx.numbers.setdefault("ct", {})
    rtss = ctx.shared / "rtstruct_breast" / "rtss.dcm"
    if not rtss.is_file():
        ctx.missing("CT: breast structure set",
                    "the real structure set rtstruct_breast/rtss.dcm is absent (set WORKBENCH_SHARED_DATA)")
        return
    rois = ["Heart"] if ctx.quick else ["Heart", "Lt Lung"]
    rays = 32 if ctx.quick else 64
    rows = []
    for roi in rois:
        # default caps (trend): the whole structure, as the references count it (not between the end planes only)
        s = reconstruct_to_folder(rtss, roi_folder(ctx, roi), roi=roi, render=False,
                                  reference=False, rays=rays, samples=2 if roi == "Lt Lung" else 3)
        ctx.step(f"ct: {roi} reconstructed")
        refs = REFERENCES_CC[roi]
        nums[roi] = {"volume_cc": s["volume_ml"], "slab_volume_cc": s["slab_volume_ml"], "caps": s["caps"],
                     "volume_U_cc": s["volume_U_mm3"] / 1000, "volume_caps": s["volume_caps"],
                     "n_contours": s["n_contours"], "n_bodies": s["n_bodies"],
                     "surface_path": s.get("surface_path", "coons"),
                     "references_cc": refs}
        for name, ref in refs.items():
            rows.append([roi, s["n_contours"], s["volume_ml"], s["slab_volume_ml"], name, ref,
                         100 * (s["volume_ml"] / ref - 1)])
        if roi == "Lt Lung":
            nums[roi].update(_outline_facts(rtss, roi, roi_folder(ctx, roi)))
    if ctx.quick:
        rep.note("--quick: only the Heart is reconstructed; the full run adds the Lt Lung "
                 "(165 contours on 80 planes, with holes).")
    lung = ""
    if "Lt Lung" in rois:
        ln = nums["Lt Lung"]
        parts = f"{count_noun(ln['n_outer'], 'outer part')} around {count_noun(ln['n_holes'], 'cavity', 'cavities')}"
        if ln.get("surface_path") == "implicit":
            lung = (f" The Lt Lung ({parts}) is one implicit surface (summary.json surface_path implicit): each "
                    "plane's contours as a signed distance, blended across the 3 mm planes with the seed's parabolic "
                    "weights and extracted by marching cubes; where a chain of contours starts or stops, the surface "
                    "closes half-way to the next plane. Its horizontal ribs are the outlines changing from plane to "
                    "plane; the fine relief within a plane is the contours' own small steps and the distance "
                    "field's pixel (summary.json bodies pixel_mm).")
        else:
            lung = (f" The Lt Lung's horizontal ledges are the ends of its {parts}: where a chain of contours "
                    "starts or stops between two 3 mm planes, the surface closes it with a cap on that contour and "
                    "does not invent shape between the planes.")
        if ln["straight_wall_contours"]:
            lung += (f" Its straight vertical edge on the left of 'front' is in the contours themselves: "
                     f"{ln['straight_wall_contours']} contours run straight along x = {ln['straight_wall_x_mm']:.1f}"
                     " mm.")
    ctx.figure("ct-breast", breast_view,
               "Structures of the real breast RT structure set reconstructed from their "
               f"contours: {' and '.join(rois)} (red: Heart, blue: Lt Lung; DICOM patient "
               "coordinates, x towards the patient's left, so 'front' is the anterior view "
               "and 'left' looks from the patient's right)." + lung,
               " && ".join(ctx.cmd("slices", "reconstruct", str(rtss), "--roi", roi, "--rays",
                                   str(rays), "--out", str(roi_folder(ctx, roi)))
                           for roi in rois),
               params={"meshes": [ctx.rel(roi_folder(ctx, roi) / "surface.ply") for roi in rois],
                       "colors": [list(PALETTE[roi]) for roi in rois]})
    rep.table(["structure", "contours", "our volume (cc, caps trend)", "our slab volume (cc, end planes half)",
               "reference", "reference volume (cc)", "difference (%)"], rows,
              caption="Volumes of the same contours beside other systems' figures. Ours: caps trend, the "
              "whole structure (section areas integrated between the planes, the structure beyond the end "
              "planes from the areas' trend; U (k = 2) in summary.json); our slab volume counts every contour "
              "a slab and the end planes half, the convention of dicompyler-core's polygon figure (like with "
              "like). The planning system's DVH and the dose-grid rasterisation count voxels, whose end slabs "
              "reach about half a spacing beyond the end planes. Planning systems disagree among themselves "
              "by about 1-5 %, mostly at the end slices.", digits=5)
