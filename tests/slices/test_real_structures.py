"""Real structure sets (issue 34): every contour accepted or reported, every ROI one valid solid by an
independent checker (pymeshlab, trimesh), the implicit surface for branching and multi-body structures."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slices import io
from slices.io import Contour
from slices.pipeline import reconstruct
from slices.structure import reconstruct_contours
from tests.slices._stacks import circle

pymeshlab = pytest.importorskip("pymeshlab")
trimesh = pytest.importorskip("trimesh")


# ------------------------------------------------------------------ independent checks
def independent_checks(mesh, weld_mm: float = 1e-3) -> dict:
    """pymeshlab's self-intersecting faces and topology after welding at ``weld_mm`` on the mesh as written
    (``surface.ply``, :func:`surfaces.io.write_mesh`); trimesh's checks."""
    import tempfile
    from pathlib import Path

    from surfaces.io import write_mesh

    ms = pymeshlab.MeshSet()
    with tempfile.TemporaryDirectory() as folder:
        write_mesh(mesh, Path(folder) / "surface.ply")
        ms.load_new_mesh(str(Path(folder) / "surface.ply"))
    ms.compute_selection_by_self_intersections_per_face()
    crossing = ms.current_mesh().selected_face_number()
    ms.meshing_merge_close_vertices(threshold=pymeshlab.PureValue(weld_mm))
    topo = ms.get_topological_measures()
    tm = trimesh.Trimesh(mesh.vertices, mesh.triangles, process=True)
    return {"self_intersecting": crossing, "non_manifold_edges": topo["non_two_manifold_edges"],
            "non_manifold_vertices": topo["non_two_manifold_vertices"], "boundary_edges": topo["boundary_edges"],
            "components": topo["connected_components_number"], "watertight": tm.is_watertight,
            "winding": tm.is_winding_consistent, "volume": float(tm.volume)}


def assert_valid_solid(mesh, components: int | None = None) -> dict:
    c = independent_checks(mesh)
    assert c["self_intersecting"] == 0, c
    assert c["non_manifold_edges"] == 0 and c["non_manifold_vertices"] == 0 and c["boundary_edges"] == 0, c
    assert c["watertight"] and c["winding"], c
    if components is not None:
        assert c["components"] == components, c
    return c


def _write_json(path, contours):
    path.write_text(json.dumps({"units": "mm", "contours": [
        {"z": float(z), "points": np.asarray(p).tolist()} for z, p in contours]}))
    return path


def _square(x0, y0, s):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]], float)


# ------------------------------------------------------------------ tolerant input
def test_pinched_outline_is_repaired_and_reported(tmp_path):
    # two right triangles of 50 mm^2 whose corners touch at (10, 0), the middle of the outline's first edge
    pinched = np.array([[0, 0], [20, 0], [20, 10], [10, 0], [0, 10]], float)
    path = _write_json(tmp_path / "pinch.json", [(z, pinched) for z in (0.0, 2.0, 4.0, 6.0)])
    result = reconstruct(path, caps="half", reference=False)
    s = result.summary
    assert len(s["contour_repairs"]) == 4 and all(r["parts"] == 2 for r in s["contour_repairs"])
    assert all(r["area_after_mm2"] == pytest.approx(100.0) for r in s["contour_repairs"])
    # two triangles of 50 mm^2 over 4 planes with half caps: 8 mm tall
    assert s["volume_mm3"] == pytest.approx(2 * 50 * 8, rel=0.03)
    assert s["surface_path"] == "implicit"
    assert_valid_solid(result.mesh)


def test_degenerate_contour_is_skipped_with_a_note(tmp_path):
    ring = circle(0, 0, 10)
    items = [(z, ring) for z in (0.0, 2.0, 4.0)] + [(2.0, [[0, 0], [1, 1]]), (4.0, [[0, 0], [1, 1], [2, 2]])]
    stack = io.load(_write_json(tmp_path / "d.json", items))
    assert len(stack.contours) == 3
    note = " ".join(stack.notes)
    assert "skipped 2 contour(s) that enclose nothing" in note and "zero area" in note and "2 distinct" in note


def test_duplicated_contour_and_plane_never_change_the_volume(tmp_path):
    ring = circle(0, 0, 10, 48)
    planes = (0.0, 2.0, 4.0, 6.0)
    clean = reconstruct(_write_json(tmp_path / "a.json", [(z, ring) for z in planes]), reference=False)
    # the plane at 4 mm written twice (once 0.001 mm off), the one at 2 mm holding the contour twice
    dup = [(z, ring) for z in planes] + [(2.0, ring.copy()), (4.001, ring + 1e-6)]
    result = reconstruct(_write_json(tmp_path / "b.json", dup), reference=False)
    notes = " ".join(result.summary["notes"])
    assert "merged 1 plane(s)" in notes and "dropped 2 duplicated contour(s)" in notes
    assert result.summary["n_contours"] == 4
    assert result.summary["volume_mm3"] == pytest.approx(clean.summary["volume_mm3"], rel=1e-9)


