"""Demo section 4a (kidney phantom from contours) on its reduced (--quick) sizes."""

from __future__ import annotations

import json

from workbench.demo.ct import section_ct

from .test_context import parses, quick_context


def test_kidney_section(tmp_path):
    ctx = quick_context(tmp_path)
    section_ct(ctx)
    kidney = ctx.numbers["ct"]["kidney"]
    truth = json.loads((tmp_path / "ct" / "kidney" / "truth.json").read_text())
    assert kidney["volume_true_mm3"] == truth["volume_mm3"]
    assert kidney["n_contours"] == truth["n_contours"]
    assert abs(kidney["volume_error_percent"]) < 5.0
    assert kidney["surface_distance_mean_mm"] < 1.0
    assert (kidney["surface_distance_mean_mm"] <= kidney["surface_distance_rms_mm"]
            <= kidney["surface_distance_max_mm"])
    assert kidney["watertight"]
    summary = json.loads((tmp_path / "ct" / "kidney_surface" / "summary.json").read_text())
    assert summary["volume_mm3"] == kidney["volume_reconstructed_mm3"]
    (figure,) = ctx.report.figures
    assert figure.file == "figures/ct-kidney.png" and parses(figure.command)
    assert "--spacing 4.0" in figure.command and "--rays 32" in figure.command
