"""Lens distortion (OpenCV's model): images through the lens resampled to the pinhole camera."""

import cv2
import numpy as np
import pytest

from photometric.camera import camera_from_dict, intrinsic_matrix, make_camera, undistort_images
from surfaces.validate import InputError

SHAPE = (120, 160)
DIST = (-0.12, 0.03, 0.001, -0.0015, 0.0)


def _pattern(xn, yn):
    """A smooth scene as a function of the pinhole ray's normalised coordinates."""
    return 0.5 + 0.25 * np.sin(9 * xn) * np.cos(7 * yn)


def test_undistorted_images_match_the_pinhole_scene():
    cam = make_camera("perspective", focal_length_px=(170.0, 168.0), camera_height_mm=100.0,
                      principal_point_px=(81.2, 58.7), distortion=DIST)
    K = intrinsic_matrix(cam, SHAPE)
    h, w = SHAPE
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    # the distorted image: each sensor pixel shows the scene along its undistorted ray (OpenCV's iteration)
    pts = np.stack([cols.ravel(), rows.ravel()], axis=1)[:, None, :]
    und = cv2.undistortPoints(pts, K, np.array(DIST))[:, 0]
    distorted = _pattern(und[:, 0], und[:, 1]).reshape(h, w).astype(np.float32)
    out, seen = undistort_images(cam, distorted[None])
    truth = _pattern((cols - K[0, 2]) / K[0, 0], (rows - K[1, 2]) / K[1, 1])
    inner = seen.copy() if seen is not None else np.ones(SHAPE, bool)
    inner[:4], inner[-4:], inner[:, :4], inner[:, -4:] = False, False, False, False
    assert np.abs(out[0] - truth)[inner].max() < 0.01  # bilinear resampling of a smooth scene
    assert np.abs(distorted - truth)[inner].max() > 0.02  # the lens mattered


def test_distortion_round_trip_and_errors():
    cam = make_camera("perspective", focal_length_px=1000.0, camera_height_mm=200.0, distortion=[-0.03])
    assert cam.distortion == (-0.03, 0.0, 0.0, 0.0, 0.0)
    assert camera_from_dict(cam.to_dict((100, 100))) == make_camera(
        "perspective", focal_length_px=1000.0, camera_height_mm=200.0, principal_point_px=(49.5, 49.5),
        distortion=[-0.03])
    assert make_camera("perspective", focal_length_px=1000.0, camera_height_mm=200.0, distortion=[0, 0]).distortion \
        is None
    with pytest.raises(InputError, match="distortion"):
        make_camera("perspective", focal_length_px=1000.0, camera_height_mm=200.0, distortion=[0.1] * 6)
    with pytest.raises(InputError, match="perspective"):
        make_camera("orthographic", pixel_size_mm=0.1, distortion=[0.1])


def test_read_resamples_through_the_lens():
    from photometric import stages

    pos = np.array([[60.0, 0.0, 100.0], [-30.0, 52.0, 100.0], [-30.0, -52.0, 100.0]])
    images = np.full((3, 40, 50), 0.4, np.float32)
    inp = stages.read(images, light_positions=pos, camera="perspective", focal_length_px=60.0, camera_height_mm=150.0,
                      distortion=[0.2])
    assert inp.info["undistorted"][0] == 0.2
    assert inp.setup.camera.distortion == (0.2, 0.0, 0.0, 0.0, 0.0)
    # pincushion distortion: the pinhole corners' rays land outside the sensor and leave the mask
    assert not inp.data.mask[0, 0] and inp.data.mask[20, 25]
