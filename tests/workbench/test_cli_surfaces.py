"""The ``workbench`` entry point and ``workbench surfaces`` commands."""

import json
import subprocess
import sys

import numpy as np
import pytest

from workbench.cli import main


def _torus_grid(path):
    a = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    b = np.linspace(0, 2 * np.pi, 10, endpoint=False)
    A, B = np.meshgrid(a, b, indexing="ij")
    grid = np.stack([(3 + np.cos(B)) * np.cos(A), (3 + np.cos(B)) * np.sin(A), np.sin(B)], -1)
    np.save(path, grid)


def test_coons_command_writes_mesh_patches_and_summary(tmp_path, capsys):
    _torus_grid(tmp_path / "g.npy")
    out = tmp_path / "t.ply"
    assert main(["surfaces", "coons", str(tmp_path / "g.npy"), "--closed-u", "--closed-v", "--out", str(out)]) == 0
    summary = json.loads((tmp_path / "t.json").read_text())
    assert summary["watertight"] and summary["n_patches"] == 200
    assert abs(summary["volume"]) == pytest.approx(2 * np.pi**2 * 3, rel=1e-2)
    assert (tmp_path / "t.npz").is_file() and out.is_file()
    assert main(["surfaces", "info", str(tmp_path / "t.npz")]) == 0
    info = json.loads(capsys.readouterr().out.split("\n", 1)[1])
    assert info["n_patches"] == 200
    assert main(["surfaces", "convert", str(out), "--out", str(tmp_path / "t.stl")]) == 0
    assert (tmp_path / "t.stl").stat().st_size == 84 + 50 * summary["n_triangles"]


def test_bad_input_is_one_line_and_exit_code_2(tmp_path, capsys):
    assert main(["surfaces", "coons", str(tmp_path / "missing.npy"), "--out", str(tmp_path / "x.ply")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("workbench: error:") and "missing.npy" in err and "\n" not in err
    np.save(tmp_path / "bad.npy", np.zeros((1, 5, 3)))
    assert main(["surfaces", "coons", str(tmp_path / "bad.npy"), "--out", str(tmp_path / "x.ply")]) == 2
    assert "at least 2x2" in capsys.readouterr().err
    assert not (tmp_path / "x.ply").exists()


def test_console_script_help_and_usage_errors():
    run = subprocess.run([sys.executable, "-m", "workbench", "--help"], capture_output=True, text=True)
    assert run.returncode == 0
    for group in ("surfaces", "photometric", "slices", "synth"):
        assert group in run.stdout
    run = subprocess.run([sys.executable, "-m", "workbench", "surfaces", "coons"], capture_output=True, text=True)
    assert run.returncode == 2 and "Traceback" not in run.stderr
