"""Benchmark of the shared surface model against geomdl (issue 2).

Evaluates 1,000,000 points on a 100x100-patch bicubic surface (random patch
parameters, and a regular 10x10 grid per patch), tessellates 10,000 patches at
8x8 subdivisions, and evaluates the same surface with geomdl (NURBS-Python),
written as a cubic B-spline whose interior knots have multiplicity 3 (exactly
the Bezier patches). geomdl is pure Python, one loop per point, so it is timed
on a subsample and scaled linearly to 1,000,000 points (stated in the table).

Run: ``.venv/bin/python benchmarks/bench_surfaces.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import Table, best_of, write_results  # noqa: E402

from surfaces.coons import from_grid  # noqa: E402
from surfaces.mesh import tessellate  # noqa: E402

N_POINTS = 1_000_000
GEOMDL_SAMPLE = 5_000


def surface_100x100():
    x, y = np.meshgrid(np.linspace(0, 10, 101), np.linspace(0, 10, 101), indexing="ij")
    z = np.sin(x) * np.cos(0.7 * y) + 0.1 * x
    return from_grid(np.stack([x, y, z], -1))


def geomdl_surface(patches):
    from geomdl import BSpline

    rows, cols = patches.shape
    net = np.empty((3 * rows + 1, 3 * cols + 1, 3))
    ii = 3 * np.arange(rows)
    jj = 3 * np.arange(cols)
    for a in range(4):
        for b in range(4):
            # neighbouring patches share their edge points (C0), so overlaps agree
            net[np.ix_(ii + a, jj + b)] = patches.control[:, :, a, b]

    def knots(n):
        return [0.0] * 4 + [float(k) for k in range(1, n) for _ in range(3)] + [float(n)] * 4

    surf = BSpline.Surface()
    surf.degree_u = surf.degree_v = 3
    surf.ctrlpts_size_u, surf.ctrlpts_size_v = net.shape[0], net.shape[1]
    surf.ctrlpts = net.reshape(-1, 3).tolist()
    surf.knotvector_u = knots(rows)
    surf.knotvector_v = knots(cols)
    return surf


def main() -> str:
    patches = surface_100x100()
    rng = np.random.default_rng(0)
    s = rng.uniform(0, 100, N_POINTS)
    t = rng.uniform(0, 100, N_POINTS)
    pi, pj, u, v = patches.locate(s, t)

    t_rand, pts = best_of(lambda: patches.evaluate(pi, pj, u, v))
    t_grid, _ = best_of(lambda: patches.evaluate_grid(10, 10))
    t_deriv, _ = best_of(lambda: patches.derivatives(pi, pj, u, v, order=1))
    t_tess, mesh = best_of(lambda: tessellate(patches, 8))

    surf = geomdl_surface(patches)
    params = list(zip((s[:GEOMDL_SAMPLE] / 100).tolist(), (t[:GEOMDL_SAMPLE] / 100).tolist()))
    # geomdl normalises knot vectors to [0, 1]
    t0 = time.perf_counter()
    ref = np.asarray(surf.evaluate_list(params))
    t_geomdl_sample = time.perf_counter() - t0
    t_geomdl = t_geomdl_sample * N_POINTS / GEOMDL_SAMPLE
    agree = float(np.max(np.abs(ref - pts[:GEOMDL_SAMPLE])))

    rows = [
        ("evaluate 1,000,000 random (patch, u, v) points", f"{t_rand:.3f}", f"{t_geomdl / t_rand:.0f}x"),
        ("evaluate 1,000,000 points, 10x10 grid per patch", f"{t_grid:.3f}", f"{t_geomdl / t_grid:.0f}x"),
        ("points + first derivatives at 1,000,000 random points", f"{t_deriv:.3f}", "-"),
        (f"tessellate 10,000 patches at 8x8 ({mesh.n_triangles:,} triangles)", f"{t_tess:.3f}", "-"),
        (
            f"geomdl evaluate_list, {GEOMDL_SAMPLE:,} points, scaled to 1,000,000",
            f"{t_geomdl:.1f} (measured {t_geomdl_sample:.2f} s)",
            "1x",
        ),
    ]
    return write_results("surfaces", "Surface model (issue 2)", [
        "`.venv/bin/python benchmarks/bench_surfaces.py`",
        Table(["task (100x100-patch bicubic surface)", "time (s)", "speed-up vs geomdl"], rows),
        f"Largest difference between geomdl and our points: {agree:.2e} (same surface).\n"
        "Targets: 1,000,000 points in under 0.5 s; at least 50x faster than geomdl.",
    ])


if __name__ == "__main__":
    print(main())
