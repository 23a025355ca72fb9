"""The batch driver: plan a run from the state of ``OUT``, open a Dask client, run and record the jobs.

One Dask task per job (:func:`workbench.batch.runners.execute_job`); rows are
appended to ``OUT/results.csv`` as jobs finish and the file is rewritten with
the latest row of every job at the end. ``OUT/.batch.lock`` is held while a
run is going on, so two runs never share ``OUT``.
"""

from __future__ import annotations

import csv
import importlib.util
import os
import re
import shutil
import time
import traceback
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from surfaces.validate import InputError, positive
from workbench.batch.jobs import Job, check_job_id, job_folder
from workbench.batch.results import (
    FAILED_DIR,
    RESULT_COLUMNS,
    RESULTS_NAME,
    TMP_PREFIX,
    BatchReport,
    healed_results,
    is_complete,
    marker_kind,
    failed_figures,
    one_line_error,
    read_results,
    record_outcome,
    result_row,
    write_results,
)
from workbench.batch.runners import RUNNERS, execute_job
from workbench.runs.folder import hold_lock

LOCK_NAME = ".batch.lock"


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
    retried : tuple of Job
        Jobs with a failure record that a ``retry_failed`` run runs again (also in ``to_run``).
    """

    to_run: tuple[Job, ...]
    complete: tuple[Job, ...]
    failed_before: tuple[Job, ...]
    pending: tuple[Job, ...]
    retried: tuple[Job, ...] = ()


def plan(jobs: Sequence[Job], out: str | os.PathLike, retry_failed: bool = False,
         retry: Callable[[Job], bool] | None = None) -> Plan:
    """Split jobs by the state of ``OUT``: to run, complete, failed before, pending.

    Parameters
    ----------
    jobs : sequence of Job
        Jobs with unique ids.
    out : path
        Batch output folder (may not exist yet).
    retry_failed : bool, optional
        Run only the jobs with a failure record in ``OUT/failed``.
    retry : callable, optional
        A plain run (not ``retry_failed``) also runs again the failed jobs for which
        ``retry(job)`` is true (``workbench inspect``: those whose inputs changed).

    Returns
    -------
    Plan

    Raises
    ------
    InputError
        On an unsafe id (:func:`workbench.batch.jobs.check_job_id`), duplicate ids, a job folder
        that is a symbolic link, or when a complete folder under an id belongs to a job of
        another kind.
    """
    out = Path(out)
    ids = [check_job_id(job.id, f"job {job.id!r}", (FAILED_DIR, RESULTS_NAME)) for job in jobs]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise InputError(f"jobs: duplicate id(s) {', '.join(dup[:5])}")
    to_run, complete, failed_before, pending, retried = [], [], [], [], []
    for job in jobs:
        folder = job_folder(out, job.id)
        if is_complete(folder):
            done_kind = marker_kind(folder)
            if done_kind != job.kind:
                raise InputError(f"job {job.id}: {folder} holds a finished {done_kind} job, not {job.kind}")
            complete.append(job)
        elif (out / FAILED_DIR / f"{job.id}.json").is_file():
            again = retry_failed or (retry is not None and retry(job))
            (to_run if again else failed_before).append(job)
            if again:
                retried.append(job)
        else:
            (pending if retry_failed else to_run).append(job)
    return Plan(tuple(to_run), tuple(complete), tuple(failed_before), tuple(pending), tuple(retried))


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
        raise InputError(f"scheduler: expected 'local' or tcp://HOST:PORT, got {scheduler!r}")
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise InputError(f"scheduler {scheduler}: cannot connect ({one_line_error(exc)})") from None
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
    retry: Callable[[Job], bool] | None = None,
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
    retry : callable, optional
        :func:`plan`'s ``retry``: failed jobs a plain run runs again.

    Returns
    -------
    BatchReport

    Raises
    ------
    ValueError
        On duplicate ids, a kind without runner, another run holding ``OUT``.
    """
    out = prepare_out(out)
    runners = dict(runners or RUNNERS)
    missing = sorted({job.kind for job in jobs} - set(runners))
    if missing:
        raise InputError(f"runners: no runner for kind(s) {', '.join(missing)}")
    with _lock(out):
        _remove_stale_tmp(out)
        steps = plan(jobs, out, retry_failed, retry)
        skipped = len(jobs) - len(steps.to_run)
        previous = healed_results(out, steps.complete, steps.failed_before, rewrite=bool(steps.to_run))
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
                    row = result_row(job, "failed", f"task: {one_line_error(exc)}", 0.0, failed_figures(job))
                    row["traceback"] = "".join(traceback.format_exception(exc))
                record_outcome(out, job, row)
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
        write_results(results, merged.values())
    return time.perf_counter() - start


def prepare_out(out: str | os.PathLike) -> Path:
    """Create the batch output folder and check that its bookkeeping stays inside it.

    Parameters
    ----------
    out : path
        Batch output folder (created with its parents when missing).

    Returns
    -------
    Path
        The folder, absolute.

    Raises
    ------
    InputError
        ``out`` is an existing file, cannot be created (read-only, no permission), or its
        ``results.csv`` or ``failed`` is a symbolic link (nothing is written through a link).
    """
    out = check_out(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out: cannot create {out} ({exc.strerror or one_line_error(exc)})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"--out: {out} is not writable")
    return out


def check_out(out: str | os.PathLike) -> Path:
    """Check a batch output folder without creating anything (:func:`prepare_out` also creates it).

    Parameters
    ----------
    out : path
        Batch output folder (may not exist yet).

    Returns
    -------
    Path
        The folder, absolute.

    Raises
    ------
    InputError
        ``out`` is an existing file, or its ``results.csv`` or ``failed`` is a symbolic link.
    """
    out = Path(out).resolve()
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} exists and is not a folder")
    for name in (RESULTS_NAME, FAILED_DIR):
        if (out / name).is_symlink():
            raise InputError(f"--out: {out / name} is a symbolic link; the batch writes only inside {out} "
                             "(remove the link)")
    return out


def heal(jobs: Sequence[Job], out: str | os.PathLike) -> int:
    """Give every finished job without a results.csv row its row, without running anything.

    A job folder completed by a task whose driver was killed (its scheduler ran the task
    to its end) has no row; :func:`run_batch` heals such rows when it runs, and this does
    the same when there is nothing to run (a restarted ``workbench inspect watch``).

    Parameters
    ----------
    jobs : sequence of Job
        Jobs with unique, safe ids.
    out : path
        Batch output folder; nothing happens when it does not exist.

    Returns
    -------
    int
        Rows added or replaced.
    """
    out = Path(out).resolve()
    if not out.is_dir():
        return 0
    with _lock(out):
        steps = plan(jobs, out)
        before = read_results(out / RESULTS_NAME)
        after = healed_results(out, steps.complete, steps.failed_before, rewrite=False)
    return sum(before.get(k) != row for k, row in after.items())


def _remove_stale_tmp(out: Path) -> None:
    """Remove temporary job folders left by a run that died (we hold the lock); a link is unlinked, never followed."""
    for tmp in out.glob(f"{TMP_PREFIX}*"):
        if tmp.is_symlink():
            tmp.unlink(missing_ok=True)
        elif tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)


def _lock(out: Path):
    return hold_lock(out / LOCK_NAME, f"batch folder {out}: another run holds {out / LOCK_NAME}")
