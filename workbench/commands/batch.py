"""``workbench batch photometric|slices MANIFEST --out OUT``: many jobs on a Dask cluster.

Thin layer over :mod:`workbench.batch`: read the manifest (or discover the
jobs below a folder), open a local cluster or connect to a running scheduler,
run the jobs with a progress bar, print a short summary. Every number printed
is also in ``OUT/batch_<kind>.json``; per-job figures are in ``OUT/results.csv``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from pathlib import Path

from workbench import batch
from workbench.commands.common import add_command
from surfaces.validate import InputError

_DESCRIPTIONS = {
    "photometric": (
        "Run photometric.pipeline.reconstruct on many inputs. MANIFEST is a CSV (header row) or "
        "JSON-lines file, one job per row: 'input' (a DiLiGenT-style folder) or 'images' "
        "(';'-separated) + 'lights' (+ 'intensities', 'mask'), optional 'id', and pipeline "
        "options as further columns (integrator, pixel_size, ...; 'select' is 'triad' or "
        "';'-separated image names). A folder instead of a "
        "manifest runs every folder below it that holds a light_directions.txt."
    ),
    "slices": (
        "Run slices.pipeline.reconstruct on many inputs. MANIFEST is a CSV (header row) or "
        "JSON-lines file, one job per row: 'input' (an RTSTRUCT file, a contours.json or a CT "
        "folder with options hu_min/hu_max) and 'roi' (one name or ';'-separated names), "
        "optional 'id', and pipeline options as further columns (method, caps, rays, ...). "
        "A folder instead of a manifest runs every RTSTRUCT and contours.json below it."
    ),
}
_EPILOG = (
    "Each job writes OUT/<id> atomically; OUT/results.csv gets one row per job as it "
    "finishes; failures are kept in OUT/failed/<id>.json. A rerun skips complete and failed "
    "jobs (not re-listed); --retry-failed reruns only the failed ones. Exit code 1 when a "
    "job of this run failed. Multi-machine: start 'dask scheduler' on one host and "
    "'dask worker tcp://HOST:8786' on each machine (all seeing the input paths and OUT on a "
    "shared filesystem under the same names), then pass --scheduler tcp://HOST:8786."
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``photometric`` and ``slices`` to the ``batch`` group (see :mod:`workbench.commands`)."""
    for kind in batch.KINDS:
        parser = add_command(
            subparsers,
            kind,
            _runner(kind),
            help=f"run many {kind} jobs (manifest or folder) on a Dask cluster",
            description=_DESCRIPTIONS[kind],
            epilog=_EPILOG,
        )
        parser.add_argument(
            "manifest",
            metavar="MANIFEST",
            type=Path,
            help="CSV or JSON-lines manifest (one job per row), or a folder: every job below it",
        )
        parser.add_argument("--out", required=True, type=Path, help="batch output folder (created when missing)")
        parser.add_argument(
            "--scheduler",
            default="local",
            help="'local' (default: a new LocalCluster of --workers processes) or the address "
            "of a running scheduler, tcp://HOST:8786",
        )
        parser.add_argument(
            "--workers",
            type=int,
            default=None,
            help="worker processes of the local cluster (default: number of CPUs, "
            f"{os.cpu_count()} here); ignored with a tcp:// scheduler",
        )
        parser.add_argument(
            "--threads-per-worker",
            type=int,
            default=1,
            help="threads per local worker process (default 1)",
        )
        parser.add_argument(
            "--option",
            action="append",
            default=[],
            metavar="KEY=VALUE",
            help="pipeline option for every job, e.g. render=false (repeatable; a manifest "
            "column of the same name wins)",
        )
        parser.add_argument(
            "--retry-failed",
            action="store_true",
            help="run only the jobs that failed before (those with OUT/failed/<id>.json)",
        )


def _runner(kind: str):
    def run(args: argparse.Namespace) -> int:
        return _run(kind, args)

    return run


def _options(items: list[str]) -> dict:
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--option: expected KEY=VALUE, got {item!r}")
        options[key.strip()] = batch.coerce_value(value.strip())
    return options


def one_line_warnings() -> None:
    """Print every Python warning of this process as one ``workbench: warning:`` line on stderr.

    Run on each Dask worker of a batch (``client.run``): a library's multi-line
    warning (a SciPy RuntimeWarning with its source line) then reads as the
    command line's own warnings do, whichever worker process printed it.
    """
    import warnings

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        text = str(message).strip().splitlines()
        print(f"workbench: warning: {text[0] if text else category.__name__}", file=sys.stderr, flush=True)

    warnings.showwarning = show


