"""Tests of :mod:`workbench.batch.driver`: planning from ``OUT``, the lock, the client and the run."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

import pytest

from workbench.batch import FAILED_DIR, LOCK_NAME, RESULTS_NAME, Job, connect, plan, read_results, run_batch
from workbench.batch.results import COMPLETE_MARKER


def _finish(out: Path, job_id: str, kind: str) -> None:
    (out / job_id).mkdir(parents=True)
    (out / job_id / COMPLETE_MARKER).write_text(json.dumps({"row": {"kind": kind}}))


def test_plan_splits_jobs_by_the_state_of_out(tmp_path):
    jobs = [Job(name, "slices", f"/d/{name}") for name in ("done", "broken", "new")]
    _finish(tmp_path, "done", "slices")
    (tmp_path / FAILED_DIR).mkdir()
    (tmp_path / FAILED_DIR / "broken.json").write_text("{}")
    steps = plan(jobs, tmp_path)
    assert [[j.id for j in part] for part in (steps.to_run, steps.complete, steps.failed_before, steps.pending)] == [
        ["new"], ["done"], ["broken"], []]
    retry = plan(jobs, tmp_path, retry_failed=True)
    assert [[j.id for j in part] for part in (retry.to_run, retry.complete, retry.failed_before, retry.pending)] == [
        ["broken"], ["done"], [], ["new"]]
    # the jobs that failed before are still counted as such when they are retried
    assert [j.id for j in retry.retried] == ["broken"] and steps.retried == ()
    assert plan(jobs, tmp_path / "not yet").to_run == tuple(jobs)


def test_plan_refuses_duplicates_and_a_folder_of_another_kind(tmp_path):
    with pytest.raises(ValueError, match="duplicate id"):
        plan([Job("a", "slices", "/x"), Job("a", "slices", "/y")], tmp_path)
    _finish(tmp_path, "a", "photometric")
    with pytest.raises(ValueError, match="holds a finished photometric job, not slices"):
        plan([Job("a", "slices", "/x")], tmp_path)


def test_lock_refuses_a_live_run_and_takes_over_a_dead_one(tmp_path):
    lock = tmp_path / LOCK_NAME
    lock.write_text(json.dumps({"pid": os.getppid(), "host": socket.gethostname()}))
    with pytest.raises(ValueError, match="another run holds"):
        run_batch([], tmp_path)
    lock.write_text(json.dumps({"pid": 2**22 + 12345, "host": socket.gethostname()}))
    report = run_batch([], tmp_path)
    assert report.ran == 0 and not lock.exists()


def test_run_batch_needs_a_runner_for_every_kind(tmp_path):
    with pytest.raises(ValueError, match="no runner for kind"):
        run_batch([Job("a", "slices", "/x")], tmp_path, runners={"photometric": _toy_runner})


@pytest.mark.parametrize("address", ["tcp://nohost", "http://x:8786", "localhost:8786", "tcp://a b:1"])
def test_connect_rejects_bad_addresses(address):
    with pytest.raises(ValueError, match="scheduler"):
        with connect(address):
            pass


def _toy_runner(job: Job, out_dir: Path) -> dict:
    if job.options.get("fail"):
        raise ValueError(f"{job.id}: told to fail")
    (out_dir / "volume.txt").write_text(str(job.options["volume"]))
    return {"volume_mm3": float(job.options["volume"]), "n_bodies": 1}


@pytest.fixture(scope="module")
def threads_client():
    """An in-process Dask client: the driver's bookkeeping without worker processes."""
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=":0") as client:
        yield client


def test_run_records_rows_skips_on_rerun_and_retries_failures(threads_client, tmp_path):
    out = tmp_path / "out"
    jobs = [Job(f"j{i}", "slices", f"/d/j{i}", {"volume": 100 * i, "fail": i == 1}) for i in range(3)]
    seen = []
    report = run_batch(jobs, out, threads_client, runners={"slices": _toy_runner}, progress=seen.append)
    assert (report.n_jobs, report.ran, report.ok, report.failed, report.skipped) == (3, 3, 2, 1, 0)
    assert sorted(r["id"] for r in seen) == ["j0", "j1", "j2"] and all("traceback" not in r for r in seen)
    rows = read_results(out / RESULTS_NAME)
    assert {k: r["status"] for k, r in rows.items()} == {"j0": "ok", "j1": "failed", "j2": "ok"}
    assert rows["j2"]["volume_mm3"] == "200.00" and rows["j1"]["error"] == "ValueError: j1: told to fail"
    assert (out / "j2" / "volume.txt").read_text() == "200" and not (out / "j1").exists()
    assert json.loads((out / FAILED_DIR / "j1.json").read_text())["attempts"] == 1

    again = run_batch(jobs, out, threads_client, runners={"slices": _toy_runner})
    assert (again.ran, again.skipped) == (0, 3)
    assert read_results(out / RESULTS_NAME) == rows

    fixed = [Job(j.id, j.kind, j.input, {**j.options, "fail": False}) for j in jobs]
    retry = run_batch(fixed, out, threads_client, retry_failed=True, runners={"slices": _toy_runner})
    assert (retry.ran, retry.ok, retry.skipped) == (1, 1, 2)
    after = read_results(out / RESULTS_NAME)
    # the retried job keeps its place (rows are in the order the first run finished them)
    assert list(after) == list(rows) and after["j1"]["status"] == "ok" and after["j0"] == rows["j0"]
    assert not (out / FAILED_DIR / "j1.json").exists()
    assert sorted(p.name for p in out.iterdir()) == [FAILED_DIR, "j0", "j1", "j2", RESULTS_NAME]


def _dying_runner(job: Job, out_dir: Path) -> dict:
    """Fault injection: the worker process dies in the middle of the job."""
    (out_dir / "half_written.npy").write_bytes(b"\0" * 64)
    os._exit(3)


def test_worker_death_is_a_recorded_failure(cluster, tmp_path):
    from distributed import Client

    out = tmp_path / "out"
    job = Job("dies", "photometric", str(tmp_path))
    with Client(cluster) as client:
        report = run_batch([job], out, client, runners={"photometric": _dying_runner})
    assert (report.ran, report.failed) == (1, 1)
    (row,) = report.rows
    assert row["status"] == "failed" and row["error"].startswith("task: KilledWorker")
    assert json.loads((out / FAILED_DIR / "dies.json").read_text())["error"] == row["error"]
    # the dead worker's temporary folder is gone, no job folder exists
    assert sorted(p.name for p in out.iterdir()) == [FAILED_DIR, RESULTS_NAME]
