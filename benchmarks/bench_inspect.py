"""``workbench inspect``: verdicts of a rendered production lot against truth, and throughput.

Two parts, one process run, everything rendered in the run (nothing precomputed):

1. **The lot.** ``--lot`` parts (default 40) of a 60 mm plate on a near-field rig (4 LEDs
   on a ring 200 mm from the part centre at 40 deg slant, orthographic camera, flat field,
   0.3 % image noise, a different albedo texture and brightness per part): clean parts and
   parts with one scratch, crack or dent of known depth around the 0.10 mm limit
   (:func:`workbench.inspect.lot.lot_plan`). The rig is calibrated from the rendered flat
   field (``inspect calibrate``), the lot runs through ``inspect run`` on 2 local workers
   under ``simple`` and under ``guard_band``; the table counts verdicts per truth class.
2. **Throughput.** ``--parts`` 5 MP 4-light parts (2592 x 1944 px, 16-bit PNG, and the same
   pixels as uncompressed 16-bit TIFF), from images on disk to ``result.json`` and
   ``overlay.png`` on 2 local workers (cluster start and one warm-up part per worker
   excluded), against running ``workbench photometric reconstruct --images ... --rig rig.json``
   per part, one after another, on the same parts in the same run. Where the time goes: the
   stage timings (wall) and the CPU seconds each part's ``result.json`` records.

Writes ``benchmarks/results/inspect.md`` and prints it.

Run: ``.venv/bin/python benchmarks/bench_inspect.py [--lot 40] [--lot-size 1024] [--parts 6] [--workers 2]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from common import Table, write_results

from photometric.camera import make_camera
from workbench.batch import connect
from workbench.inspect.lot import LotPart, lot_plan, render_lot
from workbench.inspect.run import run_inspection
from workbench.runs.photometric import calibrate_to_rig

LIMIT = 0.10
FIELD_MM = 60.0
BIG = (1944, 2592)
#: stated input uncertainties of the guard_band run (image noise estimated from the 4 lights' residuals)
UNCERTAINTY = {"method": "linear", "light_position_tolerance_mm": 0.2}


def _rig(root: Path, truth: dict) -> Path:
    flats = sorted(str(p) for p in (root / "rig").glob("flat_*.png"))
    rig = root / "rig.json"
    calibrate_to_rig(rig, light_positions=root / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    return rig


def _spec(root: Path, rule: str) -> Path:
    path = root / f"spec_{rule}.json"
    path.write_text(json.dumps({"max_depth_mm": LIMIT, "decision_rule": rule}))
    return path


def _klass(depth: float) -> str:
    if depth == 0:
        return "clean"
    if depth < 0.9 * LIMIT:
        return "under (0.3-0.6 x limit)"
    if depth <= 1.1 * LIMIT:
        return "borderline (0.93-1.07 x limit)"
    return "over (1.5-2.2 x limit)"


def lot_section(root: Path, client, n: int, size: int) -> list:
    t0 = time.perf_counter()
    truth = render_lot(root, lot_plan(n, LIMIT, seed=7), size=size, field_mm=FIELD_MM, noise=0.003)
    t_render = time.perf_counter() - t0
    rig = _rig(root, truth)
    outcome = {}
    for rule in ("simple", "guard_band"):
        options = {"uncertainty": UNCERTAINTY} if rule == "guard_band" else {}
        run = run_inspection(root / "parts", rig, _spec(root, rule), root / f"out_{rule}", client=client,
                             options=options)
        outcome[rule] = run
    # the same guard_band lot through photometric.pipeline.reconstruct (the route before the stages: a
    # pipeline-only option sends a part there), to compare every verdict and U
    before = run_inspection(root / "parts", rig, _spec(root, "guard_band"), root / "out_before", client=client,
                            options={"uncertainty": UNCERTAINTY, **BEFORE})
    same_verdicts, same_u = _compare(root / "out_guard_band", root / "out_before", [p["id"] for p in truth["parts"]])
    classes = ["clean", "under (0.3-0.6 x limit)", "borderline (0.93-1.07 x limit)", "over (1.5-2.2 x limit)"]
    rows, errors, checks = [], [], {"clean pass": [0, 0], "over by > 2U fail": [0, 0],
                                    "under by > 2U pass": [0, 0], "within U of the limit uncertain": [0, 0]}
    for klass in classes:
        members = [p for p in truth["parts"] if _klass(p["depth_mm"]) == klass]
        row = [klass, len(members)]
        for rule in ("simple", "guard_band"):
            counts = {"pass": 0, "fail": 0, "uncertain": 0, "not measured": 0}
            for p in members:
                path = root / f"out_{rule}" / p["id"] / "result.json"
                if not path.is_file():
                    counts["not measured"] += 1
                    continue
                r = json.loads(path.read_text())
                counts[r["verdict"]] += 1
                if rule == "simple" and p["defect"] is not None:
                    errors.append(r["max_depth_mm"] - p["depth_mm"])
                if rule == "guard_band":
                    u = r.get("max_depth_U_mm")
                    if p["defect"] is None:
                        checks["clean pass"][0] += 1
                        checks["clean pass"][1] += r["verdict"] == "pass"
                    elif u is not None and p["depth_mm"] - LIMIT > 2 * u:
                        checks["over by > 2U fail"][0] += 1
                        checks["over by > 2U fail"][1] += r["verdict"] == "fail"
                    elif u is not None and LIMIT - p["depth_mm"] > 2 * u:
                        checks["under by > 2U pass"][0] += 1
                        checks["under by > 2U pass"][1] += r["verdict"] == "pass"
                    elif u is not None and abs(p["depth_mm"] - LIMIT) < u:
                        checks["within U of the limit uncertain"][0] += 1
                        checks["within U of the limit uncertain"][1] += r["verdict"] == "uncertain"
            row += [counts["pass"], counts["fail"], counts["uncertain"], counts["not measured"]]
        rows.append(row)
    failed_reasons = sorted({row["error"] for row in outcome["guard_band"].batch.rows if row["status"] == "failed"})
    table = Table(["truth", "parts", "simple: pass", "fail", "uncertain", "not measured",
                   "guard_band: pass", "fail", "uncertain", "not measured"], rows, "lrrrrrrrrr")
    err = np.asarray(errors)
    parts = [
        "## The lot: verdicts against truth",
        f"{n} parts rendered at {size} x {size} px over a {FIELD_MM:g} mm field ({truth['pixel_size_mm']:.4f} mm "
        f"per pixel) in {t_render:.0f} s; depth limit {LIMIT} mm. Simple rule: {outcome['simple'].batch.ok} parts "
        f"measured in {outcome['simple'].batch.wall_s:.1f} s on the cluster.",
        table,
        f"Measured depth of the rendered defect minus its true depth (simple run, {err.size} defects): mean "
        f"{err.mean():+.4f} mm, RMS {np.sqrt(np.mean(err ** 2)):.4f} mm, worst {err[np.argmax(np.abs(err))]:+.4f} mm.",
        f"guard_band: U (k = 2) from photometric's linear propagation with {UNCERTAINTY} (image noise estimated "
        "from the residuals of the 4 lights). Acceptance under guard_band, by truth (parts for which the "
        "measurement stated U): "
        + "; ".join(f"{k}: {ok} of {total}" for k, (total, ok) in checks.items()) + ".",
    ]
    parts.append(f"guard_band through the stages (no surface) and through `reconstruct` (the route before, "
                 f"{before.batch.wall_s:.1f} s against {outcome['guard_band'].batch.wall_s:.1f} s on the cluster): "
                 f"same verdict for {same_verdicts} of {n} parts, same imperfections and U (rel. 1e-6) for {same_u} "
                 f"of {n}.")
    if failed_reasons:
        parts.append("guard_band parts not measured: " + "; ".join(failed_reasons) + " (guard_band never "
                     "invents a U: without the stated uncertainty of a near-field solve it refuses).")
    return parts


#: options that send a part through photometric.pipeline.reconstruct, as every guard_band part went before the
#: stages (a coarse Coons surface and mesh that nothing in result.json uses, the rig's strengths from its gains
#: each part)
BEFORE = {"surface": "coons"}


def _compare(a: Path, b: Path, ids: list) -> tuple[int, int]:
    """Parts with the same verdict, and with the same imperfections (values exact, U to rel. 1e-6)."""
    verdicts = same = 0
    for pid in ids:
        ra, rb = (json.loads((root / pid / "result.json").read_text()) for root in (a, b))
        verdicts += ra["verdict"] == rb["verdict"]
        ia, ib = ra["imperfections"], rb["imperfections"]
        ok = len(ia) == len(ib)
        for x, y in zip(ia, ib):
            for key, value in x["values"].items():
                other = y["values"][key]
                ok &= value["value"] == other["value"] and (value["U"] == other["U"] or (
                    value["U"] is not None and other["U"] is not None
                    and abs(value["U"] - other["U"]) <= 1e-6 * abs(other["U"])))
        same += ok
    return verdicts, same


def _tiff_copies(parts: list, root: Path) -> list:
    """The same parts as uncompressed 16-bit TIFF (an industrial camera's usual format), pixel for pixel."""
    out = []
    for pid, folder in parts:
        dst = root / pid
        dst.mkdir(parents=True, exist_ok=True)
        names = []
        for png in sorted(folder.glob("*.png")):
            img = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
            name = png.with_suffix(".tif").name
            cv2.imwrite(str(dst / name), img, [cv2.IMWRITE_TIFF_COMPRESSION, 1])
            names.append(name)
        (dst / "filenames.txt").write_text("\n".join(names) + "\n")
        out.append((pid, dst.resolve()))
    return out


def _stage_means(out: Path, timed: list) -> dict:
    stages: dict[str, list] = {}
    for pid, _ in timed:
        t = json.loads((out / pid / "result.json").read_text())["timings_s"]
        st = t["stages"]
        named = {"read": st["read"], "screen images, light matrix": st["screen"], "near-field: normals": st["solve"],
                 "near-field: integration and anchoring": st["integrate"],
                 "near-field: set-up, coarse-to-fine bookkeeping, slopes, points":
                     st["nearfield"] - st["solve"] - st["integrate"],
                 "defects": st["defects"], "decide": t["decide"], "overlay": t["overlay"]}
        named["rig (cached), mask, result.json"] = t["total"] - sum(named.values())
        named["one part (inside its worker)"] = t["total"]
        named["CPU s of one part (its worker process)"] = t["cpu"]
        for k, v in named.items():
            stages.setdefault(k, []).append(v)
    return {k: sum(v) / len(v) for k, v in stages.items()}


def throughput_section(root: Path, client, n_parts: int, workers: int) -> list:
    plan = [LotPart(f"big_{k:02d}", ("scratch", "crack", "dent", None)[k % 4], 0.12 if k % 4 < 3 else 0.0, 1.0, k)
            for k in range(n_parts + workers)]
    t0 = time.perf_counter()
    truth = render_lot(root, plan, size=BIG, field_mm=FIELD_MM, noise=0.003)
    t_render = time.perf_counter() - t0
    rig = _rig(root, truth)
    spec = _spec(root, "simple")
    parts = [(p.id, (root / "parts" / p.id).resolve()) for p in plan]
    warm, timed = parts[:workers], parts[workers:]
    timed_tif = _tiff_copies(timed, root / "parts_tif")
    run_inspection(warm, rig, spec, root / "warm", client=client)
    load = os.getloadavg()[0]
    run = run_inspection(timed, rig, spec, root / "out", client=client)
    run_tif = run_inspection(timed_tif, rig, spec, root / "out_tif", client=client)
    same = all(json.loads((root / "out" / pid / "result.json").read_text())["imperfections"]
               == json.loads((root / "out_tif" / pid / "result.json").read_text())["imperfections"] for pid, _ in timed)
    guard = _spec(root, "guard_band")
    run_guard = run_inspection(timed, rig, guard, root / "out_guard", client=client,
                               options={"uncertainty": UNCERTAINTY})
    run_before = run_inspection(timed, rig, guard, root / "out_before", client=client,
                                options={"uncertainty": UNCERTAINTY, **BEFORE})
    guard_same = _compare(root / "out_guard", root / "out_before", [pid for pid, _ in timed])
    rate, rate_tif = run.parts_per_second, run_tif.parts_per_second
    mean, mean_tif = _stage_means(root / "out", timed), _stage_means(root / "out_tif", timed)
    # the same parts through `workbench photometric reconstruct`, one process per part, one after another
    cli = [sys.executable, "-m", "workbench", "photometric", "reconstruct"]
    t0 = time.perf_counter()
    for pid, folder in timed:
        images = sorted(str(p) for p in folder.glob("*.png"))
        subprocess.run([*cli, "--images", *images, "--rig", str(rig), "--out", str(root / "recon" / pid)],
                       check=True, capture_output=True)
    t_cli = time.perf_counter() - t0
    cli_rate = len(timed) / t_cli
    total = mean["one part (inside its worker)"]
    rows = [[k, f"{v:.2f}", f"{mean_tif[k]:.2f}", "" if k.startswith("CPU") else f"{100 * v / total:.0f}"]
            for k, v in mean.items()]
    cpu, cpu_tif = mean["CPU s of one part (its worker process)"], mean_tif["CPU s of one part (its worker process)"]
    return [
        "## Throughput: 5 MP 4-light parts from disk to result.json + overlay.png",
        f"{len(timed)} parts of {BIG[1]} x {BIG[0]} px (rendered in {t_render:.0f} s with {workers} warm-up parts), "
        f"{workers} local workers (one thread each: BLAS/OpenMP, OpenCV and the near-field pool held to 1), "
        f"load average when the timed runs started {load:.1f}. The same parts as 16-bit PNG (as rendered) and as "
        f"uncompressed 16-bit TIFF (the same pixels; imperfections identical in both runs: {same}).",
        Table(["run", "parts", "wall s", "parts/s"], [
            [f"workbench inspect run, {workers} workers, 16-bit PNG", len(timed), f"{run.batch.wall_s:.1f}",
             f"{rate:.3f}"],
            [f"workbench inspect run, {workers} workers, 16-bit TIFF", len(timed), f"{run_tif.batch.wall_s:.1f}",
             f"{rate_tif:.3f}"],
            ["workbench photometric reconstruct --rig, per part, one after another (PNG)", len(timed), f"{t_cli:.1f}",
             f"{cli_rate:.3f}"],
        ], "lrrr"),
        f"Ratio (inspect run, PNG / photometric reconstruct per part): **{rate / cli_rate:.1f}**. Target 1 part/s "
        "(PNG): " + ("reached." if rate >= 1.0 else f"**not reached** ({rate:.2f} parts/s; TIFF {rate_tif:.2f})."),
        f"CPU per part: {cpu:.2f} s (PNG), {cpu_tif:.2f} s (TIFF), so {workers} workers on {workers} free cores "
        f"would finish about {workers / cpu:.2f} (PNG) and {workers / cpu_tif:.2f} (TIFF) parts/s; the wall figures "
        "above are what the shared machine gave.",
        "Where the time of one part goes (mean over the timed parts, wall seconds as each worker measured them; "
        "the inspection composes the library stages itself: read, screening, the near-field solve with the rig's "
        "strengths prepared once per worker, the defect measures; no surface model or mesh):",
        Table(["stage", "PNG s", "TIFF s", "% (PNG)"], rows, "lrrr"),
        *_guard_section(root, timed, run_guard, run_before, guard_same),
    ]


def _part_means(out: Path, timed: list) -> dict:
    """Mean wall seconds of the measurement and of the part, and CPU seconds, over the parts' result.json."""
    keys = {"measurement (read to U)": "reconstruct", "one part (inside its worker)": "total",
            "CPU s of one part (its worker process)": "cpu"}
    t = [json.loads((out / pid / "result.json").read_text())["timings_s"] for pid, _ in timed]
    means = {name: sum(x[key] for x in t) / len(t) for name, key in keys.items()}
    means["of which uncertainty"] = sum(x["stages"].get("uncertainty", 0.0) for x in t) / len(t)
    means["of which surface model and mesh"] = sum(x["stages"].get("surface", 0.0) for x in t) / len(t)
    return means


def _guard_section(root: Path, timed: list, run_guard, run_before, same: tuple) -> list:
    new, old = _part_means(root / "out_guard", timed), _part_means(root / "out_before", timed)
    rows = [[k, f"{old[k]:.2f}", f"{new[k]:.2f}", f"{old[k] / new[k]:.2f}" if new[k] > 0 else ""] for k in new]
    rows.append(["parts/s, 2 workers (wall)", f"{run_before.parts_per_second:.3f}",
                 f"{run_guard.parts_per_second:.3f}",
                 f"{run_guard.parts_per_second / run_before.parts_per_second:.2f}"])
    cpu = "CPU s of one part (its worker process)"
    return [
        "### guard_band: the stages against the route before",
        f"The same {len(timed)} PNG parts under `guard_band` with U from {UNCERTAINTY}: through the part's "
        "stages (read, solve with the rig's strengths prepared once per worker, integrate, measure, uncertainty; "
        "no surface) and through `photometric.pipeline.reconstruct`, the route every part with an uncertainty "
        "took before (a coarse Coons surface and mesh that nothing in result.json uses, the rig's strengths "
        f"from its gains each part), in the same run. Same verdict for {same[0]} of {len(timed)} parts, same "
        f"imperfections and U for {same[1]} of {len(timed)}.",
        Table(["per part (mean)", "before s", "stages s", "before / stages"], rows, "lrrr"),
        f"CPU per guard_band part: {old[cpu]:.2f} s before, {new[cpu]:.2f} s with the stages: "
        f"**{100 * (1 - new[cpu] / old[cpu]):.0f} % less** (target: at least 10 %).",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lot", type=int, default=40)
    ap.add_argument("--lot-size", type=int, default=1024)
    ap.add_argument("--parts", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench_inspect_") as tmp, connect("local", args.workers) as client:
        root = Path(tmp)
        lot = lot_section(root / "lot", client, args.lot, args.lot_size)
        big = throughput_section(root / "big", client, args.parts, args.workers) if args.parts else []
    text = write_results("inspect", "workbench inspect: a rendered lot and throughput", [
        f"Machine: {os.cpu_count()} CPUs shared with other work (load average before the run {load_before:.1f}, "
        f"after {os.getloadavg()[0]:.1f}), Python {platform.python_version()}. Command: "
        f"`.venv/bin/python benchmarks/bench_inspect.py --lot {args.lot} --lot-size {args.lot_size} "
        f"--parts {args.parts} --workers {args.workers}`.",
        *lot, *big,
    ])
    print(text)


if __name__ == "__main__":
    main()
