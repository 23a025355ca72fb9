"""Branching and merging joined along the mid-line (issue 19): a Y (trouser) phantom and split contours."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms.trouser import trouser_contours, trouser_volume
from slices import chaining
from slices.chaining import split_contour
from slices.polygons import clean_contour, signed_area
from slices.io import Contour
from slices.structure import reconstruct_contours
from slices.summary import chaining_text
from surfaces.intersect import self_intersections
from surfaces.topology import shells
from tests.slices._stacks import circle

HEIGHT, SPACING = 40.0, 2.0


def _trouser(merge: bool = False) -> list[Contour]:
    items = trouser_contours(SPACING, HEIGHT, n_points=64)
    # a merge is the branching upside down
    return [Contour(HEIGHT - z if merge else z, clean_contour(p)) for z, p in items]


def _shelf_area(mesh, planes) -> float:
    """Area of horizontal triangles on interior planes (a flat shelf), mm^2."""
    n = mesh.face_normals(normalize=False)
    area = 0.5 * np.linalg.norm(n, axis=1)
    flat = np.abs(n[:, 2]) > (1 - 1e-6) * 2 * area
    z = mesh.triangle_corners()[:, :, 2].mean(axis=1)
    interior = (z > planes[0] + 1e-6) & (z < planes[-1] - 1e-6)
    return float(area[flat & interior].sum())


def test_split_parts_cover_the_parent_along_the_mid_line():
    parent = clean_contour(np.stack([14 * np.cos(np.linspace(0, 2 * np.pi, 120, endpoint=False)),
                                     7 * np.sin(np.linspace(0, 2 * np.pi, 120, endpoint=False))], 1))
    left, right = circle(-8, 0, 5, 48), circle(8, 1, 5, 48)
    parts = split_contour(parent, [left, right])
    assert parts is not None and len(parts) == 2
    assert sum(signed_area(p) for p in parts) == pytest.approx(signed_area(parent), rel=5e-3)
    assert parts[0][:, 0].mean() < 0 < parts[1][:, 0].mean()
    # points off the outline lie on the perpendicular bisector of the two centres (x = -y / 16 + 1/32)
    for p in parts:
        inner = np.abs((p[:, 0] / 14) ** 2 + (p[:, 1] / 7) ** 2 - 1) > 0.05
        assert inner.sum() >= 3
        np.testing.assert_allclose(p[inner, 0], -p[inner, 1] / 16 + 1 / 32, atol=0.15)
    # a child with no share of the parent (beyond the other): no split
    assert split_contour(parent, [left, circle(-30, 0, 2, 24)]) is None


@pytest.mark.parametrize("merge", [False, True])
def test_trouser_phantom_is_one_clean_solid_without_a_shelf(merge):
    conts = _trouser(merge)
    rec = reconstruct_contours(conts, surface_path="coons", caps="flat", samples=2)
    assert len(rec.bodies) == 3
    assert sum("split" in (b.body.start, b.body.stop) for b in rec.bodies) == 3
    assert all(b.caps_used.count("flat") == 2 for b in rec.bodies)
    exact = trouser_volume(0.0, HEIGHT)
    assert rec.volume_mm3 == pytest.approx(exact, rel=5e-3)
    solid, united = rec.solid_mesh()
    assert united and solid.is_watertight() and solid.is_oriented()
    assert len(np.unique(shells(solid.triangles, solid.n_vertices))) == 1
    assert self_intersections(solid.vertices, solid.triangles).n_faces == 0
    assert solid.signed_volume() == pytest.approx(rec.volume_mm3, rel=1e-3)
    planes = np.unique([c.z for c in conts])
    assert _shelf_area(solid, planes) < 0.5  # mm^2: slivers where the parts' curves meet the parent's
    assert "3 chain ends joined at a contour divided along the mid-line" in chaining_text(rec)


def test_without_the_split_the_branching_leaves_a_shelf(monkeypatch):
    # what main did: half caps meeting half-way between the planes, a flat shelf where the parent is wider
    monkeypatch.setattr(chaining, "split_contour", lambda parent, children: None)
    conts = _trouser()
    rec = reconstruct_contours(conts, surface_path="coons", caps="flat", samples=2, unfold=False)
    assert {b.body.stop for b in rec.bodies} == {"branch", "end"}
    solid, _ = rec.solid_mesh()
    assert _shelf_area(solid, np.unique([c.z for c in conts])) > 20.0
