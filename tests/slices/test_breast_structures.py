"""Real structure set (breast plan): capped reconstructions are outward oriented solids; set operations."""

from __future__ import annotations

import pytest

from slices.io import load
from slices.pipeline import compose_rois, reconstruct, reconstruct_contours
from surfaces import boolean
from surfaces.io import read_mesh


def _rtss(shared_data):
    return shared_data / "rtstruct_breast" / "rtss.dcm"


def _assert_solid(mesh, what: str, outward: bool = True) -> None:
    assert mesh.is_watertight(), f"{what}: not watertight"
    assert mesh.is_oriented(), f"{what}: neighbouring triangles disagree on orientation"
    sign = 1.0 if outward else -1.0
    assert sign * mesh.signed_volume() > 0, f"{what}: oriented {'inward' if outward else 'outward'}"


@pytest.mark.parametrize(("roi", "caps"), [
    ("Breast", "flat"), ("Breast", "half"), ("Breast", "dome"), ("Heart", "flat"), ("Heart", "half"),
    ("Heart", "dome"), ("Lt Lung", "half"), ("BODY", "half"),
])
def test_capped_bodies_and_solid_are_oriented_outward(shared_data, roi, caps):
    stack = load(_rtss(shared_data), roi=roi)
    rec = reconstruct_contours(stack.contours, caps=caps, samples=1 if roi == "BODY" else 2)
    for i, b in enumerate(rec.bodies):
        # holes are oriented into the hole (negative signed volume) so the solid excludes them
        _assert_solid(b.mesh, f"{roi} body {i} ({b.body.kind})", outward=b.body.kind == "outer")
        # the coarse test tessellation against the exact patch integral (tiny bodies: absolute slack)
        assert abs(b.mesh.signed_volume()) == pytest.approx(b.volume_mm3, rel=5e-2, abs=1e-4 * rec.volume_mm3)
    # BODY's mesh exceeds the union limit: the command line writes its bodies side by side
    solid = rec.mesh if roi == "BODY" else rec.solid_mesh()[0]
    _assert_solid(solid, f"{roi} solid")
    assert solid.signed_volume() == pytest.approx(rec.volume_mm3, rel=2e-2)


def test_written_breast_surface_is_an_oriented_solid(shared_data, tmp_path):
    """The reported case: ``workbench slices reconstruct rtss.dcm --roi Breast --caps half``, read back."""
    summary = reconstruct(_rtss(shared_data), tmp_path, roi="Breast", caps="half", samples=2,
                          render=False, reference=False)
    assert summary["mesh_watertight"] and summary["mesh_oriented"]
    mesh = read_mesh(tmp_path / "surface.ply")
    _assert_solid(mesh, "surface.ply")
    assert mesh.signed_volume() == pytest.approx(summary["volume_mm3"], rel=2e-3)


@pytest.fixture(scope="module")
def breast(shared_data):
    stack = load(_rtss(shared_data), roi="Breast")
    return stack, reconstruct_contours(stack.contours, caps="half", samples=2)


@pytest.mark.parametrize("other", ["Nodes", "Tumor Bed"])
def test_difference_equals_base_minus_intersection(shared_data, breast, other):
    """vol(A - B) = vol(A) - vol(A n B): Nodes overlap the breast in part, the tumour bed lies inside it."""
    stack, rec = breast
    mesh, comp = compose_rois(_rtss(shared_data), stack, rec, minus=[other], caps="half", samples=2)
    a = rec.solid_mesh()[0]
    b = reconstruct_contours(load(_rtss(shared_data), roi=other).contours, caps="half", samples=2).solid_mesh()[0]
    inter = boolean.boolean(a, b, "intersection").volume
    vol_a, vol_b = a.signed_volume(), b.signed_volume()
    assert 0 < inter <= vol_b * (1 + 1e-9)
    if other == "Nodes":
        assert inter < 0.5 * vol_b  # a real partial overlap, not containment
    _assert_solid(mesh, "Breast - " + other)
    assert comp["base"]["mesh_volume_mm3"] == pytest.approx(vol_a, rel=1e-12)
    assert comp["minus"][0]["mesh_volume_mm3"] == pytest.approx(vol_b, rel=1e-12)
    assert comp["result_volume_mm3"] == pytest.approx(vol_a - inter, rel=1e-6)
    assert comp["removed_volume_mm3"] == pytest.approx(inter, rel=1e-6)
    assert comp["added_volume_mm3"] == pytest.approx(0.0, abs=1e-6 * vol_a)
    assert comp["watertight"] and comp["oriented"]
    assert comp["base"]["volume_ml"] == pytest.approx(rec.volume_mm3 / 1000)


def test_union_with_plus_adds_the_outside_part(shared_data, breast):
    stack, rec = breast
    mesh, comp = compose_rois(_rtss(shared_data), stack, rec, plus=["Nodes"], caps="half", samples=2)
    a = rec.solid_mesh()[0]
    b = reconstruct_contours(load(_rtss(shared_data), roi="Nodes").contours, caps="half", samples=2).solid_mesh()[0]
    inter = boolean.boolean(a, b, "intersection").volume
    assert comp["added_volume_mm3"] == pytest.approx(b.signed_volume() - inter, rel=1e-6)
    assert comp["result_volume_mm3"] == pytest.approx(a.signed_volume() + b.signed_volume() - inter, rel=1e-6)
    _assert_solid(mesh, "Breast + Nodes")


def test_composition_needs_closed_solids_and_known_rois(shared_data, breast, tmp_path):
    with pytest.raises(ValueError, match="caps"):
        reconstruct(_rtss(shared_data), tmp_path, roi="Breast", caps="none", minus=["Nodes"])
    stack, rec = breast
    with pytest.raises(ValueError, match="Heart"):
        compose_rois(_rtss(shared_data), stack, rec, minus=["Liver"], caps="half", samples=2)
    with pytest.raises(ValueError, match="minus"):
        compose_rois(_rtss(shared_data), stack, rec, caps="half", samples=2)
