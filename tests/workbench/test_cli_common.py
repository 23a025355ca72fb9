"""Tests of :mod:`workbench.commands.common`, the helpers every sub-command module shares."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from surfaces.bezier import BezierPatches
from surfaces.coons import from_grid
from surfaces.io import save_patches, write_mesh
from surfaces.mesh import TriangleMesh, tessellate
from workbench.commands.common import add_command, load_npy, mesh_out, parse_vector, read_model, write_summary


@pytest.fixture(scope="module")
def patches() -> BezierPatches:
    u, v = np.meshgrid(np.linspace(0, 1, 4), np.linspace(0, 2, 5), indexing="ij")
    return from_grid(np.stack([u, v, u * v], axis=-1))


def test_add_command_sets_help_description_and_action():
    parser = argparse.ArgumentParser(prog="workbench")
    sub = parser.add_subparsers()
    add_command(sub, "one", lambda args: 3, help="first")
    two = add_command(sub, "two", lambda args: 4, help="second", description="the second command", epilog="E")
    assert (two.description, two.epilog, two.prog) == ("the second command", "E", "workbench two")
    assert sub.choices["one"].description == "first"
    args = parser.parse_args(["one"])
    assert args.func(args) == 3


def test_read_model_by_suffix(tmp_path, patches):
    save_patches(patches, tmp_path / "s.npz")
    mesh = tessellate(patches, 2)
    for suffix in (".ply", ".obj", ".stl"):
        write_mesh(mesh, tmp_path / f"s{suffix}")
        back = read_model(tmp_path / f"s{suffix}")
        assert isinstance(back, TriangleMesh) and len(back.triangles) == len(mesh.triangles)
    model = read_model(str(tmp_path / "s.npz"))
    assert isinstance(model, BezierPatches)
    np.testing.assert_array_equal(model.control, patches.control)


def test_read_model_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="gone.ply: no such mesh file"):
        read_model(tmp_path / "gone.ply")
    with pytest.raises(FileNotFoundError, match="gone.npz: no such patch file"):
        read_model(tmp_path / "gone.npz")
    (tmp_path / "x.vtk").write_text("vtk")
    with pytest.raises(ValueError, match="x.vtk: unsupported mesh format"):
        read_model(tmp_path / "x.vtk")


def test_load_npy(tmp_path):
    np.save(tmp_path / "g.npy", np.arange(6.0).reshape(2, 3))
    np.testing.assert_array_equal(load_npy(tmp_path / "g.npy", "grid"), np.arange(6.0).reshape(2, 3))
    with pytest.raises(FileNotFoundError, match=r"--pu: .*nope.npy does not exist"):
        load_npy(tmp_path / "nope.npy", "--pu")
    (tmp_path / "text.npy").write_text("not an array")
    with pytest.raises(ValueError, match=r"--twist: .*text.npy is not a readable .npy file"):
        load_npy(tmp_path / "text.npy", "--twist")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match="grid: .* is not a readable .npy file"):  # no pickles
        load_npy(tmp_path / "obj.npy", "grid")


def test_mesh_out(tmp_path):
    assert mesh_out(tmp_path / "A.PLY") == tmp_path / "A.PLY"
    assert mesh_out(str(tmp_path / "a.stl"), "--mesh") == tmp_path / "a.stl"
    with pytest.raises(ValueError, match=r"--out: unsupported mesh format '\.png'; use \.ply, \.obj or \.stl"):
        mesh_out(tmp_path / "a.png")
    with pytest.raises(ValueError, match="unsupported mesh format ''"):
        mesh_out(tmp_path / "mesh")
    with pytest.raises(FileNotFoundError, match="--mesh: folder .*missing does not exist"):
        mesh_out(tmp_path / "missing" / "a.obj", "--mesh")


@pytest.mark.parametrize("text", ["1,2", "1,2,3,4", "a,b,c", "nan,0,1", "1,inf,0", ""])
def test_parse_vector_rejects(text):
    with pytest.raises(ValueError, match=f"--target: expected three .*{text!r}"):
        parse_vector(text, "--target")


def test_parse_vector():
    v = parse_vector(" 1e-3, -2 ,3", "--eye")
    assert v.dtype == np.float64 and v.shape == (3,)
    np.testing.assert_array_equal(v, [0.001, -2.0, 3.0])


def test_write_summary_creates_its_folder(tmp_path):
    path = write_summary(tmp_path / "a" / "b" / "s.json", {"n": np.int64(3), "area": np.float64(0.5),
                                                            "watertight": np.bool_(True), "v": np.zeros(2)})
    assert path == tmp_path / "a" / "b" / "s.json"
    assert json.loads(path.read_text()) == {"n": 3, "area": 0.5, "watertight": True, "v": [0.0, 0.0]}
    assert path.read_text().endswith("}\n") and sorted(p.name for p in path.parent.iterdir()) == ["s.json"]
