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


# ---- the mesh readers (numpy parsers of PLY, STL and OBJ) ------------------------------------------


def _small_torus(normals: bool = True, colors: bool = False) -> TriangleMesh:
    mesh = tessellate(from_grid(_torus(nu=8, nv=6), closed_u=True, closed_v=True), 2)
    if not normals:
        mesh.vertex_normals = None
    if colors:
        rng = np.random.default_rng(3)
        mesh.vertex_colors = rng.integers(0, 256, (mesh.n_vertices, 3)) / 255.0
    return mesh


def _same_mesh(back: TriangleMesh, mesh: TriangleMesh, normals: bool, colors: bool, atol: float = 1e-6) -> None:
    np.testing.assert_allclose(back.vertices, mesh.vertices, atol=atol)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    assert (back.vertex_normals is not None) == normals and (back.vertex_colors is not None) == colors
    if normals:
        np.testing.assert_allclose(back.vertex_normals, mesh.vertex_normals, atol=1e-6)
    if colors:
        np.testing.assert_allclose(back.vertex_colors, mesh.vertex_colors, atol=1e-9)


@pytest.mark.parametrize("normals", [False, True])
@pytest.mark.parametrize("colors", [False, True])
def test_ply_round_trip_keeps_normals_and_colours(tmp_path, normals, colors):
    mesh = _small_torus(normals, colors)
    _same_mesh(read_mesh(write_mesh(mesh, tmp_path / "t.ply")), mesh, normals, colors)


@pytest.mark.parametrize("ascii_", [False, True])
@pytest.mark.parametrize("colors", [False, True])
def test_ply_written_by_open3d_reads_as_open3d_reads_it(tmp_path, ascii_, colors):
    """open3d is the independent writer, and its own reader is the reference on a valid file."""
    o3d = pytest.importorskip("open3d")
    mesh = _small_torus(True, colors)
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices),
                                  o3d.utility.Vector3iVector(mesh.triangles.astype(np.int32)))
    m.vertex_normals = o3d.utility.Vector3dVector(mesh.vertex_normals)
    if colors:
        m.vertex_colors = o3d.utility.Vector3dVector(mesh.vertex_colors)
    path = tmp_path / "o3d.ply"
    assert o3d.io.write_triangle_mesh(str(path), m, write_ascii=ascii_)
    assert path.read_bytes().startswith(b"ply\nformat " + (b"ascii" if ascii_ else b"binary_little_endian"))
    back = read_mesh(path)
    ref = o3d.io.read_triangle_mesh(str(path))
    np.testing.assert_array_equal(back.vertices, np.asarray(ref.vertices))
    np.testing.assert_array_equal(back.triangles, np.asarray(ref.triangles))
    np.testing.assert_allclose(back.vertex_normals, np.asarray(ref.vertex_normals), atol=1e-12)
    if colors:
        np.testing.assert_allclose(back.vertex_colors, np.asarray(ref.vertex_colors), atol=1e-12)
    _same_mesh(back, mesh, True, colors, atol=1e-5)


@pytest.mark.parametrize("suffix, encoding", [(".ply", "binary"), (".ply", "ascii"), (".stl", "binary"),
                                              (".stl", "ascii"), (".obj", None)])
def test_meshes_exported_by_trimesh_read_back(tmp_path, suffix, encoding):
    trimesh = pytest.importorskip("trimesh")
    mesh = _small_torus(normals=False)
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=False)
    exchange = trimesh.exchange
    data = {(".ply", "binary"): lambda: exchange.ply.export_ply(tm, encoding="binary"),
            (".ply", "ascii"): lambda: exchange.ply.export_ply(tm, encoding="ascii"),
            (".stl", "binary"): lambda: exchange.stl.export_stl(tm),
            (".stl", "ascii"): lambda: exchange.stl.export_stl_ascii(tm),
            (".obj", None): lambda: exchange.obj.export_obj(tm, include_normals=False)}[suffix, encoding]()
    path = tmp_path / f"t{suffix}"
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    back = read_mesh(path)
    assert back.n_triangles == mesh.n_triangles and back.n_vertices == mesh.n_vertices
    assert back.is_watertight()
    assert back.signed_volume() == pytest.approx(mesh.signed_volume(), rel=1e-6)
    assert back.surface_area() == pytest.approx(float(tm.area), rel=1e-6)
    if suffix != ".stl":  # indexed formats keep the vertex order
        np.testing.assert_allclose(back.vertices, mesh.vertices, atol=1e-6)
        np.testing.assert_array_equal(back.triangles, mesh.triangles)


