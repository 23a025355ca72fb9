"""Moving frames along curves (surfaces.frames) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.bspline import interpolate_curve
from surfaces.curves import helix, line
from surfaces.frames import FRAMES, frames, rotation_minimizing_frames


def _curvy_path():
    pts = np.array([[0, 0, 0], [1, 0, 0.5], [2, 1, 1], [3, 1, 2], [3, 2, 3], [2, 3, 3.5]], float)
    return interpolate_curve(pts)


def test_rmf_is_rotation_minimising():
    """The RMF normal's derivative has no component along the binormal (Bishop frame)."""
    path = _curvy_path()
    v = np.linspace(0.05, 0.95, 50)
    h = 1e-5
    t, n, b = frames(path, v, "rmf")
    _, n2, _ = frames(path, v + h, "rmf")
    _, n1, _ = frames(path, v - h, "rmf")
    dn = (n2 - n1) / (2 * h)
    assert np.max(np.abs(np.sum(dn * b, axis=1))) < 1e-5 * np.max(np.linalg.norm(dn, axis=1))
    np.testing.assert_allclose(np.cross(t, n), b, atol=1e-12)
    np.testing.assert_allclose(np.sum(t * n, axis=1), 0, atol=1e-12)


@pytest.mark.parametrize("radius, pitch, turns", [(2.0, 1.0, 1.0), (1.0, 3.0, 0.8)])
def test_rmf_of_helix_turns_against_frenet_by_torsion(radius, pitch, turns):
    """On a helix the RMF normal turns away from the Frenet normal by int tau ds."""
    c = pitch / (2 * np.pi)
    v = np.linspace(0, 1, 21)
    curve = helix(radius, pitch, turns)
    _, n_rmf, _ = frames(curve, v, "rmf")
    _, n_frenet, _ = frames(curve, v, "frenet")
    expected = c / np.hypot(radius, c) * 2 * np.pi * turns * v  # tau * arc length
    got = np.arccos(np.clip(np.sum(n_rmf * n_frenet, axis=1), -1, 1))
    np.testing.assert_allclose(got, expected, atol=1e-7)


def test_frenet_frame_of_helix():
    v = np.linspace(0, 1, 11)
    t, n, b = frames(helix(2.0, 1.0, 1.0), v, "frenet")
    # the principal normal of a helix points at the axis
    pts = helix(2.0, 1.0, 1.0).evaluate(v)
    towards_axis = -pts[:, :2] / np.linalg.norm(pts[:, :2], axis=1, keepdims=True)
    np.testing.assert_allclose(n[:, :2], towards_axis, atol=1e-12)
    np.testing.assert_allclose(n[:, 2], 0, atol=1e-12)


@pytest.mark.parametrize("kind", FRAMES)
def test_frames_are_orthonormal_and_right_handed(kind):
    v = np.linspace(0, 1, 17)
    t, n, b = frames(helix(1.5, 2.0, 1.25), v, kind)
    for x in (t, n, b):
        np.testing.assert_allclose(np.linalg.norm(x, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.sum(t * n, axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(t, n), b, atol=1e-12)


def test_fixed_frame_and_axis_frame():
    """The fixed frame keeps its start; None is the z axis with N = x (surfaces of revolution)."""
    t, n, _ = frames(helix(1.0, 1.0, 1.0), np.linspace(0, 1, 5), "fixed", up=[0.0, 0.0, 1.0])
    assert np.allclose(t, t[0]) and np.allclose(n, n[0])
    t0 = helix(1.0, 1.0, 1.0).derivative(np.zeros(1))[0]
    np.testing.assert_allclose(t[0], t0 / np.linalg.norm(t0), atol=1e-12)
    assert abs(n[0] @ t[0]) < 1e-12 and n[0][2] > 0
    t, n, b = frames(None, [0.0, 0.5], "rmf")
    np.testing.assert_allclose(t, [[0, 0, 1]] * 2)
    np.testing.assert_allclose(n, [[1, 0, 0]] * 2)
    np.testing.assert_allclose(b, [[0, 1, 0]] * 2)


def test_rmf_along_a_line_does_not_turn():
    """A straight path has no torsion: the RMF keeps the given first normal."""
    t, n, _ = rotation_minimizing_frames(line([0, 0, 0], [1, 2, 2]), np.linspace(0, 1, 9), up=[0, 0, 1])
    np.testing.assert_allclose(t, np.tile([1 / 3, 2 / 3, 2 / 3], (9, 1)), atol=1e-12)
    np.testing.assert_allclose(n, np.tile(n[0], (9, 1)), atol=1e-12)
    assert abs(n[0] @ t[0]) < 1e-12


def test_frame_errors():
    with pytest.raises(ValueError, match="frame: expected one of"):
        frames(helix(1.0, 1.0, 1.0), [0.5], "bishop")
    with pytest.raises(ValueError, match="up: must not be parallel"):
        frames(line([0, 0, 0], [0, 0, 1]), [0.5], "rmf", up=[0, 0, 2])
    with pytest.raises(ValueError, match="zero speed"):
        frames(line([0, 0, 0], [0, 0, 0]), [0.5], "rmf")
