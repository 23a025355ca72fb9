"""Tests of global B-spline interpolation (seed 003): published vectors, peers, exactness."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline, make_interp_spline

from surfaces import bspline
from surfaces.bezier import BezierPatches, bernstein
from surfaces.knots import METHODS

EXAMPLE_9_1 = np.array([(0, 0), (3, 4), (-1, 4), (-4, 0), (-4, -3)], dtype=float)


def _grid(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    """A wavy, non-uniformly spaced open grid (R, C, 3)."""
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.uniform(0.5, 1.5, rows))
    y = np.cumsum(rng.uniform(0.5, 1.5, cols))
    gx, gy = np.meshgrid(x, y, indexing="ij")
    z = np.sin(gx / 2.0) * np.cos(gy / 3.0) + 0.1 * rng.standard_normal(gx.shape)
    return np.stack([gx, gy, z], axis=-1)


def _tube(rows: int, cols: int, seed: int = 0) -> np.ndarray:
    """A bumpy tube: closed around (axis 0), open along z (axis 1)."""
    rng = np.random.default_rng(seed)
    phi = np.linspace(0, 2 * np.pi, rows, endpoint=False) + rng.uniform(-0.1, 0.1, rows)
    z = np.linspace(0, 3, cols)
    P, Z = np.meshgrid(phi, z, indexing="ij")
    r = 1.0 + 0.2 * np.cos(3 * P) * np.sin(Z)
    return np.stack([r * np.cos(P), r * np.sin(P), Z], axis=-1)


def _torus(rows: int, cols: int) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, rows, endpoint=False)
    b = np.linspace(0, 2 * np.pi, cols, endpoint=False)
    A, B = np.meshgrid(a, b, indexing="ij")
    r = 2.0 + 0.5 * np.cos(B)
    return np.stack([r * np.cos(A), r * np.sin(A), 0.5 * np.sin(B)], axis=-1)


# ------------------------------------------------------------------ published vectors
def test_nurbs_book_example_9_1_chord():
    curve = bspline.interpolate_curve(EXAMPLE_9_1, degree=3, method="chord")
    np.testing.assert_allclose(curve.params, [0, 5 / 17, 9 / 17, 14 / 17, 1], atol=1e-15)
    np.testing.assert_allclose(curve.knots, [0, 0, 0, 0, 28 / 51, 1, 1, 1, 1], atol=1e-15)
    published = [(0, 0), (7.31696, 3.68678), (-2.95813, 6.67828), (-4.49495, -0.67369), (-4, -3)]
    np.testing.assert_allclose(curve.control, published, atol=5e-6)


def test_nurbs_book_example_9_1_centripetal():
    curve = bspline.interpolate_curve(EXAMPLE_9_1, degree=3, method="centripetal")
    np.testing.assert_allclose(curve.params, [0, 0.272552, 0.516330, 0.788882, 1], atol=5e-7)
    np.testing.assert_allclose(curve.evaluate(curve.params), EXAMPLE_9_1, atol=1e-12)


# ------------------------------------------------------------------ curves
@pytest.mark.parametrize("degree", [2, 3, 4, 5])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("closed", [False, True])
def test_curve_passes_through_points(degree, method, closed):
    rng = np.random.default_rng(degree)
    q = rng.uniform(-3, 3, (11, 3))
    curve = bspline.interpolate_curve(q, degree=degree, method=method, closed=closed)
    np.testing.assert_allclose(curve.evaluate(curve.params), q, atol=1e-10)
    if closed:
        # periodic: value and every derivative up to p - 1 agree across u = 0 / u = 1
        for order in range(degree):
            d0, d1 = curve.derivative([0.0, 1.0 - 1e-13], order)
            np.testing.assert_allclose(d0, d1, atol=1e-8 * (1 + np.abs(d0).max()))


@pytest.mark.parametrize("degree", [2, 3, 4, 5])
def test_curve_matches_scipy_with_averaged_knots(degree):
    rng = np.random.default_rng(10 + degree)
    q = rng.uniform(-3, 3, (12, 2))
    curve = bspline.interpolate_curve(q, degree=degree)
    peer = make_interp_spline(curve.params, q, k=degree, t=curve.knots, axis=0)
    np.testing.assert_allclose(curve.control, peer.c, atol=1e-9)
    u = np.linspace(0, 1, 301)
    np.testing.assert_allclose(curve.evaluate(u), peer(u), atol=1e-9)
    np.testing.assert_allclose(curve.derivative(u, 2), peer(u, nu=2), atol=1e-7)


def test_closed_cubic_matches_scipy_periodic():
    rng = np.random.default_rng(5)
    q = rng.uniform(-3, 3, (9, 3))
    curve = bspline.interpolate_curve(q, degree=3, closed=True)
    x = np.append(curve.params, 1.0)
    peer = make_interp_spline(x, np.vstack([q, q[:1]]), k=3, bc_type="periodic")
    u = np.linspace(0, 1, 257)
    np.testing.assert_allclose(curve.evaluate(u), peer(u), atol=1e-9)


def test_closed_curve_drops_repeated_last_point():
    q = _torus(12, 3)[:, 0]
    a = bspline.interpolate_curve(q, closed=True)
    b = bspline.interpolate_curve(np.vstack([q, q[:1]]), closed=True)
    np.testing.assert_allclose(a.control, b.control, atol=1e-14)


def test_curve_bezier_segments_match_curve():
    rng = np.random.default_rng(3)
    q = rng.uniform(-3, 3, (10, 3))
    curve = bspline.interpolate_curve(q, degree=3)
    seg = curve.bezier_segments()
    breaks = np.unique(curve.knots)
    t = rng.uniform(0, 1, 50)
    s = rng.integers(0, seg.shape[0], 50)
    u = breaks[s] + t * (breaks[s + 1] - breaks[s])
    mine = np.einsum("na,nak->nk", bernstein(t), seg[s])
    np.testing.assert_allclose(mine, curve.evaluate(u), atol=1e-10)


# ------------------------------------------------------------------ surfaces: peers
@pytest.mark.parametrize("centripetal", [False, True])
@pytest.mark.parametrize("degrees", [(3, 3), (2, 3), (3, 4)])
def test_surface_matches_geomdl(centripetal, degrees):
    from geomdl import fitting

    q = _grid(8, 7, seed=1)
    method = "centripetal" if centripetal else "chord"
    surf = bspline.interpolate_surface(q, degree=degrees, method=method)
    peer = fitting.interpolate_surface(
        q.reshape(-1, 3).tolist(), q.shape[0], q.shape[1], degrees[0], degrees[1],
        centripetal=centripetal,
    )
    np.testing.assert_allclose(surf.knots_u, peer.knotvector_u, atol=1e-12)
    np.testing.assert_allclose(surf.knots_v, peer.knotvector_v, atol=1e-12)
    rng = np.random.default_rng(2)
    uv = rng.uniform(0, 1, (40, 2))
    uv[:2] = [[0.0, 0.0], [1.0, 1.0]]
    theirs = np.array(peer.evaluate_list(uv.tolist()))
    np.testing.assert_allclose(surf.evaluate(uv[:, 0], uv[:, 1]), theirs, atol=1e-9)


def test_surface_matches_scipy_two_stage():
    q = _grid(9, 8, seed=4)
    surf = bspline.interpolate_surface(q, degree=3)
    stage1 = make_interp_spline(surf.params_u, q, k=3, t=surf.knots_u, axis=0).c  # (R, C, 3)
    # with axis=1 scipy returns the coefficients with the interpolation axis first
    stage2 = make_interp_spline(surf.params_v, stage1, k=3, t=surf.knots_v, axis=1).c
    np.testing.assert_allclose(surf.control, stage2.transpose(1, 0, 2), atol=1e-9)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 1, (2, 200))
    bu = BSpline.design_matrix(u, surf.knots_u, 3).toarray()
    bv = BSpline.design_matrix(v, surf.knots_v, 3).toarray()
    ref = np.einsum("na,nb,abk->nk", bu, bv, surf.control)
    np.testing.assert_allclose(surf.evaluate(u, v), ref, atol=1e-9)


def test_closed_surface_matches_scipy_periodic():
    q = _tube(10, 6, seed=3)
    surf = bspline.interpolate_surface(q, degree=3, closed_u=True)
    x = np.append(surf.params_u, 1.0)
    ref_u = make_interp_spline(x, np.concatenate([q, q[:1]]), k=3, bc_type="periodic", axis=0)
    rows = make_interp_spline(surf.params_v, ref_u.c, k=3, t=surf.knots_v, axis=1)
    rng = np.random.default_rng(1)
    u, v = rng.uniform(0, 1, (2, 100))
    coeff_v = rows(v)  # (n_u_ctrl, N, 3): the u-curve control points at each v
    vals = np.array([BSpline(ref_u.t, coeff_v[:, i], 3)(u[i]) for i in range(u.size)])
    np.testing.assert_allclose(surf.evaluate(u, v), vals, atol=1e-9)


# ------------------------------------------------------------------ surfaces: exactness
@pytest.mark.parametrize("degree", [2, 3, 4, 5])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("closed", [(False, False), (True, False), (True, True)])
def test_surface_passes_through_every_point(degree, method, closed):
    q = _torus(12, 10) if closed[1] else (_tube(12, 8) if closed[0] else _grid(9, 8))
    surf = bspline.interpolate_surface(
        q, degree=degree, method=method, closed_u=closed[0], closed_v=closed[1]
    )
    got = surf.evaluate_grid(surf.params_u, surf.params_v)
    np.testing.assert_allclose(got, q, atol=1e-10)


@pytest.mark.parametrize("degree", [2, 3])
@pytest.mark.parametrize("closed", [(False, False), (True, False), (True, True)])
def test_bezier_conversion_is_exact(degree, closed):
    q = _torus(9, 8) if closed[1] else (_tube(9, 7) if closed[0] else _grid(8, 7))
    surf = bspline.interpolate_surface(q, degree=degree, closed_u=closed[0], closed_v=closed[1])
    patches = surf.to_bezier()
    assert isinstance(patches, BezierPatches)
    assert (patches.closed_u, patches.closed_v) == closed
    rng = np.random.default_rng(7)
    u, v = rng.uniform(0, 1, (2, 500))
    pi, pj, s, t = surf.patch_parameters(u, v)
    expected = surf.evaluate(u, v)
    np.testing.assert_allclose(patches.evaluate(pi, pj, s, t), expected, atol=1e-10)
    # independent Bernstein evaluation of the raw control array
    ctrl = surf.bezier_control()
    mine = np.einsum("na,nb,nabk->nk", bernstein(s), bernstein(t), ctrl[pi, pj])
    np.testing.assert_allclose(mine, expected, atol=1e-10)
    # first derivatives agree too (patch derivative = B-spline derivative * span length)
    du = patches.derivatives(pi, pj, s, t).du
    span = np.diff(np.unique(surf.knots_u[surf.degree_u : -surf.degree_u]))[pi]
    np.testing.assert_allclose(du / span[:, None], surf.derivative(u, v, 1, 0), atol=1e-8)


def test_bezier_seams_are_shared_exactly():
    patches = bspline.interpolate_surface(_tube(10, 7), closed_u=True).to_bezier()
    c = patches.control
    assert np.array_equal(c[1:, :, 0], c[:-1, :, 3])
    assert np.array_equal(c[:, 1:, :, 0], c[:, :-1, :, 3])
    assert np.array_equal(c[-1, :, 3], c[0, :, 0])


@pytest.mark.parametrize("degree", [4, 5])
def test_bezier_conversion_refuses_higher_degrees(degree):
    surf = bspline.interpolate_surface(_grid(8, 8), degree=degree)
    with pytest.raises(ValueError, match="degree"):
        surf.to_bezier()


def test_interpolate_surface_patches_slices_layout():
    """The slices helper's call: grid (n_u around the contour, n_slices, 3), u closed."""
    q = _tube(16, 5)
    patches = bspline.interpolate_surface_patches(q, degree=3, closed_u=True)
    # closed u: one patch per data interval; open v: averaged knots give C - 3 spans
    assert patches.shape == (16, 2)
    assert patches.closed_u and not patches.closed_v
    # data rows sit on patch corners along the closed u; the open ends are the end columns
    np.testing.assert_allclose(patches.control[:, 0, 0, 0], q[:, 0], atol=1e-10)
    np.testing.assert_allclose(patches.control[:, -1, 0, 3], q[:, -1], atol=1e-10)


