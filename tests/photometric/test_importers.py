"""Calibrations of other tools (Quéau's light.mat/camera.mat, their text form) read into the rig frame."""

import cv2
import numpy as np
import pytest
from scipy.io import savemat

from photometric.camera import make_camera, pixel_rays
from photometric.importers import CameraFrameCalibration, camera_to_rig_points, read_calibration, read_queau, to_rig
from photometric.rig import Rig, at_camera_height
from surfaces.validate import InputError

S = np.array([[-50.0, -78.0, 74.0], [54.0, -82.0, 73.0], [-82.0, -31.0, 75.0], [92.0, 38.0, 74.0]])
DIR = -S / np.linalg.norm(S, axis=1, keepdims=True) + np.array([0.0, 0.0, 1.5])
DIR /= np.linalg.norm(DIR, axis=1, keepdims=True)
PHI = np.array([[2.5e6], [2.6e6], [3.8e6], [3.9e6]])
FX, FY, CX1, CY1 = 3043.0, 3026.0, 970.6, 762.7  # principal point as MATLAB writes it (1-based)


def _write_queau(folder, transposed=True):
    K = np.array([[FX, 0, CX1], [0, FY, CY1], [0, 0, 1.0]])
    savemat(folder / "light.mat", {"S": S, "Dir": DIR, "Phi": PHI, "mu": np.ones((4, 1))})
    savemat(folder / "camera.mat", {"K": K.T if transposed else K})


def test_queau_files_in_the_rig_frame(tmp_path):
    _write_queau(tmp_path)
    cal = read_calibration(tmp_path)
    assert cal.source["k_transposed"] and cal.focal_length_px == (FX, FY)
    assert cal.principal_point_px == pytest.approx((CX1 - 1, CY1 - 1))
    rig = to_rig(cal, 200.0, (1200, 1920))
    assert np.allclose(rig.lights.positions, np.stack([S[:, 0], -S[:, 1], 200.0 - S[:, 2]], axis=1))
    assert np.allclose(rig.lights.axes, DIR * [1, -1, -1])
    assert rig.camera.focal_length_px == FX and rig.camera.fy == FY
    # intensities: Phi / |P|^2 relative (radiant intensities kept when the plane moves)
    e = PHI[:, 0] / np.sum(rig.lights.positions**2, axis=1)
    assert np.allclose(rig.intensities[:, 0], e / e.max())
    # a K stored the usual way gives the same camera
    other = tmp_path / "plain"
    other.mkdir()
    _write_queau(other, transposed=False)
    assert read_queau(other / "light.mat", other / "camera.mat").principal_point_px == cal.principal_point_px


def test_pixel_of_a_camera_frame_point_matches_opencv(tmp_path):
    """OpenCV projects a camera-frame point with K (0-based); the rig camera's ray through that pixel
    passes through the converted point."""
    _write_queau(tmp_path)
    cal = read_calibration(tmp_path / "light.mat")
    rig = to_rig(cal, 250.0, (1200, 1920))
    K0 = np.array([[FX, 0, CX1 - 1], [0, FY, CY1 - 1], [0, 0, 1.0]])
    pts = np.array([[12.0, -30.0, 240.0], [-40.0, 25.0, 260.0], [5.0, 3.0, 250.0]])
    px, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K0, None)
    px = px[:, 0]
    origins, rays = pixel_rays(rig.camera, (1200, 1920), px[:, 1], px[:, 0])
    target = camera_to_rig_points(pts, 250.0)
    for o, d, x in zip(origins, rays, target):
        t = (x - o) @ d
        assert np.linalg.norm(o + t * d - x) < 1e-9


def test_text_tables_read_like_the_mat_files(tmp_path):
    _write_queau(tmp_path)
    np.savetxt(tmp_path / "led_positions.txt", S)
    np.savetxt(tmp_path / "led_directions.txt", DIR)
    np.savetxt(tmp_path / "light_intensities.txt", np.repeat(PHI, 3, axis=1))
    np.savetxt(tmp_path / "led_mu.txt", np.ones(4))
    np.savetxt(tmp_path / "K.txt", np.array([[FX, 0, CX1], [0, FY, CY1], [0, 0, 1.0]]))
    text_dir = tmp_path / "text"
    text_dir.mkdir()
    for name in ("led_positions.txt", "led_directions.txt", "light_intensities.txt", "led_mu.txt", "K.txt"):
        (tmp_path / name).rename(text_dir / name)
    a, b = read_calibration(tmp_path), read_calibration(text_dir)
    assert b.source["format"] == "text"
    for name in ("positions_mm", "axes", "phi", "mu"):
        assert np.allclose(getattr(a, name), getattr(b, name))
    assert a.principal_point_px == b.principal_point_px and a.focal_length_px == b.focal_length_px
    assert read_calibration(text_dir, k_origin=0).principal_point_px == (CX1, CY1)


