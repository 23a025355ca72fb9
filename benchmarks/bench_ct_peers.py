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

Times are comparable stage by stage: the process is warmed up first (imports,
one small ROI through both pipelines), and both sides start from the contours in
memory. Our surface time is ``surface_time_s`` of the summary (chaining, bodies,
fold checks; reading is ``read_time_s`` and the union of the bodies
``union_time_s``, each in its own column); the peer's is rasterising and
marching cubes on the contours already loaded. Both are wall times
(``time.perf_counter``), the best of :data:`REPEATS` runs for ROIs whose surface
takes under :data:`REPEAT_BELOW_S` (one run otherwise), so a shared machine's
stalls count on neither side; the same two stages are also timed in CPU time
(:func:`cpu_times`). Command CPU: the command line itself (``workbench
slices reconstruct --caps half --no-render``) in a fresh process, its user +
system CPU time (BLAS held to one thread), start-up and imports included.

Issue 34 adds the independent checks of every written solid: pymeshlab's
``compute_selection_by_self_intersections_per_face`` (self-intersecting faces), its
topological measures after welding vertices closer than :data:`WELD_MM` (non-manifold
edges and vertices, boundary edges, connected components) and trimesh's
``is_watertight``/``is_winding_consistent``; the peer's connected parts (outer shells of
its marching-cubes mesh); which surface path the structure took (``coons``, the seed's
patches, or ``implicit``, :mod:`slices.implicit`); the volume against rasterise (pixel
centres inside, unbiased) + marching cubes at 0.5 mm, within +-1 % for ROIs of 8 cc or
more; and the worst ROI's surface time over the peer's, warm and in a fresh command. Rows:
every ROI of the breast set, the IBSI-1 phantom's GTV-1 (shared data) and, when the
environment variable ``RTUTILS_SAMPLE`` names it, the MIM export of rt-utils' early sample
data (``sample/rt.dcm`` of github.com/qurit/rt-utils before commit 63c77e4, 3-plane structures).

Run: ``.venv/bin/python benchmarks/bench_ct_peers.py [ROI ...]`` (writes
``benchmarks/results/ct_peers.md`` and prints it). With ROI names (row labels), the rows of
the other ROIs are kept from the page as it was (marked "earlier run"), so a
run on the small ROIs does not drop BODY's row, which takes minutes.
"""

from __future__ import annotations

import json
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
from slices.structure import reconstruct_contours  # noqa: E402
from surfaces.intersect import self_intersections  # noqa: E402
from surfaces.mesh import TriangleMesh  # noqa: E402
from surfaces.topology import shells  # noqa: E402

RTSS = ROOT.parent / "shared" / "data" / "rtstruct_breast" / "rtss.dcm"
IBSI = ROOT.parent / "shared" / "data" / "ibsi_ct_phantom" / "RS.dcm"

#: Vertices closer than this (mm) are welded before the manifold checks.
WELD_MM = 1e-3

#: Volumes are compared with the peer's for ROIs of at least this many cc.
COMPARED_CC = 8.0


def row_sources() -> list[tuple[str, Path, str]]:
    """``(label, structure set, ROI name)`` of every row: the breast set's ROIs, the IBSI GTV, rt-utils' MIM sample."""
    rows = [(r["name"], RTSS, r["name"]) for r in list_rois(RTSS) if r["n_contours"]]
    if IBSI.is_file():
        rows.append(("IBSI GTV-1", IBSI, "GTV-1"))
    mim = os.environ.get("RTUTILS_SAMPLE")
    if mim and Path(mim).is_file():
        rows += [(f"MIM {r['name']}", Path(mim), r["name"]) for r in list_rois(mim) if r["n_contours"]]
    return rows


def independent_checks(verts, faces) -> dict:
    """pymeshlab's self-intersecting faces and topology after welding (:data:`WELD_MM`) on the solid as the
    command writes it (``surface.ply``, :func:`surfaces.io.write_mesh`), trimesh's checks."""
    import pymeshlab
    import trimesh

    from surfaces.io import write_mesh

    ms = pymeshlab.MeshSet()
    with tempfile.TemporaryDirectory() as folder:
        write_mesh(TriangleMesh(verts, faces), Path(folder) / "surface.ply")
        ms.load_new_mesh(str(Path(folder) / "surface.ply"))
    ms.compute_selection_by_self_intersections_per_face()
    crossing = ms.current_mesh().selected_face_number()
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(WELD_MM))
    topo = ms.get_topological_measures()
    tm = trimesh.Trimesh(np.asarray(verts, np.float64), np.asarray(faces, np.int64), process=True)
    return {"self": int(crossing), "nm_edges": int(topo["non_two_manifold_edges"]),
            "nm_vertices": int(topo["non_two_manifold_vertices"]), "boundary": int(topo["boundary_edges"]),
            "components": int(topo["connected_components_number"]),
            "trimesh": bool(tm.is_watertight and tm.is_winding_consistent)}
