"""Peak memory of the three reconstruct commands against the size of their input.

Every run is a fresh ``workbench`` process started by a small runner process that
reports ``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` (the peak resident set of
that one command). The interpreter's baseline (Python with the modules the
command imports, nothing computed) is measured the same way and subtracted, and the
rest is divided by the raw input bytes:

* ``workbench photometric reconstruct`` (far field, 3 16-bit PNG images of a lit
  hemisphere; raw bytes = 3 x H x W x 2) at 1, 4, 16 and 64 MP. The 64 MP case is
  run only when its extrapolated peak fits in half of the machine's available
  memory; otherwise the page says so.
* ``workbench slices reconstruct --hu-min 0`` on a CT phantom series (``workbench synth
  phantom --format dicom`` at three pixel sizes; raw bytes = the series' pixel data).
* ``workbench surfaces coons`` on 64^2, 128^2 and 256^2 point grids at 8 samples per
  patch (raw bytes = the grid's float64 values), beside the command's own estimate.

Writes ``benchmarks/results/memory.md`` and prints it.

Run: ``.venv/bin/python benchmarks/bench_memory.py [--sizes 1 4 16 64] [--profile-sizes 4 16]
[--phantom-pixels 0.8 0.4 0.2] [--grids 64 128 256]`` (``--profile-sizes``: the photometric sizes whose
peak is also profiled stage by stage, default 4 MP).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import Table, write_results

RUNNER = (
    "import resource, subprocess, sys; "
    "code = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL); "
    "print(code, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)"
)
WORKBENCH = [sys.executable, "-m", "workbench"]
# what `photometric reconstruct` imports before any work: the baseline to subtract
BASELINE_IMPORTS = ("import numpy, cv2, scipy.fft, scipy.ndimage, photometric.pipeline, photometric.defects, "
                    "workbench.cli, workbench.runs.photometric, surfaces.io")

GEN_IMAGES = """
import sys, cv2, numpy as np
from photometric.lights import ring_lights
side, out = int(sys.argv[1]), sys.argv[2]
L = ring_lights(3, 45.0)
y = np.linspace(-1, 1, side, dtype=np.float32)[:, None]
x = np.linspace(-1, 1, side, dtype=np.float32)[None, :]
r2 = x * x + y * y
inside = r2 < 0.64
nz = np.where(inside, np.sqrt(np.clip(0.64 - r2, 0, None)) / 0.8, 1).astype(np.float32)
nx = np.where(inside, x / 0.8, 0).astype(np.float32)
ny = np.where(inside, -y / 0.8, 0).astype(np.float32)
del r2, inside, x, y
for k, l in enumerate(L):
    img = np.clip(0.6 * (nx * l[0] + ny * l[1] + nz * l[2]) + 0.05, 0, 1)
    cv2.imwrite(f"{out}/{k}.png", np.round(img * 65535).astype(np.uint16))
np.savetxt(f"{out}/L.txt", L)
"""

# peak RSS of each stage above the interpreter with the stages' modules imported: the kernel's high-water
# mark (VmHWM), reset at every stage change through /proc/self/clear_refs (no sampling gaps)
PROFILE = """
import sys
import cv2, scipy.fft, scipy.ndimage, scipy.sparse.linalg, skimage.measure, skimage.filters
import photometric.defects, photometric.integrate, photometric.normals, surfaces.fit
from workbench.runs.photometric import reconstruct_to_folder
def status(key):
    with open("/proc/self/status") as f:
        return int(next(line for line in f if line.startswith(key)).split()[1]) * 1024
stage, peaks = ["start"], {}
base = status("VmRSS")
def enter(name):
    peaks[stage[0]] = status("VmHWM") - base
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    stage[0] = name
enter("start")
d = sys.argv[1]
reconstruct_to_folder([f"{d}/{k}.png" for k in range(3)], f"{d}/profile", lights=f"{d}/L.txt", progress=enter)
enter("end")
print(" ".join(f"{k}={v}" for k, v in peaks.items() if k != "start"))
"""


def peak_rss(cmd: list[str]) -> tuple[int, int, float]:
    """Run ``cmd`` in a fresh runner process; return its exit code, peak RSS (bytes) and wall time (s)."""
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", RUNNER, *cmd], capture_output=True, text=True, check=True)
    code, rss = out.stdout.split()
    return int(code), int(rss), time.perf_counter() - t0


def available_bytes() -> int:
    """``MemAvailable`` of /proc/meminfo (0 when unknown)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def mib(n: float) -> str:
    return f"{n / 2**20:,.0f}"


