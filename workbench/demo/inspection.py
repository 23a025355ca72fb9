"""Demo section 1: a synthetic plate with defects, from rendered triad to Bezier surface and measured defects."""

from __future__ import annotations

import json

import numpy as np
from scipy import ndimage

from datasets_synthetic.render import make_triad_folder
from photometric.io import read_folder
from photometric.normals import angular_error_deg
from photometric.uncertainty import Tolerances
from surfaces.fit import fit_height
from surfaces.fit_mesh import fit_mesh
from surfaces.grid import xy_to_pixel
from surfaces.io import read_mesh
from surfaces.mixed import MixedPatches
from surfaces.render import render
from workbench import images as im
from workbench.demo.context import Context
from workbench.demo.meshes import heightfield_mesh
from workbench.runs.photometric import reconstruct_to_folder
from workbench.studies.uncertainty import FIGURE_LABELS, draw_budget, uncertainty_budget

#: light direction of the ray-cast pictures (from the upper left, towards the camera)
PICTURE_LIGHT = (-0.45, 0.5, 0.74)
#: vertical exaggeration of the plate's pictures
EXAGGERATION = 10.0
#: the tolerances the inspector states: image noise (full scale, the render's) and each
#: light's direction (deg per tangent axis)
STATED_NOISE = 0.005
STATED_LIGHT_TOLERANCE_DEG = 0.5


def match_defects(found: list[dict], truth: list[dict], pixel_size: float) -> list[dict]:
    """Pair each true defect with the nearest measured region, if it is near enough.

    Parameters
    ----------
    found : list of dict
        Measured regions (``defects.json``): ``center_px`` (row, col), ``max_depth_mm``,
        ``max_width_mm``, ``length_mm``, ``area_mm2``.
    truth : list of dict
        The scene's defects (``scene.json``): ``kind``, ``center_px``, ``depth_mm``,
        ``width_mm``, ``length_mm``, ``area_mm2``.
    pixel_size : float
        Pixel size in mm.

    Returns
    -------
    list of dict
        One per true defect: ``kind``, ``truth`` and ``measured`` (the nearest region
        when its centre lies within half the defect's larger extent, else None).

    Examples
    --------
    >>> truth = [{"kind": "dent", "center_px": [10, 10], "length_mm": 2.0, "width_mm": 2.0}]
    >>> [m["measured"] for m in match_defects([{"center_px": [10, 13]}], truth, 0.2)]
    [{'center_px': [10, 13]}]
    >>> [m["measured"] for m in match_defects([{"center_px": [10, 16]}], truth, 0.2)]
    [None]
    """
    matched = []
    for t in truth:
        cr, cc = t["center_px"]
        best = min(found, key=lambda d: np.hypot(d["center_px"][0] - cr, d["center_px"][1] - cc),
                   default=None)
        dist = (np.hypot(best["center_px"][0] - cr, best["center_px"][1] - cc) * pixel_size
                if best is not None else np.inf)
        near = best is not None and dist < 0.5 * max(t["length_mm"], t["width_mm"])
        matched.append({"kind": t["kind"], "truth": t, "measured": best if near else None})
    return matched


def defect_numbers(matched: list[dict]) -> list[dict]:
    """True and measured depth, width, length and area of each matched defect (``demo.json``).

    Parameters
    ----------
    matched : list of dict
        As returned by :func:`match_defects`.

    Returns
    -------
    list of dict
        ``kind`` and ``<quantity>_true_mm``/``<quantity>_measured_mm`` (``area_*_mm2``);
        measured values are None for a defect that was not found.
    """
    keys = (("depth", "depth_mm", "max_depth_mm"), ("width", "width_mm", "max_width_mm"),
            ("length", "length_mm", "length_mm"), ("area", "area_mm2", "area_mm2"))
    rows = []
    for d in matched:
        row = {"kind": d["kind"]}
        for name, true_key, measured_key in keys:
            unit = true_key.split("_")[-1]
            row[f"{name}_true_{unit}"] = d["truth"][true_key]
            row[f"{name}_measured_{unit}"] = d["measured"][measured_key] if d["measured"] else None
        rows.append(row)
    return rows


