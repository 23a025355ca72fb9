"""Benchmark of the surface step of photometric stereo (issue 16): the fit against the Coons grid.

Run: ``.venv/bin/python benchmarks/bench_surface_fit.py [--quick]``. Writes
``benchmarks/results/surface_fit.md`` and prints it.

* Accuracy: rendered noise-free crack, dent and scratch plates and a sphere
  (:func:`datasets_synthetic.render.make_triad_folder`, 3 lights, no shadows) and the
  DiLiGenT bear with all 14 images, each reconstructed once; the surface step then runs
  on the same height and slopes with ``surface="fit"`` (:func:`surfaces.fit.fit_height`,
  default tolerance) and ``surface="coons"`` (:func:`photometric.integrate.height_to_patches`,
  the seed's construction). Both surfaces are evaluated on their patches at every pixel
  centre inside the mask and at least 3 px from its border: the largest ``|surface -
  height|`` as a percentage of the largest defect depth (the cap height for the sphere,
  the height range for the bear), and the angle between the surface normal and the
  measured normal (the mesh's vertex normals are these patch normals).
* The bear's integrators (``--integrator``) at the default and at given tolerances, and
  the robust integrator after more reweighting steps (:data:`IRLS_STEPS`).
* Speed: a 2048 x 2048 (4 MP) height field with its slopes (the inspection plate,
  analytic) fitted at the default tolerance, best of 2; where the time goes (cProfile of
  one fit); the Coons construction of the same field for comparison.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import Table, best_of, write_results  # noqa: E402

from datasets_synthetic.heightfields import make_scene  # noqa: E402
from datasets_synthetic.render import make_triad_folder  # noqa: E402
from photometric.integrate import height_to_patches, robust_least_squares  # noqa: E402
from photometric.pipeline import TARGET_PATCHES, reconstruct  # noqa: E402
from surfaces.fit import default_step, fit_height, fit_mesh  # noqa: E402

SHARED = Path(os.environ.get("WORKBENCH_SHARED_DATA", ROOT.parent / "shared" / "data"))
SCENES = ("crack", "dent", "scratch", "sphere")


def _patch_values(patches, method: str, shape):
    """Surface points and unit normals at every pixel centre, evaluated on the patches."""
    H, W = shape
    rows, cols = np.mgrid[0:H, 0:W]
    r, c = rows.ravel().astype(float), cols.ravel().astype(float)
    if method == "fit":
        pi, u, v = patches.locate_lattice(r + 0.5, c + 0.5)
        pj = 0
    else:  # the Coons grid spans the image with equal steps
        R, C = patches.shape
        pi, pj, u, v = patches.locate(r * (R / (H - 1)), c * (C / (W - 1)))
    pi = np.broadcast_to(pi, r.shape)
    on = pi >= 0  # the fit has patches only over the mask and a margin
    d = patches.derivatives(pi[on], np.broadcast_to(pj, r.shape)[on], u[on], v[on])
    z = np.full(r.shape, np.nan)
    n = np.full((r.size, 3), np.nan)
    z[on] = d.point[:, 2]
    n[on] = np.cross(d.du, d.dv)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return z.reshape(shape), n.reshape(H, W, 3)


def _figures(height, p, q, normals, mask, pixel_size, depth):
    """Both surface steps on one height field: deviation and normal figures, sizes, times."""
    shape = height.shape
    inner = ndimage.binary_erosion(mask, iterations=3, border_value=0)
    out = {}
    t0 = time.perf_counter()
    fit = fit_height(height, p, q, mask=mask, pixel_size=pixel_size)
    t_fit = time.perf_counter() - t0
    step = max(2, int(np.ceil(max(shape) / TARGET_PATCHES)))
    t0 = time.perf_counter()
    coons = height_to_patches(height, p, q, pixel_size=pixel_size, step=step)
    t_coons = time.perf_counter() - t0
    for method, patches, seconds in (("fit", fit.patches, t_fit), ("coons", coons, t_coons)):
        z, n = _patch_values(patches, method, shape)
        sel = inner & fit.region if method == "fit" else inner
        dev = np.abs(z - height)[sel]
        ang = np.degrees(np.arccos(np.clip((n * normals).sum(axis=2), -1.0, 1.0)))[sel]
        out[method] = {
            "max_dev_pct": 100.0 * float(dev.max()) / depth,
            "rms_dev_pct": 100.0 * float(np.sqrt(np.mean(dev**2))) / depth,
            "normal_p99_deg": float(np.percentile(ang, 99)),
            "normal_mean_deg": float(ang.mean()),
            "n_patches": int(patches.n_patches),
            "seconds": seconds,
        }
    # the floor: the integrated height's own normals (central differences) against the measured
    # ones; a surface that stays within a tolerance of the height cannot get far below it
    gs, gt = np.gradient(np.where(mask, height, 0.0))
    n = np.stack([-gt / pixel_size, gs / pixel_size, np.ones(shape)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    floor = np.degrees(np.arccos(np.clip((n * normals).sum(axis=2), -1.0, 1.0)))[inner]
    out["floor"] = {"normal_p99_deg": float(np.percentile(floor, 99)), "normal_mean_deg": float(floor.mean())}
    out["fit"]["tolerance_pct"] = 100.0 * fit.tolerance / depth
    out["fit"]["excluded_px"] = int((inner & ~fit.region).sum())
    return out


#: Slope weights and tolerances (fraction of the height range; None: the default) of the
#: bear's slope-weighting study.
SLOPE_STUDY = ((1.0, None), (16.0, None), (100.0, None), (1.0, 0.0005), (100.0, 0.0005), (1000.0, 0.0005))


def slope_study(height, p, q, normals, mask, pixel_size, depth):
    """The fit with heavier slope weights (and a tighter tolerance): deviation and normal figures."""
    inner = ndimage.binary_erosion(mask, iterations=3, border_value=0)
    out = []
    for lam, rel in SLOPE_STUDY:
        tol = None if rel is None else rel * depth
        fit = fit_height(height, p, q, mask=mask, pixel_size=pixel_size, slope_weight=lam, tolerance=tol)
        z, n = _patch_values(fit.patches, "fit", height.shape)
        sel = inner & fit.region
        ang = np.degrees(np.arccos(np.clip((n * normals).sum(axis=2), -1.0, 1.0)))[sel]
        out.append({"slope_weight": lam, "tolerance_pct": 100.0 * fit.tolerance / depth,
                    "max_dev_pct": 100.0 * float(np.abs(z - height)[sel].max()) / depth,
                    "normal_mean_deg": float(ang.mean()), "normal_p99_deg": float(np.percentile(ang, 99)),
                    "n_patches": int(fit.patches.n_patches)})
    return out


#: The bear's integrators: L2 on the rectangle (dct), L2 on the mask (lsq), the robust
#: (discontinuity-preserving) integral on the mask.
INTEGRATORS = ("dct", "lsq", "robust")
#: Fit tolerances of the integrator study (fraction of the height range; None: the default,
#: with the slope check where the height's noise sets it; "given": the same tolerance passed
#: explicitly, so without the slope check, as every tolerance given).
TOLERANCE_STUDY = (None, "given", 0.0025, 0.001)


def integrator_study(res, mask, pixel_size, depth):
    """One integrator's height on the bear: its time, and the fit at looser and tighter tolerances.

    One row per entry of :data:`TOLERANCE_STUDY`.
    """
    inner = ndimage.binary_erosion(mask, iterations=3, border_value=0)
    out = []
    default_tol = None
    for rel in TOLERANCE_STUDY:
        tol = None if rel is None else default_tol if rel == "given" else rel * depth
        fit = fit_height(res.height, res.p, res.q, mask=mask, pixel_size=pixel_size, tolerance=tol)
        if rel is None:
            default_tol = fit.tolerance
        z, n = _patch_values(fit.patches, "fit", res.height.shape)
        sel = inner & fit.region
        ang = np.degrees(np.arccos(np.clip((n * res.normals).sum(axis=2), -1.0, 1.0)))[sel]
        out.append({"seconds": res.summary["timings_s"]["integrate"], "tolerance_pct": 100.0 * fit.tolerance / depth,
                    "given": rel is not None,
                    "max_dev_pct": 100.0 * float(np.abs(z - res.height)[sel].max()) / depth,
                    "normal_mean_deg": float(ang.mean()), "normal_p99_deg": float(np.percentile(ang, 99)),
                    "n_patches": int(fit.patches.n_patches)})
    return out


#: Reweighting steps of the robust integrator's study (``iterations`` of
#: :func:`photometric.integrate.robust_least_squares`; the default 1).
IRLS_STEPS = (0, 1, 3, 8)


def irls_study(res, mask, pixel_size):
    """The robust integral of the bear's slopes after more reweighting steps: CPU time, floor, fit."""
    out = []
    for steps in IRLS_STEPS:
        with threadpool_limits(limits=1):
            c0 = time.process_time()
            z = robust_least_squares(res.p, res.q, mask=mask, pixel_size=pixel_size, iterations=steps)
            cpu = time.process_time() - c0
        depth = float(np.ptp(z[mask]))
        f = _figures(z, res.p, res.q, res.normals, mask, pixel_size, depth)
        out.append({"iterations": steps, "cpu": cpu, "floor": f["floor"], "fit": f["fit"]})
    return out


