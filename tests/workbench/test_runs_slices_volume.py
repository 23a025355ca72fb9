"""Whole-structure volumes through ``workbench.runs.slices`` and the CLI.

Moved from tests/slices/test_volume.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import json

import pytest

from datasets_synthetic.phantoms import make_phantom
from slices.volume import format_volume


def test_the_command_prints_the_volume_with_its_caps_and_u(tmp_path, capsys):
    from workbench.cli import main

    ph = make_phantom("ellipsoid", a=8.0, b=6.0, c=7.0)
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"contours": [{"z": c["z"], "points": c["points"].tolist()}
                                             for c in ph.contours(2.0, n_points=48, offset_mm=0.3)]}))
    assert main(["slices", "reconstruct", str(path), "--out", str(tmp_path / "o"), "--no-render"]) == 0
    out = capsys.readouterr().out
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert "caps trend: whole structure" in out and "(k = 2)" in out
    assert format_volume(s["volume_mm3"], s["volume_U_mm3"]) in out
    assert s["volume_by_caps_mm3"]["trend"] == s["volume_mm3"]
    assert abs(s["volume_mm3"] / ph.volume_mm3 - 1) < 0.01
    assert s["volume_uncertainty"]["budget"]["contour_position"]["u_mm3"] > 0


@pytest.mark.slow
def test_breast_heart_and_lung_stay_inside_their_planning_references(shared_data, tmp_path):
    from workbench.runs.slices import reconstruct_to_folder

    rs = shared_data / "rtstruct_breast" / "rtss.dcm"
    heart = reconstruct_to_folder(rs, tmp_path / "h", roi="Heart", render=False, reference=False, samples=2)
    # dicompyler-core 432.84 (end planes half), the planning system's DVH 437.46, the dose grid 440.23 cc
    assert 432.84 * 0.99 <= heart["volume_ml"] <= 440.23 * 1.01
    assert heart["caps"] == "trend" and heart["volume_caps"].startswith("caps trend")
    lung = reconstruct_to_folder(rs, tmp_path / "l", roi="Lt Lung", render=False, reference=False, samples=1)
    assert lung["volume_ml"] == pytest.approx(1995.18, rel=0.01)  # dicompyler-core, holes subtracted
