"""Holes by containment, bodies by overlap across planes, the planning systems' slab volume."""

from __future__ import annotations

import numpy as np
import pytest

from slices import chaining
from slices.chaining import chain, classify_holes, overlaps, slab_volume
from slices.polygons import centroid, clean_contour, signed_area
from slices.io import Contour
from tests.slices._stacks import branching_stack, circle

SQUARE = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)


def test_holes_by_containment_islands_are_outer_again():
    conts = [Contour(0.0, circle(0, 0, 20)), Contour(0.0, circle(0, 0, 10)), Contour(0.0, circle(0, 0, 4)),
             Contour(0.0, circle(50, 0, 4))]
    np.testing.assert_array_equal(classify_holes(conts), [False, True, False, False])


def test_overlap_of_polygons():
    assert overlaps(SQUARE, SQUARE + 5)
    assert not overlaps(SQUARE, SQUARE + 11)  # bounding boxes apart
    l_shape = np.array([[0, 0], [10, 0], [10, 2], [2, 2], [2, 10], [0, 10]], float)
    assert not overlaps(l_shape, np.array([[5, 5], [9, 5], [9, 9], [5, 9]], float))  # boxes overlap, shapes not


def test_branching_splits_chain_and_separate_bodies():
    conts = branching_stack() + [Contour(0.0, circle(40, 0, 5)), Contour(2.0, circle(40, 0, 5))]
    bodies = chain(conts, 2.0)
    assert len(bodies) == 4
    stops = sorted((b.start, b.stop) for b in bodies)
    assert stops.count(("end", "branch")) == 1 and stops.count(("branch", "end")) == 2
    np.testing.assert_array_equal(bodies[0].z, [0.0, 2.0])


def test_merging_chains_and_holes_come_last():
    conts = [Contour(z, circle(0, 0, 20)) for z in (0.0, 1.0, 2.0)] + [Contour(1.0, circle(0, 0, 5))]
    merge = [Contour(0.0, circle(-5, 0, 4)), Contour(0.0, circle(5, 0, 4)), Contour(1.0, circle(0, 0, 10))]
    bodies = chain(conts, 1.0)
    assert [b.kind for b in bodies] == ["outer", "hole"]
    assert sorted((b.start, b.stop) for b in chain(merge, 1.0)) == [("end", "merge"), ("end", "merge"),
                                                                      ("merge", "end")]


def test_gap_inside_a_body_is_an_error_between_bodies_not():
    conts = [Contour(0.0, circle(0, 0, 10)), Contour(2.0, circle(0, 0, 10)), Contour(6.0, circle(0, 0, 10))]
    with pytest.raises(ValueError, match="resample"):
        chain(conts, 2.0)
    apart = conts[:2] + [Contour(6.0, circle(40, 0, 10))]
    assert len(chain(apart, 2.0)) == 2
    assert len(chain(conts, None)) == 1  # unequal spacing accepted: consecutive planes are neighbours


def test_slab_volume_counts_end_planes_half():
    hole = np.array([[2, 2], [4, 2], [4, 4], [2, 4]], float)
    conts = [Contour(z, SQUARE) for z in (0.0, 1.0, 2.0, 3.0)] + [Contour(1.0, hole)]
    assert slab_volume(conts, 1.0) == pytest.approx(100 * 3 - 4)
    # unequal planes: the trapezoid rule over the true positions
    uneven = [Contour(z, SQUARE) for z in (0.0, 1.0, 3.0)]
    assert slab_volume(uneven, None) == pytest.approx(300.0)
    assert slab_volume(uneven[:1], None) == 0.0


def test_a_split_branching_starts_each_child_on_its_part_of_the_parent():
    from datasets_synthetic.phantoms.trouser import trouser_contours

    conts = [Contour(z, clean_contour(p)) for z, p in trouser_contours(2.0, 30.0, n_points=48)]
    bodies = chain(conts, 2.0)
    trunk, *legs = bodies
    assert (trunk.start, trunk.stop) == ("end", "split") and len(legs) == 2
    for leg in legs:
        assert (leg.start, leg.stop) == ("split", "end")
        assert leg.z[0] == trunk.z[-1] and np.all(np.diff(leg.z) == 2.0)
    # the parts cover the trunk's last contour, one on each side of the mid-line x = 0
    parts = [leg.contours[0].points for leg in legs]
    assert sum(signed_area(p) for p in parts) == pytest.approx(signed_area(trunk.contours[-1].points), rel=5e-3)
    assert sorted(np.sign(p[:, 0].mean()) for p in parts) == [-1.0, 1.0]


def test_a_split_is_refused_where_a_child_would_loft_from_a_much_larger_part(monkeypatch):
    # branching_stack: a 10 mm circle into two 4 mm circles; each half is 3x a child: half caps stay
    assert all("split" not in (b.start, b.stop) for b in chain(branching_stack(), 2.0))
    monkeypatch.setattr(chaining, "SPLIT_AREA_RATIO", 4.0)
    assert sum("split" in (b.start, b.stop) for b in chain(branching_stack(), 2.0)) == 3


