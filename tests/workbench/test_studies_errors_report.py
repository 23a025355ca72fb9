"""workbench.studies.errors_report: report.json, report.md and the plots in one folder."""

from __future__ import annotations

import json

import pytest

from photometric.lights import ring_lights
from workbench.studies.errors_analysis import analyse
from workbench.studies.errors_report import write_report


@pytest.fixture(scope="module")
def report():
    return analyse(ring_lights(3, 45.0), deviation_max=2.0, grid=7, samples=200, crack=False)


@pytest.mark.slow
def test_files_and_json(report, tmp_path):
    files = write_report(report, tmp_path / "out")
    out = tmp_path / "out"
    assert files["json"] == "report.json" and files["markdown"] == "report.md"
    text = (out / "report.json").read_text()
    assert text.endswith("}\n")
    stored = json.loads(text)
    assert "_arrays" not in stored and stored["plots"] == files["plots"]
    assert stored["tolerances"] == json.loads(json.dumps(report["tolerances"]))
    assert stored["configuration"]["condition_number"] == pytest.approx(report["configuration"]["condition_number"])
    md = (out / "report.md").read_text()
    for name in files["plots"]:
        assert (out / name).is_file() and f"({name})" in md


def test_bad_report_and_folder(report, tmp_path):
    with pytest.raises(ValueError, match="report"):
        write_report({"inputs": {}}, tmp_path)
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError, match="out_dir"):
        write_report(report, tmp_path / "file")
