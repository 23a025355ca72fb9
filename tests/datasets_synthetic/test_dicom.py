"""DICOM CT series and RT Structure Set: read back with pydicom, geometry round-trips to 1e-6 mm."""

from __future__ import annotations

import json

import numpy as np
import pydicom
import pytest

from datasets_synthetic.dicom import CT_IMAGE_STORAGE, RT_STRUCTURE_SET_STORAGE, write_ct_series, write_rtstruct
from datasets_synthetic.phantoms import make_phantom, write_phantom


@pytest.fixture(scope="module")
def kidney_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("kidney")
    ph = make_phantom("kidney")
    truth = write_phantom(out, ph, spacing=5.0, pixel=1.5, fmt="rtstruct", n_points=40, seed=7,
                          n_surface=1000)
    return out, ph, truth


def _series(folder):
    files = sorted(folder.glob("*.dcm"))
    return [pydicom.dcmread(f) for f in files]


def test_ct_series_reads_back_with_consistent_geometry(kidney_dir):
    out, ph, truth = kidney_dir
    slices = _series(out / "ct")
    assert len(slices) == truth["ct"]["n_slices"] == truth["n_planes"] + 4
    z = np.array([float(s.ImagePositionPatient[2]) for s in slices])
    np.testing.assert_allclose(np.diff(z), 5.0, atol=1e-9)
    np.testing.assert_allclose(z[2:-2], truth["planes_mm"], atol=1e-6)
    for key in ("StudyInstanceUID", "SeriesInstanceUID", "FrameOfReferenceUID"):
        assert len({getattr(s, key) for s in slices}) == 1
    assert len({s.SOPInstanceUID for s in slices}) == len(slices)
    for s in slices:
        assert s.SOPClassUID == CT_IMAGE_STORAGE == s.file_meta.MediaStorageSOPClassUID
        assert s.file_meta.MediaStorageSOPInstanceUID == s.SOPInstanceUID
        assert [float(v) for v in s.PixelSpacing] == [1.5, 1.5]
        assert float(s.SliceThickness) == 5.0
        assert [float(v) for v in s.ImageOrientationPatient] == [1, 0, 0, 0, 1, 0]
        assert float(s.SliceLocation) == pytest.approx(float(s.ImagePositionPatient[2]), abs=1e-9)


