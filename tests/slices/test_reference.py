"""The smoothing B-spline reference (seed 000, ref. [5]): near the data, but not through it."""

from __future__ import annotations

import numpy as np
import pytest

from slices.io import Contour
from slices.reference import SMOOTH_MM, compare, deviation_at_points, smoothing_surface
from slices.structure import reconstruct_contours
from tests.slices._stacks import circle


def test_smoothing_surface_of_a_cylinder_keeps_near_the_circle():
    conts = [circle(0, 0, 10, 64)] * 5
    grid = smoothing_surface(conts, np.arange(5.0), n_u=128)
    assert grid.shape == (5, 128, 2)
    # the same section on every plane, within the smoothing target of the circle (it does not interpolate)
    np.testing.assert_allclose(grid, np.broadcast_to(grid[0], grid.shape), atol=1e-9)
    dev = deviation_at_points(conts, np.arange(5.0), grid)
    assert 0.5 * SMOOTH_MM < np.sqrt(np.mean(dev**2)) <= SMOOTH_MM
    assert np.abs(np.linalg.norm(grid, axis=2) - 10.0).max() < 2 * SMOOTH_MM


def test_smoothing_spreads_noise_instead_of_passing_through_it():
    rng = np.random.default_rng(4)
    conts = [circle(0, 0, 10, 64) + rng.normal(0, 0.3, (64, 2)) for _ in range(6)]
    grid = smoothing_surface(conts, np.arange(6.0) * 2.0, n_u=256)
    dev = deviation_at_points(conts, np.arange(6.0), grid)
    assert dev.shape == (6 * 64,)
    # about the noise level: the RMS target of each contour spline, not zero
    assert 0.5 * SMOOTH_MM < np.sqrt(np.mean(dev**2)) < 2 * SMOOTH_MM
    assert np.abs(np.linalg.norm(grid, axis=2) - 10.0).mean() < 0.2


def test_deviation_of_points_on_the_section_is_zero():
    square = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    on = np.array([[2, 0], [4, 1], [1, 4]], float)
    off = np.array([[2, 1]], float)
    grid = square[None]
    np.testing.assert_allclose(deviation_at_points([on], [0.0], grid), 0.0, atol=1e-12)
    assert deviation_at_points([off], [0.0], grid)[0] == pytest.approx(1.0)
    assert deviation_at_points([], [], np.zeros((0, 4, 2))).shape == (0,)


def test_compare_reports_both_surfaces():
    conts = [Contour(z, circle(0, 0, 10, 48) * (1 + 0.02 * z)) for z in (0.0, 2.0, 4.0, 6.0)]
    rec = reconstruct_contours(conts, mesh=False)
    out = compare(rec)
    assert out["smooth_mm"] == SMOOTH_MM
    assert out["ours_max_control_point_deviation_mm"] == rec.max_deviation_mm < 1e-9
    assert 0 < out["mean_control_point_deviation_mm"] <= out["max_control_point_deviation_mm"] < 0.5
    single = reconstruct_contours([Contour(0.0, circle(0, 0, 10))], spacing=2.0, caps="half", mesh=False)
    assert compare(single)["max_control_point_deviation_mm"] is None  # no body with two slices
