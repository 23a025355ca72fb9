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
from surfaces.io import read_mesh, write_mesh
from surfaces.render import render
from workbench import images as im
from workbench.demo.context import Context
from workbench.demo.figures import Source, drawer
from workbench.images import COLORBAR_PX
from workbench.report import REPORT_WIDTH_PX
from workbench.demo.meshes import heightfield_mesh
from workbench.runs.photometric import reconstruct_to_folder
from workbench.studies.uncertainty import FIGURE_LABELS, draw_budget, uncertainty_budget

#: light direction of the ray-cast pictures (from the upper left, towards the camera)
PICTURE_LIGHT = (-0.45, 0.5, 0.74)
#: vertical exaggeration of the plate's pictures
EXAGGERATION = 10.0
#: vertical exaggeration of the fitted surface's picture: its tessellation's facets on the crack's
#: walls alias into a rib texture at 10x
BEZIER_EXAGGERATION = 3.0
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


def height_errors(recon, triad) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angular error of the normals, the height and its error against the truth, from the run's folders.

    Parameters
    ----------
    recon : path-like
        The reconstruction folder (``normals.npy``, ``valid.npy``, ``height.npy``).
    triad : path-like
        The synthetic triad folder (ground truth: ``normal_gt.npy``, ``height_gt.npy``).

    Returns
    -------
    err_deg, height_mm, height_error_mm : (H, W) float arrays
        NaN outside the valid pixels; both heights with their mean over the valid pixels removed.
    """
    from pathlib import Path

    recon, triad = Path(recon), Path(triad)
    valid = np.load(recon / "valid.npy")
    normal_gt = read_folder(triad).normal_gt
    height_gt = np.load(triad / "height_gt.npy")
    err = np.where(valid, angular_error_deg(np.load(recon / "normals.npy"), normal_gt), np.nan)
    height = np.load(recon / "height.npy")
    height = height - np.nanmean(height[valid])
    herr = np.where(valid, height - (height_gt - np.mean(height_gt[valid])), np.nan)
    return err, height, herr


def crack_profile(crack: dict, truth: np.ndarray, height: np.ndarray, surface: np.ndarray,
                  pixel_size: float) -> dict:
    """Height profiles across a crack at its centre, levelled on the plate beside it.

    Parameters
    ----------
    crack : dict
        The scene's crack (``center_mm`` (x, y), ``axis_deg`` in the x-y plane, ``width_mm``).
    truth, height, surface : (H, W) float arrays
        True height, integrated height and the fitted surface at the pixel centres (mm; NaN allowed).
    pixel_size : float
        mm per pixel.

    Returns
    -------
    dict
        ``s_mm`` (N,) position across the crack, ``true_mm``, ``height_mm``, ``surface_mm`` (N,)
        each minus its median beyond 1.5 widths, ``depth_*_mm``: minus each profile's minimum,
        ``max_dev_height_um`` (integrated height against truth), ``max_dev_surface_um`` (surface
        against integrated height) and ``stretch``, the height axis' exaggeration in the plot.
    """
    w = float(crack["width_mm"])
    s = np.linspace(-2.5 * w, 2.5 * w, 501)
    a = np.deg2rad(float(crack["axis_deg"]))
    x = crack["center_mm"][0] - s * np.sin(a)
    y = crack["center_mm"][1] + s * np.cos(a)
    rows, cols = xy_to_pixel(x, y, truth.shape, pixel_size)
    out = {"s_mm": s}
    outside = np.abs(s) > 1.5 * w
    for key, field in (("true", truth), ("height", height), ("surface", surface)):
        vals = ndimage.map_coordinates(np.asarray(field, float), [rows, cols], order=1, mode="nearest",
                                       cval=np.nan)
        vals = vals - np.nanmedian(vals[outside])
        out[f"{key}_mm"] = vals
        out[f"depth_{key}_mm"] = float(-np.nanmin(vals))
    out["max_dev_height_um"] = float(1000 * np.nanmax(np.abs(out["height_mm"] - out["true_mm"])))
    out["max_dev_surface_um"] = float(1000 * np.nanmax(np.abs(out["surface_mm"] - out["height_mm"])))
    # the plot is about 2.5 times wider than tall: how much the height axis is stretched
    out["stretch"] = float((s[-1] - s[0]) / max(out["depth_true_mm"], 1e-12) / 2.5)
    return out


def _in_a_row(tiles: list) -> list:
    """The pictures shrunk (area average) so that one row of them fits the report's column at its own size."""
    side = (REPORT_WIDTH_PX + 4) // len(tiles) - 4
    return [im.fit(t, side) for t in tiles]


