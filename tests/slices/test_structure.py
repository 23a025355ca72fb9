"""All bodies of a structure: volume, area, holes, branchings and the united solid, against phantoms."""

from __future__ import annotations

import json
import numpy as np

import pytest

from slices.caps import curve_area
from slices.polygons import signed_area
from slices.io import Contour
from slices.options import ReadOptions, SurfaceOptions
from slices.structure import reconstruct_contours, reconstruct_roi, solid_union
from slices.surface import slice_curves
from tests.slices._stacks import branching_stack, circle, mesh_distance, phantom_stack


@pytest.fixture(scope="module")
def ellipsoid():
    return phantom_stack("ellipsoid", a=15.0, b=10.0, c=12.0, n_points=48)


@pytest.mark.parametrize("method", ["blending", "coons", "bspline"])
def test_methods_pass_through_points_and_close(ellipsoid, method):
    _, conts, truth = ellipsoid
    rec = reconstruct_contours(conts, method=method, caps="flat", samples=4)
    assert rec.max_deviation_mm < 1e-6
    assert rec.mesh.is_watertight()
    exact = truth["volume_between_end_planes_mm3"]
    assert abs(rec.volume_mm3 / exact - 1) < 2e-3
    # the mesh encloses (almost) the same volume as the patches
    assert abs(rec.mesh.signed_volume() / rec.volume_mm3 - 1) < 5e-3


def test_options_object_and_keywords_agree(ellipsoid):
    _, conts, _ = ellipsoid
    opts = SurfaceOptions(caps="half", n_rays=32)
    a = reconstruct_contours(conts[:5], mesh=False, options=opts)
    b = reconstruct_contours(conts[:5], mesh=False, caps="half", n_rays=32)
    assert a.volume_mm3 == b.volume_mm3 and a.options == b.options == opts
    # keywords override the object
    c = reconstruct_contours(conts[:5], mesh=False, options=opts, caps="flat")
    assert c.options.caps == "flat" and c.volume_mm3 < a.volume_mm3


def test_adaptive_density_follows_the_contours_sampling(ellipsoid):
    _, conts, _ = ellipsoid
    from slices.body import EDGE_MM, MESH_BUDGET

    rec = reconstruct_contours(conts)
    assert rec.options.samples is None  # what was asked for; each body got the density of mesh_samples
    mesh = rec.mesh
    assert mesh.is_watertight() and mesh.is_oriented()
    corners = mesh.vertices[mesh.triangles]
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)
    assert np.median(edges) <= EDGE_MM
    # coarser than two subdivisions per patch side, and still on the patch surface: the inscribed
    # mesh encloses and covers a little less than the patches, by well under a percent
    assert mesh.n_vertices < reconstruct_contours(conts, samples=2).mesh.n_vertices
    assert 0.995 * rec.volume_mm3 < mesh.signed_volume() < rec.volume_mm3
    assert 0.995 * rec.area_mm2 < mesh.surface_area() < rec.area_mm2
    # a larger one (four times the points per contour and the planes) stays far below the budget
    _, dense, _ = phantom_stack("ellipsoid", spacing=0.5, a=15.0, b=10.0, c=12.0, n_points=192)
    big = reconstruct_contours(dense, mesh=True)
    assert big.mesh.n_vertices < min(MESH_BUDGET, reconstruct_contours(dense, samples=2).mesh.n_vertices)


def test_kidney_accuracy():
    ph, conts, truth = phantom_stack("kidney", n_points=96)
    rec = reconstruct_contours(conts, caps="flat", samples=4)
    assert rec.max_deviation_mm < 1e-6
    assert abs(rec.volume_mm3 / truth["volume_between_end_planes_mm3"] - 1) < 5e-3
    pts = ph.surface_points(4000, seed=1)
    inside = (pts[:, 2] >= truth["z_first_contour_mm"]) & (pts[:, 2] <= truth["z_last_contour_mm"])
    assert mesh_distance(rec.mesh, pts[inside]).mean() < 0.1


def test_ring_hole_is_subtracted():
    _, conts, truth = phantom_stack("ring", n_points=48)
    rec = reconstruct_contours(conts, surface_path="coons", caps="flat", samples=2)
    kinds = sorted(b.body.kind for b in rec.bodies)
    assert kinds == ["hole", "outer"]
    assert abs(rec.volume_mm3 / truth["volume_between_end_planes_mm3"] - 1) < 5e-3
    hole = next(b for b in rec.bodies if b.body.kind == "hole")
    # the hole's surface faces into the hole: its oriented mesh encloses negative volume
    assert hole.mesh.signed_volume() < 0


def test_branching_splits_chain_and_separate_bodies():
    conts = branching_stack() + [Contour(0.0, circle(40, 0, 5)), Contour(2.0, circle(40, 0, 5))]
    rec = reconstruct_contours(conts, surface_path="coons", caps="flat", samples=2)
    # the split bodies meet half-way: volume close to the slab count of the middle slab
    assert rec.volume_mm3 > 0 and len(rec.bodies) == 4
    assert rec.mesh.is_watertight()


