"""Curves (surfaces.curves): analytic curves, callables and curve files, against closed forms."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surfaces.curves import (
    ParametricCurve,
    as_3d,
    as_curve,
    circle,
    helix,
    line,
    load_curve,
    parameters,
    thread_profile,
)


T = np.linspace(0.0, 1.0, 9)


@pytest.mark.parametrize(
    "spec, expected",
    [
        ({"type": "circle", "radius": 2.0},
         lambda t: np.stack([2 * np.cos(2 * np.pi * t), 2 * np.sin(2 * np.pi * t)], 1)),
        ({"type": "circle", "radius": 1.0, "center": [1, 2, 3], "normal": [0, 0, 5]},
         lambda t: np.stack([1 + np.cos(2 * np.pi * t), 2 + np.sin(2 * np.pi * t), np.full_like(t, 3.0)], 1)),
        ({"type": "line", "start": [0, 0, 0], "end": [1, 2, 3]}, lambda t: np.outer(t, [1, 2, 3])),
        ({"type": "helix", "radius": 1.0, "pitch": 0.5, "turns": 2},
         lambda t: np.stack([np.cos(4 * np.pi * t), np.sin(4 * np.pi * t), t], 1)),
        # a quadratic Bezier given as a clamped B-spline: (1-t)^2 P0 + 2t(1-t) P1 + t^2 P2
        ({"type": "bspline", "control": [[0, 0], [1, 1], [2, 0]], "knots": [0, 0, 0, 1, 1, 1], "degree": 2},
         lambda t: np.stack([2 * t, 2 * t * (1 - t)], 1)),
    ],
)
def test_load_curve_formats(spec, expected, tmp_path):
    """Every analytic format evaluates to its closed form."""
    path = tmp_path / "c.json"
    path.write_text(json.dumps(spec))
    np.testing.assert_allclose(load_curve(path).evaluate(T), expected(T), atol=1e-12)


@pytest.mark.parametrize(
    "points, closed",
    [([[0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 1]], False), ([[1, 0], [0, 1], [-1, 0], [0, -1]], True)],
)
def test_load_curve_interpolates_points(points, closed):
    """A points curve passes through its points at its parameters (and closes when asked)."""
    curve = load_curve({"points": points, "degree": 3 if not closed else 2, "closed": closed})
    np.testing.assert_allclose(curve.evaluate(curve.params), points, atol=1e-12)
    assert curve.closed == closed
    if closed:
        np.testing.assert_allclose(curve.evaluate([0.0]), curve.evaluate([1.0]), atol=1e-12)


@pytest.mark.parametrize(
    "spec, message",
    [
        ({"type": "spiral"}, "unknown curve type"),
        ({"type": "circle"}, "needs the field 'radius'"),
        ({"type": "circle", "radius": -1}, "radius"),
        ({"type": "bspline", "control": [[0, 0], [1, 1], [2, 0]], "knots": [0, 1]}, "knots"),
    ],
)
def test_load_curve_errors(spec, message):
    with pytest.raises(ValueError, match=message):
        load_curve(spec)


def test_load_curve_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_curve(tmp_path / "none.json")


@pytest.mark.parametrize("curve", [circle(1.5), helix(2.0, 0.7, 1.5), thread_profile(1.0, 0.3, 0.5),
                                   circle(1.0, (0.0, 0.0, 1.0), (1.0, 1.0, 0.0))])
def test_exact_derivatives_match_differences(curve):
    t = np.linspace(0.1, 0.9, 7)
    h = 1e-5
    for order in (1, 2):
        lower = curve.derivative(t - h, order - 1) if order > 1 else curve.evaluate(t - h)
        upper = curve.derivative(t + h, order - 1) if order > 1 else curve.evaluate(t + h)
        np.testing.assert_allclose(curve.derivative(t, order), (upper - lower) / (2 * h), rtol=1e-6, atol=1e-6)


def test_circle_and_thread_profile_closed_forms():
    c = circle(2.0, (1.0, 1.0, 1.0), (0.0, 0.0, 1.0))
    pts = c.evaluate(T)
    np.testing.assert_allclose(np.linalg.norm(pts - 1.0, axis=1), 2.0, atol=1e-12)
    np.testing.assert_allclose(pts[:, 2], 1.0, atol=1e-12)
    assert c.closed
    prof = thread_profile(1.0, 0.3, 0.5).evaluate([0.0, 0.5, 1.0])
    np.testing.assert_allclose(prof, [[1.0, 0.0], [1.3, 0.25], [1.0, 0.5]], atol=1e-12)
    with pytest.raises(ValueError, match="normal: must not be the zero vector"):
        circle(1.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


def test_callables_use_finite_differences():
    """A callable without derivatives gets central differences (error O(h^2))."""
    parabola = as_curve(lambda t: np.stack([t, t * t], axis=1))
    assert isinstance(parabola, ParametricCurve)
    np.testing.assert_allclose(parabola.derivative(T, 1), np.stack([np.ones_like(T), 2 * T], 1), atol=1e-8)
    np.testing.assert_allclose(parabola.derivative(T, 2), np.tile([0.0, 2.0], (len(T), 1)), atol=1e-5)
    with pytest.raises(ValueError, match="orders 1 and 2"):
        parabola.derivative(T, 3)
    with pytest.raises(ValueError, match="curve: expected"):
        as_curve(3.0)


def test_parameters_and_as_3d():
    assert parameters(0.25).tolist() == [0.25]
    with pytest.raises(ValueError, match="t:"):
        parameters(np.zeros((2, 2)))
    np.testing.assert_array_equal(as_3d(np.array([[1.0, 2.0]])), [[1.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match="directrix: expected 2D or 3D"):
        as_3d(np.zeros((2, 4)), "directrix")
    np.testing.assert_allclose(line([0, 0], [2, 4]).evaluate([0.5]), [[1.0, 2.0]])
