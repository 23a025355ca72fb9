"""Measurement validity in the inspection (issue 32, item 1): a measurement out of its quality limits never passes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from photometric.camera import make_camera
from photometric.rig import read_rig
from surfaces.io import write_png
from surfaces.validate import InputError
from workbench.inspect.part import inspect_part, reference_quality
from workbench.runs.photometric import calibrate_to_rig


def _u16(img):
    return np.round(np.clip(img, 0.0, 1.0) * 65535.0).astype(np.uint16)


def _folder(root, images, names=None):
    names = names or [f"{k + 1:03d}.png" for k in range(len(images))]
    for name, img in zip(names, images):
        write_png(root / name, _u16(img))
    (root / "filenames.txt").write_text("\n".join(names) + "\n")
    return root


@pytest.fixture(scope="module")
def mitsuba_parts(tmp_path_factory):
    """A matte and a rough-plastic plate (alpha 0.3, specular 0.3) rendered by Mitsuba 3 on one 4-LED rig."""
    pytest.importorskip("mitsuba", reason="Mitsuba 3 renders the glossy plate")
    from datasets_synthetic.cameras import orthographic_camera
    from datasets_synthetic.heightfields import plane
    from datasets_synthetic.mitsuba_scenes import material, render_mitsuba
    from datasets_synthetic.point_lights import ring_point_lights

    root = tmp_path_factory.mktemp("gloss")
    size, pixel_mm = 96, 0.5
    lights = ring_point_lights(4, 45.0, 150.0, 90.0, 0.0)
    cam = orthographic_camera((size, size), pixel_mm)
    fx = {"read_noise": 0.002, "bit_depth": 12}
    out = {}
    for kind in ("diffuse", "roughplastic"):
        r = render_mitsuba(plane((size, size), pixel_mm), cam, lights, material(kind, 0.7, alpha=0.3, specular=0.3),
                           spp=8, flats=kind == "diffuse", exposure=None, effects=fx)
        if kind == "diffuse":
            flats = [str(p) for p in (_folder(root / "flats", r.flats, [f"flat_{k + 1:03d}.png" for k in range(4)])
                                      .glob("flat_*.png"))]
            np.savetxt(root / "light_positions.txt", lights.positions)
            calibrate_to_rig(root / "rig.json", light_positions=root / "light_positions.txt",
                             camera=make_camera("orthographic", pixel_size_mm=pixel_mm), flat_field=sorted(flats),
                             flat_albedo=0.8)
        out[kind] = _folder(root / kind, r.images)
    spec = root / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.08}))
    return {"root": root, "rig": root / "rig.json", "spec": spec, **out}


def test_a_glossy_part_is_never_passed_and_the_matte_control_is(mitsuba_parts, tmp_path):
    m = mitsuba_parts
    figures = inspect_part(m["diffuse"], tmp_path / "matte", m["rig"], m["spec"])
    assert figures["verdict"] == "pass" and figures["background_rms_mm"] < 0.005
    result = json.loads((tmp_path / "matte" / "result.json").read_text())
    assert result["quality"]["trusted"] and result["quality"]["limits_source"] == "default"
    with pytest.raises(InputError, match="not measured: the measurement fails its quality limits.*background"):
        inspect_part(m["roughplastic"], tmp_path / "gloss", m["rig"], m["spec"])
    assert not (tmp_path / "gloss" / "result.json").exists()


def test_a_reference_part_sets_the_limits_in_the_rig(mitsuba_parts, tmp_path, capsys):
    from workbench.cli import main

    m = mitsuba_parts
    flats = sorted(str(p) for p in (m["root"] / "flats").glob("flat_*.png"))
    rig = tmp_path / "rig.json"
    args = ["inspect", "calibrate", "--flat", *flats, "--light-positions", str(m["root"] / "light_positions.txt"),
            "--pixel-size", "0.5", "--flat-albedo", "0.8", "--out", str(rig), "--reference-part", str(m["diffuse"])]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "quality limits" in printed and str(rig) in printed and "/tmp/rig-" not in printed
    q = read_rig(rig).quality
    ref = q["reference_figures"]["background_rms_mm"]
    assert 0 < ref < 0.005 and q["limits"]["background_rms_mm"] == pytest.approx(min(0.005, 4 * ref))
    assert q["limits"]["invalid_fraction"] <= 0.05
    assert q["reference_slopes"] is not None and max(abs(v) for v in q["reference_slopes"]) < 0.01
    # the limits and the slope reference come from the rig now; the matte part still passes
    inspect_part(m["diffuse"], tmp_path / "matte", rig, m["spec"])
    result = json.loads((tmp_path / "matte" / "result.json").read_text())
    assert result["verdict"] == "pass" and result["quality"]["limits_source"] == "rig"
    assert result["quality"]["figures"]["slope_bias_mrad"] is not None
    # a glossy reference cannot set limits: refused, nothing written
    with pytest.raises(InputError, match="reference-part.*fails the stated quality limits"):
        reference_quality(m["roughplastic"], rig)
    assert main([*args[:-4], "--out", str(tmp_path / "bad.json"), "--reference-part", str(m["roughplastic"])]) == 2
    assert not (tmp_path / "bad.json").exists()


def test_reference_part_refuses_a_missing_folder(small_lot, tmp_path):
    with pytest.raises(FileNotFoundError):
        reference_quality(tmp_path / "none", small_lot["rig"])


def _result(verdict, n, background, limit=0.005):
    return {"verdict": verdict, "n_imperfections": n,
            "quality": {"figures": {"background_rms_mm": background, "invalid_fraction": 0.0},
                        "limits": {"background_rms_mm": limit, "invalid_fraction": 0.05}}}


def test_lot_flags_drift_and_a_clean_sweep_on_off_quality():
    from workbench.inspect.report import lot_quality_flags

    steady = [_result("pass", 0, 3e-4)] * 6 + [_result("fail", 1, 3e-4)] * 2
    assert lot_quality_flags(steady) == []
    # a clean sweep is fine on good measurements, flagged when the figures are off or parts were refused
    assert lot_quality_flags([_result("pass", 0, 3e-4)] * 8) == []
    sweep = lot_quality_flags([_result("pass", 0, 4e-3)] * 8)
    assert len(sweep) == 1 and sweep[0].startswith("100 % yield")
    refused = [{"id": "p9", "status": "failed", "error": "part p9 not measured: the measurement fails its quality "
                "limits (default limits): ..."}]
    flags = lot_quality_flags([_result("pass", 0, 3e-4)] * 8, refused)
    assert len(flags) == 2 and "1 part(s) could not be measured" in flags[0] and "100 % yield" in flags[1]
    # a frame error is not a quality refusal
    assert lot_quality_flags([_result("pass", 0, 3e-4)] * 8, [{"error": "frame 002 is dark"}]) == []
    drift = lot_quality_flags([_result("fail", 1, 3e-4)] * 4 + [_result("pass", 0, 3.5e-3)] * 4)
    assert len(drift) == 1 and drift[0].startswith("quality drift: background_rms_mm")


@pytest.fixture(scope="module")
def glossy_rig(tmp_path_factory):
    """8 LEDs, Mitsuba 3 rough plastic (alpha 0.3, specular 0.3): flats, a level reference plate, a clean part."""
    pytest.importorskip("mitsuba", reason="Mitsuba 3 renders the glossy plate")
    from datasets_synthetic.cameras import orthographic_camera
    from datasets_synthetic.heightfields import plane
    from datasets_synthetic.mitsuba_scenes import material, render_mitsuba
    from datasets_synthetic.point_lights import ring_point_lights

    root = tmp_path_factory.mktemp("gloss8")
    size, pixel_mm = 96, 0.5
    lights = ring_point_lights(8, 45.0, 150.0, 90.0, 0.0)
    cam = orthographic_camera((size, size), pixel_mm)
    fx = {"read_noise": 0.002, "bit_depth": 12}
    bsdf = material("roughplastic", 0.7, alpha=0.3, specular=0.3)
    ref = render_mitsuba(plane((size, size), pixel_mm), cam, lights, bsdf, spp=8, flats=True, effects=fx, seed=3)
    part = render_mitsuba(plane((size, size), pixel_mm), cam, lights, bsdf, spp=8, flats=False, effects=fx,
                          exposure=ref.exposure, seed=4)
    _folder(root / "flats", ref.flats, [f"flat_{k + 1:03d}.png" for k in range(8)])
    np.savetxt(root / "light_positions.txt", lights.positions)
    spec = root / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.08}))
    return {"root": root, "reference": _folder(root / "reference", ref.images), "part": _folder(root / "part",
            part.images), "spec": spec, "flats": sorted(str(p) for p in (root / "flats").glob("flat_*.png"))}


@pytest.mark.slow
def test_a_glossy_rig_measures_the_glossy_part_the_lambertian_one_refuses(glossy_rig, tmp_path, capsys):
    from workbench.cli import main

    g = glossy_rig
    base = ["inspect", "calibrate", "--flat", *g["flats"], "--light-positions", str(g["root"] / "light_positions.txt"),
            "--pixel-size", "0.5", "--flat-albedo", "0.8"]
    plain = tmp_path / "plain.json"
    assert main([*base, "--out", str(plain)]) == 0
    with pytest.raises(InputError, match="quality limits"):
        inspect_part(g["part"], tmp_path / "p0", plain, g["spec"])
    # without a roughness the glossy model is refused before anything is written
    assert main([*base, "--out", str(tmp_path / "x.json"), "--reference-part", str(g["reference"]),
                 "--reflectance", "glossy"]) == 2
    assert "--gloss-alpha" in capsys.readouterr().err and not (tmp_path / "x.json").exists()
    glossy = tmp_path / "glossy.json"
    assert main([*base, "--out", str(glossy), "--reference-part", str(g["reference"]), "--reflectance", "glossy",
                 "--gloss-alpha", "0.3"]) == 0
    refl = read_rig(glossy).reflectance
    # the weight of Mitsuba's roughplastic coat (specular 0.3 of the diffuse) measured by bench_glossy: 0.317
    assert refl["model"] == "glossy" and refl["alpha"] == 0.3 and 0.2 < refl["weight"] < 0.45
    figures = inspect_part(g["part"], tmp_path / "p1", glossy, g["spec"])
    assert figures["verdict"] == "pass" and figures["background_rms_mm"] < 0.005
    result = json.loads((tmp_path / "p1" / "result.json").read_text())
    assert result["measurement"]["reflectance"]["model"] == "glossy"
    assert result["quality"]["limits_source"] == "rig"
