"""One body: caps against each other, closed-grid integrals, single slices, holes and the mesh."""

from __future__ import annotations

import numpy as np
import pytest

from slices.body import build_body
from slices.caps import curve_area
from slices.chaining import Body, chain
from slices.io import Contour
from slices.options import SurfaceOptions
from slices.surface import slice_curves
from surfaces import measure
from tests.slices._stacks import circle, phantom_stack


@pytest.fixture(scope="module")
def ellipsoid_body():
    _, conts, _ = phantom_stack("ellipsoid", a=15.0, b=10.0, c=12.0, n_points=48)
    return chain(conts, 2.5)[0]


def test_caps_relations(ellipsoid_body):
    body, d = ellipsoid_body, 2.5
    flat = build_body(body, d, SurfaceOptions(caps="flat"), mesh=False)
    half = build_body(body, d, SurfaceOptions(caps="half"), mesh=False)
    dome = build_body(body, d, SurfaceOptions(caps="dome", samples=2))
    none = build_body(body, d, SurfaceOptions(caps="none"), mesh=False)
    sc = slice_curves([body.contours[0].points, body.contours[-1].points], [body.z[0], body.z[-1]], 64)
    ends = abs(curve_area(sc.curves[0])) + abs(curve_area(sc.curves[1]))
    # half caps add a prism of half a spacing at both ends
    assert half.volume_mm3 - flat.volume_mm3 == pytest.approx(ends * d / 2, rel=1e-3)
    assert flat.volume_mm3 < dome.volume_mm3 < half.volume_mm3
    assert dome.mesh.is_watertight()
    assert none.volume_mm3 == pytest.approx(flat.volume_mm3)
    assert none.area_mm2 == pytest.approx(flat.area_mm2 - ends, rel=1e-3)
    assert flat.mesh is None and flat.display_mesh is None


def test_one_pass_integrals_match_volume_and_area(ellipsoid_body):
    body = Body("outer", ellipsoid_body.contours[:6], "end", "end")
    patches = build_body(body, 2.5, mesh=False).patches
    vol, area = measure.integrals(patches, order=6)
    assert vol == pytest.approx(measure.volume(patches), rel=1e-12)
    assert area == pytest.approx(measure.area(patches, order=6), rel=1e-12)


def test_side_columns_and_reported_lattice(ellipsoid_body):
    b = build_body(ellipsoid_body, 2.5, SurfaceOptions(caps="half", n_rays=32, start_angle=0.05), mesh=False)
    rows, cols = b.patches.control.shape[:2]
    assert rows == b.n_lattice
    # fan column, half-cap prism, K - 1 slice columns, prism, fan column
    assert b.side_columns == slice(1, cols - 1) and cols == len(ellipsoid_body.contours) - 1 + 4
    assert b.start_angle == 0.05 and b.max_deviation_mm < 1e-9


def test_flat_capped_mesh_is_watertight_and_display_keeps_caps_apart(ellipsoid_body):
    b = build_body(ellipsoid_body, 2.5, SurfaceOptions(caps="flat", samples=2))
    assert b.mesh.is_watertight() and b.mesh.is_oriented()
    assert b.display_mesh.n_triangles == b.mesh.n_triangles
    assert b.display_mesh.n_vertices > b.mesh.n_vertices
    assert b.mesh.signed_volume() == pytest.approx(b.volume_mm3, rel=1e-2)


def test_single_contour_body():
    body = Body("outer", (Contour(0.0, circle(0, 0, 10, 64)),), "end", "end")
    half = build_body(body, 3.0, SurfaceOptions(caps="half", samples=2))
    area = abs(curve_area(slice_curves([body.contours[0].points], [0.0], 64).curves[0]))
    assert half.volume_mm3 == pytest.approx(area * 3.0, rel=1e-9)
    for caps in ("flat", "none"):
        # no thickness with these caps: the body gets the slab of one spacing, not dropped
        thin = build_body(body, 3.0, SurfaceOptions(caps=caps, samples=2))
        assert thin.caps_used == ("half", "half") and thin.volume_mm3 == pytest.approx(half.volume_mm3)
        assert thin.mesh.is_watertight()
    assert half.mesh.is_watertight()
    dome = build_body(body, 3.0, SurfaceOptions(caps="dome"), mesh=False)
    assert 0 < dome.volume_mm3 < half.volume_mm3


def test_hole_body_faces_into_the_hole():
    body = Body("hole", tuple(Contour(z, circle(0, 0, 5, 48)) for z in (0.0, 2.0, 4.0)), "end", "end")
    b = build_body(body, 2.0, SurfaceOptions(samples=2))
    assert b.volume_mm3 > 0  # the volume is reported positive; the reconstruction subtracts it
    assert b.mesh.signed_volume() < 0 and b.mesh.is_oriented()


def test_branching_end_gets_half_caps():
    conts = tuple(Contour(z, circle(0, 0, 8, 48)) for z in (0.0, 2.0))
    flat = SurfaceOptions(caps="flat")  # the half cap at the branching against a flat true end
    ended = build_body(Body("outer", conts, "end", "end"), 2.0, flat, mesh=False)
    split = build_body(Body("outer", conts, "end", "branch"), 2.0, flat, mesh=False)
    area = abs(curve_area(slice_curves([conts[0].points], [0.0], 64).curves[0]))
    assert split.volume_mm3 - ended.volume_mm3 == pytest.approx(area * 1.0, rel=1e-6)


