"""overlay.png: outlines coloured by verdict, labels, scale bar; shrunk to MAX_SIDE."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.inspect.decide import judge
from workbench.inspect.overlay import COLOURS, overlay_image, scale_bar_mm
from workbench.inspect.spec import parse_spec


@pytest.mark.parametrize("field, bar", [(60.0, 10.0), (20.0, 2.0), (3.0, 0.5), (0.9, 0.1), (120.0, 20.0)])
def test_scale_bar_is_a_round_fifth(field, bar):
    assert scale_bar_mm(field) == pytest.approx(bar)


def _defect(i, depth, center_px, axis=0.0):
    return {"id": i, "kind": "depression", "max_depth_mm": depth, "length_mm": 6.0, "mean_width_mm": 0.5,
            "max_width_mm": 0.5, "area_mm2": 3.0, "volume_mm3": 0.1, "axis_deg": axis, "center_px": center_px,
            "uncertainty_k2": {"max_depth_mm": 0.005}}


def _count(pic, colour):
    return int(np.all(pic == np.array(colour, np.uint8), axis=2).sum())


def test_overlay_colours_by_verdict():
    spec = parse_spec({"max_depth_mm": 0.1, "roi_mm": [[-8, -8], [8, -8], [8, 8], [-8, 8]]})
    d = judge([_defect(0, 0.2, [50, 100]), _defect(1, 0.05, [150, 100], axis=30.0)], spec, (200, 200), 0.1)
    albedo = np.full((200, 200), 0.5)
    pic = overlay_image(albedo, np.ones((200, 200), bool), d, spec, 0.1)
    assert pic.shape == (200, 200, 3) and pic.dtype == np.uint8
    assert _count(pic, COLOURS["fail"]) > 50 and _count(pic, COLOURS["pass"]) > 50
    assert _count(pic, COLOURS["uncertain"]) == 0
    top, bottom = pic[:100], pic[100:]
    # the failing outline (row 50) is red in the top half, the passing one green below
    assert _count(top[20:], COLOURS["fail"]) > 30 and _count(bottom, COLOURS["pass"]) > 30
    assert _count(bottom, COLOURS["fail"]) == 0
    # the scale bar: white pixels in the bottom-left corner on the grey albedo
    assert _count(pic[-30:, :60], (255, 255, 255)) > 20


def test_overlay_shrinks_large_images():
    d = judge([], parse_spec({"max_depth_mm": 0.1}), (3000, 2000), 0.02)
    pic = overlay_image(np.random.default_rng(0).random((3000, 2000), np.float32), np.ones((3000, 2000), bool),
                        d, parse_spec({"max_depth_mm": 0.1}), 0.02, max_side=600)
    assert pic.shape == (600, 400, 3)
    assert _count(pic[:60, :200], COLOURS["pass"]) > 20  # the verdict in the corner
