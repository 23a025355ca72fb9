"""Tests of surfaces.boolean: set operations, input refusal, curves, composition.

References: exact volumes of axis-aligned boxes and their overlaps, the
inclusion-exclusion identity vol(A u B) + vol(A n B) = vol(A) + vol(B), the
closed-form lens volume of two spheres, and tessellated Bezier ellipsoids of
the shared patch model.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surfaces import boolean as bl
from surfaces.coons import from_grid
from surfaces.mesh import TriangleMesh
from surfaces.repair import check_solid
from surfaces.topology import directed_edges
from tests.surfaces._shapes import bezier_ellipsoid, box, icosphere

REL = 1e-6


def all_ops(a, b, **kw):
    return {op: bl.boolean(a, b, op, **kw) for op in bl.OPS}


def assert_identities(res):
    u, i, d = res["union"], res["intersection"], res["difference"]
    total = u.volume_a + u.volume_b
    assert abs(u.volume + i.volume - total) <= REL * total
    assert abs(d.volume - (u.volume_a - i.volume)) <= REL * total
    for r in res.values():
        assert r.summary()["watertight"] and r.summary()["oriented"]
        if len(r.mesh.triangles):
            assert r.check["solid"]
            assert r.volume == pytest.approx(r.mesh.signed_volume(), rel=1e-12)


PAIRS = {
    "boxes_general": (box([0, 0, 0], [2, 1, 1]), box([1, 0.5, 0.25], [3, 2, 2])),
    "boxes_touching_face": (box([0, 0, 0], [1, 1, 1]), box([1, 0, 0], [2, 1, 1])),
    "boxes_coplanar_faces": (box([0, 0, 0], [2, 2, 1]), box([1, 1, 0], [3, 3, 1])),
    "boxes_shared_vertex": (box([0, 0, 0], [1, 1, 1]), box([1, 1, 1], [2, 2, 2])),
    "boxes_identical": (box([0, 0, 0], [1, 2, 3]), box([0, 0, 0], [1, 2, 3])),
    "boxes_nested": (box([0, 0, 0], [4, 4, 4]), box([1, 1, 1], [2, 2, 3])),
    "boxes_disjoint": (box([0, 0, 0], [1, 1, 1]), box([3, 0, 0], [4, 1, 1])),
    "spheres": (icosphere(1.0, (0, 0, 0)), icosphere(1.0, (0.9, 0.2, -0.1))),
    "sphere_box": (icosphere(1.2, (0.3, 0.3, 0.3)), box([0, 0, 0], [1, 1, 1])),
    "bezier_ellipsoids": (
        bezier_ellipsoid([1.0, 1.0, 1.0], [0, 0, 0]),
        bezier_ellipsoid([1.2, 0.8, 0.9], [0.5, 0.3, 0.2]),
    ),
    "far_from_origin_mm": (
        icosphere(12.0, (480.0, -310.0, 1250.0)),
        icosphere(9.0, (488.0, -305.0, 1252.0)),
    ),
}


@pytest.mark.parametrize("name", list(PAIRS))
def test_inclusion_exclusion(name):
    a, b = PAIRS[name]
    assert_identities(all_ops(a, b))


def overlap_box_volume(lo1, hi1, lo2, hi2):
    ext = np.clip(np.minimum(hi1, hi2) - np.maximum(lo1, lo2), 0, None)
    return float(np.prod(ext))


@pytest.mark.parametrize(
    "lo2, hi2",
    [
        ([1, 0.5, 0.25], [3, 2, 2]),
        ([1, 0, 0], [2, 1, 1]),
        ([0.5, 0.5, 0], [1.5, 1.5, 1]),
        ([-1, -1, -1], [3, 3, 3]),
        ([0.25, 0.25, 0.25], [0.75, 0.5, 0.5]),
    ],
)
def test_box_volumes_exact(lo2, hi2):
    lo1, hi1 = np.zeros(3), np.array([2.0, 1.0, 1.0])
    lo2, hi2 = np.asarray(lo2, float), np.asarray(hi2, float)
    res = all_ops(box(lo1, hi1), box(lo2, hi2))
    inter = overlap_box_volume(lo1, hi1, lo2, hi2)
    va, vb = np.prod(hi1 - lo1), np.prod(hi2 - lo2)
    assert res["intersection"].volume == pytest.approx(inter, rel=1e-12, abs=1e-12)
    assert res["union"].volume == pytest.approx(va + vb - inter, rel=1e-12)
    assert res["difference"].volume == pytest.approx(va - inter, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("d", [0.5, 1.0, 1.5])
def test_sphere_lens_against_closed_form(d):
    r = 1.0
    res = all_ops(icosphere(r, (0, 0, 0), level=4), icosphere(r, (d, 0, 0), level=4))
    lens = np.pi * (4 * r + d) * (2 * r - d) ** 2 / 12
    # an inscribed polyhedron underestimates: one-sided, within 1 %
    assert 0.99 * lens < res["intersection"].volume < lens
    ball = 4 / 3 * np.pi * r**3
    assert 0.99 * (2 * ball - lens) < res["union"].volume < 2 * ball - lens
    assert_identities(res)


def test_curve_lies_on_both_boxes():
    lo1, hi1 = np.zeros(3), np.array([2.0, 1.0, 1.0])
    lo2, hi2 = np.array([1, 0.5, 0.25]), np.array([3.0, 2.0, 2.0])
    for op in bl.OPS:
        r = bl.boolean(box(lo1, hi1), box(lo2, hi2), op)
        assert len(r.curves) == 1 and r.curves_closed == (True,)
        pts = r.curves[0]
        for lo, hi in ((lo1, hi1), (lo2, hi2)):
            c, h = (lo + hi) / 2, (hi - lo) / 2
            # on a box surface the largest normalised coordinate is exactly 1
            assert np.allclose(np.max(np.abs(pts - c) / h, axis=1), 1.0, atol=1e-12)
        # consecutive points are joined by result edges (ordered polyline)
        edges = set(map(tuple, np.sort(directed_edges(r.mesh.triangles), axis=1)))
        idx = {tuple(p): i for i, p in enumerate(r.mesh.vertices)}
        ring = [idx[tuple(p)] for p in pts]
        assert all(tuple(sorted(e)) in edges for e in zip(ring, ring[1:] + ring[:1]))


def test_curve_of_spheres_is_the_intersection_circle():
    d = 0.8
    r = bl.boolean(icosphere(1.0, (0, 0, 0), 4), icosphere(1.0, (d, 0, 0), 4), "intersection")
    assert len(r.curves) == 1 and r.curves_closed[0]
    pts = r.curves[0]
    # circle in the plane x = d/2 with radius sqrt(1 - d^2/4), up to the chord sag of level 4
    assert np.allclose(pts[:, 0], d / 2, atol=5e-3)
    rad = np.hypot(pts[:, 1], pts[:, 2])
    assert np.allclose(rad, np.sqrt(1 - d**2 / 4), atol=5e-3)
    length = r.summary()["curve_lengths"][0]
    assert length == pytest.approx(2 * np.pi * np.sqrt(1 - d**2 / 4), rel=5e-3)


def test_two_curves_when_b_pierces_a():
    a = box([0, 0, 0], [1, 1, 1])
    b = box([0.25, 0.25, -1], [0.75, 0.75, 2])
    r = bl.boolean(a, b, "difference")
    assert len(r.curves) == 2 and all(r.curves_closed)
    assert r.volume == pytest.approx(1 - 0.25, rel=1e-12)


def test_disjoint_intersection_is_empty():
    r = bl.boolean(box([0, 0, 0], [1, 1, 1]), box([2, 0, 0], [3, 1, 1]), "intersection")
    assert len(r.mesh.triangles) == 0 and r.volume == 0.0 and r.curves == ()


# ----------------------------------------------------------------------------- input checks
@pytest.mark.parametrize(
    "make, pattern",
    [
        (lambda m: TriangleMesh(m.vertices, m.triangles[2:]), "A: not closed"),
        (lambda m: TriangleMesh(m.vertices, m.triangles[:, ::-1]), "A: oriented inward"),
        (
            lambda m: TriangleMesh(m.vertices, np.vstack([m.triangles[:1, ::-1], m.triangles[1:]])),
            "A: not consistently oriented",
        ),
        (lambda m: TriangleMesh(m.vertices, np.vstack([m.triangles, m.triangles[:1]])), "A: not a manifold"),
        (
            lambda m: TriangleMesh(
                m.vertices[m.triangles].reshape(-1, 3), np.arange(3 * len(m.triangles)).reshape(-1, 3)
            ),
            "duplicate vertices",
        ),
    ],
)
def test_bad_input_is_refused_with_name(make, pattern):
    m = icosphere(level=2)
    with pytest.raises(ValueError, match=pattern):
        bl.boolean(make(m), icosphere(1.0, (0.5, 0, 0), 2), "union")


def test_bad_arguments():
    m = icosphere(level=1)
    with pytest.raises(ValueError, match="op: must be one of"):
        bl.boolean(m, m, "xor")
    with pytest.raises(ValueError, match="B: expected a TriangleMesh"):
        bl.boolean(m, np.zeros((3, 3)), "union")


# ----------------------------------------------------------------------------- composition
def test_compose_matches_pairwise_operations():
    organ = icosphere(3.0, level=3)
    bed = icosphere(1.0, (2.0, 0, 0), level=3)
    lobe = box([-1, -1, 2], [1, 1, 4])
    mesh, summary = bl.compose(
        organ, minus=[bed], plus=[lobe], names={"base": "Lung", "minus": ["Bed"], "plus": ["Lobe"]}
    )
    step = bl.boolean(bl.boolean(organ, lobe, "union").mesh, bed, "difference")
    assert summary["volume"] == pytest.approx(step.volume, rel=1e-9)
    assert check_solid(mesh)["solid"]
    assert summary["names"] == {"base": "Lung", "minus": ["Bed"], "plus": ["Lobe"]}
    inter = bl.boolean(bl.boolean(organ, lobe, "union").mesh, bed, "intersection").volume
    assert summary["removed_volume"] == pytest.approx(inter, rel=1e-9)


# ----------------------------------------------------------------------------- kidney phantom
def kidney_mesh(step=1.0):
    """Closed mesh of the kidney phantom: marching cubes of its smoothed indicator (mm)."""
    from scipy.ndimage import gaussian_filter
    from skimage.measure import marching_cubes

    from datasets_synthetic.phantoms import make_phantom

    kidney = make_phantom("kidney")
    surface = kidney.surface_points(20000, seed=0)
    lo, hi = surface.min(axis=0), surface.max(axis=0)
    axes = [np.arange(a - 2 * step, b + 2 * step, step) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    inside = kidney.inside(grid.reshape(-1, 3)).reshape(grid.shape[:3])
    v, t, *_ = marching_cubes(gaussian_filter(inside.astype(float), 0.7), 0.5, spacing=(step,) * 3)
    # marching cubes winds the faces towards increasing values (inward for an indicator)
    return kidney, TriangleMesh(v + [a[0] for a in axes], t[:, ::-1].astype(np.int64))


def test_kidney_phantom_minus_tumour_bed():
    kidney, k = kidney_mesh()
    assert check_solid(k, "kidney")["solid"]
    assert k.signed_volume() == pytest.approx(kidney.volume_mm3, rel=0.01)
    bed = icosphere(9.0, (-8.0, 0.0, 12.0), level=3)  # on the concave hilum side
    lobe = bezier_ellipsoid([10.0, 14.0, 20.0], [6.0, 4.0, -25.0], samples=3)
    for other in (bed, lobe):
        assert_identities(all_ops(k, other))
    mesh, summary = bl.compose(k, minus=[bed], plus=[lobe])
    inter = bl.boolean(bl.boolean(k, lobe, "union").mesh, bed, "intersection").volume
    assert summary["removed_volume"] == pytest.approx(inter, rel=1e-9)
    assert 0 < inter < bed.signed_volume()
    assert check_solid(mesh)["solid"]


def test_patch_models_are_accepted_directly():
    from surfaces.measure import volume

    th = np.linspace(0, np.pi, 9)
    ph = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    tt, pp = np.meshgrid(th, ph, indexing="ij")
    unit = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    pa = from_grid(unit, closed_v=True)
    pb = from_grid(unit * [1.2, 0.8, 0.9] + [0.5, 0.3, 0.2], closed_v=True)
    res = all_ops(pa, pb)
    assert_identities(res)
    # the inscribed tessellation (8 x 8 per patch) underestimates the patch model's exact volume
    assert 0.995 * volume(pa) < res["union"].volume_a < volume(pa)


# ----------------------------------------------------------------------------- reconstructed CT structures


# ----------------------------------------------------------------------------- property test
_corner = st.tuples(*[st.integers(0, 4)] * 3)


@settings(max_examples=40, deadline=None)
@given(_corner, _corner, _corner, _corner)
def test_random_grid_boxes_exact(p, q, r, s):
    """Boxes on a coarse integer grid: touching, coplanar, shared edges and corners are frequent."""
    lo1, hi1 = np.minimum(p, q), np.maximum(p, q) + 1
    lo2, hi2 = np.minimum(r, s), np.maximum(r, s) + 1
    res = all_ops(box(lo1, hi1), box(lo2, hi2))
    inter = overlap_box_volume(lo1, hi1, lo2, hi2)
    va, vb = float(np.prod(hi1 - lo1)), float(np.prod(hi2 - lo2))
    assert res["intersection"].volume == pytest.approx(inter, rel=1e-12, abs=1e-12)
    assert res["union"].volume == pytest.approx(va + vb - inter, rel=1e-12)
    assert res["difference"].volume == pytest.approx(va - inter, rel=1e-12, abs=1e-12)
    assert_identities(res)


@settings(max_examples=30, deadline=None)
@given(_corner, _corner, _corner, _corner, st.integers(0, 2**32 - 1))
def test_random_grid_boxes_rotated(p, q, r, s, seed):
    """The same boxes under a common random rotation: the coincidences hold only up to rounding."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.random(random_state=seed).as_matrix()
    lo1, hi1 = np.minimum(p, q), np.maximum(p, q) + 1
    lo2, hi2 = np.minimum(r, s), np.maximum(r, s) + 1
    a, b = box(lo1, hi1), box(lo2, hi2)
    res = all_ops(TriangleMesh(a.vertices @ rot.T, a.triangles), TriangleMesh(b.vertices @ rot.T, b.triangles))
    inter = overlap_box_volume(lo1, hi1, lo2, hi2)
    va, vb = float(np.prod(hi1 - lo1)), float(np.prod(hi2 - lo2))
    assert res["intersection"].volume == pytest.approx(inter, rel=1e-9, abs=1e-9)
    assert res["union"].volume == pytest.approx(va + vb - inter, rel=1e-9)
    assert_identities(res)