def accuracy(size: int, tmp: Path) -> list[tuple[str, float, dict]]:
    """Figures of every rendered scene and of the bear: ``(name, depth_px, figures)``.

    The bear's figures also carry ``"slopes"``, the rows of :func:`slope_study` (dct and
    lsq), and ``"integrator"``, those of :func:`integrator_study`.
    """
    rows = []
    for scene in SCENES:
        folder = tmp / scene
        make_triad_folder(folder, scene=scene, size=size, noise=0.0, shadows="none", deviate=None,
                          albedo=0.8, bit_depth=None, pixel_size=0.05, seed=0)
        info = json.loads((folder / "scene.json").read_text())
        if scene == "sphere":
            depth = info["scene_params"]["height_mm"]
        else:
            depth = max(d["depth_mm"] for d in info["defects"])
        res = reconstruct(folder, surface="coons")
        mask = res.valid & np.isfinite(res.height)
        figures = _figures(res.height, res.p, res.q, res.normals, mask, 0.05, depth)
        rows.append((f"{scene} ({size} px)", depth / 0.05, figures))
    bear = SHARED / "diligent_bear"
    for integrator in INTEGRATORS if bear.is_dir() else ():
        res = reconstruct(bear, surface="coons", integrator=integrator)
        mask = res.valid & np.isfinite(res.height)
        h = res.summary["pixel_size_mm"]
        depth = float(np.ptp(res.height[mask]))
        figures = _figures(res.height, res.p, res.q, res.normals, mask, h, depth)
        if integrator != "robust":  # the slope study of the two L2 integrators, as before
            figures["slopes"] = slope_study(res.height, res.p, res.q, res.normals, mask, h, depth)
        figures["integrator"] = integrator_study(res, mask, h, depth)
        if integrator == "robust":
            figures["irls"] = irls_study(res, mask, h)
        rows.append((f"DiLiGenT bear (14 images, {integrator})", depth / h, figures))
    return rows


