"""Batches of photometric or slices jobs on a Dask cluster (``workbench batch``).

A *manifest* (CSV with a header row, or JSON lines) names one job per row; a
folder instead of a manifest means every job found below it. Each job is one
Dask task that reads its data from its paths (no arrays travel through the
scheduler), calls the library pipeline (:func:`photometric.pipeline.reconstruct`
or :func:`slices.pipeline.reconstruct`) and writes its own folder ``OUT/<id>``
atomically: the pipeline writes into ``OUT/.tmp-<id>-<uuid>``, a ``_COMPLETE``
marker (JSON: the job's row, input and options) is written last, and the folder
is renamed to ``OUT/<id>`` with :func:`os.replace`. A failing job leaves no
folder, only its row in ``OUT/results.csv`` (one-line error) and a record in
``OUT/failed/<id>.json`` (with the traceback).

Bookkeeping in ``OUT``:

- ``results.csv``: one row per job (columns :data:`RESULT_COLUMNS`), appended
  and flushed as each job finishes; at the end of a run the file is rewritten
  atomically with the latest row of every job, so a retried job keeps one row.
- Resuming: a rerun skips jobs whose folder is complete and jobs with a failure
  record; skipped jobs are *not re-listed* (their earlier row stays as it was).
  ``retry_failed=True`` runs only the jobs with a failure record.
- ``batch_<kind>.json``: the figures of the last run (counts, wall time, jobs
  per minute, scheduler).
- ``.batch.lock``: held while a run is going on, so two runs never share ``OUT``.

The same code runs on a :class:`distributed.LocalCluster` or on any running
cluster (``tcp://HOST:8786``); with several machines every worker must see the
input paths and ``OUT`` under the same names (a shared filesystem).
"""

from __future__ import annotations

import csv
import importlib.util
import inspect
import io
import json
import os
import re
import shutil
import socket
import time
import traceback
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from surfaces.validate import positive

KINDS: tuple[str, ...] = ("photometric", "slices")
#: key figures copied from a job's summary into its results.csv row, per kind
FIGURES: dict[str, tuple[str, ...]] = {
    "photometric": ("n_defects", "max_depth_mm", "invalid_fraction", "light_condition_number"),
    "slices": ("volume_mm3", "volume_ml", "area_mm2", "n_bodies", "n_patches"),
}
RESULT_COLUMNS: tuple[str, ...] = (
    "id",
    "kind",
    "status",
    "error",
    "time_s",
    *FIGURES["photometric"],
    *FIGURES["slices"],
    "input",
)
RESULTS_NAME = "results.csv"
FAILED_DIR = "failed"
COMPLETE_MARKER = "_COMPLETE"
TMP_PREFIX = ".tmp-"
LOCK_NAME = ".batch.lock"
# manifest columns holding file paths (resolved against the manifest's folder)
_PATH_OPTIONS: dict[str, tuple[str, ...]] = {
    "photometric": ("lights", "intensities", "mask"),
    "slices": (),
}
_ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,127}$")
_RESERVED_IDS = frozenset({FAILED_DIR, RESULTS_NAME})


@dataclass(frozen=True)
class Job:
    """One batch job: what to reconstruct and with which options.

    Attributes
    ----------
    id : str
        Unique, filesystem-safe name; the job's folder is ``OUT/<id>``.
    kind : str
        ``"photometric"`` or ``"slices"``.
    input : str or tuple of str
        Absolute path of the input (DiLiGenT-style folder, structure set, contour
        file or CT folder), or, for photometric jobs given as images + lights, the
        absolute paths of the images in light order.
    options : dict
        Keyword options for the pipeline (paths among them are absolute).
    roi : str or None
        Slices jobs on a structure set: the ROI name to reconstruct.
    """

    id: str
    kind: str
    input: str | tuple[str, ...]
    options: dict[str, Any] = field(default_factory=dict)
    roi: str | None = None

    def describe(self) -> str:
        """Return the input as one line (images joined with ``;``) for tables and records."""
        return ";".join(self.input) if isinstance(self.input, tuple) else self.input


@dataclass(frozen=True)
class Plan:
    """Which jobs a run does and which it leaves, from the state of ``OUT``.

    Attributes
    ----------
    to_run : tuple of Job
        Jobs this run submits.
    complete : tuple of Job
        Jobs whose folder ``OUT/<id>`` is complete (skipped, not re-listed).
    failed_before : tuple of Job
        Jobs with a failure record that this run does not retry.
    pending : tuple of Job
        Jobs never attempted that a ``retry_failed`` run leaves for a plain run.
    """

    to_run: tuple[Job, ...]
    complete: tuple[Job, ...]
    failed_before: tuple[Job, ...]
    pending: tuple[Job, ...]


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


# --------------------------------------------------------------------------- manifests