# ------------------------------------------------------------------ degenerate input
def _hemisphere(rows: int, cols: int) -> np.ndarray:
    """Rows run from the pole (row 0 collapsed to one point) down to the equator."""
    theta = np.linspace(0, np.pi / 2, rows)
    phi = np.linspace(0, np.pi, cols)
    T, P = np.meshgrid(theta, phi, indexing="ij")
    return np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)


def test_collapsed_row_pole_works():
    q = _hemisphere(7, 9)
    assert np.ptp(q[0], axis=0).max() == 0.0
    surf = bspline.interpolate_surface(q, degree=3)
    np.testing.assert_allclose(surf.evaluate_grid(surf.params_u, surf.params_v), q, atol=1e-10)
    # the whole pole row evaluates to the pole
    v = np.linspace(0, 1, 25)
    np.testing.assert_allclose(surf.evaluate(np.zeros_like(v), v), np.tile(q[0, 0], (25, 1)),
                               atol=1e-12)
    patches = surf.to_bezier()
    assert np.all(np.isfinite(patches.control))


def test_pole_that_breaks_geomdl_is_handled():
    """geomdl divides by the zero chord length of the pole row; we leave that row out.

    The result must still be the two-stage interpolant: scipy's ``make_interp_spline``
    with the same parameters and knots gives the same control net, and the surface
    passes through every grid point, the pole included.
    """
    from geomdl import fitting

    q = _hemisphere(7, 9)
    with pytest.raises(ZeroDivisionError):
        fitting.interpolate_surface(q.reshape(-1, 3).tolist(), 7, 9, 3, 3)
    surf = bspline.interpolate_surface(q)
    stage1 = make_interp_spline(surf.params_u, q, k=3, t=surf.knots_u, axis=0).c
    stage2 = make_interp_spline(surf.params_v, stage1, k=3, t=surf.knots_v, axis=1).c  # (C, R, 3)
    np.testing.assert_allclose(surf.control, stage2.transpose(1, 0, 2), atol=1e-12)
    np.testing.assert_allclose(surf.evaluate_grid(surf.params_u, surf.params_v), q, atol=1e-12)
    # the u parameters average the chord lengths of every column; v skips the pole row
    chords = np.linalg.norm(np.diff(q, axis=0), axis=2)
    expected_u = np.concatenate([[0.0], (np.cumsum(chords, axis=0) / chords.sum(0)).mean(axis=1)])
    np.testing.assert_allclose(surf.params_u, expected_u, atol=1e-14)


