"""workbench.studies.errors_markdown: the text of report.md."""

from __future__ import annotations

import pytest

from photometric.lights import ring_lights
from workbench.studies.errors_analysis import analyse
from workbench.studies.errors_markdown import markdown


@pytest.fixture(scope="module")
def report():
    return analyse(ring_lights(3, 45.0), deviation_max=2.0, grid=7, samples=200, crack_size=40)


def _pictures(report):
    return {"maps": [f"m{i}.png" for i in range(len(report["error_maps"]))], "curves": "c.png",
            "mc": ["h.png", "e.png"], "condition": "k.png", "crack": "crack.png"}


def test_tables_hold_the_numbers(report):
    text = markdown(report, _pictures(report))
    assert text.startswith("# Accuracy of photometric stereo") and text.endswith("\n")
    # one row per recommendation, with the report's own numbers
    for r in report["recommendation_table"]:
        assert (f"| {r['derivative_range']:g} | {r['tolerance']:g} | {r['single_light_deg']:.3g} "
                f"({r['single_light_first_order_deg']:.3g}) |") in text
    for r in report["tolerances"]:
        assert f"| {', '.join(map(str, r['lights']))} | {r['slant']['value']:.3g} |" in text
    assert "| 1 | 0.0000 | 0.7071 | 0.7071 | 45.00 | 90.00 |" in text.replace("-0.0000", "0.0000")


def test_every_picture_is_linked(report):
    pictures = _pictures(report)
    text = markdown(report, pictures)
    for name in [*pictures["maps"], "c.png", "h.png", "e.png", "k.png", "crack.png"]:
        assert f"({name})" in text
    assert "## Crack study" in text and "## The given surface" not in text


def test_saturated_limits_are_marked(report):
    rep = dict(report)
    rep["tolerances"] = [{"lights": [1], "slant": {"value": 30.0, "saturated": True},
                          "azimuth": {"value": 0.0, "saturated": True}, "any": {"value": 1.5, "saturated": False}}]
    text = markdown(rep, _pictures(report))
    assert "| 1 | >= 30 | 0 (a flat surface already exceeds eps) | 1.5 |" in text