def load_jobs(source: str | os.PathLike, kind: str, defaults: Mapping[str, Any] | None = None) -> list[Job]:
    """Read the jobs of a manifest file, or discover every job below a folder.

    Parameters
    ----------
    source : path
        A manifest (see :func:`read_manifest`) or a folder (see :func:`discover_jobs`).
    kind : {"photometric", "slices"}
        Job kind.
    defaults : mapping, optional
        Pipeline options for every job (a manifest row's own values take precedence).

    Returns
    -------
    list of Job
        Jobs in manifest (or sorted discovery) order, with unique ids.

    Raises
    ------
    FileNotFoundError
        When ``source`` does not exist.
    ValueError
        On a malformed manifest or when a folder holds no job.
    """
    path = Path(source)
    if path.is_dir():
        return discover_jobs(path, kind, defaults)
    if not path.exists():
        raise FileNotFoundError(f"manifest {path}: no such file or folder")
    return read_manifest(path, kind, defaults)


def read_manifest(path: str | os.PathLike, kind: str, defaults: Mapping[str, Any] | None = None) -> list[Job]:
    """Parse a CSV (header row) or JSON-lines manifest into jobs.

    Photometric rows name either ``input`` (a DiLiGenT-style folder) or
    ``images`` (a list, or paths separated by ``;``) with ``lights`` (and
    optionally ``intensities`` and ``mask``). Slices rows name ``input`` (an
    RTSTRUCT file, a ``contours.json`` or a CT folder) and, for a structure set,
    ``roi`` (one name, a list, or names separated by ``;``: one job per name; when
    absent, one job per ROI that has contours); a CT folder takes the HU window
    as ``hu_min``/``hu_max`` options. Every other column is a keyword
    option of the pipeline (``integrator``, ``pixel_size``, ``method``,
    ``caps``, ``rays``, ...); in a CSV, numbers and ``true``/``false`` are
    converted and empty cells are left out. An ``id`` column is optional;
    without it the id is derived from the input path (see :func:`job_id`).
    Relative paths are taken from the manifest's folder. Lines starting with
    ``#`` and blank lines are ignored.

    Parameters
    ----------
    path : path
        Manifest file. ``.csv`` is CSV; ``.jsonl``, ``.ndjson`` and ``.json`` are
        JSON lines; any other name is JSON lines when its first character is ``{``.
    kind : {"photometric", "slices"}
        Job kind; an optional ``kind`` column must agree with it.
    defaults : mapping, optional
        Pipeline options for every job; a row's own values take precedence.

    Returns
    -------
    list of Job
        One job per row, in file order.

    Raises
    ------
    FileNotFoundError
        When the manifest does not exist.
    ValueError
        On a row without its input, an unknown option, a bad or duplicate id.
    """
    kind = _check_kind(kind)
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"manifest {path}: no such file")
    text = path.read_text(encoding="utf-8-sig")
    base = path.resolve().parent
    jsonl = path.suffix.lower() in (".jsonl", ".ndjson", ".json") or (
        path.suffix.lower() != ".csv" and text.lstrip().startswith("{")
    )
    rows = _json_rows(text, path) if jsonl else _csv_rows(text, path)
    if not rows:
        raise ValueError(f"manifest {path}: no job rows")
    jobs = [
        job
        for line, row in rows
        for job in _jobs_from_row({**(defaults or {}), **row}, kind, base, f"manifest {path} line {line}")
    ]
    return _unique_ids(jobs)


def discover_jobs(root: str | os.PathLike, kind: str, defaults: Mapping[str, Any] | None = None) -> list[Job]:
    """Find every job below a folder.

    Photometric: every folder holding a ``light_directions.txt`` (DiLiGenT layout)
    or a ``lights.npy`` (RobustPhotometricStereo layout). Slices: every
    DICOM file whose Modality is RTSTRUCT (checked on the header alone), one job
    per ROI that has contours (:func:`slices.io.list_rois`), and every
    ``contours.json`` in a folder that holds no RTSTRUCT (a phantom folder that
    carries both gives the structure set's jobs only). Hidden folders (``.name``,
    e.g. unfinished batch folders) and finished batch job folders (holding a
    ``_COMPLETE`` marker, e.g. when OUT lies below ``root``) are not searched.

    Parameters
    ----------
    root : path
        Folder to search recursively.
    kind : {"photometric", "slices"}
        Job kind.
    defaults : mapping, optional
        Pipeline options for every job (checked like manifest options).

    Returns
    -------
    list of Job
        Jobs sorted by path, ids derived from the path relative to ``root``
        (and the ROI name for structure sets).

    Raises
    ------
    NotADirectoryError
        When ``root`` is not a folder.
    ValueError
        When no job is found.
    """
    kind = _check_kind(kind)
    root = Path(root)
    if not root.is_dir():
        raise NotADirectoryError(f"job folder {root}: not a folder")
    root = root.resolve()
    if kind == "photometric":
        markers = [*_walk(root, "light_directions.txt"), *_walk(root, "lights.npy")]
        inputs = sorted({p.parent for p in markers})
        what = "folder with a light_directions.txt (or lights.npy)"
    else:
        structure_sets = sorted(p for p in _walk(root, "*.dcm") if _is_rtstruct(p))
        with_rtstruct = {p.parent for p in structure_sets}
        contour_files = sorted(p for p in _walk(root, "contours.json") if p.parent not in with_rtstruct)
        inputs = sorted(structure_sets + contour_files)
        what = "RTSTRUCT .dcm file or contours.json"
    if not inputs:
        raise ValueError(f"job folder {root}: no {what} found below it")
    options = dict(defaults or {})
    wanted = _as_list(options.pop("roi"), f"job folder {root}", "roi") if "roi" in options else None
    _check_options(kind, options, f"job folder {root}")
    jobs = []
    for p in inputs:
        if p.suffix.lower() == ".dcm":
            names = wanted or _rois_with_contours(p) or [None]
            jobs += [Job(job_id(p, root, [n]), kind, str(p), dict(options), n) for n in names]
        else:
            jobs.append(Job(job_id(p, root), kind, str(p), dict(options)))
    return _unique_ids(jobs)


