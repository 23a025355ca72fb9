"""Tessellation's lattice pieces against the direct forms: samples of every patch, normals and their
collapse test, the triangles kept per lattice shape, merged meshes."""

from __future__ import annotations

import numpy as np
import pytest

import surfaces.mesh as mesh_module
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh, merge_meshes, tessellate


def _patches(rows: int, cols: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(rows, cols, 4, 4, 3))


@pytest.mark.parametrize("nu,nv", [(1, 1), (1, 2), (2, 1), (3, 2), (2, 4)])
@pytest.mark.parametrize("last_u,last_v", [(False, False), (False, True), (True, False), (True, True)])
def test_lattice_block_samples_every_patch(nu, nv, last_u, last_v):
    """Points, S_u and S_v of a view of some columns, on the lattice, as BezierPatches.derivatives gives them."""
    grid = _patches(3, 6, nu + 10 * nv)
    control = grid[:, 1:5]  # a view of some columns, as a body's side columns are
    k, cols = control.shape[:2]
    out = tuple(np.full((k * nu + last_u, cols * nv + last_v, 3), np.nan) for _ in range(3))
    mesh_module._lattice_block(control, nu, nv, last_u, last_v, out)
    g, h = np.meshgrid(np.arange(k * nu + last_u), np.arange(cols * nv + last_v), indexing="ij")
    pi, pj = np.minimum(g // nu, k - 1), np.minimum(h // nv, cols - 1)
    d = BezierPatches(control).derivatives(pi.ravel(), pj.ravel(), ((g - pi * nu) / nu).ravel(),
                                           ((h - pj * nv) / nv).ravel())
    for got, want in zip(out, (d.point, d.du, d.dv)):
        np.testing.assert_allclose(got.reshape(-1, 3), want, rtol=0, atol=1e-12)


def _reference_normals(du, dv):
    normal = np.cross(du, dv)
    length2 = np.sum(normal * normal, axis=1)
    scale2 = np.sum(du * du, axis=1) * np.sum(dv * dv, axis=1)
    return normal, length2 <= 1e-20 * np.maximum(scale2, 1e-300)


@pytest.mark.parametrize("seed", range(4))
def test_lattice_normals_find_the_collapsed_samples_a_bound_cannot_clear(seed):
    """Random derivatives with zero, parallel and nearly parallel pairs among them: the same mask as the test
    on every sample, unit normals elsewhere."""
    rng = np.random.default_rng(seed)
    du, dv = rng.normal(size=(400, 3)) * 10.0 ** rng.integers(-3, 3), rng.normal(size=(400, 3))
    dv[::7] = 2.5 * du[::7]  # parallel
    du[3::11] = 0.0  # a pole
    dv[5::13] = du[5::13] * 1e3 + 1e-9 * rng.normal(size=(len(du[5::13]), 3))  # nearly parallel, not collapsed
    normal, want = _reference_normals(du, dv)
    assert want.any() and not want.all()

    class Probe:
        shape = (400, 1)

        @staticmethod
        def _unit_normals(pi, pj, u, v, a, b):
            return np.tile([0.0, 0.0, 1.0], (len(a), 1))

    got, collapsed = mesh_module._lattice_normals(Probe, du, dv, 1, 1, 1)
    np.testing.assert_array_equal(collapsed, want)
    np.testing.assert_allclose(got[~want], normal[~want] / np.linalg.norm(normal[~want], axis=1)[:, None],
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[want], np.tile([0.0, 0.0, 1.0], (int(want.sum()), 1)))


@pytest.mark.parametrize("rows,cols", [(4, 5), (300, 300)])
def test_grid_triangles_are_a_new_array_each_call(rows, cols):
    first = mesh_module._grid_triangles(rows, cols, True, False)
    first[0] = -1
    again = mesh_module._grid_triangles(rows, cols, True, False)
    np.testing.assert_array_equal(again, mesh_module._lattice_triangles(rows, cols, True, False))
    assert again.flags.writeable and again[0, 0] >= 0


def test_merge_meshes_offsets_every_mesh_once():
    rng = np.random.default_rng(0)
    meshes = [TriangleMesh(rng.random((n, 3)), rng.integers(0, n, (t, 3))) for n, t in ((5, 4), (3, 2), (7, 0), (4, 3))]
    merged = merge_meshes(meshes)
    want = np.concatenate([m.triangles + o for m, o in zip(meshes, np.cumsum([0, 5, 3, 7]))])
    np.testing.assert_array_equal(merged.triangles, want)
    assert merged.triangles.dtype == np.int64


def test_tessellating_a_view_of_some_columns_equals_the_copy():
    grid = _patches(5, 7, 3)
    view, copy = grid[:, 2:6], np.ascontiguousarray(grid[:, 2:6])
    a, b = tessellate(BezierPatches.unchecked(view), (1, 3)), tessellate(BezierPatches(copy), (1, 3))
    np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_array_equal(a.vertices, b.vertices)
