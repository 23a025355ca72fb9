"""Seed 001: bicubic Coons (Hermite) patches through a grid, converted exactly to Bezier patches.

Each grid cell becomes a Coons patch from its corners, corner tangents and twists
(eq. 2), converted to the equivalent Bezier patch by ``P_B = K B K^T`` with
``K = N_B^-1 N_C`` (eq. 7, Rogers & Adams).

What a metrologist checks, each against a closed form:

* with exact tangents and twists, a bicubic polynomial is reproduced to rounding;
* the workbench's Bezier points equal the seed's matrix formula ``K B K^T``;
* with central-difference tangents and twists the Coons surface is the uniform
  parabolic-blending surface of seed 000 (the two seeds' surfaces coincide);
* on a non-polynomial surface (a sine bump), the error shrinks ~16x when the grid
  spacing halves (fourth order).

Run: ``python examples/seed_001_coons_to_bezier.py [out_folder]``; writes ``seed_001_coons_to_bezier.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from surfaces import blending, coons  # noqa: E402
from surfaces.bezier import control_net_segments  # noqa: E402


def bicubic(x, y):
    """``z = x^3 y^2 - 2 x y^3 + x^2 + y`` and its exact derivatives ``z_x, z_y, z_xy``."""
    return (x**3 * y**2 - 2 * x * y**3 + x**2 + y, 3 * x**2 * y**2 - 2 * y**3 + 2 * x,
            2 * x**3 * y - 6 * x * y**2 + 1, 6 * x**2 * y - 6 * y**2)


def grid(f, n: int, h: float):
    """Points, tangents per unit of grid index and twists of the height field ``f`` on an ``n x n`` grid."""
    x, y = np.meshgrid(np.arange(n) * h, np.arange(n) * h, indexing="ij")
    z, zx, zy, zxy = f(x, y)
    zero, one = np.zeros_like(x), np.ones_like(x)
    points = np.stack([x, y, z], -1)
    pu = np.stack([one * h, zero, zx * h], -1)  # dP/di = h dP/dx
    pv = np.stack([zero, one * h, zy * h], -1)
    twist = np.stack([zero, zero, zxy * h * h], -1)
    return points, pu, pv, twist


def main(out: Path) -> dict:
    h = 0.25
    points, pu, pv, twist = grid(bicubic, 6, h)
    patches = coons.from_grid(points, pu, pv, twist)
    s = np.random.default_rng(0).uniform(0, 1, (2, 500)) * (points.shape[0] - 1)
    xyz = patches.evaluate_global(s[0], s[1])
    reproduction = float(np.abs(xyz[:, 2] - bicubic(xyz[:, 0], xyz[:, 1])[0]).max())

    # the seed's closed form for one patch: P_B = K B K^T
    K = np.array([[1, 0, 0, 0], [1, 0, 1 / 3, 0], [0, 1, 0, -1 / 3], [0, 1, 0, 0]])
    i, j = 2, 3
    B = np.array([[points[i, j], points[i, j + 1], pv[i, j], pv[i, j + 1]],
                  [points[i + 1, j], points[i + 1, j + 1], pv[i + 1, j], pv[i + 1, j + 1]],
                  [pu[i, j], pu[i, j + 1], twist[i, j], twist[i, j + 1]],
                  [pu[i + 1, j], pu[i + 1, j + 1], twist[i + 1, j], twist[i + 1, j + 1]]])
    seed_formula = float(np.abs(np.einsum("ak,klc,bl->abc", K, B, K) - patches.control[i, j]).max())

    # seed 001 with central differences = seed 000's uniform parabolic blending
    rng = np.random.default_rng(1)
    wavy = np.concatenate([np.stack(np.meshgrid(np.arange(7.0), np.arange(5.0), indexing="ij"), -1),
                           rng.normal(size=(7, 5, 1))], -1)
    fd = coons.from_grid(wavy, twist="fd", chord_length=False)
    blend = blending.from_grid(wavy, u_params=np.arange(7.0) / 7.0)
    seeds_agree = float(np.abs(fd.evaluate_grid(6, 6) - blend.evaluate_grid(6, 6)).max())

    # fourth-order convergence on a sine bump with exact tangents
    def bump(x, y):
        return (np.sin(x) * np.cos(y), np.cos(x) * np.cos(y), -np.sin(x) * np.sin(y), -np.cos(x) * np.sin(y))

    errors = []
    for n in (5, 9, 17):
        hh = 2.0 / (n - 1)
        p, a, b, c = grid(bump, n, hh)
        q = coons.from_grid(p, a, b, c).evaluate_grid(9, 9).reshape(-1, 3)
        errors.append(float(np.abs(q[:, 2] - bump(q[:, 0], q[:, 1])[0]).max()))
    ratios = [errors[k] / errors[k + 1] for k in range(len(errors) - 1)]

    figures = {
        "bicubic_reproduction_error": reproduction,
        "K_B_KT_difference": seed_formula,
        "coons_fd_minus_parabolic_blending": seeds_agree,
        "sine_bump_errors_h_2_h_4_h_8": errors,
        "error_ratios_per_halving": ratios,
    }
    for name, value in figures.items():
        shown = ", ".join(f"{v:.3g}" for v in value) if isinstance(value, list) else f"{value:.3g}"
        print(f"{name:>34}: {shown}")

    fig = plt.figure(figsize=(11, 4.5))
    fig.subplots_adjust(wspace=0.35)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    g = patches.evaluate_grid(8, 8)  # (R, C, 8, 8, 3): one global grid, shared edges repeated
    surface = g.transpose(0, 2, 1, 3, 4).reshape(g.shape[0] * 8, g.shape[1] * 8, 3)
    ax.plot_surface(surface[..., 0], surface[..., 1], surface[..., 2], cmap="viridis", alpha=0.8, linewidth=0)
    for seg in control_net_segments(patches):
        ax.plot(*seg.T, color="0.3", lw=0.4)
    ax.set_title("Coons patches as Bezier patches, with control net", fontsize=9)
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.loglog([2.0 / 4, 2.0 / 8, 2.0 / 16], errors, "o-", label="max |z error| (sine bump)")
    ax2.loglog([0.5, 0.125], [errors[0], errors[0] / 256], "--", color="0.5", label="slope 4")
    ax2.set_xlabel("grid spacing h")
    ax2.set_ylabel("max error")
    ax2.legend(fontsize=8)
    ax2.set_title(f"bicubic reproduced to {reproduction:.1e}", fontsize=9)
    fig.savefig(out / "seed_001_coons_to_bezier.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return figures


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="seed_001_"))
    folder.mkdir(parents=True, exist_ok=True)
    result = main(folder)
    assert result["bicubic_reproduction_error"] < 1e-12 and result["K_B_KT_difference"] < 1e-12
    assert result["coons_fd_minus_parabolic_blending"] < 1e-12
    assert all(12 < r < 20 for r in result["error_ratios_per_halving"])
    print(f"figure: {folder / 'seed_001_coons_to_bezier.png'}")
