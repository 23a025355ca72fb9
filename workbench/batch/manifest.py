"""Batch manifests: CSV or JSON-lines files of jobs, or every job found below a folder.

A manifest names one job per row (see :func:`read_manifest`); a folder instead
of a manifest means every job found below it (see :func:`discover_jobs`). Ids
are filesystem-safe and unique within a batch; relative paths are taken from
the manifest's folder; options are checked against the pipeline's signature.
"""

from __future__ import annotations

import csv
import inspect
import io
import json
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from workbench.batch.jobs import Job, check_job_id, check_kind
from workbench.batch.results import COMPLETE_MARKER, FAILED_DIR, RESULTS_NAME
from workbench.batch.runners import pipeline
from surfaces.validate import InputError, reads_file

# manifest columns holding file paths (resolved against the manifest's folder)
_PATH_OPTIONS: dict[str, tuple[str, ...]] = {
    "photometric": ("lights", "intensities", "mask"),
    "slices": (),
}
_RESERVED_IDS = frozenset({FAILED_DIR, RESULTS_NAME})


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


@reads_file("manifest")
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
    ``caps``, ``rays``, ...); a photometric ``select`` is ``triad`` or image
    names (a list, or names separated by ``;``); in a CSV, numbers and ``true``/``false`` are
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
    kind = check_kind(kind)
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
        raise InputError(f"manifest {path}: no job rows")
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
    kind = check_kind(kind)
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
        raise InputError(f"job folder {root}: no {what} found below it")
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

    Examples
    --------
    >>> job_id("/data/p7/rtstruct.dcm", "/data", ["Heart", "Lt Lung"])
    'p7-rtstruct-Heart-Lt_Lung'
    >>> job_id("/data/run 1/triad#3", "/data")
    'run_1-triad_3'
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


def _csv_rows(text: str, path: Path) -> list[tuple[int, dict[str, Any]]]:
    lines = [ln for ln in text.splitlines() if not ln.lstrip().startswith("#")]
    reader = csv.DictReader(io.StringIO("\n".join(lines)))
    if not reader.fieldnames:
        raise InputError(f"manifest {path}: no header row")
    header = [(name or "").strip() for name in reader.fieldnames]
    if any(not name for name in header) or len(set(header)) != len(header):
        raise InputError(f"manifest {path}: header has empty or repeated column names: {header}")
    rows = []
    for raw in reader:
        if None in raw:
            raise InputError(f"manifest {path} line {reader.line_num}: more cells than header columns")
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
            raise InputError(f"manifest {path} line {line_no}: not a JSON object ({exc.msg})") from None
        if not isinstance(row, dict):
            raise InputError(  # noqa: TRY004 - bad manifest content is a ValueError for the CLI
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

    Examples
    --------
    >>> [coerce_value(v) for v in ("true", "32", "0.5", "Lt Lung")]
    [True, 32, 0.5, 'Lt Lung']
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
        raise InputError(  # noqa: TRY004 - bad manifest content is a ValueError for the CLI
            f"{where}: {name} must be a list or ';'-separated text, got {value!r}"
        )
    items = [str(v).strip() for v in items if str(v).strip()]
    if not items:
        raise InputError(f"{where}: {name} is empty")
    return items


def _resolve(value: Any, base: Path, where: str, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{where}: {name} must be a path, got {value!r}")
    p = Path(value.strip()).expanduser()
    return str(p if p.is_absolute() else (base / p).resolve())


def _jobs_from_row(row: dict[str, Any], kind: str, base: Path, where: str) -> list[Job]:
    row = dict(row)
    row_kind = row.pop("kind", kind)
    if row_kind != kind:
        raise InputError(f"{where}: kind {row_kind!r} in a {kind} batch")
    given_id = row.pop("id", None)
    rois: list[str | None] = [None]
    if kind == "photometric":
        folder, images = row.pop("input", None), row.pop("images", None)
        if (folder is None) == (images is None):
            raise InputError(f"{where}: give either 'input' (a folder) or 'images' (+ 'lights'), not both or neither")
        if images is not None:
            if "lights" not in row:
                raise InputError(f"{where}: 'images' needs a 'lights' file")
            source: str | tuple[str, ...] = tuple(
                _resolve(v, base, where, "images") for v in _as_list(images, where, "images")
            )
            id_path = Path(source[0]).parent
        else:
            source = _resolve(folder, base, where, "input")
            id_path = Path(source)
    else:
        if "input" not in row:
            raise InputError(f"{where}: missing 'input' (structure set, contours.json or CT folder)")
        source = _resolve(row.pop("input"), base, where, "input")
        id_path = Path(source)
        if "roi" in row:
            rois = list(_as_list(row.pop("roi"), where, "roi"))
        elif source.lower().endswith(".dcm") and Path(source).is_file():
            rois = _rois_with_contours(Path(source)) or [None]
    if kind == "photometric" and row.get("select") is not None and row["select"] != "triad":
        row["select"] = _as_list(row["select"], where, "select")
    options = {  # a path option may also be a number (a scalar intensity)
        name: _resolve(value, base, where, name) if name in _PATH_OPTIONS[kind] and isinstance(value, str) else value
        for name, value in row.items()
    }
    _check_options(kind, options, where)
    if given_id is not None:
        check_job_id(given_id, where, _RESERVED_IDS)
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
    params = inspect.signature(pipeline(kind)).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    names = list(params)[2:]  # the input and the output folder come first
    unknown = sorted(set(options) - set(names))
    if unknown:
        raise InputError(
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
