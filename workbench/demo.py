"""The end-to-end demo: every package on data it makes (or the shared real data), one HTML report.

``run_demo(out_dir)`` computes everything in the run (no precomputed results)
and writes ``out_dir/report.html`` (self-contained: figures embedded as data
URIs), the figures as PNG files in ``out_dir/figures/``, every number in
``out_dir/demo.json`` and the intermediate data (triad folder, phantom,
surfaces) in sub-folders. Sections:

1. Inspection: a synthetic plate with a crack, a dent and a scratch, rendered
   under three lights; photometric stereo, height by integration, the Bezier
   surface through it, and the defects measured against their truth.
2. Accuracy study: derivative-error maps against light deviations and the
   recommended deviation tolerances for that light set (seed 002a).
3. Real captures: DiLiGenT bear (``../shared/data/diligent_bear``), triad and
   all 14 images, normal maps and angular error beside the baseline figures.
4. CT: a folding kidney phantom reconstructed from contours (volume, surface
   distance) and the breast structure set's Heart and Lt Lung beside their
   reference volumes.
5. A table of every figure and the command that reproduces it.

A section whose package is missing (``ModuleNotFoundError`` for one of the
workbench's own packages) is reported as "not available: <reason>" and listed
under ``unavailable`` in the returned summary; any other error propagates.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench import images as im
from workbench.report import Report

OWN_PACKAGES = ("surfaces", "photometric", "slices", "datasets_synthetic", "workbench")
BEAR_BASELINE_DEG = {"triad": 11.74, "all14": 9.60}
BEAR_PUBLISHED_96_DEG = 8.39
HEART_REFERENCE_CC = {"dicompyler-core (polygon areas, end planes half)": 432.84,
                      "treatment planning system DVH": 437.46,
                      "dicompyler-core (rasterised on dose grid)": 440.23}
LUNG_REFERENCE_CC = {"dicompyler-core (polygon areas, holes subtracted)": 1995.18}
TOLERANCES = (0.01, 0.02, 0.05, 0.1)
RANGES = (0.5, 1.0, 2.0)


def shared_data_dir() -> Path:
    """The real-data folder: ``$WORKBENCH_SHARED_DATA`` or ``../shared/data`` beside the repository."""
    env = os.environ.get("WORKBENCH_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "shared" / "data"


@dataclass
class Context:
    """State shared by the demo sections."""

    out: Path
    quick: bool
    shared: Path
    report: Report
    numbers: dict = field(default_factory=dict)
    unavailable: dict = field(default_factory=dict)
    bar: object = None

    def step(self, text: str) -> None:
        """Advance the progress bar by one step."""
        if self.bar is not None:
            self.bar.set_postfix_str(text[:40])
            self.bar.update(1)

    def cmd(self, *words: str) -> str:
        """The command line ``workbench <words>``, checked against the parser.

        Returns the command when the sub-command and every ``--option`` exist,
        otherwise the demo's own command (so the table never names a command
        that does not exist).
        """
        if _command_exists(list(words)):
            return "workbench " + " ".join(words)
        return self.demo_cmd()

    def demo_cmd(self) -> str:
        return f"workbench demo --out {self.out}" + (" --quick" if self.quick else "")

    @contextlib.contextmanager
    def guard(self, what: str):
        """Report ``what`` as not available when one of our packages is missing."""
        try:
            yield
        except ModuleNotFoundError as exc:
            top = (exc.name or "").split(".")[0]
            if top not in OWN_PACKAGES:
                raise
            reason = f"module {exc.name} is not available"
            self.unavailable[what] = reason
            self.report.note(f"{what}: not available: {reason}")


@functools.lru_cache(maxsize=1)
def _parser():
    from workbench.cli import build_parser

    return build_parser()


def _command_exists(words: list[str]) -> bool:
    """True when ``workbench <words>`` names an existing sub-command with existing options."""
    import argparse

    parser = _parser()
    i = 0
    while True:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            break
        if i >= len(words) or words[i] not in subs[0].choices:
            return False
        parser = subs[0].choices[words[i]]
        i += 1
    options = [w.split("=")[0] for w in words[i:] if w.startswith("--")]
    return all(o in parser._option_string_actions for o in options)


def heightfield_mesh(height: np.ndarray, pixel_size: float, mask: np.ndarray | None = None,
                     exaggeration: float = 1.0, step: int = 1):
    """Triangle mesh of a height field (x = col h, y = -row h, z = exaggeration * height).

    Parameters
    ----------
    height : (H, W) array_like
        Heights in mm; NaN pixels (or pixels outside ``mask``) are left out.
    pixel_size : float
        Pixel size in mm.
    mask : (H, W) bool, optional
        Pixels to keep.
    exaggeration : float
        Vertical scale factor for display.
    step : int
        Keep every ``step``-th row and column.

    Returns
    -------
    surfaces.mesh.TriangleMesh
        Two triangles per grid cell whose four corners are kept, counter-clockwise
        seen from +z.
    """
    from surfaces.mesh import TriangleMesh

    z = np.asarray(height, float)[::step, ::step]
    keep = np.isfinite(z)
    if mask is not None:
        keep &= np.asarray(mask, bool)[::step, ::step]
    rows, cols = z.shape
    r, c = np.mgrid[0:rows, 0:cols]
    verts = np.column_stack([c.ravel() * pixel_size * step, -r.ravel() * pixel_size * step,
                             np.nan_to_num(z).ravel() * exaggeration])
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    d, e = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    cell = (keep[:-1, :-1] & keep[:-1, 1:] & keep[1:, :-1] & keep[1:, 1:]).ravel()
    # rows run towards -y, so (a, d, b) is counter-clockwise seen from +z
    tris = np.concatenate([np.column_stack([a, d, b])[cell], np.column_stack([b, d, e])[cell]])
    used = np.unique(tris)
    remap = np.full(rows * cols, -1, np.int64)
    remap[used] = np.arange(len(used))
    return TriangleMesh(verts[used], remap[tris], None, None)


# ----------------------------------------------------------------------------- section 1


def section_inspection(ctx: Context) -> None:
    """Synthetic plate: triad render, photometric stereo, height, Bezier surface, defects."""
    from surfaces.render import render

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
    with ctx.guard("Inspection: synthetic triad"):
        from datasets_synthetic.render import make_triad_folder

        scene = make_triad_folder(folder, scene="plate", size=size, pixel_size=pixel, lights=3,
                                  slant=45.0, noise=0.005, shadows="cast", deviate=None, seed=0)
        ctx.step("inspection: triad rendered")
    if "Inspection: synthetic triad" in ctx.unavailable:
        return
    triad_cmd = ctx.cmd("synth", "triad", "--scene", "plate", "--size", str(size), "--pixel-size",
                        str(pixel), "--deviate", "0,0,0", "--out", str(folder))
    height_gt = np.load(folder / "height_gt.npy")
    truth_mesh = heightfield_mesh(height_gt, pixel, exaggeration=10.0, step=1 if ctx.quick else 2)
    vsize = (800, 400) if ctx.quick else (1200, 560)
    pic = render(truth_mesh, ["iso", "top"], vsize, scalars=truth_mesh.vertices[:, 2] / 10.0,
                      colorbar_label="height mm", cmap="cividis", shadows=True,
                      light=(-0.45, 0.5, 0.74))
    rep.figure(pic, "inspection-truth",
               "The plate's true height field, ray-cast with shadow rays (height exaggerated 10x; "
               "colour = true height in mm). Crack upper left, dent right, scratch at the bottom.",
               triad_cmd)
    recon = ctx.out / "inspection" / "reconstruction"
    recon_cmd = ctx.cmd("photometric", "reconstruct", str(folder), "--out", str(recon))
    with ctx.guard("Inspection: photometric stereo"):
        from scipy import ndimage

        from photometric.io import read_folder
        from photometric.normals import angular_error_deg
        from surfaces.fit import fit_height, fit_mesh
        from surfaces.grid import xy_to_pixel
        from surfaces.io import read_mesh
        from surfaces.mixed import MixedPatches
        from workbench.runs.photometric import reconstruct_to_folder

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
        summary = reconstruct_to_folder(folder, recon)
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
        mesh.vertices[:, 2] *= 10.0
        pic = render(mesh, ["iso"], vsize, scalars=z_true, colorbar_label="height mm",
                          cmap="cividis", antialias=1 if ctx.quick else 2, light=(-0.45, 0.5, 0.74))
        sizes = summary.get("surface_patch_sizes_px", {})
        rep.figure(pic, "inspection-bezier",
                   f"The bicubic Bezier surface fitted by least squares to the measured height and "
                   f"slopes ({summary['n_patches']} patches of "
                   f"{', '.join(f'{n} x {k} px' for k, n in sizes.items())}: smaller where a larger "
                   f"patch missed the tolerance of {summary['surface_tolerance_mm'] * 1000:.1f} um, "
                   f"largest deviation {summary['surface_max_dev_mm'] * 1000:.1f} um; surface.ply of "
                   "the pipeline), ray-cast with height exaggerated 10x.", recon_cmd)
        fit = fit_height(height, p, q, mask=valid, pixel_size=pixel,
                         tolerance=summary["surface_tolerance_mm"])
        nums["bezier_patches"] = int(fit.patches.n_patches)
        nums["surface_max_dev_um"] = 1000 * fit.max_deviation
        # |surface - height| at every vertex of the fitted mesh: the height bilinearly
        # interpolated at the vertex's pixel position
        fmesh = fit_mesh(fit, spacing=max(1.0, fit.step / 8))
        vr, vc = xy_to_pixel(fmesh.vertices[:, 0], fmesh.vertices[:, 1], height.shape, pixel)
        filled = np.where(valid, height, np.nanmean(height[valid]))
        dev_um = 1000 * np.abs(fmesh.vertices[:, 2] - ndimage.map_coordinates(filled, [vr, vc], order=1,
                                                                              mode="nearest"))
        fmesh.vertices[:, 2] *= 10.0
        pic = render(fmesh, ["iso", "top"], vsize, scalars=dev_um, colorbar_label="|dz| um",
                     cmap="magma", vmin=0.0, antialias=1 if ctx.quick else 2, light=(-0.45, 0.5, 0.74))
        rep.figure(pic, "inspection-deviation",
                   f"Deviation |dz| of the fitted surface from the integrated height at the mesh vertices "
                   f"(largest {nums['surface_max_dev_um']:.1f} um at the pixel centres, tolerance "
                   f"{fit.tolerance * 1000:.1f} um); height exaggerated 10x. The largest deviations "
                   "sit on the crack's floor and rim, kinks that no smooth patch follows exactly.",
                   recon_cmd)
        shown = MixedPatches(fit.patches.control * np.array([1.0, 1.0, 3.0]), cells=fit.patches.cells)
        # a square window of the lattice around the crack (upper left of the plate)
        H, W = height.shape
        r0, c0, span = int(H * 0.18), int(W * 0.2), max(12, H // 5)
        cells = shown.cells
        inside = ((cells[:, 0] >= r0) & (cells[:, 0] + cells[:, 2] <= r0 + span)
                  & (cells[:, 1] >= c0) & (cells[:, 1] + cells[:, 2] <= c0 + span))
        crop = MixedPatches(shown.control[inside], cells=cells[inside] - [r0, c0, 0])
        pic = render(crop, ["top", "iso"], (1100, 480), net=True, samples=4, antialias=2,
                     light=(-0.45, 0.5, 0.74))
        rep.figure(pic, "inspection-bezier-net",
                   f"Detail around the crack: the {int(inside.sum())} fitted patches of a {span} x {span} "
                   "pixel window with their Bezier control nets (seed 001's 'carcass') drawn over the "
                   "ray-cast surface (height exaggerated 3x): large patches on the flat plate, smaller "
                   "ones towards the crack, one-pixel patches (the dark band of dense nets) on it.",
                   recon_cmd)
        ctx.step("inspection: Bezier surface")
    if "Inspection: photometric stereo" in ctx.unavailable:
        return
    found = json.loads((recon / "defects.json").read_text())["defects"]
    truth = scene["defects"]
    rows_out, matched = [], []
    for t in truth:
        cr, cc = t["center_px"]
        best = min(found, key=lambda d: np.hypot(d["center_px"][0] - cr, d["center_px"][1] - cc),
                   default=None)
        dist = (np.hypot(best["center_px"][0] - cr, best["center_px"][1] - cc) * pixel
                if best is not None else np.inf)
        m = best if best is not None and dist < 0.5 * max(t["length_mm"], t["width_mm"]) else None
        matched.append({"kind": t["kind"], "truth": t, "measured": m})
        rows_out.append([
            t["kind"],
            t["depth_mm"], m["max_depth_mm"] if m else "not found",
            t["width_mm"], m["max_width_mm"] if m else "not found",
            t["length_mm"], m["length_mm"] if m else "not found",
            t["area_mm2"], m["area_mm2"] if m else "not found",
        ])
    nums["defects"] = [
        {"kind": d["kind"], "depth_true_mm": d["truth"]["depth_mm"],
         "depth_measured_mm": d["measured"]["max_depth_mm"] if d["measured"] else None,
         "width_true_mm": d["truth"]["width_mm"],
         "width_measured_mm": d["measured"]["max_width_mm"] if d["measured"] else None,
         "length_true_mm": d["truth"]["length_mm"],
         "length_measured_mm": d["measured"]["length_mm"] if d["measured"] else None,
         "area_true_mm2": d["truth"]["area_mm2"],
         "area_measured_mm2": d["measured"]["area_mm2"] if d["measured"] else None}
        for d in matched
    ]
    nums["defects_found"] = len(found)
    rep.table(["defect", "depth true (mm)", "depth measured (mm)", "width true (mm)",
               "max width measured (mm)", "length true (mm)", "length measured (mm)",
               "area true (mm2)", "area measured (mm2)"], rows_out,
              caption=f"Defects measured by the pipeline (photometric.defects.measure_defects on "
              f"the reconstructed height, {len(found)} region(s) found; defects.json) against "
              "the scene's truth (scene.json).", digits=3)
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


# ----------------------------------------------------------------------------- section 2


def section_accuracy(ctx: Context) -> None:
    """Derivative-error maps against light deviations and recommended tolerances."""
    rep = ctx.report
    rep.section("2. Accuracy study: light-direction deviations",
                "How much do the reconstructed derivatives p = dz/dx, q = dz/dy suffer when the "
                "real lights deviate from the nominal ones (seed 002a)? Exact error model "
                "m = L^-1 L' n for the nominal triad (slant 45 deg, 120 deg apart), worst case "
                "over all slopes |p|, |q| <= D.")
    nums: dict = {}
    ctx.numbers["accuracy"] = nums
    with ctx.guard("Accuracy study"):
        from photometric import errors
        from photometric.lights import condition_number, ring_lights
        from workbench.studies.crack import crack_study

        lights = ring_lights(3, 45.0)
        d_range = 1.0
        n_map = 21 if ctx.quick else 41
        p, q = errors.derivative_square(d_range, 21 if ctx.quick else 41)
        from surfaces.io import atomic_write_text

        lights_file = ctx.out / "accuracy" / "lights.txt"
        lights_file.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(lights_file, "".join(" ".join(f"{v:.12f}" for v in row) + "\n"
                                               for row in lights))
        cmd = ctx.cmd("photometric", "errors", "--lights", str(lights_file), "--derivative-range",
                      str(d_range), "--deviation-max", "5", "--grid", str(n_map), "--out",
                      str(ctx.out / "accuracy"))
        maps = []
        for axis1, axis2, title in (
            ((0, "slant"), (1, "slant"), "lights 1 and 2: slant deviations"),
            ((0, "slant"), (0, "azimuth"), "light 1: slant and azimuth deviations"),
        ):
            em = errors.error_map(lights, p, q, axis1=axis1, axis2=axis2, deviation_max=5.0, n=n_map)
            worst = np.maximum(em.max_dp, em.max_dq)
            maps.append(im.plot_map(
                worst, em.dev1_deg, em.dev2_deg,
                xlabel=f"light {axis1[0] + 1} {axis1[1]} deviation (deg)",
                ylabel=f"light {axis2[0] + 1} {axis2[1]} deviation (deg)",
                title=f"max |dp|, |dq| over |p|, |q| <= {d_range:g}\n{title}",
                label="derivative error", cmap="magma", contours=(0.02, 0.05, 0.1)))
            maps.append(im.plot_map(
                em.max_angle_deg, em.dev1_deg, em.dev2_deg,
                xlabel=f"light {axis1[0] + 1} {axis1[1]} deviation (deg)",
                ylabel=f"light {axis2[0] + 1} {axis2[1]} deviation (deg)",
                title=f"max normal angle error\n{title}", label="deg", cmap="viridis",
                contours=(1.0, 2.0, 5.0)))
            key = f"{axis1[1]}{axis1[0] + 1}_{axis2[1]}{axis2[0] + 1}"
            nums[f"max_derivative_error_at_5deg_{key}"] = float(worst.max())
            nums[f"max_angle_error_at_5deg_{key}_deg"] = float(em.max_angle_deg.max())
        ctx.step("accuracy: error maps")
        rep.figure(im.montage(maps, cols=2), "accuracy-maps",
                   "Worst-case derivative error (left) and normal angle error (right) against two "
                   f"light deviations of +-5 deg, over all slopes |p|, |q| <= {d_range:g}; white "
                   "lines are tolerance levels. Errors grow linearly with the deviation (about "
                   "1 deg of normal per deg of light, Ray, Birk & Kelley 1983).", cmd)
        table = errors.recommendation_table(lights, tolerances=TOLERANCES, ranges=RANGES,
                                            n_grid=11 if ctx.quick else 21)
        ctx.step("accuracy: tolerances")
        nums["recommendation"] = table
        rep.table(
            ["derivative range D", "tolerance eps on p, q", "one light (deg)",
             "a pair of lights (deg)", "all three lights (deg)", "one light, first order (deg)"],
            [[r["derivative_range"], r["tolerance"], r["single_light_deg"], r["pair_deg"],
              r["all_lights_deg"], r["single_light_first_order_deg"]] for r in table],
            caption="Recommended operating limits: the largest angular deviation of the lights "
            "(any direction) that keeps |dp|, |dq| <= eps for every slope with |p|, |q| <= D "
            "(photometric.errors.recommendation_table; worst case over lights and directions).",
            digits=3)
        dev = np.zeros((2, 3, 2))
        dev[:, 0, 0] = 2.0
        dev[1, 1, 1] = -2.0
        crack = crack_study(lights, dev, size=64 if ctx.quick else 128)
        ctx.step("accuracy: crack study")
        maps = crack["maps"]
        tiles, captions = [], []
        for k in range(len(crack["cases"])):
            lim = float(max(np.abs(maps["dq_measured"][k]).max(),
                            np.abs(maps["dq_predicted"][k]).max()))
            for which in ("measured", "predicted"):
                tiles.append(im.scalar_image(maps[f"dq_{which}"][k], cmap="coolwarm", vmin=-lim,
                                             vmax=lim, label="dq"))
                captions.append(f"case {k + 1}: dq {which}")
        rep.figure(im.montage(tiles, cols=2, labels=captions), "accuracy-crack",
                   "Seed 002a's crack test image: rendered with deviated lights, reconstructed with "
                   "the nominal ones. Measured derivative error dq beside the exact model's "
                   "prediction; case 1: light 1 slant +2 deg; case 2: also light 2 azimuth -2 deg.",
                   ctx.cmd("photometric", "errors", "--lights", str(lights_file), "--crack-size",
                           "64" if ctx.quick else "128", "--out", str(ctx.out / "accuracy")))
        nums["crack_study"] = {k: v for k, v in crack.items() if k != "maps"}
        rep.table(
            ["case", "deviations [slant, azimuth] per light (deg)", "max |dp| measured",
             "max |dp| predicted", "max |dq| measured", "max |dq| predicted",
             "max |dq| first order", "crack depth (mm, true " + f"{crack['true_depth_mm']:.4f})"],
            [[k + 1, str(np.round(np.asarray(c["deviations_deg"]), 2).tolist()),
              c["max_abs_dp_measured"], c["max_abs_dp_predicted"], c["max_abs_dq_measured"],
              c["max_abs_dq_predicted"], c["max_abs_dq_first_order"], c["depth_mm"]]
             for k, c in enumerate(crack["cases"])],
            caption="Crack study (workbench.studies.crack.crack_study): the measured error equals the "
            "exact model's prediction; the first-order formula is within a few per cent.",
            digits=4)
        nums["condition_number"] = float(condition_number(lights))
        rep.paragraph(f"Condition number of the nominal triad: {nums['condition_number']:.3f} "
                      f"(best, 1.0, at slant {errors.OPTIMAL_SLANT_DEG:.2f} deg).")


# ----------------------------------------------------------------------------- section 3


def section_real(ctx: Context) -> None:
    """DiLiGenT bear: triad and all 14 images against ground truth and the baseline figures."""
    rep = ctx.report
    rep.section("3. Real captures: DiLiGenT bear",
                "Real 16-bit captures with ground-truth normals (DiLiGenT, Shi et al. 2016/2019), "
                "14 of the 96 images. Plain least squares, channels divided by the light "
                "intensities and averaged to grey: published baseline 11.74 deg on this triad and "
                "9.60 deg on the 14 images (8.39 deg with all 96 images).")
    folder = ctx.shared / "diligent_bear"
    nums: dict = {"folder": str(folder)}
    ctx.numbers["real"] = nums
    if not folder.is_dir():
        reason = f"the real-data folder {folder} is absent (set WORKBENCH_SHARED_DATA)"
        ctx.unavailable["Real captures"] = reason
        rep.note(f"Real captures: not available: {reason}")
        return
    with ctx.guard("Real captures"):
        from photometric.io import read_folder
        from photometric.normals import angular_error_deg
        from surfaces.render import render
        from surfaces.io import read_mesh
        from workbench.runs.photometric import reconstruct_to_folder

        results = {}
        for key, select in (("triad", "triad"), ("all14", None)):
            data = read_folder(folder, select=select)
            dest = ctx.out / "real" / f"bear_{key}"
            summary = reconstruct_to_folder(folder, dest, select=select)
            normals = np.load(dest / "normals.npy")
            err = np.where(data.mask, angular_error_deg(normals, data.normal_gt), np.nan)
            results[key] = (data, normals, err, dest)
            nums[f"{key}_mean_error_deg"] = float(np.nanmean(err))
            nums[f"{key}_median_error_deg"] = float(np.nanmedian(err))
            nums[f"{key}_pipeline_mean_error_deg"] = summary.get("mean_angular_error_deg")
            nums[f"{key}_images"] = len(data.names)
            ctx.step(f"bear: {key} solved")
        triad, all14 = results["triad"][0], results["all14"][0]

        def show(data, k):
            img = data.images[k] / np.maximum(data.intensities[k], 1e-12)[None, None, :]
            return im.to_uint8(img, vmax=float(np.percentile(img[data.mask], 99.5)))

        step = 2 if ctx.quick else 1
        cmd_triad = ctx.cmd("photometric", "reconstruct", str(folder), "--triad", "--out",
                            str(results["triad"][3]))
        cmd_all = ctx.cmd("photometric", "reconstruct", str(folder), "--out", str(results["all14"][3]))
        rep.figure(im.montage([show(triad, k)[::step, ::step] for k in range(3)], cols=3,
                              labels=list(triad.names)),
                   "bear-triad-images",
                   "The triad (lights about 40 deg slant, 120 deg apart), divided by the light "
                   "intensities.", cmd_triad)
        thumbs = [show(all14, k)[::4, ::4] for k in range(len(all14.names))]
        rep.figure(im.montage(thumbs, cols=7, labels=list(all14.names)), "bear-all-images",
                   "All 14 images (quarter size).", cmd_all)
        gt = triad.normal_gt
        tiles = [
            im.label_image(im.normal_map(gt, triad.mask), "ground truth"),
            im.label_image(im.normal_map(results["triad"][1], triad.mask), "triad"),
            im.label_image(im.normal_map(results["all14"][1], all14.mask), "14 images"),
        ]
        rep.figure(im.montage([t[::step, ::step] for t in tiles], cols=3), "bear-normals",
                   "Normal maps: ground truth, least squares on the triad and on all 14 images.",
                   cmd_all)
        vmax = 30.0
        errs = [im.error_image(results[k][2][::step, ::step], triad.mask[::step, ::step], vmax=vmax,
                               label="angle deg") for k in ("triad", "all14")]
        rep.figure(im.montage(errs, cols=2, labels=[
            f"triad: mean {nums['triad_mean_error_deg']:.2f} deg",
            f"14 images: mean {nums['all14_mean_error_deg']:.2f} deg"]), "bear-errors",
            "Angular error against the ground truth (colour bar clipped at 30 deg): shadows and "
            "highlights break the Lambertian model where fewer lights see the surface.", cmd_all)
        mesh = read_mesh(results["all14"][3] / "surface.ply")
        pic = render(mesh, ["iso", "top"], (900, 420) if ctx.quick else (1200, 560),
                          light=(-0.3, 0.4, 0.87))
        rep.figure(pic, "bear-surface",
                   "The pipeline's surface from the 14-image normals (height integrated, Bezier "
                   "patches fitted by least squares to the height and slopes, trimmed along the "
                   "mask's outline; pixel units), ray-cast.", cmd_all)
        ctx.step("bear: figures")
        rep.table(["light set", "images", "our mean error (deg)", "our median (deg)",
                   "baseline mean (deg)", "difference (deg)"], [
            ["triad", nums["triad_images"], nums["triad_mean_error_deg"],
             nums["triad_median_error_deg"], BEAR_BASELINE_DEG["triad"],
             nums["triad_mean_error_deg"] - BEAR_BASELINE_DEG["triad"]],
            ["all 14", nums["all14_images"], nums["all14_mean_error_deg"],
             nums["all14_median_error_deg"], BEAR_BASELINE_DEG["all14"],
             nums["all14_mean_error_deg"] - BEAR_BASELINE_DEG["all14"]],
            ["all 96 (published, not in this subset)", 96, "not computed (subset of 14 images)",
             "not computed", BEAR_PUBLISHED_96_DEG, "n/a: different image set"],
        ], caption="DiLiGenT bear: mean angular error inside the object mask.", digits=4)


# ----------------------------------------------------------------------------- section 4


def _contour_segments(path: Path) -> np.ndarray:
    """(K, 2, 3) polyline segments of every contour in a contours.json file."""
    data = json.loads(path.read_text())
    segs = []
    for c in data["contours"]:
        pts = np.asarray(c["points"], float)
        p3 = np.column_stack([pts, np.full(len(pts), float(c["z"]))])
        segs.append(np.stack([p3, np.roll(p3, -1, axis=0)], axis=1))
    return np.concatenate(segs)


def section_ct(ctx: Context) -> None:
    """Kidney phantom reconstructed from its contours: volume and surface distance vs truth."""
    rep = ctx.report
    rep.section("4. CT: surfaces from contour stacks",
                "Seed 000: closed contours per slice -> adaptive control points (rays from the "
                "centroid, fold handling) -> parabolic-blending curves -> one interpolating "
                "surface across the slices (Bezier patches), capped; volume by the divergence "
                "theorem.")
    nums = ctx.numbers.setdefault("ct", {})
    spacing = 4.0 if ctx.quick else 2.0
    kid = ctx.out / "ct" / "kidney"
    with ctx.guard("CT: kidney phantom"):
        from datasets_synthetic.phantoms import make_phantom, write_phantom
        from slices.pipeline import reconstruct
        from surfaces.distance import deviation
        from surfaces.render import render
        from surfaces.io import read_mesh

        phantom = make_phantom("kidney")
        truth = write_phantom(kid, phantom, spacing=spacing, pixel=0.8, fmt="json",
                              n_points=48 if ctx.quick else 96, n_surface=4000 if ctx.quick else 20000)
        ctx.step("ct: phantom written")
        out = ctx.out / "ct" / "kidney_surface"
        summary = reconstruct(kid / "contours.json", out, rays=32 if ctx.quick else 64,
                              caps="flat", render=False, reference=False)
        ctx.step("ct: kidney reconstructed")
        mesh = read_mesh(out / "surface.ply")
        pts = np.load(kid / "surface_points.npy")
        dist = deviation(pts, mesh)
        from scipy.spatial import cKDTree

        _, nearest = cKDTree(pts).query(mesh.vertices)
        vertex_dev = dist[nearest]
        lim = float(np.percentile(np.abs(dist), 99))
        nums["kidney"] = {
            "spacing_mm": spacing,
            "n_contours": truth["n_contours"],
            "volume_true_mm3": truth["volume_mm3"],
            "volume_between_end_planes_mm3": truth.get("volume_between_end_planes_mm3"),
            "volume_reconstructed_mm3": summary["volume_mm3"],
            "volume_error_percent": 100 * (summary["volume_mm3"] / truth["volume_mm3"] - 1),
            "slab_volume_mm3": summary["slab_volume_mm3"],
            "surface_distance_mean_mm": float(np.mean(np.abs(dist))),
            "surface_distance_rms_mm": float(np.sqrt(np.mean(dist**2))),
            "surface_distance_p95_mm": float(np.percentile(np.abs(dist), 95)),
            "surface_distance_max_mm": float(np.max(np.abs(dist))),
            "mesh_triangles": summary["mesh_triangles"],
            "watertight": summary["mesh_watertight"],
        }
        k = nums["kidney"]
        cmd_ph = ctx.cmd("synth", "phantom", "--shape", "kidney", "--spacing", str(spacing),
                         "--pixel", "0.8", "--out", str(kid))
        cmd_rec = ctx.cmd("slices", "reconstruct", str(kid / "contours.json"), "--rays",
                          "32" if ctx.quick else "64", "--out", str(out))
        pic = render(mesh, ["iso", "front", "top", "side"], (1000, 760),
                          scalars=vertex_dev, vmin=-lim, vmax=lim, cmap="coolwarm",
                          colorbar_label="dev. mm", net=_contour_segments(kid / "contours.json"),
                          net_color=(0.1, 0.1, 0.1), net_hidden=True)
        rep.figure(pic, "ct-kidney",
                   f"Kidney phantom (sections fold: the hilum is concave) reconstructed from "
                   f"{k['n_contours']} contours {spacing:g} mm apart (black lines); colour = signed "
                   "distance of the nearest true surface sample to the reconstruction (mm, "
                   "positive outside).", f"{cmd_ph} && {cmd_rec}")
        rep.table(["quantity", "value"], [
            ["true volume (mm3)", k["volume_true_mm3"]],
            ["reconstructed volume (mm3)", k["volume_reconstructed_mm3"]],
            ["volume error (%)", k["volume_error_percent"]],
            ["slab volume, areas x spacing (mm3)", k["slab_volume_mm3"]],
            ["surface distance, mean |d| (mm)", k["surface_distance_mean_mm"]],
            ["surface distance, RMS (mm)", k["surface_distance_rms_mm"]],
            ["surface distance, 95th percentile (mm)", k["surface_distance_p95_mm"]],
            ["surface distance, max (mm)", k["surface_distance_max_mm"]],
            ["mesh triangles", k["mesh_triangles"]],
            ["watertight", k["watertight"]],
        ], caption="Kidney phantom: reconstruction against the exact solid (distance from "
                   f"{len(pts)} true surface samples to the reconstructed surface).")


def section_breast(ctx: Context) -> None:
    """The breast structure set's Heart (and Lt Lung) against the reference volumes."""
    rep = ctx.report
    nums = ctx.numbers.setdefault("ct", {})
    rtss = ctx.shared / "rtstruct_breast" / "rtss.dcm"
    if not rtss.is_file():
        reason = f"the real structure set {rtss} is absent (set WORKBENCH_SHARED_DATA)"
        ctx.unavailable["CT: breast structure set"] = reason
        rep.note(f"CT: breast structure set: not available: {reason}")
        return
    with ctx.guard("CT: breast structure set"):
        from slices.pipeline import reconstruct
        from surfaces.render import render
        from surfaces.io import read_mesh
        from surfaces.mesh import TriangleMesh, merge_meshes

        rois = ["Heart"] if ctx.quick else ["Heart", "Lt Lung"]
        rows, meshes, colors = [], [], []
        palette = {"Heart": (0.85, 0.35, 0.35), "Lt Lung": (0.55, 0.7, 0.9)}
        for roi in rois:
            out = ctx.out / "ct" / roi.lower().replace(" ", "_")
            s = reconstruct(rtss, out, roi=roi, caps="flat", render=False, reference=False,
                            rays=32 if ctx.quick else 64, samples=2 if roi == "Lt Lung" else 3)
            ctx.step(f"ct: {roi} reconstructed")
            refs = HEART_REFERENCE_CC if roi == "Heart" else LUNG_REFERENCE_CC
            nums[roi] = {"volume_cc": s["volume_ml"], "slab_volume_cc": s["slab_volume_ml"],
                         "n_contours": s["n_contours"], "n_bodies": s["n_bodies"],
                         "references_cc": refs}
            for name, ref in refs.items():
                rows.append([roi, s["n_contours"], s["volume_ml"], s["slab_volume_ml"], name, ref,
                             100 * (s["volume_ml"] / ref - 1)])
            m = read_mesh(out / "surface.ply")
            meshes.append(TriangleMesh(m.vertices, m.triangles, m.vertex_normals, None))
            colors.append(np.broadcast_to(palette[roi], m.vertices.shape))
        if ctx.quick:
            rep.note("--quick: only the Heart is reconstructed; the full run adds the Lt Lung "
                     "(165 contours on 80 planes, with holes).")
        merged = merge_meshes(meshes)
        pic = render(merged, ["front", "left"], (1000, 520), colors=np.concatenate(colors))
        rep.figure(pic, "ct-breast",
                   "Structures of the real breast RT structure set reconstructed from their "
                   f"contours: {' and '.join(rois)} (red: Heart, blue: Lt Lung; DICOM patient "
                   "coordinates, x towards the patient's left, so 'front' is the anterior view "
                   "and 'left' looks from the patient's right).",
                   " && ".join(ctx.cmd("slices", "reconstruct", str(rtss), "--roi",
                                       f"'{roi}'" if " " in roi else roi, "--rays",
                                       "32" if ctx.quick else "64", "--out",
                                       str(ctx.out / "ct" / roi.lower().replace(" ", "_")))
                               for roi in rois))
        rep.table(["structure", "contours", "our volume (cc)", "our slab volume (cc)",
                   "reference", "reference volume (cc)", "difference (%)"], rows,
                  caption="Volumes of the same contours: ours (surface, divergence theorem; slab = "
                  "contour areas x spacing) beside other systems' figures. Planning systems "
                  "disagree among themselves by about 1-5 %, mostly at the end slices.", digits=5)


