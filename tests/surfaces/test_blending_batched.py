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


def _limit_reference(p):
    """Fritsch-Carlson limit written plainly, node by node and coordinate by coordinate."""
    n = len(p) + 1
    scale = np.ones((n, p.shape[2]))
    tiny = 1e-12 * (np.abs(p).max() + 1.0)
    for k in range(n - 1):
        for f in range(p.shape[2]):
            d = p[k, 3, f] - p[k, 0, f]
            for side, node in ((p[k, 1, f] - p[k, 0, f], k), (p[k, 3, f] - p[k, 2, f], k + 1)):
                if side * d < 0 or (abs(d) <= tiny and abs(side) > tiny):
                    r = 0.0
                else:
                    r = abs(d) / abs(side) if abs(side) > abs(d) else 1.0
                scale[node, f] = min(scale[node, f], r)
    q = p.copy()
    q[:, 1] = p[:, 0] + (p[:, 1] - p[:, 0]) * scale[:-1]
    q[:, 2] = p[:, 3] - (p[:, 3] - p[:, 2]) * scale[1:]
    return q, scale < 1.0


@pytest.mark.parametrize("seed", [0, 1])
def test_limit_monotone_equals_plain_loop(seed):
    rng = np.random.default_rng(seed)
    nodes = rng.normal(size=(7, 5))
    nodes[3, 0] = nodes[2, 0]  # a flat piece
    w = blending.blend_weights(7, np.cumsum(rng.uniform(0.5, 2.0, 7)))
    pieces = (w.reshape(-1, 7) @ nodes).reshape(6, 4, 5)
    pieces[2, 1, 1] = pieces[2, 0, 1]  # a zero tangent
    before = pieces.copy()
    got = blending.limit_monotone(pieces)
    q, limited = _limit_reference(pieces)
    np.testing.assert_array_equal(got.control, q)
    np.testing.assert_array_equal(got.limited, limited)
    np.testing.assert_array_equal(pieces, before)  # the input is left alone
    assert limited.any() and not limited.all()


def test_monotone_blend_is_blend_curves_with_its_limit():
    rng = np.random.default_rng(4)
    curves = rng.normal(size=(5, 6, 4, 3))
    curves[:, -1, 3] = curves[:, 0, 0]  # closed in u
    v = np.cumsum(rng.uniform(0.5, 2.0, 5))
    patches, limited = blending.monotone_blend(curves, params=v)
    np.testing.assert_array_equal(patches.control, blending.blend_curves(curves, params=v, monotone=True).control)
    w = blending.blend_weights(5, v)
    pieces = (w.reshape(-1, 5) @ curves.reshape(5, -1)).reshape(4, 4, -1)
    np.testing.assert_array_equal(limited, blending.limit_monotone(pieces).limited.reshape(curves.shape))
    with pytest.raises(ValueError, match="at least 2 curves"):
        blending.monotone_blend(curves[:1])


def test_restrict_rows_equals_restrict_segments_on_tiled_closed_curves():
    """Pieces tiling closed curves (rows of equal count, some ending on a knot, the last
    returning to the first) come out as the independent restriction of each piece."""
    rng = np.random.default_rng(7)
    sizes = [5, 9, 7]
    m = 16
    pts = np.concatenate([np.column_stack([np.cos(a), np.sin(a)]) * (1 + 0.2 * rng.random((n, 1)))
                          for n in sizes for a in [np.sort(rng.uniform(0, 2 * np.pi, n))]])
    t = np.concatenate([np.sort(rng.uniform(0, 1, n)) for n in sizes])
    ctrl, knots = blending.overhauser_closed_curves(pts, t, sizes)
    rows = []
    first = 0
    for c, n in enumerate(sizes):
        k = knots[first + c:first + c + n + 1]
        extra = np.sort(rng.uniform(k[0], k[-1], m - n))
        b = np.union1d(k, extra)
        assert len(b) == m + 1
        seg = np.clip(np.searchsorted(k, 0.5 * (b[:-1] + b[1:])) - 1, 0, n - 1)
        row = (first + seg, k[seg], k[seg + 1], b[:-1], b[1:])
        if c == 1:  # a row that starts inside a segment: its last piece ends on that segment too
            r = int(np.flatnonzero(seg[1:] == seg[:-1])[0]) + 1
            row = tuple(np.roll(x, -r) for x in row)
        rows.append(row)
        first += n
    g, k0, k1, b0, b1 = (np.concatenate(x) for x in zip(*rows))
    expect = blending.restrict_segments(ctrl[g], k0, k1, b0, b1)
    out = np.full((len(g), 4, 3), np.nan)
    blending.restrict_closed_rows(np.ascontiguousarray(ctrl[g].transpose(1, 2, 0)), k0, k1, b0, b1, m, out[..., :2])
    np.testing.assert_allclose(out[..., :2], expect, rtol=0, atol=1e-12)
    assert np.isnan(out[..., 2]).all()  # only the given view is written


@pytest.mark.parametrize("monotone", [False, True])
def test_blend_matches_the_dense_weights(monotone):
    # every Bezier point of the patches is the weights' combination of the curves (the inner two
    # along v from one product, the outer two copied from the curves)
    rng = np.random.default_rng(5)
    k, m = 6, 7
    curves = rng.normal(size=(k, m, 4, 3))
    curves[:, -1, 3] = curves[:, 0, 0]
    v = np.cumsum(rng.uniform(0.5, 2.0, k))
    patches = blending.blend_curves(curves, params=v, monotone=monotone)
    w = blending.blend_weights(k, v)
    dense = np.einsum("jbk,kmax->mjabx", w, curves)
    if monotone:
        assert np.all(patches.control[..., [0, 3], :] == dense[..., [0, 3], :])
    else:
        np.testing.assert_allclose(patches.control, dense, rtol=0, atol=1e-12)
        assert np.array_equal(patches.control[..., 0, :], curves[:-1].transpose(1, 0, 2, 3))


@pytest.mark.parametrize("n", [3, 4, 7, 26])
def test_identity_tangents_equal_the_tangents_of_the_identity(n):
    rng = np.random.default_rng(n)
    t = np.cumsum(rng.uniform(0.1, 3.0, n)) - 5.0
    np.testing.assert_array_equal(blending._identity_tangents(t), blending.overhauser_tangents(np.eye(n), t))