def test_single_plane_is_a_slab(tmp_path):
    disc = circle(0, 0, 10, 128)
    path = _write_json(tmp_path / "one.json", [(5.0, disc)])
    with pytest.raises(ValueError, match="slice-thickness"):
        reconstruct(path, reference=False)
    result = reconstruct(path, reference=False, slice_thickness=2.5)
    assert result.summary["volume_mm3"] == pytest.approx(np.pi * 100 * 2.5, rel=1e-3)
    assert any("slab 2.5 mm thick" in n for n in result.summary["notes"])
    # two islands on the one plane: the implicit surface, still a slab of the thickness
    two = _write_json(tmp_path / "two.json", [(5.0, _square(0, 0, 10)), (5.0, _square(20, 0, 10))])
    both = reconstruct(two, reference=False, slice_thickness=2.0)
    assert both.summary["surface_path"] == "implicit"
    # marching cubes chamfers the caps' rims (a pixel across, a level high): 5 % of these 2 mm wafers
    assert both.summary["volume_mm3"] == pytest.approx(2 * 100 * 2.0, rel=0.06)
    assert_valid_solid(both.mesh, components=2)


# ------------------------------------------------------------------ structure sets written here
def _rtstruct(path, rois: list[tuple[int, str, list[tuple[str, np.ndarray]]]]):
    """A minimal RT Structure Set: ``(number, name, [(geometric type, xyz points (n, 3)), ...])`` per ROI."""
    from pydicom.dataset import Dataset, FileMetaDataset
    from pydicom.sequence import Sequence
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.481.3"
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    ds.Modality = "RTSTRUCT"
    ds.SOPClassUID = meta.MediaStorageSOPClassUID
    ds.SOPInstanceUID = meta.MediaStorageSOPInstanceUID
    ds.StructureSetROISequence = Sequence()
    ds.ROIContourSequence = Sequence()
    for number, name, contours in rois:
        roi = Dataset()
        roi.ROINumber, roi.ROIName = number, name
        ds.StructureSetROISequence.append(roi)
        rc = Dataset()
        rc.ReferencedROINumber = number
        rc.ContourSequence = Sequence()
        for kind, xyz in contours:
            c = Dataset()
            c.ContourGeometricType = kind
            c.NumberOfContourPoints = len(xyz)
            c.ContourData = [f"{v:.6f}" for v in np.asarray(xyz, float).ravel()]
            rc.ContourSequence.append(c)
        ds.ROIContourSequence.append(rc)
    ds.save_as(str(path), enforce_file_format=True)
    return path


def _cylinder(z_values, r=10.0, n=48):
    return [("CLOSED_PLANAR", np.column_stack([circle(0, 0, r, n), np.full(n, z)])) for z in z_values]


def test_duplicated_roi_names_and_roi_number(tmp_path):
    path = _rtstruct(tmp_path / "rs.dcm", [(3, "GTV", _cylinder([0.0, 2.0, 4.0])),
                                           (7, "gtv", _cylinder([0.0, 2.0, 4.0, 6.0]))])
    with pytest.raises(ValueError, match=r"2 ROIs are named 'GTV' \(ROI numbers 3, 7\).*--roi-number"):
        io.load(path, "GTV")
    assert len(io.load(path, 7).contours) == 4
    assert len(io.load(path, 3).contours) == 3
    with pytest.raises(ValueError, match="no ROI number 5"):
        io.load(path, 5)


def test_open_planar_and_point_contours_are_named(tmp_path):
    contours = _cylinder([0.0, 2.0, 4.0]) + [("OPEN_PLANAR", np.array([[0, 0, 2.0], [5, 0, 2.0], [5, 5, 2.0]])),
                                              ("POINT", np.array([[1.0, 1.0, 4.0]])),
                                              ("CLOSED_PLANAR", np.array([[0, 0, 6.0], [1, 0, 6.0]]))]
    stack = io.load(_rtstruct(tmp_path / "rs.dcm", [(1, "ring", contours)]), "ring")
    note = " ".join(stack.notes)
    assert "1 OPEN_PLANAR (3 at z=2.00 mm)" in note and "1 POINT (4 at z=4.00 mm)" in note
    assert "CLOSED_PLANAR with 2 point(s)" in note
    assert "gap" not in note
    assert len(stack.contours) == 3