def job_id(path: str | os.PathLike, base: str | os.PathLike | None = None, roi: Sequence[str] | None = None) -> str:
    """Derive a filesystem-safe job id from an input path.

    The path relative to ``base`` (when below it; else its last two parts),
    without a file suffix, its parts joined with ``-``, ROI names appended with
    ``-``; characters other than letters, digits, ``.``, ``_``, ``+`` and ``-``
    become ``_``. Uniqueness within a batch is added by the caller (``-2``, ...).

    Parameters
    ----------
    path : path
        Input path.
    base : path, optional
        Folder the id is relative to (the manifest's or the discovery root).
    roi : sequence of str, optional
        ROI names of a slices job.

    Returns
    -------
    str
        The id (at most 120 characters).
    """
    p = Path(path)
    if base is not None:
        try:
            rel = p.resolve().relative_to(Path(base).resolve())
        except ValueError:
            rel = Path(*p.resolve().parts[-2:])
    else:
        rel = Path(*p.parts[-2:])
    parts = list(rel.parts)
    if not parts:  # the base itself is the job folder
        parts = [p.resolve().name]
    if p.is_file() or p.suffix.lower() in (".dcm", ".json"):
        parts[-1] = Path(parts[-1]).stem
    if roi:
        parts.extend(roi)
    return _safe("-".join(parts))


def _safe(text: str) -> str:
    text = re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("._-+")
    return (text or "job")[:120]


def _rois_with_contours(path: Path) -> list[str]:
    """ROI names with contours; empty when the file cannot be listed (the job then fails)."""
    from slices.io import list_rois

    try:
        return [r["name"] for r in list_rois(path) if r["n_contours"] > 0]
    except (ValueError, OSError):
        return []


def _walk(root: Path, pattern: str) -> Iterator[Path]:
    """Files matching ``pattern`` below ``root``, outside hidden folders and finished job folders.

    A batch's OUT may lie inside the folder it searches: its job folders (they hold
    the ``_COMPLETE`` marker) and unfinished ones (hidden ``.tmp-``) are not inputs.
    """
    for path in root.rglob(pattern):
        rel = path.relative_to(root).parts
        if any(part.startswith(".") for part in rel[:-1]) or not path.is_file():
            continue
        if any((root.joinpath(*rel[:i]) / COMPLETE_MARKER).is_file() for i in range(1, len(rel))):
            continue
        yield path


def _is_rtstruct(path: Path) -> bool:
    import pydicom

    try:
        ds = pydicom.dcmread(path, stop_before_pixels=True, specific_tags=["Modality"])
    except Exception:  # noqa: BLE001 - a file that is not DICOM is simply not a structure set
        return False
    return str(getattr(ds, "Modality", "")).upper() == "RTSTRUCT"


def _check_kind(kind: str) -> str:
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    return kind


def _csv_rows(text: str, path: Path) -> list[tuple[int, dict[str, Any]]]:
    lines = [ln for ln in text.splitlines() if not ln.lstrip().startswith("#")]
    reader = csv.DictReader(io.StringIO("\n".join(lines)))
    if not reader.fieldnames:
        raise ValueError(f"manifest {path}: no header row")
    header = [(name or "").strip() for name in reader.fieldnames]
    if any(not name for name in header) or len(set(header)) != len(header):
        raise ValueError(f"manifest {path}: header has empty or repeated column names: {header}")
    rows = []
    for raw in reader:
        if None in raw:
            raise ValueError(f"manifest {path} line {reader.line_num}: more cells than header columns")
        row = {
            name: coerce_value(value.strip())
            for name, value in zip(header, raw.values())
            if value is not None and value.strip() != ""
        }
        if row:
            rows.append((reader.line_num, row))
    return rows


