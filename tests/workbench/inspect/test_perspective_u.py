"""guard_band on a perspective (pinhole) rig: the inspection states U and gives real verdicts.

The parts are rendered here by the independent near-field renderer (datasets_synthetic) with a
pinhole camera 150 mm above the plate; the rig is calibrated from its rendered flat field with
the same pinhole camera."""

import json

import numpy as np
import pytest

from datasets_synthetic.cameras import perspective_camera
from datasets_synthetic.heightfields import AnalyticSurface, inspection_part
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import ring_point_lights
from photometric.camera import make_camera
from surfaces.io import write_png
from workbench.inspect.part import inspect_part
from workbench.inspect.spec import parse_spec
from workbench.runs.photometric import calibrate_to_rig

SIZE, FIELD_MM, CAMERA_MM, LIMIT_MM = 160, 16.0, 150.0, 0.10
#: (id, defect, depth mm): clean, far over, far under the limit, and within U of it
PARTS = (("clean", None, 0.0), ("over", "scratch", 0.18), ("under", "scratch", 0.04), ("at_limit", "scratch", 0.10))


def _u16(img):
    return np.round(np.clip(img, 0.0, 1.0) * 65535.0).astype(np.uint16)


@pytest.fixture(scope="module")
def perspective_lot(tmp_path_factory):
    root = tmp_path_factory.mktemp("persp")
    px = FIELD_MM / SIZE
    f = CAMERA_MM / px
    cam = perspective_camera(SIZE, f, CAMERA_MM)
    lights = ring_point_lights(4, 40.0, 200.0)
    first = render_near_field(AnalyticSurface(), cam, lights, 0.9, flat_albedo=0.8, seed=0)
    exposure = 0.8 * first.exposure
    flats = render_near_field(AnalyticSurface(), cam, lights, 0.9, exposure=exposure, flat_albedo=0.8, noise=0.003,
                              bit_depth=16, seed=0).flats
    flat_paths = []
    for k, img in enumerate(flats):
        flat_paths.append(str(root / "rig" / f"flat_{k + 1:03d}.png"))
        write_png(flat_paths[-1], _u16(img))
    calibrate_to_rig(root / "rig.json", light_positions=lights.positions,
                     camera=make_camera("perspective", focal_length_px=f, camera_height_mm=CAMERA_MM),
                     flat_field=flat_paths, flat_albedo=0.8)
    for i, (name, defect, depth) in enumerate(PARTS):
        scene = AnalyticSurface() if defect is None else inspection_part(SIZE, px, defect, depth_mm=depth,
                                                                                  center_mm=(1.0, 1.0))
        images = render_near_field(scene, cam, lights, 0.8, exposure=exposure, flat_albedo=0.8, noise=0.003,
                                   bit_depth=16, seed=10 + i).images
        for k, img in enumerate(images):
            write_png(root / "parts" / name / f"{k + 1:03d}.png", _u16(img))
    return root


def test_guard_band_gives_verdicts_on_a_perspective_rig(perspective_lot, tmp_path):
    root = perspective_lot
    spec = parse_spec({"max_depth_mm": LIMIT_MM, "decision_rule": "guard_band"})
    verdicts, docs = {}, {}
    for name, _, _ in PARTS:
        verdicts[name] = inspect_part(root / "parts" / name, tmp_path / name, root / "rig.json", spec,
                                      uncertainty={"light_position_tolerance_mm": 0.2})["verdict"]
        docs[name] = json.loads((tmp_path / name / "result.json").read_text())
    assert docs["over"]["measurement"]["camera"]["model"] == "perspective"
    assert docs["over"]["measurement"]["uncertainty"]["method"] == "linear"
    assert verdicts["clean"] == "pass" and verdicts["over"] == "fail" and verdicts["under"] == "pass", verdicts
    # at the limit the depth's interval straddles it: the guard band cannot release or reject the part
    assert verdicts["at_limit"] == "uncertain", (verdicts, docs["at_limit"]["max_depth_mm"],
                                                 docs["at_limit"]["max_depth_U_mm"])
    for name, _, depth in PARTS[1:]:
        check = docs[name]["imperfections"][0]["checks"][0]
        assert check["rule"] == "guard_band" and 0.0 < check["U"] < 0.02
        # the stated interval holds the rendered depth
        assert abs(docs[name]["max_depth_mm"] - depth) <= docs[name]["max_depth_U_mm"], (name, docs[name])
