"""workbench.studies.crack: the rendered crack against the exact error model."""

from __future__ import annotations

import numpy as np
import pytest

from photometric.lights import ring_lights
from workbench.studies.crack import crack_study, plane_depth

LIGHTS = ring_lights(3, 45.0)


def test_plane_depth_closed_form():
    rows, cols = np.mgrid[0:12, 0:15]
    z = 0.02 * cols - 0.03 * rows + 1.0
    mask = (np.abs(rows - 6) <= 1) & (np.abs(cols - 7) <= 2)
    z[mask] -= np.array([0.1, 0.3, 0.2] * 5)[: mask.sum()]
    assert plane_depth(z, mask) == pytest.approx(0.3, abs=1e-12)
    with pytest.raises(ValueError, match="defect_mask"):
        plane_depth(z, np.zeros(z.shape, bool))


def test_measured_error_equals_the_prediction():
    dev = np.zeros((3, 3, 2))
    dev[1, 0, 0] = 2.0
    dev[2, 1, 1] = -2.0
    cs = crack_study(LIGHTS, dev, size=64, pixel_size=0.05)
    nominal, slant, azimuth = cs["cases"]
    # no deviation: only the float32 rounding of the solver
    assert nominal["max_abs_dp_measured"] < 1e-3 and nominal["max_abs_dp_predicted"] < 1e-12
    assert nominal["depth_change_mm"] == pytest.approx(0.0, abs=1e-12)
    for c in (slant, azimuth):
        assert c["max_abs_dq_measured"] > 1e-3
        assert c["max_abs_diff_measured_predicted"] < 1e-4
        assert c["max_abs_dq_first_order"] == pytest.approx(c["max_abs_dq_predicted"], rel=0.1)
    assert abs(nominal["depth_error_mm"]) < 0.3 * cs["true_depth_mm"]
    maps = cs["maps"]
    assert maps["dq_measured"].shape == (3, 64, 64) and maps["lit"].dtype == bool
    lit = maps["lit"]
    np.testing.assert_allclose(maps["dq_measured"][1][lit], maps["dq_predicted"][1][lit], atol=1e-4)
    assert np.isnan(maps["dq_measured"][1][~lit]).all()


def test_bad_input():
    with pytest.raises(ValueError, match="deviations_deg"):
        crack_study(LIGHTS, np.zeros((2, 2, 2)), size=32)
    with pytest.raises(ValueError, match="no defect"):
        crack_study(LIGHTS, np.zeros((1, 3, 2)), size=32, scene="sphere")
