"""overlay.png: measured outlines on the shaded height and the albedo, labels with U, k and the limit, scale bars."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from photometric.defects import measure_defects
from workbench.inspect.decide import judge
from workbench.inspect.overlay import (COLOURS, REPORT_WIDTH, TEXT_PX, check_label, draw_scale_bar,
                                       imperfection_outlines, overlay_image, overlay_text, scale_bar_mm,
                                       shaded_height)
from workbench.inspect.part import inspect_part
from workbench.inspect.spec import parse_spec


@pytest.mark.parametrize("field, bar", [(60.0, 10.0), (20.0, 2.0), (3.0, 0.5), (0.9, 0.1), (120.0, 20.0)])
def test_scale_bar_is_a_round_fifth(field, bar):
    assert scale_bar_mm(field) == pytest.approx(bar)


def _defect(i, depth, center_px, axis=0.0, U=0.005):
    return {"id": i, "kind": "depression", "max_depth_mm": depth, "length_mm": 6.0, "mean_width_mm": 0.5,
            "max_width_mm": 0.5, "area_mm2": 3.0, "volume_mm3": 0.1, "axis_deg": axis, "center_px": center_px,
            "uncertainty_k2": {"max_depth_mm": U}}


def _count(pic, colour):
    return int(np.all(pic == np.array(colour, np.uint8), axis=2).sum())


def _dent_plate(n=160, h=0.05, radius_px=18.0, depth=0.1, centre=(60.0, 100.0)):
    """A tilted plane with a spherical-cap dent (closed form): height in mm, pixel size h mm."""
    rows, cols = np.mgrid[0:n, 0:n].astype(float)
    r2 = ((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2) * h * h
    a = radius_px * h  # footprint radius, mm
    R = (a * a + depth * depth) / (2 * depth)  # sphere radius
    cap = np.where(r2 < a * a, np.sqrt(np.maximum(R * R - r2, 0.0)) - (R - depth), 0.0)
    rng = np.random.default_rng(3)
    return 0.002 * cols * h - 0.001 * rows * h - cap + rng.normal(0, 2e-4, (n, n)), h


def _polygon_roundness(poly: np.ndarray) -> float:
    """Area of a polygon over the area of its smallest enclosing circle (1 for a disc, 2/pi for a square)."""
    x, y = poly[:, 0], poly[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    _, r = cv2.minEnclosingCircle(poly.astype(np.float32))
    return area / (np.pi * r * r)


def test_a_round_dent_is_outlined_round():
    """The outline is the measured region's contour: round for a spherical dent, unlike its 4-point box."""
    z, h = _dent_plate()
    defects, labels = measure_defects(z, h, return_labels=True)
    assert len(defects) == 1
    outline = imperfection_outlines(labels)[0][0]
    assert _polygon_roundness(outline) > 0.85
    spec = parse_spec({"max_depth_mm": 0.05})
    d = judge(defects, spec, z.shape, h)
    box = np.asarray(d.imperfections[0]["outline_mm"])  # what the overlay drew before: length x width
    assert _polygon_roundness(box) < 0.70
    # drawn: the red pixels of the left panel lie on a circle around the dent's centre
    pic = overlay_image(np.full(z.shape, 0.6), None, d, spec, h, height=z, labels=labels)
    assert pic.shape[1] == REPORT_WIDTH
    pw = (REPORT_WIDTH - 3 * 8) // 2
    scale = pw / z.shape[1]
    panel = pic[34 + TEXT_PX + 9:34 + TEXT_PX + 9 + pw, 8:8 + pw]
    ys, xs = np.nonzero(np.all(np.abs(panel.astype(int) - COLOURS["fail"]) < 40, axis=2))
    centre = (np.array([100.0, 60.0]) + 0.5) * scale - 0.5  # (x, y) of the dent in the panel
    ring = np.hypot(xs - centre[0], ys - centre[1])
    ring = ring[ring < 40 * scale]  # the outline, not the id beside it
    assert ring.size > 200
    assert np.std(ring) < 0.08 * np.mean(ring)
    assert abs(np.mean(ring) - 18.0 * scale) < 3.5 * scale  # the dent's radius, just outside it


def test_region_grown_outline_encloses_the_region():
    labels = np.zeros((40, 40), np.int32)
    labels[10:20, 15:18] = 1
    tight, grown = imperfection_outlines(labels)[0][0], imperfection_outlines(labels, grow=2)[0][0]
    assert tight[:, 0].min() == 15 and tight[:, 0].max() == 17 and tight[:, 1].min() == 10
    assert grown[:, 0].min() == 13 and grown[:, 0].max() == 19 and grown[:, 1].max() == 21


