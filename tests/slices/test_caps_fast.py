"""The cheaper forms of the caps' arithmetic against the forms they replaced: the closed-form area,
the sampling matrix of fan_apex, the columns written into close_side's grid, the ring of a flat cap."""

from __future__ import annotations

import numpy as np
import pytest

from slices import caps


def _wavy_curve(n_seg: int, seed: int, z: float = 2.0) -> np.ndarray:
    """A closed planar Bezier curve (n_seg, 4, 3) round a wavy outline, counter-clockwise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, 3 * n_seg, endpoint=False)
    r = 10 + rng.uniform(-2, 2) * np.sin(3 * t) + rng.uniform(0, 1, len(t))
    pts = np.stack([r * np.cos(t) + 50, r * np.sin(t) - 20, np.full_like(t, z)], 1)
    idx = (3 * np.arange(n_seg)[:, None] + np.arange(4)[None, :]) % len(pts)
    return pts[idx]


def _points_and_tangents(x: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One coordinate ``x`` (M, 4) of cubic Bezier segments at parameters ``s``: values and tangents (M, S),
    from the Bernstein polynomials written out (the reference the library's matrices are checked against)."""
    x, u = x[:, :, None], 1.0 - s
    values = u**3 * x[:, 0] + 3 * s * u**2 * x[:, 1] + 3 * s**2 * u * x[:, 2] + s**3 * x[:, 3]
    tangents = 3 * (u**2 * (x[:, 1] - x[:, 0]) + 2 * s * u * (x[:, 2] - x[:, 1]) + s**2 * (x[:, 3] - x[:, 2]))
    return values, tangents


def _quadrature_area(curve: np.ndarray) -> float:
    """The 3-point Gauss-Legendre form of Green's theorem that curve_area replaced."""
    nodes, weights = np.polynomial.legendre.leggauss(3)
    x, dx = _points_and_tangents(curve[:, :, 0], 0.5 * (nodes + 1.0))
    y, dy = _points_and_tangents(curve[:, :, 1], 0.5 * (nodes + 1.0))
    return float(0.25 * np.sum((x * dy - y * dx) * weights))


@pytest.mark.parametrize("seed", range(6))
def test_closed_form_area_equals_the_quadrature(seed):
    curve = _wavy_curve(7 + 5 * seed, seed)
    assert caps.curve_area(curve) == pytest.approx(_quadrature_area(curve), rel=1e-13)
    assert caps.curve_area(curve[::-1, ::-1]) == pytest.approx(-_quadrature_area(curve), rel=1e-13)
    # a circle of radius 10 made of cubic arcs: within 1e-5 relative of pi r^2
    assert caps.curve_area(_circle_curve(10.0, 16)) == pytest.approx(np.pi * 100, rel=1e-5)


def _circle_curve(r: float, n_seg: int) -> np.ndarray:
    """A circle of cubic arcs (the 4/3 tan(theta/4) handles)."""
    a = np.linspace(0, 2 * np.pi, n_seg + 1)
    k = 4.0 / 3.0 * np.tan(np.pi / (2 * n_seg))
    p0 = np.stack([np.cos(a[:-1]), np.sin(a[:-1])], 1)
    p3 = np.stack([np.cos(a[1:]), np.sin(a[1:])], 1)
    p1 = p0 + k * np.stack([-p0[:, 1], p0[:, 0]], 1)
    p2 = p3 - k * np.stack([-p3[:, 1], p3[:, 0]], 1)
    xy = r * np.stack([p0, p1, p2, p3], 1)
    return np.concatenate([xy, np.zeros(xy.shape[:2] + (1,))], 2)


def test_sampling_matrix_gives_the_points_and_tangents():
    curve = _wavy_curve(11, 3)
    sampled = curve[:, :, :2].transpose(2, 0, 1) @ caps._APEX_MATRIX
    for k in range(2):
        q, t = _points_and_tangents(curve[:, :, k], np.arange(8) / 8)
        np.testing.assert_allclose(sampled[k, :, :8], q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sampled[k, :, 8:], t, rtol=0, atol=1e-11)


def _reference_grid(side, bottom, top, low_center, high_center, height, low, high):
    """close_side as the concatenation of prism_column and fan_column it replaced."""
    full = [] if side is None else [side]
    if low == "half":
        full.insert(0, caps.prism_column(bottom, -height))
        bottom = bottom.copy()
        bottom[..., 2] -= height
    if high == "half":
        full.append(caps.prism_column(top, height))
        top = top.copy()
        top[..., 2] += height
    if low != "dome":
        full.insert(0, caps.fan_column(bottom, np.append(caps.fan_apex(bottom, low_center), bottom[0, 0, 2]), False))
    if high != "dome":
        full.append(caps.fan_column(top, np.append(caps.fan_apex(top, high_center), top[0, 0, 2]), True))
    return np.concatenate(full, axis=1)


@pytest.mark.parametrize("low,high", [("flat", "flat"), ("half", "half"), ("none", "half"), ("half", "dome"),
                                      ("dome", "flat"), ("dome", "dome")])
@pytest.mark.parametrize("single", [False, True])
def test_close_side_writes_the_columns_it_used_to_concatenate(low, high, single):
    bottom, top = _wavy_curve(9, 1, z=0.0), _wavy_curve(9, 2, z=6.0)
    side = None
    if not single:
        # three side columns between the curves (straight in z)
        w = np.arange(10) / 9.0
        rows = bottom[:, None] + w[None, :, None, None] * (top - bottom)[:, None]  # (M, 10, 4, 3)
        side = np.stack([rows[:, 3 * c:3 * c + 4] for c in range(3)], 1).transpose(0, 1, 3, 2, 4)
    elif "half" not in (low, high):
        low = "half"
    grid = caps.close_side(side, bottom, bottom if single else top, (50.0, -20.0), (50.0, -20.0), 1.25, low, high)
    want = _reference_grid(side, bottom, bottom if single else top, (50.0, -20.0), (50.0, -20.0), 1.25, low, high)
    np.testing.assert_array_equal(grid.control, want)
    for curve, out_z in grid.flat_caps:
        sides = grid.side_columns
        edge = grid.control[:, sides.start, :, 0] if out_z < 0 else grid.control[:, sides.stop - 1, :, 3]
        np.testing.assert_array_equal(curve, edge)


@pytest.mark.parametrize("samples", [1, 2, 5])
def test_cap_ring_is_the_bezier_curve_at_the_tessellation_samples(samples):
    curve = _wavy_curve(13, 4)
    mesh = caps.planar_cap_mesh(curve, samples, 1.0)
    s = np.arange(samples) / samples
    b = np.stack(caps._bezier_weights(s)[:4])  # (4, S)
    want = np.einsum("ks,mkx->msx", b, curve).reshape(-1, 3)
    np.testing.assert_allclose(mesh.vertices[:len(want)], want, rtol=0, atol=1e-12)
    assert mesh.triangles.flags.writeable and mesh.triangles.dtype == np.int64


@pytest.mark.parametrize("order", [3, 5, 8])
def test_gauss_tangents_give_the_tangents_at_the_nodes(order):
    curve = _wavy_curve(9, order)
    tangent, weights = caps._gauss_tangents(order)
    nodes = 0.5 * (np.polynomial.legendre.leggauss(order)[0] + 1.0)
    for k in range(2):
        np.testing.assert_allclose(curve[:, :, k] @ tangent, _points_and_tangents(curve[:, :, k], nodes)[1],
                                   rtol=0, atol=1e-11)
    assert weights.sum() == pytest.approx(1.0, rel=1e-14)
