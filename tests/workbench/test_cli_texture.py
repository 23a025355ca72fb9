"""``workbench photometric texture``: files, keys, the reconstruct folder as input, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from datasets_synthetic.render import render, write_diligent_folder
from datasets_synthetic.textures import textured_plate
from photometric.lights import ring_lights
from photometric.texture import UNITS, texture
from workbench.cli import main

D = 0.005


@pytest.fixture(scope="module")
def plate():
    return textured_plate("shot_blasted", size=128, pixel_size=D, sq_um=2.0, tilt=(0.01, 0.0), seed=1)


def test_height_npy(tmp_path, plate, capsys):
    np.save(tmp_path / "height.npy", plate.height)
    out = tmp_path / "out"
    code = main(["photometric", "texture", str(tmp_path / "height.npy"), "--pixel-size", str(D), "--s-filter-mm",
                 "0.02", "--l-filter-mm", "0.25", "--form", "poly2", "--height-u-mm", "0.0001", "--mc-samples", "8",
                 "--out", str(out)])
    assert code == 0
    data = json.loads((out / "texture.json").read_text())
    assert (out / "texture.png").stat().st_size > 1000
    assert set(data["parameters"]) == set(UNITS)
    for rec in data["parameters"].values():
        assert {"value", "U", "unit"} <= set(rec)
    assert data["form"] == "poly2" and data["filters"]["s_filter_mm"] == 0.02 and data["band"]["long_mm"] == 0.25
    # the same numbers as the library
    ref = texture(plate.height, D, s_filter_mm=0.02, l_filter_mm=0.25, form="poly2")
    assert data["parameters"]["Sq"]["value"] == pytest.approx(ref.values["Sq"], rel=1e-12)
    assert data["parameters"]["Sq"]["U"] > 0
    assert "Sq" in capsys.readouterr().out


def test_reconstruct_folder(tmp_path, plate):
    L = ring_lights(4, 40.0)
    images = render(plate, L, noise=0.01, seed=2)
    write_diligent_folder(tmp_path / "plate", images, L, np.ones(4), np.ones(plate.shape, bool), plate.normals,
                          plate.height, {"pixel_size_mm": D})
    rec = tmp_path / "rec"
    code = main(["photometric", "reconstruct", str(tmp_path / "plate"), "--noise-sigma", "0.01", "--out", str(rec)])
    assert code == 0
    out = tmp_path / "tex"
    assert main(["photometric", "texture", str(rec), "--s-filter-mm", "0.04", "--l-filter-mm", "0.25",
                 "--mc-samples", "10", "--out", str(out)]) == 0
    data = json.loads((out / "texture.json").read_text())
    assert data["pixel_size_source"] == "summary.json" and data["band"]["pixel_size_mm"] == D
    assert data["filters"]["integrator_transfer"] == "divided out (dct)"
    assert data["filters"]["edge"] == "drop" and data["filters"]["edge_band_px"] == 38
    assert data["uncertainty"]["model"].startswith("integrated white slope noise")
    truth = texture(plate.height, D, s_filter_mm=0.04, l_filter_mm=0.25, edge="drop").values
    sq = data["parameters"]["Sq"]
    assert sq["value"] == pytest.approx(truth["Sq"], rel=0.05)
    assert abs(sq["corrected"] - truth["Sq"]) <= sq["U_corrected"] + 0.01 * truth["Sq"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["{h}"], "--pixel-size: required"),
        (["{h}", "--pixel-size", "0"], "--pixel-size: must be a positive"),
        (["{h}", "--pixel-size", "0.01", "--s-filter-mm", "0.5", "--l-filter-mm", "0.1"], "s_filter_mm"),
        (["{h}", "--pixel-size", "0.01", "--mask", "{m}"], "--mask: shape"),
        (["{tmp}/nothere.npy", "--pixel-size", "0.01"], "does not exist"),
        (["{tmp}", "--pixel-size", "0.01"], "height.npy"),
    ],
)
def test_bad_input_exits_2(tmp_path, capsys, plate, args, message):
    np.save(tmp_path / "h.npy", plate.height)
    np.save(tmp_path / "m.npy", np.ones((3, 3), bool))
    fmt = {"h": str(tmp_path / "h.npy"), "m": str(tmp_path / "m.npy"), "tmp": str(tmp_path)}
    code = main(["photometric", "texture", *[a.format(**fmt) for a in args], "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "texture.json").exists()


def test_spec_limits_and_the_reconstruct_hook(tmp_path, plate):
    from workbench.runs.texture import judge_texture, texture_of_result

    np.save(tmp_path / "height.npy", plate.height)
    (tmp_path / "summary.json").write_text(json.dumps({"pixel_size_mm": D, "pixel_size_source": "option",
                                                       "integrator": "fc"}))
    np.save(tmp_path / "height_u.npy", np.full(plate.shape, 5e-5))
    doc = texture_of_result(tmp_path, s_filter_mm=0.02, l_filter_mm=0.25, mc_samples=8)
    assert (tmp_path / "texture.json").is_file() and (tmp_path / "texture.png").is_file()
    assert doc["uncertainty"]["model"].startswith("white height noise")
    sa = doc["parameters"]["Sa"]
    v, U = sa["corrected"], sa["U_corrected"]
    limits = {"max_Sa_um": v + 3 * U, "max_Sq_um": 0.5 * doc["parameters"]["Sq"]["value"], "max_Sz_um": 1e3,
              "roi_mm": [[0, 0]]}
    checks = {c["limit_key"]: c for c in judge_texture(doc, limits, "guard_band")}
    assert set(checks) == {"max_Sa_um", "max_Sq_um", "max_Sz_um"}
    assert checks["max_Sa_um"]["verdict"] == "pass" and checks["max_Sq_um"]["verdict"] == "fail"
    assert judge_texture(doc, {"max_Sa_um": v + 0.5 * U}, "guard_band")[0]["verdict"] == "uncertain"
    assert judge_texture(doc, {"max_Sa_um": v + 0.5 * U}, "simple")[0]["verdict"] == "pass"


def test_reconstruct_texture_writes_beside_the_height(tmp_path, plate, capsys):
    """``photometric reconstruct --texture``: texture.json and texture.png in --out, listed, and a rerun is accepted."""
    L = ring_lights(4, 40.0)
    images = render(plate, L, noise=0.01, seed=2)
    write_diligent_folder(tmp_path / "plate", images, L, np.ones(4), np.ones(plate.shape, bool), plate.normals,
                          plate.height, {"pixel_size_mm": D})
    rec = tmp_path / "rec"
    args = ["photometric", "reconstruct", str(tmp_path / "plate"), "--noise-sigma", "0.01", "--texture",
            "--texture-s-filter-mm", "0.04", "--texture-l-filter-mm", "0.25", "--texture-form", "poly2",
            "--out", str(rec)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "texture (ISO 25178-2" in out and "Sa " in out
    summary = json.loads((rec / "summary.json").read_text())
    assert {"texture.json", "texture.png"} <= set(summary["files"])
    assert summary["texture"]["filters"] == {"s_filter_mm": 0.04, "l_filter_mm": 0.25, "form": "poly2"}
    doc = json.loads((rec / "texture.json").read_text())
    assert doc["form"] == "poly2" and doc["band"]["long_mm"] == 0.25
    assert summary["texture"]["Sq"]["value"] == doc["parameters"]["Sq"]["value"]
    # the same numbers as the texture command on the folder
    assert main(["photometric", "texture", str(rec), "--s-filter-mm", "0.04", "--l-filter-mm", "0.25", "--form",
                 "poly2", "--out", str(tmp_path / "tex")]) == 0
    again = json.loads((tmp_path / "tex" / "texture.json").read_text())
    assert again["parameters"]["Sq"]["value"] == pytest.approx(doc["parameters"]["Sq"]["value"], rel=1e-12)
    truth = texture(plate.height, D, s_filter_mm=0.04, l_filter_mm=0.25, form="poly2", edge="drop").values
    assert doc["parameters"]["Sq"]["value"] == pytest.approx(truth["Sq"], rel=0.05)
    # a rerun into the same folder is not refused (texture files belong to a result folder)
    assert main(args) == 0


@pytest.mark.parametrize("extra, message", [
    (["--texture-l-filter-mm", "0.25"], "--texture-l-filter-mm: only applies with --texture"),
    (["--texture", "--texture-s-filter-mm", "0.3", "--texture-l-filter-mm", "0.25"], "must be below l_filter_mm"),
    (["--texture", "--texture-l-filter-mm", "-1"], "l_filter_mm: expected a positive number"),
    (["--texture"], "--texture: needs the pixel size in mm"),
])
def test_reconstruct_texture_bad_options_exit_2(tmp_path, capsys, extra, message):
    plate = textured_plate("ground", size=32, pixel_size=D, sq_um=2.0, seed=1)
    L = ring_lights(4, 40.0)
    write_diligent_folder(tmp_path / "in", render(plate, L), L, np.ones(4), np.ones(plate.shape, bool), plate.normals,
                          plate.height, {})  # no pixel size in scene.json
    code = main(["photometric", "reconstruct", str(tmp_path / "in"), *extra, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()
