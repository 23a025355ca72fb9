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
2. Not padded: the mean U of the depth next to the actual spread of the error.
3. Cost: a 4 MP reconstruction with and without the linear uncertainty, same run, best of 3.

Run: ``.venv/bin/python benchmarks/bench_uncertainty.py [--trials 200] [--mc-trials 200]
[--mc-samples 30] [--near-trials 200]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import Table, write_results  # noqa: E402

from workbench.studies.uncertainty import coverage_study  # noqa: E402

FIGS = [("max_depth_mm", "depth (mm)"), ("mean_width_mm", "mean width (mm)"), ("length_mm", "length (mm)"),
        ("area_mm2", "area (mm²)"), ("volume_mm3", "volume (mm³)"), ("height", "height at random pixels (mm)")]


def coverage_rows(runs: list[tuple[str, dict]]) -> list[list[str]]:
    rows = []
    for key, label in FIGS:
        row = [label]
        for _, out in runs:
            c = out[key]
            row += [f"{100 * c['coverage']:.1f} %", f"{c['mean_U']:.5f}", f"{c['error_sd']:.5f}"]
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


def main(argv=None) -> str:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--mc-trials", type=int, default=200)
    ap.add_argument("--mc-samples", type=int, default=30)
    ap.add_argument("--near-trials", type=int, default=200)
    ap.add_argument("--size", type=int, default=2048, help="image side of the cost benchmark")
    args = ap.parse_args(argv)

    far = [("linear", coverage_study(args.trials, "linear", seed=17))]
    far.append(("Monte Carlo", coverage_study(args.mc_trials, "montecarlo", mc_samples=args.mc_samples, seed=17)))
    near = [("linear", coverage_study(args.near_trials, "linear", rig="near", seed=18))]
    t_plain, t_unc, stages = cost(args.size)

    def head(runs):
        cols = ["figure"]
        for name, _ in runs:
            cols += [f"{name}: coverage", f"{name}: mean U", f"{name}: error sd"]
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
        "per trial for the height, zero mean over the valid pixels as the integrator states it). Target: 93-97 % "
        "for depth, width, length and height. Shared 2-core machine.",
        "## Far field: coverage, linear and Monte Carlo side by side",
        Table(head(far), coverage_rows(far), "l" + "rrr" * len(far)),
        timing(far),
        f"Monte Carlo repeats the fast solve {args.mc_samples} times per trial (lights, noise added to the images).",
        "## Near field (LEDs 150 mm away, 0.5 mm standard uncertainty per coordinate, orthographic camera)",
        Table(head(near), coverage_rows(near), "l" + "rrr" * len(near)),
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
