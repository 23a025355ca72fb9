"""Conversion to open3d geometry (surfaces.convert)."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.bezier import control_net_segments
from surfaces.convert import control_net_lineset, to_open3d


def test_control_net_segments_and_lineset():
    """24 segments per patch; the line set has the same points."""
    rng = np.random.default_rng(0)
    ctrl = rng.normal(size=(2, 3, 4, 4, 3))
    seg = control_net_segments(ctrl)
    assert seg.shape == (24 * 6, 2, 3)
    assert np.allclose(seg[0], ctrl[0, 0, :2, 0])
    lines = control_net_lineset(ctrl, color=(1, 0, 0))
    assert len(lines.lines) == len(seg)
    assert np.allclose(np.asarray(lines.points), seg.reshape(-1, 3))


def test_to_open3d_colours_and_normals(sphere):
    verts, tris = sphere
    mesh = to_open3d(sphere, scalars=verts[:, 2], cmap="coolwarm")
    assert len(mesh.triangles) == len(tris)
    normals = np.asarray(mesh.vertex_normals)
    assert np.allclose(np.einsum("ij,ij->i", normals, verts), 1.0, atol=2e-3)
    colors = np.asarray(mesh.vertex_colors)
    assert colors.shape == verts.shape and np.ptp(colors) > 0.5
    with pytest.raises(ValueError, match="scalars"):
        to_open3d(sphere, scalars=verts[:10, 2])


def test_to_open3d_keeps_given_colours_and_checks_them(sphere):
    verts, _ = sphere
    mesh = to_open3d(sphere, colors=np.tile([0.2, 0.4, 0.6], (len(verts), 1)))
    assert np.allclose(np.asarray(mesh.vertex_colors), [0.2, 0.4, 0.6])
    with pytest.raises(ValueError, match="colors: RGB values"):
        to_open3d(sphere, colors=np.full((len(verts), 3), 2.0))


def test_to_open3d_closed_patch_model_is_watertight():
    from surfaces.coons import from_grid
    from surfaces.mesh import tessellate
    from tests.surfaces.test_mesh import _torus

    patches = from_grid(_torus(), closed_u=True, closed_v=True)
    n_vertices = tessellate(patches, 2).n_vertices
    o3 = to_open3d(patches, samples=2, colors=np.tile([0.2, 0.4, 0.6], (n_vertices, 1)))
    assert o3.is_watertight()
    assert len(o3.vertex_normals) == len(o3.vertices)