def test_stl_and_obj_round_trips(tmp_path):
    mesh = _small_torus()
    stl = read_mesh(write_mesh(mesh, tmp_path / "t.stl"))
    assert stl.n_vertices == mesh.n_vertices and stl.is_watertight()
    assert stl.signed_volume() == pytest.approx(mesh.signed_volume(), rel=1e-6)
    # the welded STL's normals are the area-weighted ones of its triangles: close to the surface's own
    assert np.einsum("ij,ij->i", stl.vertex_normals, stl.vertex_normals) == pytest.approx(1.0)
    _same_mesh(read_mesh(write_mesh(mesh, tmp_path / "t.obj")), mesh, True, False, atol=1e-8)


def test_big_endian_ply_reads_as_little_endian(tmp_path):
    mesh = _small_torus(normals=False)
    header = (f"ply\nformat binary_big_endian 1.0\nelement vertex {mesh.n_vertices}\n"
              "property double x\nproperty double y\nproperty double z\n"
              f"element face {mesh.n_triangles}\nproperty list uchar uint vertex_index\nend_header\n").encode()
    faces = np.empty(mesh.n_triangles, [("n", "u1"), ("i", ">u4", (3,))])
    faces["n"], faces["i"] = 3, mesh.triangles
    path = tmp_path / "be.ply"
    path.write_bytes(header + mesh.vertices.astype(">f8").tobytes() + faces.tobytes())
    back = read_mesh(path)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)


@pytest.mark.parametrize("binary", [False, True])
def test_ply_polygons_of_mixed_sizes_become_fans(tmp_path, binary):
    """Runs of quads, triangles and a pentagon (longer than the first read block) with extra properties."""
    rng = np.random.default_rng(0)
    verts = rng.random((40, 3))
    sizes = [4] * 150 + [3] * 5 + [5] + [4] * 70 + [3]
    faces = [rng.choice(40, n, replace=False) for n in sizes]
    expected = np.array([[f[0], f[i], f[i + 1]] for f in faces for i in range(1, len(f) - 1)])
    header = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment mixed polygons",
              "element vertex 40", "property float x", "property float y", "property float z",
              "property uchar quality", f"element face {len(faces)}", "property short flag",
              "property list uchar int vertex_indices", "property float weight", "element extra 2",
              "property list int double values", "end_header"]
    if binary:
        vert = np.empty(40, [("p", "<f4", (3,)), ("q", "u1")])
        vert["p"], vert["q"] = verts, 7
        body = vert.tobytes() + b"".join(np.int16(-1).tobytes() + np.uint8(len(f)).tobytes()
                                         + f.astype("<i4").tobytes() + np.float32(0.5).tobytes() for f in faces)
        body += np.int32(2).tobytes() + np.ones(2).tobytes() + np.int32(0).tobytes()
    else:
        lines = [" ".join(f"{c!r}" for c in v.astype(np.float32).tolist()) + " 7" for v in verts]
        lines += [f"-1 {len(f)} " + " ".join(map(str, f)) + " 0.5" for f in faces]
        lines += ["2 1.0 1.0", "0"]
        body = ("\n".join(lines) + "\n").encode()
    path = tmp_path / "poly.ply"
    path.write_bytes(("\n".join(header) + "\n").encode() + body)
    back = read_mesh(path)
    np.testing.assert_array_equal(back.triangles, expected)
    np.testing.assert_allclose(back.vertices, verts, atol=1e-7)


def test_obj_faces_with_slashes_negative_indices_and_polygons(tmp_path):
    text = """# a unit square as a quad, then a triangle by negative indices
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vn 0 0 1
f 1/1/1 2/1/1 3/1/1 4/1/1
v 0 0 1
f -1//1 -5//1 -4//1
g other
f 1/1 2/1 5/1
"""
    path = tmp_path / "s.obj"
    path.write_text(text)
    back = read_mesh(path)
    assert back.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [4, 0, 1], [0, 1, 4]]
    assert back.vertex_normals is None  # the last face has no normal references
    assert back.surface_area() == pytest.approx(1.0 + 2 * 0.5)
    path.write_text(text.replace("f 1/1 2/1 5/1\n", ""))
    np.testing.assert_array_equal(read_mesh(path).vertex_normals, np.tile([0.0, 0, 1], (5, 1)))


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "outside the 3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "OBJ counts from 1"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "outside the 3"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "'v' line has 2 numbers"),
    ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", "not a readable OBJ file"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no triangles could be read"),
])
def test_bad_obj_files_say_what_is_wrong(tmp_path, text, message):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(InputError, match=rf"bad.obj: .*{message}"):
        read_mesh(path)