def _json_rows(text: str, path: Path) -> list[tuple[int, dict[str, Any]]]:
    rows = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            row = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f"manifest {path} line {line_no}: not a JSON object ({exc.msg})") from None
        if not isinstance(row, dict):
            raise ValueError(  # noqa: TRY004 - bad manifest content is a ValueError for the CLI
                f"manifest {path} line {line_no}: expected a JSON object, got {type(row).__name__}"
            )
        rows.append((line_no, {str(k).strip(): v for k, v in row.items() if v is not None}))
    return rows


def coerce_value(value: str) -> Any:
    """Convert a manifest cell or ``--option`` value: ``true``/``false``, int, float, else text.

    Parameters
    ----------
    value : str
        The text.

    Returns
    -------
    bool, int, float or str
    """
    low = value.lower()
    if low in ("true", "false"):
        return low == "true"
    for cast in (int, float):
        try:
            return cast(value)
        except ValueError:
            pass
    return value


def _as_list(value: Any, where: str, name: str) -> list[str]:
    items = value.split(";") if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)):
        raise ValueError(  # noqa: TRY004 - bad manifest content is a ValueError for the CLI
            f"{where}: {name} must be a list or ';'-separated text, got {value!r}"
        )
    items = [str(v).strip() for v in items if str(v).strip()]
    if not items:
        raise ValueError(f"{where}: {name} is empty")
    return items


