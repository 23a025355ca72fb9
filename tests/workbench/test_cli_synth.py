"""``workbench synth triad|phantom``: files, JSON keys and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pydicom
import pytest

from workbench.cli import main


def test_triad_command_writes_a_diligent_folder(tmp_path, capsys):
    out = tmp_path / "triad"
    code = main(["synth", "triad", "--scene", "plate", "--size", "64", "--lights", "3", "--slant", "45",
                 "--noise", "0.005", "--shadows", "cast", "--deviate", "2,0,0", "--out", str(out),
                 "--seed", "1"])
    assert code == 0
    for name in ("001.png", "002.png", "003.png", "filenames.txt", "light_directions.txt",
                 "light_intensities.txt", "mask.png", "normal_gt.npy", "height_gt.npy", "scene.json"):
        assert (out / name).is_file()
    scene = json.loads((out / "scene.json").read_text())
    assert scene["seed"] == 1 and scene["size"] == 64 and scene["shadows"] == "cast"
    assert scene["light_error_deg"][0] == pytest.approx(2.0)
    assert [d["kind"] for d in scene["defects"]] == ["v_crack", "spherical_dent", "u_scratch"]
    printed = capsys.readouterr().out
    assert "2.000 deg" in printed and "v_crack" in printed


def test_triad_deviation_pairs_and_seed_reproducibility(tmp_path):
    args = ["synth", "triad", "--scene", "bumps", "--size", "32", "--lights", "4", "--deviate",
            "1:2,0,0:-3,0", "--seed", "5", "--noise", "0.01"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    assert main(args + ["--out", str(tmp_path / "b")]) == 0
    a = json.loads((tmp_path / "a" / "scene.json").read_text())
    np.testing.assert_allclose(a["deviations_deg"], [[1, 2], [0, 0], [0, -3], [0, 0]])
    assert (tmp_path / "a" / "001.png").read_bytes() == (tmp_path / "b" / "001.png").read_bytes()


@pytest.mark.parametrize("fmt", ["json", "dicom", "rtstruct"])
def test_phantom_command(tmp_path, fmt, capsys):
    out = tmp_path / fmt
    code = main(["synth", "phantom", "--shape", "kidney", "--spacing", "5", "--pixel", "2",
                 "--format", fmt, "--out", str(out), "--surface-points", "500"])
    assert code == 0
    truth = json.loads((out / "truth.json").read_text())
    for key in ("volume_mm3", "volume_between_end_planes_mm3", "area_mm2"):
        assert truth[key] > 0
    assert np.load(out / "surface_points.npy").shape == (500, 3)
    contours = json.loads((out / "contours.json").read_text())
    assert contours["units"] == "mm" and len(contours["contours"]) == truth["n_contours"]
    assert (out / "ct").is_dir() == (fmt != "json")
    assert (out / "rtstruct.dcm").is_file() == (fmt == "rtstruct")
    if fmt == "rtstruct":
        rt = pydicom.dcmread(out / "rtstruct.dcm")
        assert len(rt.ROIContourSequence[0].ContourSequence) == truth["n_contours"]
    assert f"{truth['volume_mm3']:.3f}" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["synth", "triad", "--size", "32", "--deviate", "1,2"], "--deviate"),
        (["synth", "triad", "--size", "32", "--specular", "0.3"], "--specular"),
        (["synth", "triad", "--size", "32", "--albedo", "shiny"], "--albedo"),
        (["synth", "phantom", "--spacing", "-1"], "spacing"),
        (["synth", "phantom", "--shape", "ring", "--spacing", "500", "--offset", "250"], "spacing"),
    ],
)
def test_bad_input_exits_with_code_2(tmp_path, capsys, args, message):
    assert main(args + ["--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_phantom_pixel_size_has_the_alias_pixel():
    """``--pixel-size`` as in every other command; ``--pixel`` (the old name) still works."""
    from workbench.cli import build_parser

    parse = build_parser().parse_args
    assert parse(["synth", "phantom", "--out", "x"]).pixel_size == 0.8
    assert parse(["synth", "phantom", "--pixel-size", "0.5", "--out", "x"]).pixel_size == 0.5
    assert parse(["synth", "phantom", "--pixel", "2", "--out", "x"]).pixel_size == 2.0
