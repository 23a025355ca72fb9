"""Parameters, knot vectors and knot insertion (surfaces.knots) against The NURBS Book and scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from surfaces.bezier import bernstein
from surfaces.knots import (
    METHODS,
    averaged_knots,
    bezier_pieces,
    check_degree,
    chord_lengths,
    cubic_pieces,
    data_parameters,
    interpolation_knots,
    periodic_knots,
    span_parameters,
    to_knot_domain,
)

EXAMPLE_9_1 = np.array([[(0, 0), (3, 4), (-1, 4), (-4, 0), (-4, -3)]], dtype=float)


def test_chord_lengths_along_any_axis():
    """Example 9.1's chords 5, 4, 5, 3, and the closing chord |(-4, -3)| = 5 when closed."""
    np.testing.assert_allclose(chord_lengths(EXAMPLE_9_1[0]), [5, 4, 5, 3])
    np.testing.assert_allclose(chord_lengths(EXAMPLE_9_1[0], closed=True), [5, 4, 5, 3, 5])
    grid = np.stack([EXAMPLE_9_1[0], 2 * EXAMPLE_9_1[0]], axis=1)  # (5, 2, 2): two lines along axis 0
    np.testing.assert_allclose(chord_lengths(grid, 0), [[5, 10], [4, 8], [5, 10], [3, 6]])
    np.testing.assert_allclose(chord_lengths(grid, 1), np.linalg.norm(EXAMPLE_9_1[0], axis=1)[:, None])
    np.testing.assert_allclose(chord_lengths(grid, 1, closed=True),
                               np.repeat(np.linalg.norm(EXAMPLE_9_1[0], axis=1)[:, None], 2, axis=1))


def test_example_9_1_parameters_and_knots():
    """The NURBS Book Example 9.1: chords 5, 4, 5, 3; centripetal uses their square roots."""
    np.testing.assert_allclose(data_parameters(EXAMPLE_9_1, "chord"), np.array([0, 5, 9, 14, 17]) / 17)
    np.testing.assert_allclose(data_parameters(EXAMPLE_9_1, "uniform"), [0, 0.25, 0.5, 0.75, 1])
    root = np.sqrt([5.0, 4.0, 5.0, 3.0])
    np.testing.assert_allclose(data_parameters(EXAMPLE_9_1, "centripetal"),
                               np.concatenate([[0], np.cumsum(root)]) / root.sum())
    u = data_parameters(EXAMPLE_9_1, "chord")
    np.testing.assert_allclose(averaged_knots(u, 3), [0, 0, 0, 0, 28 / 51, 1, 1, 1, 1], atol=1e-15)
    np.testing.assert_array_equal(interpolation_knots(u, 3, False), averaged_knots(u, 3))
    assert set(METHODS) == {"uniform", "chord", "centripetal"}


def test_closed_parameters_and_periodic_knots():
    square = np.array([[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]])
    u = data_parameters(square, "chord", closed=True)
    np.testing.assert_allclose(u, [0, 0.25, 0.5, 0.75])
    for p in (2, 3):
        k = periodic_knots(u, p)
        assert len(k) == len(u) + 2 * p + 1
        # period-1 spacing: the knots repeat shifted by one period
        np.testing.assert_allclose(k[len(u):] - k[:-len(u)], 1.0)
        np.testing.assert_array_equal(interpolation_knots(u, p, True), k)
    np.testing.assert_allclose(periodic_knots(u, 3)[3:7], u)  # odd degree: knots at the parameters
    np.testing.assert_allclose(periodic_knots(u, 2)[2:6], u - 0.125)  # even degree: at the midpoints


def test_pole_lines_are_left_out_of_the_average():
    lines = np.stack([np.zeros((4, 3)), np.array([[0, 0, 0], [1, 0, 0], [3, 0, 0], [4, 0, 0.0]])])
    np.testing.assert_allclose(data_parameters(lines), [0, 0.25, 0.75, 1])
    with pytest.raises(ValueError, match="every line has zero length"):
        data_parameters(np.zeros((2, 4, 3)))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(method="arc"), "method: expected one of"),
        (dict(params=[0.0, 0.5, 0.4, 0.9, 1.0]), "params: must be strictly increasing"),
        (dict(params=[0.1, 0.2, 0.3, 0.4, 1.0]), "params: open parameters must run from 0 to 1"),
        (dict(params=[0.0, 0.2, 0.3, 0.4, 1.0], closed=True), "params: closed parameters"),
    ],
)
def test_parameter_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        data_parameters(EXAMPLE_9_1, **kwargs)


def test_repeated_points_are_named():
    repeated = np.array([[[0.0, 0], [1, 0], [1, 0], [2, 0]]])
    with pytest.raises(ValueError, match="points: rows 1 and 2 coincide"):
        data_parameters(repeated, what="rows")


def test_check_degree():
    assert check_degree(np.int64(4)) == 4
    for bad in (1, 6, 2.0, True):
        with pytest.raises(ValueError, match="degree_u: expected an integer from 2 to 5"):
            check_degree(bad, "degree_u")


@pytest.mark.parametrize("degree", [2, 3, 4, 5])
def test_bezier_pieces_reproduce_the_spline(degree):
    """Knot insertion: every Bezier piece evaluates to the B-spline on its span (scipy as the peer)."""
    rng = np.random.default_rng(degree)
    n = degree + 6
    knots = np.concatenate([np.zeros(degree), np.sort(rng.uniform(0, 1, n - degree + 1)), np.ones(degree)])
    knots[degree], knots[n] = 0.0, 1.0
    control = rng.normal(size=(n, 3))
    pieces = bezier_pieces(knots, degree, control)
    breaks = np.unique(knots[degree : n + 1])
    assert pieces.shape == (len(breaks) - 1, degree + 1, 3)
    spline = BSpline(knots, control, degree)
    from math import comb

    t = np.linspace(0, 1, 7)
    basis = np.stack([comb(degree, a) * t**a * (1 - t) ** (degree - a) for a in range(degree + 1)], 1)
    for s, piece in enumerate(pieces):
        x = breaks[s] + t * (breaks[s + 1] - breaks[s])
        np.testing.assert_allclose(basis @ piece, spline(x), atol=1e-12)
    idx, local = span_parameters(knots, degree, x)
    assert np.all(idx == len(pieces) - 1) and np.allclose(local, t)


def test_cubic_pieces_elevate_quadratics_exactly():
    knots = np.array([0, 0, 0, 0.4, 1, 1, 1.0])
    control = np.array([[0.0], [1.0], [3.0], [2.0]])
    cubic = cubic_pieces(knots, 2, control)
    assert cubic.shape == (2, 4, 1)
    t = np.linspace(0, 1, 5)
    spline = BSpline(knots, control, 2)
    np.testing.assert_allclose(bernstein(t) @ cubic[1], spline(0.4 + 0.6 * t), atol=1e-12)
    with pytest.raises(ValueError, match="exact only for degree 2"):
        cubic_pieces(np.concatenate([np.zeros(5), np.ones(5)]), 4, np.zeros((5, 1)))


def test_to_knot_domain_wraps_by_one_period():
    knots = periodic_knots(np.array([0.0, 0.3, 0.6, 0.8]), 3)
    x = to_knot_domain(np.array([-0.5, 0.0, 0.25, 1.0, 2.75]), knots, 3)
    assert np.all((x >= knots[3]) & (x < knots[3] + 1))
    np.testing.assert_allclose(np.mod(x, 1.0), np.mod([-0.5, 0.0, 0.25, 1.0, 2.75], 1.0), atol=1e-15)