def _resolve(value: Any, base: Path, where: str, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{where}: {name} must be a path, got {value!r}")
    p = Path(value.strip()).expanduser()
    return str(p if p.is_absolute() else (base / p).resolve())


def _jobs_from_row(row: dict[str, Any], kind: str, base: Path, where: str) -> list[Job]:
    row = dict(row)
    row_kind = row.pop("kind", kind)
    if row_kind != kind:
        raise ValueError(f"{where}: kind {row_kind!r} in a {kind} batch")
    given_id = row.pop("id", None)
    rois: list[str | None] = [None]
    if kind == "photometric":
        folder, images = row.pop("input", None), row.pop("images", None)
        if (folder is None) == (images is None):
            raise ValueError(f"{where}: give either 'input' (a folder) or 'images' (+ 'lights'), not both or neither")
        if images is not None:
            if "lights" not in row:
                raise ValueError(f"{where}: 'images' needs a 'lights' file")
            source: str | tuple[str, ...] = tuple(
                _resolve(v, base, where, "images") for v in _as_list(images, where, "images")
            )
            id_path = Path(source[0]).parent
        else:
            source = _resolve(folder, base, where, "input")
            id_path = Path(source)
    else:
        if "input" not in row:
            raise ValueError(f"{where}: missing 'input' (structure set, contours.json or CT folder)")
        source = _resolve(row.pop("input"), base, where, "input")
        id_path = Path(source)
        if "roi" in row:
            rois = list(_as_list(row.pop("roi"), where, "roi"))
        elif source.lower().endswith(".dcm") and Path(source).is_file():
            rois = _rois_with_contours(Path(source)) or [None]
    options = {  # a path option may also be a number (a scalar intensity)
        name: _resolve(value, base, where, name) if name in _PATH_OPTIONS[kind] and isinstance(value, str) else value
        for name, value in row.items()
    }
    _check_options(kind, options, where)
    if given_id is not None and not (_ID_PATTERN.match(str(given_id)) and str(given_id) not in _RESERVED_IDS):
        raise ValueError(
            f"{where}: id {given_id!r} is not a safe folder name (letters, digits, . _ + -; "
            f"not {', '.join(sorted(_RESERVED_IDS))})"
        )
    jobs = []
    for roi in rois:
        if given_id is None:
            ident = job_id(id_path, base, [roi] if roi else None)
        else:  # several ROIs of one row share its id as a prefix
            ident = str(given_id) if len(rois) == 1 else f"{given_id}-{_safe(str(roi))}"
        jobs.append(Job(ident, kind, source, dict(options), roi))
    return jobs


def _check_options(kind: str, options: Mapping[str, Any], where: str) -> None:
    """Reject options the pipeline does not take, when its signature says which it takes."""
    params = inspect.signature(_pipeline(kind)).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    names = list(params)[2:]  # the input and the output folder come first
    unknown = sorted(set(options) - set(names))
    if unknown:
        raise ValueError(
            f"{where}: unknown option(s) {', '.join(unknown)}; the {kind} pipeline takes {', '.join(names)}"
        )


def _unique_ids(jobs: list[Job]) -> list[Job]:
    seen: dict[str, int] = {}
    explicit = [job.id for job in jobs]
    out = []
    for job in jobs:
        ident = job.id
        if ident in seen:
            n = seen[ident] + 1
            while f"{job.id}-{n}" in seen or f"{job.id}-{n}" in explicit:
                n += 1
            seen[job.id] = n
            ident = f"{job.id}-{n}"
        seen.setdefault(ident, 1)
        out.append(job if ident == job.id else Job(ident, job.kind, job.input, job.options, job.roi))
    return out


# --------------------------------------------------------------------------- job runners


def _pipeline(kind: str) -> Callable[..., dict]:
    if kind == "photometric":
        from photometric.pipeline import reconstruct
    else:
        from workbench.runs.slices import reconstruct_to_folder as reconstruct
    return reconstruct


def run_photometric(job: Job, out_dir: Path) -> dict:
    """Run one photometric job: :func:`photometric.pipeline.reconstruct` into ``out_dir``.

    Parameters
    ----------
    job : Job
        A photometric job (folder, or images with a ``lights`` option).
    out_dir : Path
        Empty folder the pipeline writes into.

    Returns
    -------
    dict
        The pipeline's summary (the content of its ``summary.json``), with
        ``max_depth_mm``, the depth of the deepest defect in its ``defects.json``
        (0.0 when there is none), when the summary lacks it.
    """
    source = list(job.input) if isinstance(job.input, tuple) else job.input
    summary = dict(_pipeline("photometric")(source, out_dir, **job.options))
    if "max_depth_mm" not in summary:
        # the pipeline lists its defects in defects.json; the row reports the deepest
        defects = json.loads((Path(out_dir) / "defects.json").read_text())["defects"]
        summary["max_depth_mm"] = max((float(d["max_depth_mm"]) for d in defects), default=0.0)
    return summary


def run_slices(job: Job, out_dir: Path) -> dict:
    """Run one slices job: :func:`slices.pipeline.reconstruct` into ``out_dir``.

    Parameters
    ----------
    job : Job
        A slices job (structure set + ROI names, contour file, or CT folder + HU window).
    out_dir : Path
        Empty folder the pipeline writes into.

    Returns
    -------
    dict
        The pipeline's summary (the content of its ``summary.json``).
    """
    return _pipeline("slices")(job.input, out_dir, roi=job.roi, **job.options)


#: the job runner table: kind -> callable(job, out_dir) -> summary dict
RUNNERS: dict[str, Callable[[Job, Path], dict]] = {
    "photometric": run_photometric,
    "slices": run_slices,
}


def key_figures(kind: str, summary: Mapping[str, Any]) -> dict[str, Any]:
    """Pick the key figures of a job's summary for its results.csv row.

    Each name of ``FIGURES[kind]`` is looked up at the top level of the summary,
    then inside its nested dictionaries (first match, depth first).

    Parameters
    ----------
    kind : {"photometric", "slices"}
        Job kind.
    summary : mapping
        The pipeline's summary dictionary.

    Returns
    -------
    dict
        Figure name -> value (int or float); figures the summary lacks are left out.
    """

    def find(node: Mapping[str, Any], name: str) -> Any:
        if name in node and isinstance(node[name], (int, float)):
            return node[name]
        for value in node.values():
            if isinstance(value, Mapping):
                found = find(value, name)
                if found is not None:
                    return found
        return None

    figures = {}
    for name in FIGURES[_check_kind(kind)]:
        value = find(summary, name)
        if value is not None:
            figures[name] = int(value) if isinstance(value, bool) else value
    return figures


def is_complete(folder: str | os.PathLike) -> bool:
    """Return whether a job folder is complete (it holds the ``_COMPLETE`` marker).

    Parameters
    ----------
    folder : path
        ``OUT/<id>``.

    Returns
    -------
    bool
    """
    return (Path(folder) / COMPLETE_MARKER).is_file()


def execute_job(job: Job, out: str | os.PathLike, runner: Callable[[Job, Path], dict] | None = None) -> dict[str, Any]:
    """Run one job into ``OUT/<id>`` atomically; the body of one Dask task.

    The runner writes into ``OUT/.tmp-<id>-<uuid>``; the ``_COMPLETE`` marker is
    written last and the folder renamed to ``OUT/<id>`` (:func:`os.replace`). On
    any exception the temporary folder is removed and a failed row is returned
    (the exception does not propagate), so the batch goes on.

    Parameters
    ----------
    job : Job
        The job.
    out : path
        Batch output folder (must exist; same path on every worker).
    runner : callable, optional
        ``runner(job, out_dir) -> summary dict``; default ``RUNNERS[job.kind]``.

    Returns
    -------
    dict
        The results.csv row (``id, kind, status, error, time_s``, key figures,
        ``input``) plus ``traceback`` (empty when the job succeeded).
    """
    out = Path(out)
    runner = runner or RUNNERS[job.kind]
    tmp = out / f"{TMP_PREFIX}{job.id}-{uuid.uuid4().hex[:12]}"
    start = time.perf_counter()
    try:
        tmp.mkdir(parents=True)
        summary = runner(job, tmp)
        if not isinstance(summary, Mapping):
            raise TypeError(f"the {job.kind} pipeline returned {type(summary).__name__}, not a summary dict")
        elapsed = time.perf_counter() - start
        row = _row(job, "ok", "", elapsed, key_figures(job.kind, summary))
        marker = {
            "row": row,
            "input": job.input,
            "roi": job.roi,
            "options": job.options,
            "host": socket.gethostname(),
            "finished_utc": _now(),
        }
        _write_text_atomic(tmp / COMPLETE_MARKER, json.dumps(marker, indent=2, default=str) + "\n")
        final = out / job.id
        if final.exists():  # an incomplete leftover under this id: replace it
            shutil.rmtree(final)
        os.replace(tmp, final)
    except Exception as exc:  # noqa: BLE001 - any job error is recorded, and the batch goes on
        shutil.rmtree(tmp, ignore_errors=True)
        row = _row(job, "failed", one_line_error(exc), time.perf_counter() - start, {})
        row["traceback"] = traceback.format_exc()
        return row
    row["traceback"] = ""
    return row


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
    """
    message = str(exc).strip().splitlines()
    text = f"{type(exc).__name__}: {message[0]}" if message else type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _row(job: Job, status: str, error: str, time_s: float, figures: Mapping[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {name: "" for name in RESULT_COLUMNS}
    row.update(
        id=job.id,
        kind=job.kind,
        status=status,
        error=error,
        time_s=f"{time_s:.3f}",
        input=job.describe(),
    )
    for name, value in figures.items():
        row[name] = f"{value:.10g}" if isinstance(value, float) else str(value)
    return row


# --------------------------------------------------------------------------- the driver


def plan(jobs: Sequence[Job], out: str | os.PathLike, retry_failed: bool = False) -> Plan:
    """Split jobs by the state of ``OUT``: to run, complete, failed before, pending.

    Parameters
    ----------
    jobs : sequence of Job
        Jobs with unique ids.
    out : path
        Batch output folder (may not exist yet).
    retry_failed : bool, optional
        Run only the jobs with a failure record in ``OUT/failed``.

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        On duplicate ids, or when a complete folder under an id belongs to a job
        of another kind.
    """
    out = Path(out)
    ids = [job.id for job in jobs]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise ValueError(f"jobs: duplicate id(s) {', '.join(dup[:5])}")
    to_run, complete, failed_before, pending = [], [], [], []
    for job in jobs:
        folder = out / job.id
        if is_complete(folder):
            done_kind = _marker_kind(folder)
            if done_kind != job.kind:
                raise ValueError(f"job {job.id}: {folder} holds a finished {done_kind} job, not {job.kind}")
            complete.append(job)
        elif (out / FAILED_DIR / f"{job.id}.json").is_file():
            (to_run if retry_failed else failed_before).append(job)
        else:
            (pending if retry_failed else to_run).append(job)
    return Plan(tuple(to_run), tuple(complete), tuple(failed_before), tuple(pending))


@contextmanager
def connect(scheduler: str = "local", workers: int | None = None, threads_per_worker: int = 1) -> Iterator[Any]:
    """Open a Dask client: a new local cluster, or a running scheduler.

    Parameters
    ----------
    scheduler : str
        ``"local"``: a :class:`distributed.LocalCluster` of ``workers`` processes
        with ``threads_per_worker`` threads each (HTTP service and, when bokeh is
        installed, the dashboard on a free port), closed on exit. ``"tcp://HOST:PORT"``: connect to a
        running scheduler (``dask scheduler``); its workers are used as they are
        and ``workers`` is ignored.
    workers : int, optional
        Local worker processes; default the number of CPUs.
    threads_per_worker : int, optional
        Threads per local worker (default 1: the pipelines use numpy/OpenCV threads).

    Yields
    ------
    distributed.Client

    Raises
    ------
    ValueError
        On a malformed scheduler address, bad counts, or when the scheduler
        cannot be reached.
    """
    import dask
    from distributed import Client, LocalCluster

    n_threads = int(positive(threads_per_worker, "threads_per_worker"))
    if scheduler == "local":
        n_workers = int(positive(workers if workers is not None else (os.cpu_count() or 1), "workers"))
        # distributed's nanny gives its workers MALLOC_TRIM_THRESHOLD_=65536, which pins
        # glibc's mmap threshold: every large numpy temporary of a pipeline becomes a fresh
        # mmap. In a plain process with it set, 10 triads of 512x512 took 9.5-9.7 s instead
        # of 5.0-5.6 s in 2 of 3 rounds (noisy shared machine; bench_batch.py compares both
        # clusters). Batch jobs free their memory when they end, so keep glibc's default.
        with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
            # a free port: without bokeh the scheduler still serves HTTP (health, metrics),
            # and the default 8787 clashes with any other cluster on the machine
            cluster = LocalCluster(
                n_workers=n_workers,
                threads_per_worker=n_threads,
                processes=True,
                dashboard_address=":0",
            )
        try:
            client = Client(cluster)
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
        return
    if not re.match(r"^(tcp|tls)://[^\s:/]+:\d+$", scheduler):
        raise ValueError(f"scheduler: expected 'local' or tcp://HOST:PORT, got {scheduler!r}")
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"scheduler {scheduler}: cannot connect ({one_line_error(exc)})") from None
    try:
        yield client
    finally:
        client.close()


def dashboard_link(client: Any) -> str | None:
    """Return the dashboard address of a client's scheduler, or ``None`` when it has none.

    The scheduler serves its dashboard only when bokeh is installed where it
    runs (checked there); without bokeh its HTTP port has no dashboard.

    Parameters
    ----------
    client : distributed.Client

    Returns
    -------
    str or None
    """
    services = client.scheduler_info().get("services", {})
    if "dashboard" not in services or not client.run_on_scheduler(_has_bokeh):
        return None
    return client.dashboard_link


def _has_bokeh() -> bool:
    """Whether bokeh is importable (run on the scheduler: the dashboard needs it there)."""
    return importlib.util.find_spec("bokeh") is not None


def run_batch(
    jobs: Sequence[Job],
    out: str | os.PathLike,
    client: Any = None,
    *,
    scheduler: str = "local",
    workers: int | None = None,
    threads_per_worker: int = 1,
    retry_failed: bool = False,
    runners: Mapping[str, Callable[[Job, Path], dict]] | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> BatchReport:
    """Run jobs on Dask, one task per job, and record their results in ``OUT``.

    Jobs whose folder is complete, and jobs with a failure record, are skipped
    (not re-listed in results.csv); ``retry_failed`` runs only the latter. The
    remaining jobs are submitted at once; results are gathered with
    :func:`distributed.as_completed` and each row is appended to
    ``OUT/results.csv`` (flushed) as its job finishes. Failures are recorded in
    ``OUT/failed/<id>.json``; a later success removes the record. Task-level
    failures (a worker that dies) are recorded like job errors.

    Parameters
    ----------
    jobs : sequence of Job
        Jobs with unique ids (:func:`load_jobs`).
    out : path
        Batch output folder; created when missing.
    client : distributed.Client, optional
        Client to use; when omitted one is opened with :func:`connect`
        (``scheduler``, ``workers``, ``threads_per_worker``) and closed after,
        and only when there is something to run.
    scheduler, workers, threads_per_worker
        See :func:`connect`.
    retry_failed : bool, optional
        Run only the jobs that failed before.
    runners : mapping, optional
        Job runner table ``kind -> runner(job, out_dir) -> summary``; default
        :data:`RUNNERS`. Runners must be importable on the workers.
    progress : callable, optional
        Called with each finished job's row (in the driver, as it finishes).

    Returns
    -------
    BatchReport

    Raises
    ------
    ValueError
        On duplicate ids, a kind without runner, another run holding ``OUT``.
    """
    out = Path(out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    runners = dict(runners or RUNNERS)
    missing = sorted({job.kind for job in jobs} - set(runners))
    if missing:
        raise ValueError(f"runners: no runner for kind(s) {', '.join(missing)}")
    with _lock(out):
        _remove_stale_tmp(out)
        steps = plan(jobs, out, retry_failed)
        skipped = len(jobs) - len(steps.to_run)
        previous = _healed_results(out, steps)
        finished: list[dict[str, Any]] = []
        wall = 0.0
        if steps.to_run:
            if client is None:
                with connect(scheduler, workers, threads_per_worker) as own:
                    wall = _submit_and_gather(own, steps.to_run, out, runners, previous, finished, progress)
            else:
                wall = _submit_and_gather(client, steps.to_run, out, runners, previous, finished, progress)
            # every task has ended: a folder left by a worker that died mid-job is garbage now
            _remove_stale_tmp(out)
    n_failed = sum(row["status"] == "failed" for row in finished)
    return BatchReport(
        n_jobs=len(jobs),
        ran=len(finished),
        ok=len(finished) - n_failed,
        failed=n_failed,
        skipped=skipped,
        wall_s=wall,
        jobs_per_minute=60.0 * len(finished) / wall if finished and wall > 0 else 0.0,
        rows=tuple({k: v for k, v in row.items() if k != "traceback"} for row in finished),
    )


def _submit_and_gather(
    client: Any,
    jobs: Sequence[Job],
    out: Path,
    runners: Mapping[str, Callable[[Job, Path], dict]],
    previous: Mapping[str, dict[str, str]],
    finished: list[dict[str, Any]],
    progress: Callable[[dict[str, Any]], None] | None,
) -> float:
    """Submit one task per job, record each row as it finishes; return the wall time in s.

    ``previous`` holds the rows already in results.csv (by id); the file is
    rewritten at the end with them and the new rows.
    """
    from distributed import as_completed

    start = time.perf_counter()
    token = uuid.uuid4().hex[:8]
    futures = [
        client.submit(
            execute_job,
            job,
            str(out),
            runners[job.kind],
            key=f"batch-{job.kind}-{job.id}-{token}",
            pure=False,
        )
        for job in jobs
    ]
    by_key = {fut.key: job for fut, job in zip(futures, jobs)}
    results = out / RESULTS_NAME
    try:
        with open(results, "a", newline="", encoding="utf-8") as fh:
            writer = csv.DictWriter(fh, fieldnames=RESULT_COLUMNS, extrasaction="ignore", lineterminator="\n")
            for fut in as_completed(futures):
                job = by_key[fut.key]
                try:
                    row = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost task is a failed job, not a failed batch
                    row = _row(job, "failed", f"task: {one_line_error(exc)}", 0.0, {})
                    row["traceback"] = "".join(traceback.format_exception(exc))
                _record(out, job, row)
                writer.writerow(row)
                fh.flush()
                finished.append(row)
                fut.release()
                if progress is not None:
                    progress({k: v for k, v in row.items() if k != "traceback"})
    finally:
        for fut in futures:
            if not fut.done():
                fut.cancel()
        merged = dict(previous)
        for row in finished:
            merged[row["id"]] = row  # a retried job keeps its place, with its new row
        _write_results(results, merged.values())
    return time.perf_counter() - start


def _healed_results(out: Path, steps: Plan) -> dict[str, dict[str, str]]:
    """Rows of results.csv, completed from the job folders and failure records.

    A row cut short by a crash is dropped; a finished job without a row gets its
    row back from its ``_COMPLETE`` marker, a failed one from ``failed/<id>.json``.
    The file is rewritten (atomically, one header, current columns) only when
    something changed or jobs are about to be appended, so a rerun with nothing to
    do leaves it untouched.
    """
    results = out / RESULTS_NAME
    rows = read_results(results)
    kept = {k: r for k, r in rows.items() if r["status"] in ("ok", "failed") and r["kind"] in KINDS}
    changed = len(kept) != len(rows)
    for job in steps.complete:
        if job.id not in kept:
            try:
                marker = json.loads((out / job.id / COMPLETE_MARKER).read_text())["row"]
            except (ValueError, KeyError, OSError):
                continue
            kept[job.id] = {name: str(marker.get(name, "")) for name in RESULT_COLUMNS}
            changed = True
    for job in steps.failed_before:
        if job.id not in kept:
            try:
                record = json.loads((out / FAILED_DIR / f"{job.id}.json").read_text())
            except (ValueError, OSError):
                continue
            kept[job.id] = _row(job, "failed", str(record.get("error", "")), float(record.get("time_s", 0.0)), {})
            changed = True
    if changed or steps.to_run or not results.is_file():
        _write_results(results, kept.values())
    return kept


def _record(out: Path, job: Job, row: Mapping[str, Any]) -> None:
    """Keep ``OUT/failed/<id>.json`` in step with the job's last status."""
    record = out / FAILED_DIR / f"{job.id}.json"
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
        "finished_utc": _now(),
    }
    _write_text_atomic(record, json.dumps(content, indent=2, default=str) + "\n")


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


