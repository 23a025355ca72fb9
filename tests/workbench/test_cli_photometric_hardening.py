"""``workbench photometric reconstruct`` on inputs that cannot give a result: one line, exit code 2.

Moved from tests/photometric/test_hardening.py (which keeps the library's side of each case):
the library's tests do not run the workbench.
"""

from __future__ import annotations

import json

import pytest

from photometric.lights import ring_lights
from photometric.stereo import MAX_CONDITION
from tests.photometric.test_hardening import _coplanar, _sphere_images, _write_pngs
from workbench.cli import main


def test_black_image_with_outliers_says_black(tmp_path, capsys):
    L = ring_lights(3, 45.0)
    images, _ = _sphere_images(L)
    images[0] = 0.0
    paths, lights = _write_pngs(tmp_path / "in", images, L)
    code = main(["photometric", "reconstruct", "--images", *paths, "--lights", lights, "--outliers",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "'000.png' is black" in err and "no pixel is selected" not in err
    assert not (tmp_path / "out").exists()


def test_lights_with_negative_z_are_called_that(tmp_path, capsys):
    L = ring_lights(3, 45.0)
    images, _ = _sphere_images(L)
    L_bad = L.copy()
    L_bad[1, 2] *= -1
    paths, lights = _write_pngs(tmp_path / "in", images, L_bad)
    code = main(["photometric", "reconstruct", "--images", *paths, "--lights", lights,
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "z < 0" in err and "mask" not in err


def test_nearly_coplanar_lights_refused_unless_forced(tmp_path, capsys):
    L = _coplanar(0.05)
    images, _ = _sphere_images(L, albedo=0.5)
    paths, lights = _write_pngs(tmp_path / "in", images + 0.2, L)
    args = ["photometric", "reconstruct", "--images", *paths, "--lights", lights]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "condition number" in err and "--force" in err
    assert not (tmp_path / "a").exists()
    assert main([*args, "--force", "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert "workbench: warning: lights: condition number" in err
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert summary["light_condition_number"] > MAX_CONDITION
    assert summary["light_condition_limits"] == {"warn": 10.0, "refuse_without_force": 100.0}
    assert any("condition number" in w for w in summary["warnings"])


def test_help_states_the_thresholds(capsys):
    with pytest.raises(SystemExit):
        main(["photometric", "reconstruct", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "above 100 (nearly coplanar lights; above 10 it is a warning" in text
    assert "z < 0" in text
