"""NIfTI label and mask volumes as input (issue 19): contours per axial slice in mm through the affine."""

from __future__ import annotations

import numpy as np
import pytest

from slices.io import is_nifti, load, nifti_labels, read_nifti

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
