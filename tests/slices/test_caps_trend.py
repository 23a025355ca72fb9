"""Trend caps shaped as the area trend says (issue 35 follow-up): rings whose areas follow the trend, closing in
an apex; the written surface's volume and area against analytic spheres and ellipsoids; a valid solid by an
independent checker."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from slices import caps
from slices.chaining import Body
from slices.body import build_body
from slices.io import Contour
from slices.options import SurfaceOptions
from slices.surface import slice_curves
from slices.volume import whole_volume
from surfaces.intersect import self_intersections
from tests.slices._stacks import circle


def _contours(phantom, spacing: float, offset: float) -> list[Contour]:
    return [Contour(c["z"], np.asarray(c["points"], float))
            for c in phantom.contours(spacing, n_points=96, offset_mm=offset, seed=3)]


def _body(contours) -> Body:
    return Body("outer", tuple(contours), "end", "end")


def _sphere_curves(r: float, zs) -> np.ndarray:
    t = np.linspace(0.0, 2 * np.pi, 256, endpoint=False)
    pts = [np.sqrt(r * r - z * z) * np.column_stack([np.cos(t), np.sin(t)]) for z in zs]
    return slice_curves(pts, np.asarray(zs, float), 64, 256).curves


def test_trend_rings_follow_the_sphere_and_close_at_its_pole():
    # sphere of radius 5 mm cut at z = 4, 2, 0: the pole 1 mm above the end plane
    c = _sphere_curves(5.0, [4.0, 2.0, 0.0])
    rings = caps.trend_rings(c, 2.0, upward=True)
    assert rings.shape == (caps.TREND_RINGS,) + c.shape[1:]
    z = rings[:, 0, 0, 2]
    assert np.all(np.diff(z) > 0) and z[-1] == pytest.approx(5.0, abs=2e-3)
    assert np.ptp(rings[-1].reshape(-1, 3), axis=0).max() < 1e-12  # the apex: one point
    # every ring's area is the sphere's section at its height (the curves' own 0.05 % polygon error aside)
    got = np.array([abs(caps.curve_area(r)) for r in rings[:-1]])
    assert np.allclose(got, np.pi * (25.0 - z[:-1] ** 2), rtol=2e-3)
    # below a lower end: mirrored
    low = caps.trend_rings(c[::-1][::-1], 2.0, upward=False)
    assert np.all(np.diff(low[:, 0, 0, 2]) < 0)


def test_trend_rings_none_where_the_trend_does_not_close():
    c = _sphere_curves(5.0, [0.0, 0.0, 0.0]) + np.array([0.0, 0.0, 1.0]) * np.arange(3)[:, None, None, None]
    assert caps.trend_rings(c, 1.0, upward=True) is None  # a cylinder's end: a prism instead


def test_mid_ring_area_follows_the_sphere_curvature():
    c = _sphere_curves(3.0, [-1.0, 2.0])
    mid = caps.mid_ring(c[0], c[1])
    assert mid[0, 0, 2] == pytest.approx(0.5)
    target = (abs(caps.curve_area(c[0])) + abs(caps.curve_area(c[1]))) / 2 + np.pi * 9.0 / 4
    assert abs(caps.curve_area(mid)) == pytest.approx(target, rel=1e-9)
    assert abs(caps.curve_area(mid)) == pytest.approx(np.pi * (9 - 0.25), rel=2e-3)  # the sphere's own section


SOLIDS = [
    ("sphere 8 mm, 3 mm", ("ellipsoid", {"a": 4.0, "b": 4.0, "c": 4.0}), 3.0, 0.9),
    ("sphere 5 mm, two planes", ("ellipsoid", {"a": 2.5, "b": 2.5, "c": 2.5}), 3.0, 0.9),
    ("sphere 20 mm, 2 mm", ("ellipsoid", {"a": 10.0, "b": 10.0, "c": 10.0}), 2.0, 0.6),
    ("ellipsoid", ("ellipsoid", {"a": 10.0, "b": 6.0, "c": 4.0}), 3.0, 2.1),
    ("ellipsoid, long axis in z", ("ellipsoid", {"a": 3.0, "b": 5.0, "c": 8.0}), 2.0, 0.6),
]


@pytest.mark.parametrize("name, solid, spacing, offset", SOLIDS, ids=[s[0] for s in SOLIDS])
def test_trend_surface_area_and_volume_against_the_closed_forms(name, solid, spacing, offset):
    ph = make_phantom(solid[0], **solid[1])
    cs = _contours(ph, spacing, offset)
    body = _body(cs)
    trend = build_body(body, spacing, SurfaceOptions(samples=3))
    half = build_body(body, spacing, SurfaceOptions(caps="half", samples=3))  # a flat-topped prism's end
    assert trend.caps_used == ("trend", "trend") and trend.extrusions_mm == (0.0, 0.0)
    area_err = trend.area_mm2 / ph.area_mm2 - 1
    vol_err = trend.volume_mm3 / ph.volume_mm3 - 1
    assert abs(area_err) < 0.015, area_err
    assert abs(vol_err) < 0.03, vol_err
    assert abs(area_err) < abs(half.area_mm2 / ph.area_mm2 - 1)
    # the rings enclose the trend's own volume beyond each end plane (to the blend's accuracy)
    w = whole_volume(cs, spacing)
    assert sum(trend.cap_volumes_mm3) == pytest.approx(w["caps_mm3"], rel=0.03)
    # the mesh as written: closed, outward, its volume the patches'
    m = trend.mesh
    assert m.is_watertight() and m.is_oriented()
    assert m.signed_volume() == pytest.approx(trend.volume_mm3, rel=2.5e-2)  # chords of 3 samples a patch


def test_trend_volume_with_flat_caps_is_the_flat_capped_body():
    ph = make_phantom("ellipsoid", a=6.0, b=5.0, c=7.0)
    body = _body(_contours(ph, 2.0, 0.7))
    trend = build_body(body, 2.0, SurfaceOptions(), mesh=False)
    flat = build_body(body, 2.0, SurfaceOptions(caps="flat"), mesh=False)
    # the side between the planes is blended apart from the rings: the same side as flat caps'
    assert trend.volume_with_caps("flat") == pytest.approx(flat.volume_mm3, rel=1e-9)
    assert trend.volume_with_caps("half") == pytest.approx(
        flat.volume_mm3 + sum(trend.end_areas_mm2) * 1.0, rel=1e-9)


def test_single_contour_trend_body_keeps_its_prisms():
    body = Body("outer", (Contour(0.0, circle(0, 0, 1.2, 96)),), "end", "end")
    b = build_body(body, 3.0, SurfaceOptions(samples=3))
    assert b.caps_used == ("trend", "trend") and b.mesh.is_watertight() and b.mesh.is_oriented()
    assert min(b.extrusions_mm) > 0  # the slab a single plane is reported as, as thick as the trend's volume
    # a sphere through its outline: 4/3 pi r^3 with r the outline's radius (equator)
    assert b.volume_mm3 == pytest.approx(4 / 3 * np.pi * 1.2**3, rel=0.03)


@pytest.mark.parametrize("name, solid, spacing, offset", SOLIDS[:4], ids=[s[0] for s in SOLIDS[:4]])
def test_trend_mesh_has_no_self_intersections_by_independent_checks(name, solid, spacing, offset, tmp_path):
    pymeshlab = pytest.importorskip("pymeshlab")
    from surfaces.io import write_mesh

    ph = make_phantom(solid[0], **solid[1])
    b = build_body(_body(_contours(ph, spacing, offset)), spacing, SurfaceOptions())
    assert self_intersections(b.mesh.vertices, b.mesh.triangles).n_faces == 0
    write_mesh(b.mesh, tmp_path / "surface.ply")
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(tmp_path / "surface.ply"))
    ms.compute_selection_by_self_intersections_per_face()
    assert ms.current_mesh().selected_face_number() == 0
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(1e-4))
    topo = ms.get_topological_measures()
    assert topo["boundary_edges"] == 0 and topo["non_two_manifold_edges"] == 0
    assert topo["non_two_manifold_vertices"] == 0 and topo["connected_components_number"] == 1


@pytest.mark.parametrize("radius, offset", [(2.5, 0.9), (1.8, 1.5)])
def test_two_plane_trend_body_counts_other_caps_over_the_straight_side(radius, offset):
    ph = make_phantom("ellipsoid", a=radius, b=radius, c=radius)
    cs = _contours(ph, 3.0, offset)
    assert len({c.z for c in cs}) == 2
    body = _body(cs)
    trend = build_body(body, 3.0, SurfaceOptions(), mesh=False)
    flat = build_body(body, 3.0, SurfaceOptions(caps="flat"), mesh=False)
    assert trend.mid_bulge_mm3 > 0
    assert trend.volume_with_caps("flat") == pytest.approx(flat.volume_mm3, rel=1e-9)


def test_three_plane_trend_body_has_no_mid_bulge():
    ph = make_phantom("ellipsoid", a=3.0, b=3.0, c=3.0)
    cs = _contours(ph, 2.0, 0.55)
    assert len({c.z for c in cs}) == 3
    trend = build_body(_body(cs), 2.0, SurfaceOptions(), mesh=False)
    flat = build_body(_body(cs), 2.0, SurfaceOptions(caps="flat"), mesh=False)
    assert trend.mid_bulge_mm3 == 0.0
    assert trend.volume_with_caps("flat") == pytest.approx(flat.volume_mm3, rel=1e-9)


def test_summary_states_which_caps_the_surface_got():
    from slices.structure import reconstruct_contours
    from slices.summary import caps_notes

    ph = make_phantom("ellipsoid", a=4.0, b=4.0, c=4.0)
    rec = reconstruct_contours(_contours(ph, 2.0, 0.55), spacing=2.0, mesh=False)
    (note,) = caps_notes(rec)
    assert "at 2 ends, prisms" in note and "at 0 (" in note and "(s)" not in note
    # a ring with a hole takes the implicit path, which closes its own way
    ring = [Contour(float(z), p) for z in (0.0, 2.0, 4.0) for p in (circle(0, 0, 8, 64), circle(0, 0, 3, 64)[::-1])]
    rec = reconstruct_contours(ring, spacing=2.0)
    assert rec.implicit is not None and "implicit" in caps_notes(rec)[0]
    assert caps_notes(reconstruct_contours(_contours(ph, 2.0, 0.55), spacing=2.0, mesh=False,
                                           options=SurfaceOptions(caps="half"))) == []


def _polygon(corners, z: float) -> np.ndarray:
    a, b = corners, np.roll(corners, -1, axis=0)
    w = np.arange(4) / 3.0
    curve = a[:, None, :] + w[None, :, None] * (b - a)[:, None, :]
    return np.concatenate([curve, np.full(curve.shape[:2] + (1,), z)], axis=2)


@pytest.mark.parametrize("corners, ringed", [
    ([(0, 0), (4, 0), (4, 4), (0, 4)], True),
    ([(0, 0), (4, 0), (4, 4), (3, 4), (3, 1), (1, 1), (1, 4), (0, 4)], False),  # a U: no point sees it all
])
def test_trend_rings_only_where_a_point_sees_the_whole_end(corners, ringed):
    c = np.asarray(corners, float) - 2.0
    # areas A, 4 A, 9 A one spacing apart: the trend A (1 - t)^2 closes one spacing beyond
    curves = np.stack([_polygon(c * k, -float(k - 1)) for k in (1, 2, 3)])
    rings = caps.trend_rings(curves, 1.0, upward=True)
    assert (rings is not None) == ringed
    if ringed:
        assert rings[-1, 0, 0, 2] == pytest.approx(1.0)
