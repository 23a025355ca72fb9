"""Tests of :mod:`workbench.batch.results`: rows, failure records, results.csv healing, run figures."""

from __future__ import annotations

import json

import pytest

from workbench.batch import BatchReport, Job, key_figures, one_line_error, read_results, write_report
from workbench.batch.results import (
    COMPLETE_MARKER,
    FAILED_DIR,
    RESULT_COLUMNS,
    RESULTS_NAME,
    healed_results,
    marker_kind,
    record_outcome,
    result_row,
    write_results,
)

JOBS = [Job(f"j{i}", "slices", f"/data/j{i}.json") for i in range(4)]


def test_key_figures_search_nested_summaries():
    summary = {"invalid_fraction": 0.25, "lights": {"light_condition_number": 1.41}, "n_defects": 2,
               "defects": {"n_defects": 99}, "size": {"max_depth_mm": "deep"}}
    assert key_figures("photometric", summary) == {
        "n_defects": 2, "invalid_fraction": 0.25, "light_condition_number": 1.41}
    with pytest.raises(ValueError, match="kind"):
        key_figures("ct", summary)


def test_result_row_text_cells():
    job = Job("t1", "photometric", ("/t/1.png", "/t/2.png", "/t/3.png"))
    row = result_row(job, "ok", "", 0.1234, {"n_defects": 3, "max_depth_mm": 1 / 3})
    assert list(row) == list(RESULT_COLUMNS)
    assert (row["n_defects"], row["max_depth_mm"], row["time_s"]) == ("3", "0.3333", "0.123")
    assert row["input"] == "/t/1.png;/t/2.png;/t/3.png" and row["volume_mm3"] == ""


def test_one_line_error_limits_length():
    assert one_line_error(ValueError("lights: bad\nsecond line")) == "ValueError: lights: bad"
    assert one_line_error(KeyError()) == "KeyError"
    long = one_line_error(RuntimeError("x" * 1000))
    assert len(long) == 300 and long.endswith("...")


def test_record_outcome_counts_attempts_and_clears_on_success(tmp_path):
    job = JOBS[0]
    failed = {**result_row(job, "failed", "ValueError: bad", 0.5, {}), "traceback": "Traceback ..."}
    record_outcome(tmp_path, job, failed)
    record_outcome(tmp_path, job, failed)
    content = json.loads((tmp_path / FAILED_DIR / "j0.json").read_text())
    assert (content["attempts"], content["error"], content["traceback"]) == (2, "ValueError: bad", "Traceback ...")
    assert (content["input"], content["time_s"], content["kind"]) == ("/data/j0.json", 0.5, "slices")
    record_outcome(tmp_path, job, result_row(job, "ok", "", 1.0, {}))
    assert list((tmp_path / FAILED_DIR).iterdir()) == []


def test_results_roundtrip_keeps_the_last_row_of_each_id(tmp_path):
    path = tmp_path / RESULTS_NAME
    rows = [result_row(JOBS[0], "failed", "E: x", 0.1, {}), result_row(JOBS[1], "ok", "", 0.2, {"volume_ml": 2.0}),
            result_row(JOBS[0], "ok", "", 0.3, {"volume_ml": 1.0})]
    write_results(path, [{**r, "traceback": "dropped"} for r in rows])
    assert path.read_text().splitlines()[0] == ",".join(RESULT_COLUMNS)
    back = read_results(path)
    assert list(back) == ["j0", "j1"]
    assert back["j0"] == rows[2] and back["j1"]["volume_ml"] == "2.0000"
    assert read_results(tmp_path / "missing.csv") == {}


def test_healed_results_rebuilds_rows_from_markers_and_records(tmp_path):
    ok = result_row(JOBS[0], "ok", "", 1.0, {"volume_mm3": 10.0})
    (tmp_path / "j0").mkdir()
    (tmp_path / "j0" / COMPLETE_MARKER).write_text(json.dumps({"row": ok}))
    record_outcome(tmp_path, JOBS[1], result_row(JOBS[1], "failed", "ValueError: bad", 2.0, {}))
    kept = result_row(JOBS[2], "ok", "", 3.0, {})
    write_results(tmp_path / RESULTS_NAME, [kept])
    with open(tmp_path / RESULTS_NAME, "a") as fh:  # a row cut short by a crash
        fh.write("j3,slic")
    healed = healed_results(tmp_path, [JOBS[0], JOBS[2]], [JOBS[1]], rewrite=False)
    assert list(healed) == ["j2", "j0", "j1"]
    assert healed["j0"] == ok and healed["j2"] == kept
    failed = healed["j1"]
    assert (failed["status"], failed["error"], failed["time_s"]) == ("failed", "ValueError: bad", "2.000")
    assert read_results(tmp_path / RESULTS_NAME) == healed


def test_healed_results_leaves_a_sound_file_untouched(tmp_path):
    path = tmp_path / RESULTS_NAME
    write_results(path, [result_row(JOBS[0], "ok", "", 1.0, {})])
    before = path.stat().st_mtime_ns, path.read_bytes()
    healed_results(tmp_path, [], [], rewrite=False)
    assert (path.stat().st_mtime_ns, path.read_bytes()) == before
    healed_results(tmp_path, [], [], rewrite=True)
    assert path.read_bytes() == before[1]


def test_marker_kind(tmp_path):
    assert marker_kind(tmp_path) == "unknown"
    (tmp_path / COMPLETE_MARKER).write_text(json.dumps({"row": {"kind": "photometric"}}))
    assert marker_kind(tmp_path) == "photometric"


def test_write_report(tmp_path):
    report = BatchReport(n_jobs=5, ran=3, ok=2, failed=1, skipped=2, wall_s=12.34567, jobs_per_minute=14.58,
                         rows=())
    path = write_report(report, tmp_path, "slices", scheduler="local", n_workers=2)
    assert path == tmp_path / "batch_slices.json"
    content = json.loads(path.read_text())
    assert {k: content[k] for k in ("kind", "n_jobs", "ran", "ok", "failed", "skipped", "wall_s", "results")} == {
        "kind": "slices", "n_jobs": 5, "ran": 3, "ok": 2, "failed": 1, "skipped": 2, "wall_s": 12.346,
        "results": RESULTS_NAME}
    assert (content["scheduler"], content["n_workers"]) == ("local", 2) and content["finished_utc"].endswith("+00:00")
    with pytest.raises(ValueError, match="kind"):
        write_report(report, tmp_path, "ct")


def test_figures_to_the_precision_of_their_u():
    """Issue 37: a value to the decimal of its U's second significant digit, fixed decimals without U."""
    job = Job("p1", "inspect", "/lot/p1")
    row = result_row(job, "ok", "", 1.0, {"max_depth_mm": 0.09158301113, "max_depth_U_mm": 0.0043217,
                                           "total_area_mm2": 0.123456789, "Sa_um": 0.81234, "Sa_U_um": 0.1234,
                                           "invalid_fraction": -0.00001, "texture_verdict": "pass"})
    assert (row["max_depth_mm"], row["max_depth_U_mm"]) == ("0.0916", "0.0043")
    assert (row["Sa_um"], row["Sa_U_um"]) == ("0.81", "0.12")
    assert row["total_area_mm2"] == "0.1235" and row["invalid_fraction"] == "0.0000"
    assert row["texture_verdict"] == "pass"
    # without a U the column's fixed decimals
    assert result_row(job, "ok", "", 1.0, {"max_depth_mm": 0.09158301113})["max_depth_mm"] == "0.0916"