def test_single_contour_bodies():
    conts = [Contour(0.0, circle(0, 0, 10, 64)), Contour(3.0, circle(30, 0, 5, 64)),
             Contour(6.0, circle(30, 0, 5, 64))]
    area = abs(curve_area(slice_curves([circle(0, 0, 10, 64)], [0.0], 16).curves[0]))
    for caps in ("none", "flat", "half", "dome"):
        # a single contour is never dropped: with none/flat it gets the planning systems' slab
        rec = reconstruct_contours(conts, surface_path="coons", spacing=3.0, caps=caps, mesh=False)
        assert len(rec.bodies) == 2
        single = next(b for b in rec.bodies if len(b.body.contours) == 1)
        if caps != "dome":
            assert single.caps_used == ("half", "half")
            assert single.volume_mm3 == pytest.approx(area * 3.0, rel=1e-9)
        else:
            assert single.caps_used == ("dome", "dome") and 0 < single.volume_mm3 < area * 3.0


def test_bad_spacing_and_method(ellipsoid):
    _, conts, _ = ellipsoid
    moved = conts[:3] + [Contour(conts[3].z + 0.7, conts[3].points)] + conts[4:]
    with pytest.raises(ValueError, match="unequal slice spacing"):
        reconstruct_contours(moved)
    with pytest.raises(ValueError, match="method"):
        reconstruct_contours(conts, method="nurbs", mesh=False)
    with pytest.raises(ValueError, match="caps"):
        reconstruct_contours(conts, caps="round", mesh=False)
    with pytest.raises(ValueError, match="spacing: 3.0 mm given"):
        reconstruct_contours(conts, spacing=3.0, mesh=False)
    with pytest.raises(ValueError, match="no contours"):
        reconstruct_contours([])
    with pytest.raises(ValueError, match="single plane"):
        reconstruct_contours(conts[:1])


def test_breast_heart_volume_within_planning_systems(shared_data):
    from slices.io import load

    stack = load(shared_data / "rtstruct_breast" / "rtss.dcm", roi="Heart")
    rec = reconstruct_contours(stack.contours, caps="half", mesh=False)
    # dicompyler-core polygons 432.84 cc, TPS DVH 437.46 cc, dose-grid raster 440.23 cc
    assert 432.84 <= rec.volume_mm3 / 1000 <= 440.23
    assert rec.max_deviation_mm < 1e-6
    flat = reconstruct_contours(stack.contours, caps="flat", mesh=False)
    assert flat.volume_mm3 < rec.volume_mm3


def test_unequal_spacing_accepted_when_asked(ellipsoid):
    _, conts, truth = ellipsoid
    # drop every third plane: unequal spacing (2.5 and 5 mm)
    planes = sorted({c.z for c in conts})
    keep = {z for i, z in enumerate(planes) if i % 3 != 1 or i in (0, len(planes) - 1)}
    sparse = [c for c in conts if c.z in keep]
    with pytest.raises(ValueError, match="unequal slice spacing|resample"):
        reconstruct_contours(sparse, mesh=False)
    rec = reconstruct_contours(sparse, irregular=True, samples=2, caps="flat")  # between the end planes
    assert rec.max_deviation_mm < 1e-6 and rec.mesh.is_watertight()
    exact = truth["volume_between_end_planes_mm3"]
    # fewer planes: still closer to the truth than the slab (trapezoid) count
    assert abs(rec.volume_mm3 / exact - 1) < abs(rec.slab_volume_mm3 / exact - 1)
    assert abs(rec.volume_mm3 / exact - 1) < 1.5e-2


def test_branching_solid_has_no_internal_walls():
    rec = reconstruct_contours(branching_stack(64), surface_path="coons", caps="flat", samples=2)
    solid, union = rec.solid_mesh()
    assert union and solid.is_watertight()
    # the internal caps at the branching plane are gone: less area, same volume
    assert solid.surface_area() < rec.mesh.surface_area()
    assert solid.signed_volume() == pytest.approx(rec.mesh.signed_volume(), rel=1e-6)


def test_branching_phantom_solid_has_no_inner_caps():
    # two overlapping spheres whose section splits: every vertex of the united solid lies on
    # the outside (coplanar half caps at the split used to survive as an inner wall 6 mm deep)
    ph, conts, truth = phantom_stack("lobes", spacing=2.5, n_points=64)
    rec = reconstruct_contours(conts, surface_path="coons", caps="flat", samples=2)
    assert any(b.body.stop != "end" for b in rec.bodies)
    solid, union = rec.solid_mesh()
    assert union and solid.is_watertight() and solid.is_oriented()
    depth = -ph.signed_distance(solid.vertices)
    assert depth.max() < 2.6  # flat caps stop up to one spacing short of a lobe's pole


def test_union_needs_closed_meshes():
    rec = reconstruct_contours(branching_stack(), surface_path="coons", caps="none", samples=2)
    assert solid_union(rec.bodies) is None
    mesh, united = rec.solid_mesh()
    assert not united and mesh.n_triangles == rec.mesh.n_triangles
    assert reconstruct_contours(branching_stack(), surface_path="coons", mesh=False).solid_mesh() == (None, False)