def _tetra_bytes(tmp_path, suffix: str, **kwargs) -> bytes:
    tetra = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
                         **kwargs)
    return write_mesh(tetra, tmp_path / f"seed{suffix}").read_bytes()


def _ascii_ply(tmp_path) -> bytes:
    o3d = pytest.importorskip("open3d")
    m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.eye(3)), o3d.utility.Vector3iVector([[0, 1, 2]]))
    path = tmp_path / "a.ply"
    o3d.io.write_triangle_mesh(str(path), m, write_ascii=True)
    return path.read_bytes()


@pytest.mark.parametrize("suffix", [".ply", ".stl"])
def test_binary_mesh_cut_at_every_byte_is_an_input_error(tmp_path, suffix):
    """The sizes in the header (PLY) or the triangle count (STL) tell a cut file, at any length."""
    data = _tetra_bytes(tmp_path, suffix, vertex_colors=np.full((4, 3), 0.5))
    path = tmp_path / f"cut{suffix}"
    for end in range(len(data)):
        path.write_bytes(data[:end])
        with pytest.raises(InputError, match=r"cut\.(ply|stl): "):
            read_mesh(path)


@pytest.mark.parametrize("kind", ["binary ply", "ascii ply", "stl", "ascii stl", "obj"])
def test_damaged_mesh_files_read_or_give_an_input_error(tmp_path, kind):
    """Every cut, and every byte set to 0 or 255 (binary) or '9' or '-' (text): a mesh or an InputError."""
    trimesh = pytest.importorskip("trimesh")
    suffix = {"binary ply": ".ply", "ascii ply": ".ply", "stl": ".stl", "ascii stl": ".stl", "obj": ".obj"}[kind]
    if kind == "ascii ply":
        data = _ascii_ply(tmp_path)
    elif kind == "ascii stl":
        tetra = TriangleMesh(np.eye(3), [[0, 1, 2]])
        data = trimesh.exchange.stl.export_stl_ascii(trimesh.Trimesh(tetra.vertices, tetra.triangles)).encode()
    else:
        data = _tetra_bytes(tmp_path, suffix)
    path = tmp_path / f"bad{suffix}"
    values = (ord("9"), ord("-")) if "ascii" in kind or kind == "obj" else (0, 255)
    copies = [data[:end] for end in range(len(data))]
    for where in range(len(data)):
        copies += [data[:where] + bytes([value]) + data[where + 1:] for value in values]
    for copy in copies:
        path.write_bytes(copy)
        try:
            mesh = read_mesh(path)
        except InputError as err:
            assert str(err).startswith(str(path))
        else:
            assert mesh.n_triangles > 0 and np.isfinite(mesh.vertices).all()


_PLY_HEAD = ("ply\nformat {fmt} 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list {count} int vertex_indices\nend_header\n")


@pytest.mark.parametrize("data, message", [
    (b"plx\n", "not a PLY file"),
    (b"ply\nformat ascii 1.0\nelement vertex 3\n", "no 'end_header' line"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar").replace("format ascii 1.0\n", "") + "0 0 0\n", "no 'format' line"),
    (_PLY_HEAD.format(fmt="binary_middle_endian", count="uchar"), "header line 2"),
    (_PLY_HEAD.format(fmt="ascii", count="float"), "header line 8 .*INTTYPE"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar").replace("element vertex 3", "element vertex three"), "header line 3"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 0 0\n0 1 0\n3.5 0 1 2\n", "face record 0 has a negative"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", "not vertex indices"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "refers to vertex 3"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", "1 of 3 vertices have a NaN"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 0 0\n0 1 0\n", "file ends after 0 of 1 face"),
    (_PLY_HEAD.format(fmt="ascii", count="uchar") + "0 0 0\n1 0 zero\n", "not a readable PLY file"),
    (_PLY_HEAD.format(fmt="binary_little_endian", count="char").encode() + np.zeros(9, "<f4").tobytes()
     + b"\xfd" + np.zeros(3, "<i4").tobytes(), "face record 0 has a negative"),
])
def test_bad_ply_files_say_what_is_wrong(tmp_path, data, message):
    path = tmp_path / "bad.ply"
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    with pytest.raises(InputError, match=rf"bad.ply: .*{message}"):
        read_mesh(path)
