"""Job runners: one job of each kind through its pipeline, into its own folder, atomically.

:func:`pipeline` is the one place that names the pipeline entry point of each
kind; the runners, and the manifest's option check, go through it.
:func:`execute_job` is the body of one Dask task: it runs a runner into a
temporary folder and renames it to ``OUT/<id>`` once the ``_COMPLETE`` marker
is written.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import time
import traceback
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from surfaces.io import write_json
from workbench.batch.jobs import Job, check_kind, job_folder
from surfaces.validate import InputError
from workbench.batch.results import (
    COMPLETE_MARKER,
    TMP_PREFIX,
    failed_figures,
    is_complete,
    key_figures,
    now_utc,
    one_line_error,
    result_row,
)


def pipeline(kind: str) -> Callable[..., dict]:
    """Return the file-writing pipeline entry point of a job kind.

    Both take the input and the output folder first, then keyword options, and
    return the summary dictionary they also write to ``summary.json``.

    Parameters
    ----------
    kind : {"photometric", "slices"}
        Job kind.

    Returns
    -------
    callable
        :func:`workbench.runs.photometric.reconstruct_to_folder` or
        :func:`workbench.runs.slices.reconstruct_to_folder`.
    """
    if check_kind(kind) == "photometric":
        from workbench.runs.photometric import reconstruct_to_folder

        return reconstruct_to_folder
    from workbench.runs.slices import reconstruct_to_folder as slices_to_folder

    return slices_to_folder


def run_photometric(job: Job, out_dir: Path) -> dict:
    """Run one photometric job: the photometric :func:`pipeline` into ``out_dir``.

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
    # execute_job already builds the job's folder aside and swaps it in
    summary = dict(pipeline("photometric")(source, out_dir, atomic=False, **job.options))
    if "max_depth_mm" not in summary:
        # the pipeline lists its defects in defects.json; the row reports the deepest
        defects = json.loads((Path(out_dir) / "defects.json").read_text())["defects"]
        summary["max_depth_mm"] = max((float(d["max_depth_mm"]) for d in defects), default=0.0)
    return summary


def run_slices(job: Job, out_dir: Path) -> dict:
    """Run one slices job: the slices :func:`pipeline` into ``out_dir``.

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
    return pipeline("slices")(job.input, out_dir, roi=job.roi, atomic=False, **job.options)


#: the job runner table: kind -> callable(job, out_dir) -> summary dict
RUNNERS: dict[str, Callable[[Job, Path], dict]] = {
    "photometric": run_photometric,
    "slices": run_slices,
}


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
    start = time.perf_counter()
    try:  # the id is checked before any path is built from it: nothing is created or removed outside OUT
        final = job_folder(out, job.id)
    except InputError as exc:
        row = result_row(job, "failed", one_line_error(exc), 0.0, failed_figures(job))
        row["traceback"] = ""
        return row
    tmp = out / f"{TMP_PREFIX}{job.id}-{uuid.uuid4().hex[:12]}"
    try:
        tmp.mkdir(parents=True)
        summary = runner(job, tmp)
        if not isinstance(summary, Mapping):
            raise TypeError(f"the {job.kind} pipeline returned {type(summary).__name__}, not a summary dict")
        elapsed = time.perf_counter() - start
        row = result_row(job, "ok", "", elapsed, key_figures(job.kind, summary))
        marker = {
            "row": row,
            "input": job.input,
            "roi": job.roi,
            "options": job.options,
            "host": socket.gethostname(),
            "finished_utc": now_utc(),
        }
        write_json(tmp / COMPLETE_MARKER, marker)
        if is_complete(final):
            # another task finished this job meanwhile (a watch killed and restarted while its scheduler
            # kept running the first task): keep that result, drop this copy
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            if final.exists():  # an incomplete leftover under this id: replace it
                shutil.rmtree(final)
            try:
                os.replace(tmp, final)
            except OSError:
                if not is_complete(final):  # not a twin task that won the race
                    raise
                shutil.rmtree(tmp, ignore_errors=True)
    except Exception as exc:  # noqa: BLE001 - any job error is recorded, and the batch goes on
        shutil.rmtree(tmp, ignore_errors=True)
        row = result_row(job, "failed", one_line_error(exc), time.perf_counter() - start, failed_figures(job))
        row["traceback"] = traceback.format_exc()
        return row
    row["traceback"] = ""
    return row
