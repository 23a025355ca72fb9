"""Tests of ``workbench batch``: manifests, discovery, atomic job folders, the Dask driver.

The batch tests run the real pipelines (:func:`photometric.pipeline.reconstruct`,
:func:`slices.pipeline.reconstruct`) on synthetic triads and CT phantoms from
:mod:`datasets_synthetic`, on a local Dask cluster of two workers.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path

import pytest

from workbench import batch
from workbench.cli import main

N_TRIADS = 12
N_PHANTOMS = 6
SIZE = 64
PHANTOMS = (
    ("ellipsoid", {}),
    ("kidney", {}),
    ("ring", {}),
    ("lobes", {}),
    ("ellipsoid", {"a": 18.0, "b": 12.0, "c": 15.0}),
    ("lobes", {"radii_mm": (18.0, 12.0)}),
)


# --------------------------------------------------------------------------- data


def _make_triads(root: Path, n: int, size: int = SIZE) -> list[Path]:
    from datasets_synthetic.render import make_triad_folder

    scenes = ("plate", "crack", "dent", "scratch", "bumps", "sphere")
    folders = []
    for i in range(n):
        folder = root / f"line{i // 6}" / f"triad_{i:02d}"
        make_triad_folder(folder, scene=scenes[i % len(scenes)], size=size, seed=i)
        folders.append(folder)
    return folders


def _make_phantoms(root: Path, n: int) -> list[Path]:
    from datasets_synthetic.phantoms import make_phantom, write_phantom

    folders = []
    for i in range(n):
        shape, params = PHANTOMS[i % len(PHANTOMS)]
        folder = root / f"patient_{i:02d}"
        write_phantom(folder, make_phantom(shape, **params), 4.0, 1.5, fmt="rtstruct", n_points=48)
        folders.append(folder)
    return folders


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
def cluster():
    """One local cluster of two worker processes, shared through its tcp:// address.

    A task whose worker dies is not retried on another (allowed_failures=0), so that the
    worker-death test costs one worker restart.
    """
    from distributed import LocalCluster

    local = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        scheduler_kwargs={"allowed_failures": 0},
    )
    yield local.scheduler_address
    local.close()


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch_data")
    triads = _make_triads(root / "triads", N_TRIADS)
    phantoms = _make_phantoms(root / "phantoms", N_PHANTOMS)
    return root, triads, phantoms


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
                if key in summary:
                    assert float(row[key]) == pytest.approx(summary[key], rel=1e-9)
        # the photometric max depth is the deepest defect of the job's defects.json
        for row in (r for r in by_status["ok"] if r["kind"] == "photometric"):
            defects = json.loads((out / row["id"] / "defects.json").read_text())["defects"]
            assert int(row["n_defects"]) == len(defects)
            assert float(row["max_depth_mm"]) == pytest.approx(max([d["max_depth_mm"] for d in defects] or [0]))
        # peer: the same jobs called directly, without Dask, give the same figures
        for kind, folder, row_id, options in (
            ("photometric", root / "triads", "line0-triad_00", {}),
            ("slices", root / "phantoms", "patient_01-rtstruct-kidney", {"render": False, "reference": False}),
        ):
            (job,) = [j for j in batch.load_jobs(folder, kind, options) if j.id == row_id]
            direct = batch.RUNNERS[kind](job, tmp_path / f"direct_{kind}")
            row = next(r for r in rows if r["id"] == row_id)
            for key in batch.FIGURES[kind]:
                assert float(row[key]) == pytest.approx(direct[key], rel=1e-9), (row_id, key)
        # slices volumes against the phantoms' exact volumes (a loose bound: the batch's own
        # job is to run the right input, the pipeline's accuracy is tested in tests/slices)
        for row in (r for r in rows if r["kind"] == "slices"):
            truth = json.loads((Path(row["input"]).parent / "truth.json").read_text())
            assert float(row["volume_mm3"]) == pytest.approx(truth["volume_mm3"], rel=0.25)
            assert float(row["volume_ml"]) == pytest.approx(float(row["volume_mm3"]) / 1000.0, rel=1e-6)

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
        summary = json.loads((out / "batch_photometric.json").read_text())
        assert (summary["ran"], summary["ok"], summary["skipped"]) == (1, 1, N_TRIADS - 1)
        rows_after = _rows(out)
        assert len(rows_after) == N_TRIADS + N_PHANTOMS
        assert all(r["status"] == "ok" for r in rows_after)
        unchanged = {r["id"]: r for r in rows if r["id"] != "line0-triad_05"}
        assert all(unchanged[r["id"]] == r for r in rows_after if r["id"] in unchanged)
        assert not (out / batch.FAILED_DIR / "line0-triad_05.json").exists()
        assert batch.is_complete(out / "line0-triad_05")
    finally:
        (bad / "light_directions.txt").write_bytes(original)


# --------------------------------------------------------------------------- manifests

SLICES_CSV = """id,input,roi,method,rays,render,hu_min,hu_max
,cases/p1/rtstruct.dcm,Heart;Lt Lung,blending,32,false,,
ct7,cases/p7/ct,,,,,-200,300
,/abs/phantom/contours.json,,coons,,,,
"""
SLICES_JSONL = [
    {"input": "cases/p1/rtstruct.dcm", "roi": ["Heart", "Lt Lung"], "method": "blending", "rays": 32, "render": False},
    {"id": "ct7", "input": "cases/p7/ct", "hu_min": -200, "hu_max": 300},
    {"input": "/abs/phantom/contours.json", "method": "coons"},
]


@pytest.mark.parametrize("fmt", ["csv", "jsonl"])
def test_read_manifest_slices(tmp_path, fmt):
    path = tmp_path / f"jobs.{fmt}"
    if fmt == "csv":
        path.write_text("# structure sets of the week\n" + SLICES_CSV)
    else:
        path.write_text("\n".join(json.dumps(r) for r in SLICES_JSONL) + "\n\n")
    jobs = batch.load_jobs(path, "slices", {"render": True, "caps": "half"})
    assert [j.id for j in jobs] == [
        "cases-p1-rtstruct-Heart",
        "cases-p1-rtstruct-Lt_Lung",
        "ct7",
        "phantom-contours",
    ]
    assert [j.roi for j in jobs] == ["Heart", "Lt Lung", None, None]
    assert jobs[0].input == str(tmp_path / "cases" / "p1" / "rtstruct.dcm")
    assert jobs[0].options == {"method": "blending", "rays": 32, "render": False, "caps": "half"}
    assert jobs[2].options == {"hu_min": -200, "hu_max": 300, "render": True, "caps": "half"}
    assert jobs[3].input == "/abs/phantom/contours.json" and jobs[3].options["method"] == "coons"


@pytest.mark.parametrize(
    ("kind", "text", "message"),
    [
        ("slices", "roi,method\nHeart,coons\n", "missing 'input'"),
        ("slices", "id,input\n../x,a.dcm\n", "not a safe folder name"),
        ("slices", "id,input\nfailed,a.dcm\n", "not a safe folder name"),
        ("slices", "kind,input\nphotometric,a.dcm\n", "kind 'photometric' in a slices batch"),
        ("slices", "input,input\na,b\n", "repeated column"),
        ("slices", "input\na,b\n", "more cells than header"),
        ("slices", "input\n", "no job rows"),
        ("slices", '{"input": "a.dcm"}\n[1, 2]\n', "expected a JSON object"),
        ("slices", '{"input": "a.dcm"\n', "not a JSON object"),
        ("photometric", "input,images,lights\na,b.png,l.txt\n", "either 'input'"),
        ("photometric", "images\na.png;b.png;c.png\n", "needs a 'lights' file"),
        ("photometric", "images,lights\n;,l.txt\n", "images is empty"),
        ("nonsense", "input\na\n", "kind: expected one of"),
    ],
)
def test_bad_manifests_are_rejected(tmp_path, kind, text, message):
    path = tmp_path / ("jobs.jsonl" if text.startswith("{") else "jobs.csv")
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        batch.load_jobs(path, kind)


def test_missing_manifest(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        batch.load_jobs(tmp_path / "nope.csv", "slices")


def test_images_manifest_matches_folder_job(tmp_path):
    """A job given as images + lights gives the figures of the same data given as a folder."""
    (folder,) = _make_triads(tmp_path / "data", 1)
    names = (folder / "filenames.txt").read_text().split()
    manifest = tmp_path / "jobs.csv"
    rel = folder.relative_to(tmp_path)
    manifest.write_text(
        "id,images,lights,intensities,mask,pixel_size\n"
        f"by_images,{';'.join(str(rel / n) for n in names)},{rel}/light_directions.txt,"
        f"{rel}/light_intensities.txt,{rel}/mask.png,0.05\n"
    )
    (by_images,) = batch.load_jobs(manifest, "photometric")
    (by_folder,) = batch.discover_jobs(folder, "photometric")
    assert by_images.input == tuple(str(folder / n) for n in names)
    assert by_images.options["lights"] == str(folder / "light_directions.txt")
    out = tmp_path / "out"
    out.mkdir()
    rows = [batch.execute_job(job, out) for job in (by_images, by_folder)]
    assert [r["status"] for r in rows] == ["ok", "ok"], rows
    for key in batch.FIGURES["photometric"]:
        assert float(rows[0][key]) == pytest.approx(float(rows[1][key]), rel=1e-6), key
    assert sorted(p.name for p in out.iterdir()) == sorted([by_images.id, by_folder.id])


def test_failing_job_leaves_nothing(tmp_path):
    (folder,) = _make_triads(tmp_path / "data", 1)
    (folder / "002.png").write_bytes(b"\x89PNG truncated")
    (job,) = batch.discover_jobs(folder, "photometric")
    out = tmp_path / "out"
    out.mkdir()
    row = batch.execute_job(job, out)
    assert row["status"] == "failed" and "002.png" in row["error"] and "\n" not in row["error"]
    assert "Traceback" in row["traceback"]
    assert list(out.iterdir()) == []


# --------------------------------------------------------------------------- discovery and ids


def test_discover_photometric_folders(tmp_path):
    for rel in ("a/t1", "a/t2", "b", ".tmp-x-123/t3", "c/nested/deep", "out/a-t1/copy"):
        (tmp_path / rel).mkdir(parents=True)
        (tmp_path / rel / "light_directions.txt").write_text("0 0 1\n")
    (tmp_path / "out" / "a-t1" / batch.COMPLETE_MARKER).write_text("{}")  # a finished job folder
    (tmp_path / "empty").mkdir()
    jobs = batch.discover_jobs(tmp_path, "photometric")
    assert [j.id for j in jobs] == ["a-t1", "a-t2", "b", "c-nested-deep"]
    assert all(Path(j.input).is_absolute() and j.kind == "photometric" for j in jobs)
    with pytest.raises(ValueError, match="no folder with a light_directions.txt"):
        batch.discover_jobs(tmp_path / "empty", "photometric")
    with pytest.raises(NotADirectoryError):
        batch.discover_jobs(tmp_path / "missing", "photometric")


def test_discover_slices_checks_modality(shared_data, tmp_path):
    src = shared_data / "rtstruct_breast"
    (tmp_path / "p1").mkdir()
    shutil.copy(src / "rtss.dcm", tmp_path / "p1" / "rtss.dcm")
    shutil.copy(src / "ct.0.dcm", tmp_path / "p1" / "ct.0.dcm")  # a CT image: not a job
    (tmp_path / "p1" / "contours.json").write_text("{}")  # beside a structure set: not a 2nd job
    (tmp_path / "p2").mkdir()
    (tmp_path / "p2" / "contours.json").write_text("{}")
    (tmp_path / "p3").mkdir()
    (tmp_path / "p3" / "junk.dcm").write_bytes(b"not dicom at all")
    jobs = batch.discover_jobs(tmp_path, "slices")
    # one job per ROI with contours of the real structure set ("Areola" has none)
    rois = ["BODY", "Borders", "Breast", "Heart", "Lt Lung", "Nodes", "Scar", "Tumor Bed", "Tumor Bed Block"]
    assert [(j.id, Path(j.input).name, j.roi) for j in jobs] == [
        *((f"p1-rtss-{r.replace(' ', '_')}", "rtss.dcm", r) for r in rois),
        ("p2-contours", "contours.json", None),
    ]
    # an ROI named for every structure set found
    heart = batch.discover_jobs(tmp_path, "slices", {"roi": "Heart", "rays": 32})
    assert [(j.id, j.roi, j.options) for j in heart] == [
        ("p1-rtss-Heart", "Heart", {"rays": 32}),
        ("p2-contours", None, {"rays": 32}),
    ]


@pytest.mark.parametrize(
    ("path", "roi", "expected"),
    [
        ("/data/run 1/triad#3", None, "run_1-triad_3"),
        ("/data/p7/rtstruct.dcm", ("Heart", "Lt Lung"), "p7-rtstruct-Heart-Lt_Lung"),
        ("/data", None, "data"),
    ],
)
def test_job_id_is_filesystem_safe(path, roi, expected):
    ident = batch.job_id(path, "/data" if path != "/data" else "/data", roi)
    assert ident == expected
    assert batch._ID_PATTERN.match(ident)


def test_duplicate_ids_get_suffixes():
    jobs = [batch.Job("a", "slices", f"/x/{i}") for i in range(3)] + [batch.Job("a-2", "slices", "/y")]
    assert [j.id for j in batch._unique_ids(jobs)] == ["a", "a-3", "a-4", "a-2"]


# --------------------------------------------------------------------------- driver pieces


def test_lock_refuses_a_live_run_and_takes_over_a_dead_one(tmp_path):
    lock = tmp_path / batch.LOCK_NAME
    lock.write_text(json.dumps({"pid": os.getppid(), "host": __import__("socket").gethostname()}))
    with pytest.raises(ValueError, match="another run holds"):
        batch.run_batch([], tmp_path)
    lock.write_text(json.dumps({"pid": 2**22 + 12345, "host": __import__("socket").gethostname()}))
    report = batch.run_batch([], tmp_path)
    assert report.ran == 0 and not lock.exists()


@pytest.mark.parametrize("address", ["tcp://nohost", "http://x:8786", "localhost:8786", "tcp://a b:1"])
def test_connect_rejects_bad_addresses(address):
    with pytest.raises(ValueError, match="scheduler"):
        with batch.connect(address):
            pass


def test_one_line_error():
    err = batch.one_line_error(ValueError("lights: bad\nsecond line"))
    assert err == "ValueError: lights: bad"
    assert len(batch.one_line_error(RuntimeError("x" * 1000))) == 300


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


def _dying_runner(job: batch.Job, out_dir: Path) -> dict:
    """Fault injection: the worker process dies in the middle of the job."""
    (out_dir / "half_written.npy").write_bytes(b"\0" * 64)
    os._exit(3)


def test_worker_death_is_a_recorded_failure(cluster, tmp_path):
    from distributed import Client

    out = tmp_path / "out"
    job = batch.Job("dies", "photometric", str(tmp_path))
    with Client(cluster) as client:
        report = batch.run_batch([job], out, client, runners={"photometric": _dying_runner})
    assert (report.ran, report.failed) == (1, 1)
    (row,) = report.rows
    assert row["status"] == "failed" and row["error"].startswith("task: KilledWorker")
    assert json.loads((out / batch.FAILED_DIR / "dies.json").read_text())["error"] == row["error"]
    # the dead worker's temporary folder is gone, no job folder exists
    assert sorted(p.name for p in out.iterdir()) == [batch.FAILED_DIR, batch.RESULTS_NAME]
