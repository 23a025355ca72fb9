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
from workbench.batch.results import TEXTURE_COLUMNS, column_text, round_to_u
from workbench.inspect.overlay import REPORT_WIDTH
from workbench.report import Report

__all__ = ["WORST_PARTS", "DRIFT_FACTOR", "OFF_FRACTION", "collect_results", "depth_histogram", "lot_quality_flags",
           "write_inspection_report"]

#: parts shown with their overlays
WORST_PARTS = 6
_SEVERITY = {"fail": 0, "uncertain": 1, "pass": 2}
#: a lot's quality figure drifts when the median of its later half exceeds this many times its earlier half's
#: (and half the limit's worth of room is used)
DRIFT_FACTOR = 2.0
#: a quality figure is "off" in a part above this fraction of its limit (still trusted, but no longer clean)
OFF_FRACTION = 0.5
# the quality figures a lot is watched on (result.json quality.figures -> limit key)
_WATCHED = {"background_rms_mm": "background_rms_mm", "invalid_fraction": "invalid_fraction"}


def _figure(result: dict, name: str):
    fig = ((result.get("quality") or {}).get("figures") or {}).get(name)
    return None if fig is None else float(fig)


def lot_quality_flags(results: list, failed_rows: list | None = None) -> list[str]:
    """Warnings about a whole lot's measurement quality (issue 32): drift, and a clean yield that cannot be trusted.

    Parameters
    ----------
    results : list of dict
        The finished parts' ``result.json`` in run order (:func:`collect_results`).
    failed_rows : list of dict, optional
        The results.csv rows of the parts that could not be measured (their ``error``).

    Returns
    -------
    list of str
        One sentence per flag (empty: nothing to report):

        * a part refused for its quality limits (``not_measured``): how many;
        * **drift**: a watched figure (background flatness, invalid fraction) whose median
          over the later half of the lot is more than :data:`DRIFT_FACTOR` times the
          earlier half's and above :data:`OFF_FRACTION` of its limit;
        * **100 % yield without a single imperfection while the quality is off**: every
          part passed, none has an imperfection, and the lot's median of a watched
          figure is above :data:`OFF_FRACTION` of its limit, or some parts were refused
          for quality: a measurement that hides defects looks exactly like this.

    Examples
    --------
    >>> r = lambda b: {"verdict": "pass", "n_imperfections": 0, "quality": {"figures": {"background_rms_mm": b},
    ...                "limits": {"background_rms_mm": 0.005}}}
    >>> lot_quality_flags([r(0.0003), r(0.0003)])
    []
    >>> [f.split(":")[0] for f in lot_quality_flags([r(0.0003), r(0.0004), r(0.003), r(0.004)])]
    ['quality drift']
    >>> [f[:29] for f in lot_quality_flags([r(0.003), r(0.003)])]
    ['100 % yield with no imperfect']
    """
    flags = []
    refused = [row for row in failed_rows or [] if "quality limits" in (row.get("error") or "")]
    if refused:
        flags.append(f"{len(refused)} part(s) could not be measured because their measurement failed its quality "
                     "limits (see 'Parts that could not be measured'): check the parts' surface finish and the rig")
    off = []
    for name, key in _WATCHED.items():
        values = [(_figure(r, name), (r.get("quality") or {}).get("limits", {}).get(key)) for r in results]
        values = [(v, lim) for v, lim in values if v is not None and lim is not None]
        if not values:
            continue
        v = np.array([x for x, _ in values])
        limit = float(np.median([lim for _, lim in values]))
        if np.median(v) > OFF_FRACTION * limit:
            off.append(f"{name} median {np.median(v):.3g} against a limit of {limit:.3g}")
        half = len(v) // 2
        if half >= 2:
            early, late = float(np.median(v[:half])), float(np.median(v[half:]))
            if late > DRIFT_FACTOR * early and late > OFF_FRACTION * limit:
                flags.append(f"quality drift: {name} rose from a median of {early:.3g} over the first {half} parts "
                             f"to {late:.3g} over the last {len(v) - half} (limit {limit:.3g}): the measurement is "
                             "degrading (rig, lighting, surface finish)")
    clean = results and all(r["verdict"] == "pass" and not r.get("n_imperfections") for r in results)
    if clean and (off or refused):
        why = "; ".join(off) if off else f"{len(refused)} part(s) refused for quality"
        flags.append(f"100 % yield with no imperfection at all while the quality figures are off ({why}): do not "
                     "trust this lot's verdicts before checking the measurement on a part with a known defect")
    return flags


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


