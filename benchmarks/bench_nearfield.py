"""Benchmark of near-field photometric stereo: LEDs near the part, perspective lenses, flat fields (issue 15).

Run: ``.venv/bin/python benchmarks/bench_nearfield.py [--quick]``. Writes
``benchmarks/results/nearfield.md`` and prints it.

* Accuracy on rendered inspection rigs (:mod:`datasets_synthetic.nearfield`, the
  independent renderer of the rig contract): the issue's 60 mm plate with a 0.10 mm deep,
  12 mm long scratch, 3 or 4 LEDs 150-500 mm away at 45 deg slant, inverse-square
  falloff, LED lobes ``mu`` 0-2, noise 0.3 % of full scale, 16-bit, orthographic and
  perspective cameras. Each rig is reconstructed by the pipeline
  (:func:`photometric.pipeline.reconstruct`, default ``background="plane"``) with the
  near-field model and, on the same images, with today's far-field model (distant lights
  from the origin to each LED, orthographic camera): background height error after
  removing a best-fit plane, the scratch's depth and length.
* The flat-field variant: LED lobe unknown to the solver (rendered with ``mu`` = 2),
  unequal LED power and lens vignetting, solved from the LED positions and the rendered
  flat-field images.
* LED positions from mirror spheres (:mod:`datasets_synthetic.spheres`, the independent
  sphere renderer): :func:`photometric.calibrate.calibrate_rig` from two and three
  placements against the true positions (target: within 2 mm at 200 mm).
* Speed: a 5 MP (2592 x 1944) 4-LED near-field solve (alternation to convergence, heights
  and x, y) against the far-field solve plus DCT integration of the same images.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import Table, best_of, results_markdown, write_results  # noqa: E402

from datasets_synthetic.cameras import orthographic_camera, perspective_camera  # noqa: E402
from datasets_synthetic.heightfields import inspection_part  # noqa: E402
from datasets_synthetic.nearfield import render_near_field  # noqa: E402
from datasets_synthetic.point_lights import ring_point_lights  # noqa: E402
from datasets_synthetic.spheres import make_sphere_folders  # noqa: E402
from photometric.calibrate import calibrate_rig  # noqa: E402
from photometric.camera import make_camera  # noqa: E402
from photometric.integrate import integrate  # noqa: E402
from photometric.leds import point_lights  # noqa: E402
from photometric.nearfield import solve_nearfield  # noqa: E402
from photometric.pipeline import reconstruct  # noqa: E402
from photometric.stereo import solve  # noqa: E402

PLATE_MM = 60.0
CAMERA_HEIGHT_MM = 300.0
NOISE = 0.003
#: (camera, LEDs, distance mm, mu) of the accuracy table (3 m: the issue's "distant" LEDs).
RIGS = [
    ("orthographic", 3, 150.0, 0.0),
    ("orthographic", 3, 150.0, 2.0),
    ("orthographic", 4, 300.0, 1.0),
    ("orthographic", 4, 500.0, 2.0),
    ("orthographic", 3, 3000.0, 0.0),
    ("perspective", 3, 150.0, 1.0),
    ("perspective", 4, 250.0, 0.0),
    ("perspective", 4, 500.0, 2.0),
]


def _cameras(model: str, shape, pixel_mm: float):
    """The renderer's camera and the solver's options for the same lens."""
    if model == "orthographic":
        return orthographic_camera(shape, pixel_mm), {"camera": "orthographic", "pixel_size": pixel_mm}
    f = CAMERA_HEIGHT_MM / pixel_mm
    return (perspective_camera(shape, f, CAMERA_HEIGHT_MM),
            {"camera": "perspective", "focal_length_px": f, "camera_height_mm": CAMERA_HEIGHT_MM})


def _render(model, size, n, distance, mu, intensities=None, vignetting=None, seed=0):
    shape = (size, size)
    pixel_mm = PLATE_MM / size
    rcam, options = _cameras(model, shape, pixel_mm)
    part = inspection_part(shape, pixel_mm, "scratch")
    lights = ring_point_lights(n, 45.0, distance, 90.0, mu, intensities)
    r = render_near_field(part, rcam, lights, 0.8, vignetting=vignetting, noise=NOISE, bit_depth=16, seed=seed)
    return part, r, options, pixel_mm


def _timed(fn, repeat: int):
    """Best wall time (s, :func:`common.best_of`), best CPU time of the process (s) and the last result."""
    cpu = []

    def call():
        c0 = time.process_time()
        out = fn()
        cpu.append(time.process_time() - c0)
        return out

    wall, out = best_of(call, repeat)
    return wall, min(cpu), out


def _background_um(height, truth, use) -> float:
    """RMS height error (um) on ``use`` after removing its best-fit plane."""
    rows, cols = np.nonzero(use)
    err = (height - truth)[use]
    A = np.stack([np.ones_like(err), rows, cols], axis=1).astype(float)
    coef, *_ = np.linalg.lstsq(A, err, rcond=None)
    return 1e3 * float(np.sqrt(np.mean((err - A @ coef) ** 2)))


def _figures(res, r, truth_defect) -> list:
    """Background RMS, defects found, depth and length of the deepest (with errors)."""
    use = res.valid & np.isfinite(res.height) & ~r.hits.inside
    bg = _background_um(res.height, r.hits.height, use)
    if not res.defects:
        return [f"{bg:.2f}", "0", "none", "-", "none", "-"]
    d = res.defects[0]
    depth, length = d["max_depth_mm"], d["length_mm"]
    de = 100.0 * (depth / truth_defect["depth_mm"] - 1.0)
    le = 100.0 * (length / truth_defect["length_mm"] - 1.0)
    return [f"{bg:.2f}", str(len(res.defects)), f"{depth:.4f}", f"{de:+.1f}", f"{length:.3f}", f"{le:+.2f}"]


def accuracy(size: int) -> list:
    headers = ["camera", "LEDs", "distance (mm)", "mu", "model", "background RMS (um)", "defects",
               "scratch depth (mm)", "depth error (%)", "scratch length (mm)", "length error (%)", "passes",
               "time (s)"]
    rows = []
    for model, n, distance, mu in RIGS:
        part, r, options, pixel_mm = _render(model, size, n, distance, mu)
        truth = part.defects[0]
        t0 = time.perf_counter()
        near = reconstruct(r.images, lights=r.lights.directions, light_positions=r.lights.positions, led_mu=mu,
                           **options)
        t_near = time.perf_counter() - t0
        t0 = time.perf_counter()
        far = reconstruct(r.images, lights=r.lights.directions, pixel_size=pixel_mm)
        t_far = time.perf_counter() - t0
        head = [model, str(n), f"{distance:.0f}", f"{mu:g}"]
        rows.append(head + ["near field (point)", *_figures(near, r, truth), str(near.summary["iterations"]),
                            f"{t_near:.2f}"])
        rows.append(head + ["far field (today)", *_figures(far, r, truth), "1", f"{t_far:.2f}"])
    return [
        "## Accuracy on rendered inspection rigs",
        f"The issue's part: a {PLATE_MM:g} mm plate, {size} x {size} px ({1e3 * PLATE_MM / size:.1f} um per px on "
        f"the reference plane), one U-scratch 0.10 mm deep, 12 mm long, 0.5 mm wide at (3, -2) mm; LEDs on a "
        f"ring at 45 deg slant aimed at the origin, albedo 0.8, noise {100 * NOISE:g} % of full scale, 16-bit, "
        f"attached shadows; perspective: camera {CAMERA_HEIGHT_MM:g} mm above the plate. Both models through "
        "`photometric.pipeline.reconstruct` with the default `background=\"plane\"`; the background RMS is over "
        "the valid pixels outside the scratch after removing a best-fit plane (target < 5 um); the scratch is "
        "the deepest defect found (targets: depth within 5 %, length within 2 %). Time: the whole pipeline "
        "(solve, heights, surface patches, defects).",
        Table(headers, rows, "lrrrlrrrrrrrr"),
    ]


def flat_field(size: int) -> list:
    headers = ["camera", "solver knows", "background RMS (um)", "defects", "scratch depth (mm)", "depth error (%)",
               "scratch length (mm)", "length error (%)", "passes"]
    rows = []
    vignetting = {"model": "radial", "coefficients": [-0.25]}
    power = [1.0, 0.75, 1.25, 0.9]
    for model in ("orthographic", "perspective"):
        part, r, options, _ = _render(model, size, 4, 200.0, 2.0, power, vignetting, seed=1)
        truth = part.defects[0]
        common = dict(lights=r.lights.directions, light_positions=r.lights.positions, **options)
        flat = reconstruct(r.images, flat_field=r.flats, flat_albedo=r.flat_albedo, **common)
        bare = reconstruct(r.images, led_mu=0.0, **common)
        rows.append([model, "positions + flat field", *_figures(flat, r, truth), str(flat.summary["iterations"])])
        rows.append([model, "positions only (mu = 0, equal power)", *_figures(bare, r, truth),
                     str(bare.summary["iterations"])])
    return [
        "## Flat-field calibration (unknown LED lobe, power and vignetting)",
        f"4 LEDs 200 mm away, rendered with `mu` = 2, LED power {power}, radial vignetting "
        f"{vignetting['coefficients'][0]:g} rho^2; flat fields: the renderer's target (albedo 0.8) in the "
        "reference plane, same exposure, noise and bit depth. The solver gets the LED positions and the flat "
        "fields only (no `mu`, no intensities).",
        Table(headers, rows, "llrrrrrrr"),
    ]


#: Mirror-sphere placements (centre, mm; radius 10 mm): two resting on the plate, one raised.
SPHERES = [[-12.0, 8.0, 10.0], [12.0, -8.0, 10.0], [0.0, 10.0, 25.0]]


def calibration(size: int) -> list:
    headers = ["camera", "LED distance (mm)", "placements", "largest error (mm)", "mean error (mm)",
               "RMS ray residual (mm)", "largest stated uncertainty (mm)", "time (s)"]
    rows = []
    for model in ("orthographic", "perspective"):
        for distance in (200.0, 500.0):
            _, options = _cameras(model, (size, size), PLATE_MM / size)
            cam = ({"pixel_size": options["pixel_size"]} if model == "orthographic"
                   else {"focal_length_px": options["focal_length_px"], "camera_height": CAMERA_HEIGHT_MM})
            with tempfile.TemporaryDirectory() as tmp:
                scene = make_sphere_folders(tmp, SPHERES, radius=10.0, size=size, lights=4, slant=45.0,
                                            light_distance=distance, camera=model, noise=NOISE, bit_depth=16,
                                            **cam)
                truth = np.array(scene["lights"]["positions_mm"])
                for count in (2, 3):
                    t0 = time.perf_counter()
                    rig = calibrate_rig(spheres=[Path(tmp) / f"sphere_{m + 1:02d}" for m in range(count)])
                    t = time.perf_counter() - t0
                    err = np.linalg.norm(rig.lights.positions - truth, axis=1)
                    sd = np.linalg.norm(rig.calibration["uncertainty_mm"], axis=1)
                    rows.append([model, f"{distance:.0f}", str(count), f"{err.max():.3f}", f"{err.mean():.3f}",
                                 f"{rig.calibration['rms_residual_mm']:.4f}", f"{sd.max():.3f}", f"{t:.2f}"])
    return [
        "## LED positions from mirror spheres",
        f"{size} x {size} px over the {PLATE_MM:g} mm field, 4 LEDs at 45 deg slant, polished spheres of radius "
        f"10 mm at {SPHERES[0]} and {SPHERES[1]} mm (2 placements) and {SPHERES[2]} mm (3), the renderer's LED "
        f"discs of radius 1 mm, lens blur 1 px, noise {100 * NOISE:g} %, 16-bit; sphere centres from "
        "`sphere.json`. Error: distance of each calibrated LED to the true one (target < 2 mm at 200 mm); "
        "the stated uncertainty is the norm of the per-axis standard deviations `calibrate_rig` reports.",
        Table(headers, rows, "lrrrrrrr"),
    ]


def speed(shape, repeat: int) -> list:
    h, w = shape
    pixel_mm = PLATE_MM / w
    rcam = orthographic_camera(shape, pixel_mm)
    part = inspection_part(shape, pixel_mm, "scratch")
    lights = ring_point_lights(4, 45.0, 200.0, 90.0, 1.0)
    r = render_near_field(part, rcam, lights, 0.8, noise=NOISE, bit_depth=16, seed=2)
    images = r.images
    cam = make_camera("orthographic", pixel_size_mm=pixel_mm)
    pl = point_lights(lights.positions, mu=1.0)
    def far():
        f = solve(images, lights.directions)
        return integrate(f.p, f.q, "dct", mask=f.valid, pixel_size=pixel_mm)

    load = os.getloadavg()[0]
    t_near, c_near, res = _timed(lambda: solve_nearfield(images, pl, cam), repeat)
    t_far, c_far, _ = _timed(far, repeat)
    t_solve, c_solve, _ = _timed(lambda: solve(images, lights.directions), repeat)
    # the whole pipeline once each: the surface patches and defects cost the same for both models
    t_pipe_near, c_pipe_near, _ = _timed(lambda: reconstruct(images, lights=lights.directions,
                                                             light_positions=lights.positions, led_mu=1.0,
                                                             camera="orthographic", pixel_size=pixel_mm), 1)
    t_pipe_far, c_pipe_far, _ = _timed(lambda: reconstruct(images, lights=lights.directions, pixel_size=pixel_mm), 1)
    use = res.valid & ~r.hits.inside
    bg = _background_um(res.height, r.hits.height, use)
    passes = ", ".join(f"{e['level']} {e['depth_change_mm']:.2g} ({100 * e['resolved_fraction']:.1f} % of the pixels "
                       "re-solved)" for e in res.history)
    rows = [
        ["near field: `solve_nearfield` (alternation, heights, x, y)", f"{t_near:.2f}", f"{t_near / t_far:.2f}",
         f"{c_near:.2f}", f"{c_near / c_far:.2f}"],
        ["far field: `stereo.solve` + DCT integration", f"{t_far:.2f}", "1.00", f"{c_far:.2f}", "1.00"],
        ["far field: `stereo.solve` only", f"{t_solve:.2f}", f"{t_solve / t_far:.2f}", f"{c_solve:.2f}",
         f"{c_solve / c_far:.2f}"],
        ["near field: whole `pipeline.reconstruct` (+ surface patches, mesh, defects; one run)",
         f"{t_pipe_near:.2f}", f"{t_pipe_near / t_far:.2f}", f"{c_pipe_near:.2f}", f"{c_pipe_near / c_far:.2f}"],
        ["far field: whole `pipeline.reconstruct` (one run)", f"{t_pipe_far:.2f}", f"{t_pipe_far / t_far:.2f}",
         f"{c_pipe_far:.2f}", f"{c_pipe_far / c_far:.2f}"],
    ]
    return [
        "## Speed",
        f"{w} x {h} px ({h * w / 1e6:.1f} MP), 4 LEDs 200 mm away, `mu` = 1, orthographic, float32 images; best "
        f"of {repeat} wall times on this {os.cpu_count()}-core machine (target: near field under 3 s) and best of "
        f"{repeat} CPU times of the process (all threads; less sensitive to the other jobs sharing the machine, "
        f"load average {load:.1f} when the timing started). The near-field solve made {res.iterations} passes "
        f"(level and largest height change, mm: {passes}); of its last run's time "
        f"{res.timings_s['solve']:.2f} s went to the light vectors and normals and "
        f"{res.timings_s['integrate']:.2f} s to integration and anchoring. Background RMS of "
        f"this solve: {bg:.2f} um.",
        Table(["task", "wall time (s)", "wall ratio to far field", "CPU time (s, all threads)", "CPU ratio"], rows,
              "lrrrr"),
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    args = parser.parse_args(argv)
    size, speed_shape, repeat = (256, (486, 648), 2) if args.quick else (1024, (1944, 2592), 3)
    title = "Near-field photometric stereo (`photometric.nearfield`)"
    parts = [
        f"Command: `.venv/bin/python benchmarks/bench_nearfield.py{' --quick' if args.quick else ''}` "
        f"({os.cpu_count()} cores, shared; numpy {np.__version__}).",
        *speed(speed_shape, repeat),
        *accuracy(size),
        *flat_field(size),
        *calibration(size // 2),
    ]
    # a quick run is a smoke test: its sizes are not the published figures
    text = results_markdown(title, parts) if args.quick else write_results("nearfield", title, parts)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
