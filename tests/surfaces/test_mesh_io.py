"""Tessellation, welding and mesh files."""

import numpy as np
import pytest

from surfaces.bezier import BezierPatches
from surfaces.coons import from_grid
from surfaces.io import load_patches, read_mesh, save_patches, write_mesh
from surfaces.view import to_open3d
from surfaces.measure import area, flux_z, volume
from surfaces.mesh import TriangleMesh, merge_meshes, tessellate


def _torus(R=3.0, r=1.0, nu=24, nv=12):
    a = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    b = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    A, B = np.meshgrid(a, b, indexing="ij")
    return np.stack([(R + r * np.cos(B)) * np.cos(A), (R + r * np.cos(B)) * np.sin(A), r * np.sin(B)], -1)


def test_doubly_closed_torus_is_watertight_with_exact_counts():
    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    mesh = tessellate(patches, 4)
    assert mesh.n_vertices == 24 * 4 * 12 * 4
    assert mesh.n_triangles == 2 * mesh.n_vertices
    assert mesh.is_watertight() and mesh.is_oriented()
    v = volume(patches)
    assert abs(v) == pytest.approx(2 * np.pi**2 * 3.0 * 1.0, rel=5e-3)
    assert mesh.signed_volume() == pytest.approx(v, rel=5e-3)  # same orientation as the patches
    assert flux_z(patches) == pytest.approx(v, rel=1e-9)  # closed: every field gives the volume
    assert area(patches) == pytest.approx(4 * np.pi**2 * 3.0, rel=2e-3)


def test_open_grid_shares_seam_vertices():
    x, y = np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="ij")
    patches = from_grid(np.stack([x, y, np.sin(x) * np.cos(y)], -1))
    mesh = tessellate(patches, 5)
    assert mesh.n_vertices == (3 * 5 + 1) * (2 * 5 + 1)
    assert len(mesh.boundary_edges()) == 2 * (3 * 5 + 2 * 5)
    assert not mesh.is_watertight()
    assert mesh.is_oriented()
    assert np.all(mesh.face_normals()[:, 2] > 0)  # du x dv = +z for x along u, y along v


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


def test_triangle_mesh_validation():
    with pytest.raises(ValueError, match="triangles: indices"):
        TriangleMesh(np.eye(3), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="vertices"):
        TriangleMesh(np.eye(2), np.array([[0, 1, 1]]))


def test_open3d_conversion_and_patch_files(tmp_path):
    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    n_vertices = tessellate(patches, 2).n_vertices
    o3 = to_open3d(patches, samples=2, colors=np.tile([0.2, 0.4, 0.6], (n_vertices, 1)))
    assert o3.is_watertight()
    assert len(o3.vertex_normals) == len(o3.vertices)
    path = save_patches(patches, tmp_path / "p.npz")
    back = load_patches(path)
    assert isinstance(back, BezierPatches) and back.closed_u and back.closed_v
    np.testing.assert_array_equal(back.control, patches.control)


def test_merge_meshes_offsets_indices():
    a = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    b = TriangleMesh(np.eye(3) + 1, np.array([[0, 1, 2]]))
    m = merge_meshes([a, b])
    assert m.n_vertices == 6 and m.triangles[1].tolist() == [3, 4, 5]


def test_written_files_have_ordinary_permissions(tmp_path):
    import os

    mesh = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    path = write_mesh(mesh, tmp_path / "a.ply")
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
