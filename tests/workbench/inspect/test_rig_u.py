"""Inspection carries the rig's calibration uncertainty (its LED position u) unless an option overrides it."""

import json

import pytest

from workbench.inspect.part import inspect_part
from workbench.inspect.spec import parse_spec


def test_rig_position_u_is_the_default(small_lot, tmp_path):
    doc = json.loads(small_lot["rig"].read_text())
    doc["calibration"] = {**(doc.get("calibration") or {}),
                          "uncertainty_mm": [[0.05, 0.05, 0.2], [0.05, 0.1, 0.1], [0.02, 0.02, 0.05], [0.1, 0.1, 0.1]]}
    rig = small_lot["rig"].parent / "rig_with_u.json"
    rig.write_text(json.dumps(doc))
    spec = parse_spec({"max_depth_mm": 0.10, "decision_rule": "guard_band"})
    part = small_lot["parts"] / "scratch_over"

    def run(name, **unc):
        inspect_part(part, tmp_path / name, rig, spec, uncertainty={"method": "linear", **unc})
        return json.loads((tmp_path / name / "result.json").read_text())

    default, given, zero = run("default"), run("given", light_position_tolerance_mm=0.2), \
        run("zero", light_position_tolerance_mm=0.0)
    assert default["measurement"]["uncertainty"]["light_position_u_source"] == "rig"
    assert zero["measurement"]["uncertainty"]["light_position_u_source"] == "option"
    # the largest per-coordinate u of the rig (0.2 mm) is what the budget used
    assert default["max_depth_U_mm"] == pytest.approx(given["max_depth_U_mm"], rel=1e-9)
    assert default["max_depth_U_mm"] > zero["max_depth_U_mm"]
