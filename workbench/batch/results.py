"""Bookkeeping of a batch in ``OUT``: results.csv rows, failure records, complete markers, run figures.

``OUT/results.csv`` holds one row per job (columns :data:`RESULT_COLUMNS`);
``OUT/failed/<id>.json`` keeps the last error of a failed job with its
traceback; ``OUT/<id>/_COMPLETE`` marks a finished job folder and carries its
row; ``OUT/batch_<kind>.json`` holds the figures of the last run. Every file
here is written atomically (:mod:`surfaces.io`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from surfaces.io import atomic_write_text, write_json
from workbench.batch.jobs import Job, check_kind
from workbench.runs.folder import COMPLETE_MARKER, is_complete  # noqa: F401 - one marker for every result folder

#: key figures copied from a job's summary into its results.csv row, per kind
FIGURES: dict[str, tuple[str, ...]] = {
    "photometric": ("n_defects", "max_depth_mm", "invalid_fraction", "light_condition_number"),
    "slices": ("volume_mm3", "volume_ml", "area_mm2", "n_bodies", "n_patches"),
    # parts of ``workbench inspect run`` (workbench.inspect): photometric jobs with a verdict
    "inspect": ("verdict", "n_imperfections", "n_fail", "n_uncertain", "max_depth_mm", "max_depth_U_mm",
                "total_area_mm2", "invalid_fraction", "spec_sha256", "background_rms_mm", "slope_bias_mrad"),
}
#: texture parameters of an inspected part (ISO 25178-2, micrometres) given as columns, each with its U (k = 2)
TEXTURE_COLUMNS: tuple[str, ...] = ("Sa", "Sq", "Sz")
FIGURES["inspect"] = (*FIGURES["inspect"][:-1], "texture_verdict",
                      *(f"{name}{suffix}" for name in TEXTURE_COLUMNS for suffix in ("_um", "_U_um")),
                      FIGURES["inspect"][-1])
#: column -> the column holding its expanded uncertainty (k = 2): both are written to two significant digits of U
U_COLUMNS: dict[str, str] = {"max_depth_mm": "max_depth_U_mm",
                             **{f"{name}_um": f"{name}_U_um" for name in TEXTURE_COLUMNS}}
#: fixed decimals of the float columns without a U (their resolution); any other float keeps 4 significant digits
DECIMALS: dict[str, int] = {"max_depth_mm": 4, "invalid_fraction": 4, "light_condition_number": 3,
                            "volume_mm3": 2, "volume_ml": 4, "area_mm2": 2, "total_area_mm2": 4,
                            **{f"{name}{suffix}": 3 for name in TEXTURE_COLUMNS for suffix in ("_um", "_U_um")}}
#: figures whose value is text (every other figure is a number)
TEXT_FIGURES: tuple[str, ...] = ("verdict", "spec_sha256", "texture_verdict")
#: the verdict of an inspected part that could not be measured (its row's status is ``failed``)
NOT_MEASURED = "not_measured"
RESULT_COLUMNS: tuple[str, ...] = tuple(dict.fromkeys((
    "id",
    "kind",
    "status",
    "error",
    "time_s",
    *FIGURES["photometric"],
    *FIGURES["slices"],
    *FIGURES["inspect"],
    "input",
)))
RESULTS_NAME = "results.csv"
FAILED_DIR = "failed"
TMP_PREFIX = ".tmp-"


@dataclass(frozen=True)
class BatchReport:
    """Figures of one batch run (also written to ``OUT/batch_<kind>.json``).

    Attributes
    ----------
    n_jobs : int
        Jobs in the manifest.
    ran, ok, failed : int
        Jobs submitted by this run; of them, finished and failed.
    skipped : int
        Jobs not run: complete before, failed before (without ``retry_failed``)
        or, with ``retry_failed``, never attempted.
    wall_s : float
        Wall time of the run in seconds, cluster start excluded.
    jobs_per_minute : float
        ``60 * ran / wall_s`` (0 when nothing ran).
    rows : tuple of dict
        The results.csv rows of the jobs this run finished, in finishing order.
    """

    n_jobs: int
    ran: int
    ok: int
    failed: int
    skipped: int
    wall_s: float
    jobs_per_minute: float
    rows: tuple[dict[str, str], ...]


def u_decimals(U: float, significant: int = 2) -> int:
    """Decimals that keep ``significant`` significant digits of an expanded uncertainty.

    Parameters
    ----------
    U : float
        Expanded uncertainty (> 0, finite).
    significant : int
        Significant digits of U (2: what the GUM's section 7.2.6 allows at most).

    Returns
    -------
    int
        Decimal places (0 for U >= 10 ** (significant - 1)).

    Examples
    --------
    >>> u_decimals(0.0043), u_decimals(0.012), u_decimals(37.0)
    (4, 3, 0)
    """
    return max(0, significant - 1 - math.floor(math.log10(abs(float(U)))))


def round_to_u(value: float, U: float | None, digits: int = 4) -> tuple[str, str | None]:
    """A value and its U as text, both to the decimal of U's second significant digit.

    Parameters
    ----------
    value : float
    U : float or None
        Expanded uncertainty (k = 2); None, zero or not finite: the value keeps ``digits``
        significant digits and U is None.
    digits : int
        Significant digits of a value without a usable U.

    Returns
    -------
    (str, str or None)

    Examples
    --------
    >>> round_to_u(0.09158301113, 0.0043217)
    ('0.0916', '0.0043')
    >>> round_to_u(12.3456, None)
    ('12.35', None)
    """
    v = float(value)
    if U is None or not math.isfinite(float(U)) or float(U) <= 0 or not math.isfinite(v):
        return f"{v:.{digits}g}", None
    d = u_decimals(U)
    return _no_negative_zero(f"{v:.{d}f}"), f"{float(U):.{d}f}"


def _no_negative_zero(text: str) -> str:
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def format_figures(figures: Mapping[str, Any]) -> dict[str, str]:
    """The results.csv text of key figures: to the precision their U supports.

    A figure with a U column (:data:`U_COLUMNS`) and a positive U is written with U to two
    significant digits and the value to the same decimal; other floats take their column's
    fixed decimals (:data:`DECIMALS`) or 4 significant digits; integers and text as they are.
    The full numbers stay in each job's JSON.

    Parameters
    ----------
    figures : mapping
        Figure name -> value (:func:`key_figures`).

    Returns
    -------
    dict
        Figure name -> text.

    Examples
    --------
    >>> format_figures({"max_depth_mm": 0.09158301113, "max_depth_U_mm": 0.0043217, "n_fail": 1})
    {'max_depth_mm': '0.0916', 'max_depth_U_mm': '0.0043', 'n_fail': '1'}
    >>> format_figures({"max_depth_mm": 0.09158301113, "invalid_fraction": 0.00012})
    {'max_depth_mm': '0.0916', 'invalid_fraction': '0.0001'}
    """
    out: dict[str, str] = {}
    for name, value in figures.items():
        if isinstance(value, bool) or not isinstance(value, float):
            out[name] = str(value)
        elif name in DECIMALS:
            out[name] = _no_negative_zero(f"{value:.{DECIMALS[name]}f}")
        else:
            out[name] = f"{value:.4g}"
    for name, u_name in U_COLUMNS.items():
        if isinstance(figures.get(name), float) and isinstance(figures.get(u_name), float):
            value, U = round_to_u(figures[name], figures[u_name])
            if U is not None:
                out[name], out[u_name] = value, U
    return out


def column_text(row: Mapping[str, str], name: str, missing: str = "-") -> str:
    """One figure of a results.csv row as a report shows it: with its U, to the precision U supports.

    Rows written before the figures were rounded (10 significant digits) read the same.

    Parameters
    ----------
    row : mapping
        A results.csv row (:func:`read_results`).
    name : str
        Its column.
    missing : str
        Text of an empty cell.

    Returns
    -------
    str
        ``"0.0916 +- 0.0043"`` for a figure with a U column (:data:`U_COLUMNS`) and a U, the
        column's fixed decimals (:data:`DECIMALS`) otherwise, or the text as it is.

    Examples
    --------
    >>> column_text({"max_depth_mm": "0.09158301113", "max_depth_U_mm": "0.0043217"}, "max_depth_mm")
    '0.0916 +- 0.0043'
    >>> column_text({"max_depth_mm": "0.09158301113", "max_depth_U_mm": ""}, "max_depth_mm")
    '0.0916'
    """
    text = row.get(name) or ""
    if not text:
        return missing
    try:
        value = float(text)
    except ValueError:
        return text
    if "." not in text and "e" not in text.lower():
        return text  # a whole number (a count)
    u_text = row.get(U_COLUMNS.get(name, ""), "") or ""
    if u_text:
        shown, U = round_to_u(value, float(u_text))
        if U is not None:
            return f"{shown} +- {U}"
    return format_figures({name: value})[name]


def key_figures(kind: str, summary: Mapping[str, Any]) -> dict[str, Any]:
    """Pick the key figures of a job's summary for its results.csv row.

    Each name of ``FIGURES[kind]`` is looked up at the top level of the summary,
    then inside its nested dictionaries (first match, depth first).

    Parameters
    ----------
    kind : {"photometric", "slices", "inspect"}
        Job kind (``inspect``: a part of ``workbench inspect run``).
    summary : mapping
        The pipeline's summary dictionary.

    Returns
    -------
    dict
        Figure name -> value (int or float; text for :data:`TEXT_FIGURES`); figures the
        summary lacks are left out.

    Examples
    --------
    >>> key_figures("slices", {"volume_mm3": 1500.0, "mesh": {"n_patches": 96}, "n_bodies": True})
    {'volume_mm3': 1500.0, 'n_bodies': 1, 'n_patches': 96}
    """

    def find(node: Mapping[str, Any], name: str) -> Any:
        if name in node and (isinstance(node[name], (int, float))
                             or name in TEXT_FIGURES and isinstance(node[name], str)):
            return node[name]
        for value in node.values():
            if isinstance(value, Mapping):
                found = find(value, name)
                if found is not None:
                    return found
        return None

    figures = {}
    for name in FIGURES[kind if kind in FIGURES else check_kind(kind)]:
        value = find(summary, name)
        if value is not None:
            figures[name] = int(value) if isinstance(value, bool) else value
    return figures


def marker_kind(folder: str | os.PathLike) -> str:
    """Return the job kind that a finished job folder's ``_COMPLETE`` marker records.

    Parameters
    ----------
    folder : path
        A job folder ``OUT/<id>``; :func:`workbench.batch.driver.plan` checks it against the job.

    Returns
    -------
    str
        ``"photometric"`` or ``"slices"``; ``"unknown"`` when the marker is missing or unreadable.
    """
    try:
        return json.loads((Path(folder) / COMPLETE_MARKER).read_text())["row"]["kind"]
    except (ValueError, KeyError, TypeError, OSError):
        return "unknown"


def one_line_error(exc: BaseException, limit: int = 300) -> str:
    """Format an exception as ``Type: first line of the message`` (at most ``limit`` characters).

    Parameters
    ----------
    exc : BaseException
        The exception.
    limit : int, optional
        Maximum length.

    Returns
    -------
    str

    Examples
    --------
    >>> one_line_error(ValueError("lights: 2 rows\\nexpected 3"))
    'ValueError: lights: 2 rows'
    """
    message = str(exc).strip().splitlines()
    text = f"{type(exc).__name__}: {message[0]}" if message else type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def failed_figures(job: Job) -> dict[str, Any]:
    """The figures a failed job's row still carries: an inspected part's verdict is ``not_measured``.

    Parameters
    ----------
    job : Job

    Returns
    -------
    dict
        ``{"verdict": "not_measured", "spec_sha256": ...}`` for a part of ``workbench inspect``
        (the spec's hash from its options, when given), else empty.

    Examples
    --------
    >>> failed_figures(Job("p1", "inspect", "/lot/p1", {"spec_sha256": "ab12"}))
    {'verdict': 'not_measured', 'spec_sha256': 'ab12'}
    >>> failed_figures(Job("k1", "slices", "/d/k1.json"))
    {}
    """
    if job.kind != "inspect":
        return {}
    figures: dict[str, Any] = {"verdict": NOT_MEASURED}
    if job.options.get("spec_sha256"):
        figures["spec_sha256"] = str(job.options["spec_sha256"])
    return figures


def result_row(job: Job, status: str, error: str, time_s: float, figures: Mapping[str, Any]) -> dict[str, Any]:
    """Build a job's results.csv row: every column of :data:`RESULT_COLUMNS`, as text.

    Parameters
    ----------
    job : Job
        The job.
    status : {"ok", "failed"}
        How it ended.
    error : str
        One-line error (empty when it succeeded).
    time_s : float
        Time the job took, in seconds.
    figures : mapping
        Key figures (:func:`key_figures`); written by :func:`format_figures` (to the
        precision their U supports, or their column's fixed decimals).

    Returns
    -------
    dict
        Column name -> text (missing figures are empty).

    Examples
    --------
    >>> row = result_row(Job("k1", "slices", "/d/k1.json"), "ok", "", 1.23456, {"volume_ml": 2.5})
    >>> row["time_s"], row["volume_ml"], row["volume_mm3"], row["input"]
    ('1.235', '2.5000', '', '/d/k1.json')
    """
    row: dict[str, Any] = {name: "" for name in RESULT_COLUMNS}
    row.update(
        id=job.id,
        kind=job.kind,
        status=status,
        error=error,
        time_s=f"{time_s:.3f}",
        input=job.describe(),
    )
    row.update(format_figures(figures))
    return row


def record_outcome(out: str | os.PathLike, job: Job, row: Mapping[str, Any]) -> None:
    """Keep ``OUT/failed/<id>.json`` in step with the job's last status.

    A success removes the record; a failure writes it (error, traceback, time,
    the number of attempts so far, the job's input and options).

    Parameters
    ----------
    out : path
        Batch output folder.
    job : Job
        The job.
    row : mapping
        Its results.csv row (``status``, ``error``, ``time_s``, optional ``traceback``).
    """
    record = Path(out) / FAILED_DIR / f"{job.id}.json"
    if row["status"] == "ok":
        record.unlink(missing_ok=True)
        return
    attempts = 1
    if record.is_file():
        try:
            attempts = int(json.loads(record.read_text()).get("attempts", 0)) + 1
        except (ValueError, OSError):
            attempts = 1
    record.parent.mkdir(exist_ok=True)
    content = {
        "id": job.id,
        "kind": job.kind,
        "error": row["error"],
        "traceback": row.get("traceback", ""),
        "time_s": float(row["time_s"]),
        "attempts": attempts,
        "input": job.input,
        "roi": job.roi,
        "options": job.options,
        "finished_utc": now_utc(),
    }
    write_json(record, content)


def read_results(path: str | os.PathLike) -> dict[str, dict[str, str]]:
    """Read ``results.csv``: the last row of every job id, in order of first appearance.

    Parameters
    ----------
    path : path
        ``OUT/results.csv`` (missing -> empty).

    Returns
    -------
    dict
        Job id -> row (column name -> text).
    """
    path = Path(path)
    if not path.is_file():
        return {}
    rows: dict[str, dict[str, str]] = {}
    with open(path, newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            if row.get("id"):
                rows[row["id"]] = {name: row.get(name) or "" for name in RESULT_COLUMNS}
    return rows


def write_results(path: str | os.PathLike, rows: Iterable[Mapping[str, Any]]) -> Path:
    """Write ``results.csv`` atomically: one header, then the rows (extra keys are left out).

    Parameters
    ----------
    path : path
        ``OUT/results.csv``.
    rows : iterable of mapping
        Rows keyed by :data:`RESULT_COLUMNS`.

    Returns
    -------
    Path
        The file written.
    """
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=RESULT_COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return atomic_write_text(path, buffer.getvalue())


def healed_results(
    out: str | os.PathLike, complete: Sequence[Job], failed_before: Sequence[Job], rewrite: bool
) -> dict[str, dict[str, str]]:
    """Rows of results.csv, completed from the job folders and failure records.

    A row cut short by a crash is dropped; a finished job without a row gets its
    row back from its ``_COMPLETE`` marker, a failed one from ``failed/<id>.json``.
    The file is rewritten (atomically, one header, current columns) only when
    something changed, when ``rewrite`` is set (jobs are about to be appended) or
    when it is missing, so a rerun with nothing to do leaves it untouched.

    Parameters
    ----------
    out : path
        Batch output folder.
    complete : sequence of Job
        Jobs whose folder is complete.
    failed_before : sequence of Job
        Jobs with a failure record that this run does not retry.
    rewrite : bool
        Rewrite the file even when nothing changed.

    Returns
    -------
    dict
        Job id -> row, the content of results.csv after healing.
    """
    out = Path(out)
    results = out / RESULTS_NAME
    rows = read_results(results)
    kept = {k: r for k, r in rows.items() if r["status"] in ("ok", "failed") and r["kind"] in FIGURES}
    changed = len(kept) != len(rows)
    for job in complete:
        # a finished folder wins over a failed row (a twin task of a killed driver failed beside it)
        if job.id not in kept or kept[job.id]["status"] != "ok":
            try:
                marker = json.loads((out / job.id / COMPLETE_MARKER).read_text())["row"]
            except (ValueError, KeyError, OSError):
                continue
            kept[job.id] = {name: str(marker.get(name, "")) for name in RESULT_COLUMNS}
            changed = True
    for job in failed_before:
        if job.id not in kept:
            try:
                record = json.loads((out / FAILED_DIR / f"{job.id}.json").read_text())
            except (ValueError, OSError):
                continue
            kept[job.id] = result_row(
                job, "failed", str(record.get("error", "")), float(record.get("time_s", 0.0)), failed_figures(job)
            )
            changed = True
    if changed or rewrite or not results.is_file():
        write_results(results, kept.values())
    return kept


def write_report(report: BatchReport, out: str | os.PathLike, kind: str, **extra: Any) -> Path:
    """Write a run's figures to ``OUT/batch_<kind>.json`` (atomically).

    Parameters
    ----------
    report : BatchReport
        The run's figures.
    out : path
        Batch output folder.
    kind : str
        Job kind (names the file).
    **extra
        More JSON-serialisable entries (scheduler, workers, dashboard, ...).

    Returns
    -------
    Path
        The file written.
    """
    content = {
        "kind": kind,
        "n_jobs": report.n_jobs,
        "ran": report.ran,
        "ok": report.ok,
        "failed": report.failed,
        "skipped": report.skipped,
        "wall_s": round(report.wall_s, 3),
        "jobs_per_minute": round(report.jobs_per_minute, 3),
        "results": RESULTS_NAME,
        "finished_utc": now_utc(),
        **extra,
    }
    return write_json(Path(out) / f"batch_{check_kind(kind)}.json", content)


def now_utc() -> str:
    """Return the current UTC time as ISO 8601 text to the second (for records and markers)."""
    return datetime.now(UTC).isoformat(timespec="seconds")
