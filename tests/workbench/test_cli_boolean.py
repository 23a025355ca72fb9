"""Tests of ``workbench surfaces boolean``: files written, JSON volumes, errors as exit code 2."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surfaces.io import read_mesh, write_mesh
from surfaces.mesh import TriangleMesh
from surfaces.repair import check_solid
from tests.surfaces._shapes import box, icosphere
from workbench.cli import main


@pytest.fixture()
def pair(tmp_path):
    a, b = tmp_path / "A.ply", tmp_path / "B.stl"
    write_mesh(icosphere(1.0, (0, 0, 0), 3), a)
    write_mesh(icosphere(1.0, (0.7, 0.2, 0.0), 3), b)
    return a, b


@pytest.mark.parametrize("op", ["union", "intersection", "difference"])
def test_writes_mesh_and_summary(pair, tmp_path, op, capsys):
    a, b = pair
    out = tmp_path / f"C_{op}.obj"
    code = main(["surfaces", "boolean", str(a), str(b), "--op", op, "--out", str(out)])
    assert code == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    for key in ("op", "volume_a", "volume_b", "volume", "n_triangles", "watertight", "n_curves"):
        assert key in summary
    assert summary["op"] == op and summary["watertight"] and summary["n_curves"] == 1
    mesh = read_mesh(out)
    assert check_solid(mesh)["solid"]
    assert mesh.signed_volume() == pytest.approx(summary["volume"], rel=1e-6)
    printed = capsys.readouterr().out
    assert f"{summary['volume']:.6g}" in printed


def test_volumes_satisfy_inclusion_exclusion(pair, tmp_path):
    a, b = pair
    vol = {}
    for op in ("union", "intersection"):
        out = tmp_path / f"{op}.ply"
        assert main(["surfaces", "boolean", str(a), str(b), "--op", op, "--out", str(out)]) == 0
        vol[op] = json.loads(out.with_suffix(".json").read_text())
    s = vol["union"]
    total = s["volume_a"] + s["volume_b"]
    assert abs(s["volume"] + vol["intersection"]["volume"] - total) <= 1e-6 * total


def test_smooth_and_curves(pair, tmp_path):
    a, b = pair
    out, curves = tmp_path / "S.ply", tmp_path / "curves.json"
    args = ["surfaces", "boolean", str(a), str(b), "--op", "union", "--out", str(out)]
    assert main([*args, "--smooth", "1", "--curves", str(curves)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    smoothed = read_mesh(out)
    assert len(smoothed.triangles) == 4 * summary["n_triangles"]
    assert check_solid(smoothed)["solid"]
    assert summary["smooth"]["volume_smoothed"] == pytest.approx(smoothed.signed_volume(), rel=1e-6)
    lines = json.loads(curves.read_text())["curves"]
    assert len(lines) == 1 and lines[0]["closed"] and np.asarray(lines[0]["points"]).shape[1] == 3


def test_open_input_is_refused_then_repaired(tmp_path, capsys):
    m = icosphere(1.0, level=3)
    holed = TriangleMesh(m.vertices, np.delete(m.triangles, [5, 300], axis=0))
    a, b = tmp_path / "holed.ply", tmp_path / "box.ply"
    write_mesh(holed, a)
    write_mesh(box([0, 0, 0], [2, 2, 2]), b)
    out = tmp_path / "D.ply"
    args = ["surfaces", "boolean", str(a), str(b), "--op", "difference", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "holed.ply: not closed" in err and "--repair" in err
    assert not out.exists()
    assert main([*args, "--repair"]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["repairs"][str(a)]["filled_holes"] == 2


@pytest.mark.parametrize("suffix", [".ply", ".stl"])
def test_empty_result_replaces_an_older_mesh(tmp_path, capsys, suffix):
    """Disjoint solids: the empty answer is written over --out (no stale mesh survives), and said so."""
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    write_mesh(box([0, 0, 0], [1, 1, 1]), a)
    write_mesh(box([2, 0, 0], [3, 1, 1]), b)
    out = tmp_path / f"E{suffix}"
    assert main(["surfaces", "boolean", str(a), str(b), "--op", "union", "--out", str(out)]) == 0
    assert read_mesh(out).n_triangles == 24
    capsys.readouterr()
    assert main(["surfaces", "boolean", str(a), str(b), "--op", "intersection", "--out", str(out)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["empty"] and summary["volume"] == 0.0 and summary["out"] == str(out)
    assert summary["units"]["volume"] == "length^3"
    with pytest.raises(ValueError, match="no triangles"):
        read_mesh(out)
    captured = capsys.readouterr()
    assert captured.err == f"workbench: warning: the intersection is empty; {out} holds a mesh with no triangles\n"
    assert "(length units^3 of the inputs)" in captured.out and f"wrote {out} and" in captured.out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--out", "X.vtk"], "unsupported mesh format"),
        (["--out", "X.ply", "--smooth", "-1"], "must be >= 0"),
    ],
)
def test_bad_options(pair, tmp_path, extra, message, capsys):
    a, b = pair
    extra = [str(tmp_path / e) if e.startswith("X.") else e for e in extra]
    assert main(["surfaces", "boolean", str(a), str(b), "--op", "union", *extra]) == 2
    assert message in capsys.readouterr().err


def test_missing_file(tmp_path, capsys):
    code = main(
        [
            "surfaces",
            "boolean",
            str(tmp_path / "no.ply"),
            str(tmp_path / "no2.ply"),
            "--op",
            "union",
            "--out",
            str(tmp_path / "o.ply"),
        ]
    )
    assert code == 2 and "no such mesh file" in capsys.readouterr().err


def test_patch_files_as_input(tmp_path):
    from surfaces.coons import from_grid
    from surfaces.io import save_patches
    from surfaces.measure import volume

    th = np.linspace(0, np.pi, 9)
    ph = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    unit = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    pa = from_grid(unit * 10.0, closed_v=True)
    a, b = tmp_path / "a.npz", tmp_path / "b.ply"
    save_patches(pa, a)
    write_mesh(box([0, 0, 0], [20, 20, 20]), b)
    out = tmp_path / "quarter.ply"
    assert main(["surfaces", "boolean", str(a), str(b), "--op", "intersection", "--out", str(out)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    # one octant of the sphere, from the tessellation (8 x 8 per patch) of the patch model
    assert summary["volume"] == pytest.approx(volume(pa) / 8, rel=5e-3)
    assert summary["volume"] == pytest.approx(summary["volume_a"] / 8, rel=1e-9)
