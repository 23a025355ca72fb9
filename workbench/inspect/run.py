"""Many parts through the batch driver (:mod:`workbench.batch`): plan, resume, failures, Dask.

Each part is one batch job of kind ``inspect`` (:func:`run_inspect_job`, the body of one
Dask task, calls :func:`workbench.inspect.part.inspect_part`); the driver gives it its
folder ``OUT/<part>`` atomically, appends its row to ``OUT/results.csv`` as it finishes
(columns :data:`workbench.batch.RESULT_COLUMNS`, the ``inspect`` figures among them),
records a failing part in ``OUT/failed/<part>.json`` and goes on, and skips finished and
failed parts on a rerun. After the run, ``OUT/report.html``
(:func:`workbench.inspect.report.write_inspection_report`) and ``OUT/inspect_run.json``
(the run's figures) are written.

``PARTS`` is a folder of part folders (every sub-folder holding image files) or a manifest:
CSV with a header, or JSON lines, with ``input`` (a part folder, relative to the
manifest) and an optional ``id``.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from surfaces.io import write_json
from surfaces.validate import InputError
from workbench.batch import (
    FAILED_DIR,
    NOT_MEASURED,
    RESULTS_NAME,
    BatchReport,
    Job,
    check_job_id,
    job_id,
    prepare_out,
    run_batch,
)
from workbench.inspect.part import IMAGE_SUFFIXES, check_options, load_rig
from workbench.inspect.spec import Spec, check_spec_field, load_spec, parse_spec

__all__ = ["KIND", "RUN_FILE", "InspectionRun", "check_run_options", "input_signature",
           "load_parts", "make_jobs", "retry_changed", "retry_rule", "run_inspect_job", "run_inspection", "scan_parts"]

#: the batch job kind of one part
KIND = "inspect"
#: the run's figures, beside results.csv
RUN_FILE = "inspect_run.json"
_RESERVED = {FAILED_DIR, RESULTS_NAME, "figures", "report.html", RUN_FILE}


def _holds_images(folder: Path) -> bool:
    return any(p.suffix.lower() in IMAGE_SUFFIXES for p in folder.iterdir() if p.is_file())


def input_signature(folder) -> str:
    """A part's inputs in one word: sha256 of its image files' names, sizes and modification times.

    ``filenames.txt`` counts too. A failed part whose signature changed since it failed (an
    image re-captured, a missing one arrived) is measured again (:func:`retry_changed`).

    Parameters
    ----------
    folder : str or Path
        A part folder.

    Returns
    -------
    str
        64 hex digits; that of an empty signature when the folder cannot be listed.
    """
    entries = []
    try:
        for p in sorted(Path(folder).iterdir()):
            if p.is_file() and (p.suffix.lower() in IMAGE_SUFFIXES or p.name == "filenames.txt"):
                st = p.stat()
                entries.append([p.name, st.st_size, st.st_mtime_ns])
    except OSError:
        entries = []
    return hashlib.sha256(json.dumps(entries).encode()).hexdigest()


def scan_parts(inbox) -> tuple[list[tuple[str, Path]], list[tuple[str, str]]]:
    """The part folders of an inbox, and the folders that cannot be parts with the reason.

    Like :func:`load_parts` on a folder, but one bad folder never stops the others: a folder
    that cannot be listed, whose id is a name the output folder uses (``failed``, ...), or
    whose id collides with another's (``a b`` and ``a_b`` both give ``a_b``) is left out and
    reported.

    Parameters
    ----------
    inbox : str or Path

    Returns
    -------
    parts : list of (str, Path)
        Good parts, sorted by folder name.
    skipped : list of (str, str)
        ``(folder name, reason)`` of every folder left out.
    """
    src = Path(inbox)
    found: dict[str, list[Path]] = {}
    skipped: list[tuple[str, str]] = []
    try:
        folders = sorted(p for p in src.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError as exc:
        return [], [(src.name, f"cannot list the inbox ({exc.strerror or exc})")]
    for folder in folders:
        try:
            if not _holds_images(folder):
                continue
        except OSError as exc:
            skipped.append((folder.name, f"cannot be read ({exc.strerror or exc})"))
            continue
        pid = job_id(folder, src)
        if pid in _RESERVED:
            skipped.append((folder.name, f"its id {pid!r} is a name the output folder uses; rename the folder"))
            continue
        found.setdefault(pid, []).append(folder)
    parts = []
    for pid, folders_of in found.items():
        if len(folders_of) > 1:
            names = " and ".join(repr(f.name) for f in folders_of)
            skipped += [(f.name, f"its id {pid!r} is also that of {names}; rename one") for f in folders_of]
        else:
            parts.append((pid, folders_of[0].resolve()))
    return sorted(parts, key=lambda item: item[1].name), skipped


def _manifest_rows(path: Path) -> list[dict]:
    text = path.read_text()
    if path.suffix.lower() in (".jsonl", ".json", ".ndjson"):
        rows = []
        for k, line in enumerate(text.splitlines(), start=1):
            if line.strip() and not line.lstrip().startswith("#"):
                try:
                    row = json.loads(line)
                except json.JSONDecodeError as exc:
                    raise InputError(f"manifest {path} line {k}: not JSON ({exc})") from None
                if not isinstance(row, dict):
                    raise InputError(f"manifest {path} line {k}: expected an object with 'input'")
                rows.append(row)
        return rows
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return [{k.strip(): (v or "").strip() for k, v in row.items() if k} for row in csv.DictReader(io.StringIO(
        "\n".join(lines)))]


def load_parts(source) -> list[tuple[str, Path]]:
    """The parts of a run: ``(id, folder)`` from a folder of part folders or a manifest.

    Parameters
    ----------
    source : str or Path
        A folder (every sub-folder with image files is a part, sorted by name) or a
        manifest (CSV with a header, or JSON lines: ``input``, optional ``id``).

    Returns
    -------
    list of (str, Path)
        Unique, filesystem-safe ids and absolute part folders.

    Raises
    ------
    FileNotFoundError
        ``source`` does not exist.
    InputError
        No part found, a manifest row without ``input`` or with unknown columns, an unsafe
        ``id`` (:func:`workbench.batch.check_job_id`: ``..``, ``.``, absolute, with a separator),
        or repeated ids.
    """
    src = Path(source)
    if not src.exists():
        raise FileNotFoundError(f"PARTS: {src} does not exist")
    parts: list[tuple[str, Path]] = []
    if src.is_dir():
        for folder in sorted(p for p in src.iterdir() if p.is_dir() and not p.name.startswith(".")):
            if _holds_images(folder):
                parts.append((job_id(folder, src), folder.resolve()))
        if not parts:
            raise InputError(f"PARTS: {src} holds no part folder (a sub-folder with one image per light)")
    else:
        for k, row in enumerate(_manifest_rows(src), start=1):
            unknown = sorted(set(row) - {"input", "id"})
            if unknown:
                raise InputError(f"manifest {src} row {k}: unknown column(s) {', '.join(unknown)} (known: input, id)")
            if not row.get("input"):
                raise InputError(f"manifest {src} row {k}: needs 'input' (a part folder)")
            folder = (src.parent / str(row["input"])).resolve()
            pid = (check_job_id(row["id"], f"manifest {src} row {k}", _RESERVED) if row.get("id")
                   else job_id(folder, src.parent))
            parts.append((pid, folder))
        if not parts:
            raise InputError(f"manifest {src}: no part")
    ids = [pid for pid, _ in parts]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise InputError(f"PARTS: repeated part id(s) {', '.join(dup[:5])}")
    bad = sorted(set(ids) & _RESERVED)
    if bad:
        raise InputError(f"PARTS: part id {bad[0]!r} is a name the run's output folder uses")
    return parts


def _frozen(spec) -> Spec:
    return spec if isinstance(spec, Spec) else load_spec(spec)


def check_run_options(options: dict | None, rig) -> dict:
    """Check a run's reconstruction options before any part: names, numbers, uncertainty, work size.

    Parameters
    ----------
    options : dict or None
        ``--option`` items and ``uncertainty`` (a dict of
        :class:`photometric.uncertainty.Tolerances` fields).
    rig : str, Path or photometric.rig.Rig
        The rig (its image size sizes the Monte Carlo work).

    Returns
    -------
    dict
        The options, unchanged.

    Raises
    ------
    InputError
        An unknown or reserved option (:func:`workbench.inspect.part.check_options`), a number
        that is NaN or infinite, a bad tolerance, or Monte Carlo work (``mc_samples`` x image
        pixels) above :data:`photometric.uncertainty.MC_PIXEL_SAMPLES_LIMIT` (the message names the size).
    """
    from photometric.uncertainty import Tolerances, check_monte_carlo_size

    opts = check_options(dict(options or {}))
    for key, value in opts.items():
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"--option {key}: expected a finite number, got {value}")
    unc = opts.get("uncertainty")
    if unc is None:
        return opts
    for key, value in (unc.items() if isinstance(unc, dict) else ()):
        if isinstance(value, float) and not math.isfinite(value):
            raise InputError(f"--{key.replace('_', '-')}: expected a finite number, got {value}")
    tol = unc if isinstance(unc, Tolerances) else Tolerances(**unc)
    check_monte_carlo_size(tol, load_rig(rig).image_size)
    return opts


def make_jobs(parts, rig, spec, *, keep_arrays: bool = False, options: dict | None = None) -> list[Job]:
    """One batch job per part (kind :data:`KIND`); paths absolute, so any worker reads them.

    The spec is frozen into every job: its content (``spec``) and its hash (``spec_sha256``,
    :attr:`workbench.inspect.spec.Spec.sha256`), so editing spec.json during a run changes
    no part of it. Each job also carries its part's :func:`input_signature`.

    Parameters
    ----------
    parts : list of (str, Path)
        :func:`load_parts`.
    rig : str or Path
        ``rig.json``.
    spec : str, Path or Spec
        ``spec.json`` (read once here) or a spec read before.
    keep_arrays : bool, optional
    options : dict, optional
        Reconstruction options (:func:`workbench.inspect.part.check_options`).

    Returns
    -------
    list of Job
    """
    frozen = _frozen(spec)
    common = {"rig": str(Path(rig).resolve()), "spec": frozen.to_dict(), "spec_sha256": frozen.sha256,
              "keep_arrays": bool(keep_arrays), **(options or {})}
    return [Job(pid, KIND, str(folder), {**common, "input_signature": input_signature(folder)})
            for pid, folder in parts]


def retry_changed(out) -> Callable[[Job], bool]:
    """The retry rule of inspection runs: a failed part is measured again when its inputs changed.

    Parameters
    ----------
    out : str or Path
        The run's output folder (its ``failed/<id>.json`` records hold the signature of the
        inputs that failed).

    Returns
    -------
    callable
        ``retry(job) -> bool``: True when the job's ``input_signature`` differs from the
        recorded one (a record without one counts as changed only when it is unreadable).
    """
    base = Path(out)

    def retry(job: Job) -> bool:
        try:
            record = json.loads((base / FAILED_DIR / f"{job.id}.json").read_text())
            before = (record.get("options") or {}).get("input_signature")
        except (OSError, ValueError, AttributeError):
            return True
        return before is not None and before != job.options.get("input_signature")

    return retry


def run_inspect_job(job: Job, out_dir: Path) -> dict:
    """Inspect one part into ``out_dir`` (a batch runner: ``runner(job, out_dir) -> summary``).

    Parameters
    ----------
    job : Job
        A job of :func:`make_jobs`.
    out_dir : Path
        Empty folder (the driver renames it to ``OUT/<id>`` when complete).

    Returns
    -------
    dict
        :func:`workbench.inspect.part.inspect_part`'s key figures.

    Notes
    -----
    The workers of a run share the machine's cores (one worker per core by default): the
    part runs on one thread, BLAS/OpenMP pools and OpenCV held to 1 thread too
    (restored afterwards), so that workers do not oversubscribe the cores.
    """
    import cv2
    from threadpoolctl import threadpool_limits

    from workbench.inspect.part import inspect_part

    opts = dict(job.options)
    rig, spec = opts.pop("rig"), opts.pop("spec")
    spec = parse_spec(spec, "spec") if isinstance(spec, dict) else spec  # frozen by make_jobs
    sha = opts.pop("spec_sha256", None)
    opts.pop("input_signature", None)
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with threadpool_limits(limits=1):
            summary = inspect_part(job.input, out_dir, rig, spec, part_id=job.id, threads=1, **opts)
    finally:
        cv2.setNumThreads(before)
    return summary if sha is None else {**summary, "spec_sha256": sha}


def retry_rule(retry_failed, out) -> Callable[[Job], bool]:
    """Which failed parts a run measures again.

    Parameters
    ----------
    retry_failed : bool or callable
        True: every one (``--retry-failed``); False: those whose inputs changed
        (:func:`retry_changed`); a callable ``retry(job) -> bool`` is returned as it is.
    out : str or Path
        The run's output folder.

    Returns
    -------
    callable
    """
    if callable(retry_failed):
        return retry_failed
    return (lambda job: True) if retry_failed else retry_changed(out)


@dataclass(frozen=True)
class InspectionRun:
    """Figures of one inspection run (also in ``OUT/inspect_run.json``).

    Attributes
    ----------
    batch : workbench.batch.BatchReport
        Parts run, ok, failed, skipped, wall time.
    verdicts : dict
        ``pass``, ``fail``, ``uncertain``: counts over the parts this run finished.
    parts_per_second : float
        Parts finished per second of wall time (cluster start excluded).
    report : Path
        ``OUT/report.html``.
    """

    batch: BatchReport
    verdicts: dict
    parts_per_second: float
    report: Path


def run_inspection(
    parts,
    rig,
    spec,
    out,
    *,
    keep_arrays: bool = False,
    options: dict | None = None,
    client: Any = None,
    scheduler: str = "local",
    workers: int | None = None,
    progress: Callable[[dict], None] | None = None,
    command: str = "workbench inspect run",
    retry_failed: bool | Callable[[Job], bool] = False,
) -> InspectionRun:
    """Inspect many parts: check the spec, rig and options first, then run the parts on Dask.

    Parameters
    ----------
    parts : str, Path or list of (str, Path)
        ``PARTS`` (:func:`load_parts`) or its parts.
    rig : str or Path
        ``rig.json`` (checked before anything is written).
    spec : str, Path or Spec
        ``spec.json``: read once, checked against the rig's field of view
        (:func:`workbench.inspect.spec.check_spec_field`) before anything is written, and
        frozen for the whole run (its hash goes into every row and result.json).
    out : str or Path
        Output folder.
    keep_arrays : bool, optional
        Heavy outputs per part.
    options : dict, optional
        Reconstruction options for every part.
    client : distributed.Client, optional
        Use this client (else one is opened with ``scheduler`` and ``workers``).
    scheduler, workers
        :func:`workbench.batch.connect`.
    progress : callable, optional
        Called with each finished part's results.csv row.
    command : str, optional
        The command line, for the report.
    retry_failed : bool or callable, optional
        True: measure again every part that failed before; a callable ``retry(job) -> bool``
        picks them; False (default): only those whose inputs changed (:func:`retry_changed`).

    Returns
    -------
    InspectionRun
    """
    frozen = _frozen(spec)
    rig_obj = load_rig(rig)
    check_spec_field(frozen, rig_obj.image_size, rig_obj.camera.nominal_pixel_mm())
    opts = check_run_options(options, rig_obj)
    found = load_parts(parts) if isinstance(parts, (str, os.PathLike)) else list(parts)
    jobs = make_jobs(found, rig, frozen, keep_arrays=keep_arrays, options=opts)
    out = prepare_out(out)
    report = run_batch(jobs, out, client, scheduler=scheduler, workers=workers, runners={KIND: run_inspect_job},
                       progress=progress, retry=retry_rule(retry_failed, out))
    verdicts = {v: sum(row.get("verdict") == v for row in report.rows)
                for v in ("pass", "fail", "uncertain", NOT_MEASURED)}
    rate = report.ran / report.wall_s if report.wall_s > 0 else 0.0
    from workbench.inspect.report import collect_results, lot_quality_flags, write_inspection_report

    page = write_inspection_report(out, command)
    rows, results = collect_results(out)
    quality_flags = lot_quality_flags(results, [row for row in rows.values() if row["status"] == "failed"])
    write_json(Path(out) / RUN_FILE, {
        "n_parts": report.n_jobs, "ran": report.ran, "ok": report.ok, "failed": report.failed,
        "skipped": report.skipped, "verdicts": verdicts, "wall_s": round(report.wall_s, 3),
        "parts_per_second": round(rate, 4), "results": RESULTS_NAME, "report": page.name,
        "rig": str(Path(rig).resolve()), "spec": str(Path(spec).resolve()) if not isinstance(spec, Spec) else None,
        "spec_sha256": frozen.sha256, "keep_arrays": bool(keep_arrays),
        "options": opts, "scheduler": scheduler if client is None else "client",
        "quality_flags": quality_flags,
    })
    return InspectionRun(report, verdicts, rate, page)
