"""Batches of photometric or slices jobs on a Dask cluster (``workbench batch``).

A *manifest* (CSV with a header row, or JSON lines) names one job per row; a
folder instead of a manifest means every job found below it. Each job is one
Dask task that reads its data from its paths (no arrays travel through the
scheduler), calls the pipeline that writes a result folder
(:func:`workbench.runs.photometric.reconstruct_to_folder` or
:func:`workbench.runs.slices.reconstruct_to_folder`) and writes its own folder ``OUT/<id>``
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

Modules: :mod:`~workbench.batch.jobs` (the :class:`Job` record),
:mod:`~workbench.batch.manifest` (manifests, discovery, ids),
:mod:`~workbench.batch.runners` (one job through its pipeline, atomically),
:mod:`~workbench.batch.results` (results.csv, failure records, run figures),
:mod:`~workbench.batch.driver` (planning, the Dask client, the run).

The same code runs on a :class:`distributed.LocalCluster` or on any running
cluster (``tcp://HOST:8786``); with several machines every worker must see the
input paths and ``OUT`` under the same names (a shared filesystem).
"""


from workbench.batch.driver import (
    LOCK_NAME,
    Plan,
    check_out,
    connect,
    dashboard_link,
    heal,
    plan,
    prepare_out,
    run_batch,
)
from workbench.batch.jobs import ID_PATTERN, KINDS, Job, check_job_id, job_folder
from workbench.batch.manifest import coerce_value, discover_jobs, job_id, load_jobs, read_manifest
from workbench.batch.results import (
    COMPLETE_MARKER,
    FAILED_DIR,
    FIGURES,
    NOT_MEASURED,
    RESULT_COLUMNS,
    RESULTS_NAME,
    TMP_PREFIX,
    BatchReport,
    failed_figures,
    is_complete,
    key_figures,
    one_line_error,
    read_results,
    write_report,
)
from workbench.batch.runners import RUNNERS, execute_job, run_photometric, run_slices

__all__ = [
    "COMPLETE_MARKER",
    "FAILED_DIR",
    "FIGURES",
    "ID_PATTERN",
    "KINDS",
    "NOT_MEASURED",
    "LOCK_NAME",
    "RESULTS_NAME",
    "RESULT_COLUMNS",
    "RUNNERS",
    "TMP_PREFIX",
    "BatchReport",
    "Job",
    "Plan",
    "coerce_value",
    "connect",
    "dashboard_link",
    "discover_jobs",
    "check_job_id",
    "check_out",
    "execute_job",
    "failed_figures",
    "heal",
    "is_complete",
    "job_folder",
    "job_id",
    "key_figures",
    "load_jobs",
    "one_line_error",
    "plan",
    "prepare_out",
    "read_manifest",
    "read_results",
    "run_batch",
    "run_photometric",
    "run_slices",
    "write_report",
]