def test_ct_pixels_are_hounsfield_units_of_the_phantom(kidney_dir):
    out, ph, truth = kidney_dir
    slices = _series(out / "ct")
    for s in (slices[0], slices[len(slices) // 2]):
        hu = s.pixel_array * float(s.RescaleSlope) + float(s.RescaleIntercept)
        rows, cols = np.mgrid[0:s.Rows, 0:s.Columns]
        x0, y0, z = (float(v) for v in s.ImagePositionPatient)
        ps_row, ps_col = (float(v) for v in s.PixelSpacing)
        # orientation 1\0\0\0\1\0: columns along +x, rows along +y
        centres = np.column_stack([x0 + cols.ravel() * ps_col, y0 + rows.ravel() * ps_row,
                                   np.full(rows.size, z)])
        half = 0.5 * ps_col
        corners = [ph.inside(centres + [dx, dy, 0]) for dx in (-half, half) for dy in (-half, half)]
        full = np.all(corners, axis=0).reshape(hu.shape)
        empty = ~np.any(corners, axis=0).reshape(hu.shape)
        np.testing.assert_allclose(hu[empty], -1000.0)
        if full.any():
            np.testing.assert_allclose(hu[full], 40.0)
        else:
            assert np.all(hu == -1000.0)  # the extra end slices are empty
        # partial-volume pixels lie in between and approximate the section area
        frac = (hu + 1000.0) / 1040.0
        area = frac.sum() * ps_row * ps_col
        assert area == pytest.approx(float(ph.section_area_mm2(np.array([z]))[0]), rel=0.03, abs=1.0)


def test_rtstruct_references_the_series_and_round_trips_contours(kidney_dir):
    out, ph, truth = kidney_dir
    rt = pydicom.dcmread(out / "rtstruct.dcm")
    slices = {s.SOPInstanceUID: s for s in _series(out / "ct")}
    assert rt.SOPClassUID == RT_STRUCTURE_SET_STORAGE == rt.file_meta.MediaStorageSOPClassUID
    assert rt.Modality == "RTSTRUCT"
    series_uid = next(iter(slices.values())).SeriesInstanceUID
    frame = rt.ReferencedFrameOfReferenceSequence[0]
    assert frame.FrameOfReferenceUID == next(iter(slices.values())).FrameOfReferenceUID
    ref_series = frame.RTReferencedStudySequence[0].RTReferencedSeriesSequence[0]
    assert ref_series.SeriesInstanceUID == series_uid
    assert {i.ReferencedSOPInstanceUID for i in ref_series.ContourImageSequence} == set(slices)
    roi = rt.StructureSetROISequence[0]
    assert roi.ROIName == "kidney" and roi.ReferencedFrameOfReferenceUID == frame.FrameOfReferenceUID
    assert rt.RTROIObservationsSequence[0].ReferencedROINumber == roi.ROINumber
    written = json.loads((out / "contours.json").read_text())["contours"]
    items = rt.ROIContourSequence[0].ContourSequence
    assert rt.ROIContourSequence[0].ReferencedROINumber == roi.ROINumber
    assert len(items) == len(written) == truth["n_contours"]
    for item, c in zip(items, written):
        assert item.ContourGeometricType == "CLOSED_PLANAR"
        xyz = np.array([float(v) for v in item.ContourData]).reshape(-1, 3)
        assert int(item.NumberOfContourPoints) == len(xyz) == len(c["points"])
        np.testing.assert_allclose(xyz[:, :2], c["points"], atol=1e-6, rtol=0)
        np.testing.assert_allclose(xyz[:, 2], c["z"], atol=1e-6, rtol=0)
        ref = slices[item.ContourImageSequence[0].ReferencedSOPInstanceUID]
        assert float(ref.ImagePositionPatient[2]) == pytest.approx(c["z"], abs=1e-6)
    # the contours' areas integrate to the exact volume between the end planes (kidney: no holes)
    z = np.array([c["z"] for c in written])
    area = np.array([abs(0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
                     for p in (np.asarray(c["points"]) for c in written)])
    assert np.trapezoid(area, z) == pytest.approx(truth["volume_between_end_planes_mm3"], rel=0.03)


def test_rtstruct_mirrors_a_real_structure_set(kidney_dir, shared_data):
    out, _, _ = kidney_dir
    real = pydicom.dcmread(shared_data / "rtstruct_breast" / "rtss.dcm")
    ours = pydicom.dcmread(out / "rtstruct.dcm")
    for key in ("SOPClassUID", "Modality"):
        assert getattr(ours, key) == getattr(real, key)
    for seq in ("ReferencedFrameOfReferenceSequence", "StructureSetROISequence",
                "ROIContourSequence", "RTROIObservationsSequence"):
        assert seq in ours
        assert {e.keyword for e in real[seq].value[0]} - {"RTROIIdentificationCodeSequence"} <= {
            e.keyword for e in ours[seq].value[0]}
    real_item = real.ROIContourSequence[0].ContourSequence[0]
    our_item = ours.ROIContourSequence[0].ContourSequence[0]
    assert {e.keyword for e in real_item} <= {e.keyword for e in our_item}


def test_same_seed_gives_the_same_uids(tmp_path):
    ph = make_phantom("ring", major_mm=10.0, minor_mm=4.0)
    a = write_ct_series(tmp_path / "a", ph, 4.0, 2.0, seed=3)
    b = write_ct_series(tmp_path / "b", ph, 4.0, 2.0, seed=3)
    c = write_ct_series(tmp_path / "c", ph, 4.0, 2.0, seed=4)
    assert a["series_uid"] == b["series_uid"] != c["series_uid"]
    assert [s["sop_instance_uid"] for s in a["slices"]] == [s["sop_instance_uid"] for s in b["slices"]]


def test_rtstruct_rejects_contours_off_the_slices(tmp_path):
    ph = make_phantom("ring", major_mm=10.0, minor_mm=4.0)
    series = write_ct_series(tmp_path / "ct", ph, 4.0, 2.0)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    with pytest.raises(ValueError, match="matches no CT slice"):
        write_rtstruct(tmp_path / "rt.dcm", [{"z": 1.234, "points": square}], series)
    with pytest.raises(ValueError, match="at least 3 points"):
        write_rtstruct(tmp_path / "rt.dcm", [{"z": 0.0, "points": square[:2]}], series)
    with pytest.raises(ValueError, match="empty"):
        write_rtstruct(tmp_path / "rt.dcm", [], series)
    assert not (tmp_path / "rt.dcm").exists()
