"""Tests of ``workbench batch`` (the command) from end to end.

The end-to-end test runs the real pipelines (:func:`photometric.pipeline.reconstruct`,
:func:`slices.pipeline.reconstruct`) on synthetic triads and CT phantoms from
:mod:`datasets_synthetic`, on a local Dask cluster of two workers.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from tests.workbench.batch._data import make_phantoms, make_triads
from workbench import batch
from workbench.cli import main

N_TRIADS = 12
N_PHANTOMS = 6


# --------------------------------------------------------------------------- data


def _corrupt_lights(folder: Path) -> bytes:
    """Keep only two rows of light_directions.txt; return the original content."""
    path = folder / "light_directions.txt"
    original = path.read_bytes()
    path.write_text("\n".join(path.read_text().splitlines()[:2]) + "\n")
    return original


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / batch.RESULTS_NAME, newline="") as fh:
        return list(csv.DictReader(fh))


def _state(out: Path) -> dict[str, object]:
    """Everything a rerun could change in OUT: file list with sizes and mtimes, results bytes."""
    files = sorted(
        (str(p.relative_to(out)), p.stat().st_size, p.stat().st_mtime_ns)
        for p in out.rglob("*")
        if p.is_file() and not p.name.startswith("batch_")
    )
    return {"files": files, "results": (out / batch.RESULTS_NAME).read_bytes()}


# --------------------------------------------------------------------------- the batch


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch_data")
    triads = make_triads(root / "triads", N_TRIADS)
    phantoms = make_phantoms(root / "phantoms", N_PHANTOMS)
    return root, triads, phantoms


@pytest.mark.slow
def test_batch_end_to_end(data, cluster, tmp_path, capsys):
    root, triads, phantoms = data
    bad = triads[5]
    original = _corrupt_lights(bad)
    try:
        out = tmp_path / "out"
        # photometric on a fresh local cluster, slices on a running one: nothing else changes
        code_p = main(["batch", "photometric", str(root / "triads"), "--out", str(out), "--workers", "2"])
        code_s = main(
            ["batch", "slices", str(root / "phantoms"), "--out", str(out), "--scheduler", cluster]
            + ["--option", "render=false", "--option", "reference=false"]
        )
        assert (code_p, code_s) == (1, 0)
        rows = _rows(out)
        assert len(rows) == N_TRIADS + N_PHANTOMS
        by_status = {s: [r for r in rows if r["status"] == s] for s in ("ok", "failed")}
        assert len(by_status["ok"]) == N_TRIADS + N_PHANTOMS - 1
        assert [r["id"] for r in by_status["failed"]] == ["line0-triad_05"]
        failed = by_status["failed"][0]
        assert "\n" not in failed["error"] and "light" in failed["error"].lower()
        record = json.loads((out / batch.FAILED_DIR / "line0-triad_05.json").read_text())
        assert record["error"] == failed["error"] and "Traceback" in record["traceback"]
        # nothing half-written: complete folders for ok jobs only, no temporary folder
        folders = sorted(p.name for p in out.iterdir() if p.is_dir() and p.name != batch.FAILED_DIR)
        assert folders == sorted(r["id"] for r in by_status["ok"])
        assert all(batch.is_complete(out / name) for name in folders)
        assert not list(out.glob(f"{batch.TMP_PREFIX}*")) and not (out / batch.LOCK_NAME).exists()
        # key figures are filled in per kind, copied from each job's own summary.json
        for row in by_status["ok"]:
            summary = json.loads((out / row["id"] / "summary.json").read_text())
            assert float(row["time_s"]) > 0
            for key in batch.FIGURES[row["kind"]]:
                assert row[key] != "", (row["id"], key)
                if key in summary:  # to the column's fixed decimals (issue 37); summary.json in full
                    decimals = batch.results.DECIMALS.get(key, 0) if isinstance(summary[key], float) else 0
                    assert float(row[key]) == pytest.approx(summary[key], abs=0.5 * 10**-decimals + 1e-12)
        # the photometric max depth is the deepest defect of the job's defects.json
        for row in (r for r in by_status["ok"] if r["kind"] == "photometric"):
            defects = json.loads((out / row["id"] / "defects.json").read_text())["defects"]
            assert int(row["n_defects"]) == len(defects)
            assert float(row["max_depth_mm"]) == pytest.approx(max([d["max_depth_mm"] for d in defects] or [0]),
                                                           abs=0.5e-4 + 1e-12)
        # peer: the same jobs called directly, without Dask, give the same figures
        for kind, folder, row_id, options in (
            ("photometric", root / "triads", "line0-triad_00", {}),
            ("slices", root / "phantoms", "patient_01-rtstruct-kidney", {"render": False, "reference": False}),
        ):
            (job,) = [j for j in batch.load_jobs(folder, kind, options) if j.id == row_id]
            direct = batch.RUNNERS[kind](job, tmp_path / f"direct_{kind}")
            row = next(r for r in rows if r["id"] == row_id)
            for key in batch.FIGURES[kind]:
                # the same figure gives the same text (results.csv rounds to the column's decimals)
                assert row[key] == batch.results.format_figures({key: direct[key]})[key], (row_id, key)
        # slices volumes against the phantoms' exact volumes (a loose bound: the batch's own
        # job is to run the right input, the pipeline's accuracy is tested in tests/slices)
        for row in (r for r in rows if r["kind"] == "slices"):
            truth = json.loads((Path(row["input"]).parent / "truth.json").read_text())
            assert float(row["volume_mm3"]) == pytest.approx(truth["volume_mm3"], rel=0.25)
            assert float(row["volume_ml"]) == pytest.approx(float(row["volume_mm3"]) / 1000.0, abs=0.5e-4 + 5e-6)

        # a rerun does nothing: no job, no file touched
        before = _state(out)
        assert main(["batch", "photometric", str(root / "triads"), "--out", str(out)]) == 0
        assert main(["batch", "slices", str(root / "phantoms"), "--out", str(out)]) == 0
        assert _state(out) == before
        summary = json.loads((out / "batch_photometric.json").read_text())
        assert (summary["ran"], summary["skipped"]) == (0, N_TRIADS)

        # results.csv cut short by a crash: a rerun rebuilds the missing rows from the job
        # folders' _COMPLETE markers and the failure records, and runs nothing
        lines = (out / batch.RESULTS_NAME).read_text().splitlines(keepends=True)
        (out / batch.RESULTS_NAME).write_text("".join(lines[:4]) + lines[4][:12])
        assert main(["batch", "photometric", str(root / "triads"), "--out", str(out)]) == 0
        assert main(["batch", "slices", str(root / "phantoms"), "--out", str(out)]) == 0
        assert {r["id"]: r for r in _rows(out)} == {r["id"]: r for r in rows}
        assert not list(out.glob(f"{batch.TMP_PREFIX}*"))

        # --retry-failed reruns only the failed job; fixed, it succeeds
        (bad / "light_directions.txt").write_bytes(original)
        capsys.readouterr()
        code = main(
            ["batch", "photometric", str(root / "triads"), "--out", str(out), "--scheduler", cluster, "--retry-failed"]
        )
        assert code == 0
        assert "1 failed before (retrying them)" in capsys.readouterr().out
        summary = json.loads((out / "batch_photometric.json").read_text())
        assert (summary["ran"], summary["ok"], summary["skipped"]) == (1, 1, N_TRIADS - 1)
        assert summary["failed_before"] == 1
        rows_after = _rows(out)
        assert len(rows_after) == N_TRIADS + N_PHANTOMS
        assert all(r["status"] == "ok" for r in rows_after)
        unchanged = {r["id"]: r for r in rows if r["id"] != "line0-triad_05"}
        assert all(unchanged[r["id"]] == r for r in rows_after if r["id"] in unchanged)
        assert not (out / batch.FAILED_DIR / "line0-triad_05.json").exists()
        assert batch.is_complete(out / "line0-triad_05")
    finally:
        (bad / "light_directions.txt").write_bytes(original)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["slices", "{tmp}/missing.csv"], "no such file or folder"),
        (["photometric", "{tmp}/data", "--option", "render"], "expected KEY=VALUE"),
        (["photometric", "{tmp}/data", "--scheduler", "localhost:8786"], "expected 'local' or tcp://HOST:PORT"),
        (["photometric", "{tmp}/data", "--workers", "0"], "workers: must be a finite positive"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, message):
    (tmp_path / "data" / "t").mkdir(parents=True)
    (tmp_path / "data" / "t" / "light_directions.txt").write_text("0 0 1\n")
    argv = ["batch", *(a.format(tmp=tmp_path) for a in args), "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_cli_rerun_with_nothing_to_do_opens_no_cluster(tmp_path, capsys):
    (tmp_path / "data" / "t").mkdir(parents=True)
    (tmp_path / "data" / "t" / "light_directions.txt").write_text("0 0 1\n")
    out = tmp_path / "out"
    (out / "t").mkdir(parents=True)
    (out / "t" / batch.COMPLETE_MARKER).write_text(json.dumps({"row": {"kind": "photometric", "id": "t"}}))
    assert main(["batch", "photometric", str(tmp_path / "data"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "1 photometric job(s): 0 to run, 1 complete (skipped), 0 failed before" in printed
    assert "ran 0: 0 ok, 0 failed; 1 skipped" in printed
    figures = json.loads((out / "batch_photometric.json").read_text())
    assert (figures["n_jobs"], figures["skipped"], figures["n_workers"], figures["dashboard"]) == (1, 1, 0, None)
    # the complete folder's marker gave results.csv its row back
    assert [r["id"] for r in _rows(out)] == ["t"]