def photometric_rows(sizes: list[int], tmp: Path, baseline: int,
                     profile: tuple[int, ...] = (4,)) -> tuple[list, list[str]]:
    rows, notes, ratio = [], [], None
    for mp in sizes:
        side = int(round((mp * 1e6) ** 0.5))
        raw = 3 * side * side * 2
        if ratio is not None and ratio * raw + baseline > available_bytes() / 2:
            notes.append(
                f"{mp} MP skipped: at {ratio:.1f}x the raw pixels it would need about "
                f"{mib(ratio * raw + baseline)} MiB, more than half of the {mib(available_bytes())} MiB "
                "available on this shared machine now.")
            continue
        folder = tmp / f"ps{mp}"
        folder.mkdir()
        subprocess.run([sys.executable, "-c", GEN_IMAGES, str(side), str(folder)], check=True)
        code, rss, wall = peak_rss([*WORKBENCH, "photometric", "reconstruct", "--images",
                                    *(str(folder / f"{k}.png") for k in range(3)), "--lights",
                                    str(folder / "L.txt"), "--out", str(folder / "out")])
        if code != 0:
            raise RuntimeError(f"photometric reconstruct failed at {mp} MP (exit {code})")
        ratio = (rss - baseline) / raw
        if mp in profile:
            out = subprocess.run([sys.executable, "-c", PROFILE, str(folder)], capture_output=True, text=True,
                                 check=True).stdout.split()
            stages = ", ".join(f"{k} {int(v) / raw:.1f}x" for k, v in (item.split("=") for item in out))
            notes.append(f"Where it goes at {mp} MP (peak RSS of each stage above the interpreter with the stages' "
                         f"modules imported; the kernel's high-water mark, reset at each stage): {stages}. A stage's "
                         "peak includes what earlier stages hold and the heap the C library keeps after a "
                         "larger earlier stage frees its arrays.")
        rows.append([f"{mp} MP ({side} x {side})", mib(raw), mib(rss), mib(rss - baseline), f"{ratio:.1f}",
                     f"{wall:.1f}"])
        for p in folder.rglob("*"):
            if p.is_file():
                p.unlink()
    return rows, notes


def slices_rows(pixel_sizes: list[float], tmp: Path, baseline: int) -> list:
    rows = []
    for px in pixel_sizes:
        folder = tmp / f"phantom{px}"
        subprocess.run([*WORKBENCH, "synth", "phantom", "--shape", "kidney", "--format", "dicom",
                        "--pixel-size", str(px), "--out", str(folder)], check=True, capture_output=True)
        ct = folder / "ct"
        raw = _dicom_pixel_bytes(ct)
        code, rss, wall = peak_rss([*WORKBENCH, "slices", "reconstruct", str(ct), "--hu-min", "0", "--no-render",
                                    "--out", str(folder / "out")])
        if code != 0:
            raise RuntimeError(f"slices reconstruct failed on the {px} mm phantom (exit {code})")
        rows.append([f"kidney phantom, {px} mm pixels", f"{raw / 2**20:.2f}", mib(rss), mib(rss - baseline),
                     f"{(rss - baseline) / raw:.1f}", f"{wall:.1f}"])
    return rows


def _dicom_pixel_bytes(folder: Path) -> int:
    import pydicom

    total = 0
    for p in sorted(folder.iterdir()):
        ds = pydicom.dcmread(p, stop_before_pixels=True)
        total += int(ds.Rows) * int(ds.Columns) * int(ds.BitsAllocated) // 8
    return total


