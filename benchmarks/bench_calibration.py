"""Benchmark of calibrating a real rig (issue 33): other tools' calibration files and the working distance.

Run: ``.venv/bin/python benchmarks/bench_calibration.py [--quick]``. Writes
``benchmarks/results/calibration.md`` and prints it.

* The real 8-LED near-field capture ``../shared/data/nearps_hehe12`` (Quéau-format
  ``light.mat`` + ``camera.mat``, an ambient frame, a mask) runs from its own files in one
  command (``workbench photometric reconstruct --images ... --rig light.mat --mask ...
  --ambient ...``). Its working distance is estimated from the photometric residual and
  reported with U; the baseline is the guessed distances of the issue (150, 200, 300 mm):
  their residual relative to the estimate's and the across-part depth each gives.
* A closed-form check: a matte plate rendered in the test's own formula (``E = Phi cos / r^2``
  with an LED lobe, no project code) at known distances, 0.3 % noise; the estimate's error
  against the truth and whether ``U = 2 u`` covers it.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import Table, write_results  # noqa: E402

from photometric.distance import estimate_camera_height, photometric_residual  # noqa: E402
from photometric.importers import CameraFrameCalibration, read_calibration, to_rig  # noqa: E402
from photometric.io import read_ambient, read_images, read_mask  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "nearps_hehe12"
ANGLES = np.deg2rad(np.arange(8) * 45.0 + 10.0)
RING = np.stack([95 * np.cos(ANGLES), 95 * np.sin(ANGLES), np.full(8, 75.0)], axis=1)
AXES = np.stack([-0.6 * np.cos(ANGLES), -0.6 * np.sin(ANGLES), np.full(8, 0.8)], axis=1)
PHI = np.linspace(2.0e6, 3.5e6, 8)


def _plate(height_mm: float, shape, f: float, noise: float, rng) -> np.ndarray:
    """A matte plate (albedo 0.6) across the axis at ``height_mm``, 8 LEDs of lobe cos^1 (camera frame)."""
    h, w = shape
    cols, rows = np.meshgrid(np.arange(w) - (w - 1) / 2, np.arange(h) - (h - 1) / 2)
    X = np.stack([cols * height_mm / f, rows * height_mm / f, np.full(cols.shape, height_mm)], axis=-1)
    out = []
    for p, a, phi in zip(RING, AXES / np.linalg.norm(AXES, axis=1, keepdims=True), PHI):
        d = X - p
        r = np.linalg.norm(d, axis=-1)
        out.append(0.6 * phi / 2.0e6 * 1e4 * np.maximum(0.0, d @ a / r) * np.maximum(0.0, d[..., 2] / r) / r**2)
    imgs = np.array(out)
    return (imgs + noise * imgs.max() * rng.standard_normal(imgs.shape)).clip(0).astype(np.float32)


def synthetic(quick: bool) -> Table:
    rng = np.random.default_rng(33)
    shape, f = ((48, 64), 160.0) if quick else ((90, 120), 300.0)
    rows = []
    for truth in ((180.0,) if quick else (150.0, 200.0, 260.0)):
        imgs = _plate(truth, shape, f, 0.003, rng)
        cal = CameraFrameCalibration(RING, AXES / np.linalg.norm(AXES, axis=1, keepdims=True),
                                     np.repeat(PHI[:, None], 3, axis=1), np.ones(8), (f, f),
                                     ((shape[1] - 1) / 2, (shape[0] - 1) / 2))
        t0 = time.perf_counter()
        est = estimate_camera_height(imgs, to_rig(cal, 120.0, shape), binning=1)
        seconds = time.perf_counter() - t0
        err = est.camera_height_mm - truth
        rows.append([f"{truth:.0f}", f"{est.camera_height_mm:.2f}", f"{err:+.2f}", f"{2 * est.u_mm:.2f}",
                     "yes" if abs(err) <= 2 * est.u_mm else "no", f"{est.residual_rms:.2e}", f"{seconds:.1f}"])
    return Table(["true H (mm)", "estimate (mm)", "error (mm)", "U, k = 2 (mm)", "covered", "residual", "time (s)"],
                 rows, "rrrrlrr")


def real(quick: bool) -> list:
    if not DATA.is_dir():
        return [f"Not measured: {DATA} is absent."]
    from workbench.cli import main as cli

    images = [str(DATA / f"photometric_sample_raw_{k:04d}.png") for k in range(1, 9)]
    mask, ambient = DATA / "photometric_sample_mask_raw.png", DATA / "photometric_sample_raw_ambient.png"
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        code = cli(["photometric", "reconstruct", "--images", *images, "--rig", str(DATA / "light.mat"),
                    "--mask", str(mask), "--ambient", str(ambient), "--out", f"{tmp}/out"])
        seconds = time.perf_counter() - t0
        summary = json.loads(Path(f"{tmp}/out/summary.json").read_text())
    wd = summary["working_distance"]
    parts = [f"One command (`workbench photometric reconstruct --images raw_000?.png --rig light.mat --mask ... "
             f"--ambient ...`), exit code {code}, {seconds:.1f} s end to end (the solve itself "
             f"{summary['timings_s']['total']:.1f} s): working distance **{wd['camera_height_mm']:.1f} mm, "
             f"U = {wd['U_k2_mm']:.1f} mm (k = 2)** (u from the residual's curvature {wd['u_curvature_mm']:.2f} mm, "
             f"spatial jackknife {wd['u_jackknife_mm']:.2f} mm), photometric residual {wd['residual_rms']:.4f} of "
             f"full scale at {wd['binning']}x{wd['binning']} binning, {wd['observations']} observations. The "
             "data's README: the residual is lowest near 200 mm."]
    cal = read_calibration(DATA)
    imgs = read_images(images)
    read_ambient(ambient, imgs)
    m = read_mask(mask, imgs.shape[1:3])
    rows = []
    base = None
    for h in (wd["camera_height_mm"], 150.0, 200.0, 300.0):
        rig = to_rig(cal, h, imgs.shape[1:3])
        sq, _ = photometric_residual(imgs, rig, h, mask=m, binning=wd["binning"])
        rms = float(np.sqrt(np.nanmean(sq) / imgs.shape[0]))
        base = rms if base is None else base
        rows.append([f"{h:.1f}" + (" (estimate)" if len(rows) == 0 else " (guess)"), f"{rms:.4f}",
                     f"{rms / base:.3f}"])
    parts.append(Table(["camera height (mm)", "photometric residual", "ratio to the estimate's"], rows, "lrr"))
    return parts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    args = parser.parse_args(argv)
    parts = [f"Command: `.venv/bin/python benchmarks/bench_calibration.py{' --quick' if args.quick else ''}`.",
             "## The real 8-LED capture from its own files (`nearps_hehe12`)", *real(args.quick),
             "## Working distance of a rendered plate (closed form, 0.3 % noise, 8 LEDs 75 mm in front of the "
             "camera)", synthetic(args.quick),
             "Not measured here (issue 33, not built on this branch): lens distortion and checkerboard "
             "calibration, sphere calibration's Birge-scaled U, semi-calibrated LED powers, big captures' patch "
             "budget."]
    print(write_results("calibration", "Calibrating a real rig (`photometric.importers`, `photometric.distance`)",
                        parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
