"""The lot report shows each worst part's overlay at its own size: its labels keep their pixels."""

from __future__ import annotations

import re

import cv2

from workbench.batch import Job, key_figures
from workbench.batch.results import result_row, write_results
from workbench.inspect.overlay import REPORT_WIDTH, TEXT_PX
from workbench.inspect.part import inspect_part
from workbench.inspect.report import write_inspection_report


def test_report_shows_overlays_unshrunk(small_lot, tmp_path):
    out = tmp_path / "out"
    rows = []
    for pid in ("scratch_over", "dent_under"):
        figures = inspect_part(small_lot["parts"] / pid, out / pid, small_lot["rig"], small_lot["spec"])
        rows.append(result_row(Job(pid, "inspect", str(small_lot["parts"] / pid)), "ok", "", 1.0,
                               key_figures("inspect", figures)))
    write_results(out / "results.csv", rows)
    page = write_inspection_report(out, "workbench inspect run ...").read_text()
    assert "scratch_over: fail" in page and "U (k = 2)" in page
    column = int(re.search(r"max-width: (\d+)px", page).group(1))  # the page's column, CSS pixels
    for pid in ("scratch_over", "dent_under"):
        shown = cv2.imread(str(out / "figures" / f"overlay_{pid}.png"))
        drawn = cv2.imread(str(out / pid / "overlay.png"))
        # the report embeds the overlay as drawn, and it fits the column with its border and the figure's margin
        assert shown.shape == drawn.shape and shown.shape[1] == REPORT_WIDTH
        assert REPORT_WIDTH + 2 + 16 <= column
    assert TEXT_PX >= 11  # so every label reads at >= 11 px in the report
    # issue 37: no figure printed to 10 digits (0.09158301113); the depth to 4 decimals without a U
    assert not re.search(r"\d\.\d{7,}", page)
    depth = key_figures("inspect", figures)["max_depth_mm"]
    assert f">{depth:.4f}<" in page
