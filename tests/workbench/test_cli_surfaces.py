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


def _sphere_grid(radius=2.0):
    t, p = np.meshgrid(np.linspace(0, np.pi, 13), np.linspace(0, 2 * np.pi, 25), indexing="ij")
    return radius * np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)


@pytest.mark.parametrize("flip", [False, True])
def test_inward_surface_is_warned_with_the_way_to_flip_it(tmp_path, capsys, flip):
    """Poles first from the south (grid[::-1]): volume -33.5, one warning in coons and in info."""
    grid = _sphere_grid()
    np.save(tmp_path / "s.npy", grid[::-1] if flip else grid)
    out = tmp_path / "s.ply"
    assert main(["surfaces", "coons", str(tmp_path / "s.npy"), "--closed-v", "--out", str(out)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["watertight"] and summary["mesh_volume"] == pytest.approx((-1) ** flip * 32 / 3 * np.pi, rel=3e-3)
    assert summary["orientation"] == ("inward" if flip else "outward")
    assert summary["units"]["volume"] == "length^3"
    for argv in (["surfaces", "info", str(tmp_path / "s.npz")], ["surfaces", "info", str(out)]):
        first = capsys.readouterr().err
        warnings = [line for line in first.splitlines() if "warning" in line]
        if flip:
            assert len(warnings) == 1 and "oriented inward (volume -33" in warnings[0]
            assert warnings[0].startswith("workbench: warning: ") and "flip it by" in warnings[0]
        else:
            assert warnings == []
        assert main(argv) == 0
    err = capsys.readouterr().err
    assert ("triangles[:, ::-1]" in err) == flip


def test_grid_shape_and_memory_are_checked_before_loading(tmp_path, capsys):
    """A huge grid (sparse file of 9.6 GB) is refused from its header in a moment, as is a wrong shape."""
    from numpy.lib.format import open_memmap

    big = tmp_path / "big.npy"
    open_memmap(big, mode="w+", dtype=np.float64, shape=(20000, 20000, 3)).flush()
    out = tmp_path / "x.ply"
    assert main(["surfaces", "coons", str(big), "--out", str(out), "--max-memory", "4G"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "need about" in err and "more than --max-memory 4 GB" in err
    assert main(["surfaces", "coons", str(big), "--out", str(out)]) == 2  # default: half the machine
    assert "more than --max-memory" in capsys.readouterr().err
    wrong = tmp_path / "wrong.npy"
    open_memmap(wrong, mode="w+", dtype=np.float64, shape=(3, 20000, 20000)).flush()
    assert main(["surfaces", "coons", str(wrong), "--out", str(out)]) == 2
    assert "grid: expected shape (R, C, 3), got (3, 20000, 20000)" in capsys.readouterr().err
    np.save(tmp_path / "g.npy", _sphere_grid())
    np.save(tmp_path / "pu.npy", np.zeros((4, 4, 3)))
    grid = str(tmp_path / "g.npy")
    assert main(["surfaces", "coons", grid, "--pu", str(tmp_path / "pu.npy"), "--out", str(out)]) == 2
    assert "--pu: expected the grid's shape (13, 25, 3), got (4, 4, 3)" in capsys.readouterr().err
    assert main(["surfaces", "coons", str(tmp_path / "g.npy"), "--max-memory", "lots", "--out", str(out)]) == 2
    assert "--max-memory: expected a size" in capsys.readouterr().err
    assert not out.exists()


def test_coons_estimate_matches_what_it_writes(tmp_path, capsys):
    from workbench.commands.surfaces import coons_needs

    np.save(tmp_path / "g.npy", _sphere_grid()[:, :-1])  # without the closing repeat
    out = tmp_path / "s.ply"
    assert main(["surfaces", "coons", str(tmp_path / "g.npy"), "--closed-v", "--samples", "4", "--out", str(out),
                 "--max-memory", "64G"]) == 0
    needs = coons_needs((13, 24, 3), 4, False, True, ".ply")
    summary = json.loads(out.with_suffix(".json").read_text())
    assert needs["patches"] == summary["n_patches"]
    # the poles are welded afterwards (their collapsed triangles dropped): the estimate is an upper bound
    assert 0.95 * needs["triangles"] < summary["n_triangles"] <= needs["triangles"]
    assert 0.9 * needs["vertices"] < summary["n_vertices"] <= needs["vertices"]
    written = out.stat().st_size + out.with_suffix(".npz").stat().st_size
    assert written <= needs["output_bytes"]  # the .npz is compressed; the estimate is its raw size
    assert out.stat().st_size == pytest.approx(24 * summary["n_vertices"] + 13 * summary["n_triangles"], abs=300)
