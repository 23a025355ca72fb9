"""One clean solid per structure: closed, outward, one shell, no self-intersecting face (issue 19).

Checked independently of how the surface was built: the triangle-triangle test of
:mod:`surfaces.intersect`, the edge counts of the mesh, and manifold3d (which
accepts the mesh as a manifold and gives the same volume).
"""

from __future__ import annotations

import numpy as np
import pytest

from slices.io import Contour
from slices.structure import reconstruct_contours
from surfaces.intersect import self_intersections
from surfaces.topology import shells
from tests.slices._stacks import branching_stack, circle, phantom_stack


def assert_clean_solid(mesh, n_shells: int = 1):
    import manifold3d

    assert mesh.is_watertight() and mesh.is_oriented() and mesh.signed_volume() > 0
    assert len(np.unique(shells(mesh.triangles, mesh.n_vertices))) == n_shells
    hits = self_intersections(mesh.vertices, mesh.triangles)
    assert hits.n_faces == 0, f"{hits.n_faces} self-intersecting faces"
    peer = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices),
                                                 tri_verts=np.ascontiguousarray(mesh.triangles, dtype=np.uint64)))
    assert peer.status() == manifold3d.Error.NoError
    assert peer.volume() == pytest.approx(mesh.signed_volume(), rel=1e-6)


def shell_counts(mesh) -> tuple[int, int]:
    """Outer shells (positive signed volume) and cavities (negative) of a closed mesh."""
    label = shells(mesh.triangles, mesh.n_vertices)
    c = mesh.vertices[mesh.triangles]
    volume = np.bincount(label, np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])) / 6.0)
    return int(np.sum(volume > 0)), int(np.sum(volume < 0))


