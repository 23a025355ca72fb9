"""Benchmark of ``slices`` as a solid modeller on a real structure set, against rasterise + marching cubes.

Per ROI of the breast RT structure set (shared data), with ``--caps half`` and no
picture or B-spline reference (what ``workbench slices reconstruct --no-render``
computes): our surface time and command time, the written solid's checks
(watertight, oriented, connected shells, self-intersecting faces by
:func:`surfaces.intersect.self_intersections`), its area and volume, the
volumes under each end-slice convention, and the peer in the same run: the
contours rasterised at 0.5 mm (OpenCV scan-line fill) and marching cubes
(scikit-image), its time, area and self-intersecting faces. Planning-system
references (shared data README) where they exist.

Command CPU: the command line itself (``workbench slices reconstruct --caps half
--no-render``) in a fresh process, its user + system CPU time (the machine is
shared, so CPU time rather than wall time; BLAS held to one thread), start-up
and imports included. The other times are wall times inside this process.

Run: ``.venv/bin/python benchmarks/bench_ct_peers.py [ROI ...]`` (writes
``benchmarks/results/ct_peers.md`` and prints it). With ROI names, the rows of
the other ROIs are kept from the page as it was (marked "earlier run"), so a
run on the small ROIs does not drop BODY's row, which takes minutes.
"""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_slices import marching_cubes_mask  # noqa: E402
from common import Table, write_results  # noqa: E402

from slices.io import list_rois, load  # noqa: E402
from slices.pipeline import reconstruct  # noqa: E402
from surfaces.intersect import self_intersections  # noqa: E402
from surfaces.topology import shells  # noqa: E402

RTSS = ROOT.parent / "shared" / "data" / "rtstruct_breast" / "rtss.dcm"
#: Planning-system volumes in cc (shared data README).
REFERENCES = {"Heart": (432.84, 440.23), "Lt Lung": (1995.18, 1995.18)}


def shell_counts(mesh) -> tuple[int, int]:
    """Outer shells and cavities of a closed mesh (shells of positive and of negative signed volume)."""
    label = shells(mesh.triangles, mesh.n_vertices)
    c = mesh.vertices[mesh.triangles]
    volume = np.bincount(label, np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])) / 6.0)
    return int(np.sum(volume > 0)), int(np.sum(volume < 0))


#: Columns of the result table.
HEADERS = ["ROI", "bodies", "surface (s)", "command (s)", "command CPU (s)", "MC 0.5 mm (s)", "closed+oriented",
           "shells (outer + cavities)", "self-int. faces", "MC self-int. faces", "area (mm2)", "MC area (mm2)",
           "volume (cc)", "references (cc)", "inside +-1 %", "range none/flat/half/slab (cc)", "dV per 0.5 mm (cc)",
           "surfaces"]

#: Marks a row kept from the previous page.
EARLIER = " (earlier run)"

PAGE = ROOT / "benchmarks" / "results" / "ct_peers.md"


