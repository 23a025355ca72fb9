"""``workbench.runs.slices.reconstruct_to_folder`` on NIfTI label and mask volumes and on small structures.

Moved from tests/slices/test_nifti.py and test_small_structures.py: the library's tests do not run
the workbench.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from slices.io import read_nifti
from tests.slices.test_nifti import _save, _two_boxes
from tests.slices.test_small_structures import _stack
from workbench.runs.slices import reconstruct_to_folder

nibabel = pytest.importorskip("nibabel")


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


def test_summary_reports_the_planning_volume_beside_ours(tmp_path):
    ph, conts = _stack("lens", 2.0, n_points=64)
    path = tmp_path / "lens.json"
    path.write_text(json.dumps({"contours": [{"z": c.z, "points": c.points.tolist()} for c in conts]}))
    summary = reconstruct_to_folder(path, tmp_path / "out", caps="half", render=False, reference=False)
    plan = summary["planning_volume_mm3"]
    assert plan["small_structure"] and plan["ours_mm3"] == summary["volume_mm3"]
    assert plan["slab_half_ends"] == pytest.approx(summary["slab_volume_mm3"], rel=1e-12)
    assert plan["ours_over_full_ends"] == pytest.approx(summary["volume_mm3"] / plan["slab_full_ends"])
    assert any(n.startswith("small structure (3 plane(s))") for n in summary["notes"])
    written = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert written["planning_volume_mm3"]["slab_full_ends"] == pytest.approx(plan["slab_full_ends"])


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
