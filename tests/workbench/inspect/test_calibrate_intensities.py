"""``workbench inspect calibrate --intensity-images``: a rig without a flat field, its LED powers estimated.

The images come from the independent near-field renderer (datasets_synthetic.nearfield): a
matte plate under 8 LEDs 205-215 mm from the field centre with unequal power; the rig file
must hold the relative powers and the reconstruction with that rig must find the plate flat.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera
from datasets_synthetic.heightfields import AnalyticSurface
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import point_lights as render_lights
from photometric.pipeline import reconstruct
from workbench.cli import main

PIXEL_MM = 0.6


def _scene(tmp_path):
    n = 8
    az = np.radians(np.arange(n) * 45.0 + 10.0)
    d = np.linspace(205.0, 215.0, n)
    s = np.radians(45.0)
    pos = np.stack([d * np.sin(s) * np.cos(az), d * np.sin(s) * np.sin(az), d * np.cos(s)], axis=1)
    power = 1.0 + np.random.default_rng(7).uniform(-0.1, 0.1, n)
    r = render_near_field(AnalyticSurface(), orthographic_camera((80, 80), PIXEL_MM),
                          render_lights(pos, None, 0.0, power), 0.8, noise=0.001, bit_depth=16, seed=5)
    np.savetxt(tmp_path / "light_positions.txt", pos)
    files = []
    for k, img in enumerate(r.images):
        files.append(str(tmp_path / f"plate_{k}.npy"))
        np.save(files[-1], img)
    return pos, power, r.images, files



def _untilted_error(estimated, truth, positions) -> float:
    """Largest relative error of estimated LED powers after removing what a tilt of the whole field
    trades for: a factor ``exp(a + b x_k + c y_k)`` over the LEDs' directions (the semi-calibrated
    problem's near-ambiguity, fitted by least squares in the log)."""
    u = positions / np.linalg.norm(positions, axis=1, keepdims=True)
    A = np.column_stack([np.ones(len(u)), u[:, 0], u[:, 1]])
    r = np.log(np.asarray(estimated, float) / np.asarray(truth, float))
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    return float(np.max(np.abs(np.expm1(r - A @ coef))))

def _plane_rms_um(height, use) -> float:
    rows, cols = np.nonzero(use)
    A = np.stack([np.ones(rows.size), rows, cols], axis=1).astype(float)
    coef, *_ = np.linalg.lstsq(A, height[use], rcond=None)
    return 1e3 * float(np.sqrt(np.mean((height[use] - A @ coef) ** 2)))


def test_intensity_images_store_the_led_powers(tmp_path, capsys):
    pos, power, images, files = _scene(tmp_path)
    rig = tmp_path / "rig.json"
    args = ["inspect", "calibrate", "--light-positions", str(tmp_path / "light_positions.txt"), "--pixel-size",
            str(PIXEL_MM), "--intensity-images", *files, "--out", str(rig)]
    assert main(args) == 0
    assert "intensity" in capsys.readouterr().out
    doc = json.loads(rig.read_text())
    assert doc["flat_field"] is None or not doc["flat_field"]
    stored = np.asarray(doc["lights"]["intensities"], float)[:, 0]
    assert stored[0] == 1.0
    assert _untilted_error(stored, power, pos) < 0.01
    assert np.max(np.abs(stored / (power / power[0]) - 1.0)) < 0.01  # levelled: the plate is level
    assert doc["calibration"]["intensities"]["converged"]
    res = reconstruct(images, rig=str(rig))
    assert res.summary["intensities"]["source"] == "given"
    assert _plane_rms_um(res.height, res.valid) < 2.0
    with pytest.warns(UserWarning, match="205.0-215.0 mm"):
        plain = reconstruct(images, light_positions=pos, lights=pos / np.linalg.norm(pos, axis=1)[:, None],
                            pixel_size=PIXEL_MM)
    assert _plane_rms_um(plain.height, plain.valid) > 10.0


def test_intensity_images_refuse_a_flat_field(tmp_path, capsys):
    _, _, _, files = _scene(tmp_path)
    args = ["inspect", "calibrate", "--light-positions", str(tmp_path / "light_positions.txt"), "--pixel-size",
            str(PIXEL_MM), "--intensity-images", *files, "--flat", *files, "--out", str(tmp_path / "rig.json")]
    assert main(args) == 2
    assert "not both" in capsys.readouterr().err and not (tmp_path / "rig.json").exists()