def command_cpu(name: str) -> float:
    """User + system CPU seconds of ``workbench slices reconstruct --caps half --no-render`` in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([sys.executable, "-m", "workbench.cli", "slices", "reconstruct", str(RTSS), "--roi", name,
                        "--caps", "half", "--no-render", "--out", str(Path(folder) / "out")],
                       check=True, cwd=ROOT, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def earlier_rows(measured: set) -> list:
    """Rows of the existing page for the ROIs not in ``measured`` (columns it lacks shown as ``-``)."""
    if not PAGE.is_file():
        return []
    lines = [line for line in PAGE.read_text().splitlines() if line.startswith("|")]
    if len(lines) < 3:
        return []

    def cells(line: str) -> list:
        return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip()[1:-1])]

    head = cells(lines[0])
    rows = []
    for line in lines[2:]:
        old = dict(zip(head, cells(line)))
        name = old.get("ROI", "").removesuffix(EARLIER)
        if name and name not in measured:
            rows.append([name + EARLIER] + [old.get(h, "-") for h in HEADERS[1:]])
    return rows


def roi_row(name: str) -> list:
    cpu = command_cpu(name)
    t = time.perf_counter()
    result = reconstruct(RTSS, roi=name, caps="half", reference=False)
    command = time.perf_counter() - t
    s, mesh = result.summary, result.mesh
    hits = self_intersections(mesh.vertices, mesh.triangles).n_faces
    outer, cavities = shell_counts(mesh)
    stack = load(RTSS, roi=name)
    t = time.perf_counter()
    verts, faces, _ = marching_cubes_mask(stack.contours, 0.5, fast=True)
    mc_time = time.perf_counter() - t
    mc_area = float(0.5 * np.linalg.norm(np.cross(verts[faces[:, 1]] - verts[faces[:, 0]],
                                                  verts[faces[:, 2]] - verts[faces[:, 0]]), axis=1).sum())
    mc_hits = self_intersections(verts, faces).n_faces
    vol = s["volume_mm3"] / 1000
    ref = REFERENCES.get(name)
    inside = "" if ref is None else ("yes" if ref[0] * 0.99 <= vol <= ref[1] * 1.01 else "no")
    surfaces_used = sorted({b.surface for b in result.reconstruction.bodies})
    row = [name, len(result.reconstruction.bodies), f"{s['surface_time_s']:.2f}", f"{command:.2f}", f"{cpu:.2f}",
            f"{mc_time:.3f}", "yes" if mesh.is_watertight() and mesh.is_oriented() else "NO",
            f"{outer} + {cavities}", hits,
            mc_hits, f"{mesh.surface_area():.0f}", f"{mc_area:.0f}", f"{vol:.2f}",
            "-" if ref is None else f"{ref[0]:g}-{ref[1]:g}", inside,
            f"{s['volume_range_mm3'][0] / 1000:.2f}-{s['volume_range_mm3'][1] / 1000:.2f}",
            f"{s['volume_sensitivity_mm3_per_0.5mm'] / 1000:.2f}", ", ".join(surfaces_used)]
    print("  " + " | ".join(map(str, row)), file=sys.stderr, flush=True)
    return row


def page(rows: list) -> list:
    """The result page's parts for the rows measured so far (and those kept from an earlier run)."""
    rows = sorted(rows, key=lambda r: str(r[0]).removesuffix(EARLIER))
    times = [float(r[2]) for r in rows]
    mc = [float(r[5]) for r in rows]
    cmd = [float(r[3]) for r in rows]
    cpu = [float(r[4]) for r in rows if r[4] != "-"]
    kept = [str(r[0]).removesuffix(EARLIER) for r in rows if str(r[0]).endswith(EARLIER)]
    cpu_text = (f"; median command CPU time (fresh process) {np.median(cpu):.2f} s over the {len(cpu)} ROIs "
                "measured in this run" if cpu else "")
    return [
        "Generated by `benchmarks/bench_ct_peers.py` (ours and the peer in the same run, caps half, "
        "no picture, no reference).",
        "Self-intersecting faces: `surfaces.intersect.self_intersections` on the written solid. "
        "Surfaces: which side surface each body kept (`slices.body.FALLBACKS`: a folded body is "
        "rebuilt with the arc-length monotone blend, then ruled, then both with the arc length's origin "
        "aligned slice to slice, and the first clean or the cleanest kept). Shells: connected "
        "components of the written solid, outer ones (positive volume) and cavities (holes inside).",
        "Times: surface and command are wall times of `slices.pipeline.reconstruct` in the benchmark's process "
        "(imports paid by the first ROI only); command CPU is the command line in a fresh process (user + "
        "system CPU, start-up and imports included, BLAS on one thread).",
        Table(HEADERS, rows),
        f"Median surface time {np.median(times):.2f} s against {np.median(mc):.3f} s for rasterise + "
        f"marching cubes at 0.5 mm; median command time {np.median(cmd):.2f} s{cpu_text}."
        + (f" Rows kept from an earlier run: {', '.join(kept)}." if kept else ""),
    ]


def main(names=None) -> str:
    if not RTSS.is_file():
        return "shared data missing"
    kept = earlier_rows(set(names)) if names else []
    names = names or [r["name"] for r in list_rois(RTSS) if r["n_contours"]]
    rows = []
    text = ""
    for name in names:
        rows.append(roi_row(name))
        # written after every ROI, so a long run leaves the figures measured so far
        text = write_results("ct_peers", "slices against rasterise + marching cubes on a real structure set",
                             page(rows + kept))
    return text


if __name__ == "__main__":
    print(main(sys.argv[1:]))
