"""``workbench.runs.slices``: options as users type them, converted once; the result folder's files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slices.io import Contour
from slices.pipeline import reconstruct
from surfaces.io import read_mesh, write_json
from workbench.runs import slices as run


def _circle(cx, cy, r, n=40):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([cx + r * np.cos(t), cy + r * np.sin(t)], 1)


@pytest.fixture(scope="module")
def fork(tmp_path_factory):
    """A circle splitting into two, and a hole-free single contour: three bodies."""
    conts = [Contour(0.0, _circle(0, 0, 10)), Contour(2.0, _circle(0, 0, 10)),
             Contour(4.0, _circle(-5, 0, 4)), Contour(4.0, _circle(5, 0, 4)),
             Contour(6.0, _circle(-5, 0, 4)), Contour(6.0, _circle(5, 0, 4))]
    return write_json(tmp_path_factory.mktemp("in") / "fork.json",
                      {"units": "mm", "contours": [{"z": c.z, "points": c.points} for c in conts]})


def test_start_angle_at_the_edge():
    assert run.start_angle(None) is None and run.start_angle(" Auto ") is None
    assert run.start_angle("180") == pytest.approx(np.pi) and run.start_angle(-90) == pytest.approx(-np.pi / 2)
    with pytest.raises(ValueError, match="ray_start: must be an angle"):
        run.start_angle("north")
    with pytest.raises(ValueError, match="ray_start: must be finite"):
        run.start_angle("inf")


def test_library_options_renames_once():
    assert run.library_options({"rays": "32", "lattice": 3, "ray_start": "90", "caps": "half"}) == {
        "n_rays": 32, "lattice_factor": 3.0, "start_angle": pytest.approx(np.pi / 2), "caps": "half"}
    assert run.library_options({"ray_start": "auto"}) == {"start_angle": None}


def test_folder_holds_the_library_result(fork, tmp_path):
    out = tmp_path / "out"
    summary = run.reconstruct_to_folder(fork, out, rays=32, lattice=2.5, ray_start="2.5", samples=2,
                                        reference=False, surface_path="coons")
    assert sorted(p.name for p in out.iterdir()) == ["_COMPLETE", "patches.npz", "render.png", "summary.json",
                                                     "surface.ply", "surface.stl"]
    assert json.loads((out / "summary.json").read_text()) == summary
    assert summary["ray_start"] == "2.5" and summary["rays"] == 32  # as given
    assert summary["bodies"][0]["ray_start_deg"] == pytest.approx(2.5)
    assert summary["time_s"] >= sum(summary[k] for k in ("read_time_s", "surface_time_s", "union_time_s",
                                                         "write_time_s", "render_time_s"))
    keys = list(summary)
    assert keys.index("read_time_s") + 1 == keys.index("surface_time_s")
    assert keys.index("surface_time_s") + 1 == keys.index("union_time_s")
    assert keys.index("union_time_s") + 1 == keys.index("write_time_s")
    assert keys.index("reference_time_s") + 1 == keys.index("render_time_s") and keys[-1] == "time_s"
    # the same figures as the library's, for the same options in its own names
    lib = reconstruct(fork, n_rays=32, lattice_factor=2.5, start_angle=np.radians(2.5), samples=2,
                      reference=False, surface_path="coons")
    for key in ("volume_mm3", "area_mm2", "n_patches", "mesh_triangles", "mesh_union", "bodies"):
        assert summary[key] == lib.summary[key], key
    mesh = read_mesh(out / "surface.ply")
    assert mesh.n_triangles == lib.mesh.n_triangles and mesh.is_watertight()
    with np.load(out / "patches.npz") as data:
        assert list(data["body_kind"]) == ["outer", "outer", "outer"]
        assert bool(data["closed_u"]) and not bool(data["closed_v"])
        for i, patches in enumerate(lib.patches):
            np.testing.assert_array_equal(data[f"body{i}_control"], patches.control)
        largest = max(lib.patches, key=lambda p: p.n_patches)
        np.testing.assert_array_equal(data["control"], largest.control)


def test_no_render_and_defaults(fork, tmp_path):
    summary = run.reconstruct_to_folder(fork, tmp_path, render=False, union="no", reference=False)
    assert not (tmp_path / "render.png").exists() and summary["render_time_s"] < 0.05
    assert summary["ray_start"] == "auto" and summary["rays"] == 64 and not summary["mesh_union"]
    assert "reference_bspline" not in summary


def test_bad_options_leave_no_folder(fork, tmp_path):
    with pytest.raises(ValueError, match=r"unknown \['n_rays'\]"):
        run.reconstruct_to_folder(fork, tmp_path / "a", n_rays=32)
    with pytest.raises(ValueError, match="ray_start"):
        run.reconstruct_to_folder(fork, tmp_path / "b", ray_start="east")
    with pytest.raises(ValueError, match="json input; ROIs are composed within an RT structure set"):
        run.reconstruct_to_folder(fork, tmp_path / "c", minus=["Breast"], samples=1)
    assert not any((tmp_path / name).exists() for name in "abc")


def test_export_mask_rasterises_the_contours(tmp_path):
    import nibabel

    t = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    disc = np.stack([10 * np.cos(t), 10 * np.sin(t)], 1)
    path = tmp_path / "cyl.json"
    write_json(path, {"contours": [{"z": z, "points": disc.tolist()} for z in (0.0, 2.0, 4.0, 6.0)]})
    mask_path = tmp_path / "mask.nii.gz"
    summary = run.reconstruct_to_folder(path, tmp_path / "out", caps="half", samples=2, render=False,
                                        reference=False, export_mask=str(mask_path), mask_spacing="0.5,0.5,1")
    img = nibabel.load(str(mask_path))
    data = np.asarray(img.dataobj)
    # RAS affine (DICOM LPS with x and y negated)
    assert np.allclose(np.diag(img.affine)[:3], [-0.5, -0.5, 1.0]) and set(np.unique(data)) == {0, 1}
    voxels = summary["export_mask"]["voxel_volume_mm3"]
    assert voxels == pytest.approx(data.sum() * 0.25, rel=1e-12)
    # planes on 0..6 mm and half a contour spacing (1 mm) beyond the ends at 1 mm: 7 planes of the disc,
    # the slab count of the contours; the surface volume (half caps) counts 4 slabs of 2 mm
    assert voxels == pytest.approx(7 * np.pi * 100, rel=0.03)
    assert summary["volume_mm3"] == pytest.approx(voxels * 8 / 7, rel=0.03)
    with pytest.raises(ValueError, match="export-mask"):
        run.reconstruct_to_folder(path, tmp_path / "o2", export_mask=str(tmp_path / "m.png"), render=False)
