"""``workbench photometric reconstruct``: the command line of the photometric pipeline."""

import json

import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.lights import light_angles
from workbench.cli import main


@pytest.fixture(scope="module")
def plate_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("plate")
    make_triad_folder(out, scene="plate", size=64, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    return out


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


def test_cli_lights_as_slant_and_azimuth(plate_folder, tmp_path, capsys):
    """A two-column lights file is 'slant azimuth' in degrees (the 'slant tilt' form)."""
    xyz = np.loadtxt(plate_folder / "light_directions.txt")
    np.savetxt(tmp_path / "sa.txt", np.stack(light_angles(xyz), axis=1))
    names = (plate_folder / "filenames.txt").read_text().split()
    args = ["photometric", "reconstruct", "--images", *[str(plate_folder / n) for n in names],
            "--lights", str(tmp_path / "sa.txt"), "--pixel-size", "0.2", "--out", str(tmp_path / "o")]
    assert main(args) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    np.testing.assert_allclose(summary["lights"], xyz, atol=1e-9)
    out = capsys.readouterr().out
    assert f"light condition number {summary['light_condition_number']:.3f}" in out
    assert "summary.json holds every number above" in out