#: Runs of both sides whose best time is reported, for ROIs faster than :data:`REPEAT_BELOW_S`.
REPEATS = 5
REPEAT_BELOW_S = 1.0

#: Planning-system volumes in cc (shared data README).
REFERENCES = {"Heart": (432.84, 440.23), "Lt Lung": (1995.18, 1995.18)}


def shell_counts(mesh) -> tuple[int, int]:
    """Outer shells and cavities of a closed mesh (shells of positive and of negative signed volume)."""
    label = shells(mesh.triangles, mesh.n_vertices)
    c = mesh.vertices[mesh.triangles]
    volume = np.bincount(label, np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])) / 6.0)
    return int(np.sum(volume > 0)), int(np.sum(volume < 0))


#: Columns of the result table.
HEADERS = ["ROI", "path", "bodies", "surface (s)", "read (s)", "union (s)", "command (s)", "command CPU (s)",
           "command surface (s)", "MC 0.5 mm (s)",
           "surface CPU (s)", "MC CPU (s)", "closed+oriented",
           "shells (outer + cavities)", "self-int. faces", "MC self-int. faces", "area (mm2)", "summary area_mm2",
           "bodies_area_mm2", "MC area (mm2)",
           "volume (cc)", "references (cc)", "inside +-1 %", "range none/flat/half/slab (cc)", "dV per 0.5 mm (cc)",
           "surfaces", "pymeshlab self-int.", "non-manifold e/v (welded)", "trimesh watertight+winding",
           "components (ours / MC outer)", "MC centres vol (cc)", "vs MC (%)", "fresh / MC", "warm / MC"]

#: Marks a row kept from the previous page.
EARLIER = " (earlier run)"

PAGE = ROOT / "benchmarks" / "results" / "ct_peers.md"


def command_cpu(name: str, rtss: Path = RTSS) -> tuple[float, float]:
    """User + system CPU seconds of ``workbench slices reconstruct --caps half --no-render`` in a fresh process,
    and the ``surface_time_s`` its ``summary.json`` reports (what a user of the command reads)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as folder:
        subprocess.run([sys.executable, "-m", "workbench.cli", "slices", "reconstruct", str(rtss), "--roi", name,
                        "--caps", "half", "--no-render", "--out", str(Path(folder) / "out")],
                       check=True, cwd=ROOT, capture_output=True)
        surface = json.loads((Path(folder) / "out" / "summary.json").read_text())["surface_time_s"]
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), float(surface)


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


def warm_up() -> None:
    """Both pipelines once on the smallest ROI: imports and first-call costs paid before any timed run."""
    name = min((r for r in list_rois(RTSS) if r["n_contours"]), key=lambda r: r["n_contours"])["name"]
    reconstruct(RTSS, roi=name, caps="half", reference=False)
    marching_cubes_mask(load(RTSS, roi=name).contours, 0.5, fast=True)


def best_runs(name: str, rtss: Path = RTSS):
    """Our reconstruction and the peer's mesh, each timed from the contours in memory (best of a few runs)."""
    t = time.perf_counter()
    result = reconstruct(rtss, roi=name, caps="half", reference=False)
    command = time.perf_counter() - t
    stages = {k: [result.summary[k]] for k in ("surface_time_s", "read_time_s", "union_time_s")}
    stack = load(rtss, roi=name)
    mc_times = []
    for _ in range(REPEATS):
        t = time.perf_counter()
        verts, faces, _ = marching_cubes_mask(stack.contours, 0.5, fast=True)
        mc_times.append(time.perf_counter() - t)
        if mc_times[0] >= REPEAT_BELOW_S:
            break
    if stages["surface_time_s"][0] < REPEAT_BELOW_S:
        for _ in range(REPEATS - 1):
            t = time.perf_counter()
            again = reconstruct(rtss, roi=name, caps="half", reference=False)
            command = min(command, time.perf_counter() - t)
            for k in stages:
                stages[k].append(again.summary[k])
    return result, command, {k: min(v) for k, v in stages.items()}, (verts, faces), min(mc_times)