# ----------------------------------------------------------------------------- driver


SECTIONS = (section_inspection, section_accuracy, section_real, section_ct, section_breast)
STEPS = 13  # ctx.step calls in a full run (one fewer with --quick: no Lt Lung)


def run_demo(out_dir: str | os.PathLike = "demo_out", quick: bool = False,
             shared: str | os.PathLike | None = None, progress: bool = False) -> dict:
    """Run every demo section and write ``report.html``, ``demo.json`` and the figures.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created).
    quick : bool
        Reduced sizes (the CI smoke test): 128-pixel plate, coarser grids, Heart only.
    shared : path-like, optional
        Real-data folder; :func:`shared_data_dir` when omitted.
    progress : bool
        Show a tqdm progress bar (command line).

    Returns
    -------
    dict
        The ``demo.json`` content: ``report``, ``seconds``, ``quick``, ``unavailable``
        (section -> reason), ``figures`` (file, caption, command) and every number
        under its section name.
    """
    from tqdm import tqdm

    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    report = Report("Surface-reconstruction workbench: demo report", out)
    ctx = Context(out=out, quick=bool(quick),
                  shared=Path(shared) if shared is not None else shared_data_dir(), report=report)
    report.paragraph(
        "Everything on this page was computed by one run of the demo on the machine named below "
        "(no precomputed results): synthetic scenes with exact ground truth, the shared real data "
        "(DiLiGenT bear, a breast RT structure set) when present, the photometric-stereo and CT "
        "pipelines, and the one Bezier surface model both converge on. Pictures are ray-cast "
        "headless with open3d's RaycastingScene.")
    with tqdm(total=STEPS - int(bool(quick)), desc="demo", unit="step", disable=not progress) as bar:
        ctx.bar = bar
        for section in SECTIONS:
            section(ctx)
        bar.update(max(0, bar.total - bar.n))
    report.section("5. Figures and the commands that reproduce them",
                   "Each figure's data comes from the command shown; the pictures themselves are "
                   "drawn by the demo.")
    report.table(["figure", "file", "what it shows", "command"],
                 [[f, file, cap, f"`{cmd}`"] for f, file, cap, cmd in report.figure_index()])
    if ctx.unavailable:
        report.table(["section", "reason"], [[k, v] for k, v in ctx.unavailable.items()],
                     caption="Sections that could not run.")
    seconds = time.perf_counter() - t0
    meta = (f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {platform.node()}, "
            f"{os.cpu_count()} CPU(s), Python {platform.python_version()}; "
            f"{'quick' if quick else 'full'} run, {seconds:.0f} s")
    path = report.write("report.html", meta=meta)
    summary = {
        "report": str(path),
        "seconds": seconds,
        "quick": bool(quick),
        "shared_data": str(ctx.shared),
        "unavailable": ctx.unavailable,
        "figures": [{"file": f.file, "caption": f.caption, "command": f.command}
                    for f in report.figures],
        **ctx.numbers,
    }
    from surfaces.io import write_json

    write_json(out / "demo.json", summary)
    return summary