@drawer
def truth_view(src: Source, triad: str, pixel_size: float, exaggeration: float, size: list) -> np.ndarray:
    """The true height field ray-cast (iso and top views, shadow rays, 2 x 2 rays per pixel)."""
    height_gt = np.load(src.path(triad) / "height_gt.npy")
    mesh = heightfield_mesh(height_gt, pixel_size, exaggeration=exaggeration)
    return render(mesh, ["iso", "top"], tuple(size), scalars=mesh.vertices[:, 2] / exaggeration,
                  colorbar_label="height mm", cmap="cividis", shadows=True, light=PICTURE_LIGHT, antialias=2)


@drawer
def images_montage(src: Source, triad: str, labels: list) -> np.ndarray:
    """The rendered images side by side, linear grey."""
    data = read_folder(src.path(triad))
    tiles = _in_a_row([im.enlarge(im.to_uint8(img, vmax=1.0)) for img in data.images])
    return im.montage(tiles, cols=len(tiles), labels=labels)


@drawer
def normals_montage(src: Source, triad: str, recon: str) -> np.ndarray:
    """Recovered albedo, recovered normals and the true normals."""
    folder = src.path(recon)
    valid = np.load(folder / "valid.npy")
    tiles = [
        im.enlarge(im.albedo_image(np.load(folder / "albedo.npy"), valid)),
        im.enlarge(im.normal_map(np.load(folder / "normals.npy"), valid)),
        im.enlarge(im.normal_map(read_folder(src.path(triad)).normal_gt)),
    ]
    return im.montage(_in_a_row(tiles), cols=len(tiles), labels=["albedo", "normals, RGB = (n+1)/2", "true normals"])


@drawer
def height_maps(src: Source, triad: str, recon: str) -> np.ndarray:
    """Angular error, integrated height and its absolute error (see :func:`height_errors`)."""
    err, height, herr = height_errors(src.path(recon), src.path(triad))
    # two maps with their colour bars side by side within the report's width (labels at their own size)
    side = (REPORT_WIDTH_PX - 4) // 2 - COLORBAR_PX
    err, height, herr = (im.fit(a, side) for a in (err, height, herr))
    valid = np.isfinite(err)
    return im.montage([
        im.error_image(err, valid, label="angle deg"),
        im.height_image(height, valid, label="height mm", cmap="cividis"),
        im.error_image(np.abs(herr), valid, label="|dz| mm", cmap="magma"),
    ], cols=2)


@drawer
def bezier_view(src: Source, recon: str, exaggeration: float, size: list) -> np.ndarray:
    """The pipeline's ``surface.ply`` ray-cast, iso and top, 3 x 3 rays per pixel, coloured by height."""
    mesh = read_mesh(src.path(recon) / "surface.ply")
    z_true = mesh.vertices[:, 2].copy()
    mesh.vertices[:, 2] *= exaggeration
    return render(mesh, ["iso", "top"], tuple(size), scalars=z_true, colorbar_label="height mm",
                  cmap="cividis", antialias=3, light=PICTURE_LIGHT)


@drawer
def deviation_view(src: Source, mesh: str, exaggeration: float, size: list, dev_um: np.ndarray) -> np.ndarray:
    """The fitted mesh coloured by its deviation from the integrated height (um), unshaded."""
    fmesh = read_mesh(src.path(mesh))
    fmesh.vertices[:, 2] *= exaggeration
    return render(fmesh, ["iso", "top"], tuple(size), scalars=np.asarray(dev_um, float), colorbar_label="|dz| um",
                  cmap="magma", vmin=0.0, antialias=2, ambient=1.0, diffuse=0.0, specular=0.0)


