"""Seed 000: control-point parameters by rays from the centroid, and parabolic (Overhauser) blending.

A contour that folds back (a ray from the centre crosses it three times) gets the
seed's parameters: support points on ``N1`` rays (eq. 1), turning points of the
polar angle (eqs. 3-4) and chord length in between (eq. 5). The parabolic
blending of eqs. 6-12 then gives a closed C1 curve through every point.

What a metrologist checks, each against a closed form:

* the support points carry ``u = k / N1`` exactly and lie on their rays;
* the blended curve passes through every contour point (interpolation error), and
  between the points it stays close to the true outline (largest distance, mm);
* parabolic blending reproduces a parabola exactly (eqs. 7-8 are exact for it);
* for uniform parameters it is the Catmull-Rom curve (the seed's matrix form).

Run: ``python examples/seed_000_contour_rays_blending.py [out_folder]``; writes
``seed_000_contour_rays_blending.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from scipy.spatial import cKDTree  # noqa: E402

from slices import clean_contour, parameterize  # noqa: E402
from surfaces.blending import evaluate_curve, overhauser_curve  # noqa: E402


def folded_contour(n: int = 240) -> np.ndarray:
    """A three-lobed outline whose arms bend back over the rays from the centre (mm)."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    r = 30.0 + 8.0 * np.sin(3 * t)
    theta = t + 0.5 * np.sin(3 * t)  # d(theta)/dt = 1 + 1.5 cos(3t) < 0 on part of each lobe: a fold
    return clean_contour(np.stack([r * np.cos(theta), r * np.sin(theta)], axis=1))


def main(out: Path) -> dict:
    n_rays = 12
    contour = folded_contour(120)
    par = parameterize(contour, n_rays=n_rays)
    support_angles = np.arctan2(*(par.support - par.center).T[::-1])
    ray_angles = np.arange(n_rays) * 2 * np.pi / n_rays
    on_rays = float(np.abs(np.angle(np.exp(1j * (support_angles - ray_angles)))).max())
    control, knots = overhauser_curve(par.points, par.u, closed=True)
    through = float(np.abs(evaluate_curve(control, knots, par.u) - par.points).max())
    # between the points: the distance of the blended curve from the true outline (sampled densely)
    dense = evaluate_curve(control, knots, np.linspace(knots[0], knots[-1], 4000, endpoint=False))
    between = float(cKDTree(folded_contour(200_000)).query(dense)[0].max())

    # closed form 1: a parabola y = x^2 with non-uniform parameters t = x is reproduced exactly
    x = np.array([0.0, 0.3, 0.45, 1.1, 1.6, 2.0])
    ctrl_p, knots_p = overhauser_curve(np.stack([x, x**2], 1), x)
    xs = np.linspace(x[0], x[-1], 401)
    parabola = float(np.abs(evaluate_curve(ctrl_p, knots_p, xs)[:, 1] - xs**2).max())
    # closed form 2: uniform parameters give Catmull-Rom, C(t) = 1/2 [t^3 t^2 t 1] M [P0 P1 P2 P3]
    rng = np.random.default_rng(0)
    p4 = rng.normal(size=(4, 2))
    ctrl_u, knots_u = overhauser_curve(p4, np.arange(4.0))
    ts = np.linspace(0.0, 1.0, 11)
    cr = np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]]) / 2.0
    catmull = np.stack([ts**3, ts**2, ts, np.ones_like(ts)], 1) @ cr @ p4
    catmull_rom = float(np.abs(evaluate_curve(ctrl_u, knots_u, 1.0 + ts) - catmull).max())

    figures = {
        "contour_points": len(par.points),
        "rays": n_rays,
        "turning_points": int(par.turning.sum()),
        "support_off_ray_rad": on_rays,
        "interpolation_error_mm": through,
        "max_distance_from_true_outline_mm": between,
        "parabola_error": parabola,
        "catmull_rom_error": catmull_rom,
    }
    for name, value in figures.items():
        print(f"{name:>34}: {value:.3g}" if isinstance(value, float) else f"{name:>34}: {value}")

    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(*dense.T, "-", color="0.2", lw=1, label="parabolic blending (eqs. 6-12)")
    ax.plot(*par.points.T, ".", ms=3, color="tab:blue", label="contour points")
    for s in par.support:
        ax.plot(*np.stack([par.center, par.center + 1.6 * (s - par.center)]).T, color="tab:orange", lw=0.5)
    ax.plot(*par.support.T, "o", color="tab:orange", ms=5, label=f"support points (u = k/{n_rays})")
    ax.plot(*par.points[par.turning].T, "s", color="tab:red", ms=5, label="turning points (eq. 3)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"seed 000: {len(par.points)} points, curve within {between:.3f} mm of the true outline")
    fig.savefig(out / "seed_000_contour_rays_blending.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return figures


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="seed_000_"))
    folder.mkdir(parents=True, exist_ok=True)
    result = main(folder)
    assert result["turning_points"] > 0 and result["interpolation_error_mm"] < 1e-9
    assert result["max_distance_from_true_outline_mm"] < 0.1
    assert result["parabola_error"] < 1e-12 and result["catmull_rom_error"] < 1e-12
    print(f"figure: {folder / 'seed_000_contour_rays_blending.png'}")