def test_oblique_planes_in_their_frame(tmp_path):
    # a cylinder of radius 10 mm, 8 mm long, whose axis is tilted 30 degrees about x
    tilt = np.radians(30.0)
    rot = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    contours = [("CLOSED_PLANAR", xyz[:, :3] @ rot.T) for _, xyz in _cylinder([0.0, 2.0, 4.0, 6.0, 8.0], n=96)]
    path = _rtstruct(tmp_path / "rs.dcm", [(1, "tilted", contours)])
    result = reconstruct(path, roi="tilted", caps="flat", reference=False)
    assert any("oblique" in n for n in result.summary["notes"])
    assert result.stack.frame is not None and abs(result.stack.frame[2] @ rot[:, 2]) == pytest.approx(1.0)
    assert result.summary["volume_mm3"] == pytest.approx(np.pi * 100 * 8, rel=0.01)
    # the written solid lies where the contours are, in patient coordinates: its axis is the tilted one
    centred = result.mesh.vertices - result.mesh.vertices.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][2]  # the least spread: 8 mm long, 20 mm across
    assert abs(axis @ rot[:, 2]) > 0.999
    pts = np.concatenate([xyz for _, xyz in contours])
    from scipy.spatial import cKDTree

    assert cKDTree(result.mesh.vertices).query(pts)[0].max() < 1.0


def test_plain_roi_repair_option(tmp_path):
    path = _write_json(tmp_path / "c.json", [(z, circle(0, 0, 10)) for z in (0.0, 2.0, 4.0)])
    result = reconstruct(path, repair=True, reference=False)
    assert result.summary["mesh_repair"]["unfilled_holes"] == 0
    assert any(n.startswith("--repair:") for n in result.summary["notes"])


# ------------------------------------------------------------------ the implicit surface
def _fork(n=64):
    """A trunk (r 10) on 4 planes splitting into two touching branches (r 6, centres 6 mm apart) on 4 more."""
    trunk = [Contour(z, circle(0, 0, 10, n)) for z in (0.0, 2.0, 4.0, 6.0)]
    branches = [Contour(z, circle(cx, 0, 6, n)) for z in (8.0, 10.0, 12.0, 14.0) for cx in (-7.0, 7.0)]
    return trunk + branches


def _raster_mc_volume(contours, pixel=0.25):
    """Rasterise (pixel centres inside) + marching cubes: the peer's volume (mm^3), half caps."""
    from skimage.draw import polygon
    from skimage.measure import marching_cubes

    from surfaces.mesh import TriangleMesh

    pts = np.concatenate([c.points for c in contours])
    lo = pts.min(axis=0) - 3
    shape = tuple(int(v) for v in np.ceil((pts.max(axis=0) + 3 - lo) / pixel)[::-1] + 1)
    planes = np.unique([c.z for c in contours])
    masks = np.zeros((len(planes), *shape), bool)
    for c in contours:
        rr, cc = polygon((c.points[:, 1] - lo[1]) / pixel, (c.points[:, 0] - lo[0]) / pixel, shape)
        img = np.zeros(shape, bool)
        img[rr, cc] = True
        masks[np.searchsorted(planes, c.z)] ^= img
    d = float(np.diff(planes).min())
    v, f, _, _ = marching_cubes(np.pad(masks.astype(np.float32), 1), 0.5, spacing=(d, pixel, pixel))
    return abs(TriangleMesh(v, f).signed_volume())


def test_branching_with_touching_bodies_is_one_valid_solid():
    contours = _fork()
    rec = reconstruct_contours(contours, caps="half")
    assert rec.surface_path == "implicit" and rec.bodies == []
    checks = assert_valid_solid(rec.mesh, components=1)
    assert checks["volume"] == pytest.approx(rec.volume_mm3, rel=1e-9)
    # 4 cc: the branching's blend and marching cubes' chamfered rims (the peer's too) differ by ~1 %
    assert rec.volume_mm3 == pytest.approx(_raster_mc_volume(contours), rel=0.02)
    by_caps = rec.volume_by_caps()
    assert by_caps["half"] == pytest.approx(rec.volume_mm3)
    assert by_caps["flat"] < by_caps["half"]


def test_holes_make_cavities_only_where_contours_have_them():
    outer = [Contour(z, circle(0, 0, 12, 64)) for z in np.arange(0.0, 20.0, 2.0)]
    inner = [Contour(z, circle(0, 0, 5, 48)) for z in np.arange(6.0, 14.0, 2.0)]
    rec = reconstruct_contours(outer + inner, caps="half")
    assert rec.surface_path == "implicit"
    assert_valid_solid(rec.mesh, components=2)  # the outer shell and the cavity
    from slices.summary import implicit_table

    rows = implicit_table(rec)
    assert [r["kind"] for r in rows] == ["outer", "hole"]
    assert rec.volume_mm3 == pytest.approx(_raster_mc_volume(outer + inner), rel=0.01)