def coons_rows(grids: list[int], tmp: Path, baseline: int) -> list:
    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from workbench.commands.surfaces import coons_needs

    rows = []
    for n in grids:
        u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
        grid = np.stack([u, v, 0.1 * np.sin(6 * u) * np.cos(5 * v)], -1)
        path = tmp / f"grid{n}.npy"
        np.save(path, grid)
        est = coons_needs(grid.shape, 8, False, False, ".ply")["memory_bytes"]
        code, rss, wall = peak_rss([*WORKBENCH, "surfaces", "coons", str(path), "--samples", "8",
                                    "--out", str(tmp / f"coons{n}.ply")])
        if code != 0:
            raise RuntimeError(f"surfaces coons failed on the {n}^2 grid (exit {code})")
        rows.append([f"{n} x {n} grid ({(n - 1) ** 2:,} patches)", f"{grid.nbytes / 2**20:.2f}", mib(rss),
                     mib(rss - baseline), mib(est), f"{wall:.1f}"])
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 4, 16, 64], help="photometric input sizes, MP")
    ap.add_argument("--profile-sizes", type=int, nargs="*", default=[4],
                    help="photometric sizes (MP, among --sizes) also profiled stage by stage")
    ap.add_argument("--phantom-pixels", type=float, nargs="+", default=[0.8, 0.4, 0.2],
                    help="CT phantom pixel sizes, mm")
    ap.add_argument("--grids", type=int, nargs="+", default=[64, 128, 256], help="coons grid sides")
    args = ap.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as t:
        tmp = Path(t)
        _, baseline, _ = peak_rss([sys.executable, "-c", BASELINE_IMPORTS])
        _, bare, _ = peak_rss([sys.executable, "-c", "pass"])
        photo, notes = photometric_rows(args.sizes, tmp, baseline, tuple(args.profile_sizes))
        slices = slices_rows(args.phantom_pixels, tmp, baseline)
        coons = coons_rows(args.grids, tmp, baseline)
    head = ["input", "raw input (MiB)", "peak RSS (MiB)", "peak - baseline (MiB)", "ratio to input", "wall (s)"]
    parts = [
        "Command: `.venv/bin/python benchmarks/bench_memory.py` (2 cores, shared with other jobs). Each "
        "command runs in its own process; its peak RSS is `getrusage(RUSAGE_CHILDREN).ru_maxrss` of a "
        f"runner. Baseline: the interpreter with the command's imports, {mib(baseline)} MiB "
        f"(bare Python {mib(bare)} MiB); the ratio is (peak - baseline) / raw input bytes.",
        "### `workbench photometric reconstruct` (far field, 3 16-bit images)",
        Table(head, photo, "lrrrrr"),
        *notes,
        "Goal of issue 20: at most 6x the raw pixels (6 bytes per pixel for 3 16-bit images). Before the defect "
        "measures and the rest of the surface stage were bounded: 21.3x, 10.2x, 8.1x and 7.7x at 1, 4, 16 and "
        "64 MP, and at 4 MP read 3.0x, normals 4.7x, height 3.5x, surface 6.7x, defects 9.4x, write 6.7x. The "
        "images are read plane by plane into one float32 stack (2x), the normals and albedo are solved in blocks "
        "of rows and written to their files block by block, the stack is dropped after the solve, and the height "
        "is integrated in float32 in place (p, q, height, valid and mask are 14 bytes per pixel, 2.3x, for the "
        "later stages). The surface fit (`surfaces.fit.fit_height(..., keep_pixels=False)`) holds its running "
        "fitted height and two derivatives in float32 (12 bytes per pixel, padded) and one-byte weight, region "
        "and coverage planes, and keeps no per-pixel surface or deviation map for the pipeline; the percentiles "
        "of its default tolerance come from a partition of a float32 copy (`surfaces.fit.percentiles`, bit for "
        "bit numpy's on a float64 copy), its noise estimate lets its weights go before it gathers the detail, "
        "and the mesh (`fit_mesh`) numbers its vertices in int32 and evaluates them in small blocks. The defect "
        "measures (`photometric.defects.measure_defects`) read a float32 height without a float64 copy, form "
        "the residual once per sign, segment by depth without skimage's float64 and int64 image copies, and keep "
        "each region as a boolean crop of its bounding box, measured in three passes over row blocks (exact "
        "integer moments of the pixel positions, float64 sums of the depths): nothing per region pixel is kept "
        "(before: its coordinates, depths and float64 copies, about 180 bytes per region pixel; the bench scene's "
        "one depression covers 16 % of the image). The previews gather float32 maps in float32. The command's "
        "peak is now the surface fit's running planes beside the 14 bytes per pixel the pipeline holds; at 1 and "
        "4 MP fixed costs dominate (modules, the mesh lattice, a vertex every 4 to 8 pixels whatever the size, "
        "and the heap the C library keeps from earlier stages).",
        "### `workbench slices reconstruct` (CT phantom series)",
        Table(head, slices, "lrrrrr"),
        "### `workbench surfaces coons` (8 samples per patch, PLY)",
        Table(["grid", "raw input (MiB)", "peak RSS (MiB)", "peak - baseline (MiB)", "estimate (MiB)",
               "wall (s)"], coons, "lrrrrr"),
    ]
    print(write_results("memory", "Memory against input size", parts))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
