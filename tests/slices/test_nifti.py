"""NIfTI label and mask volumes as input (issue 19): contours per axial slice in mm through the affine."""

from __future__ import annotations

import numpy as np
import pytest

from slices.io import is_nifti, load, nifti_labels, read_nifti
from workbench.runs.slices import reconstruct_to_folder

nibabel = pytest.importorskip("nibabel")


def _save(path, data, affine):
    nibabel.save(nibabel.Nifti1Image(np.asarray(data), np.asarray(affine, float)), str(path))
    return path


def _two_boxes() -> np.ndarray:
    data = np.zeros((30, 24, 10), np.int16)
    data[2:12, 3:9, 2:8] = 1  # 10 x 6 voxels on 6 slices (x, y, z)
    data[16:28, 10:20, 1:9] = 2  # 12 x 10 voxels on 8 slices
    return data


def test_is_nifti():
    assert is_nifti("a/m.nii") and is_nifti("M.NII.GZ") and not is_nifti("m.npy") and not is_nifti("nii.json")


def test_contours_lie_in_mm_through_the_affine(tmp_path):
    affine = np.diag([0.5, 0.8, 2.5, 1.0])
    affine[:3, 3] = (-10.0, 4.0, 30.0)
    path = _save(tmp_path / "boxes.nii.gz", _two_boxes(), affine)
    stack = read_nifti(path, 2)
    assert stack.source == "nifti" and "label 2" in stack.name
    z = stack.planes
    np.testing.assert_allclose(z, 30.0 + 2.5 * np.arange(1, 9))
    pts = np.concatenate([c.points for c in stack.contours])
    # the boundary runs half-way between voxel centres: columns 16-27 (x), rows 10-19 (y), in RAS;
    # the contours are in DICOM patient coordinates (LPS: x and y negated)
    np.testing.assert_allclose(pts.max(axis=0), [-(-10 + 0.5 * 15.5), -(4 + 0.8 * 9.5)])
    np.testing.assert_allclose(pts.min(axis=0), [-(-10 + 0.5 * 27.5), -(4 + 0.8 * 19.5)])
    assert len(read_nifti(path).contours) == 6 * 2 + 2  # every non-zero voxel: both boxes
    assert [r["label"] for r in nifti_labels(path)] == [1, 2]
    assert nifti_labels(path)[0] == {"label": 1, "n_voxels": 360, "n_planes": 6}


def test_a_label_volume_reconstructs_each_label(tmp_path):
    path = _save(tmp_path / "boxes.nii", _two_boxes(), np.diag([1.0, 1.0, 2.0, 1.0]))
    for label, (nx, ny, nz) in ((1, (10, 6, 6)), (2, (12, 10, 8))):
        s = reconstruct_to_folder(path, tmp_path / f"o{label}", roi=label, caps="half", render=False,
                                  reference=False, samples=2)
        # each section: the voxels' rectangle less four corner triangles of 1/8 voxel (the 0.5 level
        # cuts the corners), end planes half in the slab count
        section = nx * ny - 0.5
        assert s["slab_volume_mm3"] == pytest.approx(section * 2.0 * (nz - 1), rel=1e-9)
        assert s["volume_mm3"] == pytest.approx(section * 2.0 * nz, rel=0.03)
        assert s["source"] == "nifti"


def test_bad_nifti_input(tmp_path):
    path = _save(tmp_path / "boxes.nii.gz", _two_boxes(), np.eye(4))
    with pytest.raises(ValueError, match="no voxel .* value 3"):
        read_nifti(path, 3)
    with pytest.raises(ValueError, match="--label: must be a number"):
        load(path, "Lens")
    oblique = np.eye(4)
    oblique[:3, :3] = [[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]]
    with pytest.raises(ValueError, match="not axial"):
        read_nifti(_save(tmp_path / "oblique.nii", _two_boxes(), oblique))
    with pytest.raises(ValueError, match="empty"):
        read_nifti(_save(tmp_path / "empty.nii", np.zeros((4, 4, 4), np.uint8), np.eye(4)))
    with pytest.raises(ValueError, match="3-D"):
        read_nifti(_save(tmp_path / "flat.nii", np.ones((4, 4, 4, 2), np.uint8), np.eye(4)))
    (tmp_path / "junk.nii.gz").write_bytes(b"not a nifti file")
    with pytest.raises(ValueError, match="not a readable NIfTI"):
        read_nifti(tmp_path / "junk.nii.gz")
    with pytest.raises(FileNotFoundError):
        read_nifti(tmp_path / "missing.nii")


def test_an_exported_phantom_mask_reads_back_at_the_phantom_volume(tmp_path):
    from datasets_synthetic.phantoms import make_phantom

    ph = make_phantom("ellipsoid", a=12.0, b=9.0, c=10.0)
    contours = tmp_path / "contours.json"
    contours.write_text(__import__("json").dumps({"contours": [
        {"z": c["z"], "points": c["points"].tolist()} for c in ph.contours(2.0, n_points=64)]}))
    mask = tmp_path / "mask.nii.gz"
    reconstruct_to_folder(contours, tmp_path / "a", caps="half", render=False, reference=False, samples=3,
                          export_mask=str(mask), mask_spacing="0.5,0.5,1")
    back = reconstruct_to_folder(mask, tmp_path / "b", caps="half", render=False, reference=False, samples=2)
    assert back["source"] == "nifti" and back["mesh_watertight"]
    # the mask holds the contours' slabs: planes at 1 mm from -8 to 8 mm (contours at -8 ... 8 mm, 2 mm apart,
    # each standing for +-1 mm; the planes at +-9 mm lie exactly half a spacing out and are left empty), read
    # back with half caps: the ellipsoid between -8.5 and 8.5 mm; the planes between contours are blended
    # linearly in distance, a little inside the convex outline (about 2 %)
    h = 8.5
    clipped = np.pi * 12.0 * 9.0 * (2 * h - 2 * h**3 / (3 * 10.0**2))
    assert back["volume_mm3"] == pytest.approx(clipped, rel=0.025)
    # the mask comes back where the contours were (RAS in the file, LPS in the contours)
    first = read_nifti(mask).contours
    assert np.mean([c.points.mean(axis=0) for c in first], axis=0) == pytest.approx(
        np.mean([c["points"].mean(axis=0) for c in ph.contours(2.0, n_points=64)], axis=0), abs=0.3)


def test_a_label_volume_comes_back_voxel_for_voxel_on_its_own_grid(tmp_path):
    affine = np.diag([-0.7, -0.9, 2.0, 1.0])  # a RAS affine as a DICOM converter writes it (LPS axes)
    affine[:3, 3] = (40.0, 60.0, -10.0)
    path = _save(tmp_path / "boxes.nii.gz", _two_boxes(), affine)
    s = reconstruct_to_folder(path, tmp_path / "o", roi=2, render=False, reference=False, samples=2,
                              export_mask=str(tmp_path / "back.nii.gz"))
    assert s["export_mask"]["grid_source"] == "input_image"
    back = nibabel.load(str(tmp_path / "back.nii.gz"))
    np.testing.assert_allclose(back.affine, affine)
    # the contours (find_contours at 0.5) filled at the voxel centres: the label's voxels exactly
    np.testing.assert_array_equal(np.asarray(back.dataobj) > 0, _two_boxes() == 2)