def cpu_times(name: str, rtss: Path = RTSS) -> tuple[float, float]:
    """CPU seconds (``time.process_time``, one thread) of our surface stage and of the peer, best of a few runs.

    Ours is :func:`slices.structure.reconstruct_contours` on the contours in memory, what
    ``surface_time_s`` times; on a loaded machine CPU time is the steadier figure.
    """
    contours = load(rtss, roi=name).contours
    ours, peer = [], []
    for _ in range(REPEATS):
        t = time.process_time()
        reconstruct_contours(contours, caps="half")
        ours.append(time.process_time() - t)
        t = time.process_time()
        marching_cubes_mask(contours, 0.5, fast=True)
        peer.append(time.process_time() - t)
        if ours[0] >= REPEAT_BELOW_S:
            break
    return min(ours), min(peer)


def roi_row(label: str, rtss: Path = RTSS, name: str | None = None) -> list:
    name = label if name is None else name
    cpu, fresh_surface = command_cpu(name, rtss)
    result, command, stages, (verts, faces), mc_time = best_runs(name, rtss)
    surface_cpu, mc_cpu = cpu_times(name, rtss)
    s, mesh = result.summary, result.mesh
    hits = self_intersections(mesh.vertices, mesh.triangles).n_faces
    outer, cavities = shell_counts(mesh)
    mc_area = float(0.5 * np.linalg.norm(np.cross(verts[faces[:, 1]] - verts[faces[:, 0]],
                                                  verts[faces[:, 2]] - verts[faces[:, 0]]), axis=1).sum())
    mc_hits = self_intersections(verts, faces).n_faces
    vol = s["volume_mm3"] / 1000
    ref = REFERENCES.get(name)
    inside = "" if ref is None else ("yes" if ref[0] * 0.99 <= vol <= ref[1] * 1.01 else "no")
    surfaces_used = sorted({b["surface"] for b in s["bodies"]})
    ours = independent_checks(mesh.vertices, mesh.triangles)
    mc_outer, _ = shell_counts(TriangleMesh(verts, faces))
    c_verts, c_faces, _ = marching_cubes_mask(load(rtss, roi=name).contours, 0.5, fast=False)
    centre_cc = abs(TriangleMesh(c_verts, c_faces).signed_volume()) / 1000
    dv = 100 * (vol / centre_cc - 1)
    # the two compared stages to 0.1 ms: at 3 decimals the median ROI's two figures print alike
    row = [label, s["surface_path"], s["n_bodies"], f"{stages['surface_time_s']:.4f}",
           f"{stages['read_time_s']:.3f}", f"{stages['union_time_s']:.3f}", f"{command:.2f}", f"{cpu:.2f}",
           f"{fresh_surface:.3f}",
           f"{mc_time:.4f}", f"{surface_cpu:.4f}", f"{mc_cpu:.4f}",
           "yes" if mesh.is_watertight() and mesh.is_oriented() else "NO",
           f"{outer} + {cavities}", hits, mc_hits, f"{mesh.surface_area():.0f}", f"{s['area_mm2']:.0f}",
           f"{s['bodies_area_mm2']:.0f}", f"{mc_area:.0f}", f"{vol:.2f}",
           "-" if ref is None else f"{ref[0]:g}-{ref[1]:g}", inside,
           f"{s['volume_range_mm3'][0] / 1000:.2f}-{s['volume_range_mm3'][1] / 1000:.2f}",
           f"{s['volume_sensitivity_mm3_per_0.5mm'] / 1000:.2f}", ", ".join(surfaces_used),
           ours["self"], f"{ours['nm_edges']}/{ours['nm_vertices']}"
           + (f" ({ours['boundary']} open)" if ours["boundary"] else ""),
           "yes" if ours["trimesh"] else "NO", f"{ours['components']} / {mc_outer}", f"{centre_cc:.2f}",
           f"{dv:+.2f}" + ("" if centre_cc < COMPARED_CC else (" ok" if abs(dv) <= 1 else " OUT")),
           f"{fresh_surface / mc_time:.2f}", f"{stages['surface_time_s'] / mc_time:.2f}"]
    print("  " + " | ".join(map(str, row)), file=sys.stderr, flush=True)
    return row


