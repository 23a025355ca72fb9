"""``photometric reconstruct``'s defaults for real captures: --outliers on from 6 images, --no-outliers off."""

import json

import pytest

from workbench.cli import main


@pytest.mark.parametrize(("flag", "expected", "error"), [([], True, 7.736), (["--no-outliers"], False, 9.600),
                                                         (["--outliers"], True, 7.736)])
def test_bear_outlier_default_and_its_switch(shared_data, tmp_path, flag, expected, error):
    out = tmp_path / "bear"
    assert main(["photometric", "reconstruct", str(shared_data / "diligent_bear"), "--surface", "coons", *flag,
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outliers"] is expected
    assert summary["mean_angular_error_deg"] == pytest.approx(error, abs=0.0015)


def test_surface_none_is_a_normals_and_height_run(shared_data, tmp_path, capsys):
    out = tmp_path / "none"
    assert main(["photometric", "reconstruct", str(shared_data / "diligent_bear"), "--triad", "--surface", "none",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["surface"] == "none" and "surface" not in summary["timings_s"] and "mesh" not in summary
    assert not (out / "surface.ply").exists() and (out / "height.npy").is_file() and (out / "normals.npy").is_file()
    assert "surface.ply" not in summary["files"]
    assert summary["mean_angular_error_deg"] == pytest.approx(11.735, abs=0.0015)
    assert "no surface model" in capsys.readouterr().out