def _write_contours(path, contours):
    path.write_text(json.dumps({"units": "mm", "contours": [
        {"z": c.z, "points": c.points.tolist()} for c in contours]}))
    return path


def test_reconstruct_roi_reads_and_builds(ellipsoid, tmp_path):
    _, conts, _ = ellipsoid
    path = _write_contours(tmp_path / "c.json", conts)
    stack, rec = reconstruct_roi(path, options=SurfaceOptions(caps="half", samples=1))
    assert stack.source == "json" and len(stack.contours) == len(conts)
    assert rec.volume_mm3 == pytest.approx(reconstruct_contours(conts, caps="half", samples=1).volume_mm3, rel=1e-12)


def test_reconstruct_roi_resample_blends_contour_files_at_their_planes(ellipsoid, tmp_path):
    _, conts, _ = ellipsoid
    planes = sorted({c.z for c in conts})
    sparse = [c for c in conts if c.z != planes[3]]
    path = _write_contours(tmp_path / "sparse.json", sparse)
    with pytest.raises(ValueError, match="unequal slice spacing"):
        reconstruct_roi(path)
    _, rec = reconstruct_roi(path, reading=ReadOptions(resample=True), options=SurfaceOptions(samples=1))
    assert rec.volume_mm3 == pytest.approx(reconstruct_contours(sparse, irregular=True, samples=1).volume_mm3)


def test_reconstruct_roi_with_only_single_contours(tmp_path):
    path = _write_contours(tmp_path / "one.json", [Contour(0.0, circle(0, 0, 5)), Contour(3.0, circle(20, 0, 5))])
    # flat caps (the default) give a single contour no thickness: it gets the half-cap slab instead
    _, flat = reconstruct_roi(path, options=SurfaceOptions(surface_path="coons"))
    _, rec = reconstruct_roi(path, options=SurfaceOptions(caps="half", surface_path="coons"))
    assert len(rec.bodies) == len(flat.bodies) == 2
    assert flat.volume_mm3 == pytest.approx(rec.volume_mm3) == pytest.approx(rec.slab_volume_mm3 * 2, rel=0.02)
    # the implicit surface (two bodies: the default path) gives each its slab too, to the rounding of its rims
    _, implicit = reconstruct_roi(path)
    assert implicit.surface_path == "implicit"
    assert implicit.volume_mm3 == pytest.approx(rec.volume_mm3, rel=0.03)


def test_volume_by_caps_and_offset_sensitivity():
    from slices.chaining import offset_sensitivity
    t = np.linspace(0, 2 * np.pi, 256, endpoint=False)
    disc = 10 * np.stack([np.cos(t), np.sin(t)], axis=1)
    conts = [Contour(z, disc) for z in (0.0, 5.0, 10.0, 15.0, 20.0)]
    area = float(abs(signed_area(disc)))
    by = {}
    for caps in ("flat", "half", "dome"):
        rec = reconstruct_contours(conts, caps=caps, mesh=False)
        by[caps] = rec.volume_by_caps()
        # whichever caps were built, the conventions agree (dome bodies are rebuilt)
        assert by[caps]["half"] == pytest.approx(by[caps]["flat"] + area * 5.0, rel=1e-3)
        assert by[caps]["none"] == by[caps]["flat"]
        assert by[caps]["slab"] == pytest.approx(area * 20.0)
    assert by["flat"]["half"] == pytest.approx(reconstruct_contours(conts, caps="half", mesh=False).volume_mm3)
    perimeter = float(np.linalg.norm(np.roll(disc, -1, axis=0) - disc, axis=1).sum())
    expected = (perimeter * 0.5 + np.pi * 0.25) * 20.0
    assert rec.sensitivity_mm3 == pytest.approx(expected)
    # the holes of a ring shrink when the contours grow: both perimeters count
    ring = [Contour(z, c) for z in (0.0, 5.0) for c in (disc, 0.5 * disc)]
    assert offset_sensitivity(ring, 5.0) == pytest.approx(perimeter * 1.5 * 0.5 * 5.0)


def test_messages_name_the_real_problem(tmp_path):
    disc = circle(0, 0, 10, 40)
    far = _write_contours(tmp_path / "far.json", [Contour(z, disc + 1e9) for z in (0.0, 2.0, 4.0)])
    with pytest.raises(ValueError, match="not patient coordinates in mm"):
        reconstruct_roi(far)
    tiny = _write_contours(tmp_path / "tiny.json", [Contour(z, disc * 1e-6) for z in (0.0, 2e-6, 4e-6)])
    with pytest.raises(ValueError, match="check the units"):
        reconstruct_roi(tiny)
    one = _write_contours(tmp_path / "one.json", [Contour(0.0, disc)])
    with pytest.raises(ValueError, match="slice-thickness"):
        reconstruct_roi(one)
    # --spacing given: its z is the single plane's slab (no "give it")
    for given in ("2,1,1", "2", 2.0):
        _, rec = reconstruct_roi(one, reading=ReadOptions(spacing=given), options=SurfaceOptions(samples=1))
        assert rec.spacing == 2.0 and rec.volume_mm3 == pytest.approx(abs(signed_area(disc)) * 2.0, rel=1e-2)
