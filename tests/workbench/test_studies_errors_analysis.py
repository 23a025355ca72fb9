"""workbench.studies.errors_analysis: the accuracy study as numbers, against the library."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import deviate_lights, ring_lights
from workbench.studies.errors_analysis import analyse

LIGHTS = ring_lights(3, 45.0)


@pytest.fixture(scope="module")
def report():
    stages = []
    rows, cols = np.mgrid[0:20, 0:24]
    surface = 0.1 * np.exp(-((rows - 10) ** 2 + (cols - 12) ** 2) / 30.0)
    rep = analyse(LIGHTS, deviation_max=3.0, derivative_range=1.0, tolerance=0.05, surface=surface,
                  pixel_size=0.1, grid=9, samples=400, crack_size=48, progress=stages.append)
    return rep, stages, surface


def test_stages_and_sections(report):
    rep, stages, _ = report
    assert stages == ["configuration", "sensitivity", "error maps", "curves", "tolerances", "Monte Carlo",
                      "surface height error", "crack study"]
    for key in ("convention", "inputs", "configuration", "sensitivity_per_deg", "error_maps", "error_curves",
                "tolerances", "derivative_range_limits", "recommendation_table", "monte_carlo",
                "surface_height_error", "crack_study", "_arrays"):
        assert key in rep
    assert {m["derivatives"] for m in rep["error_maps"]} == {"square", "surface", "crack"}


def test_numbers_are_the_library_numbers(report):
    rep, _, surface = report
    assert rep["inputs"]["slant_deg"] == pytest.approx([45.0] * 3)
    assert rep["inputs"]["azimuth_deg"] == pytest.approx([90.0, -150.0, -30.0])
    assert rep["configuration"]["condition_number"] == pytest.approx(np.sqrt(2.0), rel=1e-12)
    direct = E.max_deviation(LIGHTS, 0.05, 1.0, (1,), "slant", n_grid=9)
    row = rep["tolerances"][1]
    assert row["lights"] == [2] and row["slant"]["value"] == pytest.approx(direct.value, rel=1e-12)
    p, q = E.derivative_square(1.0, 9)
    sq = rep["error_maps"][0]
    m = E.error_map(LIGHTS, p, q, tuple(sq["axis1"]), tuple(sq["axis2"]), 3.0, 9)
    assert sq["max_abs_dp"] == pytest.approx(float(m.max_dp.max()), rel=1e-12)
    dev = np.zeros((3, 2))
    dev[0, 0] = 1.0
    he = E.height_error(LIGHTS, deviate_lights(LIGHTS, dev), surface, 0.1)
    assert rep["surface_height_error"][0]["rms_dh_mm"] == pytest.approx(he["rms_dh_mm"], rel=1e-12)
    J = E.sensitivity(LIGHTS, p, q)
    sens = rep["sensitivity_per_deg"]["light1_slant"]["max_dq_per_deg"]
    assert sens == pytest.approx(np.radians(1.0) * np.abs(J[..., 1, 0, 0]).max(), rel=1e-12)


def test_first_order_check_and_monte_carlo_are_consistent(report):
    rep, _, _ = report
    assert max(rep["first_order_relative_difference_at_2deg"].values()) < 0.05
    flat = rep["monte_carlo"]["normals"][0]
    assert flat["p"] == 0.0 and flat["q"] == 0.0
    assert flat["std"] == pytest.approx(flat["std_first_order"], rel=0.15)
    probs = rep["monte_carlo"]["exceedance"]["probability_over_tolerance"]
    assert probs[0] == 0.0 and np.all(np.diff(probs) >= 0)


def test_crack_part(report):
    rep, _, _ = report
    cs = rep["crack_study"]
    assert cs["size_px"] == 48 and "maps" not in cs
    assert [c["deviations_deg"][0][0] for c in cs["cases"]] == [0.0, 1.0, 2.0, 3.0]
    assert rep["_arrays"]["crack"]["dp_measured"].shape == (4, 48, 48)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"grid": 3}, "grid"), ({"tolerance": 0.0}, "tolerance"), ({"sigma_deg": -1.0}, "sigma_deg")],
)
def test_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        analyse(LIGHTS, crack=False, **kwargs)
    with pytest.raises(ValueError, match="coplanar"):
        analyse([[1, 0, 0], [0, 1, 0], [0.6, 0.8, 0]], crack=False)
