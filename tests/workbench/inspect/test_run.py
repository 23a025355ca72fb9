"""Many parts through the batch driver: results.csv rows, a bad part recorded, resume, report.html, the inbox."""

from __future__ import annotations

import csv
import json
import shutil
import time

import pytest

from workbench.inspect.run import load_parts, run_inspection
from workbench.inspect.watch import folder_signature, ready_parts, watch


@pytest.fixture(scope="module")
def client():
    """An in-process Dask client: the driver's bookkeeping without worker processes."""
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=":0") as c:
        yield c


def _rows(out):
    with open(out / "results.csv", newline="") as fh:
        return {row["id"]: row for row in csv.DictReader(fh)}


def test_load_parts_from_a_folder_and_manifests(small_lot, tmp_path):
    parts = load_parts(small_lot["parts"])
    assert [pid for pid, _ in parts] == ["clean", "crack_limit", "dent_under", "scratch_over"]
    assert all(folder.is_absolute() for _, folder in parts)
    csv_manifest = tmp_path / "lot.csv"
    lot = small_lot["parts"]
    csv_manifest.write_text(f"id,input\n# a comment\nA,{lot / 'clean'}\n,{lot}/dent_under\n")
    got = load_parts(csv_manifest)
    assert got[0] == ("A", small_lot["parts"] / "clean") and got[1][1].name == "dent_under"
    jsonl = tmp_path / "lot.jsonl"
    jsonl.write_text(json.dumps({"input": str(small_lot["parts"] / "clean")}) + "\n")
    assert load_parts(jsonl)[0][1].name == "clean"


@pytest.mark.parametrize("text, message", [
    ("input,colour\nx,red\n", "unknown column(s) colour"),
    ("id\nA\n", "needs 'input'"),
    ("id,input\nA,p1\nA,p2\n", "repeated part id(s) A"),
    ("id,input\nresults.csv,p1\n", "id 'results.csv' is not a safe folder name"),
    ("id,input\n..,p1\n", "id '..' is not a safe folder name"),
    ("id,input\n/tmp/x,p1\n", "id '/tmp/x' is not a safe folder name"),
    ("input\n", "no part"),
])
def test_manifest_errors(tmp_path, text, message):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        load_parts(path)
    assert message in str(err.value)


