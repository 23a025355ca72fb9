"""Benchmark: bicubic B-spline surface interpolation + evaluation against geomdl.

A 50 x 50 grid is interpolated (seed 003, two-stage global interpolation, chord
length parameters, averaged knots) and the surface is evaluated at 250,000
random parameter pairs, by ``surfaces.bspline`` and by geomdl
(``fitting.interpolate_surface`` + ``evaluate_list``) in the same run. geomdl
evaluates one point at a time in pure Python; by default it evaluates all the
points (about 10 s); ``--geomdl-points M`` times it on a subsample and
extrapolates linearly (the table says so). The two results are compared point
by point.

Run: ``.venv/bin/python benchmarks/bench_bspline.py [--points N] [--geomdl-points M]``.
Writes ``benchmarks/results/bspline.md`` and prints it.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from common import Table, best_of, write_results

from surfaces import bspline


def _grid(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.uniform(0.5, 1.5, n))
    y = np.cumsum(rng.uniform(0.5, 1.5, n))
    gx, gy = np.meshgrid(x, y, indexing="ij")
    z = np.sin(gx / 4.0) * np.cos(gy / 5.0) + 0.05 * rng.standard_normal(gx.shape)
    return np.stack([gx, gy, z], axis=-1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=50, help="grid size n (n x n points)")
    parser.add_argument("--points", type=int, default=250_000, help="evaluation points")
    parser.add_argument(
        "--geomdl-points",
        type=int,
        default=None,
        help="evaluate only this many points with geomdl and extrapolate (default: all)",
    )
    parser.add_argument("--repeats", type=int, default=3, help="best-of repeats for ours")
    args = parser.parse_args()

    from geomdl import fitting

    q = _grid(args.grid)
    rng = np.random.default_rng(1)
    uv = rng.uniform(0.0, 1.0, (args.points, 2))
    n_sub = min(args.geomdl_points or args.points, args.points)
    sub = uv[:n_sub]

    t_fit, surf = best_of(lambda: bspline.interpolate_surface(q, degree=3), args.repeats)
    t_eval, ours = best_of(lambda: surf.evaluate(uv[:, 0], uv[:, 1]), args.repeats)
    t_bez, _ = best_of(surf.to_bezier, args.repeats)

    flat = q.reshape(-1, 3).tolist()
    t0 = time.perf_counter()
    peer = fitting.interpolate_surface(flat, args.grid, args.grid, 3, 3)
    g_fit = time.perf_counter() - t0
    t0 = time.perf_counter()
    theirs = np.array(peer.evaluate_list(sub.tolist()))
    g_eval_sub = time.perf_counter() - t0
    g_eval = g_eval_sub * args.points / n_sub
    diff = float(np.max(np.abs(theirs - ours[: n_sub])))

    total_ours = t_fit + t_eval
    total_geomdl = g_fit + g_eval
    if n_sub < args.points:
        how = (
            f"geomdl evaluated {n_sub:,} points, extrapolated linearly to {args.points:,} "
            "(it evaluates one point at a time in pure Python)."
        )
        g_cell = f"{g_eval:.2f} (extrapolated from {g_eval_sub:.2f} s)"
    else:
        how = "geomdl evaluated every point."
        g_cell = f"{g_eval:.2f}"
    table = Table(
        ["step", "surfaces.bspline (s)", "geomdl (s)", "speed-up"],
        [
            [f"interpolate {args.grid}x{args.grid}", f"{t_fit:.4f}", f"{g_fit:.3f}", f"{g_fit / t_fit:.0f}x"],
            [f"evaluate {args.points:,} points", f"{t_eval:.4f}", g_cell, f"{g_eval / t_eval:.0f}x"],
            ["**total**", f"**{total_ours:.4f}**", f"**{total_geomdl:.2f}**", f"**{total_geomdl / total_ours:.0f}x**"],
            [f"exact conversion to {surf.to_bezier().shape} Bezier patches", f"{t_bez:.4f}", "n/a", ""],
        ],
        align="lrrr",
    )
    text = write_results("bspline", "B-spline surface interpolation: surfaces.bspline vs geomdl", [
        f"{args.grid} x {args.grid} grid, bicubic, chord-length parameters, averaged knots; "
        f"{args.points:,} random (u, v) evaluations, same points for both. Ours: best of "
        f"{args.repeats}; geomdl: one run. {how}",
        table,
        "Largest coordinate difference between the two surfaces at the points geomdl "
        f"evaluated: {diff:.2e}.",
        f"Machine: {platform.machine()}, {os.cpu_count()} logical CPUs (shared, timings noisy), "
        f"Python {platform.python_version()}, numpy {np.__version__}.",
        "Command: `.venv/bin/python benchmarks/bench_bspline.py`",
    ])
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
