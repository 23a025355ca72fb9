"""The working distance from the photometric residual: a closed-form rendering and the real 8-LED capture."""

import numpy as np
import pytest

from photometric.distance import estimate_camera_height, height_warning
from photometric.importers import CameraFrameCalibration, to_rig
from surfaces.validate import InputError

# an 8-LED ring 75 mm in front of the camera (camera frame: x right, y down, z forward), like nearps_hehe12's
ANGLES = np.deg2rad(np.arange(8) * 45.0 + 10.0)
S = np.stack([95 * np.cos(ANGLES), 95 * np.sin(ANGLES), np.full(8, 75.0)], axis=1)
DIR = np.stack([-0.6 * np.cos(ANGLES), -0.6 * np.sin(ANGLES), np.full(8, 0.8)], axis=1)
PHI = np.linspace(2.0e6, 3.5e6, 8)[:, None]
FX, FY, SHAPE = 200.0, 198.0, (60, 80)


def _render(height_mm: float) -> np.ndarray:
    """Images of a matte plate (albedo 0.6) across the optical axis, ``height_mm`` in front of the camera, lit by
    LEDs of radiance lobe cos^1: I = albedo Phi (a . (X - P) / |X - P|) (n . (P - X) / |P - X|) / |P - X|^2."""
    h, w = SHAPE
    cols, rows = np.meshgrid(np.arange(w) - (w - 1) / 2, np.arange(h) - (h - 1) / 2)
    X = np.stack([cols * height_mm / FX, rows * height_mm / FY, np.full(cols.shape, height_mm)], axis=-1)
    n = np.array([0.0, 0.0, -1.0])  # facing the camera
    imgs = []
    for p, a, phi in zip(S, DIR / np.linalg.norm(DIR, axis=1, keepdims=True), PHI[:, 0]):
        d = X - p
        r = np.linalg.norm(d, axis=-1)
        lobe = np.maximum(0.0, d @ a / r)
        imgs.append(0.6 * phi / 2.0e6 * 1e4 * lobe * np.maximum(0.0, (-d @ n) / r) / r**2)
    return np.array(imgs, np.float32)


def _rig(start_mm: float):
    cal = CameraFrameCalibration(S, DIR / np.linalg.norm(DIR, axis=1, keepdims=True), np.repeat(PHI, 3, axis=1),
                                 np.ones(8), (FX, FY), ((SHAPE[1] - 1) / 2, (SHAPE[0] - 1) / 2))
    return to_rig(cal, start_mm, SHAPE)


@pytest.mark.slow
def test_plate_distance_is_recovered():
    imgs = _render(180.0)
    assert 0.05 < imgs.max() < 1.0
    est = estimate_camera_height(imgs, _rig(150.0), binning=1)
    assert est.camera_height_mm == pytest.approx(180.0, abs=1.5)
    assert est.residual_rms < 1e-3 * imgs.max()  # the model is exact at the estimate
    assert np.isfinite(est.u_mm) and est.u_mm < 5.0
    assert height_warning(180.0, est) is None
    assert "camera height: the given 260 mm" in height_warning(260.0, est)


def test_errors():
    from dataclasses import replace

    from photometric.camera import make_camera

    rig = _rig(150.0)
    with pytest.raises(InputError, match="orthographic"):
        estimate_camera_height(_render(180.0), replace(rig, camera=make_camera("orthographic", pixel_size_mm=0.5)))
    with pytest.raises(InputError, match="7 images for 8 LEDs"):
        estimate_camera_height(_render(180.0)[:7], rig)
    with pytest.raises(InputError, match="LEDs' depth"):
        estimate_camera_height(_render(180.0), rig, bounds_mm=(50.0, 300.0))
