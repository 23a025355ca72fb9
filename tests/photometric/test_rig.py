"""photometric.rig: flat-field gains, rig.json read and checked against the images."""

import json

import numpy as np
import pytest

from photometric.camera import make_camera, plane_points
from photometric.leds import point_lights
from photometric.rig import GAINS_FILE, RIG_FORMAT, Rig, check_rig, flat_field_gains, read_rig, rig_to_dict
from tests.photometric._render import ring

CAM = make_camera("perspective", focal_length_px=500.0, camera_height_mm=250.0)


def test_flat_field_gains_measure_irradiance_times_vignetting():
    """F_k = albedo * V * E_k(X0) * (l_k . z) on the plane, so the gain is V * E_k(X0)."""
    shape = (30, 40)
    pos = 160.0 * ring(3, 40.0)
    lights = point_lights(pos)
    X0 = plane_points(CAM, shape)
    rows, cols = np.mgrid[0:30, 0:40]
    vig = 1.0 - 0.002 * ((rows - 15) ** 2 + (cols - 20) ** 2) / 4
    flats, expect = [], []
    for P in pos:
        d = P - X0
        r = np.linalg.norm(d, axis=-1)
        E = (np.linalg.norm(P) / r) ** 2 * 1.7
        expect.append(vig * E)
        flats.append(0.7 * vig * E * d[..., 2] / r)
    gains = flat_field_gains(np.array(flats), lights, CAM, 0.7, smoothing_px=0)
    assert gains.dtype == np.float32 and gains.shape == (3,) + shape
    np.testing.assert_allclose(gains, np.array(expect), rtol=1e-5)
    smooth = flat_field_gains(np.array(flats), lights, CAM, 0.7)
    # a Gaussian of sigma 2 px shifts a curved field by sigma^2 / 2 times its Laplacian (0.4 % here)
    np.testing.assert_allclose(smooth[:, 5:-5, 5:-5], np.array(expect)[:, 5:-5, 5:-5], rtol=6e-3)


def test_flat_field_errors():
    lights = point_lights(160.0 * ring(3, 40.0))
    with pytest.raises(ValueError, match="2 flat-field image"):
        flat_field_gains(np.ones((2, 5, 5)), lights, CAM)
    with pytest.raises(ValueError, match="non-negative"):
        flat_field_gains(-np.ones((3, 5, 5)), lights, CAM)
    with pytest.raises(ValueError, match="point lights"):
        flat_field_gains(np.ones((3, 5, 5)), ring(3, 40.0), CAM)


def _write(folder, rig, gains_file=GAINS_FILE):
    doc = rig_to_dict(rig, gains_file)
    (folder / "rig.json").write_text(json.dumps(doc))
    if rig.gains is not None:
        np.savez(folder / gains_file, gains=rig.gains)
    return doc


def test_rig_json_round_trip(tmp_path):
    lights = point_lights(160.0 * ring(4, 40.0), mu=[1.0, 1.0, 0.5, 0.0])
    gains = np.random.default_rng(1).uniform(0.5, 1.0, (4, 6, 8)).astype(np.float32)
    rig = Rig(lights, CAM, (6, 8), np.ones((4, 3)), gains, 0.8, 2.0, {"method": "test", "residuals_mm": [0.1]})
    doc = _write(tmp_path, rig)
    assert doc["format"] == RIG_FORMAT and doc["version"] == 1
    assert doc["camera"] == {"model": "perspective", "focal_length_px": 500.0, "camera_height_mm": 250.0,
                             "principal_point_px": [3.5, 2.5]}
    assert doc["flat_field"] == {"gains": GAINS_FILE, "albedo": 0.8, "smoothing_px": 2.0}
    back = read_rig(tmp_path / "rig.json")
    np.testing.assert_array_equal(back.gains, gains)
    np.testing.assert_allclose(back.lights.positions, lights.positions)
    np.testing.assert_allclose(back.lights.mu, lights.mu)
    assert back.lights.mu_known and back.image_size == (6, 8) and back.flat_albedo == 0.8
    assert back.calibration == {"method": "test", "residuals_mm": [0.1]}
    check_rig(back, 4, (6, 8))
    with pytest.raises(ValueError, match="rig: 4 lights for 3 images"):
        check_rig(back, 3, (6, 8))
    with pytest.raises(ValueError, match="rig: calibrated for 6 x 8 px images, the images are 6 x 9 px"):
        check_rig(back, 4, (6, 9))


def test_rig_without_flat_field_and_unknown_mu(tmp_path):
    rig = Rig(point_lights(160.0 * ring(3, 40.0)), make_camera("orthographic", pixel_size_mm=0.1), (5, 5))
    doc = _write(tmp_path, rig)
    assert doc["flat_field"] is None and doc["lights"]["mu"] is None and doc["lights"]["axes"] is None
    back = read_rig(tmp_path / "rig.json")
    assert back.gains is None and not back.lights.mu_known and back.intensities is None


@pytest.mark.parametrize(
    "change, error, message",
    [
        ({"format": "other"}, ValueError, "is not a 'workbench-rig' file"),
        ({"version": 2}, ValueError, "version 2"),
        ({"image_size": [5]}, ValueError, "image_size"),
        ({"lights": {"positions_mm": [[0, 0, 100], [100, 0, -1], [0, 100, 100]]}}, ValueError, "below"),
        ({"camera": {"model": "perspective", "camera_height_mm": 200}}, ValueError, "focal-length-px"),
        ({"flat_field": {"gains": "nope.npz", "albedo": 0.5}}, FileNotFoundError, "nope.npz"),
    ],
)
def test_read_rig_errors(tmp_path, change, error, message):
    rig = Rig(point_lights(160.0 * ring(3, 40.0)), make_camera("orthographic", pixel_size_mm=0.1), (5, 5))
    doc = rig_to_dict(rig)
    doc.update(change)
    (tmp_path / "rig.json").write_text(json.dumps(doc))
    with pytest.raises(error, match=message):
        read_rig(tmp_path / "rig.json")


def test_read_rig_gains_of_the_wrong_shape(tmp_path):
    rig = Rig(point_lights(160.0 * ring(3, 40.0)), CAM, (5, 5), gains=np.ones((3, 5, 5), np.float32))
    _write(tmp_path, rig)
    np.savez(tmp_path / GAINS_FILE, gains=np.ones((3, 5, 6), np.float32))
    with pytest.raises(ValueError, match=r"shape \(3, 5, 6\), expected \(3, 5, 5\)"):
        read_rig(tmp_path / "rig.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="not valid JSON"):
        read_rig(tmp_path / "bad.json")
    with pytest.raises(FileNotFoundError):
        read_rig(tmp_path / "none.json")