def _star(rng, cx, cy, radius, n):
    """A random star-shaped (often non-convex) counter-clockwise polygon."""
    t = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = radius * rng.uniform(0.3, 1.0, n)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def test_vectorised_overlap_equals_the_raster_test():
    # every pair at once, certified pairs and rasterised ones, against overlaps() pair by pair:
    # apart, touching, slightly and deeply overlapping, nested, non-convex
    rng = np.random.default_rng(7)
    contours = []
    for _ in range(160):
        size = rng.uniform(1.0, 20.0)
        contours.append(Contour(0.0, _star(rng, rng.uniform(-20, 20), rng.uniform(-20, 20), size, rng.integers(3, 40))))
    l_shape = np.array([[0, 0], [10, 0], [10, 2], [2, 2], [2, 10], [0, 10]], float)
    contours += [Contour(0.0, l_shape), Contour(0.0, np.array([[5, 5], [9, 5], [9, 9], [5, 9]], float)),
                 Contour(0.0, SQUARE), Contour(0.0, SQUARE + [10.0, 0.0]), Contour(0.0, SQUARE * 0.1 + 4.5)]
    table = chaining.Outlines.of(contours)
    i, j = np.triu_indices(len(contours), 1)
    got = chaining._overlapping(table, contours, i, j)
    want = np.array([overlaps(contours[a].points, contours[b].points) for a, b in zip(i, j)])
    np.testing.assert_array_equal(got, want)
    assert 0.2 < want.mean() < 0.8  # both answers are well represented


def test_outline_table_equals_the_per_contour_figures():
    rng = np.random.default_rng(3)
    contours = [Contour(float(k), _star(rng, rng.uniform(-5, 5), 0.0, rng.uniform(1, 9), rng.integers(3, 30)))
                for k in range(25)]
    table = chaining.Outlines.of(contours)
    for k, c in enumerate(contours):
        p = c.points
        np.testing.assert_allclose(table.area[k], signed_area(p), rtol=1e-12)
        np.testing.assert_allclose(table.perimeter[k], np.linalg.norm(np.roll(p, -1, 0) - p, axis=1).sum(),
                                   rtol=1e-12)
        np.testing.assert_allclose(table.centroid[k], centroid(p), rtol=1e-10, atol=1e-12)
    # signed distance to the outline: a unit square's centre is 0.5 inside, a far point outside
    sq = chaining.Outlines.of([Contour(0.0, SQUARE / 10)])
    depth = sq.inside_depth(np.array([[0.5, 0.5], [3.0, 0.5]]), np.array([0, 0]))
    np.testing.assert_allclose(depth, [0.5, -2.0])


def test_outline_planes_equal_np_unique_of_the_rounded_z():
    # the table's distinct planes and each contour's plane are np.unique's of z rounded to 1e-6 mm:
    # shuffled planes, repeats, values apart by less than the rounding, and NaN planes (held as one)
    rng = np.random.default_rng(5)
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    for zs in (rng.permutation(np.r_[np.arange(8) * 2.5, [5.0, 5.0000001, -0.0, 0.0]]),
               np.array([3.0, np.nan, 1.0, np.nan, 3.0]), np.array([7.25])):
        table = chaining.Outlines.of([Contour(float(z), tri) for z in zs])
        planes, plane_of = np.unique(np.round(zs, 6), return_inverse=True)
        np.testing.assert_array_equal(table.planes, planes)
        np.testing.assert_array_equal(table.plane_of, plane_of)


def test_holes_equal_the_pairwise_containment_count():
    # nested and overlapping random outlines on a few planes: the table's parity of containing
    # contours equals counting them pair by pair with points_in_polygon
    from slices.polygons import points_in_polygon

    rng = np.random.default_rng(4)
    contours = [Contour(float(rng.integers(0, 3)), _star(rng, rng.uniform(-3, 3), rng.uniform(-3, 3),
                                                         rng.uniform(1, 15), rng.integers(3, 30)))
                for _ in range(60)]
    want = []
    for a, ca in enumerate(contours):
        inside = [points_in_polygon(ca.points[:1], cb.points)[0] for b, cb in enumerate(contours)
                  if b != a and cb.z == ca.z]
        want.append(sum(inside) % 2 == 1)
    np.testing.assert_array_equal(classify_holes(contours), want)
    assert 5 < sum(want) < 55
    table = chaining.Outlines.of(contours)
    members = table.members()
    assert len(table.planes) == 3 and sum(len(m) for m in members) == 60
    # pairs of neighbouring planes, in order of planes, then contours
    want = [(a, b) for p in range(len(members) - 1) for a in members[p] for b in members[p + 1]]
    i, j = table.neighbour_pairs()
    assert list(zip(i.tolist(), j.tolist())) == [(int(a), int(b)) for a, b in want]
