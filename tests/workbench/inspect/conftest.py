"""A small rendered lot shared by the inspection tests: a near-field rig and four parts with known defects."""

from __future__ import annotations

import json

import pytest

from photometric.camera import make_camera
from workbench.inspect.lot import LotPart, render_lot
from workbench.runs.photometric import calibrate_to_rig

#: clean, clearly over 0.10 mm, clearly under, and a crack at the limit
PARTS = (LotPart("clean", None, 0.0, 1.0, 11), LotPart("scratch_over", "scratch", 0.16, 0.9, 12),
         LotPart("dent_under", "dent", 0.04, 1.08, 13), LotPart("crack_limit", "crack", 0.10, 0.95, 14))


@pytest.fixture(scope="session")
def small_lot(tmp_path_factory):
    """224 x 224 px over 20 mm, four LEDs 200 mm away, 0.3 % noise; rig.json calibrated from the flat field."""
    root = tmp_path_factory.mktemp("lot")
    truth = render_lot(root, PARTS, size=224, field_mm=20.0)
    flats = sorted(str(p) for p in (root / "rig").glob("flat_*.png"))
    calibrate_to_rig(root / "rig.json", light_positions=root / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    spec = root / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.10, "max_count": 1}))
    return {"root": root, "parts": root / "parts", "rig": root / "rig.json", "spec": spec, "truth": truth,
            "flats": flats}
