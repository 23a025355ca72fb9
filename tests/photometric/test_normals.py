"""photometric.normals: unit normals from slopes and the one angular error."""

from __future__ import annotations

import numpy as np
import pytest

from photometric.normals import angular_error_deg, normals_from_slopes


def test_normals_from_slopes_closed_form():
    # z = 0.3 x - 0.2 y  ->  p = 0.3, q = -0.2, n = (-p, -q, 1)/|.|
    n = normals_from_slopes(np.full((2, 3), 0.3), np.full((2, 3), -0.2))
    assert n.shape == (2, 3, 3)
    np.testing.assert_allclose(n[1, 2], np.array([-0.3, 0.2, 1.0]) / np.sqrt(1.13), atol=1e-15)
    np.testing.assert_allclose(-n[..., 0] / n[..., 2], 0.3, atol=1e-15)
    np.testing.assert_allclose(-n[..., 1] / n[..., 2], -0.2, atol=1e-15)
    with pytest.raises(ValueError, match="p, q"):
        normals_from_slopes(np.zeros((2, 2)), np.zeros((3, 3)))


def test_angular_error_closed_form():
    a = np.zeros((2, 2, 3))
    a[..., 2] = 1
    b = a.copy()
    b[0, 0] = (np.sin(np.radians(30)), 0, np.cos(np.radians(30)))
    b[1, 1] = (0, -1, 0)
    e = angular_error_deg(a, 2 * b)  # lengths do not matter
    assert e.shape == (2, 2)
    assert e[0, 0] == pytest.approx(30.0, abs=1e-12)
    assert e[1, 1] == pytest.approx(90.0, abs=1e-12) and e[0, 1] == 0 and e[1, 0] == 0
    mask = np.array([[True, False], [False, True]])
    np.testing.assert_allclose(angular_error_deg(a, b)[mask], [30.0, 90.0], atol=1e-12)
    assert angular_error_deg([0, 0, 1.0], [0, 0, -1.0]) == pytest.approx(180.0)


@pytest.mark.parametrize("angle", [1e-7, 1e-4, 0.5])
def test_angular_error_is_accurate_for_small_angles(angle):
    t = np.radians(angle)
    a = np.array([0.0, 0.0, 1.0])
    b = np.array([np.sin(t), 0.0, np.cos(t)], np.float32).astype(float)
    exact = np.degrees(np.arctan2(b[0], b[2]))
    assert angular_error_deg(a, b) == pytest.approx(exact, rel=1e-9)
    # arccos of the dot product loses the small angles that atan2 keeps
    if angle < 1e-6:
        assert np.degrees(np.arccos(np.clip(a @ b, -1, 1))) != pytest.approx(exact, rel=1e-3)


def test_angular_error_broadcasts_and_checks_shapes():
    e = angular_error_deg(np.eye(3), [[1.0, 0.0, 0.0]])
    np.testing.assert_allclose(e, [0.0, 90.0, 90.0], atol=1e-12)
    assert np.isnan(angular_error_deg([np.nan, 0, 1], [0, 0, 1]))
    with pytest.raises(ValueError, match="a, b"):
        angular_error_deg(np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="broadcast"):
        angular_error_deg(np.zeros((2, 3)), np.zeros((3, 3)))