def test_single_chain_keeps_the_seed_patches():
    contours = [Contour(z, circle(0, 0, 10 + z / 4, 48)) for z in np.arange(0.0, 12.0, 2.0)]
    rec = reconstruct_contours(contours, caps="half")
    assert rec.surface_path == "coons" and len(rec.bodies) == 1
    forced = reconstruct_contours(contours, caps="half", surface_path="implicit")
    assert forced.volume_mm3 == pytest.approx(rec.volume_mm3, rel=0.01)
    assert_valid_solid(forced.mesh, components=1)


# ------------------------------------------------------------------ real structure sets
BREAST_ROIS = ["Borders", "Breast", "Heart", "Nodes", "Scar", "Tumor Bed", "Tumor Bed Block"]


@pytest.mark.parametrize("roi", BREAST_ROIS)
def test_breast_rois_are_valid_solids(shared_data, roi):
    result = reconstruct(shared_data / "rtstruct_breast" / "rtss.dcm", roi=roi, caps="half", reference=False)
    assert_valid_solid(result.mesh)


@pytest.mark.slow
@pytest.mark.parametrize("roi", ["BODY", "Lt Lung"])
def test_breast_large_rois_are_valid_solids(shared_data, roi):
    result = reconstruct(shared_data / "rtstruct_breast" / "rtss.dcm", roi=roi, caps="half", reference=False)
    assert result.summary["surface_path"] == "implicit"
    checks = assert_valid_solid(result.mesh)
    outer = sum(r["kind"] == "outer" for r in result.summary["bodies"])
    assert checks["components"] == len(result.summary["bodies"]) and outer >= 1


def test_ibsi_gtv_is_accepted_and_valid(shared_data):
    result = reconstruct(shared_data / "ibsi_ct_phantom" / "RS.dcm", roi="GTV-1", caps="half", reference=False)
    s = result.summary
    assert len(s["contour_repairs"]) >= 5
    assert max(abs(r["area_change_pct"]) for r in s["contour_repairs"]) < 0.05  # shapely: under 0.05 %
    assert_valid_solid(result.mesh)
    # the peers (shared data README): plastimatch 358.7 cc, rasterise + marching cubes 358.4 cc
    assert s["volume_ml"] == pytest.approx(358.5, rel=0.01)


def test_rtutils_mim_sample_rois_are_valid_solids():
    """rt-utils' early sample data (a MIM export, 4 ROIs on 3 planes; ``sample/rt.dcm`` of
    github.com/qurit/rt-utils before commit 63c77e4): set ``RTUTILS_SAMPLE`` to that file."""
    import os
    from pathlib import Path

    sample = os.environ.get("RTUTILS_SAMPLE")
    if not sample or not Path(sample).is_file():
        pytest.skip("rt-utils' MIM sample is not here (set RTUTILS_SAMPLE to its sample/rt.dcm, fetched from "
                    "github.com/qurit/rt-utils before commit 63c77e4)")
    for roi in io.list_rois(sample):
        if roi["n_contours"]:
            result = reconstruct(sample, roi=roi["number"], caps="half", reference=False)
            assert_valid_solid(result.mesh, components=1)


def test_bodies_across_missing_planes_close_half_way():
    # two discs of radius 10 mm 6 mm apart along z (planes 6 and 8 missing) and a disc of radius 4 mm beside the
    # lower one: three parts, each a slab of its planes with half caps, no island in the empty planes
    contours = ([Contour(z, circle(0, 0, 10, 96)) for z in (0.0, 2.0, 4.0, 10.0, 12.0, 14.0)]
                + [Contour(z, circle(40, 0, 4, 64)) for z in (0.0, 2.0, 4.0)])
    rec = reconstruct_contours(contours, caps="half")
    assert rec.surface_path == "implicit"
    assert_valid_solid(rec.mesh, components=3)
    from slices.summary import implicit_table

    rows = sorted(implicit_table(rec), key=lambda r: -r["volume_mm3"])
    from slices.polygons import signed_area

    area = [signed_area(circle(0, 0, 10, 96)), signed_area(circle(0, 0, 4, 64))]
    assert [r["volume_mm3"] for r in rows] == pytest.approx([6 * area[0], 6 * area[0], 6 * area[1]], rel=0.01)
    assert [(r["z_min_mm"], r["z_max_mm"]) for r in rows[2:]] == [pytest.approx((-1.0, 5.0), abs=0.05)]