def test_unequal_planes_use_the_median_interval():
    conts = tuple(Contour(z, circle(0, 0, 8, 48)) for z in (0.0, 2.0, 4.0, 8.0))
    b = build_body(Body("outer", conts, "end", "end"), 3.0, SurfaceOptions(caps="half"), mesh=False)
    flat = build_body(Body("outer", conts, "end", "end"), 3.0, SurfaceOptions(caps="flat"), mesh=False)
    area = abs(curve_area(slice_curves([conts[0].points], [0.0], 64).curves[0]))
    # planes 2, 2 and 4 mm apart: half caps of half the median interval (2 mm), not of the 3 mm given
    assert b.volume_mm3 - flat.volume_mm3 == pytest.approx(2 * area * 1.0, rel=1e-6)
    assert np.isfinite(b.area_mm2)


def test_mesh_samples_follow_edge_length_and_budget():
    from slices.body import EDGE_MM, MAX_SAMPLES, mesh_samples

    c = np.zeros((40, 10, 4, 4, 3))
    c[..., 0] = 0.5 * EDGE_MM * np.arange(4)[:, None] / 3  # half an edge around
    c[..., 2] = 4.5 * EDGE_MM * np.arange(4)[None, :] / 3  # four and a half edges across
    assert mesh_samples(c) == (1, 5)
    assert mesh_samples(100 * c) == (MAX_SAMPLES, MAX_SAMPLES)
    # the budget lowers the larger count first
    assert mesh_samples(c, budget=40 * 10 * 3) == (1, 3)
    assert mesh_samples(c, budget=1) == (1, 1)


def test_body_records_its_mesh_density(ellipsoid_body):
    from slices.body import mesh_samples

    adaptive = build_body(ellipsoid_body, 2.5, SurfaceOptions(caps="half"))
    side = adaptive.patches.control[:, adaptive.side_columns]
    assert adaptive.mesh_samples == mesh_samples(side)
    assert build_body(ellipsoid_body, 2.5, SurfaceOptions(samples=2)).mesh_samples == (2, 2)
    assert build_body(ellipsoid_body, 2.5, mesh=False).mesh_samples is None


@pytest.mark.parametrize("shape", [(3, 2), (37, 29), (1, 1), (64, 9)])
def test_mesh_samples_equals_the_median_of_every_control_polygon(shape):
    # chunked over the flat control points: the same polygons and medians as written per patch
    from slices.body import EDGE_MM, MAX_SAMPLES, mesh_samples
    from slices.caps import _median

    rng = np.random.default_rng(sum(shape))
    c = rng.normal(scale=3.0, size=shape + (4, 4, 3))
    pu = np.linalg.norm(np.diff(c, axis=2), axis=-1).sum(axis=2)
    pv = np.linalg.norm(np.diff(c, axis=3), axis=-1).sum(axis=3)
    for p in (pu, pv, pu[..., :3]):
        assert _median(p.copy()) == pytest.approx(np.median(p), rel=1e-15, abs=0)
    want = tuple(int(np.clip(np.ceil(np.median(p) / EDGE_MM), 1, MAX_SAMPLES)) for p in (pu, pv))
    budget = 10**9
    assert mesh_samples(c, budget) == want
    assert mesh_samples(np.asfortranarray(c), budget) == want


@pytest.mark.parametrize("offset", [0.0, 300.0])
def test_mesh_samples_decides_in_double_precision_near_a_multiple_of_the_edge(offset):
    # polygons a nanometre longer than one and two edges: single precision cannot tell them from
    # exactly one and two edges (which would give one subdivision fewer each way)
    from slices.body import EDGE_MM, _polygon_lengths, mesh_samples

    c = np.full((40, 10, 4, 4, 3), offset)
    c[..., 0] += (EDGE_MM + 1e-9) * np.arange(4)[:, None] / 3
    c[..., 2] += (2 * EDGE_MM + 1e-9) * np.arange(4)[None, :] / 3
    (pu, pv), _ = _polygon_lengths(c, np.float32)
    assert np.ceil(np.median(pu) / EDGE_MM) == 1 and np.ceil(np.median(pv) / EDGE_MM) == 2
    assert mesh_samples(c) == (2, 3)
    c[..., 0] -= 2e-9 * np.arange(4)[:, None] / 3  # a nanometre shorter
    assert mesh_samples(c) == (1, 3)


def test_mesh_samples_single_precision_agrees_with_double():
    from slices.body import EDGE_MM, MAX_SAMPLES, _polygon_lengths, mesh_samples
    from slices.caps import _median

    rng = np.random.default_rng(7)
    for scale in (0.1, 0.7, 1.3, 2.0, 4.0):
        c = rng.normal(scale=scale, size=(50, 7, 4, 4, 3)) + rng.normal(scale=200.0, size=3)
        (pu, pv), reach = _polygon_lengths(c, np.float64)
        assert reach == pytest.approx(np.abs(c).max(), rel=1e-15)
        want = tuple(int(np.clip(np.ceil(_median(p) / EDGE_MM), 1, MAX_SAMPLES)) for p in (pu, pv))
        assert mesh_samples(c, 10**9) == want
    # coordinates too large for single-precision squares, or for a float32 at all: double precision
    c = np.zeros((4, 3, 4, 4, 3))
    c[..., 2] = 3.0 * EDGE_MM * np.arange(4)[None, :] / 3
    for far, reach in ((1e17, 2e17), (1e39, np.inf)):
        c[..., 0] = far * (1 + np.arange(4)[:, None] / 3)
        with np.errstate(over="ignore", invalid="ignore"):
            assert _polygon_lengths(c, np.float32)[1] == pytest.approx(reach, rel=1e-7)
        assert mesh_samples(c) == (MAX_SAMPLES, 3)