def _write_results(path: Path, rows) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=RESULT_COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    _write_text_atomic(path, buffer.getvalue())


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
        "finished_utc": _now(),
        **extra,
    }
    path = Path(out) / f"batch_{_check_kind(kind)}.json"
    _write_text_atomic(path, json.dumps(content, indent=2) + "\n")
    return path


def _marker_kind(folder: Path) -> str:
    try:
        return json.loads((folder / COMPLETE_MARKER).read_text())["row"]["kind"]
    except (ValueError, KeyError, TypeError, OSError):
        return "unknown"


def _remove_stale_tmp(out: Path) -> None:
    """Remove temporary job folders left by a run that died (we hold the lock)."""
    for tmp in out.glob(f"{TMP_PREFIX}*"):
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)


@contextmanager
def _lock(out: Path) -> Iterator[None]:
    path = out / LOCK_NAME
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started_utc": _now()}
    fd = _create_exclusive(path)
    if fd is None:
        try:
            holder = json.loads(path.read_text())
        except (ValueError, OSError):
            holder = {}
        if holder.get("host") == me["host"] and not _pid_alive(int(holder.get("pid", -1))):
            path.unlink(missing_ok=True)  # that run died; take over
            fd = _create_exclusive(path)
        if fd is None:
            raise ValueError(
                f"batch folder {out}: another run holds {path} (pid {holder.get('pid')} on "
                f"{holder.get('host')}); delete the file if that run is dead"
            )
    with os.fdopen(fd, "w") as fh:
        json.dump(me, fh)
    try:
        yield
    finally:
        path.unlink(missing_ok=True)


def _create_exclusive(path: Path) -> int | None:
    try:
        return os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        return None


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _write_text_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")
