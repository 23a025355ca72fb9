"""Benchmark of the light-deviation error analysis (issue 5, seed 002(a)).

Peers in the same run:
1. Error map over two deviations: the closed-form exact model
   (``photometric.errors.error_map``) against the empirical way of a lab study:
   render the derivative square under each deviated light set and solve it with
   ``photometric.stereo.solve`` (the workbench's own least-squares solver), one
   deviation at a time. Speed ratio and the largest disagreement.
2. Monte Carlo: vectorised ``monte_carlo`` against a plain Python loop that builds
   the deviated lights and solves ``np.linalg.solve`` per sample.
3. Tolerance inversion: Brent's method (``max_deviation``) against a dense scan of
   the deviation in 0.001 deg steps.
4. Accuracy of the first-order model (relative difference to the exact error) against
   the deviation size, and the recommended operating limits for three triads.
Times are the best of 3 runs (the machine is shared).

Run: ``.venv/bin/python benchmarks/bench_errors.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import Table, best_of, write_results  # noqa: E402

from photometric import errors as E  # noqa: E402
from photometric.lights import condition_number, deviate_lights, ring_lights, rotate_lights  # noqa: E402
from photometric.normals import normals_from_slopes  # noqa: E402
from photometric.stereo import solve  # noqa: E402

BEAR = Path(__file__).resolve().parents[2] / "shared" / "data" / "diligent_bear" / "light_directions.txt"


def bench_map(L, n_dev=21, n_normals=41, dmax=5.0):
    p, q = E.derivative_square(1.0, n_normals)
    t_ours, m = best_of(lambda: E.error_map(L, p, q, (0, "slant"), (1, "slant"), dmax, n_dev))
    normals = normals_from_slopes(p, q)

    def empirical():
        v = np.linspace(-dmax, dmax, n_dev)
        out = np.empty((n_dev, n_dev))
        for i, d2 in enumerate(v):
            for j, d1 in enumerate(v):
                dev = np.zeros((3, 2))
                dev[0, 0], dev[1, 0] = d1, d2
                Lt = deviate_lights(L, dev)
                images = np.einsum("kc,hwc->khw", Lt, normals).astype(np.float32)  # linear model, no clipping
                res = solve(images, L)
                out[i, j] = np.abs(res.p - p).max()
        return out

    t_peer, emp = best_of(empirical, repeat=1)
    return t_ours, t_peer, float(np.abs(emp - m.max_dp).max()), n_dev * n_dev * n_normals * n_normals


def bench_mc(L, samples=20000):
    p = np.array([0.0, 0.5, 1.0, 0.0, 1.0, -1.0])
    q = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 0.5])
    t_ours, mc = best_of(lambda: E.monte_carlo(L, 1.0, p, q, samples, seed=0))
    angle, direction = E.random_deviations(3, 1.0, samples, seed=0)
    n = np.stack([-p, -q, np.ones_like(p)], axis=0)

    def loop():
        dp = np.empty((samples, p.size))
        for s in range(samples):
            Lt = rotate_lights(L, angle[s], direction[s])
            m = np.linalg.solve(L, Lt @ n)
            dp[s] = -m[0] / m[2] - p
        return dp

    t_peer, dp = best_of(loop, repeat=1)
    return t_ours, t_peer, float(np.abs(dp - mc.dp).max())


def bench_tolerance(L):
    t_ours, tol = best_of(lambda: E.max_deviation(L, 0.05, 1.0, (0,), "slant", n_grid=21))

    def scan():
        grid = np.arange(0.0, 5.0, 0.001)
        p, q = E.derivative_square(1.0, 21)
        dev = np.zeros((grid.size, 2, 3, 2))
        dev[:, 0, 0, 0], dev[:, 1, 0, 0] = grid, -grid
        ex = E.exact_error(L, deviate_lights(L, dev), p, q)
        worst = np.maximum(np.abs(ex.dp), np.abs(ex.dq)).reshape(grid.size, -1).max(axis=1)
        return grid[np.argmax(worst > 0.05)] - 0.001

    t_peer, limit = best_of(scan, repeat=1)
    return t_ours, t_peer, tol.value, float(limit)


def first_order_accuracy(L):
    p, q = E.derivative_square(1.0, 41)
    rows = []
    for d in (0.5, 1.0, 2.0, 5.0, 10.0):
        worst = 0.0
        for k in range(3):
            for j in range(2):
                dev = np.zeros((3, 2))
                dev[k, j] = d
                ex = E.exact_error(L, deviate_lights(L, dev), p, q)
                fp, fq = E.first_order_error(L, dev, p, q)
                for a, b in ((ex.dp, fp), (ex.dq, fq)):
                    if np.abs(a).max() > 1e-12:
                        worst = max(worst, float(np.abs(a - b).max() / np.abs(a).max()))
        rows.append((d, worst))
    return rows


def main() -> str:
    L45 = ring_lights(3, 45.0)
    speed = []
    t1, t2, diff, evals = bench_map(L45)
    speed.append([f"error map 21x21 deviations x 41x41 normals ({evals / 1e6:.2f} M normals)", f"{t1:.3f}",
                  "render + photometric.stereo.solve per deviation", f"{t2:.3f}", f"{t2 / t1:.0f}x",
                  f"max diff {diff:.1e} (float32 images)"])
    t1, t2, diff = bench_mc(L45)
    speed.append(["Monte Carlo, 20000 samples x 6 normals", f"{t1:.3f}", "Python loop, np.linalg.solve per sample",
                  f"{t2:.3f}", f"{t2 / t1:.0f}x", f"max diff {diff:.1e}"])
    t1, t2, ours, scan = bench_tolerance(L45)
    speed.append(["tolerance inversion (light 1 slant, eps 0.05, D 1)", f"{t1:.3f}", "dense scan, 0.001 deg steps",
                  f"{t2:.3f}", f"{t2 / t1:.0f}x", f"{ours:.5f} deg vs {scan:.3f} deg"])
    parts = [
        "Standard triad at 45 deg slant (azimuths 90, 210, 330 deg) unless stated. Best of 3 runs, shared "
        "2-core machine.",
        Table(["task", "ours (s)", "peer", "peer (s)", "ratio", "agreement"], speed),
        "## First-order model against the exact error (worst relative difference over |p|, |q| <= 1, "
        "any light, slant or azimuth)",
        Table(["deviation (deg)", "relative difference"], [[f"{d:g}", f"{100 * r:.2f} %"]
                                                           for d, r in first_order_accuracy(L45)]),
        "## Operating limits: largest deviation (deg, any direction) for |dp|, |dq| <= eps over |p|, |q| <= D",
    ]
    triads = [("standard triad, slant 45 deg", L45),
              (f"standard triad, slant {E.OPTIMAL_SLANT_DEG:.2f} deg (optimal conditioning)",
               ring_lights(3, E.OPTIMAL_SLANT_DEG))]
    if BEAR.is_file():
        triads.append(("DiLiGenT bear triad (images 090, 048, 033)", np.loadtxt(BEAR)[:3]))
    for name, L in triads:
        t0 = time.perf_counter()
        rows = E.recommendation_table(L, tolerances=(0.02, 0.05, 0.1), ranges=(0.5, 1.0, 2.0), n_grid=21)
        dt = time.perf_counter() - t0
        parts += [
            f"### {name} (condition number {condition_number(L):.3f}; table in {dt:.2f} s)",
            Table(["D", "eps", "one light", "two lights", "all three"],
                  [[f"{r['derivative_range']:g}", f"{r['tolerance']:g}", f"{r['single_light_deg']:.3f}",
                    f"{r['pair_deg']:.3f}", f"{r['all_lights_deg']:.3f}"] for r in rows]),
        ]
    return write_results("errors", "Light-deviation error analysis (photometric.errors)", parts)


if __name__ == "__main__":
    print(main())
