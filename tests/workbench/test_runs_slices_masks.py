"""Masks through ``workbench.runs.slices`` and the CLI.

Moved from tests/slices/test_masks.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from slices.mask import MASK_VOXEL_LIMIT, check_size
from surfaces.validate import InputError
from surfaces.voxelize import VoxelGrid, lps_to_ras
from tests.slices.test_masks import _dice, _raw_contours, _reference_fill, nibabel


def test_the_mask_size_is_refused_before_any_work(tmp_path):
    from workbench.runs.slices import reconstruct_to_folder

    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    disc = np.stack([10 * np.cos(t), 10 * np.sin(t)], 1)
    path = tmp_path / "cyl.json"
    path.write_text(json.dumps({"contours": [{"z": z, "points": disc.tolist()} for z in (0.0, 2.0, 4.0)]}))
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"--export-mask: a mask of .* voxels \(.* TiB as uint8\).* over the limit"):
        reconstruct_to_folder(path, tmp_path / "out", export_mask=str(tmp_path / "m.nii.gz"),
                              mask_spacing="0.001,0.001,0.001", render=False)
    assert time.perf_counter() - t0 < 5.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cyl.json"]  # nothing written, no folder
    with pytest.raises(InputError, match="only with --export-mask"):
        reconstruct_to_folder(path, tmp_path / "out", mask_spacing="1,1,1", render=False)
    assert check_size(VoxelGrid(np.eye(4), (2, 3, 4)))["n_voxels"] == 24
    with pytest.raises(InputError, match="over the limit"):
        check_size(VoxelGrid(np.eye(4), (MASK_VOXEL_LIMIT, 2, 1)))


def test_export_mask_end_to_end_on_the_breast_heart(shared_data, tmp_path):
    from workbench.runs.slices import reconstruct_to_folder

    rs = shared_data / "rtstruct_breast" / "rtss.dcm"
    s = reconstruct_to_folder(rs, tmp_path / "out", roi="Heart", render=False, reference=False, samples=2,
                              export_mask=str(tmp_path / "heart.nii.gz"))
    m = s["export_mask"]
    assert m["grid_source"] == "ct_series" and m["orientation"] == "LPS"
    img = nibabel.load(str(tmp_path / "heart.nii.gz"))
    assert nibabel.aff2axcodes(img.affine) == ("L", "P", "S")
    ct = __import__("pydicom").dcmread(str(shared_data / "rtstruct_breast" / "ct.0.dcm"))
    # voxel (0, 0) of every plane is the CT's first pixel, in RAS
    np.testing.assert_allclose(img.affine[:2, 3], -np.asarray(ct.ImagePositionPatient[:2], float), atol=1e-4)
    ref = _reference_fill(_raw_contours(rs, "Heart"), VoxelGrid(lps_to_ras(img.affine), img.shape))
    assert _dice(np.asarray(img.dataobj), ref) >= 0.99
    # whole end slabs: dicompyler-core's 432.84 cc counts them half
    assert m["voxel_volume_mm3"] / 1000 == pytest.approx(439.70, rel=0.01)


def test_the_command_refuses_a_huge_mask_at_once(tmp_path, capsys):
    from workbench.cli import main

    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    disc = np.stack([10 * np.cos(t), 10 * np.sin(t)], 1)
    path = tmp_path / "cyl.json"
    path.write_text(json.dumps({"contours": [{"z": z, "points": disc.tolist()} for z in (0.0, 2.0, 4.0)]}))
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(["slices", "reconstruct", str(path), "--out", str(tmp_path / "out"), "--export-mask",
                 str(tmp_path / "m.nii.gz"), "--mask-spacing", "0.001,0.001,0.001"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "over the limit" in err[-1] and "TiB" in err[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == before
