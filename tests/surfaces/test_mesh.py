"""Triangle meshes (surfaces.mesh): tessellation, welding, volumes and normals."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.bezier import BezierPatches
from surfaces.coons import from_grid
from surfaces.measure import area, flux_z, volume
from surfaces.mesh import (
    TriangleMesh,
    as_mesh,
    compact,
    merge_meshes,
    signed_volume,
    tessellate,
    vertex_normals,
    weld,
    weld_map,
)
from tests.surfaces._shapes import box, icosphere


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


def test_triangle_mesh_validation():
    with pytest.raises(ValueError, match="triangles: indices"):
        TriangleMesh(np.eye(3), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="vertices"):
        TriangleMesh(np.eye(2), np.array([[0, 1, 1]]))


def test_merge_meshes_offsets_indices():
    a = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    b = TriangleMesh(np.eye(3) + 1, np.array([[0, 1, 2]]))
    m = merge_meshes([a, b])
    assert m.n_vertices == 6 and m.triangles[1].tolist() == [3, 4, 5]


OCTAHEDRON = (
    np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float),
    np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]),
)


@pytest.mark.parametrize("offset", [0.0, 1e6, (1e6 + 0.1, -2e6 + 0.3, 3e6 + 0.7)])
def test_signed_volume_far_from_the_origin(offset):
    """Closed forms: a 2 x 3 x 4 box (24) and the octahedron |x|+|y|+|z| <= 2 (32/3), moved away."""
    shift = np.broadcast_to(np.asarray(offset, float), (3,))
    b = box([0, 0, 0], [2, 3, 4])
    octa_v, octa_t = OCTAHEDRON
    for verts, tris, exact in ((b.vertices + shift, b.triangles, 24.0), (2 * octa_v + shift, octa_t, 32 / 3)):
        assert signed_volume(verts, tris) == pytest.approx(exact, rel=1e-12)
        assert TriangleMesh(verts, tris).signed_volume() == pytest.approx(exact, rel=1e-12)
        assert signed_volume(verts, tris[:, ::-1]) == pytest.approx(-exact, rel=1e-12)
        assert signed_volume(verts, tris, per_triangle=True).sum() == pytest.approx(exact, rel=1e-12)


def test_uncentred_formula_would_fail_far_away():
    """Why the volume is centred: the plain sum over origin tetrahedra cancels catastrophically."""
    b = box([0, 0, 0], [2, 3, 4])
    shifted = b.vertices + [1e6 + 0.1, -2e6 + 0.3, 3e6 + 0.7]
    c = shifted[b.triangles]
    plain = np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0
    assert abs(plain - 24.0) > 1e-5
    assert TriangleMesh(shifted, b.triangles).signed_volume() == pytest.approx(24.0, rel=1e-14)


def test_signed_volume_validates():
    with pytest.raises(ValueError, match="triangles: vertex indices"):
        signed_volume(np.eye(3), [[0, 1, 3]])
    assert signed_volume(np.eye(3), np.zeros((0, 3), int)) == 0.0


def test_vertex_normals_of_a_sphere_point_outward():
    ball = icosphere(2.0, (1.0, 2.0, 3.0), level=3)
    n = vertex_normals(ball.vertices, ball.triangles)
    radial = (ball.vertices - [1.0, 2.0, 3.0]) / 2.0
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.degrees(np.arccos(np.clip(np.sum(n * radial, axis=1), -1, 1))).max() < 1.0
    # one face: all three normals are the face normal; an unused vertex gets zero
    one = vertex_normals([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]], [[0, 1, 2]])
    assert np.allclose(one, [[0, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, 0]])
    mesh = TriangleMesh(ball.vertices, ball.triangles)
    face = mesh.face_normals()
    assert np.allclose(np.linalg.norm(face, axis=1), 1.0)
    assert mesh.surface_area() == pytest.approx(0.5 * np.linalg.norm(mesh.face_normals(False), axis=1).sum())


def test_weld_map_merges_chains_of_close_points():
    pts = np.array([[0.0, 0, 0], [0.6, 0, 0], [1.2, 0, 0], [5.0, 0, 0], [0.0, 0, 0]])
    assert weld_map(pts, 0.7).tolist() == [0, 0, 0, 3, 0]
    assert weld_map(pts, 0.7, candidates=[3, 4]).tolist() == [0, 1, 2, 3, 4]
    assert weld_map(pts, 0.7, candidates=[0, 4]).tolist() == [0, 1, 2, 3, 0]


def test_weld_and_compact():
    b = box([0, 0, 0], [1, 1, 1])
    soup = TriangleMesh(b.vertices[b.triangles].reshape(-1, 3), np.arange(36).reshape(-1, 3))
    welded = weld(soup)
    assert welded.n_vertices == 8 and welded.is_watertight() and welded.signed_volume() == pytest.approx(1.0)
    extra = TriangleMesh(np.vstack([b.vertices, [[9.0, 9.0, 9.0]]]), b.triangles,
                         vertex_colors=np.full((9, 3), 0.5))
    small = compact(extra)
    assert small.n_vertices == 8 and small.vertex_colors.shape == (8, 3)
    np.testing.assert_array_equal(small.triangles, b.triangles)


def test_as_mesh_accepts_mesh_like_inputs():
    import open3d as o3d

    b = box([0, 0, 0], [1, 1, 1])
    assert as_mesh(b) is b
    from_tuple = as_mesh((b.vertices, b.triangles.astype(np.int32)))
    assert from_tuple.triangles.dtype == np.int64 and from_tuple.signed_volume() == pytest.approx(1.0)
    o3 = o3d.geometry.TriangleMesh.create_box(1.0, 2.0, 3.0)
    o3.compute_vertex_normals()
    m = as_mesh(o3)
    assert m.vertex_normals is not None and m.signed_volume() == pytest.approx(6.0)
    u = np.linspace(0, 1, 4)
    patch = BezierPatches(np.stack(np.meshgrid(u, u, [0.0], indexing="ij"), -1)[:, :, 0][None, None])
    assert as_mesh(patch, samples=3).n_triangles == 2 * 3 * 3
    with pytest.raises(ValueError, match="thing: expected a TriangleMesh"):
        as_mesh(np.zeros((3, 3)), "thing")
    with pytest.raises(ValueError, match="thing.triangles: indices"):
        as_mesh((b.vertices, b.triangles + 8), "thing")


@pytest.mark.parametrize("closed_u", [False, True])
@pytest.mark.parametrize("closed_v", [False, True])
def test_tessellate_with_a_pair_of_samples_puts_the_lattice_on_the_patches(closed_u, closed_v):
    rng = np.random.default_rng(5)
    control = rng.normal(size=(3, 4, 4, 4, 3))
    # closed directions: the last patch row (column) ends where the first starts
    if closed_u:
        control[-1, :, 3] = control[0, :, 0]
    if closed_v:
        control[:, -1, :, 3] = control[:, 0, :, 0]
    patches = BezierPatches(control, closed_u, closed_v)
    su, sv = 2, 3
    mesh = tessellate(patches, (su, sv), weld_seams=False)
    n_u, n_v = 3 * su + (not closed_u), 4 * sv + (not closed_v)
    assert mesh.n_vertices == n_u * n_v
    g, h = np.divmod(np.arange(n_u * n_v), n_v)
    # the lattice of global parameters (i + a / su, j + b / sv), the last sample of an open side at t = 1
    expect = patches.evaluate_global(g / su, h / sv)
    np.testing.assert_allclose(mesh.vertices, expect, atol=1e-12)
    np.testing.assert_allclose(mesh.vertex_normals, patches.normals(*patches.locate(g / su, h / sv)), atol=1e-9)
    # one count both ways is the square tessellation
    square = tessellate(patches, 2, weld_seams=False)
    same = tessellate(patches, (2, 2), weld_seams=False)
    np.testing.assert_array_equal(square.triangles, same.triangles)
    np.testing.assert_allclose(square.vertices, same.vertices, atol=1e-12)


def test_tessellate_refuses_bad_sample_pairs():
    patches = BezierPatches(np.random.default_rng(0).normal(size=(1, 1, 4, 4, 3)))
    for bad in ((0, 2), (2, 3, 4), (1, -1)):
        with pytest.raises(ValueError, match="samples"):
            tessellate(patches, bad)


def test_points_apart_proves_only_what_holds():
    from surfaces.mesh import points_apart

    rng = np.random.default_rng(8)
    pts = rng.uniform(-50, 50, (400, 3))
    d = np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1))
    closest = d[np.triu_indices(len(pts), 1)].min()
    assert points_apart(pts, 1e-9)
    # never proven apart when two points are within the distance (one duplicated, one moved a little)
    for extra in (pts[7], pts[7] + [0.0, 3e-10, 0.0]):
        assert not points_apart(np.vstack([pts, extra]), 1e-9)
    assert not points_apart(pts, closest * 1.01)
    assert points_apart(pts[:1], 1.0) and points_apart(pts[:0], 1.0)


def test_weld_map_skips_the_tree_only_when_points_are_apart(monkeypatch):
    import scipy.spatial

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    calls = []
    real = scipy.spatial.cKDTree

    def tree(p, *a, **k):
        calls.append(len(p))
        return real(p, *a, **k)

    monkeypatch.setattr(scipy.spatial, "cKDTree", tree)
    assert weld_map(pts, 1e-9).tolist() == [0, 1, 2, 3] and calls == []
    assert weld_map(np.vstack([pts, pts[2] + 1e-12]), 1e-9).tolist() == [0, 1, 2, 3, 2] and calls == [5]


def test_meshes_made_from_checked_ones_equal_the_checked_construction():
    # compact, merge_meshes and tessellate build their results unchecked: the same fields as checked
    from surfaces.mesh import TriangleMesh as Mesh

    b = box([0, 0, 0], [1, 2, 3])
    v, t = b.vertices, b.triangles
    mesh = Mesh(v, t, np.tile([0.0, 0.0, 1.0], (len(v), 1)))
    extra = Mesh(np.vstack([v, [[9.0, 9.0, 9.0]]]), t, np.tile([0.0, 0.0, 1.0], (len(v) + 1, 1)))
    for out in (merge_meshes([mesh, extra]), compact(extra)):
        checked = Mesh(out.vertices, out.triangles, out.vertex_normals, out.vertex_colors, out.metadata)
        for name in ("vertices", "triangles", "vertex_normals"):
            a, b = getattr(out, name), getattr(checked, name)
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert out.vertex_colors is None and out.metadata == {}
    assert compact(extra).n_vertices == len(v)
    trusted = Mesh.unchecked(np.array(v, dtype=np.float32), np.asarray(t, dtype=np.int32))
    assert trusted.vertices.dtype == np.float64 and trusted.triangles.dtype == np.int64


def test_weld_map_takes_candidates_in_any_order_and_repeated():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 1e-12], [1, 0, 1e-12], [5, 5, 5]])
    want = weld_map(pts, 1e-9).tolist()
    assert want == [0, 1, 0, 1, 4]
    for cand in ([0, 1, 2, 3], [3, 2, 1, 0, 0], [[0, 1], [2, 3]]):
        assert weld_map(pts, 1e-9, cand).tolist() == want
    assert weld_map(pts, 1e-9, [0, 1, 3]).tolist() == [0, 1, 2, 1, 4]
