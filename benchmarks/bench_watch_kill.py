"""``workbench inspect watch`` under SIGKILL: every part gets exactly one results.csv row.

A lot of ``--parts`` (default 48) small rendered parts sits in an inbox. ``workbench inspect
watch`` runs in a subprocess and is killed with SIGKILL ``--kills`` times (default 5) at
random moments (seeded), restarted each time, then run once more to the end. Two set-ups:

- **local**: the watch's own local Dask cluster (``--workers 2``); its worker processes are
  killed with it (what is left of its process tree is killed by pid);
- **scheduler**: a running ``dask scheduler`` and ``dask worker`` (2 processes) on loopback,
  started here; they outlive the watch, so tasks of a killed watch finish its parts without it
  (the case of issue 31 that left 43 rows for 48 parts).

The baseline, in the same run: ``workbench inspect run`` over the same inbox without any kill
(rows and wall time). The figures: rows in results.csv, distinct ids, parts with a complete
folder, rows whose status is not ``ok``, and the wall time of the whole killed-and-restarted
sequence against the baseline's.

Writes ``benchmarks/results/watch_kill.md`` and prints it.

Run: ``.venv/bin/python benchmarks/bench_watch_kill.py [--parts 48] [--kills 5] [--seed 31]``
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
from common import Table, write_results

from photometric.camera import make_camera
from workbench.inspect.lot import lot_plan, render_lot
from workbench.runs.photometric import calibrate_to_rig

REPO = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(REPO)}


def make_inbox(root: Path, n: int, size: int) -> tuple[Path, Path, Path]:
    """Render ``n`` parts and calibrate the rig; return (inbox, rig.json, spec.json)."""
    truth = render_lot(root, lot_plan(n, 0.10, seed=31), size=size, field_mm=20.0, noise=0.003)
    flats = sorted(str(p) for p in (root / "rig").glob("flat_*.png"))
    rig = root / "rig.json"
    calibrate_to_rig(rig, light_positions=root / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    spec = root / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.10}))
    return root / "parts", rig, spec


def rows_of(out: Path) -> list[dict]:
    """Every data line of results.csv (duplicates kept: they are what is counted)."""
    path = out / "results.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def kill_tree(proc: subprocess.Popen) -> None:
    """SIGKILL a process started here and every process it started (by pid)."""
    try:
        children = psutil.Process(proc.pid).children(recursive=True)
    except psutil.NoSuchProcess:
        children = []
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    for child in children:
        try:
            child.kill()
        except psutil.NoSuchProcess:
            pass


def watch_argv(inbox: Path, rig: Path, spec: Path, out: Path, where: list[str], timeout: float | None) -> list[str]:
    argv = [sys.executable, "-m", "workbench", "inspect", "watch", str(inbox), "--rig", str(rig), "--spec",
            str(spec), "--out", str(out), "--interval", "0.3", "--settle", "0", *where]
    return argv + (["--timeout", f"{timeout:g}"] if timeout is not None else [])


def complete(out: Path) -> int:
    """Part folders with their ``_COMPLETE`` marker."""
    return sum(1 for _ in out.glob("*/_COMPLETE")) if out.is_dir() else 0


def killed_watch(inbox: Path, rig: Path, spec: Path, out: Path, where: list[str], kills: int, n: int,
                 rng: random.Random, kill_local_tree: bool) -> dict:
    """Start and SIGKILL the watch ``kills`` times mid-run, then run it to the end.

    Each kill comes at a random moment of the run: once a random number of further parts (at least
    one, leaving at least one) has a complete folder, plus a random 0-0.5 s.
    """
    t0 = time.perf_counter()
    moments = []
    for _ in range(kills):
        proc = subprocess.Popen(watch_argv(inbox, rig, spec, out, where, None), env=ENV, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        done = complete(out)
        target = rng.randint(min(done + 1, n - 1), n - 1) if done < n - 1 else n
        started = time.perf_counter()
        while complete(out) < target and time.perf_counter() - started < 300 and proc.poll() is None:
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 0.5))
        moments.append((round(time.perf_counter() - started, 2), complete(out), len(rows_of(out))))
        if kill_local_tree:
            kill_tree(proc)
        else:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
    # the last watch: the parts still in flight on a running scheduler finish meanwhile; a watch
    # started once they are all complete heals their rows
    final = subprocess.run(watch_argv(inbox, rig, spec, out, where, 1.0), env=ENV, capture_output=True, text=True,
                           timeout=900)
    rows = rows_of(out)
    return {"wall_s": time.perf_counter() - t0, "moments": moments, "rows": rows, "exit": final.returncode,
            "stdout": final.stdout.strip().splitlines()[-1:] if final.stdout else []}


def start_scheduler(tmp: Path) -> tuple[str, list[subprocess.Popen]]:
    """``dask scheduler`` + ``dask worker`` (2 processes, 1 thread each) on loopback; return its address."""
    dask = str(Path(sys.executable).with_name("dask"))
    file = tmp / "scheduler.json"
    sched = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
                              "--scheduler-file", str(file)], env=ENV, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, cwd=tmp)
    deadline = time.monotonic() + 60
    while not file.is_file() and time.monotonic() < deadline:
        time.sleep(0.1)
    address = json.loads(file.read_text())["address"]
    worker = subprocess.Popen([dask, "worker", address, "--nworkers", "2", "--nthreads", "1", "--no-dashboard",
                               "--local-directory", str(tmp / "dask-worker")], env=ENV, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, cwd=tmp)
    from distributed import Client

    with Client(address, timeout="30s") as client:
        client.wait_for_workers(2, timeout=60)
    return address, [worker, sched]


def summary_row(name: str, result: dict, n: int, out: Path, baseline_s: float) -> list:
    rows = result["rows"]
    ids = {r["id"] for r in rows}
    complete = sum((out / pid / "_COMPLETE").is_file() for pid in ids)
    not_ok = sum(r["status"] != "ok" for r in rows)
    return [name, n, len(rows), len(ids), complete, not_ok, f"{result['wall_s']:.1f}",
            f"{result['wall_s'] / baseline_s:.2f}", "; ".join(f"{w:g} s: {c} done, {k} rows" for w, c, k in
                                                             result["moments"])]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", type=int, default=48)
    ap.add_argument("--kills", type=int, default=5)
    ap.add_argument("--size", type=int, default=160, help="part image size, px")
    ap.add_argument("--seed", type=int, default=31)
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="bench_watch_kill_") as tmp_name:
        tmp = Path(tmp_name)
        t0 = time.perf_counter()
        inbox, rig, spec = make_inbox(tmp / "lot", args.parts, args.size)
        t_render = time.perf_counter() - t0
        # baseline: one uninterrupted inspect run over the same inbox
        t0 = time.perf_counter()
        base = subprocess.run([sys.executable, "-m", "workbench", "inspect", "run", str(inbox), "--rig", str(rig),
                               "--spec", str(spec), "--out", str(tmp / "out_run"), "--workers", "2"], env=ENV,
                              capture_output=True, text=True, timeout=900)
        baseline_s = time.perf_counter() - t0
        base_rows = rows_of(tmp / "out_run")
        table_rows = [["inspect run, no kill (baseline)", args.parts, len(base_rows), len({r["id"] for r in base_rows}),
                       sum((tmp / "out_run" / r["id"] / "_COMPLETE").is_file() for r in base_rows),
                       sum(r["status"] != "ok" for r in base_rows), f"{baseline_s:.1f}", "1.00", ""]]
        local = killed_watch(inbox, rig, spec, tmp / "out_local", ["--workers", "2"], args.kills, args.parts, rng,
                             True)
        table_rows.append(summary_row("watch, local cluster, killed", local, args.parts, tmp / "out_local",
                                      baseline_s))
        address, services = start_scheduler(tmp)
        try:
            remote = killed_watch(inbox, rig, spec, tmp / "out_sched", ["--scheduler", address], args.kills,
                                  args.parts, rng, False)
        finally:
            for proc in services:
                proc.send_signal(signal.SIGINT)
            for proc in services:
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
        table_rows.append(summary_row("watch, running scheduler, killed", remote, args.parts, tmp / "out_sched",
                                      baseline_s))
        shutil.rmtree(tmp / "dask-worker", ignore_errors=True)
    if base.returncode != 0:
        print(base.stderr, file=sys.stderr)
    table = Table(["run", "parts", "rows", "distinct ids", "complete folders", "rows not ok", "wall (s)",
                   "wall / baseline", "each kill: s after start: complete folders, rows then"], table_rows, "lrrrrrrrl")
    command = (f"Command: `.venv/bin/python benchmarks/bench_watch_kill.py --parts {args.parts} --kills {args.kills} "
               f"--size {args.size} --seed {args.seed}`; machine: {os.cpu_count()} CPUs shared with other work, "
               f"Python {platform.python_version()}.")
    text = write_results("watch_kill", "inspect watch under SIGKILL", [
        command,
        f"{args.parts} parts ({args.size} x {args.size} px, 4 lights, rendered in {t_render:.0f} s), "
        f"{args.kills} SIGKILLs of the watch at random moments mid-run (once a random number of further parts is "
        f"complete, plus 0-0.5 s; seed {args.seed}), a restart after each, then "
        "one last watch (--timeout 1); every watch polls every 0.3 s with --settle 0. Expected: rows = distinct "
        "ids = complete folders = parts, no row failed. Wall time includes every start of the CLI and its "
        "cluster; the baseline is one uninterrupted `inspect run --workers 2` in the same run.",
        table,
        "Last line of the last watch: local "
        f"{' '.join(local['stdout'])!r}, scheduler {' '.join(remote['stdout'])!r}.",
    ])
    print(text)
    ok = all(int(r[2]) == int(r[3]) == int(r[4]) == args.parts and int(r[5]) == 0 for r in table_rows)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
