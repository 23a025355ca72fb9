"""``OUT/report.html`` of an inspection run: yield, depths against the limit, the worst parts.

Built from the files of the run alone (``results.csv`` and each finished part's
``result.json`` and ``overlay.png``), so a resumed or watched run rebuilds it the same way.
One self-contained page (:class:`workbench.report.Report`: figures embedded, also kept in
``OUT/figures/``).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from workbench.batch import RESULTS_NAME, read_results
from workbench.inspect.overlay import REPORT_WIDTH
from workbench.report import Report

__all__ = ["WORST_PARTS", "collect_results", "depth_histogram", "write_inspection_report"]

#: parts shown with their overlays
WORST_PARTS = 6
_SEVERITY = {"fail": 0, "uncertain": 1, "pass": 2}


def collect_results(out) -> tuple[dict, list]:
    """The results.csv rows of an inspection output folder and the ``result.json`` of each finished part.

    Parameters
    ----------
    out : str or Path
        The run's output folder.

    Returns
    -------
    rows : dict
        Part id -> results.csv row (:func:`workbench.batch.read_results`).
    results : list of dict
        The ``result.json`` of every part whose row says ``ok``, in row order.
    """
    out = Path(out)
    rows = read_results(out / RESULTS_NAME)
    results = []
    for pid, row in rows.items():
        path = out / pid / "result.json"
        if row["status"] == "ok" and path.is_file():
            results.append(json.loads(path.read_text()))
    return rows, results


def depth_histogram(depths, limit: float | None, size=(560, 320)) -> np.ndarray:
    """Histogram of imperfection depths with the limit marked (matplotlib, Agg).

    Parameters
    ----------
    depths : array_like
        Maximum depths, mm.
    limit : float or None
        ``max_depth_mm`` of the spec (drawn as a red line).
    size : (width, height)
        Picture size, pixels.

    Returns
    -------
    numpy.ndarray, shape (height, width, 3), uint8
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    d = np.asarray(depths, float)
    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    top = max([float(d.max()) if d.size else 0.0] + ([1.3 * limit] if limit else [])) or 1.0
    ax.hist(d, bins=np.linspace(0.0, top, 31), color="#4a78b0", edgecolor="white")
    if limit is not None:
        ax.axvline(limit, color="#d02020", linewidth=2, label=f"limit {limit:g} mm")
        ax.legend(loc="upper right")
    ax.set_xlabel("maximum depth of each imperfection (mm)")
    ax.set_ylabel("imperfections")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _thumbnail(path: Path, width: int = REPORT_WIDTH) -> np.ndarray:
    """An overlay at most ``width`` wide: shown at its own size in the report's column, so its labels keep
    :data:`workbench.inspect.overlay.TEXT_PX` pixels (an older, larger overlay is shrunk to fit)."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)[..., ::-1]
    scale = min(1.0, width / img.shape[1])
    if scale < 1.0:
        img = cv2.resize(img, (width, max(1, round(img.shape[0] * scale))), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(img)


def write_inspection_report(out, command: str, title: str = "Inspection run") -> Path:
    """Write ``OUT/report.html`` from the run's files.

    Parameters
    ----------
    out : str or Path
        The run's output folder.
    command : str
        The command line of the run (shown under every figure).
    title : str, optional

    Returns
    -------
    Path
        ``OUT/report.html``.
    """
    out = Path(out)
    rows, results = collect_results(out)
    report = Report(title, out)
    counts = {v: sum(r["verdict"] == v for r in results) for v in ("pass", "fail", "uncertain")}
    failed = [row for row in rows.values() if row["status"] == "failed"]
    n = len(results)
    report.section("Yield", "Verdicts of the finished parts; parts that could not be measured are listed apart.")
    report.table(["parts measured", "pass", "fail", "uncertain", "yield (%)", "could not be measured"],
                 [[n, counts["pass"], counts["fail"], counts["uncertain"],
                   100.0 * counts["pass"] / n if n else "no part measured", len(failed)]])
    if results:
        spec = results[-1]["spec"]
        rule = results[-1]["decision_rule"]
        report.paragraph(f"Decision rule: {rule}. Limits: "
                         + ", ".join(f"{k} = {v}" for k, v in spec.items() if k.startswith(("max_", "min_")))
                         + ".")
        depths = [im["values"]["max_depth_mm"]["value"] for r in results for im in r["imperfections"]
                  if im["region"] == "inspected"]
        report.section("Depths against the limit")
        report.figure(depth_histogram(depths, spec.get("max_depth_mm")), "depth_histogram",
                      f"Maximum depth of every inspected imperfection over {n} parts ({len(depths)} imperfections)"
                      + (f"; red: the limit {spec['max_depth_mm']:g} mm" if "max_depth_mm" in spec else ""),
                      command)
        worst = sorted(results, key=lambda r: (_SEVERITY[r["verdict"]], -float(r.get("max_depth_mm") or 0.0)))
        report.section("Worst parts", "Failed parts first, then uncertain ones, deepest imperfection first. "
                       "Each overlay: the shaded height (relief exaggerated by the stated factor) and the albedo, "
                       "each imperfection's measured outline coloured by verdict (red fail, amber uncertain, "
                       "green pass, grey not decided), zooms on the worst ones, and one line per check: the "
                       "value, its U (k = 2) and the limit it is compared with.")
        table = []
        for r in worst[:WORST_PARTS]:
            depth = r.get("max_depth_mm") or 0.0
            u = r.get("max_depth_U_mm")
            table.append([r["part"], r["verdict"], r["n_imperfections"], float(depth),
                          "not stated" if u is None else float(u), ", ".join(r["decided_by"]) or "every check passed"])
        report.table(["part", "verdict", "imperfections", "max depth (mm)", "U (mm, k = 2)", "decided by"], table)
        for r in worst[:WORST_PARTS]:
            overlay = out / r["part"] / "overlay.png"
            if overlay.is_file():
                report.figure(_thumbnail(overlay), f"overlay_{r['part']}".replace(".", "_").replace("+", "_"),
                              f"{r['part']}: {r['verdict']}", command)
    if failed:
        report.section("Parts that could not be measured")
        report.table(["part", "error"], [[row["id"], row["error"] or "see failed/"] for row in failed])
    report.section("All parts")
    report.table(["part", "status", "verdict", "imperfections", "max depth (mm)", "time (s)"],
                 [[pid, row["status"], row["verdict"] or "-", row["n_imperfections"] or "-",
                   row["max_depth_mm"] or "-", row["time_s"] or "-"] for pid, row in rows.items()])
    return report.write(meta=f"{n} parts measured; results in {RESULTS_NAME}")
