"""photometric.errors.maps: error maps over two deviations and error curves."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import deviate_lights
from tests.photometric.errors._lights import TRIAD45, square


def test_error_map_matches_direct_evaluation():
    p, q = square(1.0, 11)
    m = E.error_map(TRIAD45, p, q, (0, "slant"), (2, "azimuth"), deviation_max=4.0, n=9)
    assert m.max_dp.shape == (9, 9)
    assert m.max_dp[4, 4] < 1e-13 and m.max_dq[4, 4] < 1e-13  # centre: no deviation
    i, j = 7, 2  # row i -> axis2 value, column j -> axis1 value
    dev = np.zeros((3, 2))
    dev[0, 0], dev[2, 1] = m.dev1_deg[j], m.dev2_deg[i]
    ex = E.exact_error(TRIAD45, deviate_lights(TRIAD45, dev), p, q)
    assert m.max_dp[i, j] == pytest.approx(np.abs(ex.dp).max(), rel=1e-12)
    assert m.mean_dq[i, j] == pytest.approx(np.abs(ex.dq).mean(), rel=1e-12)
    assert m.max_angle_deg[i, j] == pytest.approx(ex.angle_deg.max(), rel=1e-9)


def test_error_map_lit_only_uses_fewer_normals():
    p, q = square(2.0, 21)
    full = E.error_map(TRIAD45, p, q, n=5)
    lit = E.error_map(TRIAD45, p, q, n=5, lit_only=True)
    assert lit.n_normals < full.n_normals
    assert np.all(lit.max_dp <= full.max_dp + 1e-15)


def test_error_map_bad_axes():
    with pytest.raises(ValueError, match="axis2"):
        E.error_map(TRIAD45, 0.0, 0.0, (0, "slant"), (1, "tilt"))
    with pytest.raises(ValueError, match="must differ"):
        E.error_map(TRIAD45, 0.0, 0.0, (0, "slant"), (0, "slant"))
    with pytest.raises(ValueError, match="axis1"):
        E.error_map(TRIAD45, 0.0, 0.0, (3, "slant"), (0, "azimuth"))


def test_error_curves_first_order_tangent():
    c = E.error_curves(TRIAD45, [0.0, 1.0], light=0, deviation_max=2.0, n=41)
    assert c["dp"].shape == (41, 2)
    mid = 20
    assert np.abs(c["dp"][mid]).max() < 1e-14
    slope_exact = (c["dq"][mid + 1] - c["dq"][mid - 1]) / (c["deviation_deg"][mid + 1] - c["deviation_deg"][mid - 1])
    slope_lin = (c["dq_first_order"][mid + 1] - c["dq_first_order"][mid - 1]) / (
        c["deviation_deg"][mid + 1] - c["deviation_deg"][mid - 1]
    )
    np.testing.assert_allclose(slope_exact, slope_lin, rtol=1e-3)


def test_error_curves_match_the_exact_model():
    c = E.error_curves(TRIAD45, [0.5], light=1, kind="azimuth", deviation_max=3.0, n=7, slope_direction_deg=90.0)
    dev = np.zeros((3, 2))
    dev[1, 1] = c["deviation_deg"][1]
    ex = E.exact_error(TRIAD45, deviate_lights(TRIAD45, dev), 0.0, 0.5)  # gradient along +y
    assert c["dp"][1, 0] == pytest.approx(float(ex.dp), abs=1e-15)
    assert c["dq"][1, 0] == pytest.approx(float(ex.dq), abs=1e-15)