def page(rows: list) -> list:
    """The result page's parts for the rows measured so far (and those kept from an earlier run)."""
    rows = sorted(rows, key=lambda r: str(r[0]).removesuffix(EARLIER))
    col = {h: i for i, h in enumerate(HEADERS)}
    worst = []
    for key in ("fresh / MC", "warm / MC"):
        vals = [(float(r[col[key]]), str(r[0])) for r in rows if r[col[key]] not in ("-", "")]
        worst.append(f"{key} worst {max(vals)[0]:.2f} ({max(vals)[1]})" if vals else f"{key}: no figure")
    named = [str(r[0]).removesuffix(EARLIER) for r in rows]
    nm, vs = col["non-manifold e/v (welded)"], col["vs MC (%)"]
    spotlight = "; ".join(
        f"{r[0]}: fresh {r[col['fresh / MC']]}x, warm {r[col['warm / MC']]}x, "
        f"pymeshlab {r[col['pymeshlab self-int.']]} self-intersecting, non-manifold {r[nm]}, vs MC {r[vs]} %"
        for r in rows if str(r[0]).removesuffix(EARLIER) in ("Lt Lung", "BODY", "IBSI GTV-1"))
    times = [float(r[col["surface (s)"]]) for r in rows]
    mc = [float(r[col["MC 0.5 mm (s)"]]) for r in rows]
    cmd = [float(r[col["command (s)"]]) for r in rows]
    cpu = [float(r[col["command CPU (s)"]]) for r in rows if r[col["command CPU (s)"]] != "-"]
    fresh = [float(r[col["command surface (s)"]]) for r in rows if r[col["command surface (s)"]] != "-"]
    both = [(float(r[col["surface CPU (s)"]]), float(r[col["MC CPU (s)"]])) for r in rows
            if r[col["surface CPU (s)"]] != "-"]
    both_text = (f" In CPU time (one thread): median surface {np.median([b[0] for b in both]):.4f} s against "
                 f"{np.median([b[1] for b in both]):.4f} s for the peer over the {len(both)} ROIs with both figures."
                 if both else "")
    kept = [str(r[0]).removesuffix(EARLIER) for r in rows if str(r[0]).endswith(EARLIER)]
    cpu_text = (f"; median command CPU time (fresh process) {np.median(cpu):.2f} s over the {len(cpu)} ROIs "
                "with a figure" if cpu else "")
    cpu_text += (f"; median surface_time_s of the command's summary.json (fresh process) {np.median(fresh):.3f} s "
                 f"over the {len(fresh)} ROIs with a figure" if fresh else "")
    return [
        "Generated by `benchmarks/bench_ct_peers.py` (ours and the peer in the same run, caps half, "
        "no picture, no reference).",
        "Issue 34 columns: path is the structure's surface path (coons: the seed's patches for one chain of "
        "contours; implicit: `slices.implicit`, blended signed distances and marching cubes); pymeshlab "
        "self-int. is `compute_selection_by_self_intersections_per_face` on the written solid; non-manifold e/v "
        f"are pymeshlab's non-two-manifold edges and vertices after welding vertices closer than {WELD_MM:g} mm; "
        "trimesh watertight+winding its `is_watertight` and `is_winding_consistent`; components are pymeshlab's "
        "connected components of ours beside the outer shells of the peer's marching cubes (cavities count in "
        "ours); MC centres vol is rasterise (pixel centres inside, skimage) + marching cubes at 0.5 mm, and vs MC "
        f"our volume against it (ok / OUT: within +-1 % or not, for ROIs of {COMPARED_CC:g} cc or more); fresh / MC "
        "is the fresh command's `surface_time_s` over MC 0.5 mm, warm / MC the warm surface time over it.",
        "Self-intersecting faces: `surfaces.intersect.self_intersections` on the written solid. "
        "Surfaces: which side surface each body kept (`slices.body.FALLBACKS`: a folded body is "
        "rebuilt with the arc-length monotone blend, then ruled, then both with the arc length's origin "
        "aligned slice to slice, and the first clean or the cleanest kept). Shells: connected "
        "components of the written solid, outer ones (positive volume) and cavities (holes inside). Area: "
        "the written solid's triangles; summary area_mm2 is what `summary.json` reports (the patches' for one "
        "body, the written solid's when bodies are united: shared caps and walls no longer count, cavity "
        "walls do), bodies_area_mm2 the sum over the bodies' patches.",
        "Times: the process is warmed up first (imports and one small ROI through both pipelines). Surface is "
        "`surface_time_s` of `slices.pipeline.reconstruct`: from the contours in memory to the bodies' meshes "
        "(chaining, bodies, fold checks); read (`read_time_s`, the RTSTRUCT into contours) and union "
        "(`union_time_s`, the bodies united into one solid) are apart. MC 0.5 mm is rasterising and marching "
        "cubes on the same contours in memory. Both are wall times, the best of "
        f"{REPEATS} runs where the surface takes under {REPEAT_BELOW_S:g} s (one run otherwise); surface CPU "
        "and MC CPU are the same two stages in CPU time (`time.process_time`, one thread, the same best of "
        "runs), steadier on a shared machine; command is "
        "`reconstruct` as a whole (reading included), its best run; command CPU is the command line in a fresh "
        "process (user + system CPU, start-up and imports included, BLAS on one thread), and command surface the "
        "`surface_time_s` that run's `summary.json` reports (its first surface in the process: the libraries "
        "are loaded before the clocks start, first-use costs such as fresh memory are in).",
        Table(HEADERS, rows),
        f"Median surface time {np.median(times):.4f} s against {np.median(mc):.4f} s for rasterise + "
        f"marching cubes at 0.5 mm; median command time {np.median(cmd):.2f} s{cpu_text}."
        + both_text + (f" Rows kept from an earlier run: {', '.join(kept)}." if kept else ""),
        f"Worst ROI over {len(named)} rows: {'; '.join(worst)}. {spotlight}.",
    ]


def main(names=None) -> str:
    if not RTSS.is_file():
        return "shared data missing"
    kept = earlier_rows(set(names)) if names else []
    sources = [r for r in row_sources() if not names or r[0] in names]
    warm_up()
    rows = []
    text = ""
    for label, rtss, name in sources:
        rows.append(roi_row(label, rtss, name))
        # written after every ROI, so a long run leaves the figures measured so far
        text = write_results("ct_peers", "slices against rasterise + marching cubes on a real structure set",
                             page(rows + kept))
    return text


if __name__ == "__main__":
    print(main(sys.argv[1:]))
