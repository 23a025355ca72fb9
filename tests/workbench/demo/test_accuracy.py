"""Demo section 2 (light-deviation accuracy) on its reduced (--quick) grids."""

from __future__ import annotations

import numpy as np
import pytest

from photometric.io import load_lights
from photometric.lights import ring_lights
from workbench.demo.accuracy import RANGES, TOLERANCES, section_accuracy

from .test_context import parses, quick_context


@pytest.fixture(scope="module")
def accuracy(tmp_path_factory):
    ctx = quick_context(tmp_path_factory.mktemp("accuracy"))
    section_accuracy(ctx)
    return ctx


def test_numbers(accuracy):
    nums = accuracy.numbers["accuracy"]
    table = nums["recommendation"]
    assert len(table) == len(TOLERANCES) * len(RANGES)
    assert {(r["derivative_range"], r["tolerance"]) for r in table} == {
        (d, t) for d in RANGES for t in TOLERANCES}
    # a looser tolerance allows a larger deviation of one light
    for d in RANGES:
        allowed = [r["single_light_deg"] for r in sorted(table, key=lambda r: r["tolerance"])
                   if r["derivative_range"] == d]
        assert np.all(np.diff(allowed) >= 0)
    # both maps reach the corner of +-5 deg: errors of a few hundredths, a few degrees of normal
    for key in ("slant1_slant2", "slant1_azimuth1"):
        assert 0.01 < nums[f"max_derivative_error_at_5deg_{key}"] < 1.0
        assert 1.0 < nums[f"max_angle_error_at_5deg_{key}_deg"] < 20.0
    for case in nums["crack_study"]["cases"]:
        assert case["max_abs_diff_measured_predicted"] < 1e-3
    assert nums["condition_number"] >= 1.0


def test_lights_file_and_commands(accuracy):
    lights = load_lights(accuracy.out / "accuracy" / "lights.txt")
    np.testing.assert_allclose(lights, ring_lights(3, 45.0), atol=1e-9)
    assert [f.file for f in accuracy.report.figures] == ["figures/accuracy-maps.png",
                                                        "figures/accuracy-crack.png"]
    assert all(parses(f.command) for f in accuracy.report.figures)
    assert "--grid 21" in accuracy.report.figures[0].command
