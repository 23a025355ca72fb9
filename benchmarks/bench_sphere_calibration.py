"""Benchmark of the mirror-sphere LED calibration through a distorting lens, and of its stated u (issue 33 item 2).

Run: ``.venv/bin/python benchmarks/bench_sphere_calibration.py [--trials N]``. Writes
``benchmarks/results/sphere_calibration.md`` and prints it. (Named apart from ``bench_calibration.py``,
which another branch writes for the working distance and the imported rig.)

Each random trial, for a lens with ``k1 = -0.03`` and ``+0.03`` (OpenCV's model, perspective camera
384 px, f = 825 px, 200 mm above the reference plane; 8 LEDs 200 mm from the centre on a 45 deg ring):

1. 12 views of a 9 x 6 checkerboard at random poses are rendered through the lens (a pinhole render
   by homography, then :func:`datasets_synthetic.mitsuba_scenes.distort_image`) and calibrated by
   OpenCV (``findChessboardCorners``, ``cornerSubPix``, ``calibrateCameraExtended`` with ``k3`` fixed):
   ``K``, the distortion, their standard deviations and the RMS reprojection error;
2. three mirror spheres (radius 20 mm) at random places and heights (so random highlight phases), with
   random noise (0.002-0.01 of full scale, 16 bit), are rendered through the same lens by
   :mod:`datasets_synthetic.spheres` (its lens option: each highlight ray splatted where the lens
   records it);
3. the images are undistorted to the pinhole camera of the calibrated ``K`` (``cv2.remap``, bicubic)
   and calibrated by :func:`photometric.calibrate.calibrate_positions`, with the checkerboard's
   RMS reprojection error and focal-length deviation as the lens's own uncertainty.

The error is measured in the calibrated camera's frame (every later step works in it): a principal
point error rotates that frame as a whole about the camera centre, which the rotation that best maps
the true pixel rays to the calibrated ones removes (Kabsch over a 15 x 15 grid of pixels); the sphere
centres are given in the same frame. Rows: the checkerboard lens, the exact lens (the renderer's K and
distortion: the sphere calibration alone), and no correction (pinhole on the distorted images).
Coverage: the fraction of LED coordinates whose error is within U = 2 u.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import Table, write_results  # noqa: E402

from datasets_synthetic.cameras import make_camera as synth_camera  # noqa: E402
from datasets_synthetic.mitsuba_scenes import distort_image, lens_matrix  # noqa: E402
from datasets_synthetic.point_lights import rig_lights  # noqa: E402
from datasets_synthetic.spheres import render_mirror_sphere  # noqa: E402
from photometric.calibrate import SphereImages, calibrate_positions  # noqa: E402
from photometric.camera import make_camera  # noqa: E402
from surfaces.validate import InputError  # noqa: E402

SIZE, F, HC, RADIUS = 384, 825.0, 200.0, 20.0
BOARD, VIEWS = (9, 6), 12
SQUARE = 0.8 * 180.0 * SIZE / F / 12.0  # mm: the board with its margin fills about 80 % of the view at 180 mm
SPREAD = 30.0  # sphere centres within +-SPREAD mm


def board_views(cam, dist, rng):
    """Checkerboard views through the lens (random tilts, distances 150-210 mm)."""
    cols, rows = BOARD
    K = lens_matrix(cam)
    tex_px = 20
    tex = np.kron((np.indices((rows + 3, cols + 3)).sum(0) % 2).astype(np.float32), np.ones((tex_px, tex_px),
                                                                                            np.float32))
    tex = 0.15 + 0.7 * tex
    tex[:tex_px], tex[-tex_px:], tex[:, :tex_px], tex[:, -tex_px:] = 0.85, 0.85, 0.85, 0.85  # a white margin
    views = []
    for _ in range(VIEWS):
        rvec = rng.normal(0.0, 0.25, 3)
        rvec[2] = rng.uniform(-0.3, 0.3)
        R, _ = cv2.Rodrigues(rvec)
        centre = np.array([rng.uniform(-2, 2) * SQUARE, rng.uniform(-2, 2) * SQUARE, rng.uniform(150, 210)])
        t = centre - R @ np.array([(cols + 3) * SQUARE / 2, (rows + 3) * SQUARE / 2, 0.0])
        S = np.diag([SQUARE / tex_px, SQUARE / tex_px, 1.0])
        ss = 2  # rendered at twice the size, then averaged: antialiased edges
        K2 = K.copy()
        K2[:2] *= ss
        K2[:2, 2] = K[:2, 2] * ss + (ss - 1) / 2
        H = K2 @ np.column_stack([R[:, 0], R[:, 1], t]) @ S
        big = cv2.warpPerspective(tex, H, (SIZE * ss, SIZE * ss), flags=cv2.INTER_LINEAR, borderValue=0.5)
        ideal = cv2.resize(big, (SIZE, SIZE), interpolation=cv2.INTER_AREA)
        views.append(np.clip(distort_image(ideal, K, dist) + rng.normal(0, 0.005, ideal.shape), 0, 1))
    return views


def checkerboard_lens(views):
    """OpenCV's calibration: K, distortion, std of (fx, fy, cx, cy), RMS reprojection error, views used."""
    cols, rows = BOARD
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * SQUARE
    found = []
    for img in views:
        g8 = (img * 255).astype(np.uint8)
        ok, c = cv2.findChessboardCorners(g8, (cols, rows), cv2.CALIB_CB_ADAPTIVE_THRESH
                                          | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if ok:
            found.append(cv2.cornerSubPix(g8, c, (5, 5), (-1, -1),
                                          (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)))
    rms, K, d, _, _, sd, _, _ = cv2.calibrateCameraExtended([obj] * len(found), found, (SIZE, SIZE), None, None,
                                                            flags=cv2.CALIB_FIX_K3)
    return K, d.ravel()[:5], sd.ravel()[:4], float(rms), len(found)


def _dirs(pix, K):
    v = np.stack([(pix[:, 0] - K[0, 2]) / K[0, 0], -(pix[:, 1] - K[1, 2]) / K[1, 1], -np.ones(len(pix))], 1)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def frame_rotation(K_true, d_true, K, d, K_new):
    """Rotation R with calibrated ray ~ R true ray (Kabsch over a grid of pixels)."""
    g = np.stack(np.meshgrid(np.linspace(20, SIZE - 20, 15), np.linspace(20, SIZE - 20, 15)), -1).reshape(-1, 1, 2)
    t = _dirs(cv2.undistortPoints(g, K_true, d_true, P=K_true).reshape(-1, 2), K_true)
    e = _dirs(cv2.undistortPoints(g, K, d, P=K_new).reshape(-1, 2), K_new)
    U, _, Vt = np.linalg.svd(e.T @ t)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def place_spheres(cam, lights, dist, rng, noise):
    renders = []
    while len(renders) < 3:
        c = np.array([rng.uniform(-SPREAD, SPREAD), rng.uniform(-SPREAD, SPREAD),
                      RADIUS + rng.choice([0.0, 15.0])])
        if any(np.linalg.norm(c[:2] - r.center_mm[:2]) < 2.1 * RADIUS for r in renders):
            continue
        try:
            r = render_mirror_sphere(cam, lights, c, RADIUS, highlight_samples=32, supersample=2, noise=noise,
                                     bit_depth=16, seed=rng, distortion=dist)
        except InputError:
            continue
        if r.highlights_px.min() >= 12 and r.highlights_px.max() <= SIZE - 13:
            renders.append(r)
    return renders


def solve(renders, lights, K, d, K_true, d_true, rng_sd=None):
    """LED error (N, 3), stated u (N, 3), info, or None when the calibration refuses."""
    f = 0.5 * (K[0, 0] + K[1, 1])
    K_new = np.array([[f, 0.0, K[0, 2]], [0.0, f, K[1, 2]], [0.0, 0.0, 1.0]])
    C = np.array([0.0, 0.0, HC])
    if d is None:  # no correction: the distorted images taken as pinhole images
        R, imgs = np.eye(3), [r.images for r in renders]
    else:
        R = frame_rotation(K_true, d_true, K, d, K_new)
        mx, my = cv2.initUndistortRectifyMap(K, d, None, K_new, (SIZE, SIZE), cv2.CV_32FC1)
        imgs = [np.stack([cv2.remap(im, mx, my, cv2.INTER_CUBIC) for im in r.images]) for r in renders]

    def to_frame(X):
        return C + (np.asarray(X) - C) @ R.T

    sets = [SphereImages(im, to_frame(r.center_mm), RADIUS, f"s{i}") for i, (im, r) in enumerate(zip(imgs, renders))]
    camera = make_camera("perspective", focal_length_px=f, camera_height_mm=HC, principal_point_px=K_new[:2, 2])
    extra = {} if rng_sd is None else {"pixel_sigma_px": rng_sd[0], "focal_length_sigma_px": rng_sd[1]}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            P, info = calibrate_positions(sets, camera, **extra)
    except InputError:
        return None
    return P - to_frame(lights.positions), np.array(info["uncertainty_mm"]), info


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=6, help="random trials per lens sign (default 6)")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(33)
    cam = synth_camera("perspective", SIZE, None, F, HC)
    _, lights, _ = rig_lights(8, 45.0, 200.0, 90.0, 0.0, None, None)
    K_true = lens_matrix(cam)
    rows, lens_rows = [], []
    t0 = time.perf_counter()
    for k1 in (-0.03, 0.03):
        d_true = np.array([k1, 0.0, 0.0, 0.0, 0.0])
        stats = {"checkerboard": [], "exact lens": [], "none": []}
        for _ in range(args.trials):
            K, d, sd, rms, used = checkerboard_lens(board_views(cam, d_true, rng))
            lens_rows.append((k1, rms, used, sd))
            renders = place_spheres(cam, lights, d_true, rng, rng.uniform(0.002, 0.01))
            stats["checkerboard"].append(solve(renders, lights, K, d, K_true, d_true, (rms, float(sd[:2].mean()))))
            stats["exact lens"].append(solve(renders, lights, K_true, d_true, K_true, d_true))
            stats["none"].append(solve(renders, lights, K_true, None, K_true, d_true))
        for name, runs in stats.items():
            done = [r for r in runs if r is not None]
            if not done:
                rows.append([f"{k1:+.2f}", name, f"0 / {len(runs)}", "-", "-", "-", "-", "-", "-"])
                continue
            err = np.concatenate([e for e, _, _ in done])
            u = np.concatenate([v for _, v, _ in done])
            norm = np.linalg.norm(err, axis=1)
            birge = [i["birge_ratio"] for _, _, i in done]
            warned = sum(bool(i["warnings"]) for _, _, i in done)
            rows.append([f"{k1:+.2f}", name, f"{len(done)} / {len(runs)}", f"{np.median(norm):.2f}",
                         f"{norm.max():.2f}", f"{np.median(np.linalg.norm(u, axis=1)):.2f}",
                         f"{100 * np.mean(np.abs(err) <= 2 * u):.1f}", f"{np.median(birge):.2f}", str(warned)])
    elapsed = time.perf_counter() - t0
    table = Table(["k1", "lens correction", "calibrated / trials", "LED error median (mm)", "LED error max (mm)",
                   "stated u median (mm, 3-D)", "coverage of U = 2u (%)", "Birge ratio median", "warned"],
                  rows, "rllrrrrrr")
    lens = Table(["k1", "views", "RMS reprojection (px)", "sd fx, fy (px)", "sd cx, cy (px)"],
                 [[f"{k:+.2f}", str(v), f"{r:.3f}", f"{s[0]:.2f}, {s[1]:.2f}", f"{s[2]:.2f}, {s[3]:.2f}"]
                  for k, r, v, s in lens_rows], "rrrrr")
    text = write_results("sphere_calibration", "Mirror-sphere calibration through a distorting lens", [
        f"{args.trials} random trials per lens sign (sphere places and heights, highlight phase, noise), 8 LEDs at "
        f"200 mm, spheres of radius {RADIUS:g} mm, camera {SIZE} px, f = {F:g} px, {HC:g} mm above the plane; "
        f"{elapsed:.0f} s. Command: `.venv/bin/python benchmarks/bench_sphere_calibration.py --trials "
        f"{args.trials}`. 'none' fails when the rays miss by more than 3 times the noise (the calibration refuses).",
        table, "Checkerboard calibrations (OpenCV, k3 fixed):", lens])
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
