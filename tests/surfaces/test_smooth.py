"""Tests of surfaces.smooth: Loop subdivision keeps set-operation results closed."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces import boolean as bl
from surfaces.repair import check_solid
from surfaces.smooth import loop_smooth
from surfaces.topology import edge_table
from tests.surfaces._shapes import box, icosphere


@pytest.mark.parametrize("iterations, filt", [(1, "taubin"), (2, "none"), (1, "laplacian")])
def test_loop_smooth_keeps_closed(iterations, filt):
    r = bl.boolean(icosphere(1, (0, 0, 0), 3), icosphere(1, (0.8, 0.2, 0), 3), "union")
    s = loop_smooth(r.mesh, iterations, filter=filt, filter_iterations=5)
    assert check_solid(s)["solid"]
    assert len(s.triangles) == len(r.mesh.triangles) * 4**iterations
    # Loop subdivision approximates: it rounds the crease inward, keeping most of the volume
    assert 0.95 * r.volume < s.signed_volume() < r.volume


def max_dihedral_deg(mesh):
    directed, edge_id, counts, _ = edge_table(mesh.triangles, len(mesh.vertices))
    order = np.argsort(edge_id, kind="stable")
    faces = (order // 3).reshape(-1, 2)
    n = mesh.face_normals()
    return np.degrees(np.arccos(np.clip(np.sum(n[faces[:, 0]] * n[faces[:, 1]], axis=1), -1, 1))).max()


def test_loop_smooth_flattens_the_crease():
    r = bl.boolean(box([0, 0, 0], [1, 1, 1]), icosphere(0.8, (1, 1, 1), 3), "difference")
    assert max_dihedral_deg(r.mesh) >= 89.9  # the box's right-angled edges
    # every Loop step opens the sharpest crease further (measured 78, 48, 34 degrees)
    angles = [max_dihedral_deg(loop_smooth(r.mesh, k, filter="none")) for k in (1, 2, 3)]
    assert 89.9 > angles[0] > angles[1] > angles[2] and angles[2] < 40


def test_bad_arguments():
    m = icosphere(level=1)
    with pytest.raises(ValueError, match="filter: must be one of"):
        loop_smooth(m, 1, filter="bilateral")
    with pytest.raises(ValueError, match="iterations"):
        loop_smooth(m, -1)
    with pytest.raises(ValueError, match="mesh: not closed"):
        loop_smooth((m.vertices, m.triangles[1:]), 1)
