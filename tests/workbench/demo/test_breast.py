"""Demo section 4b (breast structure set): folders, references, and the absent-data report."""

from __future__ import annotations

from pathlib import Path

from workbench.demo.breast import PALETTE, REFERENCES_CC, roi_folder, section_breast
from workbench.demo.context import Context

from .test_context import quick_context


def test_roi_folder_and_tables():
    ctx = Context(out=Path("/o"), quick=True, shared=Path("/s"), report=None)
    assert roi_folder(ctx, "Lt Lung") == Path("/o/ct/lt_lung")
    assert roi_folder(ctx, "Heart") == Path("/o/ct/heart")
    assert set(REFERENCES_CC) == set(PALETTE) == {"Heart", "Lt Lung"}
    assert all(400 < v < 450 for v in REFERENCES_CC["Heart"].values())


def test_absent_data_is_reported(tmp_path):
    ctx = quick_context(tmp_path)
    section_breast(ctx)
    assert list(ctx.unavailable) == ["CT: breast structure set"]
    assert "rtss.dcm" in ctx.unavailable["CT: breast structure set"]
    assert ctx.numbers["ct"] == {}
    html = ctx.report.write().read_text()
    assert html.count("not available") == 1 and "<img" not in html
