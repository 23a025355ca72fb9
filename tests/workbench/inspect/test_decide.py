"""Verdicts: the simple and guard_band (ISO 14253-1) rules, per imperfection and per part."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.grid import pixel_grid
from workbench.inspect.decide import center_mm, decide_value, inside_polygon, judge, outline_gap, outline_mm
from workbench.inspect.spec import parse_spec

U = {"max_depth_mm": 0.01, "length_mm": 0.2, "mean_width_mm": 0.05, "area_mm2": 0.1, "volume_mm3": 0.01}


def defect(i, depth, center_px, *, length=3.0, width=0.3, area=0.8, axis=0.0, u=U):
    d = {"id": i, "kind": "depression", "max_depth_mm": depth, "length_mm": length, "mean_width_mm": width,
         "max_width_mm": width, "area_mm2": area, "volume_mm3": 0.01, "axis_deg": axis, "center_px": center_px}
    if u is not None:
        d["uncertainty_k2"] = dict(u)
    return d


@pytest.mark.parametrize("value, U_, rule, lower, expected", [
    (0.10, None, "simple", False, "pass"),  # at the limit: conforms
    (0.1001, None, "simple", False, "fail"),
    (0.121, 0.02, "guard_band", False, "fail"),  # value - U > limit
    (0.119, 0.02, "guard_band", False, "uncertain"),
    (0.10, 0.02, "guard_band", False, "uncertain"),
    (0.081, 0.02, "guard_band", False, "uncertain"),
    (0.079, 0.02, "guard_band", False, "pass"),  # value + U < limit
    (3, 0.0, "guard_band", False, "pass"),  # exact quantity at its limit
    (4, 0.0, "guard_band", False, "fail"),
    (1.5, 0.2, "guard_band", True, "pass"),  # a lower limit (distance >= 1)
    (1.1, 0.2, "guard_band", True, "uncertain"),
    (0.7, 0.2, "guard_band", True, "fail"),
    (0.9, None, "simple", True, "fail"),
])
def test_decide_value(value, U_, rule, lower, expected):
    limit = {True: 1.0, False: 0.10}[lower] if not isinstance(value, int) else 3
    assert decide_value(value, U_, limit, rule, lower) == expected


def test_guard_band_refuses_without_U():
    with pytest.raises(ValueError, match="guard_band: the measured value has no expanded uncertainty"):
        decide_value(0.1, None, 0.1, "guard_band")
    with pytest.raises(ValueError, match="U must be a finite non-negative"):
        decide_value(0.1, -0.01, 0.1, "guard_band")
    with pytest.raises(ValueError, match="decision_rule"):
        decide_value(0.1, 0.01, 0.1, "strict")


def test_geometry_helpers_closed_forms():
    sq = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    assert outline_gap(sq, sq + [5, 0]) == pytest.approx(3.0)
    assert outline_gap(sq, sq + [5, 6]) == pytest.approx(5.0)  # corner to corner: hypot(3, 4)
    assert outline_gap(sq, sq + [1, 1]) == 0.0 and outline_gap(sq, sq + [2, 0]) == 0.0
    inside = inside_polygon([[1, 1], [3, 1], [1, -0.1], [1.9, 1.9]], sq)
    assert inside.tolist() == [True, False, False, True]
    box = outline_mm({"length_mm": 4.0, "max_width_mm": 1.0, "axis_deg": 90.0}, [1.0, 2.0])
    np.testing.assert_allclose(np.sort(box[:, 0]), [0.5, 0.5, 1.5, 1.5], atol=1e-12)
    np.testing.assert_allclose(np.sort(box[:, 1]), [0, 0, 4, 4], atol=1e-12)


def test_center_from_pixels_follows_the_grid_convention():
    x, y = pixel_grid((5, 7), 0.5)
    assert center_mm({"center_px": [1.0, 6.0]}, (5, 7), 0.5).tolist() == [x[1, 6], y[1, 6]]
    assert center_mm({"center_px": [0, 0], "center_mm": [3.0, 4.0]}, (5, 7), 0.5).tolist() == [3.0, 4.0]


def test_judge_per_imperfection_and_per_part():
    # 101 x 101 px of 0.1 mm: pixel (50, 50) is the origin, y up
    spec = parse_spec({"max_depth_mm": 0.1, "max_length_mm": 5.0, "max_count": 2, "max_total_area_mm2": 3.0,
                       "min_distance_mm": 1.0, "decision_rule": "guard_band",
                       "roi_mm": [[-4, -4], [4, -4], [4, 4], [-4, 4]],
                       "exclusion_zones_mm": [[[2, 2], [4, 2], [4, 4], [2, 4]]]})
    defects = [defect(0, 0.13, [50, 50]),                    # fails (0.13 - 0.01 > 0.1)
               defect(1, 0.105, [30, 50]),                   # uncertain, 2 mm above the first
               defect(2, 0.5, [20, 80]),                     # centre (3, 3) in the exclusion zone
               defect(3, 0.5, [50, 95], length=1.0)]         # centre (4.5, 0) outside the ROI
    d = judge(defects, spec, (101, 101), 0.1)
    regions = [r["region"] for r in d.imperfections]
    assert regions == ["inspected", "inspected", "excluded", "outside_roi"]
    assert [r["verdict"] for r in d.imperfections] == ["fail", "uncertain", None, None]
    assert d.imperfections[2]["checks"] == [] and d.imperfections[0]["values"]["max_depth_mm"] == {
        "value": 0.13, "U": 0.01}
    checks = {c["quantity"]: c for c in d.part_checks}
    assert checks["count"]["value"] == 2 and checks["count"]["verdict"] == "pass"
    assert checks["total_area_mm2"]["value"] == pytest.approx(1.6) and checks["total_area_mm2"]["U"] == 0.2
    # two 3 mm x 0.3 mm boxes along x, 2 mm apart centre to centre: gap 2 - 0.3
    assert checks["min_distance_mm"]["value"] == pytest.approx(1.7)
    assert checks["min_distance_mm"]["U"] == pytest.approx(0.2) and checks["min_distance_mm"]["limit_kind"] == "min"
    assert d.verdict == "fail" and d.decided_by == ["imperfection 0 max_depth_mm"]
    assert all(c["rule"] == "guard_band" for r in d.imperfections for c in r["checks"])


def test_part_level_limits_decide():
    spec = parse_spec({"max_count": 1, "min_distance_mm": 2.5})
    d = judge([defect(0, 0.05, [50, 50], u=None), defect(1, 0.05, [30, 50], u=None)], spec, (101, 101), 0.1)
    assert d.verdict == "fail" and d.decided_by == ["part count", "part min_distance_mm"]
    clean = judge([], spec, (101, 101), 0.1)
    assert clean.verdict == "pass" and clean.decided_by == [] and [c["quantity"] for c in clean.part_checks] == [
        "count"]


def test_guard_band_refuses_an_imperfection_without_U():
    spec = parse_spec({"max_depth_mm": 0.1, "decision_rule": "guard_band"})
    with pytest.raises(ValueError, match="guard_band: imperfection 0 max_depth_mm has no expanded uncertainty"):
        judge([defect(0, 0.05, [50, 50], u=None)], spec, (101, 101), 0.1)
    # simple decides without U, and records that none was stated
    d = judge([defect(0, 0.05, [50, 50], u=None)], parse_spec({"max_depth_mm": 0.1}), (101, 101), 0.1)
    assert d.verdict == "pass" and d.imperfections[0]["values"]["max_depth_mm"]["U"] is None
    with pytest.raises(ValueError, match="guard_band: part total_area_mm2 has no expanded uncertainty"):
        judge([defect(0, 0.05, [50, 50], u={"max_depth_mm": 0.01})],
              parse_spec({"max_total_area_mm2": 1.0, "decision_rule": "guard_band"}), (101, 101), 0.1)