def test_bad_files_say_what_is_wrong(tmp_path):
    savemat(tmp_path / "light.mat", {"Dir": DIR})
    savemat(tmp_path / "camera.mat", {"K": np.eye(3)})
    with pytest.raises(InputError, match="lacks \\['S'\\]"):
        read_calibration(tmp_path / "light.mat")
    savemat(tmp_path / "light.mat", {"S": S})
    savemat(tmp_path / "camera.mat", {"K": np.array([[FX, 0, 0], [3.0, FY, 0], [CX1, CY1, 1.0]])})  # skew, transposed
    with pytest.raises(InputError, match="skewed"):
        read_calibration(tmp_path)
    _write_queau(tmp_path)
    with pytest.raises(InputError, match="below the reference plane"):
        to_rig(read_calibration(tmp_path), 70.0, (10, 10))
    with pytest.raises(FileNotFoundError):
        read_calibration(tmp_path / "nothing.mat")


def test_moving_the_reference_plane_keeps_radiant_intensity():
    cam = make_camera("perspective", focal_length_px=1000.0, camera_height_mm=200.0)
    cal_rig = to_rig(CameraFrameCalibration(S, DIR, np.repeat(PHI, 3, axis=1),
                                            np.ones(4), (FX, FY), (960.0, 600.0)),
                     200.0, (1200, 1920))
    moved = at_camera_height(cal_rig, 260.0)
    assert np.allclose(moved.lights.positions[:, 2] - cal_rig.lights.positions[:, 2], 60.0)
    radiant = cal_rig.intensities[:, 0] * np.sum(cal_rig.lights.positions**2, axis=1)
    assert np.allclose(moved.intensities[:, 0] * np.sum(moved.lights.positions**2, axis=1), radiant)
    back = at_camera_height(moved, 200.0)
    assert np.allclose(back.lights.positions, cal_rig.lights.positions)
    assert np.allclose(back.intensities, cal_rig.intensities)
    with pytest.raises(InputError, match="perspective"):
        at_camera_height(Rig(cal_rig.lights, make_camera("orthographic", pixel_size_mm=0.1), (4, 4)), 100.0)
    with pytest.raises(InputError, match="flat-field"):
        at_camera_height(Rig(cal_rig.lights, cam, (4, 4), gains=np.ones((4, 4, 4), np.float32)), 100.0)


def test_real_capture_calibration(shared_data):
    """nearps_hehe12's own light.mat and camera.mat (the data README states fx 3043, fy 3026, principal point
    (970.6, 762.7) 1-based, camera frame x right, y down, z forward)."""
    cal = read_calibration(shared_data / "nearps_hehe12")
    assert len(cal) == 8 and cal.source["k_transposed"]
    assert cal.focal_length_px == pytest.approx((3043.08, 3026.46), abs=0.01)
    assert cal.principal_point_px == pytest.approx((969.61, 761.66), abs=0.01)
    rig = to_rig(cal, 200.0, (1200, 1920))
    pos, axes = rig.lights.positions, rig.lights.axes
    assert np.all(pos[:, 2] > 100) and np.all(axes[:, 2] < 0)  # above the part, shining down
    # each LED leans towards the optical axis: its axis' horizontal part points back across the axis
    assert np.all(np.sum(axes[:, :2] * -pos[:, :2], axis=1) > 0)


def test_led_axes_reach_the_solve(tmp_path):
    from photometric import stages

    pos = np.array([[60.0, 0.0, 100.0], [-30.0, 52.0, 100.0], [-30.0, -52.0, 100.0]])
    axes = np.array([[0.0, 0.0, -1.0], [0.1, 0.0, -1.0], [0.0, 0.1, -1.0]])
    np.savetxt(tmp_path / "axes.txt", axes)
    images = np.full((3, 8, 8), 0.3, np.float32)
    inp = stages.read(images, light_positions=pos, led_axes=tmp_path / "axes.txt", led_mu=1.0, pixel_size=0.1)
    assert np.allclose(inp.setup.lights.axes, axes / np.linalg.norm(axes, axis=1, keepdims=True))
    assert inp.setup.lights.mu.tolist() == [1.0, 1.0, 1.0]
    with pytest.raises(InputError, match="led_axes"):
        stages.read(images, lights=pos / np.linalg.norm(pos, axis=1, keepdims=True), led_axes=axes)