def section_inspection(ctx: Context) -> None:
    """Synthetic plate: triad render, photometric stereo, height, Bezier surface, defects.

    Parameters
    ----------
    ctx : Context
        The run; numbers go to ``ctx.numbers["inspection"]``, data to ``ctx.out/inspection``.
    """
    rep = ctx.report
    rep.section("1. Inspection: a plate with a crack, a dent and a scratch",
                "A synthetic 25.6 mm plate (datasets_synthetic.inspection_plate) with a V-crack, a "
                "spherical dent and a U-scratch, a textured albedo, rendered under three lights at "
                "45 deg slant, 120 deg apart, with cast shadows and 0.5 % noise (16-bit). The "
                "triad is solved by Lambertian photometric stereo (rho n = L^-1 I), the slopes "
                "are integrated into a height field (DCT Poisson solver), a bicubic Coons/Bezier "
                "surface is fitted through it and the defects are measured against the truth.")
    size, pixel = (128, 0.2) if ctx.quick else (512, 0.05)
    folder = ctx.out / "inspection" / "triad"
    nums: dict = {"size_px": size, "pixel_size_mm": pixel}
    ctx.numbers["inspection"] = nums
    scene = make_triad_folder(folder, scene="plate", size=size, pixel_size=pixel, lights=3,
                              slant=45.0, noise=0.005, shadows="cast", deviate=None, seed=0)
    ctx.step("inspection: triad rendered")
    triad_cmd = ctx.cmd("synth", "triad", "--scene", "plate", "--size", str(size), "--pixel-size",
                        str(pixel), "--deviate", "0,0,0", "--out", str(folder))
    height_gt = np.load(folder / "height_gt.npy")
    truth_mesh = heightfield_mesh(height_gt, pixel, exaggeration=EXAGGERATION)
    vsize = (800, 400) if ctx.quick else (1200, 560)
    pic = render(truth_mesh, ["iso", "top"], vsize, scalars=truth_mesh.vertices[:, 2] / EXAGGERATION,
                 colorbar_label="height mm", cmap="cividis", shadows=True, light=PICTURE_LIGHT)
    rep.figure(pic, "inspection-truth",
               "The plate's true height field, ray-cast with shadow rays (height exaggerated 10x; "
               "colour = true height in mm). Crack upper left, dent right, scratch at the bottom.",
               triad_cmd)
    recon = ctx.out / "inspection" / "reconstruction"
    recon_cmd = ctx.cmd("photometric", "reconstruct", str(folder), "--out", str(recon), "--noise-sigma",
                        str(STATED_NOISE), "--light-tolerance-deg", str(STATED_LIGHT_TOLERANCE_DEG))

    data = read_folder(folder)
    lights = np.asarray(scene["lights_nominal"], float)
    pics = [im.enlarge(im.to_uint8(img, vmax=1.0)) for img in data.images]
    slants = np.degrees(np.arccos(np.clip(lights[:, 2], -1, 1)))
    azim = np.degrees(np.arctan2(lights[:, 1], lights[:, 0]))
    labels = [f"light {k + 1}: slant {s:.0f}, azimuth {a:.0f} deg"
              for k, (s, a) in enumerate(zip(slants, azim))]
    rep.figure(im.montage(pics, cols=3, labels=labels), "inspection-images",
               "The three rendered images (16-bit PNG, shown linearly); the shadows are cast "
               "by the defects' walls.", triad_cmd)
    summary = reconstruct_to_folder(folder, recon, uncertainty=Tolerances(
        noise_sigma=STATED_NOISE, light_tolerance_deg=STATED_LIGHT_TOLERANCE_DEG))
    ctx.step("inspection: photometric pipeline")
    normals = np.load(recon / "normals.npy")
    albedo = np.load(recon / "albedo.npy")
    valid = np.load(recon / "valid.npy")
    p, q = np.load(recon / "p.npy"), np.load(recon / "q.npy")
    height = np.load(recon / "height.npy")
    err = np.where(valid, angular_error_deg(normals, data.normal_gt), np.nan)
    height = height - np.nanmean(height[valid])
    herr = np.where(valid, height - (height_gt - np.mean(height_gt[valid])), np.nan)
    nums.update(normal_error_mean_deg=float(np.nanmean(err)),
                normal_error_median_deg=float(np.nanmedian(err)),
                pipeline_mean_angular_error_deg=summary.get("mean_angular_error_deg"),
                pipeline_height_rmse_mm=summary.get("height_rmse_mm"),
                valid_fraction=float(valid.mean()),
                height_rms_error_mm=float(np.sqrt(np.nanmean(herr**2))),
                height_range_true_mm=float(np.ptp(height_gt)),
                pipeline_seconds=summary["timings_s"]["total"])
    tiles = [
        im.label_image(im.enlarge(im.albedo_image(albedo, valid)), "albedo"),
        im.label_image(im.enlarge(im.normal_map(normals, valid)), "normals, RGB = (n+1)/2"),
        im.label_image(im.enlarge(im.normal_map(data.normal_gt)), "true normals"),
    ]
    rep.figure(im.montage(tiles, cols=3), "inspection-normals",
               "Recovered albedo, recovered normal map and the true normal map "
               "(x to R, y up to G, z towards the camera to B).", recon_cmd)
    rep.figure(im.montage([
        im.error_image(err, valid, label="angle deg"),
        im.height_image(height, valid, label="height mm", cmap="cividis"),
        im.error_image(np.abs(herr), valid, label="|dz| mm", cmap="magma"),
    ], cols=3), "inspection-height",
        f"Angular error of the normals (mean {nums['normal_error_mean_deg']:.2f} deg), the "
        f"integrated height and its absolute error against the truth (RMS "
        f"{nums['height_rms_error_mm'] * 1000:.1f} um after removing the mean).", recon_cmd)
    mesh = read_mesh(recon / "surface.ply")
    nums["mesh_triangles"] = int(mesh.n_triangles)
    z_true = mesh.vertices[:, 2].copy()
    mesh.vertices[:, 2] *= EXAGGERATION
    pic = render(mesh, ["iso"], vsize, scalars=z_true, colorbar_label="height mm",
                 cmap="cividis", antialias=1 if ctx.quick else 2, light=PICTURE_LIGHT)
    sizes = summary.get("surface_patch_sizes_px", {})
    rep.figure(pic, "inspection-bezier",
               f"The bicubic Bezier surface fitted by least squares to the measured height and "
               f"slopes ({summary['n_patches']} patches of "
               f"{', '.join(f'{n} x {k} px' for k, n in sizes.items())}: smaller where a larger "
               f"patch missed the tolerance of {summary['surface_tolerance_mm'] * 1000:.1f} um, "
               f"largest deviation {summary['surface_max_dev_mm'] * 1000:.1f} um; surface.ply of "
               "the pipeline), ray-cast with height exaggerated 10x.", recon_cmd)
    fit = fit_height(height, p, q, mask=valid, pixel_size=pixel, tolerance=summary["surface_tolerance_mm"])
    nums["bezier_patches"] = int(fit.patches.n_patches)
    nums["surface_max_dev_um"] = 1000 * fit.max_deviation
    # |surface - height| at every vertex of the fitted mesh: the height bilinearly
    # interpolated at the vertex's pixel position
    fmesh = fit_mesh(fit, spacing=max(1.0, fit.step / 8))
    vr, vc = xy_to_pixel(fmesh.vertices[:, 0], fmesh.vertices[:, 1], height.shape, pixel)
    filled = np.where(valid, height, np.nanmean(height[valid]))
    dev_um = 1000 * np.abs(fmesh.vertices[:, 2] - ndimage.map_coordinates(filled, [vr, vc], order=1,
                                                                          mode="nearest"))
    fmesh.vertices[:, 2] *= EXAGGERATION
    pic = render(fmesh, ["iso", "top"], vsize, scalars=dev_um, colorbar_label="|dz| um",
                 cmap="magma", vmin=0.0, antialias=1 if ctx.quick else 2, light=PICTURE_LIGHT)
    rep.figure(pic, "inspection-deviation",
               f"Deviation |dz| of the fitted surface from the integrated height at the mesh vertices "
               f"(largest {nums['surface_max_dev_um']:.1f} um at the pixel centres, tolerance "
               f"{fit.tolerance * 1000:.1f} um); height exaggerated 10x. The largest deviations "
               "sit on the crack's floor and rim, kinks that no smooth patch follows exactly.",
               recon_cmd)
    shown = MixedPatches(fit.patches.control * np.array([1.0, 1.0, 3.0]), cells=fit.patches.cells)
    # a square window of the lattice around the crack (upper left of the plate)
    rows, cols = height.shape
    r0, c0, span = int(rows * 0.18), int(cols * 0.2), max(12, rows // 5)
    cells = shown.cells
    inside = ((cells[:, 0] >= r0) & (cells[:, 0] + cells[:, 2] <= r0 + span)
              & (cells[:, 1] >= c0) & (cells[:, 1] + cells[:, 2] <= c0 + span))
    crop = MixedPatches(shown.control[inside], cells=cells[inside] - [r0, c0, 0])
    pic = render(crop, ["top", "iso"], (1100, 480), net=True, samples=4, antialias=2, light=PICTURE_LIGHT)
    rep.figure(pic, "inspection-bezier-net",
               f"Detail around the crack: the {int(inside.sum())} fitted patches of a {span} x {span} "
               "pixel window with their Bezier control nets (seed 001's 'carcass') drawn over the "
               "ray-cast surface (height exaggerated 3x): large patches on the flat plate, smaller "
               "ones towards the crack, one-pixel patches (the dark band of dense nets) on it.",
               recon_cmd)
    ctx.step("inspection: Bezier surface")

    found = json.loads((recon / "defects.json").read_text())["defects"]
    matched = match_defects(found, scene["defects"], pixel)
    nums["defects"] = defect_numbers(matched)
    nums["defects_found"] = len(found)
    rep.table(["defect", "depth true (mm)", "depth measured (mm)", "width true (mm)",
               "max width measured (mm)", "length true (mm)", "length measured (mm)",
               "area true (mm2)", "area measured (mm2)"],
              [[d["kind"], *("not found" if v is None else v for k, v in d.items() if k != "kind")]
               for d in nums["defects"]],
              caption=f"Defects measured by the pipeline (photometric.defects.measure_defects on "
              f"the reconstructed height, {len(found)} region(s) found; defects.json) against "
              "the scene's truth (scene.json).", digits=3)
    section_uncertainty(ctx, recon, matched, recon_cmd)
    rep.table(["quantity", "value"], [
        ["mean angular error of the normals (deg)", nums["normal_error_mean_deg"]],
        ["median angular error (deg)", nums["normal_error_median_deg"]],
        ["valid pixels (fraction)", nums["valid_fraction"]],
        ["height RMS error (mm)", nums["height_rms_error_mm"]],
        ["true height range (mm)", nums["height_range_true_mm"]],
        ["Bezier patches", nums["bezier_patches"]],
        ["mesh triangles (surface.ply)", nums["mesh_triangles"]],
        ["pipeline time (s)", nums["pipeline_seconds"]],
    ], caption="Inspection accuracy against the synthetic truth.")


def section_uncertainty(ctx: Context, recon, matched: list[dict], command: str) -> None:
    """The measured defects with their expanded uncertainty (k = 2) and the deepest one's budget chart.

    Parameters
    ----------
    ctx : Context
        The run; ``ctx.numbers["inspection"]["uncertainty"]`` gets, per matched defect,
        ``kind``, ``id`` and ``text`` (figure -> ``"0.100 ± 0.006 mm (k = 2)"``).
    recon : Path
        The reconstruction folder (written with stated tolerances: ``uncertainty.json``).
    matched : list of dict
        :func:`match_defects` of the folder's defects.
    command : str
        The command line of the reconstruction.
    """
    import matplotlib.pyplot as plt

    budget = uncertainty_budget(recon)
    by_id = {row["id"]: row for row in budget["defects"]}
    rows, nums = [], []
    for m in matched:
        row = by_id.get(m["measured"]["id"]) if m["measured"] else None
        if row is None:
            rows.append([m["kind"], *["not found"] * len(FIGURE_LABELS)])
            continue
        nums.append({"kind": m["kind"], "id": row["id"], "text": row["text"]})
        rows.append([m["kind"], *(row["text"][f] for f in FIGURE_LABELS)])
    ctx.numbers["inspection"]["uncertainty"] = nums
    tol = budget["tolerances"]
    ctx.report.table(["defect", *(f"{label} ({unit})" for label, unit in FIGURE_LABELS.values())], rows,
                     caption=f"The measured defects with their expanded uncertainty U (k = 2, about 95 %; GUM) "
                     f"under the stated tolerances: image noise {budget['noise_sigma']:g} (full scale), "
                     f"{tol['light_tolerance_deg']:g} deg per light direction; {budget['method']} propagation "
                     "(defects.json, uncertainty.json).")
    deepest = budget["defects"][0]
    kind = next((r["kind"] for r in nums if r["id"] == deepest["id"]), deepest["kind"])
    fig = draw_budget(uncertainty_budget(recon, defect=deepest["id"])["budget"],
                      f"Uncertainty budget of the deepest defect ({kind.replace('_', ' ')}), k = 2")
    fig.canvas.draw()
    picture = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    ctx.report.figure(picture, "inspection-budget",
                      "Uncertainty budget of the deepest defect: each source's share of the combined "
                      "variance u_c^2 of each figure (image noise, light directions, the pixel grid's "
                      "discretisation and the measures' own bias), with the value and U (k = 2) beside "
                      "each bar (workbench.studies.uncertainty.draw_budget).", command)