def c_shape_stack() -> list[Contour]:
    """A disc with its hole opened by a wide channel (a C, one outline), on three planes."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)[3:-3]
    outer = np.stack([12 * np.cos(t), 12 * np.sin(t)], 1)
    inner = np.stack([5 * np.cos(t[::-1]), 5 * np.sin(t[::-1])], 1)
    pts = np.vstack([outer, inner])
    return [Contour(z, pts) for z in (0.0, 2.5, 5.0)]


@pytest.mark.parametrize("shape", ["ellipsoid", "kidney", "ring", "lobes", "tilted_cylinder", "lens", "chiasm"])
@pytest.mark.parametrize("caps", ["flat", "half", "dome"])
def test_phantoms_give_one_clean_solid(shape, caps, request):
    if (shape, caps) == ("ring", "dome"):
        request.applymarker(pytest.mark.xfail(strict=True, reason="known: the outer contour's dome closes over "
                                              "the ring's hole, leaving a cavity (2 shells)"))
    _, conts, _ = phantom_stack(shape, 2.5)
    rec = reconstruct_contours(conts, surface_path="coons", caps=caps, samples=2)
    solid, _ = rec.solid_mesh()
    assert_clean_solid(solid)
    assert all(b.self_intersecting_faces == 0 for b in rec.bodies)


@pytest.mark.parametrize("shape", ["ellipsoid", "kidney", "ring", "tilted_cylinder"])
def test_smooth_phantom_volumes_within_half_a_percent(shape):
    _, conts, truth = phantom_stack(shape, 2.5)
    rec = reconstruct_contours(conts, caps="flat", mesh=False)
    assert rec.volume_mm3 == pytest.approx(truth["volume_between_end_planes_mm3"], rel=0.005)


@pytest.mark.parametrize("shape", ["lens", "chiasm"])
def test_small_structures_report_every_convention(shape):
    ph, conts, truth = phantom_stack(shape, 2.5)
    assert 1 <= len(conts) <= 5
    rec = reconstruct_contours(conts, caps="half", mesh=False)
    by = rec.volume_by_caps()
    # the conventions bracket the true volume: flat caps stop at the end contours, half caps a slab beyond
    assert by["flat"] < ph.volume_mm3 < by["half"]
    assert by["slab"] < by["flat"]


def test_branching_and_c_shape_give_one_clean_solid():
    rec = reconstruct_contours(branching_stack(), surface_path="coons", caps="half", samples=3)
    solid, united = rec.solid_mesh()
    assert united and len(rec.bodies) == 3
    assert_clean_solid(solid)
    # the united solid has no inner caps: less area than the bodies side by side
    assert solid.surface_area() < rec.mesh.surface_area()
    rec = reconstruct_contours(c_shape_stack(), surface_path="coons", caps="flat", samples=2)
    solid, _ = rec.solid_mesh()
    assert_clean_solid(solid)


def test_single_contour_holes_are_subtracted_under_flat_caps():
    disc = [Contour(z, circle(0, 0, 20, 64)) for z in (0.0, 3.0, 6.0, 9.0)]
    hole = [Contour(3.0, circle(0, 0, 5, 32))]
    with_hole = reconstruct_contours(disc + hole, surface_path="coons", caps="flat", samples=2)
    without = reconstruct_contours(disc, surface_path="coons", caps="flat", samples=2)
    hole_slab = abs(with_hole.bodies[-1].volume_mm3)
    assert with_hole.bodies[-1].body.kind == "hole" and with_hole.bodies[-1].caps_used == ("half", "half")
    assert with_hole.volume_mm3 == pytest.approx(without.volume_mm3 - hole_slab)
    solid, united = with_hole.solid_mesh()
    assert united and solid.signed_volume() == pytest.approx(with_hole.volume_mm3, rel=0.01)
    assert_clean_solid(solid, n_shells=2)  # the outer skin and the closed cavity


def _rtss(shared_data):
    return shared_data / "rtstruct_breast" / "rtss.dcm"


@pytest.mark.parametrize("roi", [
    "Scar", "Borders", "Nodes", "Tumor Bed",
    pytest.param("Tumor Bed Block", marks=pytest.mark.slow),
    pytest.param("Heart", marks=pytest.mark.slow),
    pytest.param("Breast", marks=pytest.mark.slow),
    pytest.param("Lt Lung", marks=pytest.mark.slow),
])
def test_breast_rois_give_one_clean_solid(shared_data, roi):
    from slices.pipeline import reconstruct

    result = reconstruct(_rtss(shared_data), roi=roi, caps="half", samples=2, reference=False)
    # several bodies: united (coons) or one implicit surface (issue 34)
    assert result.union or len(result.reconstruction.bodies) == 1 or result.summary["surface_path"] == "implicit"
    # one outer skin; holes drawn inside the structure are closed cavities, shells of their own
    outer, cavities = shell_counts(result.mesh)
    if result.summary["surface_path"] == "implicit":
        # other outer shells are separate islands the structure set draws (the breast's 0.03 mm^2 contour
        # at z = -74.44 mm, too small for a 0.5 mm raster): each holds contour points
        rows = sorted((r for r in result.summary["bodies"] if r["kind"] == "outer"), key=lambda r: -r["volume_mm3"])
        pts = np.concatenate([np.column_stack([c.points, np.full(len(c.points), c.z)])
                              for c in result.stack.contours])
        for r in rows[1:]:
            assert np.any((pts[:, 2] >= r["z_min_mm"]) & (pts[:, 2] <= r["z_max_mm"])), r
        assert max(r["volume_mm3"] for r in rows) > 0.9999 * sum(r["volume_mm3"] for r in rows)
    else:
        assert outer == 1
    assert_clean_solid(result.mesh, n_shells=outer + cavities)
    body_rows = result.summary["bodies"]
    assert all(r.get("self_intersecting_faces", 0) == 0 and r["surface"] for r in body_rows)


@pytest.mark.slow
def test_lt_lung_is_one_outer_skin_around_its_cavities(shared_data):
    from slices.pipeline import reconstruct

    result = reconstruct(_rtss(shared_data), roi="Lt Lung", caps="half", reference=False)
    mesh = result.mesh
    assert result.summary["surface_path"] == "implicit" and mesh.is_watertight() and mesh.is_oriented()
    outer, cavities = shell_counts(mesh)
    holes = sum(r["kind"] == "hole" for r in result.summary["bodies"])
    # the 32 shells the benchmark used to count are the skin and 31 holes inside it, each subtracted
    assert outer == 1 and 0 < cavities == holes
    assert mesh.signed_volume() == pytest.approx(result.summary["volume_mm3"], rel=0.01)


@pytest.mark.slow
def test_breast_body_solid_has_no_needle_at_its_split_plane(shared_data):
    from slices.pipeline import reconstruct

    # 35 bodies; three end in flat caps at z = -104.44 mm where a fourth starts, and the union left a
    # 5e-8 mm sliver whose needle pierced the wall there (every body clean on its own)
    result = reconstruct(_rtss(shared_data), roi="BODY", caps="half", reference=False, surface_path="coons")
    assert result.union and all(r["self_intersecting_faces"] == 0 for r in result.summary["bodies"])
    mesh = result.mesh
    assert mesh.is_watertight() and mesh.is_oriented()
    assert self_intersections(mesh.vertices, mesh.triangles).n_faces == 0
    assert mesh.signed_volume() == pytest.approx(result.summary["volume_mm3"], rel=0.01)


@pytest.mark.slow
def test_breast_body_dome_solid_has_no_needle_at_its_split_plane(shared_data):
    from slices.pipeline import reconstruct

    # with dome caps the union left a needle of 2e-6 mm at z = -104.44 mm (2 crossing faces): it is
    # collapsed among the faces around the crossing only
    result = reconstruct(_rtss(shared_data), roi="BODY", caps="dome", reference=False, surface_path="coons")
    mesh = result.mesh
    assert result.union and mesh.is_watertight() and mesh.is_oriented()
    assert self_intersections(mesh.vertices, mesh.triangles).n_faces == 0
    assert mesh.signed_volume() == pytest.approx(result.summary["volume_mm3"], rel=0.01)
