"""Seed 003: a B-spline surface through every point of a grid, converted exactly to Bezier patches.

Rows are interpolated in ``u``, then the rows' control points in ``v`` (The NURBS
Book A9.4), chord-length parameters averaged over the lines, one knot vector per
direction; degree 3 both ways.

What a metrologist checks, each against a closed form:

* the surface passes through every grid point (interpolation error);
* a bicubic polynomial is reproduced exactly (with uniform parameters);
* on a smooth surface (a Gaussian hill) the error between the points falls about
  16x per halving of the spacing (fourth order);
* the conversion to Bezier patches (knot insertion) changes no point of the surface.

Run: ``python examples/seed_003_bspline_interpolation.py [out_folder]``; writes
``seed_003_bspline_interpolation.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from surfaces.bspline import interpolate_surface  # noqa: E402


def hill(x, y):
    """A Gaussian hill, mm."""
    return 3.0 * np.exp(-((x - 0.4) ** 2 + (y - 0.6) ** 2) / 0.18)


def grid(n: int, f) -> np.ndarray:
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    return np.stack([x, y, f(x, y)], -1)


def main(out: Path) -> dict:
    points = grid(9, hill)
    surf = interpolate_surface(points)
    at_points = surf.evaluate_grid(surf.params_u, surf.params_v)
    through = float(np.abs(at_points - points).max())

    poly = grid(6, lambda x, y: x**3 * y**3 - 2 * x**2 * y + y**3)
    exact = interpolate_surface(poly, method="uniform")
    s = np.random.default_rng(0).uniform(0, 1, (2, 400))
    pts = exact.evaluate(s[0], s[1])
    reproduction = float(np.abs(pts[:, 2] - (pts[:, 0] ** 3 * pts[:, 1] ** 3 - 2 * pts[:, 0] ** 2 * pts[:, 1]
                                             + pts[:, 1] ** 3)).max())

    errors, spacings = [], []
    for n in (9, 17, 33):
        sn = interpolate_surface(grid(n, hill), method="uniform")
        q = sn.evaluate(s[0], s[1])
        errors.append(float(np.abs(q[:, 2] - hill(q[:, 0], q[:, 1])).max()))
        spacings.append(1.0 / (n - 1))
    ratios = [errors[k] / errors[k + 1] for k in range(len(errors) - 1)]

    # the Bezier patches (knot insertion) at the same parameters as the B-spline
    patches = surf.to_bezier()
    pi, pj, ls, lt = surf.patch_parameters(s[0], s[1])
    conversion = float(np.abs(patches.evaluate(pi, pj, ls, lt) - surf.evaluate(s[0], s[1])).max())

    figures = {
        "interpolation_error_mm": through,
        "bicubic_reproduction_error": reproduction,
        "hill_errors_mm_h_1_8_1_16_1_32": errors,
        "error_ratios_per_halving": ratios,
        "bezier_conversion_difference_mm": conversion,
    }
    for name, value in figures.items():
        shown = ", ".join(f"{x:.3g}" for x in value) if isinstance(value, list) else f"{value:.3g}"
        print(f"{name:>32}: {shown}")

    fig = plt.figure(figsize=(11, 4.5))
    fig.subplots_adjust(wspace=0.35)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    dense = surf.evaluate_grid(np.linspace(0, 1, 40), np.linspace(0, 1, 40))
    ax.plot_surface(dense[..., 0], dense[..., 1], dense[..., 2], cmap="viridis", alpha=0.75, linewidth=0)
    ax.scatter(*points.reshape(-1, 3).T, color="k", s=6)
    ax.set_title("bicubic B-spline through a 9 x 9 grid", fontsize=9)
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.loglog(spacings, errors, "o-", label="max |z error| between the points")
    ax2.loglog([spacings[0], spacings[-1]], [errors[0], errors[0] / 256], "--", color="0.5", label="slope 4")
    ax2.set_xlabel("grid spacing")
    ax2.set_ylabel("max error (mm)")
    ax2.legend(fontsize=8)
    ax2.set_title(f"through every point to {through:.1e} mm", fontsize=9)
    fig.savefig(out / "seed_003_bspline_interpolation.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return figures


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="seed_003_"))
    folder.mkdir(parents=True, exist_ok=True)
    result = main(folder)
    assert result["interpolation_error_mm"] < 1e-9 and result["bicubic_reproduction_error"] < 1e-9
    assert result["bezier_conversion_difference_mm"] < 1e-9
    assert all(10 < r < 24 for r in result["error_ratios_per_halving"])
    print(f"figure: {folder / 'seed_003_bspline_interpolation.png'}")
