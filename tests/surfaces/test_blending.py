"""Parabolic blending (Overhauser) curves and surfaces, seed 000 eqs. 6-19."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces import blending
from surfaces.bezier import BezierPatches


def _barry_goldman(p, t, u):
    """Direct evaluation of eq. 6: linear blend of the two parabolas (Neville form)."""
    def parabola(i0, x):
        ts, ps = t[i0:i0 + 3], p[i0:i0 + 3]
        out = 0.0
        for a in range(3):
            w = np.prod([(x - ts[b]) / (ts[a] - ts[b]) for b in range(3) if b != a])
            out = out + w * ps[a]
        return out

    t1, t2 = t[1], t[2]
    return ((t2 - u) * parabola(0, u) + (u - t1) * parabola(1, u)) / (t2 - t1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_segment_equals_eq6(seed):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.2, 2.0, 4))
    p = rng.normal(size=(4, 3))
    ctrl, knots = blending.overhauser_curve(p, t, closed=False)
    u = np.linspace(t[1], t[2], 11)
    ours = blending.evaluate_curve(ctrl, knots, u)
    ref = np.array([_barry_goldman(p, t, x) for x in u])
    np.testing.assert_allclose(ours, ref, atol=1e-12)


@pytest.mark.parametrize("closed", [False, True])
def test_interpolates_every_point(closed):
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 0.99, 25))
    p = rng.normal(size=(25, 2))
    ctrl, knots = blending.overhauser_curve(p, t, closed=closed)
    np.testing.assert_allclose(blending.evaluate_curve(ctrl, knots, t), p, atol=1e-13)
    if closed:
        np.testing.assert_allclose(ctrl[-1, 3], ctrl[0, 0])


def test_reproduces_quadratics_and_is_c1():
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.1, 1.0, 12))
    f = np.stack([t**2 - 3 * t, 2 * t + 1], axis=1)
    ctrl, knots = blending.overhauser_curve(f, t)
    u = np.linspace(t[0], t[-1], 200)
    np.testing.assert_allclose(blending.evaluate_curve(ctrl, knots, u),
                               np.stack([u**2 - 3 * u, 2 * u + 1], 1), atol=1e-11)
    left = blending.evaluate_curve(ctrl[:-1], knots[:-1], knots[1:-1], derivative=1)
    right = blending.evaluate_curve(ctrl[1:], knots[1:], knots[1:-1], derivative=1)
    np.testing.assert_allclose(left, right, atol=1e-10)


def test_uniform_is_catmull_rom():
    p = np.random.default_rng(5).normal(size=(4, 3))
    ctrl, _ = blending.overhauser_curve(p, np.arange(4.0))
    s = np.linspace(0, 1, 7)
    m = 0.5 * np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]])
    cr = np.stack([s**3, s**2, s, np.ones_like(s)], 1) @ m @ p
    seg = blending.evaluate_curve(ctrl[1:2], np.array([1.0, 2.0]), 1 + s)
    np.testing.assert_allclose(seg, cr, atol=1e-13)


def test_restrict_curve_is_exact():
    rng = np.random.default_rng(6)
    t = np.sort(rng.uniform(0, 0.95, 15))
    p = rng.normal(size=(15, 3))
    ctrl, knots = blending.overhauser_curve(p, t, closed=True)
    fine = np.union1d(knots, np.linspace(knots[0], knots[-1], 40))
    sub = blending.restrict_curve(ctrl, knots, fine)
    u = np.linspace(knots[0], knots[-1], 301)
    np.testing.assert_allclose(blending.evaluate_curve(sub, fine, u),
                               blending.evaluate_curve(ctrl, knots, u), atol=1e-12)
    with pytest.raises(ValueError, match="every knot"):
        blending.restrict_curve(ctrl, knots, np.linspace(knots[0], knots[-1], 7))


def test_closed_curve_defaults_to_chord_length():
    """A closed curve without parameters gets chord-length ones in [0, 1): a rectangle 3 x 1
    has chords 3, 1, 3, 1, so its parameters are 0, 3/8, 1/2, 7/8 and the curve is the one
    given those parameters."""
    p = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0], [0.0, 1.0]])
    ctrl, knots = blending.overhauser_curve(p, closed=True)
    np.testing.assert_allclose(knots, [0, 3 / 8, 1 / 2, 7 / 8, 1], atol=1e-15)
    ref, _ = blending.overhauser_curve(p, [0, 3 / 8, 1 / 2, 7 / 8], closed=True)
    np.testing.assert_allclose(ctrl, ref, atol=1e-14)
    np.testing.assert_allclose(blending.overhauser_tangents(p, closed=True),
                               blending.overhauser_tangents(p, [0, 3 / 8, 1 / 2, 7 / 8], closed=True),
                               atol=1e-14)
    with pytest.raises(ValueError, match="consecutive points coincide"):
        blending.overhauser_curve(np.vstack([p, p[:1]]), closed=True)
    with pytest.raises(ValueError, match="coincident grid rows"):
        blending.from_grid(np.zeros((3, 3, 3)))


@pytest.mark.parametrize("closed_v", [False, True])
def test_surface_through_grid(closed_v):
    rng = np.random.default_rng(7)
    pts = rng.normal(size=(9, 6, 3))
    patches = blending.from_grid(pts, closed_u=True, closed_v=closed_v)
    assert isinstance(patches, BezierPatches)
    rows, cols = patches.shape
    assert rows == 9 and cols == (6 if closed_v else 5)
    i, j = np.meshgrid(np.arange(9), np.arange(cols), indexing="ij")
    got = patches.evaluate(i.ravel(), j.ravel(), np.zeros(i.size), np.zeros(i.size))
    np.testing.assert_allclose(got, pts[:, :cols].reshape(-1, 3), atol=1e-12)


def test_blend_weights_match_uniform_overhauser():
    # the v-direction blend of scalar "curves" equals the uniform Overhauser curve through them
    vals = np.random.default_rng(8).normal(size=7)
    w = blending.blend_weights(7)
    ctrl, _ = blending.overhauser_curve(vals[:, None], np.arange(7.0))
    np.testing.assert_allclose(np.einsum("jbk,k->jb", w, vals), ctrl[:, :, 0], atol=1e-13)


def test_bad_input():
    with pytest.raises(ValueError, match="increase strictly"):
        blending.overhauser_curve(np.zeros((4, 2)) + np.arange(4)[:, None], [0, 1, 1, 2])
    with pytest.raises(ValueError, match="at least"):
        blending.overhauser_tangents(np.zeros((2, 2)), closed=True)
    with pytest.raises(ValueError, match="at least 2 curves"):
        blending.blend_weights(1)
