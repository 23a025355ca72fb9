"""photometric.errors.tolerances: worst case and its inversion into operating limits."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import rotate_lights
from tests.photometric.errors._lights import BEAR, TRIAD45, square


@pytest.mark.parametrize("moved", [(0,), (1,), (0, 1), (0, 1, 2)])
@pytest.mark.parametrize("mode", ["any", "slant", "azimuth"])
def test_tolerance_inversion_round_trips(moved, mode):
    eps, D = 0.05, 1.0
    tol = E.max_deviation(BEAR, eps, D, moved, mode, n_grid=21)
    assert not tol.saturated
    err = E.worst_case_error(BEAR, tol.value, D, moved, mode, n_grid=21)
    assert abs(err - eps) / eps < 1e-6
    # the linearised limit is close for these small angles
    assert abs(tol.first_order - tol.value) / tol.value < 0.05
    # beyond the limit the tolerance is violated, inside it is kept
    assert E.worst_case_error(BEAR, 1.01 * tol.value, D, moved, mode, n_grid=21) > eps
    assert E.worst_case_error(BEAR, 0.99 * tol.value, D, moved, mode, n_grid=21) < eps


@pytest.mark.parametrize("moved", [(0,), (1, 2)])
def test_derivative_range_inversion_round_trips(moved):
    eps, delta = 0.05, 0.7
    res = E.max_derivative_range(TRIAD45, eps, delta, moved, "any", n_grid=21)
    assert not res.saturated and res.value > 0
    err = E.worst_case_error(TRIAD45, delta, res.value, moved, "any", n_grid=21)
    assert abs(err - eps) / eps < 1e-6
    # the two inversions agree: at range D the allowed deviation is delta
    back = E.max_deviation(TRIAD45, eps, res.value, moved, "any", n_grid=21)
    assert abs(back.value - delta) / delta < 1e-6


def test_derivative_range_saturates_when_flat_surface_already_fails():
    res = E.max_derivative_range(TRIAD45, 1e-4, 5.0, (0,), "any", n_grid=11)
    assert res.saturated and res.value == 0.0


def test_max_deviation_saturates_at_the_search_limit():
    res = E.max_deviation(TRIAD45, 0.5, 0.1, (0,), "slant", n_grid=5, upper_deg=1.0)
    assert res.saturated and res.value == 1.0 and res.error < 0.5


def test_worst_direction_candidates_beat_a_fine_ring():
    # single light: the exact worst case over a fine ring of directions may not exceed the
    # first-order-optimal candidates by more than O(delta^3)
    p, q = square(1.0, 21)
    delta = 3.0
    ring = np.linspace(0, 360, 720, endpoint=False)
    angle = np.zeros((ring.size, 3))
    angle[:, 1] = delta
    direction = np.zeros((ring.size, 3))
    direction[:, 1] = ring
    ex = E.exact_error(TRIAD45, rotate_lights(TRIAD45, angle, direction), p, q)
    brute = max(np.abs(ex.dp).max(), np.abs(ex.dq).max())
    cand = E.worst_case_error(TRIAD45, delta, 1.0, (1,), "any", n_grid=21, n_directions=0)
    assert brute <= cand * (1 + 1e-3)
    assert cand <= brute * (1 + 1e-3)


def test_pair_is_stricter_than_single():
    rows = E.recommendation_table(TRIAD45, tolerances=(0.05,), ranges=(1.0,), n_grid=11)
    r = rows[0]
    assert r["all_lights_deg"] < r["pair_deg"] < r["single_light_deg"]
    tighter = E.recommendation_table(TRIAD45, tolerances=(0.02,), ranges=(2.0,), n_grid=11)[0]
    assert tighter["single_light_deg"] < r["single_light_deg"]
    # the table's single-light entry is the strictest light's max_deviation
    single = min(E.max_deviation(TRIAD45, 0.05, 1.0, (k,), "any", n_grid=11, n_directions=0).value for k in range(3))
    assert r["single_light_deg"] == pytest.approx(single, rel=1e-12)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="mode"):
        E.max_deviation(TRIAD45, 0.05, 1.0, (0,), "sideways")
    with pytest.raises(ValueError, match="lights_moved"):
        E.worst_case_error(TRIAD45, 1.0, 1.0, (5,))
    with pytest.raises(ValueError, match="tolerance"):
        E.max_deviation(TRIAD45, -0.05, 1.0)
    with pytest.raises(ValueError, match="deviation_deg"):
        E.max_derivative_range(TRIAD45, 0.05, 0.0)
