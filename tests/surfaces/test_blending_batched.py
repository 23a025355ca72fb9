"""Batched parabolic-blending curves and their restriction: equal to the per-curve functions."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces import blending
from surfaces.bezier import bernstein


def _ragged_closed(rng, n_curves, d=3):
    sizes = rng.integers(3, 12, n_curves)
    pts = [rng.normal(size=(n, d)) for n in sizes]
    params = [np.sort(rng.uniform(0.0, 0.9, n)) + rng.uniform(-2, 2) for n in sizes]
    return sizes, pts, params


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closed_curves_equal_one_by_one(seed):
    rng = np.random.default_rng(seed)
    sizes, pts, params = _ragged_closed(rng, 7)
    ctrl, knots = blending.overhauser_closed_curves(np.vstack(pts), np.concatenate(params), sizes)
    start = np.cumsum(sizes) - sizes
    for c, (p, t) in enumerate(zip(pts, params)):
        alone_ctrl, alone_knots = blending.overhauser_curve(p, t, closed=True)
        np.testing.assert_array_equal(ctrl[start[c]:start[c] + sizes[c]], alone_ctrl)
        np.testing.assert_array_equal(knots[start[c] + c:start[c] + c + sizes[c] + 1], alone_knots)


def test_closed_curves_reject_bad_input():
    p = np.zeros((7, 2)) + np.arange(7)[:, None]
    t = np.r_[np.arange(4) / 4, np.arange(3) / 3]
    with pytest.raises(ValueError, match="sizes"):
        blending.overhauser_closed_curves(p, t, [5, 3])
    with pytest.raises(ValueError, match="sizes"):
        blending.overhauser_closed_curves(p, t, [5, 2])
    with pytest.raises(ValueError, match="increase strictly"):
        blending.overhauser_closed_curves(p, t[::-1], [4, 3])
    with pytest.raises(ValueError, match="one period"):
        blending.overhauser_closed_curves(p, np.r_[np.arange(4) / 2, np.arange(3) / 3], [4, 3])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_restrict_curves_equal_one_by_one(seed):
    rng = np.random.default_rng(seed)
    sizes, pts, params = _ragged_closed(rng, 6)
    ctrl, knots = blending.overhauser_closed_curves(np.vstack(pts), np.concatenate(params), sizes)
    m = 16
    start = np.cumsum(sizes) - sizes
    breaks = []
    for c, n in enumerate(sizes):
        k = knots[start[c] + c:start[c] + c + n + 1]
        extra = rng.uniform(k[0], k[-1], m + 1 - len(k))
        breaks.append(np.sort(np.concatenate([k, extra])))
    out = blending.restrict_curves(ctrl, knots, sizes, np.array(breaks))
    assert out.shape == (len(sizes), m, 4, 3)
    for c, n in enumerate(sizes):
        k = knots[start[c] + c:start[c] + c + n + 1]
        alone = blending.restrict_curve(ctrl[start[c]:start[c] + n], k, breaks[c])
        np.testing.assert_allclose(out[c], alone, rtol=0, atol=1e-13)
        # every new segment lies on the original curve
        s = np.linspace(0.0, 1.0, 5)
        u = breaks[c][:-1, None] + s * np.diff(breaks[c])[:, None]
        on = blending.evaluate_curve(ctrl[start[c]:start[c] + n], k, u.ravel())
        mine = np.einsum("sa,mad->msd", bernstein(s), out[c]).reshape(-1, 3)
        np.testing.assert_allclose(mine, on, atol=1e-12)


def test_restrict_curves_needs_every_knot():
    ctrl, knots = blending.overhauser_closed_curves(np.eye(3), np.arange(3) / 3, [3])
    with pytest.raises(ValueError, match="every knot"):
        blending.restrict_curves(ctrl, knots, [3], [[0.0, 0.5, 1.0]])
    with pytest.raises(ValueError, match="sizes"):
        blending.restrict_curves(ctrl, knots, [2], [[0.0, 1 / 3, 2 / 3, 1.0]])


def test_restrict_segments_closed_form():
    # u^3 on [0, 2] restricted to [a, b]: Bezier points of the cubic in the local parameter
    a, b = 0.5, 1.5
    seg = np.array([[[0.0], [0.0], [0.0], [8.0]]])  # (2 s)^3 = u^3 with u = 2 s
    out = blending.restrict_segments(seg, [0.0], [2.0], [a], [b])[0, :, 0]
    w = b - a
    expect = [a**3, a**3 + w * 3 * a**2 / 3, b**3 - w * 3 * b**2 / 3, b**3]
    np.testing.assert_allclose(out, expect, atol=1e-14)
    with pytest.raises(ValueError, match="increase strictly"):
        blending.restrict_segments(seg, [0.0], [2.0], [b], [a])
