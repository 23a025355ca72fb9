"""Tests of surfaces.repair: the diagnosis of solid boundaries and their repair."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.mesh import TriangleMesh
from surfaces.repair import check_solid, repair_mesh, require_solid
from tests.surfaces._shapes import icosphere
from tests.surfaces.test_boolean import all_ops, assert_identities


def test_check_solid_reports_defects():
    m = icosphere(level=2)
    assert check_solid(m)["solid"]
    holed = TriangleMesh(m.vertices, m.triangles[1:])
    info = check_solid(holed, "holed")
    assert not info["closed"] and info["boundary_edges"] == 3
    inward = TriangleMesh(m.vertices, m.triangles[:, ::-1])
    info = check_solid(inward, "inward")
    assert info["closed"] and info["oriented"] and not info["outward"]
    flipped = m.triangles.copy()
    flipped[0] = flipped[0, ::-1]
    info = check_solid(TriangleMesh(m.vertices, flipped), "flip")
    assert info["misoriented_edges"] == 3


def soup(m):
    return TriangleMesh(m.vertices[m.triangles].reshape(-1, 3), np.arange(3 * len(m.triangles)).reshape(-1, 3))


@pytest.mark.parametrize("defect", ["soup", "flipped", "inward", "holes", "degenerate_duplicate"])
def test_repair_restores_the_solid(defect):
    m = icosphere(level=3)
    v0 = m.signed_volume()
    rng = np.random.default_rng(1)
    t = m.triangles.copy()
    if defect == "soup":
        broken, key = soup(m), "welded_vertices"
    elif defect == "flipped":
        f = rng.random(len(t)) < 0.3
        t[f] = t[f][:, ::-1]
        broken, key = TriangleMesh(m.vertices, t), "flipped_triangles"
    elif defect == "inward":
        broken, key = TriangleMesh(m.vertices, t[:, ::-1]), "flipped_shells"
    elif defect == "holes":
        broken, key = TriangleMesh(m.vertices, np.delete(t, [3, 200, 600], axis=0)), "filled_holes"
    else:
        extra = np.array([[0, 0, 5], [7, 8, 7]])
        broken, key = TriangleMesh(m.vertices, np.vstack([t, t[:4], extra])), "removed_duplicate_triangles"
    assert not check_solid(broken)["solid"]
    fixed, report = repair_mesh(broken, "X")
    assert report[key] > 0 and report["repaired"]
    assert check_solid(fixed)["solid"]
    # filling three one-triangle holes by fans over their corners gives back the same volume
    assert fixed.signed_volume() == pytest.approx(v0, rel=1e-12)
    res = all_ops(broken, icosphere(1.0, (0.7, 0.1, 0.0)), repair=True)
    assert res["union"].repairs["A"][key] > 0
    assert_identities(res)


def test_repair_keeps_a_cavity_inward():
    outer, inner = icosphere(2.0, level=2), icosphere(1.0, level=2)
    both = TriangleMesh(
        np.vstack([outer.vertices, inner.vertices]),
        np.vstack([outer.triangles, inner.triangles + len(outer.vertices)]),  # inner wrongly outward
    )
    fixed, report = repair_mesh(both, "hollow")
    assert report["flipped_shells"] == 1
    assert fixed.signed_volume() == pytest.approx(outer.signed_volume() - inner.signed_volume())


def test_repair_refuses_what_it_cannot_fix():
    m = icosphere(level=3)
    big_hole = m.triangles[m.vertices[m.triangles].mean(axis=1)[:, 2] < 0.5]
    with pytest.raises(ValueError, match="holey: not closed.*after repair"):
        repair_mesh(TriangleMesh(m.vertices, big_hole), "holey", max_hole_edges=8)


def test_require_solid_names_the_input_and_the_hint():
    m = icosphere(level=1)
    assert require_solid(m, "ball")["solid"]
    with pytest.raises(ValueError, match="ball: not closed.*; fix it"):
        require_solid(TriangleMesh(m.vertices, m.triangles[1:]), "ball", "; fix it")


def test_check_solid_counts_degenerate_triangles_and_accepts_arrays():
    m = icosphere(level=1)
    info = check_solid((m.vertices, np.vstack([m.triangles, [[0, 0, 1]]])), "deg")
    assert info["degenerate_triangles"] == 1 and not info["solid"]
    assert any("degenerate" in p for p in info["problems"])
    empty = check_solid(TriangleMesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), "empty")
    assert not empty["closed"] and empty["problems"] == ["empty: has no triangles"]
