"""Structure-set composition on the real breast plan: set operations of reconstructed ROIs."""

from __future__ import annotations

import pytest

from slices.compose import compose_rois, roi_solid
from slices.io import load
from slices.structure import reconstruct_contours
from surfaces import boolean
from tests.slices._stacks import branching_stack


def _rtss(shared_data):
    return shared_data / "rtstruct_breast" / "rtss.dcm"


def _assert_solid(mesh, what: str) -> None:
    assert mesh.is_watertight(), f"{what}: not watertight"
    assert mesh.is_oriented(), f"{what}: neighbouring triangles disagree on orientation"
    assert mesh.signed_volume() > 0, f"{what}: oriented inward"


@pytest.fixture(scope="module")
def breast(shared_data):
    stack = load(_rtss(shared_data), roi="Breast")
    return stack, reconstruct_contours(stack.contours, caps="half", samples=2)


def _other(shared_data, roi):
    return reconstruct_contours(load(_rtss(shared_data), roi=roi).contours, caps="half", samples=2).solid_mesh()[0]


@pytest.mark.parametrize("other", ["Nodes", "Tumor Bed"])
def test_difference_equals_base_minus_intersection(shared_data, breast, other):
    """vol(A - B) = vol(A) - vol(A n B): Nodes overlap the breast in part, the tumour bed lies inside it."""
    stack, rec = breast
    mesh, comp = compose_rois(_rtss(shared_data), stack, rec, minus=[other])
    a = rec.solid_mesh()[0]
    b = _other(shared_data, other)
    inter = boolean.boolean(a, b, "intersection").volume
    vol_a, vol_b = a.signed_volume(), b.signed_volume()
    assert 0 < inter <= vol_b * (1 + 1e-9)
    if other == "Nodes":
        assert inter < 0.5 * vol_b  # a real partial overlap, not containment
    _assert_solid(mesh, "Breast - " + other)
    assert comp["base"]["mesh_volume_mm3"] == pytest.approx(vol_a, rel=1e-12)
    # the other ROI is built with the base's options
    assert comp["minus"][0]["mesh_volume_mm3"] == pytest.approx(vol_b, rel=1e-12)
    assert comp["result_mesh_volume_mm3"] == pytest.approx(vol_a - inter, rel=1e-6)
    assert comp["removed_volume_mm3"] == pytest.approx(inter, rel=1e-6)
    # the reported difference: the base's patch volume less what the meshes remove, never above the minuend
    assert comp["result_volume_mm3"] == pytest.approx(rec.volume_mm3 - inter, rel=1e-6)
    assert comp["result_volume_mm3"] < rec.volume_mm3
    assert comp["added_volume_mm3"] == pytest.approx(0.0, abs=1e-6 * vol_a)
    assert comp["watertight"] and comp["oriented"]
    assert comp["base"]["volume_ml"] == pytest.approx(rec.volume_mm3 / 1000)
    assert comp["operation"] == f"'Breast' - {other!r}"


def test_union_with_plus_adds_the_outside_part(shared_data, breast):
    stack, rec = breast
    mesh, comp = compose_rois(_rtss(shared_data), stack, rec, plus=["Nodes"])
    a = rec.solid_mesh()[0]
    b = _other(shared_data, "Nodes")
    inter = boolean.boolean(a, b, "intersection").volume
    assert comp["added_volume_mm3"] == pytest.approx(b.signed_volume() - inter, rel=1e-6)
    assert comp["result_mesh_volume_mm3"] == pytest.approx(a.signed_volume() + b.signed_volume() - inter, rel=1e-6)
    assert comp["result_volume_mm3"] == pytest.approx(rec.volume_mm3 + b.signed_volume() - inter, rel=1e-6)
    _assert_solid(mesh, "Breast + Nodes")


def test_composition_needs_known_rois(shared_data, breast):
    stack, rec = breast
    with pytest.raises(ValueError, match="Heart"):
        compose_rois(_rtss(shared_data), stack, rec, minus=["Liver"])
    with pytest.raises(ValueError, match="minus"):
        compose_rois(_rtss(shared_data), stack, rec)


def test_composition_needs_a_structure_set(tmp_path):
    from slices.io import ContourStack
    from surfaces.io import write_json

    path = write_json(tmp_path / "fork.json", {"contours": [{"z": c.z, "points": c.points} for c in branching_stack()]})
    rec = reconstruct_contours(branching_stack(), caps="flat", samples=1)
    with pytest.raises(ValueError, match="json input"):
        compose_rois(path, ContourStack(branching_stack(), "json", "fork"), rec, minus=["fork"])


def test_roi_solid_unites_bodies_or_says_why_not():
    from slices.io import ContourStack

    rec = reconstruct_contours(branching_stack(), surface_path="coons", caps="flat", samples=2)
    stack = ContourStack(branching_stack(), "json", "fork")
    solid = roi_solid(stack, rec)
    assert solid.is_watertight() and solid.surface_area() < rec.mesh.surface_area()  # inner caps gone
    open_rec = reconstruct_contours(branching_stack(), surface_path="coons", caps="none", samples=2)
    with pytest.raises(ValueError, match="fork: its 3 bodies could not be united"):
        roi_solid(stack, open_rec)
