"""Tests of :mod:`workbench.batch.manifest`: manifests, folder discovery, job ids and options."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from workbench.batch import Job, coerce_value, discover_jobs, job_id, load_jobs, read_manifest
from workbench.batch.jobs import ID_PATTERN as _ID_PATTERN
from workbench.batch.manifest import _unique_ids
from workbench.batch.results import COMPLETE_MARKER

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
    jobs = load_jobs(path, "slices", {"render": True, "caps": "half"})
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
        load_jobs(path, kind)


def test_missing_manifest(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        load_jobs(tmp_path / "nope.csv", "slices")


# --------------------------------------------------------------------------- discovery and ids


def test_discover_photometric_folders(tmp_path):
    for rel in ("a/t1", "a/t2", "b", ".tmp-x-123/t3", "c/nested/deep", "out/a-t1/copy"):
        (tmp_path / rel).mkdir(parents=True)
        (tmp_path / rel / "light_directions.txt").write_text("0 0 1\n")
    (tmp_path / "out" / "a-t1" / COMPLETE_MARKER).write_text("{}")  # a finished job folder
    (tmp_path / "empty").mkdir()
    jobs = discover_jobs(tmp_path, "photometric")
    assert [j.id for j in jobs] == ["a-t1", "a-t2", "b", "c-nested-deep"]
    assert all(Path(j.input).is_absolute() and j.kind == "photometric" for j in jobs)
    with pytest.raises(ValueError, match="no folder with a light_directions.txt"):
        discover_jobs(tmp_path / "empty", "photometric")
    with pytest.raises(NotADirectoryError):
        discover_jobs(tmp_path / "missing", "photometric")


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
    jobs = discover_jobs(tmp_path, "slices")
    # one job per ROI with contours of the real structure set ("Areola" has none)
    rois = ["BODY", "Borders", "Breast", "Heart", "Lt Lung", "Nodes", "Scar", "Tumor Bed", "Tumor Bed Block"]
    assert [(j.id, Path(j.input).name, j.roi) for j in jobs] == [
        *((f"p1-rtss-{r.replace(' ', '_')}", "rtss.dcm", r) for r in rois),
        ("p2-contours", "contours.json", None),
    ]
    # an ROI named for every structure set found
    heart = discover_jobs(tmp_path, "slices", {"roi": "Heart", "rays": 32})
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
    ident = job_id(path, "/data" if path != "/data" else "/data", roi)
    assert ident == expected
    assert _ID_PATTERN.match(ident)


def test_duplicate_ids_get_suffixes():
    jobs = [Job("a", "slices", f"/x/{i}") for i in range(3)] + [Job("a-2", "slices", "/y")]
    assert [j.id for j in _unique_ids(jobs)] == ["a", "a-3", "a-4", "a-2"]


def test_manifest_paths_and_options(tmp_path):
    """Path options resolve against the manifest's folder; a scalar intensity stays a number."""
    path = tmp_path / "sub" / "jobs.jsonl"
    path.parent.mkdir()
    rows = [
        {"input": "triads/a", "lights": "L.txt", "intensities": 0.8, "integrator": "lsq"},
        {"id": "b", "input": "/abs/b", "mask": "~/m.png", "pixel_size": 0.05},
    ]
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    a, b = read_manifest(path, "photometric", {"integrator": "dct"})
    assert a.input == str(tmp_path / "sub" / "triads" / "a") and a.id == "triads-a"
    assert a.options == {"lights": str(tmp_path / "sub" / "L.txt"), "intensities": 0.8, "integrator": "lsq"}
    assert b.id == "b" and b.input == "/abs/b"
    assert b.options == {"mask": str(Path("~/m.png").expanduser()), "pixel_size": 0.05, "integrator": "dct"}


def test_unknown_option_names_what_the_pipeline_takes(tmp_path):
    path = tmp_path / "jobs.csv"
    path.write_text("input,integratr\ntriad,lsq\n")
    with pytest.raises(ValueError, match=r"unknown option\(s\) integratr; the photometric pipeline takes .*integrator"):
        load_jobs(path, "photometric")


def test_csv_cells_are_coerced(tmp_path):
    path = tmp_path / "jobs.csv"
    path.write_text("input,render,rays,lattice,method\na.json,TRUE,32,2.5,coons\nb.json,false,,,\n")
    a, b = load_jobs(path, "slices")
    assert a.options == {"render": True, "rays": 32, "lattice": 2.5, "method": "coons"}
    assert b.options == {"render": False}  # empty cells are left out


@pytest.mark.parametrize(
    ("text", "value"),
    [("true", True), ("False", False), ("7", 7), ("-2.5", -2.5), ("1e-3", 1e-3), ("Lt Lung", "Lt Lung"), ("", "")],
)
def test_coerce_value(text, value):
    got = coerce_value(text)
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize(("cell", "expected"), [
    ("triad", "triad"), ("a.png;b.png;c.png", ["a.png", "b.png", "c.png"]), ("only.png", ["only.png"])])
def test_photometric_select_is_triad_or_names_separated_by_semicolons(tmp_path, cell, expected):
    path = tmp_path / "jobs.csv"
    path.write_text(f"input,select\nbear,{cell}\n")
    (job,) = read_manifest(path, "photometric")
    assert job.options["select"] == expected
    path = tmp_path / "jobs.jsonl"
    path.write_text(json.dumps({"input": "bear", "select": expected}) + "\n")
    (job,) = read_manifest(path, "photometric")
    assert job.options["select"] == expected