@drawer
def profile_plot(src: Source, width_mm: float, s_mm: np.ndarray, true_mm: np.ndarray, height_mm: np.ndarray,
                 surface_mm: np.ndarray) -> np.ndarray:
    """The crack's profiles (see :func:`crack_profile`), mm on both axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 3.6), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot(s_mm, true_mm, color="0.2", lw=2.2, label="true height")
    ax.plot(s_mm, height_mm, color="tab:blue", lw=1.4, label="integrated height (pixel centres, bilinear)")
    ax.plot(s_mm, surface_mm, color="tab:orange", lw=1.2, ls="--", label="fitted Bezier surface")
    ax.axvspan(-width_mm / 2, width_mm / 2, color="0.92", zorder=0, label=f"true width {width_mm:.3f} mm")
    ax.set_xlabel("position across the crack (mm)", fontsize=11)
    ax.set_ylabel("height (mm)", fontsize=11)
    ax.tick_params(labelsize=10)
    ax.grid(True, color="0.85", lw=0.6)
    ax.legend(fontsize=9, loc="lower right")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


@drawer
def budget_chart(src: Source, budget: dict, title: str) -> np.ndarray:
    """The uncertainty budget chart of one defect (:func:`workbench.studies.uncertainty.draw_budget`)."""
    import matplotlib.pyplot as plt

    fig = draw_budget(budget, title)
    fig.canvas.draw()
    picture = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return picture


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
    vsize = (800, 400) if ctx.quick else (REPORT_WIDTH_PX, 540)
    ctx.figure("inspection-truth", truth_view,
               f"The plate's true height field, ray-cast with shadow rays (height exaggerated "
               f"{EXAGGERATION:g}x, 2 x 2 rays per pixel; colour = true height in mm). Crack upper left, dent "
               "right, scratch at the bottom.",
               triad_cmd, params={"triad": ctx.rel(folder), "pixel_size": pixel, "exaggeration": EXAGGERATION,
                                  "size": list(vsize)})
    recon = ctx.out / "inspection" / "reconstruction"
    recon_cmd = ctx.cmd("photometric", "reconstruct", str(folder), "--out", str(recon), "--noise-sigma",
                        str(STATED_NOISE), "--light-tolerance-deg", str(STATED_LIGHT_TOLERANCE_DEG))

    lights = np.asarray(scene["lights_nominal"], float)
    slants = np.degrees(np.arccos(np.clip(lights[:, 2], -1, 1)))
    azim = np.degrees(np.arctan2(lights[:, 1], lights[:, 0]))
    labels = [f"light {k + 1}: slant {s:.0f}, azimuth {a:.0f} deg"
              for k, (s, a) in enumerate(zip(slants, azim))]
    ctx.figure("inspection-images", images_montage,
               "The three rendered images (16-bit PNG, shown linearly); the shadows are cast "
               "by the defects' walls.", triad_cmd, params={"triad": ctx.rel(folder), "labels": labels})
    summary = reconstruct_to_folder(folder, recon, uncertainty=Tolerances(
        noise_sigma=STATED_NOISE, light_tolerance_deg=STATED_LIGHT_TOLERANCE_DEG))
    ctx.step("inspection: photometric pipeline")
    valid = np.load(recon / "valid.npy")
    p, q = np.load(recon / "p.npy"), np.load(recon / "q.npy")
    err, height, herr = height_errors(recon, folder)
    nums.update(normal_error_mean_deg=float(np.nanmean(err)),
                normal_error_median_deg=float(np.nanmedian(err)),
                pipeline_mean_angular_error_deg=summary.get("mean_angular_error_deg"),
                pipeline_height_rmse_mm=summary.get("height_rmse_mm"),
                valid_fraction=float(valid.mean()),
                height_rms_error_mm=float(np.sqrt(np.nanmean(herr**2))),
                height_range_true_mm=float(np.ptp(height_gt)),
                pipeline_seconds=summary["timings_s"]["total"])
    ctx.figure("inspection-normals", normals_montage,
               "Recovered albedo, recovered normal map and the true normal map "
               "(x to R, y up to G, z towards the camera to B).", recon_cmd,
               params={"triad": ctx.rel(folder), "recon": ctx.rel(recon)})
    ctx.figure("inspection-height", height_maps,
               f"Angular error of the normals (mean {nums['normal_error_mean_deg']:.2f} deg), the "
               f"integrated height and its absolute error against the truth (RMS "
               f"{nums['height_rms_error_mm'] * 1000:.1f} um after removing the mean).", recon_cmd,
               params={"triad": ctx.rel(folder), "recon": ctx.rel(recon)})
    sizes = summary.get("surface_patch_sizes_px", {})
    ctx.figure("inspection-bezier", bezier_view,
               f"The bicubic Bezier surface fitted by least squares to the measured height and "
               f"slopes ({summary['n_patches']} patches of "
               f"{', '.join(f'{n} x {k} px' for k, n in sizes.items())}: smaller where a larger "
               f"patch missed the tolerance of {summary['surface_tolerance_mm'] * 1000:.1f} um, "
               f"largest deviation {summary['surface_max_dev_mm'] * 1000:.1f} um; surface.ply of "
               f"the pipeline), ray-cast with the height exaggerated {BEZIER_EXAGGERATION:g}x and 3 x 3 rays "
               "per pixel (at 10x, one ray per pixel aliases the crack's steep facets into a rib texture); "
               "colour = height in mm, read it in the top view, where no wall hides a floor.", recon_cmd,
               params={"recon": ctx.rel(recon), "exaggeration": BEZIER_EXAGGERATION, "size": list(vsize)})
    nums["mesh_triangles"] = int(read_mesh(recon / "surface.ply").n_triangles)
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
    fitted = write_mesh(fmesh, ctx.out / "inspection" / "fitted_surface.ply")
    ctx.figure("inspection-deviation", deviation_view,
               f"Deviation |dz| of the fitted surface from the integrated height at the mesh vertices "
               f"(largest {nums['surface_max_dev_um']:.1f} um at the pixel centres, tolerance "
               f"{fit.tolerance * 1000:.1f} um); height exaggerated {BEZIER_EXAGGERATION:g}x, 2 x 2 rays per "
               "pixel, drawn unshaded so that the colour is the deviation alone. "
               "The largest deviations sit on the crack's floor and rim, kinks that no smooth patch "
               "follows exactly.", recon_cmd,
               params={"mesh": ctx.rel(fitted), "exaggeration": BEZIER_EXAGGERATION, "size": list(vsize)},
               arrays={"dev_um": dev_um})
    crack = next((d for d in scene["defects"] if d["kind"] == "v_crack"), None)
    if crack is not None:
        prof = crack_profile(crack, height_gt, height, fit.surface[..., 2], pixel)
        nums["crack_profile"] = {k: v for k, v in prof.items() if not k.endswith("_mm") or k.startswith("depth")}
        ctx.figure("inspection-crack-profile", profile_plot,
                   f"Profile across the crack at its centre, both axes in mm (the height axis stretched "
                   f"about {prof['stretch']:.0f}x): the true height sampled at the pixel centres (deepest "
                   f"{prof['depth_true_mm']:.4f} mm; the scene's V is {crack['depth_mm']:.4f} mm deep at its "
                   f"exact floor line, between pixel centres), the height integrated from the normals "
                   f"({prof['depth_height_mm']:.4f} mm) and the fitted Bezier surface "
                   f"({prof['depth_surface_mm']:.4f} mm), each levelled on the plate beyond 1.5 crack widths. "
                   f"Along the profile the integrated height stays within {prof['max_dev_height_um']:.1f} um of "
                   f"the truth and the surface within {prof['max_dev_surface_um']:.1f} um of the integrated "
                   f"height; pixels are {pixel:g} mm.",
                   recon_cmd, params={"width_mm": crack["width_mm"]},
                   arrays={k: prof[k] for k in ("s_mm", "true_mm", "height_mm", "surface_mm")})
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
    ctx.figure("inspection-budget", budget_chart,
               "Uncertainty budget of the deepest defect: each source's share of the combined "
               "variance u_c^2 of each figure (image noise, light directions, the pixel grid's "
               "discretisation and the measures' own bias), with the value and U (k = 2) beside "
               "each bar (workbench.studies.uncertainty.draw_budget).", command,
               params={"budget": uncertainty_budget(recon, defect=deepest["id"])["budget"],
                       "title": f"Uncertainty budget of the deepest defect ({kind.replace('_', ' ')}), k = 2"})
