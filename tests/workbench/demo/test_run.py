"""The demo's driver: sections in order, the figure index, report.html and demo.json."""

from __future__ import annotations

import json

import numpy as np
import pytest

from workbench.demo import run
from workbench.demo.context import Context

from ..test_demo import check_report


def _section_a(ctx: Context) -> None:
    ctx.report.section("A", "first")
    picture = np.zeros((8, 10, 3), np.uint8)
    picture[2:6, 3:7] = (200, 40, 40)
    ctx.report.figure(picture, "a-square", "a red square", ctx.cmd("demo", "--out", str(ctx.out)))
    ctx.numbers["a"] = {"value": np.float64(1.5)}
    ctx.step("a")


def _section_b(ctx: Context) -> None:
    ctx.missing("Section B", "its data is absent")


@pytest.mark.parametrize("quick", [True, False])
def test_run_demo_writes_report_and_numbers(tmp_path, monkeypatch, quick):
    calls = []
    monkeypatch.setattr(run, "SECTIONS", (lambda ctx: calls.append(ctx.quick), _section_a, _section_b))
    summary = run.run_demo(tmp_path / "out", quick=quick, shared=tmp_path / "data")
    assert calls == [quick]
    stored = json.loads((tmp_path / "out" / "demo.json").read_text())
    assert stored == json.loads(json.dumps(summary))
    assert stored["quick"] is quick and stored["a"] == {"value": 1.5}
    assert stored["shared_data"] == str(tmp_path / "data")
    assert stored["unavailable"] == {"Section B": "its data is absent"}
    assert stored["figures"] == [{"file": "figures/a-square.png", "caption": "a red square",
                                  "command": "workbench demo --out ."}]
    parsed = check_report(tmp_path / "out" / "report.html")
    assert len(parsed.images) == 1
    # the figure index and the table of sections that could not run
    assert "workbench demo --out ." in parsed.cells  # relative to the report's folder
    assert ["Section B", "its data is absent"] == parsed.cells[-2:]
    html = (tmp_path / "out" / "report.html").read_text()
    assert ("quick run" if quick else "full run") in html


def test_sections_in_report_order():
    names = [s.__name__ for s in run.SECTIONS]
    assert names == ["section_inspection", "section_accuracy", "section_real", "section_ct",
                     "section_breast"]