def test_collapsed_row_matches_pole_free_averaging():
    """The pole row is left out of the v averaging (Algorithm A9.3), not divided by zero."""
    q = _hemisphere(7, 9)
    surf = bspline.interpolate_surface(q, degree=3, method="chord")
    d = np.linalg.norm(np.diff(q[1:], axis=1), axis=2)
    expected = np.concatenate([[0.0], (np.cumsum(d, axis=1) / d.sum(1, keepdims=True)).mean(0)])
    np.testing.assert_allclose(surf.params_v, expected, atol=1e-14)


def test_evaluation_exactly_at_one():
    q = _grid(7, 6)
    surf = bspline.interpolate_surface(q)
    np.testing.assert_allclose(surf.evaluate([1.0], [1.0])[0], q[-1, -1], atol=1e-12)
    np.testing.assert_allclose(surf.evaluate([1.0], [0.0])[0], q[-1, 0], atol=1e-12)
    closed = bspline.interpolate_surface(_tube(8, 6), closed_u=True)
    np.testing.assert_allclose(closed.evaluate([1.0], [0.5]), closed.evaluate([0.0], [0.5]),
                               atol=1e-12)


def test_repeated_points_raise():
    q = np.array([[0, 0], [1, 0], [1, 0], [2, 1], [3, 0]], float)
    with pytest.raises(ValueError, match="points 1 and 2 coincide"):
        bspline.interpolate_curve(q)
    grid = _grid(7, 6)
    grid[3] = grid[2]
    with pytest.raises(ValueError, match="rows 2 and 3 coincide"):
        bspline.interpolate_surface(grid)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(points=np.zeros((3, 3, 2))), "shape"),
        (dict(points=_grid(3, 6)), "at least 4 x 4"),
        (dict(points=_grid(6, 6), degree=6), "degree_u"),
        (dict(points=_grid(6, 6), method="foley"), "method"),
        (dict(points=np.full((5, 5, 3), np.nan)), "NaN"),
        (dict(points=np.zeros((5, 5, 3))), "zero length"),
    ],
)
def test_bad_input_raises(kwargs, message):
    with pytest.raises(ValueError, match=message):
        bspline.interpolate_surface(**kwargs)


def test_parameters_outside_domain_raise():
    surf = bspline.interpolate_surface(_grid(6, 6))
    with pytest.raises(ValueError, match="u: parameters"):
        surf.evaluate([1.5], [0.5])


# ------------------------------------------------------------------ properties
@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(6, 30),
    degree=st.integers(2, 5),
    method=st.sampled_from(METHODS),
    seed=st.integers(0, 2**31 - 1),
)
def test_knot_vector_properties(n, degree, method, seed):
    q = np.random.default_rng(seed).uniform(-10, 10, (n, 3))
    curve = bspline.interpolate_curve(q, degree=degree, method=method)
    t = curve.knots
    assert t.size == n + degree + 1
    assert np.all(np.diff(t) >= 0)
    assert np.all(t[: degree + 1] == 0) and np.all(t[-degree - 1 :] == 1)
    # Schoenberg-Whitney: every data parameter lies inside its basis function's support
    idx = np.arange(n)
    assert np.all((t[idx] <= curve.params) & (curve.params <= t[idx + degree + 1]))
    np.testing.assert_allclose(curve.evaluate(curve.params), q, atol=1e-9)
