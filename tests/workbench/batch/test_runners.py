"""Tests of :mod:`workbench.batch.runners`: one job through its pipeline into its own folder, atomically."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import pytest

from tests.workbench.batch._data import make_triads
from workbench.batch import FIGURES, Job, discover_jobs, execute_job, is_complete, load_jobs
from workbench.batch.results import COMPLETE_MARKER, RESULT_COLUMNS
from workbench.batch.runners import RUNNERS, pipeline


@pytest.mark.parametrize("kind", ["photometric", "slices"])
def test_pipeline_takes_input_and_folder_first(kind):
    params = list(inspect.signature(pipeline(kind)).parameters.values())
    assert len(params) >= 2 and all(p.kind is p.POSITIONAL_OR_KEYWORD for p in params[:2])
    assert set(RUNNERS) == {"photometric", "slices"}


def test_pipeline_rejects_unknown_kind():
    with pytest.raises(ValueError, match="kind: expected one of photometric, slices"):
        pipeline("ct")


def _volume_runner(job: Job, out_dir: Path) -> dict:
    (out_dir / "surface.txt").write_text(job.id)
    return {"volume_mm3": 1234.5, "mesh": {"n_patches": 96}, "note": "not a figure"}


def test_execute_job_renames_a_complete_folder(tmp_path):
    job = Job("k1", "slices", "/data/k1/contours.json", {"rays": 32})
    (tmp_path / "k1").mkdir()
    (tmp_path / "k1" / "stale.txt").write_text("left by a run that died")  # no marker: replaced
    row = execute_job(job, tmp_path, _volume_runner)
    assert row["status"] == "ok" and row["error"] == "" and row["traceback"] == ""
    assert (row["volume_mm3"], row["n_patches"], row["volume_ml"]) == ("1234.50", "96", "")
    assert set(row) == {*RESULT_COLUMNS, "traceback"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k1"]
    assert sorted(p.name for p in (tmp_path / "k1").iterdir()) == [COMPLETE_MARKER, "surface.txt"]
    marker = json.loads((tmp_path / "k1" / COMPLETE_MARKER).read_text())
    assert marker["row"] == {k: v for k, v in row.items() if k != "traceback"}
    assert (marker["input"], marker["roi"], marker["options"]) == (job.input, None, {"rays": 32})
    assert is_complete(tmp_path / "k1")


def test_execute_job_refuses_a_result_that_is_not_a_summary(tmp_path):
    row = execute_job(Job("bad", "slices", "/x"), tmp_path, lambda job, out_dir: [1, 2])
    assert row["status"] == "failed"
    assert row["error"] == "TypeError: the slices pipeline returned list, not a summary dict"
    assert list(tmp_path.iterdir()) == []


def test_images_manifest_matches_folder_job(tmp_path):
    """A job given as images + lights gives the figures of the same data given as a folder."""
    (folder,) = make_triads(tmp_path / "data", 1)
    names = (folder / "filenames.txt").read_text().split()
    manifest = tmp_path / "jobs.csv"
    rel = folder.relative_to(tmp_path)
    manifest.write_text(
        "id,images,lights,intensities,mask,pixel_size\n"
        f"by_images,{';'.join(str(rel / n) for n in names)},{rel}/light_directions.txt,"
        f"{rel}/light_intensities.txt,{rel}/mask.png,0.05\n"
    )
    (by_images,) = load_jobs(manifest, "photometric")
    (by_folder,) = discover_jobs(folder, "photometric")
    assert by_images.input == tuple(str(folder / n) for n in names)
    assert by_images.options["lights"] == str(folder / "light_directions.txt")
    out = tmp_path / "out"
    out.mkdir()
    rows = [execute_job(job, out) for job in (by_images, by_folder)]
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    for key in FIGURES["photometric"]:
        assert float(rows[0][key]) == pytest.approx(float(rows[1][key]), rel=1e-6), key
    assert sorted(p.name for p in out.iterdir()) == sorted([by_images.id, by_folder.id])
    # the row's max depth is the deepest defect the pipeline listed
    defects = json.loads((out / by_folder.id / "defects.json").read_text())["defects"]
    # results.csv holds the depth to DECIMALS["max_depth_mm"] decimals (issue 37); defects.json in full
    assert float(rows[1]["max_depth_mm"]) == pytest.approx(max([d["max_depth_mm"] for d in defects] or [0.0]),
                                                           abs=0.5e-4 + 1e-12)


def test_failing_job_leaves_nothing(tmp_path):
    (folder,) = make_triads(tmp_path / "data", 1)
    (folder / "002.png").write_bytes(b"\x89PNG truncated")
    (job,) = discover_jobs(folder, "photometric")
    out = tmp_path / "out"
    out.mkdir()
    row = execute_job(job, out)
    assert row["status"] == "failed" and "002.png" in row["error"] and "\n" not in row["error"]
    assert "Traceback" in row["traceback"]
    assert list(out.iterdir()) == []
