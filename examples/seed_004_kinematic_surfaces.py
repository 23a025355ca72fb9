"""Seed 004: kinematic surfaces, a generatrix carried along a directrix, as Bezier patches.

Two surfaces with closed-form measures, both built by the workbench's kinematic
module and converted to the shared Bezier-patch model (B-spline interpolation of
samples, then knot insertion):

* a helicoid (a line screwed about the z axis): area
  ``A = theta [r s + c^2 ln(r + s)] / 2`` from ``r = a`` to ``b``, ``s = sqrt(r^2 + c^2)``,
  ``c = pitch / 2 pi``, ``theta = 2 pi turns``;
* a torus (a circle revolved about the z axis): Pappus, ``A = 4 pi^2 R r`` and
  ``V = 2 pi^2 R r^2``.

What a metrologist checks: the relative errors of area and volume against those
closed forms, and that they fall as the patches get finer.

Run: ``python examples/seed_004_kinematic_surfaces.py [out_folder]``; writes
``seed_004_kinematic_surfaces.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from surfaces.curves import circle  # noqa: E402
from surfaces.kinematic import helicoid, revolve  # noqa: E402
from surfaces.measure import area, volume  # noqa: E402


def helicoid_area(a: float, b: float, pitch: float, turns: float) -> float:
    c = pitch / (2 * np.pi)

    def primitive(r):
        s = np.hypot(r, c)
        return 0.5 * (r * s + c * c * np.log(r + s))

    return 2 * np.pi * turns * (primitive(b) - primitive(a))


def main(out: Path) -> dict:
    a, b, pitch, turns = 2.0, 10.0, 8.0, 1.5  # mm
    R, r = 30.0, 8.0  # mm
    exact_helicoid = helicoid_area(a, b, pitch, turns)
    exact_area, exact_volume = 4 * np.pi**2 * R * r, 2 * np.pi**2 * R * r * r
    screw = helicoid(a, b, pitch, turns)
    torus = revolve(circle(r, center=(R, 0.0)))
    rows = []
    for n in (8, 16, 32):
        hel = screw.to_bezier(n_u=4, n_v=n)
        tor = torus.to_bezier(n_u=n, n_v=n)
        rows.append({
            "samples": n,
            "helicoid_area_rel_error": area(hel) / exact_helicoid - 1,
            "torus_area_rel_error": area(tor) / exact_area - 1,
            "torus_volume_rel_error": abs(volume(tor)) / exact_volume - 1,
        })
    print(f"helicoid a={a} b={b} pitch={pitch} turns={turns}: area {exact_helicoid:.4f} mm^2 (closed form)")
    print(f"torus R={R} r={r}: area {exact_area:.4f} mm^2, volume {exact_volume:.4f} mm^3 (Pappus)")
    print(f"{'samples':>8} {'helicoid A':>12} {'torus A':>12} {'torus V':>12}   (relative errors)")
    for row in rows:
        print(f"{row['samples']:>8} {row['helicoid_area_rel_error']:>12.2e} {row['torus_area_rel_error']:>12.2e} "
              f"{row['torus_volume_rel_error']:>12.2e}")

    fig = plt.figure(figsize=(11, 4.5))
    for k, (surface, title) in enumerate(((screw, "helicoid (line screwed about z)"),
                                          (torus, "torus (circle revolved about z)"))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        u, v = surface.sample_parameters(12 if k == 0 else 40, 80)
        g = surface.evaluate_grid(u, v)
        ax.plot_surface(g[..., 0], g[..., 1], g[..., 2], cmap="viridis", linewidth=0, alpha=0.85)
        ax.set_title(title, fontsize=9)
        ax.set_box_aspect(np.ptp(g.reshape(-1, 3), axis=0))
    fig.suptitle(f"seed 004: torus volume within {abs(rows[-1]['torus_volume_rel_error']):.1e} of Pappus "
                 f"at {rows[-1]['samples']} samples", fontsize=10)
    fig.savefig(out / "seed_004_kinematic_surfaces.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return {"rows": rows}


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="seed_004_"))
    folder.mkdir(parents=True, exist_ok=True)
    result = main(folder)
    last = result["rows"][-1]
    assert abs(last["helicoid_area_rel_error"]) < 1e-4 and abs(last["torus_volume_rel_error"]) < 1e-4
    print(f"figure: {folder / 'seed_004_kinematic_surfaces.png'}")