def test_folder_without_parts(tmp_path):
    with pytest.raises(ValueError, match="holds no part folder"):
        load_parts(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_parts(tmp_path / "none")


def test_run_records_a_bad_part_and_resumes(small_lot, tmp_path, client):
    parts = tmp_path / "parts"
    shutil.copytree(small_lot["parts"], parts)
    bad = parts / "zz_missing_image"
    shutil.copytree(parts / "clean", bad)
    (bad / "003.png").unlink()
    (bad / "filenames.txt").unlink()
    out = tmp_path / "out"
    seen = []
    run = run_inspection(parts, small_lot["rig"], small_lot["spec"], out, client=client, progress=seen.append)
    assert (run.batch.ran, run.batch.ok, run.batch.failed) == (5, 4, 1) and len(seen) == 5
    rows = _rows(out)
    assert rows["clean"]["verdict"] == "pass" and rows["scratch_over"]["verdict"] == "fail"
    assert rows["dent_under"]["verdict"] == "pass" and rows["clean"]["kind"] == "inspect"
    assert rows["zz_missing_image"]["status"] == "failed" and "3 image(s) for 4 lights" in rows[
        "zz_missing_image"]["error"]
    assert not (out / "zz_missing_image").exists() and (out / "failed" / "zz_missing_image.json").is_file()
    for pid in ("clean", "scratch_over", "dent_under", "crack_limit"):
        assert {"result.json", "overlay.png", "_COMPLETE"} <= {p.name for p in (out / pid).iterdir()}
    assert run.verdicts["fail"] >= 1 and run.parts_per_second > 0
    assert sum(run.verdicts[v] for v in ("pass", "fail", "uncertain")) == 4 and run.verdicts["not_measured"] == 1
    figures = json.loads((out / "inspect_run.json").read_text())
    assert (figures["ran"], figures["failed"], figures["verdicts"]) == (5, 1, run.verdicts)
    page = (out / "report.html").read_text()
    assert "Yield" in page and "Depths against the limit" in page and "scratch_over: fail" in page
    assert page.count("data:image/png;base64,") >= 3 and "3 image(s) for 4 lights" in page
    # a rerun skips finished and failed parts, and leaves their rows
    again = run_inspection(parts, small_lot["rig"], small_lot["spec"], out, client=client)
    assert (again.batch.ran, again.batch.skipped) == (0, 5) and _rows(out) == rows


def test_bad_spec_or_rig_writes_nothing(small_lot, tmp_path, client):
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": -1}))
    with pytest.raises(ValueError, match="max_depth_mm: must not be negative"):
        run_inspection(small_lot["parts"], small_lot["rig"], spec, tmp_path / "out", client=client)
    with pytest.raises(FileNotFoundError, match="--rig"):
        run_inspection(small_lot["parts"], tmp_path / "rig.json", small_lot["spec"], tmp_path / "out", client=client)
    with pytest.raises(ValueError, match="--option speed"):
        run_inspection(small_lot["parts"], small_lot["rig"], small_lot["spec"], tmp_path / "out",
                       options={"speed": 1}, client=client)
    assert not (tmp_path / "out").exists()


def test_ready_parts_wait_for_the_last_image_to_settle(small_lot, tmp_path):
    inbox = tmp_path / "inbox"
    part = inbox / "p1"
    part.mkdir(parents=True)
    for name in ("001.png", "002.png", "003.png"):
        shutil.copy(small_lot["parts"] / "clean" / name, part / name)
    seen = {}
    assert ready_parts(inbox, 4, seen, settle=1.0, now=0.0) == []
    assert ready_parts(inbox, 4, seen, settle=1.0, now=5.0) == []  # 3 of 4 images
    shutil.copy(small_lot["parts"] / "clean" / "004.png", part / "004.png")
    assert ready_parts(inbox, 4, seen, settle=1.0, now=6.0) == []  # just changed
    assert ready_parts(inbox, 4, seen, settle=1.0, now=6.5) == []  # not settled yet
    assert ready_parts(inbox, 4, seen, settle=1.0, now=7.5) == [("p1", part.resolve())]
    before = folder_signature(part)
    (part / "004.png").write_bytes((small_lot["parts"] / "clean" / "004.png").read_bytes() + b"\0")
    assert folder_signature(part) != before
    assert ready_parts(inbox, 4, seen, settle=1.0, now=8.0) == []  # still being written


def test_watch_inspects_each_part_once_and_survives_a_restart(small_lot, tmp_path, client):
    inbox = tmp_path / "inbox"
    inbox.mkdir()
    shutil.copytree(small_lot["parts"] / "scratch_over", inbox / "p1")
    out = tmp_path / "out"
    runs = []
    t0 = time.monotonic()
    totals = watch(inbox, small_lot["rig"], small_lot["spec"], out, client=client, interval=0.2, settle=0.0,
                   timeout=3.0, on_run=runs.append)
    assert time.monotonic() - t0 < 30
    assert totals["ran"] == 1 and totals["polls"] >= 2 and len(runs) == 1
    assert _rows(out)["p1"]["verdict"] == "fail"
    # a new part arrives; a restarted watch inspects only it
    shutil.copytree(small_lot["parts"] / "clean", inbox / "p2")
    totals = watch(inbox, small_lot["rig"], small_lot["spec"], out, client=client, interval=0.2, settle=0.0,
                   timeout=3.0)
    assert totals["ran"] == 1 and set(_rows(out)) == {"p1", "p2"} and _rows(out)["p2"]["verdict"] == "pass"
    with pytest.raises(NotADirectoryError, match="INBOX"):
        watch(tmp_path / "none", small_lot["rig"], small_lot["spec"], out, client=client, timeout=0)


def test_inspect_figures_in_the_batch_rows():
    from workbench.batch import FIGURES, RESULT_COLUMNS, key_figures

    summary = {"verdict": "uncertain", "n_imperfections": 2, "n_fail": 0, "n_uncertain": 1, "max_depth_mm": 0.1,
               "max_depth_U_mm": 0.01, "total_area_mm2": 3.5, "invalid_fraction": 0.0, "spec_sha256": "ab" * 32,
               "background_rms_mm": 0.0003, "slope_bias_mrad": 0.1, "timings_s": {"total": 1.0}}
    assert key_figures("inspect", summary) == {k: summary[k] for k in FIGURES["inspect"] if k in summary}
    texture = {"texture_verdict": "pass", "Sa_um": 0.8, "Sa_U_um": 0.1, "Sq_um": 1.0, "Sq_U_um": 0.1, "Sz_um": 9.0,
               "Sz_U_um": 1.0}
    assert key_figures("inspect", {**summary, **texture}) == {k: {**summary, **texture}[k] for k in FIGURES["inspect"]}
    assert set(FIGURES["inspect"]) <= set(RESULT_COLUMNS) and len(set(RESULT_COLUMNS)) == len(RESULT_COLUMNS)
    assert RESULT_COLUMNS[:5] == ("id", "kind", "status", "error", "time_s") and RESULT_COLUMNS[-1] == "input"


def test_a_part_job_runs_on_one_thread_and_restores_opencv(monkeypatch, tmp_path):
    """Workers share the cores: the part's near-field pool, BLAS/OpenMP and OpenCV run 1 thread each
    while the job runs, and OpenCV's own setting is back afterwards."""
    import cv2
    from threadpoolctl import threadpool_info

    import workbench.inspect.part as part
    from workbench.batch import Job
    from workbench.inspect.run import KIND, run_inspect_job

    seen = {}

    def fake(folder, out_dir, rig, spec, **kw):
        seen.update(kw, cv2=cv2.getNumThreads(), pools={p["num_threads"] for p in threadpool_info()})
        return {"verdict": "pass"}

    monkeypatch.setattr(part, "inspect_part", fake)
    before = cv2.getNumThreads()
    job = Job("p1", KIND, str(tmp_path), {"rig": "r.json", "spec": "s.json", "keep_arrays": False})
    assert run_inspect_job(job, tmp_path / "out") == {"verdict": "pass"}
    assert seen["threads"] == 1 and seen["cv2"] == 1 and seen["pools"] <= {1}
    assert seen["part_id"] == "p1" and seen["keep_arrays"] is False
    assert cv2.getNumThreads() == before
