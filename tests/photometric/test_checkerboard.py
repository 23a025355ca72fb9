"""Checkerboard camera calibration against boards rendered through a distorting lens (OpenCV's own model)."""

import cv2
import numpy as np
import pytest

from photometric.camera import calibrate_checkerboard
from surfaces.validate import InputError

H, W = 360, 480
K = np.array([[520.0, 0.0, 243.5], [0.0, 515.0, 176.2], [0.0, 0.0, 1.0]])
DIST = np.array([-0.10, 0.03, 0.0008, -0.0005, 0.0])
COLS, ROWS, SQ = 8, 5, 12.0


def _view(rvec, tvec, sub=3):
    """What the sensor sees: each (sub-)pixel's undistorted ray meets the board plane; black and white squares
    (the board's (COLS + 1) x (ROWS + 1) squares on a white margin), averaged over sub x sub samples."""
    R, _ = cv2.Rodrigues(np.asarray(rvec, float))
    t = np.asarray(tvec, float)
    off = (np.arange(sub) + 0.5) / sub - 0.5
    rows, cols = np.mgrid[0:H, 0:W].astype(np.float64)
    acc = np.zeros((H, W))
    for dy in off:
        for dx in off:
            pts = np.stack([(cols + dx).ravel(), (rows + dy).ravel()], axis=1)[:, None, :]
            xn = cv2.undistortPoints(pts, K, DIST)[:, 0]
            ray = np.concatenate([xn, np.ones((len(xn), 1))], axis=1)
            n = R[:, 2]
            s = (n @ t) / (ray @ n)
            xb = (ray * s[:, None] - t) @ R  # board coordinates (R^T (X - t))
            i, j = np.floor(xb[:, 0] / SQ), np.floor(xb[:, 1] / SQ)
            on = (i >= -1) & (i <= COLS - 1) & (j >= -1) & (j <= ROWS - 1)
            acc += np.where(on & ((i + j) % 2 == 0), 0.1, 0.9).reshape(H, W)
    return (acc / sub**2).astype(np.float32)


POSES = [((0.15, -0.2, 0.02), (-45.0, -25.0, 260.0)), ((-0.25, 0.1, -0.05), (-40.0, -30.0, 280.0)),
         ((0.3, 0.25, 0.1), (-50.0, -20.0, 300.0)), ((-0.1, -0.35, 0.0), (-35.0, -28.0, 250.0)),
         ((0.05, 0.3, -0.1), (-55.0, -35.0, 290.0)), ((0.0, 0.0, 0.0), (-42.0, -24.0, 240.0))]


@pytest.mark.slow
def test_camera_and_distortion_are_recovered():
    views = [_view(r, t) for r, t in POSES]
    cam, info = calibrate_checkerboard(views, (COLS, ROWS), SQ)
    assert info["views"] == len(POSES) and info["rms_reprojection_px"] < 0.2
    assert cam.focal_length_px == pytest.approx(K[0, 0], rel=0.01) and cam.fy == pytest.approx(K[1, 1], rel=0.01)
    assert cam.principal_point_px == pytest.approx((K[0, 2], K[1, 2]), abs=2.0)
    # k1 and k2 trade off with each other and with the principal point; the lens is judged by the reprojection
    # RMS above and by its sign and size: barrel, like the true one
    assert cam.distortion[0] < -0.05
    # the camera height: the first board's plane distance (board on the reference plane)
    R, _ = cv2.Rodrigues(np.array(POSES[0][0]))
    assert cam.camera_height_mm == pytest.approx(abs((-R.T @ np.array(POSES[0][1]))[2]), rel=0.01)


def test_errors():
    flat = np.full((60, 80), 0.5, np.float32)
    with pytest.raises(InputError, match="image 0: no 8 x 5 inner corners"):
        calibrate_checkerboard([flat] * 3, (COLS, ROWS), SQ)
    with pytest.raises(InputError, match="board"):
        calibrate_checkerboard([flat] * 3, (1, 5), SQ)
