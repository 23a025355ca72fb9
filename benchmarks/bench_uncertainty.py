"""Benchmark of the measurement uncertainty (issue 17, ``photometric.uncertainty``).

1. Coverage, the test that matters: independent rendered trials of a 0.05 mm deep U-scratch
   (random sub-pixel place and axis) under lights whose TRUE directions deviate at random
   (0.5 deg standard uncertainty per tangent axis) with 0.2 % noise, reconstructed with the
   nominal lights and those tolerances stated
   (:func:`workbench.studies.uncertainty.coverage_study`). How often the stated 95 %
   intervals (k = 2) hold the true depth, width, length (and area, volume) and the true
   height at random pixels; linear propagation and Monte Carlo side by side, with their
   times. The same for a near-field rig (LEDs 150 mm away whose true positions deviate by
   0.5 mm per coordinate).
   Each coverage with its 95 % Wilson interval over the trials: a figure misses the 93-97 %
   target only when that interval lies wholly outside it.
2. The depth's grid error: the groove model of ``photometric.uncertainty.defects`` (exact
   slopes at the pixel centres, integrated and measured like the solve) by axis and by pixel
   size and width, and the coverage of the depth for a 0.10 mm and a 0.02 mm scratch.
3. Width, length, area: the coverage of the outline's quantisation term by its rule, on
   rasterised stadiums of the scratch.
4. Every orientation and sub-pixel place (issue 32): coverage of depth, width and length over
   random axes (axis-aligned included) and places, and at the worst place of an axis-aligned groove.
5. Not padded: the mean U of the depth next to the actual spread of the error.
6. Cost: a 4 MP reconstruction with and without the linear uncertainty, same run, best of 3.

Run: ``.venv/bin/python benchmarks/bench_uncertainty.py [--trials 200] [--mc-trials 200]
[--mc-samples 30] [--near-trials 200] [--size-trials 100] [--sweep-trials 200] [--workers 1]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import Table, write_results  # noqa: E402

from workbench.studies.uncertainty import TARGET_COVERAGE, coverage_study  # noqa: E402

FIGS = [("max_depth_mm", "depth (mm)"), ("mean_width_mm", "mean width (mm)"), ("length_mm", "length (mm)"),
        ("area_mm2", "area (mm²)"), ("volume_mm3", "volume (mm³)"), ("height", "height at random pixels (mm)")]


def coverage_cell(c: dict) -> str:
    low, high = c["coverage_interval"]
    mark = " (missed)" if c["missed_target"] else ""
    return f"{100 * c['coverage']:.1f} % [{100 * low:.1f}, {100 * high:.1f}]{mark}"


def coverage_rows(runs: list[tuple[str, dict]]) -> list[list[str]]:
    rows = []
    for key, label in FIGS:
        row = [label]
        for _, out in runs:
            c = out[key]
            row += [coverage_cell(c), f"{c['mean_U']:.5f}", f"{c['error_mean']:+.5f}", f"{c['error_sd']:.5f}"]
        rows.append(row)
    return rows


def grid_model_rows(rng_seed: int = 0) -> tuple[list[list[str]], list[list[str]]]:
    """The depth's grid error of the groove model: by axis (0.05 mm deep, 0.4 mm wide, 5 mm
    long, 0.05 mm pixels), and by pixel size and width over random axes; mean and spread
    over random sub-pixel placements (mm)."""
    import numpy as np

    from photometric.uncertainty.defects import _groove_depth_errors

    rng = np.random.default_rng(rng_seed)
    by_axis = []
    for axis in (0.0, 5.0, 15.0, 26.57, 30.0, 40.0, 44.0, 45.0, 46.0, 60.0, 90.0):
        e = _groove_depth_errors(0.05, 8.0, 100.0, axis, 0.05, rng.uniform(-0.5, 0.5, (48, 4)))
        by_axis.append([f"{axis:g}", f"{e.mean():+.5f}", f"{e.std(ddof=1):.5f}"])
    by_size = []
    for h, w in ((0.05, 0.4), (0.025, 0.4), (0.05, 0.8), (0.05, 0.2)):
        e = np.concatenate([_groove_depth_errors(0.05, w / h, 5.0 / h, rng.uniform(-90.0, 90.0), h,
                                                 rng.uniform(-0.5, 0.5, (4, 4))) for _ in range(40)])
        by_size.append([f"{h}", f"{w}", f"{0.05 * h / w:.5f}", f"{e.mean():+.5f}", f"{e.std(ddof=1):.5f}"])
    return by_axis, by_size


def length_rows(trials: int = 200, rng_seed: int = 0) -> list[list[str]]:
    """The length of stadiums rasterised at random axes and sub-pixel places (their pixel
    centres inside): the former extent of the centres plus one pixel against the sub-pixel
    length of :func:`photometric.defects._stadium_length`; error mean, sd and 95th percentile
    of |error| in pixels."""
    import math

    import numpy as np

    from photometric.defects import _stadium_length

    rng = np.random.default_rng(rng_seed)
    rows = []
    for w, length in ((8.0, 100.0), (8.0, 8.0), (16.0, 40.0), (3.0, 30.0)):
        old, new = [], []
        reach = int(0.5 * length + w) + 3
        y0, x0 = np.meshgrid(np.arange(-reach, reach + 1.0), np.arange(-reach, reach + 1.0), indexing="ij")
        for _ in range(trials):
            a = math.radians(rng.uniform(-90.0, 90.0))
            ux, uy = math.cos(a), math.sin(a)
            x, y = x0 - rng.uniform(-0.5, 0.5), y0 - rng.uniform(-0.5, 0.5)
            along = np.clip(x * ux + y * uy, -0.5 * (length - w), 0.5 * (length - w))
            inside = np.hypot(x - along * ux, y - along * uy) < 0.5 * w
            px, py = x0[inside] - x0[inside].mean(), y0[inside] - y0[inside].mean()
            axis = np.linalg.eigh(np.cov(np.stack([px, py])))[1][:, 1]
            s = px * axis[0] + py * axis[1]
            old.append(s.max() - s.min() + 1.0 - length)
            new.append(_stadium_length(float(s.size), float(s @ s), float(s.max() - s.min()), 1.0) - length)
        row = [f"{w:g} x {length:g}"]
        for e in (np.asarray(old), np.asarray(new)):
            row += [f"{e.mean():+.3f}", f"{e.std(ddof=1):.3f}", f"{np.percentile(np.abs(e), 95.0):.3f}"]
        rows.append(row)
    return rows


def outline_rule_rows(trials: int = 400, rng_seed: int = 0) -> list[list[str]]:
    """Coverage of the outline figures' U (width, length, area) over stadiums of the far-field
    scratch (8 x 100 px) rasterised at random axes and sub-pixel places, measured as the
    pipeline measures them (``_rasterised`` reproduces the rendered scratch's measures trial by
    trial): the quantisation model of each measured outline gives U by its errors at their
    largest (the budget's rule since issue 32: it holds at every sub-pixel place), by their
    95 % half-width (issue 17's rule: 95 % on average over places) and by the older
    max(2 sd, 95th percentile of |error|)."""
    import numpy as np

    from photometric.uncertainty import defects

    rng = np.random.default_rng(rng_seed)
    figs = ("mean_width_mm", "length_mm", "area_mm2")
    held = {f: [0, 0, 0] for f in figs}
    mean_u = {f: [0.0, 0.0, 0.0] for f in figs}
    errs = {f: [] for f in figs}
    for axis in rng.uniform(-90.0, 90.0, trials):
        v = defects._rasterised(8.0, 100.0, axis, 0.05, rng.uniform(-0.5, 0.5, (1, 2)))
        width, length, area = v["model"][0]
        truth = {"mean_width_mm": width, "length_mm": length, "area_mm2": area}
        rec = {"mean_width_mm": v["mean_width_mm"][0], "length_mm": v["length_mm"][0], "axis_deg": axis}
        for f, e in defects._quantisation(rec, 0.05, rng).items():
            err = v[f][0] - truth[f]
            errs[f].append(err)
            for j, U in enumerate((defects._every_phase_half_width(e, 0.0), defects._coverage_half_width(e, 0.0),
                                   max(2.0 * float(np.std(e, ddof=1)), float(np.percentile(np.abs(e), 95.0))))):
                held[f][j] += abs(err) <= U
                mean_u[f][j] += U / trials
    names = {"mean_width_mm": "mean width (mm)", "length_mm": "length (mm)", "area_mm2": "area (mm²)"}
    rows = []
    for f in figs:
        e = np.asarray(errs[f])
        rows.append([names[f], f"{100 * held[f][0] / trials:.1f} %", f"{mean_u[f][0]:.5f}",
                     f"{100 * held[f][1] / trials:.1f} %", f"{mean_u[f][1]:.5f}",
                     f"{100 * held[f][2] / trials:.1f} %", f"{mean_u[f][2]:.5f}", f"{e.std(ddof=1):.5f}",
                     f"{np.percentile(np.abs(e), 95.0):.5f}"])
    return rows


SWEEP_FIGS = (("max_depth_mm", "depth_mm", "depth"), ("mean_width_mm", "width_mm", "mean width"),
              ("length_mm", "length_mm", "length"))
#: The sweep's grooves: kind, width (mm); 0.05 mm deep, 3 mm long, 0.05 mm pixels.
SWEEP_GROOVES = (("V-scratch", 0.3), ("V-scratch", 0.6), ("U-scratch", 0.4))


def sweep_trial(rng, kind: str, width_mm: float, axis_deg: float, phase) -> dict | None:
    """One rendered groove at ``axis_deg`` and sub-pixel place ``phase`` (rows, cols), lights
    deviated by 0.5 deg per tangent axis and 0.2 % noise, reconstructed with the nominal lights:
    per figure ``(error, U)``."""
    import math

    from datasets_synthetic.heightfields import u_scratch, v_crack
    from datasets_synthetic.render import render
    from photometric.lights import ring_lights
    from photometric.pipeline import reconstruct
    from photometric.uncertainty.propagation import perturbed_lights

    h, L = 0.05, ring_lights(3, 45.0)
    make = v_crack if kind.startswith("V") else u_scratch
    centre = (60.0 + float(rng.integers(-3, 4)) + phase[0], 60.0 + float(rng.integers(-3, 4)) + phase[1])
    hf = make(120, h, depth_mm=0.05, width_mm=width_mm, length_mm=3.0, center_px=centre, axis_deg=axis_deg)
    images = render(hf, perturbed_lights(L, math.radians(0.5), rng), albedo=0.8, noise=0.002, seed=rng)
    tol = {"noise_sigma": 0.002, "light_tolerance_deg": 0.5, "seed": int(rng.integers(1 << 31))}
    res = reconstruct(images, lights=L, pixel_size=h, uncertainty=tol)
    if not res.defects:
        return None
    rec, k2, truth = res.defects[0], res.uncertainty.defects[0]["uncertainty_k2"], hf.defects[0]
    return {fig: (rec[fig] - truth[key], k2[fig]) for fig, key, _ in SWEEP_FIGS}


def sweep_rows(trials: int = 200, rng_seed: int = 32) -> tuple[list[list[str]], list[list[str]], float]:
    """Coverage of depth, width and length over random orientations (0-180 deg; one trial in
    four exactly axis-aligned, 0 or 90 deg) and random sub-pixel places, per groove of
    :data:`SWEEP_GROOVES`; and at the worst place of an axis-aligned groove (bottom between
    two pixel rows or columns, 24 trials each). Returns the two tables' rows and the seconds."""
    import numpy as np

    from workbench.studies.uncertainty import coverage_interval

    rng = np.random.default_rng(rng_seed)
    t0 = time.perf_counter()
    rows, worst = [], []
    for kind, width in SWEEP_GROOVES:
        for label, n, table in (("random", trials, rows), ("worst", 24, worst)):
            results = []
            for i in range(n):
                if label == "random":
                    axis = float(rng.choice([0.0, 90.0])) if i % 4 == 0 else float(rng.uniform(0.0, 180.0))
                    phase = rng.uniform(0.0, 1.0, 2)
                else:
                    axis, phase = (0.0, 90.0)[i % 2], (0.5, 0.5)
                out = sweep_trial(rng, kind, width, axis, phase)
                if out is not None:
                    results.append(out)
            row = [f"{kind} {width} mm ({width / 0.05:g} px)", f"{len(results)} / {n}"]
            for fig, _, _ in SWEEP_FIGS:
                e = np.array([r[fig][0] for r in results])
                U_ = np.array([r[fig][1] for r in results])
                hits = int(np.sum(np.abs(e) <= U_))
                low, high = coverage_interval(hits, len(results))
                row += [f"{100 * hits / len(results):.1f} % [{100 * low:.1f}, {100 * high:.1f}]",
                        f"{U_.mean():.5f}", f"{e.mean():+.5f}", f"{np.abs(e).max():.5f}"]
            table.append(row)
    return rows, worst, time.perf_counter() - t0


def pixel_area_rows(trials: int = 40, rng_seed: int = 33, supersample: int = 4) -> list[list[str]]:
    """Coverage when each pixel integrates its area (as a camera, and Mitsuba's samples per
    pixel, do; our renderer samples the pixel centre): grooves rendered ``supersample`` times
    finer and averaged over each pixel's block, random axes (one in three exactly 0 or 90 deg)
    and places, 0.2 % noise; reconstructed with ``pixel_area`` False (the former model: centre
    sampling) and True (stated)."""
    import numpy as np

    from datasets_synthetic.heightfields import u_scratch, v_crack
    from datasets_synthetic.render import render
    from photometric.lights import ring_lights
    from photometric.pipeline import reconstruct
    from workbench.studies.uncertainty import coverage_interval

    rng = np.random.default_rng(rng_seed)
    h, L, S, n = 0.05, ring_lights(3, 45.0), int(supersample), 120
    rows = []
    for kind, width in (("U-scratch", 0.4), ("V-scratch", 0.3)):
        make = v_crack if kind.startswith("V") else u_scratch
        found = {False: [], True: []}
        for i in range(trials):
            axis = float(rng.choice([0.0, 90.0])) if i % 3 == 0 else float(rng.uniform(0.0, 180.0))
            phase = rng.uniform(0.0, 1.0, 2)
            centre = (S * (60.0 + phase[0]) + 0.5 * (S - 1), S * (60.0 + phase[1]) + 0.5 * (S - 1))
            hf = make(n * S, h / S, depth_mm=0.05, width_mm=width, length_mm=3.0, center_px=centre, axis_deg=axis)
            fine = render(hf, L, albedo=0.8)
            images = fine.reshape(fine.shape[0], n, S, n, S).mean(axis=(2, 4))
            images = (images + rng.normal(0.0, 0.002, images.shape)).astype(np.float32)
            truth = hf.defects[0]
            for area in found:
                res = reconstruct(images, lights=L, pixel_size=h,
                                  uncertainty={"noise_sigma": 0.002, "pixel_area": area, "seed": i})
                if res.defects:
                    rec, k2 = res.defects[0], res.uncertainty.defects[0]["uncertainty_k2"]
                    found[area].append({fig: (rec[fig] - truth[key], k2[fig]) for fig, key, _ in SWEEP_FIGS})
        for area, results in found.items():
            row = [f"{kind} {width} mm", "yes" if area else "no", f"{len(results)} / {trials}"]
            for fig, _, _ in SWEEP_FIGS:
                e = np.array([r[fig][0] for r in results])
                U_ = np.array([r[fig][1] for r in results])
                hits = int(np.sum(np.abs(e) <= U_))
                low, high = coverage_interval(hits, len(results))
                row += [f"{100 * hits / len(results):.1f} % [{100 * low:.1f}, {100 * high:.1f}]", f"{U_.mean():.5f}",
                        f"{e.mean():+.5f}"]
            rows.append(row)
    return rows


def cost(size: int = 2048, repeat: int = 3) -> tuple[float, float, dict]:
    """Best-of times of the reconstruction without and with the linear uncertainty (4 MP)."""
    from datasets_synthetic.heightfields import u_scratch
    from datasets_synthetic.render import render
    from photometric.lights import ring_lights
    from photometric.pipeline import reconstruct
    from photometric.uncertainty import Tolerances

    L = ring_lights(3, 45.0)
    hf = u_scratch(size, 0.01, depth_mm=0.05, width_mm=0.4, length_mm=5.0, axis_deg=20.0)
    images = render(hf, L, albedo=0.8, noise=0.002, seed=0)
    del hf
    plain, extra, stages = [], [], {}
    tol = Tolerances(noise_sigma=0.002, light_tolerance_deg=0.5)
    for _ in range(repeat):
        res = reconstruct(images, lights=L, pixel_size=0.01)
        plain.append(res.summary["timings_s"]["total"])
        res = reconstruct(images, lights=L, pixel_size=0.01, uncertainty=tol)
        extra.append(res.summary["timings_s"]["uncertainty"])
        if extra[-1] == min(extra):
            stages = res.summary["uncertainty"]["timings_s"]
    return min(plain), min(extra), stages


def _study(spec: tuple[str, dict]) -> tuple[str, dict]:
    name, kwargs = spec
    return name, coverage_study(**kwargs)


def main(argv=None) -> str:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--mc-trials", type=int, default=200)
    ap.add_argument("--mc-samples", type=int, default=30)
    ap.add_argument("--near-trials", type=int, default=200)
    ap.add_argument("--size-trials", type=int, default=100, help="trials of the 0.10 and 0.02 mm scratches")
    ap.add_argument("--size", type=int, default=2048, help="image side of the cost benchmark")
    ap.add_argument("--sweep-trials", type=int, default=200,
                    help="trials per groove of the orientation x phase sweep (issue 32)")
    ap.add_argument("--area-trials", type=int, default=40,
                    help="trials per groove rendered with pixels that integrate their area (issue 32)")
    ap.add_argument("--workers", type=int, default=1, help="processes for the coverage studies (the cost runs alone)")
    args = ap.parse_args(argv)

    specs = [("far linear", {"n_trials": args.trials, "method": "linear", "seed": 17}),
             ("far mc", {"n_trials": args.mc_trials, "method": "montecarlo", "mc_samples": args.mc_samples,
                         "seed": 17}),
             ("near", {"n_trials": args.near_trials, "method": "linear", "rig": "near", "seed": 18}),
             *[(f"{d} mm", {"n_trials": args.size_trials, "method": "linear", "depth_mm": d, "seed": 19})
               for d in (0.10, 0.02)]]
    if args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            done = dict(pool.map(_study, specs))
    else:
        done = dict(map(_study, specs))
    far = [("linear", done["far linear"]), ("Monte Carlo", done["far mc"])]
    near = [("linear", done["near"])]
    sizes = [(f"{d} mm", done[f"{d} mm"]) for d in (0.10, 0.02)]
    by_axis, by_size = grid_model_rows()
    by_length = length_rows()
    by_rule = outline_rule_rows()
    sweep, sweep_worst, sweep_s = sweep_rows(args.sweep_trials)
    area = pixel_area_rows(args.area_trials)
    t_plain, t_unc, stages = cost(args.size)

    def head(runs):
        cols = ["figure"]
        for name, _ in runs:
            cols += [f"{name}: coverage [95 % interval]", f"{name}: mean U", f"{name}: error mean",
                     f"{name}: error sd"]
        return cols

    def timing(runs):
        return Table(["method", "trials", "missed", "study (s)", "per trial (s)", "uncertainty per trial (s)"],
                     [[name, out["trials"], out["missed"], f"{out['seconds']:.1f}", f"{out['seconds_per_trial']:.3f}",
                       f"{out['uncertainty_seconds_per_trial']:.3f}"] for name, out in runs], "lrrrrr")

    lin = far[0][1]
    depth = lin["max_depth_mm"]
    opts = lin["options"]
    parts = [
        f"U-scratch {opts['depth_mm']} mm deep, {opts['width_mm']} mm wide, {opts['length_mm']} mm long on a "
        f"{opts['size']} x {opts['size']} px plate ({opts['pixel_size']} mm pixels, albedo {opts['albedo']}), "
        f"random sub-pixel centre and axis per trial; {opts['n_lights']} lights at {opts['slant_deg']:g} deg slant. "
        f"Each trial renders with the TRUE lights (each deviated by independent tangent errors of "
        f"{opts['light_tolerance_deg']} deg standard deviation per axis) and {100 * opts['noise']:.1f} % noise, "
        "reconstructs with the nominal lights and states those tolerances; coverage is the fraction of the "
        f"stated 95 % intervals (value ± U, k = 2) that hold the truth ({opts['pixels_per_trial']} random pixels "
        "per trial for the height, zero mean over the valid pixels as the integrator states it). Target: "
        f"{100 * TARGET_COVERAGE[0]:.0f}-{100 * TARGET_COVERAGE[1]:.0f} % for depth, width, length and height. Each "
        "coverage is given with its 95 % Wilson interval over the trials (the independent units; the height's "
        "pixels of one trial share its lights, so the trials count); a figure misses the target only when that "
        "interval lies wholly outside the band (marked). Shared 2-core machine.",
        "## Far field: coverage, linear and Monte Carlo side by side",
        Table(head(far), coverage_rows(far), "l" + "rrrr" * len(far)),
        timing(far),
        f"Monte Carlo repeats the fast solve {args.mc_samples} times per trial (lights, noise added to the images).",
        "## The depth's grid error: why the depth read deep, and its place in the budget",
        "Without noise and light errors the measured depth of the rendered scratch is already off, by an amount "
        "that depends on the axis and the sub-pixel place: the renderer (like the camera's solve) gives the exact "
        "slopes at the pixel centres, and the U-groove's slope steps from 0 to 4 D / w at its rim. Between the "
        "last centre outside and the first inside, the trapezoidal edges of the integrator take half the inner "
        "slope, whatever the rim's place f between them: a first-order height error (2 D h / w)(1 - 2 f) per "
        "rim, plus a second-order -(4 D h^2 / w^2) f (1 - f) (shallower, -2/3 D h^2 / w^2 on average). Along an "
        "oblique groove f changes from pixel to pixel, so the error wanders along the bottom, and the depth, the "
        "deepest pixel, picks its largest excursion: deeper on average. Where the axis is near 45 deg (and other "
        "small rational slopes of the grid) the rim's staircase repeats and the excursion is large and of one "
        "sign. The budget now carries this grid error from a model of the defect (a parabolic-section groove of "
        "the measured depth, mean width, length and axis; exact slopes at the pixel centres, integrated and "
        "measured like the solve, 8-24 random sub-pixel placements): its spread as `discretisation` and its mean "
        "as an uncorrected bias (`method_bias`, the u_b whose k = 2 interval with every other term holds 95 % of "
        "the shifted errors, GUM F.2.4.5; since issue 32 at the placement of the largest error, as the phase of "
        "one defect is fixed); the value is not corrected, as the groove's section is an assumption. "
        "It replaces the former half-pixel sampling term. The model follows the rendered scratch through the "
        "whole pipeline axis by axis (test_groove_depth_model_matches_the_rendered_scratch) and scales with D "
        "and h / w.",
        Table(["axis (deg)", "mean error (mm)", "spread (mm)"], by_axis, "rrr"),
        "The groove model by axis: 0.05 mm deep, 0.4 mm wide, 5 mm long, 0.05 mm pixels, 48 placements each.",
        Table(["pixel (mm)", "width (mm)", "D h / w (mm)", "mean error (mm)", "spread (mm)"], by_size, "rrrrr"),
        "The groove model over random axes (40 axes x 4 placements): the error follows D h / w.",
        Table(["scratch depth", "depth: coverage [95 % interval]", "mean U", "error mean", "error sd"],
              [[label] + coverage_rows([(label, run)])[0][1:] for label, run in sizes], "lrrrr"),
        f"Depth coverage of a 0.10 mm and a 0.02 mm scratch (same scene otherwise, linear, "
        f"{sizes[0][1]['trials']} trials each): the same model holds.",
        "## Length: the pixel grid alone, measured to a sub-pixel",
        "The length's error comes from the pixel quantisation of the outline alone: noise and light errors move "
        "the slope footprint by nothing here (the rim's slope, 4 D / w = 0.5, is far above the footprint "
        "threshold), so linear and Monte Carlo see the same length errors trial by trial (same error mean and "
        "sd above), and the extra Monte Carlo samples cannot change them. Their coverages differ only by the "
        "random sub-pixel draws of the quantisation model that sets U and by the binomial spread of the trials "
        "(their 95 % intervals above; about ±1.5 % at 200).",
        "The length was the extent of the region's pixel centres along its axis plus one pixel. That is right on "
        "average for an axis along the grid (each end lies between 0 and 1 pixel beyond its outermost centre), "
        "but on an oblique axis the centres' projections fill the axis densely and the true ends lie just beyond "
        "the outermost ones: plus one pixel read about 0.4 pixel (0.020 mm) long on average, stated only as a "
        "`method_bias` (linear coverage 92.5 %, Monte Carlo 90.0 % over 200 trials). GUM corrects a known "
        "systematic effect, and here the measure can be made unbiased at the source: pixel counts are unbiased "
        "samples of the outline's area and of its second moment along the axis (at a random sub-pixel place), "
        "and the length is now that of the stadium (rectangle with half-disc ends) with the region's area and "
        "second moment, kept between the extent of the centres and that plus two pixels "
        "(`photometric.defects._stadium_length`). The quantisation model of the budget measures its rasterised "
        "stadiums the same way. The mean width, the pixels of the central half of that length per pixel of half "
        "the length, follows it.",
        Table(["stadium w x L (px)", "extent + 1: error mean", "sd", "95 % |error|", "sub-pixel: error mean", "sd",
               "95 % |error|"], by_length, "lrrrrrr"),
        "Stadiums rasterised at 200 random axes and sub-pixel places each (their pixel centres inside), errors "
        "in pixels. Short round regions (8 x 8, a dent) keep a smaller long bias: their principal axis is "
        "the direction of the larger of two nearly equal moments, and a moment below the disc's reads as the "
        "disc; both lift the length.",
        "## Width, length, area: the outline's quantisation in the budget",
        "Their errors come from the pixel quantisation of the outline: bounded, flat-topped and skewed "
        "(the outline moves in steps of the pixel pitch projected on the axis), far from normal. A k = 2 "
        "interval on their standard deviation over-covers such an error (a uniform one of half-range a: 2 sd = "
        "1.15 a holds 100 %), so, as GUM-S1 takes a coverage interval from the distribution itself, issue 17 "
        "took U as the 95 % half-width of the quantisation model's errors (the measured outline, a stadium, "
        "rasterised at random sub-pixel places, widths and lengths; bias included) convolved with the Gaussian "
        "of the other terms (pixel size; Monte Carlo's spread). That holds 95 % on average over places, but the "
        "place of one defect is fixed: an axis-aligned outline at the worst place reads its largest error at "
        "every trial (issue 32). Since issue 32 U is the 95 % half-width of Normal(max |e|, others), the "
        "largest error of the model's placements (random ones plus the grid's symmetry points), so it holds "
        "at every place and covers more than 95 % on average. The budget states it as the `discretisation` "
        "term's effective standard uncertainty, the u_q for which 2 sqrt(u_q^2 + sum of the others' u^2) is "
        "that half-width, so it still sums with k = 2. One rule for the three figures. The table compares the "
        "rules on the far-field scratch's outline alone (the length and width of the rendered scratch equal "
        "those of its rasterised stadium trial by trial).",
        Table(["figure", "every place (now): coverage", "mean U", "95 % half-width (issue 17): coverage", "mean U",
               "max(2 sd, 95 %): coverage", "mean U", "error sd", "95 % |error|"], by_rule, "lrrrrrrrr"),
        "Stadiums of 8 x 100 px (0.05 mm pixels) at 400 random axes and sub-pixel places; the truth is the "
        "stadium's own width, length and area.",
        "## Every orientation and sub-pixel place (issue 32)",
        "The coverage figures above use oblique grooves at random places, which average the grid error over "
        "the phase. For one defect the phase is fixed: an axis-aligned V-scratch whose bottom lies between two "
        "pixel rows reads the same shallow depth at every trial (9-12 % here), and a 6 px one the same long "
        "length (+0.6 px); the 95 % quantile of the errors over random placements, the former rule, held them "
        "in 6 of 20 trials (depth) and never (that length). The grid terms of depth, width, length and area "
        "now take U from the LARGEST error of the model's placements (the 95 % half-width of "
        "Normal(max |e|, others); the outline model adds placements on the grid's symmetry points), so the "
        "interval holds at every placement; over random placements it then covers more than 95 %.",
        Table(["groove", "trials", *[f"{name}: {col}" for _, _, name in SWEEP_FIGS
                                     for col in ("coverage [95 % interval]", "mean U", "error mean", "max |error|")]],
              sweep, "lr" + "rrrr" * len(SWEEP_FIGS)),
        f"Random orientations in 0-180 deg (one trial in four exactly 0 or 90 deg) and random sub-pixel "
        f"places; 0.05 mm deep, 3 mm long grooves, 0.05 mm pixels, 3 lights at 45 deg deviated by 0.5 deg, "
        f"0.2 % noise, linear propagation ({sweep_s:.0f} s for the sweep, both tables).",
        Table(["groove", "trials", *[f"{name}: {col}" for _, _, name in SWEEP_FIGS
                                     for col in ("coverage [95 % interval]", "mean U", "error mean", "max |error|")]],
              sweep_worst, "lr" + "rrrr" * len(SWEEP_FIGS)),
        "The worst place: axis exactly 0 or 90 deg, the groove's centre between two pixel rows and columns.",
        "### Pixels that integrate their area (as a camera, and Mitsuba's samples per pixel, do)",
        "Our renderer samples each pixel at its centre; a camera's pixel (and a Mitsuba render with several "
        "samples per pixel) averages its area, a box blur of 0.29 px standard deviation. The slope footprint "
        "then reads about a pixel wider and longer (its threshold is crossed half a pixel before the rim on "
        "each side), which the centre-sampling model of width and length did not know: why their U never "
        "covered the error in the Mitsuba renders of issue 32. Stated (`Tolerances.pixel_area`), the budget "
        "takes the widening off the outline it rasterises and adds it to its errors as a bias (not corrected in "
        "the value), and the depth's groove model averages its slopes over each pixel (4 x 4 samples).",
        Table(["groove", "pixel_area stated", "trials",
               *[f"{name}: {col}" for _, _, name in SWEEP_FIGS for col in ("coverage [95 % interval]", "mean U",
                                                                          "error mean")]],
              area, "lrr" + "rrr" * len(SWEEP_FIGS)),
        f"Rendered 4 x 4 times finer and averaged over each pixel; 0.05 mm deep, 3 mm long, 0.05 mm pixels, "
        f"exact lights, 0.2 % noise; {args.area_trials} trials per groove, the same images for both rows.",
        "## Near field (LEDs 150 mm away, 0.5 mm standard uncertainty per coordinate, orthographic camera)",
        Table(head(near), coverage_rows(near), "l" + "rrrr" * len(near)),
        timing(near),
        "## Not padded: the depth's U against the actual error",
        Table(["quantity", "value"], [
            ["true depth (mm)", f"{opts['depth_mm']}"],
            ["mean U of the depth, linear (mm)", f"{depth['mean_U']:.5f}"],
            ["mean U / depth", f"{100 * depth['mean_U'] / opts['depth_mm']:.1f} % (limit 40 %)"],
            ["error of the depth: mean (mm)", f"{depth['error_mean']:.5f}"],
            ["error of the depth: standard deviation (mm)", f"{depth['error_sd']:.5f}"],
            ["error of the depth: RMS (mm)", f"{depth['error_rms']:.5f}"],
            ["2 x RMS / mean U", f"{2 * depth['error_rms'] / depth['mean_U']:.2f}"],
        ], "lr"),
        f"## Cost: {args.size} x {args.size} px ({args.size * args.size / 1e6:.1f} MP) reconstruction, best of 3",
        Table(["run", "time (s)"], [
            ["reconstruction without uncertainty (read, solve, integrate, surface, defects)", f"{t_plain:.2f}"],
            ["linear uncertainty added", f"{t_unc:.2f}"],
            ["ratio", f"{100 * t_unc / t_plain:.0f} % (limit 50 %)"],
            *[[f"uncertainty stage: {k}", f"{v:.2f}"] for k, v in stages.items()],
        ], "lr"),
    ]
    return write_results("uncertainty", "Measurement uncertainty (photometric.uncertainty)", parts)


if __name__ == "__main__":
    t0 = time.perf_counter()
    print(main())
    print(f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
