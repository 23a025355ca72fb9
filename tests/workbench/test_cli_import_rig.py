"""``workbench photometric import-rig`` and ``reconstruct --rig light.mat``: another tool's calibration, run."""

import json

import numpy as np
import pytest
from scipy.io import savemat

from photometric.rig import read_rig
from workbench.cli import main

S = np.array([[-50.0, -78.0, 74.0], [54.0, -82.0, 73.0], [-82.0, -31.0, 75.0], [92.0, 38.0, 74.0]])
DIR = np.array([[0.6, 0.5, 0.6], [-0.3, 0.7, 0.7], [0.9, 0.3, 0.4], [-0.9, -0.4, 0.3]])


@pytest.fixture
def queau(tmp_path):
    savemat(tmp_path / "light.mat", {"S": S, "Dir": DIR, "Phi": np.full((4, 1), 2.5e6), "mu": np.ones((4, 1))})
    savemat(tmp_path / "camera.mat", {"K": np.array([[3043.0, 0, 970.6], [0, 3026.0, 762.7], [0, 0, 1.0]]).T})
    return tmp_path


def test_import_rig_writes_the_rig_frame(queau, tmp_path, capsys):
    out = tmp_path / "rig.json"
    assert main(["photometric", "import-rig", str(queau / "light.mat"), "--camera-height", "210",
                 "--image-size", "1200,1920", "--out", str(out)]) == 0
    rig = read_rig(out)
    assert np.allclose(rig.lights.positions, np.stack([S[:, 0], -S[:, 1], 210 - S[:, 2]], axis=1))
    assert rig.camera.principal_point_px == pytest.approx((969.6, 761.7))
    assert (rig.camera.focal_length_px, rig.camera.fy) == (3043.0, 3026.0)
    doc = json.loads(out.read_text())
    assert doc["calibration"]["source"]["format"] == "queau"
    text = capsys.readouterr().out
    assert "3043.00 x 3026.00 px" in text and "(0-based)" in text
    # overrides: the axes from a file, fx and fy, a 0-based principal point
    np.savetxt(tmp_path / "axes.txt", S)
    assert main(["photometric", "import-rig", str(queau), "--camera-height", "210", "--image-size", "1200,1920",
                 "--led-axes", str(tmp_path / "axes.txt"), "--focal-length-px", "3000,2990",
                 "--principal-point-px", "959.5,599.5", "--out", str(out)]) == 0
    rig = read_rig(out)
    assert np.allclose(rig.lights.axes, (S * [1, -1, -1]) / np.linalg.norm(S, axis=1, keepdims=True))
    assert (rig.camera.focal_length_px, rig.camera.fy, rig.camera.principal_point_px) == (3000.0, 2990.0,
                                                                                          (959.5, 599.5))


def test_import_rig_needs_the_distance_or_the_images(queau, tmp_path, capsys):
    assert main(["photometric", "import-rig", str(queau), "--image-size", "1200,1920",
                 "--out", str(tmp_path / "rig.json")]) == 2
    assert "--camera-height" in capsys.readouterr().err
    assert not (tmp_path / "rig.json").exists()


@pytest.mark.slow
def test_real_capture_runs_from_its_own_files(shared_data, tmp_path, capsys):
    """nearps_hehe12 in one command: its light.mat/camera.mat, ambient frame and mask; the working distance is
    estimated (its data README: the residual is lowest near 200 mm)."""
    d = shared_data / "nearps_hehe12"
    images = [str(d / f"photometric_sample_raw_{k:04d}.png") for k in range(1, 9)]
    code = main(["photometric", "reconstruct", "--images", *images, "--rig", str(d / "light.mat"),
                 "--mask", str(d / "photometric_sample_mask_raw.png"),
                 "--ambient", str(d / "photometric_sample_raw_ambient.png"), "--out", str(tmp_path / "out")])
    assert code == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    wd = summary["working_distance"]
    assert 185.0 < wd["camera_height_mm"] < 215.0
    assert 0 < wd["u_mm"] < 10.0 and wd["U_k2_mm"] == pytest.approx(2 * wd["u_mm"])
    assert summary["camera"]["camera_height_mm"] == pytest.approx(wd["camera_height_mm"])
    assert summary["camera"]["focal_length_y_px"] == pytest.approx(3026.46, abs=0.01)
    assert any("dark capture" in w for w in summary["warnings"])
    assert summary["rig_source"]["source"]["format"] == "queau"
    assert "working distance:" in capsys.readouterr().out
