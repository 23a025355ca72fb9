"""``workbench.runs.slices.reconstruct_to_folder`` on NIfTI label and mask volumes and on small structures.

Moved from tests/slices/test_nifti.py and test_small_structures.py: the library's tests do not run
the workbench.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.slices.test_nifti import _save, _two_boxes
from tests.slices.test_small_structures import _stack
from workbench.runs.slices import reconstruct_to_folder

pytest.importorskip("nibabel")


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
    assert back["volume_mm3"] == pytest.approx(ph.volume_mm3, rel=0.01)


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