def test_labels_state_the_quantity_U_k_and_the_limit():
    spec = parse_spec({"max_depth_mm": 0.08, "max_count": 1, "decision_rule": "guard_band"})
    d = judge([_defect(0, 0.0991, [50, 50], U=0.0042), _defect(1, 0.0795, [150, 150], U=0.004),
               _defect(2, 0.03, [100, 150], U=0.0015)], spec, (200, 200), 0.1)
    text = overlay_text(d)
    assert text[0] == "FAIL (guard band, ISO 14253-1): decided by #0 depth, part count"
    assert "#0 FAIL  depth 0.099 +- 0.004 mm (k = 2) > 0.080 limit" in text
    assert "#1 UNCERTAIN  depth 0.080 +- 0.004 mm (k = 2) within U of 0.080 limit" in text
    assert "#2 PASS  depth 0.0300 +- 0.0015 mm (k = 2) < 0.0800 limit" in text  # two digits of a U starting in 1
    assert "part FAIL  count 3 > 1 limit" in text
    lower = {"quantity": "min_distance_mm", "value": 1.2, "U": 0.3, "limit": 2.0, "limit_kind": "min",
             "rule": "guard_band", "verdict": "fail"}
    assert check_label(lower) == "distance 1.2 +- 0.3 mm (k = 2) < 2.0 limit"
    simple = {"quantity": "area_mm2", "value": 1.234, "U": None, "limit": 2.0, "limit_kind": "max",
              "rule": "simple", "verdict": "pass"}
    assert check_label(simple) == "area 1.234 mm^2 (U not stated) <= 2.000 limit"


def test_a_decision_without_limit_or_outside_the_roi_says_so():
    spec = parse_spec({"max_count": 5, "roi_mm": [[-5, -5], [5, -5], [5, 5], [-5, 5]]})
    d = judge([_defect(0, 0.05, [100, 100], U=None), _defect(1, 0.2, [10, 10], U=None)], spec, (200, 200), 0.1)
    text = overlay_text(d)
    assert "#0 depth 0.050 mm: no limit in the spec" in text
    assert "#1 depth 0.200 mm: outside the region of interest, not decided" in text


@pytest.mark.parametrize("width, mm_per_px", [(40, 0.5), (120, 0.013), (551, 0.0363), (1100, 0.2), (60, 3.0)])
def test_scale_bar_label_lies_inside_the_panel(width, mm_per_px):
    panel = np.zeros((60, width, 3), np.uint8)
    x0, y0, x1, y1 = draw_scale_bar(panel, mm_per_px)
    assert 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= 60
    assert panel[y0:y1, x0:x1].max() == 255  # the white label is drawn inside its box


def test_shaded_height_ignores_the_tilt_and_states_its_relief():
    rows, cols = np.mgrid[0:64, 0:64].astype(float)
    plane = 0.3 * cols - 0.1 * rows  # steep, but a plane: shaded evenly, as flat (1/sqrt 2)
    shade, e = shaded_height(plane * 0.1, 0.1)
    assert np.allclose(shade, np.sqrt(0.5), atol=1e-6) and e == 1.0
    z = 1e-4 * np.random.default_rng(0).normal(size=(64, 64))
    shade, e = shaded_height(z, 0.1)
    assert e in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000) and e > 1
    assert shade.std() > 0.02  # the texture shows


def test_overlay_colours_by_verdict_on_both_panels():
    spec = parse_spec({"max_depth_mm": 0.1, "roi_mm": [[-8, -8], [8, -8], [8, 8], [-8, 8]]})
    d = judge([_defect(0, 0.2, [50, 100]), _defect(1, 0.05, [150, 100], axis=30.0)], spec, (200, 200), 0.1)
    pic = overlay_image(np.full((200, 200), 0.5), np.ones((200, 200), bool), d, spec, 0.1)
    assert pic.shape[1] == REPORT_WIDTH and pic.dtype == np.uint8
    left, right = pic[:, :REPORT_WIDTH // 2], pic[:, REPORT_WIDTH // 2:]
    for half in (left, right):  # without a label image: the 4-point box, still coloured by verdict
        assert _count(half, COLOURS["fail"]) > 50 and _count(half, COLOURS["pass"]) > 50
    assert _count(pic, COLOURS["uncertain"]) == 0


def test_result_json_holds_the_overlay_text(small_lot, tmp_path):
    spec = parse_spec({"max_depth_mm": 0.10, "max_count": 1})
    inspect_part(small_lot["parts"] / "scratch_over", tmp_path / "p", small_lot["rig"], spec)
    result = json.loads((tmp_path / "p" / "result.json").read_text())
    text = result["overlay_text"]
    assert text[0].startswith("FAIL") and any(
        line.startswith("#0 FAIL  depth ") and line.endswith("> 0.100 limit") for line in text)
    pic = cv2.imread(str(tmp_path / "p" / "overlay.png"))
    assert pic.shape[1] == REPORT_WIDTH and TEXT_PX >= 11


def test_a_tall_image_keeps_the_width_and_a_bounded_height():
    spec = parse_spec({"max_depth_mm": 0.1})
    d = judge([_defect(0, 0.2, [1500, 500])], spec, (3000, 1000), 0.02)
    pic = overlay_image(np.full((3000, 1000), 0.5, np.float32), None, d, spec, 0.02)
    pw = (REPORT_WIDTH - 3 * 8) // 2
    assert pic.shape[1] == REPORT_WIDTH and pic.shape[0] < 1.3 * pw + 200
