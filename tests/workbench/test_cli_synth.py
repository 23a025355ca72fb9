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


def test_triad_near_field_orthographic_folder(tmp_path, capsys):
    out = tmp_path / "near"
    code = main(["synth", "triad", "--scene", "inspection_scratch", "--size", "96x128", "--field", "32",
                 "--lights", "4", "--slant", "45", "--light-distance", "150", "--led-mu", "1.5",
                 "--intensities", "1,0.9,1.1,1", "--noise", "0.003", "--shadows", "attached", "--out", str(out)])
    assert code == 0
    for name in ("001.png", "004.png", "flat_001.png", "flat_004.png", "light_positions.txt",
                 "light_directions.txt", "xy_gt.npy", "height_gt.npy", "normal_gt.npy", "scene.json"):
        assert (out / name).is_file(), name
    scene = json.loads((out / "scene.json").read_text())
    assert scene["camera"] == {"model": "orthographic", "pixel_size_mm": 0.25}
    assert scene["lights"]["mu"] == [1.5] * 4 and scene["lights"]["intensities"] == [1.0, 0.9, 1.1, 1.0]
    assert scene["image_size"] == [96, 128] and scene["noise"] == 0.003 and scene["saturated_fraction"] == 0.0
    positions = np.loadtxt(out / "light_positions.txt")
    np.testing.assert_allclose(np.linalg.norm(positions, axis=1), 150.0)
    np.testing.assert_allclose(np.degrees(np.arccos(positions[:, 2] / 150.0)), 45.0)
    printed = capsys.readouterr().out
    assert "LED 1: at (0.00, 106.07, 106.07) mm" in printed and "u_scratch" in printed


def test_triad_near_field_perspective_with_vignetting(tmp_path):
    out = tmp_path / "persp"
    code = main(["synth", "triad", "--scene", "sphere", "--size", "48", "--lights", "3", "--light-distance", "200",
                 "--camera", "perspective", "--focal-length-px", "480", "--camera-height", "300",
                 "--vignetting", "cos4", "--shadows", "attached", "--albedo", "0.7", "--out", str(out)])
    assert code == 0
    scene = json.loads((out / "scene.json").read_text())
    assert scene["camera"] == {"model": "perspective", "focal_length_px": 480.0, "camera_height_mm": 300.0,
                               "principal_point_px": [23.5, 23.5]}
    assert scene["vignetting"] == {"model": "cos4"} and scene["pixel_size_mm"] == pytest.approx(300.0 / 480.0)
    assert np.load(out / "xy_gt.npy").shape == (48, 48, 2)
    # --field instead of the focal length: f = width * height / field
    assert main(["synth", "triad", "--scene", "plane", "--size", "40", "--lights", "3", "--light-distance", "200",
                 "--camera", "perspective", "--field", "20", "--camera-height", "250", "--shadows", "attached",
                 "--out", str(tmp_path / "f")]) == 0
    assert json.loads((tmp_path / "f" / "scene.json").read_text())["camera"]["focal_length_px"] == 500.0


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--light-distance", "150", "--slant", "90"], "--slant"),
        (["--light-distance", "-5"], "--light-distance"),
        (["--light-distance", "150", "--camera", "perspective", "--camera-height", "200"], "--focal-length-px"),
        (["--light-distance", "150", "--camera", "perspective", "--focal-length-px", "300"], "--camera-height"),
        (["--light-distance", "150", "--camera", "perspective", "--focal-length-px", "300", "--camera-height",
          "-1"], "--camera-height"),
        (["--light-distance", "150", "--camera", "perspective", "--focal-length-px", "300", "--camera-height",
          "100", "--pixel-size", "0.1"], "--pixel-size"),
        (["--light-distance", "150", "--scene", "sphere", "--camera", "perspective", "--focal-length-px", "2",
          "--camera-height", "0.01"], "above the part"),
        (["--light-distance", "150", "--focal-length-px", "300"], "--focal-length-px"),
        (["--light-distance", "150", "--field", "10", "--pixel-size", "0.1"], "--field"),
        (["--light-distance", "150", "--led-mu", "1,2"], "--led-mu"),
        (["--light-distance", "150", "--led-mu", "-1"], "mu"),
        (["--light-distance", "150", "--vignetting", "fisheye"], "--vignetting"),
        (["--light-distance", "150", "--specular", "0.3,40"], "--specular"),
        (["--led-mu", "1"], "--light-distance"),
        (["--camera", "perspective"], "--light-distance"),
        (["--size", "32x48"], "--size"),
    ],
)
def test_near_field_bad_input_exits_with_code_2(tmp_path, capsys, extra, message):
    args = ["synth", "triad", "--scene", "plane", "--size", "32", "--shadows", "attached"]
    assert main(args + extra + ["--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x" / "scene.json").exists()


def test_spheres_command_writes_one_folder_per_placement(tmp_path, capsys):
    out = tmp_path / "cal"
    code = main(["synth", "spheres", "--light-distance", "200", "--lights", "4", "--slant", "40",
                 "--centers=-12,8,10", "--centers", "12,-8,10", "0,0,25", "--radius", "10", "--size", "96x128",
                 "--camera", "perspective", "--focal-length-px", "500", "--camera-height", "300",
                 "--supersample", "2", "--out", str(out)])
    assert code == 0
    scene = json.loads((out / "scene.json").read_text())
    assert [s["folder"] for s in scene["spheres"]] == ["sphere_01", "sphere_02", "sphere_03"]
    positions = np.asarray(scene["lights"]["positions_mm"])
    np.testing.assert_allclose(np.linalg.norm(positions, axis=1), 200.0)
    for folder, centre in zip(("sphere_01", "sphere_02", "sphere_03"), ([-12, 8, 10], [12, -8, 10], [0, 0, 25])):
        assert json.loads((out / folder / "sphere.json").read_text()) == {"radius_mm": 10.0, "center_mm": centre}
        assert (out / folder / "filenames.txt").read_text().split() == ["001.png", "002.png", "003.png", "004.png"]
        assert json.loads((out / folder / "scene.json").read_text())["camera"]["model"] == "perspective"
    assert "sphere_03: centre [0.0, 0.0, 25.0] mm" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--centers", "0,0"], "--centers"),
        (["--centers", "0,0,5", "--pixel-size", "1"], "cuts the reference plane"),
        (["--centers", "0,0,10", "--slant", "95"], "--slant"),
        (["--centers", "0,0,10", "--camera", "perspective", "--camera-height", "300"], "--focal-length-px"),
        (["--centers", "0,0,10", "--camera", "perspective", "--focal-length-px", "100", "--camera-height", "15"],
         "above the sphere"),
    ],
)
def test_spheres_bad_input_exits_with_code_2(tmp_path, capsys, extra, message):
    args = ["synth", "spheres", "--light-distance", "150", "--size", "32"]
    assert main(args + extra + ["--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()