def speed(size: int, repeat: int):
    """Fit and Coons times of a ``size``-square inspection plate; cProfile of one fit."""
    hf = make_scene("plate", size)
    cpus = []

    def timed_fit():
        c0 = time.process_time()
        out = fit_height(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size)
        cpus.append(time.process_time() - c0)
        return out

    t_fit, fit = best_of(timed_fit, repeat)
    cpu = min(cpus)
    t_mesh, mesh = best_of(lambda: fit_mesh(fit, spacing=fit.step / min(fit.step, 8)), 1)
    step = max(2, int(np.ceil(size / TARGET_PATCHES)))
    t_coons, coons = best_of(lambda: height_to_patches(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size,
                                                       step=step), repeat)
    prof = cProfile.Profile()
    prof.enable()
    fit_height(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size)
    prof.disable()
    stats = pstats.Stats(prof)
    total = max(v[3] for v in stats.stats.values())
    top = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:8]
    profile = [(f"{Path(k[0]).name}:{k[2]}", v[2], 100.0 * v[2] / total) for k, v in top]
    return {"fit": (t_fit, fit), "fit_cpu": cpu, "mesh": (t_mesh, mesh), "coons": (t_coons, coons), "profile": profile,
            "total_profiled": total, "step": default_step((size, size))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a smoke run, not the figures)")
    args = parser.parse_args(argv)
    size, big, repeat = (128, 512, 1) if args.quick else (512, 2048, 3)
    with tempfile.TemporaryDirectory() as tmp:
        rows = accuracy(size, Path(tmp))
    sp = speed(big, repeat)

    acc = Table(
        ["scene", "depth (px)", "method", "max dev (% depth)", "rms dev (% depth)", "normals p99 (deg)",
         "normals mean (deg)", "patches", "time (s)"],
        [
            [name if m == "fit" else "", f"{depth:.2f}" if m == "fit" else "", m,
             f"{f[m]['max_dev_pct']:.2f}", f"{f[m]['rms_dev_pct']:.3f}", f"{f[m]['normal_p99_deg']:.2f}",
             f"{f[m]['normal_mean_deg']:.2f}", f[m]["n_patches"], f"{f[m]['seconds']:.3f}"]
            for name, depth, f in rows for m in ("fit", "coons")
        ],
        "lrlrrrrrr",
    )
    ratios = Table(
        ["scene", "max dev coons / fit", "normals p99 coons / fit", "normals mean coons / fit",
         "floor: height's own normals p99 / mean (deg)", "fit tolerance (% depth)", "pixels left out (jumps)"],
        [
            [name, f"{f['coons']['max_dev_pct'] / f['fit']['max_dev_pct']:.1f}",
             f"{f['coons']['normal_p99_deg'] / max(f['fit']['normal_p99_deg'], 1e-12):.1f}",
             f"{f['coons']['normal_mean_deg'] / max(f['fit']['normal_mean_deg'], 1e-12):.1f}",
             f"{f['floor']['normal_p99_deg']:.2f} / {f['floor']['normal_mean_deg']:.2f}",
             f"{f['fit']['tolerance_pct']:.2f}", f['fit']['excluded_px']]
            for name, _, f in rows
        ],
        "lrrrrrr",
    )
    slopes = Table(
        ["scene", "slope weight", "tolerance (% depth)", "max dev (% depth)", "normals mean (deg)",
         "normals p99 (deg)", "patches"],
        [
            [name, f"{r['slope_weight']:g}", f"{r['tolerance_pct']:.2f}", f"{r['max_dev_pct']:.2f}",
             f"{r['normal_mean_deg']:.2f}", f"{r['normal_p99_deg']:.2f}", r["n_patches"]]
            for name, _, f in rows for r in f.get("slopes", ())
        ],
        "lrrrrrr",
    )
    integrators = Table(
        ["scene", "integrate (s)", "floor mean / p99 (deg)", "tolerance (% depth)", "max dev (% depth)",
         "normals mean (deg)", "normals p99 (deg)", "patches"],
        [
            [name, f"{r['seconds']:.2f}", f"{f['floor']['normal_mean_deg']:.2f} / {f['floor']['normal_p99_deg']:.2f}",
             f"{r['tolerance_pct']:.2f}" + (" (given)" if r["given"] else " (default)"), f"{r['max_dev_pct']:.2f}",
             f"{r['normal_mean_deg']:.2f}", f"{r['normal_p99_deg']:.2f}", r["n_patches"]]
            for name, _, f in rows for r in f.get("integrator", ())
        ],
        "lrrrrrrr",
    )
    irls = Table(
        ["scene", "reweighting steps", "integrate CPU (s)", "floor mean / p99 (deg)", "tolerance (% depth)",
         "max dev (% depth)", "normals mean (deg)", "normals p99 (deg)", "patches", "pixels left out (jumps)"],
        [
            [name, r["iterations"], f"{r['cpu']:.2f}",
             f"{r['floor']['normal_mean_deg']:.2f} / {r['floor']['normal_p99_deg']:.2f}",
             f"{r['fit']['tolerance_pct']:.2f}", f"{r['fit']['max_dev_pct']:.2f}",
             f"{r['fit']['normal_mean_deg']:.2f}", f"{r['fit']['normal_p99_deg']:.2f}", r["fit"]["n_patches"],
             r["fit"]["excluded_px"]]
            for name, _, f in rows for r in f.get("irls", ())
        ],
        "lrrrrrrrrr",
    )
    t_fit, fit = sp["fit"]
    t_mesh, mesh = sp["mesh"]
    t_coons, coons = sp["coons"]
    speed_table = Table(
        ["task", "time (s)", "result"],
        [
            [f"fit_height {big} x {big} (default tolerance {fit.tolerance:.4f} mm, step {fit.step} px)",
             f"{t_fit:.2f}",
             f"{fit.patches.n_patches} patches {fit.patch_sizes()}, max dev {fit.max_deviation:.4f} mm; "
             f"CPU time {sp['fit_cpu']:.2f} s (best of {repeat}, all threads)"],
            [f"fit_mesh (lattice {fit.step / min(fit.step, 8):g} px)", f"{t_mesh:.2f}",
             f"{mesh.n_vertices} vertices, {mesh.n_triangles} triangles"],
            [f"height_to_patches (Coons, step {int(np.ceil(big / TARGET_PATCHES))} px)", f"{t_coons:.2f}",
             f"{coons.n_patches} patches"],
        ],
        "lrl",
    )
    profile = Table(["function (one fit, cProfile)", "own time (s)", "share (%)"],
                    [[name, f"{t:.3f}", f"{share:.0f}"] for name, t, share in sp["profile"]], "lrr")
    cmd = ".venv/bin/python benchmarks/bench_surface_fit.py" + (" --quick" if args.quick else "")
    load = os.getloadavg()[0]
    text = write_results(
        "surface_fit",
        "Surface step of photometric stereo: least-squares fit vs Coons grid (issue 16)",
        [
            f"`{cmd}`; {os.cpu_count()} cores, load average {load:.1f} at the end (shared machine).",
            "Each scene is reconstructed once (noise-free renders, 3 lights; the bear with all 14 "
            "images); both surface steps then run on the same height and slopes. Figures at every "
            "pixel centre inside the mask and at least 3 px from its border, evaluated on the patches; "
            "normals against the measured (solved) normals. The floor is the angle between the "
            "integrated height's own normals (central differences) and the measured normals: "
            "where height and normals disagree (non-integrable normals, a masked sphere's rim, "
            "the bear's DCT height), a surface within the tolerance of the height cannot follow "
            "the measured normals more closely than that.",
            acc,
            ratios,
            "## Slope weighting on the bear",
            "The fit against heavier slope weights (``slope_weight``; the default 1) at the default "
            "tolerance and at 0.05 % of the height range. The measured normals are not integrable: "
            "the lsq height is the least-squares integral of them, and no surface follows them much "
            "closer than its own normals do (the floor above); the DCT height is farther from them "
            "at low frequencies, and a surface that trades height for slopes gains there only by "
            "leaving the height beyond the 2 % figure. The default stays 1.",
            slopes,
            "## Integrators on the bear",
            "The bear's height from each integrator (``--integrator``), fitted at the default "
            "tolerance (with the slope check, then given: without it) and at 0.25 % and 0.1 % of "
            "the height range; the floor as above. ``robust`` "
            "(:func:`photometric.integrate.robust_least_squares`) weighs each grid edge by the curl "
            "beside it, then by its residual (least absolute deviations), so that the "
            "non-integrable slopes of the silhouette and of the depth jumps stay where they are "
            "instead of bending the whole height.",
            integrators,
            "The robust height is the closest to the measured normals on average (the lowest floor "
            "mean) but has the highest 99th percentile: it also cuts along noisy, non-integrable "
            "patches, and a fit cannot follow a cut within one pixel. On the bear the height's "
            "noise sets the default tolerance (about 1 % of the depth: the fur and the fine detail "
            "read as noise), and 8 px patches within it added about 0.8 deg to the mean. The fit's "
            "slope check (``slope_angle`` of :func:`surfaces.fit.fit_height`, on by default where "
            "the height's noise sets the tolerance) refines a cell of 4 px or more whose normals "
            "leave the measured ones by a mean angle more than 1 deg above the height's own "
            "normals; the \"given\" rows are the same tolerance passed explicitly, without the "
            "check. With it the robust height's surface follows the measured normals within 3 deg "
            "on average at the default tolerance; ``lsq`` and ``dct`` gain about as much from "
            "higher floors. The plates' default tolerances are set by their height ranges "
            "(noise-free renders; the 4 MP plate below), so the check is off there. The default "
            "integrator stays ``dct``: ``robust`` takes a sparse factorisation per step (meant for "
            "masked objects up to about a megapixel, not 4 MP plates), raises the 99th "
            "percentile, and the plates' and ``bench_photometric``'s figures are measured with "
            "``dct``; for a masked object with silhouettes choose ``--integrator robust`` (lowest "
            "mean: issue 16's 3 deg figure for the bear is met with it) or ``lsq`` (lowest 99th "
            "percentile).",
            "## Reweighting steps of the robust integrator",
            "The bear's robust integral after 0, 1 (the default), 3 and 8 reweighting steps (each "
            "one sparse LU towards the least absolute edge residuals; CPU time, BLAS on one "
            "thread), fitted at the default tolerance. More steps lower the edges' absolute "
            "residuals, not the mean normal angle: the floor's mean is lowest after one step, and "
            "the fitted surface's mean moves by hundredths of a degree while its 99th percentile, "
            "its largest deviation and the pixels left to the depth-jump detector grow with every "
            "step (the iterates cut along noise too), so the default stays one step.",
            irls,
            "## Speed",
            speed_table,
            f"Where the time of one fit goes (cProfile, {sp['total_profiled']:.2f} s under the profiler):",
            profile,
            "The noise estimate of the default tolerance (``height_noise``: the height minus its "
            "Gaussian-smoothed copy, 16 px on the 4 MP plate) was the largest item of the fit, "
            "four 129-tap filter passes (34 % of a fit, 0.78 s, in the run before): a full mask's "
            "weights are now separable (two 1-D filters) and the height's smoothing is one FFT "
            "convolution per axis, equal to the direct filter to rounding. Wall time follows the "
            "load of this shared machine; the CPU time is the fit's own.",
        ],
    )
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
