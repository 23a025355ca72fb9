"""Readers: contour JSON, mask stacks, CT series (sorted by position), RT structure sets."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom, write_phantom
from slices import io
from slices.polygons import signed_area


def _write_json(path, contours):
    path.write_text(json.dumps({"units": "mm", "contours": [
        {"z": z, "points": np.asarray(p).tolist()} for z, p in contours]}))
    return path


def _square(s=10.0):
    return [[0, 0], [s, 0], [s, s], [0, s]]


def test_json_reader_orients_and_sorts(tmp_path):
    cw = _square()[::-1]
    path = _write_json(tmp_path / "c.json", [(3.0, cw), (0.0, _square())])
    stack = io.load(path)
    assert [c.z for c in stack.contours] == [0.0, 3.0]
    assert all(signed_area(c.points) > 0 for c in stack.contours)


def test_json_without_any_closed_contour(tmp_path):
    with pytest.raises(ValueError, match="no contour encloses an area.*2 distinct point"):
        io.load(_write_json(tmp_path / "bad.json", [(0.0, [[0, 0], [1, 0]])]))


def test_json_crossing_contour_is_repaired(tmp_path):
    # a bow tie: shapely's make_valid gives its two triangles (the shoelace area was 0)
    stack = io.load(_write_json(tmp_path / "bow.json", [(0.0, [[0, 0], [10, 10], [10, 0], [0, 10]])]))
    assert len(stack.contours) == 2
    assert sum(signed_area(c.points) for c in stack.contours) == pytest.approx(50.0)
    assert stack.repairs[0]["parts"] == 2 and stack.repairs[0]["area_after_mm2"] == pytest.approx(50.0)


def test_json_not_axial_and_missing(tmp_path):
    path = tmp_path / "tilt.json"
    path.write_text(json.dumps({"contours": [{"z": 0, "points": [[0, 0, 0], [1, 0, 1], [0, 1, 0]]}]}))
    with pytest.raises(ValueError, match="axial"):
        io.load(path)
    with pytest.raises(FileNotFoundError):
        io.load(tmp_path / "nothing.json")


def _ball_mask(shape=(12, 40, 40), r=8.0, spacing=(2.0, 0.5, 0.5)):
    z, y, x = np.indices(shape).astype(float)
    zc, yc, xc = (np.array(shape) - 1) / 2
    d = ((z - zc) * spacing[0]) ** 2 + ((y - yc) * spacing[1]) ** 2 + ((x - xc) * spacing[2]) ** 2
    return d <= r**2


@pytest.mark.parametrize("fmt", ["npy", "tif", "png"])
def test_mask_stacks(tmp_path, fmt):
    import cv2

    mask = _ball_mask()
    if fmt == "npy":
        path = tmp_path / "m.npy"
        np.save(path, mask)
    elif fmt == "tif":
        path = tmp_path / "m.tif"
        assert cv2.imwritemulti(str(path), [m.astype(np.uint8) * 255 for m in mask])
    else:
        path = tmp_path / "pngs"
        path.mkdir()
        for k, m in enumerate(mask):
            cv2.imwrite(str(path / f"s{k:03d}.png"), m.astype(np.uint8) * 255)
    stack = io.load(path, spacing="2,0.5,0.5")
    zs = sorted({c.z for c in stack.contours})
    assert np.allclose(np.diff(zs), 2.0)
    # the middle contour is a circle of the ball's radius (within half a pixel)
    mid = max(stack.contours, key=lambda c: np.ptp(c.points[:, 0]))
    r = np.linalg.norm(mid.points - mid.points.mean(0), axis=1)
    assert abs(r.mean() - 8.0) < 0.5
    with pytest.raises(ValueError, match="spacing"):
        io.load(path)


def test_grey_stack_needs_window(tmp_path):
    vol = np.random.default_rng(0).integers(0, 1000, (4, 10, 10))
    np.save(tmp_path / "g.npy", vol)
    with pytest.raises(ValueError, match="--hu-min"):
        io.load(tmp_path / "g.npy", spacing="1,1,1")


@pytest.fixture(scope="module")
def phantom_dicom(tmp_path_factory):
    out = tmp_path_factory.mktemp("ph")
    ph = make_phantom("ellipsoid", a=12.0, b=9.0, c=10.0)
    truth = write_phantom(out, ph, 2.0, 0.5, fmt="rtstruct", n_points=48, n_surface=500)
    return out, truth


def test_ct_series_sorted_by_position(phantom_dicom, tmp_path):
    src, truth = phantom_dicom
    ct = tmp_path / "ct"
    files = sorted((src / "ct").iterdir())
    ct.mkdir()
    # file names in reverse order of position: the reader must sort by IPP, not by name
    for k, f in enumerate(files):
        shutil.copy(f, ct / f"img{len(files) - k:03d}.dcm")
    stack = io.load(ct, hu_min=-500, hu_max=500)
    zs = np.unique([c.z for c in stack.contours])
    assert np.allclose(np.diff(zs), 2.0)
    assert np.allclose(zs, truth["planes_mm"], atol=1e-6)


def test_ct_series_unequal_spacing(phantom_dicom, tmp_path):
    import pydicom

    src, _ = phantom_dicom
    ct = tmp_path / "ct"
    ct.mkdir()
    files = sorted((src / "ct").iterdir())
    for k, f in enumerate(files):
        ds = pydicom.dcmread(f)
        if k == len(files) // 2:
            continue  # drop one slice from the middle
        ds.save_as(ct / f.name)
    with pytest.raises(ValueError, match="unequal slice spacing"):
        io.load(ct, hu_min=-500, hu_max=500)
    stack = io.load(ct, hu_min=-500, hu_max=500, resample=True)
    assert any("resampled" in n for n in stack.notes)


def test_rtstruct_written_by_phantom(phantom_dicom):
    src, truth = phantom_dicom
    rois = io.list_rois(src / "rtstruct.dcm")
    assert len(rois) >= 1
    stack = io.load(src / "rtstruct.dcm", roi=rois[0]["name"])
    assert len(stack.contours) == truth["n_planes"]


def test_rtstruct_breast(shared_data):
    path = shared_data / "rtstruct_breast" / "rtss.dcm"
    rois = {r["name"]: r for r in io.list_rois(path)}
    assert rois["Heart"]["n_contours"] == 33 and rois["BODY"]["max_points"] == 794
    heart = io.load(path, roi="heart")
    assert len(heart.contours) == 33
    assert io.load(path, roi="5").name == "Heart"
    with pytest.raises(ValueError, match="existing ROIs are .*Heart"):
        io.load(path, roi="Hart")
    with pytest.raises(ValueError, match="choose an ROI"):
        io.load(path)


@pytest.mark.parametrize("size", [30_000, 500_000, 1_500_000])
def test_truncated_rtstruct_is_a_clear_error(shared_data, tmp_path, size):
    data = (shared_data / "rtstruct_breast" / "rtss.dcm").read_bytes()
    cut = tmp_path / "rtss.dcm"
    cut.write_bytes(data[:size])
    for read in (io.list_rois, lambda p: io.load(p, roi="BODY")):
        with pytest.raises(ValueError, match="truncated or incomplete"):
            read(cut)


def test_structure_set_readers_check_their_file(phantom_dicom, tmp_path):
    src, _ = phantom_dicom
    ct_slice = next((src / "ct").iterdir())
    for reader in (io.list_rois, lambda p: io.read_rtstruct(p, "ellipsoid")):
        with pytest.raises(FileNotFoundError, match="no such RT structure set file"):
            reader(tmp_path / "none.dcm")
        with pytest.raises(ValueError, match="not an RT Structure Set"):
            reader(ct_slice)
    (tmp_path / "junk.dcm").write_bytes(b"not dicom")
    with pytest.raises(ValueError, match="not a readable DICOM file"):
        io.list_rois(tmp_path / "junk.dcm")
    with pytest.raises(ValueError, match="must be an RT Structure Set"):
        io.load(ct_slice)


def test_segmentation_note_names_the_window(phantom_dicom):
    src, _ = phantom_dicom
    stack = io.load(src / "ct", hu_min=-500, hu_max=500)
    assert "segmented by window [-500, 500], largest connected component" in stack.notes
    with pytest.raises(ValueError, match="above --hu-max"):
        io.load(src / "ct", hu_min=10, hu_max=0)


def test_every_reader_names_a_missing_input(tmp_path):
    """One path check: each reader says what it expected at the path."""
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(NotADirectoryError, match="file.txt: not a folder of DICOM files"):
        io.read_ct_series(tmp_path / "file.txt")
    with pytest.raises(FileNotFoundError, match="none.npy: no such mask stack"):
        io.read_mask_stack(tmp_path / "none.npy", "1,1,1")
    with pytest.raises(FileNotFoundError, match="none.json: no such contour file"):
        io.read_contour_json(tmp_path / "none.json")
    with pytest.raises(FileNotFoundError, match="none: no such file or folder"):
        io.load(tmp_path / "none")
    with pytest.raises(FileNotFoundError, match="no such contour file"):
        io.read_contour_json(tmp_path)


def test_keyholes_to_two_holes_open_into_three_loops():
    """Two cuts from the outer loop, each to its own hole: every cut vertex comes twice, and the
    loops come out whatever the order in which the repeated pairs are cut (largest first)."""
    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    outer = np.stack([30 * np.cos(t), 30 * np.sin(t)], axis=1)
    h = np.linspace(0, 2 * np.pi, 16, endpoint=False)

    def hole(cx):
        return np.stack([cx + 5 * np.cos(h), 5 * np.sin(-h)], axis=1)

    right, left = hole(12.0), hole(-12.0)
    # in from (30, 0) to the right hole and back, round to (-30, 0), in to the left hole and back
    contour = np.concatenate([outer[:1], right[:1], right[1:], right[:1], outer[:1], outer[1:25], left[8:9],
                              left[9:], left[:9], left[8:9], outer[24:]])
    loops = io.open_keyholes(contour)
    areas = [io.signed_area(loop) for loop in loops]
    assert len(loops) == 3
    assert abs(abs(areas[0]) - io.signed_area(outer)) < 1e-9 * io.signed_area(outer)
    assert np.allclose(sorted(abs(x) for x in areas[1:]), [io.signed_area(hole(0.0)[::-1])] * 2)


def test_one_roi_is_read_without_parsing_the_others(shared_data, monkeypatch):
    """Reading one ROI parses that ROI's points only (the others' are left to pydicom)."""
    path = shared_data / "rtstruct_breast" / "rtss.dcm"
    parsed = []
    real = io._contour_array
    monkeypatch.setattr(io, "_contour_array", lambda item: parsed.append(1) or real(item))
    stack = io.load(path, roi="Scar")
    assert len(parsed) == len(stack.contours) < 441