def _texture_section(report: Report, results: list) -> None:
    """The areal texture of the parts that have one: the judged value +- U of each limited (or headline)
    parameter, and the texture checks' verdict."""
    from workbench.runs.texture import format_parameter

    first = results[-1]["texture"]
    limited = list(dict.fromkeys(c["quantity"] for r in results for c in r["texture"]["checks"]))
    names = limited or list(TEXTURE_COLUMNS)
    band = first["band"]
    filters = first["filters"]
    report.section(
        "Areal texture (ISO 25178-2)",
        f"Form removed: {first['form']}; S-filter "
        + ("none" if filters.get("s_filter_mm") is None else f"{filters['s_filter_mm']:g} mm")
        + ", L-filter " + ("none" if filters.get("l_filter_mm") is None else f"{filters['l_filter_mm']:g} mm")
        + f"; band measured {band['short_mm'] * 1000:.3g} um to {band['long_mm']:.3g} mm. Each value is the "
        "noise-bias corrected value with its U (k = 2) when the part was measured with an uncertainty, else the "
        "value as measured (no U); limits: "
        + (", ".join(f"{c['limit_key']} = {c['limit']:g}" for c in first["checks"]) or "none") + ".")
    rows = []
    for r in results:
        tex = r["texture"]
        verdicts = [c["verdict"] for c in tex["checks"]]
        worst = max(verdicts, key=list(_SEVERITY)[::-1].index) if verdicts else "not limited"
        rows.append([r["part"], *(format_parameter(tex["parameters"][n]) for n in names), worst])
    report.table(["part", *names, "texture verdict"], rows)


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
    flags = lot_quality_flags(results, failed)
    report.section("Measurement quality",
                   "Whether the lot's measurements can be trusted (photometric.quality: background flatness about "
                   "the background model, slope bias against the rig's reference part, invalid fraction). A part "
                   "whose measurement fails a limit is not measured (never passed). "
                   + ("FLAGS: " + " ".join(f"({k + 1}) {f}" for k, f in enumerate(flags)) if flags
                      else "No flag: no drift, and the yield is not a clean sweep on off-quality measurements."))
    if results:
        bg = [v for v in (_figure(r, "background_rms_mm") for r in results) if v is not None]
        lim = (results[-1].get("quality") or {}).get("limits", {})
        if bg:
            report.table(["figure", "median", "max", "limit", "limits from"],
                         [["background flatness (um RMS)", 1e3 * float(np.median(bg)), 1e3 * float(np.max(bg)),
                           1e3 * lim["background_rms_mm"] if "background_rms_mm" in lim else "-",
                           (results[-1].get("quality") or {}).get("limits_source", "-")]])
    if results:
        spec = results[-1]["spec"]
        rule = results[-1]["decision_rule"]
        report.paragraph(f"Decision rule: {rule}. Limits: "
                         + ", ".join(f"{k} = {v:g}" for k, v in spec.items() if k.startswith(("max_", "min_")))
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
            # each figure to the precision its U supports (two significant digits of U); the JSON keeps them full
            depth, u = round_to_u(float(r.get("max_depth_mm") or 0.0), r.get("max_depth_U_mm"))
            if u is None:
                depth = f"{float(r.get('max_depth_mm') or 0.0):.4f}"
            table.append([r["part"], r["verdict"], r["n_imperfections"], depth,
                          "not stated" if u is None else u, ", ".join(r["decided_by"]) or "every check passed"])
        report.table(["part", "verdict", "imperfections", "max depth (mm)", "U (mm, k = 2)", "decided by"], table)
        for r in worst[:WORST_PARTS]:
            overlay = out / r["part"] / "overlay.png"
            if overlay.is_file():
                report.figure(_thumbnail(overlay), f"overlay_{r['part']}".replace(".", "_").replace("+", "_"),
                              f"{r['part']}: {r['verdict']}", command)
    textured = [r for r in results if r.get("texture")]
    if textured:
        _texture_section(report, textured)
    if failed:
        report.section("Parts that could not be measured")
        report.table(["part", "error"], [[row["id"], row["error"] or "see failed/"] for row in failed])
    report.section("All parts", "Each figure to the precision its U (k = 2) supports: U to two significant digits, "
                   "the value to the same decimal; without a U, a fixed number of decimals per column. "
                   f"{RESULTS_NAME} holds the same text, each part's result.json the full numbers.")
    texture_cols = [n for n in TEXTURE_COLUMNS if any(row.get(f"{n}_um") for row in rows.values())]
    report.table(["part", "status", "verdict", "imperfections", "max depth (mm)",
                  *(f"{n} (um)" for n in texture_cols), "time (s)"],
                 [[pid, row["status"], row["verdict"] or "-", row["n_imperfections"] or "-",
                   column_text(row, "max_depth_mm"), *(column_text(row, f"{n}_um") for n in texture_cols),
                   row["time_s"] or "-"] for pid, row in rows.items()])
    return report.write(meta=f"{n} parts measured; results in {RESULTS_NAME}")
