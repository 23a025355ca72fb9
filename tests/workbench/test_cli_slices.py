"""``workbench slices reconstruct`` and ``workbench slices rois`` end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from workbench.cli import main


@pytest.fixture(scope="module")
def contour_json(tmp_path_factory):
    ph = make_phantom("ellipsoid", a=12.0, b=9.0, c=10.0)
    path = tmp_path_factory.mktemp("in") / "contours.json"
    cs = ph.contours(2.0, n_points=40)
    path.write_text(json.dumps({"units": "mm", "contours": [
        {"z": c["z"], "points": c["points"].tolist()} for c in cs]}))
    return path, ph.truth(2.0)


@pytest.mark.parametrize("caps", ["flat", "half"])
def test_reconstruct_writes_outputs(contour_json, tmp_path, caps, capsys):
    path, truth = contour_json
    out = tmp_path / "out"
    code = main(["slices", "reconstruct", str(path), "--caps", caps, "--rays", "32", "--out", str(out),
                 "--reference"])
    assert code == 0
    for name in ("surface.ply", "surface.stl", "patches.npz", "summary.json", "render.png"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    for key in ("volume_mm3", "volume_ml", "area_mm2", "slab_volume_mm3", "n_slices", "n_contours",
                "n_bodies", "n_patches", "max_control_point_deviation_mm", "time_s"):
        assert key in summary, key
    assert summary["max_control_point_deviation_mm"] < 1e-6
    assert summary["mesh_watertight"]
    exact = truth["volume_between_end_planes_mm3"]
    if caps == "flat":
        assert abs(summary["volume_mm3"] / exact - 1) < 5e-3
    assert summary["reference_bspline"]["max_control_point_deviation_mm"] > 1e-3
    printed = capsys.readouterr().out
    assert f"{summary['volume_ml']:.3f} ml" in printed
    with np.load(out / "patches.npz") as data:
        assert data["control"].shape[2:] == (4, 4, 3)


def test_methods_and_bad_input(contour_json, tmp_path, capsys):
    path, _ = contour_json
    assert main(["slices", "reconstruct", str(path), "--method", "coons", "--no-render",
                 "--out", str(tmp_path / "c")]) == 0
    assert main(["slices", "reconstruct", str(tmp_path / "missing.json"), "--out", str(tmp_path / "m")]) == 2
    assert "no such" in capsys.readouterr().err
    bad = (("--samples", "0", "samples"), ("--rays", "2", "n_rays"), ("--lattice", "0.5", "lattice"))
    for flag, value, name in bad:
        out = tmp_path / name
        assert main(["slices", "reconstruct", str(path), flag, value, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"error: {name}" in err
        assert not out.exists()


def test_rois_and_unknown_roi(shared_data, tmp_path, capsys):
    rtss = shared_data / "rtstruct_breast" / "rtss.dcm"
    table = tmp_path / "tables" / "rois.json"  # the folder is created
    assert main(["slices", "rois", str(rtss), "--json", str(table)]) == 0
    out = capsys.readouterr().out
    assert "Heart" in out and "Lt Lung" in out
    assert json.loads(table.read_text())[4]["name"] == "Heart"
    assert main(["slices", "reconstruct", str(rtss), "--roi", "Liver", "--out", str(tmp_path / "liver")]) == 2
    assert "Heart" in capsys.readouterr().err


def test_reconstruct_minus_composes(shared_data, tmp_path, capsys):
    """``--roi "Tumor Bed Block" --minus "Tumor Bed" --minus Nodes``: the written solid is the difference.

    The bed pokes out of the block in one place; the nodes lie apart from both (removes nothing).
    """
    from surfaces.io import read_mesh
    from surfaces.repair import check_solid

    rtss = shared_data / "rtstruct_breast" / "rtss.dcm"
    out = tmp_path / "comp"
    code = main(["slices", "reconstruct", str(rtss), "--roi", "Tumor Bed Block", "--minus", "Tumor Bed",
                 "--minus", "Nodes", "--caps", "half", "--samples", "2", "--no-render", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    comp = summary["composition"]
    assert summary["volume_source"] == "composition"
    assert [e["roi"] for e in comp["minus"]] == ["Tumor Bed", "Nodes"] and comp["base"]["roi"] == "Tumor Bed Block"
    assert summary["volume_mm3"] == pytest.approx(comp["result_volume_mm3"])
    assert summary["volume_ml"] == pytest.approx(comp["result_volume_ml"])
    # the base ROI's own patch volume is kept beside the composed one
    assert comp["base"]["volume_ml"] == pytest.approx(comp["base"]["volume_mm3"] / 1000)
    # nearly all of the bed lies inside the block
    assert 0.99 * comp["minus"][0]["mesh_volume_mm3"] < comp["removed_volume_mm3"] < comp["minus"][0]["mesh_volume_mm3"]
    assert comp["result_mesh_volume_mm3"] == pytest.approx(
        comp["base"]["mesh_volume_mm3"] - comp["removed_volume_mm3"], rel=1e-9)
    # a difference never exceeds its minuend (issue 20): the base's own volume less what is removed
    assert comp["result_volume_mm3"] == pytest.approx(comp["base"]["volume_mm3"] - comp["removed_volume_mm3"])
    assert comp["result_volume_mm3"] <= comp["base"]["volume_mm3"]
    assert comp["watertight"] and summary["mesh_watertight"] and summary["mesh_oriented"]
    mesh = read_mesh(out / "surface.ply")
    assert mesh.is_watertight() and mesh.is_oriented()
    assert mesh.signed_volume() == pytest.approx(comp["result_mesh_volume_mm3"], rel=1e-5)  # float32 PLY
    info = check_solid(mesh)
    assert info["solid"], info["problems"]
    printed = capsys.readouterr().out
    assert "composition" in printed and f"{comp['result_volume_ml']:.3f} ml" in printed


def test_ray_start_option(contour_json, tmp_path, capsys):
    path, _ = contour_json
    out = tmp_path / "r"
    assert main(["slices", "reconstruct", str(path), "--ray-start", "2.5", "--no-render", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ray_start"] == "2.5"
    assert summary["bodies"][0]["ray_start_deg"] == pytest.approx(2.5)
    auto = tmp_path / "a"
    assert main(["slices", "reconstruct", str(path), "--no-render", "--out", str(auto)]) == 0
    summary = json.loads((auto / "summary.json").read_text())
    assert summary["ray_start"] == "auto" and 0 <= summary["bodies"][0]["ray_start_deg"] < 360 / 64
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main(["slices", "reconstruct", str(path), "--ray-start", "north", "--out", str(bad)]) == 2
    assert "ray_start" in capsys.readouterr().err and not bad.exists()


def test_nifti_label_volume_on_the_command_line(tmp_path, capsys):
    nibabel = pytest.importorskip("nibabel")
    data = np.zeros((20, 20, 8), np.uint8)
    data[2:10, 2:10, 1:6] = 3
    data[12:18, 12:18, 2:7] = 5
    path = tmp_path / "labels.nii.gz"
    nibabel.save(nibabel.Nifti1Image(data, np.diag([1.0, 1.0, 2.0, 1.0])), str(path))
    assert main(["slices", "rois", str(path), "--json", str(tmp_path / "labels.json")]) == 0
    assert [r["label"] for r in json.loads((tmp_path / "labels.json").read_text())] == [3, 5]
    out = tmp_path / "five"
    assert main(["slices", "reconstruct", str(path), "--label", "5", "--caps", "half", "--no-render",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["source"] == "nifti" and summary["n_slices"] == 5
    assert summary["volume_mm3"] == pytest.approx((36 - 0.5) * 2 * 5, rel=0.03)
    capsys.readouterr()
    assert main(["slices", "reconstruct", str(path), "--label", "4", "--out", str(tmp_path / "x")]) == 2
    assert "labels present" in capsys.readouterr().err
    assert main(["slices", "reconstruct", str(path), "--label", "3", "--roi", "3",
                 "--out", str(tmp_path / "y")]) == 2
    assert main(["slices", "reconstruct", str(tmp_path / "labels.json"), "--label", "3",
                 "--out", str(tmp_path / "z")]) == 2
    assert "only for NIfTI" in capsys.readouterr().err


def test_a_slices_command_line_registers_the_slices_commands_only():
    """``main`` builds the parser of the group asked for (the other command modules are not imported)."""
    from workbench.cli import GROUPS, build_parser

    parser = build_parser("slices")
    top = next(a for a in parser._actions if a.dest == "command")
    assert set(GROUPS) <= set(top.choices)
    commands = {name: next(a for a in top.choices[name]._actions if a.dest == "subcommand").choices
                for name in GROUPS}
    assert set(commands["slices"]) == {"reconstruct", "rois"}
    assert not any(commands[name] for name in GROUPS if name != "slices")
    args = parser.parse_args(["slices", "rois", "rtss.dcm"])
    assert args.file == "rtss.dcm" and callable(args.func)
