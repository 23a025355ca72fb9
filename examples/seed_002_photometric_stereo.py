"""Seed 002(a): photometric stereo from a triad, and what a deviated light does to it.

A 12.8 mm plate with a dent is lit by three lights at 45 deg slant (a triad), rendered as
8-bit images, and reconstructed with the library's stages (read, solve, integrate, measure:
:mod:`photometric.stages`). Then one light is taken to sit 1 deg off its nominal slant:
the first-order model of :mod:`photometric.errors` predicts the slope error, the images
rendered under the deviated light and solved with the nominal ones measure it, and the
tolerance inversion says how far a light may deviate for a stated slope error.

Prints the numbers a metrologist checks and writes ``seed_002_photometric_stereo.png``
into the folder given as the first argument (default: a new temporary folder).

Run: ``python examples/seed_002_photometric_stereo.py [OUT_DIR]``
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from datasets_synthetic.heightfields import make_scene  # noqa: E402
from datasets_synthetic.render import render  # noqa: E402
from photometric import stages  # noqa: E402
from photometric.errors import exact_error, max_deviation, worst_case_error  # noqa: E402
from photometric.lights import deviate_lights, ring_lights  # noqa: E402
from photometric.normals import angular_error_deg  # noqa: E402
from photometric.options import PhotometricOptions  # noqa: E402

PIXEL_MM = 0.1
DEVIATION_DEG = 1.0


def reconstruct(images: np.ndarray, lights: np.ndarray, opts: PhotometricOptions):
    """The library's stages, composed without a surface model: normals, height, defects."""
    inp = stages.read(images, opts, lights=lights, pixel_size=PIXEL_MM)
    sol = stages.solve(inp, opts)
    height = stages.integrate(inp, sol, opts)
    return sol.fit, height.height, stages.measure(inp, sol, height, opts).defects


def main(out_dir: Path) -> dict:
    scene = make_scene("dent", 128, pixel_size=PIXEL_MM)
    lights = ring_lights(3, 45.0)  # the triad: slant 45 deg, azimuths 90, 210, 330 deg
    opts = PhotometricOptions()
    images = render(scene, lights, albedo=0.8, bit_depth=8)
    fit, height, defects = reconstruct(images, lights, opts)
    valid = fit.valid
    err = angular_error_deg(fit.normals, scene.normals)[valid]
    dz = (height - np.nanmean(height[valid])) - (scene.height - scene.height[valid].mean())
    true_depth = scene.defects[0]["depth_mm"] if scene.defects else float("nan")
    deepest = max(defects, key=lambda d: d["max_depth_mm"]) if defects else None

    # one light 1 deg off its nominal slant: predicted, then measured on images rendered under it
    moved = deviate_lights(lights, [[DEVIATION_DEG, 0.0], [0.0, 0.0], [0.0, 0.0]])
    model = exact_error(lights, moved, scene.p, scene.q)
    fit_dev, _, _ = reconstruct(render(scene, moved, albedo=0.8, bit_depth=8), lights, opts)
    both = valid & fit_dev.valid
    measured_dp = fit_dev.p[both] - fit.p[both]
    slope_range = float(max(np.abs(scene.p).max(), np.abs(scene.q).max()))
    worst = worst_case_error(lights, DEVIATION_DEG, slope_range, lights_moved=0, mode="slant")
    limit = max_deviation(lights, 0.01, slope_range, lights_moved=0, mode="slant")

    figures = {
        "normals: mean angular error, deg": float(err.mean()),
        "normals: median angular error, deg": float(np.median(err)),
        "height: RMS error (means removed), mm": float(np.sqrt(np.nanmean(dz[valid] ** 2))),
        "dent: true depth, mm": float(true_depth),
        "dent: measured depth, mm": float(deepest["max_depth_mm"]) if deepest else float("nan"),
        "slope range of the scene |p|, |q| <=": slope_range,
        f"light 0 off by {DEVIATION_DEG:g} deg slant: predicted max |dp|": float(np.abs(model.dp[both]).max()),
        f"light 0 off by {DEVIATION_DEG:g} deg slant: measured max |dp|": float(np.abs(measured_dp).max()),
        f"worst case over the slope square, {DEVIATION_DEG:g} deg": float(worst),
        "largest slant deviation of light 0 for |dp|, |dq| <= 0.01, deg": float(limit.value),
    }
    for name, value in figures.items():
        print(f"{name}: {value:.4g}")

    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    axes[0].imshow(np.clip(fit.normals * 0.5 + 0.5, 0, 1))
    axes[0].set_title("normals (triad)")
    im = axes[1].imshow(height, cmap="viridis")
    axes[1].set_title("height, mm")
    fig.colorbar(im, ax=axes[1], shrink=0.8)
    im = axes[2].imshow(np.where(both, fit_dev.p - fit.p, np.nan), cmap="coolwarm")
    axes[2].set_title(f"dp: light 0 off by {DEVIATION_DEG:g} deg")
    fig.colorbar(im, ax=axes[2], shrink=0.8)
    for ax in axes:
        ax.set_axis_off()
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "seed_002_photometric_stereo.png"
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {path}")
    return figures


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="seed_002_")))
