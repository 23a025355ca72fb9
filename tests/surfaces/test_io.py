"""Files (surfaces.io): meshes, patch models, PNG pictures, JSON and atomic writes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surfaces.bezier import BezierPatches
from surfaces.coons import from_grid
from surfaces.io import (
    atomic_path,
    atomic_write_text,
    jsonable,
    load_patches,
    read_mesh,
    save_npy,
    save_patches,
    write_json,
    write_mesh,
    write_png,
)
from surfaces.mesh import TriangleMesh, tessellate
from surfaces.validate import InputError
from tests.surfaces.test_mesh import _torus


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl"])
def test_mesh_files_round_trip(tmp_path, suffix):
    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    mesh = tessellate(patches, 3)
    path = write_mesh(mesh, tmp_path / f"torus{suffix}")
    back = read_mesh(path)
    assert back.n_vertices == mesh.n_vertices
    assert back.n_triangles == mesh.n_triangles
    assert back.is_watertight()
    assert back.signed_volume() == pytest.approx(mesh.signed_volume(), rel=1e-5)
    assert not list(tmp_path.glob(".*"))  # no temporary files left


def test_write_mesh_rejects_unknown_format_and_missing_folder(tmp_path):
    mesh = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="unsupported mesh format"):
        write_mesh(mesh, tmp_path / "a.xyz")
    with pytest.raises(FileNotFoundError):
        write_mesh(mesh, tmp_path / "missing" / "a.ply")
    with pytest.raises(FileNotFoundError):
        read_mesh(tmp_path / "none.ply")


def test_written_files_have_ordinary_permissions(tmp_path):
    import os

    mesh = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    path = write_mesh(mesh, tmp_path / "a.ply")
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_patch_files_round_trip(tmp_path):
    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    path = save_patches(patches, tmp_path / "p.npz")
    back = load_patches(path)
    assert isinstance(back, BezierPatches) and back.closed_u and back.closed_v
    np.testing.assert_array_equal(back.control, patches.control)
    with pytest.raises(FileNotFoundError):
        load_patches(tmp_path / "none.npz")


def test_write_mesh_tessellates_patches(tmp_path):
    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    back = read_mesh(write_mesh(patches, tmp_path / "t.ply", samples=2))
    assert back.n_triangles == tessellate(patches, 2).n_triangles and back.is_watertight()


def test_save_png_roundtrip(tmp_path):
    import cv2

    img = np.zeros((10, 12, 3), np.uint8)
    img[..., 0] = 200
    path = write_png(tmp_path / "sub" / "a.png", img)
    back = cv2.imread(str(path))
    assert back.shape == (10, 12, 3) and back[0, 0, 2] == 200 and back[0, 0, 0] == 0
    assert [p.name for p in path.parent.iterdir()] == ["a.png"]
    with pytest.raises(ValueError, match="dtype|uint8"):
        write_png(tmp_path / "b.png", img.astype(float))


def test_json_npy_and_atomic_writes(tmp_path):
    data = {"a": np.float32(1.5), "b": np.arange(3), "c": (np.bool_(True), tmp_path)}
    assert jsonable(data) == {"a": 1.5, "b": [0, 1, 2], "c": [True, str(tmp_path)]}
    path = write_json(tmp_path / "x.json", data)
    assert json.loads(path.read_text())["b"] == [0, 1, 2]
    arr = np.arange(6, dtype=np.int16).reshape(2, 3)
    back = np.load(save_npy(tmp_path / "a.npy", arr))
    assert back.dtype == np.int16 and np.array_equal(back, arr)
    atomic_write_text(tmp_path / "t.txt", "hello")
    assert (tmp_path / "t.txt").read_text() == "hello"
    with pytest.raises(RuntimeError):
        with atomic_path(tmp_path / "t.txt") as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert (tmp_path / "t.txt").read_text() == "hello"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npy", "t.txt", "x.json"]


@pytest.mark.parametrize("suffix", [".ply", ".stl"])
def test_mesh_files_written_in_blocks_are_the_same_bytes(tmp_path, suffix, monkeypatch):
    import surfaces.io

    mesh = tessellate(from_grid(_torus(), closed_u=True, closed_v=True), 3)
    mesh.vertex_colors = np.full((mesh.n_vertices, 3), 0.5)
    whole = write_mesh(mesh, tmp_path / f"whole{suffix}").read_bytes()
    monkeypatch.setattr(surfaces.io, "WRITE_BLOCK", 7)  # many small blocks, a ragged last one
    assert write_mesh(mesh, tmp_path / f"blocks{suffix}").read_bytes() == whole
    back = read_mesh(tmp_path / f"blocks{suffix}")
    assert back.n_triangles == mesh.n_triangles


def test_write_mesh_with_arguments_reversed_names_them(tmp_path):
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(TypeError, match=r"path: expected a file name .* got TriangleMesh; the order is write_mesh"):
        write_mesh(tmp_path / "t.ply", mesh)
    assert list(tmp_path.iterdir()) == []


def test_read_mesh_of_a_broken_file_is_one_error_and_no_chatter(tmp_path, capfd):
    """A cut file says where it ends, in one InputError naming the file; nothing is printed."""
    path = write_mesh(TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]), tmp_path / "t.ply")
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(InputError, match=r"t.ply: file ends after 0 of 1 face records"):
        read_mesh(path)
    captured = capfd.readouterr()
    assert captured.err == "" and captured.out == ""
