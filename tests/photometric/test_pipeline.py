import json

import cv2
import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.io import read_folder, read_image
from photometric.pipeline import reconstruct
from workbench.cli import main

FILES = ["normals.npy", "albedo.npy", "p.npy", "q.npy", "valid.npy", "height.npy", "normals.png",
         "albedo.png", "height.png", "surface.ply", "defects.json", "summary.json"]


@pytest.fixture(scope="module")
def plate_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("plate")
    make_triad_folder(out, scene="plate", size=128, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    return out


def test_reconstruct_folder_writes_everything(plate_folder, tmp_path):
    summary = reconstruct(plate_folder, tmp_path / "out", integrator="dct")
    out = tmp_path / "out"
    for name in FILES:
        assert (out / name).is_file(), name
    normals = np.load(out / "normals.npy")
    assert normals.shape == (128, 128, 3) and normals.dtype == np.float32
    assert np.allclose(np.linalg.norm(normals, axis=2), 1, atol=1e-5)
    assert np.load(out / "valid.npy").dtype == bool
    assert summary == json.loads((out / "summary.json").read_text())
    assert summary["pixel_size_mm"] == 0.2 and summary["pixel_size_source"] == "scene.json"
    # 16-bit quantisation only: normals within a few hundredths of a degree
    assert summary["mean_angular_error_deg"] < 0.05
    assert summary["height_rmse_mm"] < 0.01 * summary["height_range_mm"]
    assert summary["invalid_fraction"] == 0.0
    assert summary["light_condition_number"] == pytest.approx(np.sqrt(2), rel=1e-6)
    for key in ("read", "solve", "integrate", "surface", "defects", "write", "total"):
        assert summary["timings_s"][key] >= 0
    defects = json.loads((out / "defects.json").read_text())
    assert defects["units"] == "mm" and len(defects["defects"]) == summary["n_defects"] == 3
    truth = json.loads((plate_folder / "scene.json").read_text())
    assert "defects" in truth


def test_reconstruct_images_and_lights_arrays(tmp_path):
    data_dir = tmp_path / "d"
    make_triad_folder(data_dir, scene="sphere", size=64, noise=0.0, shadows="none", deviate=None,
                      albedo=0.7, bit_depth=None, seed=0)
    data = read_folder(data_dir)
    summary = reconstruct(data.images, tmp_path / "o", lights=data.lights, pixel_size=0.5,
                          integrator="lsq", step=8, samples=2)
    assert summary["size"] == {"height": 64, "width": 64, "images": 3, "channels": 1}
    assert summary["patches"] == [8, 8] and summary["pixel_size_source"] == "option"
    height = np.load(tmp_path / "o" / "height.npy")
    assert height.shape == (64, 64)


def test_read_image_keeps_16_bits_and_rgb_order(tmp_path):
    img = np.zeros((4, 5, 3), np.uint16)
    img[..., 0] = 1000  # red
    img[..., 2] = 65535  # blue
    cv2.imwrite(str(tmp_path / "a.png"), img[..., ::-1])
    back = read_image(tmp_path / "a.png")
    assert back.dtype == np.float32
    assert np.allclose(back[0, 0], [1000 / 65535, 0, 1.0])


def test_read_folder_select_and_bear(shared_data):
    data = read_folder(shared_data / "diligent_bear", select=["048.png", "033.png", "091.png"])
    assert data.names == ("048.png", "033.png", "091.png")
    assert data.intensities.shape == (3, 3) and data.mask.dtype == bool
    assert data.images.max() <= 1.0 and data.images.dtype == np.float32
    with pytest.raises(ValueError, match="select"):
        read_folder(shared_data / "diligent_bear", select=["nope.png"])


def test_cli_folder_and_triad(shared_data, tmp_path, capsys):
    code = main(["photometric", "reconstruct", str(shared_data / "diligent_bear"), "--triad",
                 "--out", str(tmp_path / "bear")])
    assert code == 0
    summary = json.loads((tmp_path / "bear" / "summary.json").read_text())
    assert abs(summary["mean_angular_error_deg"] - 11.74) < 0.05
    assert summary["images"] == ["090.png", "048.png", "033.png"]
    text = capsys.readouterr().out
    assert f"{summary['mean_angular_error_deg']:.3f}" in text


def test_cli_images_form(plate_folder, tmp_path):
    names = (plate_folder / "filenames.txt").read_text().split()
    args = ["photometric", "reconstruct", "--images", *[str(plate_folder / n) for n in names],
            "--lights", str(plate_folder / "light_directions.txt"),
            "--intensities", str(plate_folder / "light_intensities.txt"),
            "--mask", str(plate_folder / "mask.png"), "--integrator", "fc",
            "--pixel-size", "0.2", "--out", str(tmp_path / "o")]
    assert main(args) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["integrator"] == "fc" and summary["pixel_size_mm"] == 0.2
    assert "mean_angular_error_deg" not in summary  # no ground truth given with --images


@pytest.mark.parametrize(
    "args",
    [
        ["photometric", "reconstruct"],
        ["photometric", "reconstruct", "--images", "a.png", "b.png", "c.png"],
        ["photometric", "reconstruct", "/definitely/not/here"],
        ["photometric", "reconstruct", "--images", "a.png", "--lights", "l.txt", "--triad"],
    ],
)
def test_cli_bad_input_exit_2(args, capsys):
    assert main(args) == 2
    assert "error" in capsys.readouterr().err


def test_previews_readable(plate_folder, tmp_path):
    reconstruct(plate_folder, tmp_path / "p", step=16)
    for name in ("normals.png", "albedo.png", "height.png"):
        img = cv2.imread(str(tmp_path / "p" / name), cv2.IMREAD_UNCHANGED)
        assert img is not None and img.shape[:2] == (128, 128) and img.dtype == np.uint8
    normals = cv2.imread(str(tmp_path / "p" / "normals.png"))[..., ::-1].astype(float)
    # a flat plate faces the camera: blue (z) near 255, red/green near the middle
    assert np.median(normals[..., 2]) > 250 and abs(np.median(normals[..., 0]) - 127.5) < 2