@contextlib.contextmanager
def _quiet_shutdown():
    """Collect distributed's "Worker process still alive ..., killing" log lines instead of printing them.

    A local cluster closes after every job has reported; a worker still releasing
    memory or threads then is killed by its nanny, which logs a multi-line warning
    that reads like a failure. The caller prints one ``workbench: warning:`` line.
    """
    killed: list[str] = []

    class _Filter(logging.Filter):
        def filter(self, record: logging.LogRecord) -> bool:
            if "killing" in record.getMessage():
                killed.append(record.getMessage())
                return False
            return True

    logger = logging.getLogger("distributed.nanny")
    flt = _Filter()
    logger.addFilter(flt)
    try:
        yield killed
    finally:
        logger.removeFilter(flt)


def _run(kind: str, args: argparse.Namespace) -> int:
    from tqdm import tqdm

    jobs = batch.load_jobs(args.manifest, kind, _options(args.option))
    out = args.out.resolve()
    steps = batch.plan(jobs, out, args.retry_failed)
    print(
        f"{len(jobs)} {kind} job(s): {len(steps.to_run)} to run, {len(steps.complete)} complete "
        f"(skipped), {len(steps.failed_before) + len(steps.retried)} failed before"
        + (" (use --retry-failed)" if steps.failed_before else "")
        + (" (retrying them)" if steps.retried else "")
        + (f", {len(steps.pending)} never run (left for a run without --retry-failed)" if steps.pending else "")
    )
    dashboard, n_workers, address = None, 0, None
    if steps.to_run:
        with (_quiet_shutdown() as killed,
              batch.connect(args.scheduler, args.workers, args.threads_per_worker) as client):
            client.run(one_line_warnings)  # a library warning in a job: one line, as on the command line
            dashboard = batch.dashboard_link(client)
            n_workers = len(client.scheduler_info().get("workers", {}))
            address = client.scheduler.address
            print(f"scheduler {address} with {n_workers} worker(s)")
            if dashboard:
                print(f"dashboard: {dashboard}")
            # miniters=1, mininterval=0: redraw at every finished job, however unevenly they finish
            with tqdm(total=len(steps.to_run), unit="job", file=sys.stderr, dynamic_ncols=True, miniters=1,
                      mininterval=0) as bar:
                counts = {"ok": 0, "failed": 0}

                def progress(row: dict) -> None:
                    counts[row["status"]] = counts.get(row["status"], 0) + 1
                    elapsed = bar.format_dict["elapsed"]
                    rate = 60.0 * (bar.n + 1) / elapsed if elapsed > 0 else 0.0
                    bar.set_postfix(
                        ok=counts["ok"],
                        failed=counts["failed"],
                        jobs_per_min=f"{rate:.1f}",
                        refresh=False,
                    )
                    bar.update(1)
                    bar.refresh()

                report = batch.run_batch(jobs, out, client, retry_failed=args.retry_failed, progress=progress)
        if killed:
            print(f"workbench: warning: Dask stopped {len(killed)} worker process(es) still busy at the cluster's "
                  "shutdown (after every job had reported; no result is lost)", file=sys.stderr)
    else:
        report = batch.run_batch(jobs, out, retry_failed=args.retry_failed)
    path = batch.write_report(
        report,
        out,
        kind,
        complete_before=len(steps.complete),
        failed_before=len(steps.failed_before) + len(steps.retried),
        never_run=len(steps.pending),
        scheduler=args.scheduler,
        scheduler_address=address,
        n_workers=n_workers,
        threads_per_worker=args.threads_per_worker,
        retry_failed=args.retry_failed,
        dashboard=dashboard,
    )
    print(
        f"ran {report.ran}: {report.ok} ok, {report.failed} failed; {report.skipped} skipped; "
        f"{report.wall_s:.1f} s, {report.jobs_per_minute:.1f} jobs/min"
    )
    for row in report.rows:
        if row["status"] == "failed":
            print(f"  failed {row['id']}: {row['error']}")
    print(f"results: {out / batch.RESULTS_NAME}; figures: {path}")
    return 1 if report.failed else 0
