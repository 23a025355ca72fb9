"""A phantom's files: contours, surface sample, truth, and the optional DICOM series and structure set."""

from __future__ import annotations

import json

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom, write_phantom


def test_write_phantom_json(tmp_path):
    ph = make_phantom("lobes")
    truth = write_phantom(tmp_path, ph, spacing=3.0, pixel=1.0, fmt="json", n_surface=500)
    data = json.loads((tmp_path / "contours.json").read_text())
    assert data["units"] == "mm"
    assert {"z", "points"} <= set(data["contours"][0])
    assert len(data["contours"]) == truth["n_contours"]
    stored = json.loads((tmp_path / "truth.json").read_text())
    for key in ("volume_mm3", "volume_between_end_planes_mm3", "area_mm2"):
        assert stored[key] == pytest.approx(getattr(ph, key) if key != "volume_between_end_planes_mm3"
                                            else truth[key])
    assert np.load(tmp_path / "surface_points.npy").shape == (500, 3)
    assert not (tmp_path / "ct").exists()


def test_write_phantom_rtstruct_and_kidney_accuracy(tmp_path):
    ph = make_phantom("kidney")
    truth = write_phantom(tmp_path, ph, spacing=10.0, pixel=2.0, fmt="rtstruct", n_points=24, n_surface=100, seed=7)
    assert truth["files"] == {"contours": "contours.json", "truth": "truth.json",
                              "surface_points": "surface_points.npy", "ct": "ct", "rtstruct": "rtstruct.dcm"}
    assert truth["area_accuracy_mm2"] == ph.area_accuracy_mm2
    assert (truth["format"], truth["seed"], truth["pixel_mm"]) == ("rtstruct", 7, 2.0)
    assert len(list((tmp_path / "ct").iterdir())) == truth["ct"]["n_slices"] and (tmp_path / "rtstruct.dcm").is_file()
    assert json.loads((tmp_path / "truth.json").read_text()) == json.loads(json.dumps(truth))
    lo, hi = truth["points_per_contour"]
    assert 8 <= lo <= hi


def test_write_phantom_refuses_bad_input(tmp_path):
    with pytest.raises(ValueError, match="phantom: expected a Phantom"):
        write_phantom(tmp_path, "ring", 2.0, 1.0)
    with pytest.raises(ValueError, match="fmt"):
        write_phantom(tmp_path, make_phantom("ring"), 2.0, 1.0, fmt="nifti")
    with pytest.raises(ValueError, match="pixel"):
        write_phantom(tmp_path, make_phantom("ring"), 2.0, 0.0)
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        write_phantom(tmp_path / "file", make_phantom("ring"), 2.0, 1.0)
