"""Seed 000 control-point parameters (eqs. 1-5), contour checks and orientation."""

from __future__ import annotations

import numpy as np
import pytest

from slices import control_points as cp
from slices import polygons as pg


def _ellipse(n, a=30.0, b=20.0, phase=0.0, center=(0.0, 0.0)):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) + phase
    return np.stack([center[0] + a * np.cos(t), center[1] + b * np.sin(t)], 1)


def _folded(n=240):
    """A 'C' outline: thick arc, opening at +x; the centroid lies inside the opening."""
    ang = np.linspace(0.5, 2 * np.pi - 0.5, n // 2)
    outer = np.stack([40 * np.cos(ang), 40 * np.sin(ang)], 1)
    inner = np.stack([22 * np.cos(ang[::-1]), 22 * np.sin(ang[::-1])], 1)
    return np.vstack([outer, inner])


def _spiral_fold(n=400):
    """A star-like outline with a fold: one arm bends back over a ray (non-star-shaped)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 30 + 8 * np.sin(3 * t)
    theta = t + 0.5 * np.sin(3 * t)  # the polar angle runs backwards on part of each lobe
    return np.stack([r * np.cos(theta), r * np.sin(theta)], 1)


@pytest.mark.parametrize("n_rays", [3, 16, 64])
@pytest.mark.parametrize("shape", ["ellipse", "c", "fold"])
def test_parameters_monotone_and_start_at_ray0(n_rays, shape):
    pts = {"ellipse": _ellipse(90, center=(5, -3)), "c": _folded(), "fold": _spiral_fold()}[shape]
    pts = pg.clean_contour(pts)
    par = cp.parameterize(pts, n_rays)
    assert np.all(np.diff(par.u) > 0) and par.u[0] >= 0 and par.u[-1] < 1
    assert len(par.support) == n_rays
    # support point 0 lies on the ray along +x from the ray origin
    d = par.support[0] - par.center
    assert abs(d[1]) < 1e-9 * np.linalg.norm(d) + 1e-9 and d[0] > 0
    # every point is one of the input points, order kept (rotated)
    k = int(np.flatnonzero(np.all(pts == par.points[0], axis=1))[0])
    np.testing.assert_array_equal(par.points, np.roll(pts, -k, axis=0))


def test_points_on_rays_get_k_over_n1():
    # eq. 1: vertices exactly on the rays of a regular polygon get u_k = k / N1
    n1 = 12
    ang = 2 * np.pi * np.arange(n1) / n1
    pts = np.stack([np.cos(ang), np.sin(ang)], 1) * 10
    par = cp.parameterize(pts, n1)
    np.testing.assert_allclose(par.u, np.arange(n1) / n1, atol=1e-12)


def test_chord_length_inside_segments():
    # eq. 5: points between two support points split the parameter by arc length
    n1 = 4
    pts = np.array([[10, 0], [10, 5], [10, 10], [0, 10], [-10, 10], [-10, 0], [-10, -10], [0, -10], [10, -10]], float)
    par = cp.parameterize(pts, n1)
    # (10, 5) lies a quarter of the arc length from (10, 0) to (0, 10) -> u = 0.25 / 4 * ... check ratio
    u = dict(zip(map(tuple, par.points), par.u))
    seg = np.array([0, 5, 10, 20])  # arc length from (10,0): (10,5), (10,10), (0,10)
    np.testing.assert_allclose([u[(10.0, 5.0)], u[(10.0, 10.0)]], seg[1:3] / seg[3] * 0.25)


def test_turning_points_in_folds_get_even_parameters():
    par = cp.parameterize(pg.clean_contour(_spiral_fold()), 64)
    assert par.turning.sum() > 0 and par.turning.sum() % 2 == 0
    # eq. 4: inside a segment the turning points split [u_k, u_k+1] evenly
    seg = np.floor(par.u[par.turning] * 64 + 1e-9).astype(int)
    for s in np.unique(seg):
        ut = np.sort(par.u[par.turning][seg == s])
        frac = ut * 64 - s
        np.testing.assert_allclose(frac, np.arange(1, len(ut) + 1) / (len(ut) + 1), atol=1e-9)


def test_tangent_ray_keeps_monotone():
    # a vertex exactly on ray 1 where the contour touches the ray and turns back
    pts = np.array([[10, 0], [8, 8], [7.0, 7.0], [0, 10], [-10, 0], [0, -10]], float)
    par = cp.parameterize(pg.clean_contour(pts), 8)
    assert np.all(np.diff(par.u) > 0)


def test_centroid_outside_uses_interior_point():
    pts = pg.clean_contour(_folded())
    assert not pg.points_in_polygon(pg.centroid(pts)[None], pts)[0]
    par = cp.parameterize(pts, 32)
    assert pg.points_in_polygon(par.center[None], pts)[0]


def test_quantize_keeps_order():
    u = np.array([0.0, 1e-4, 2e-4, 0.3, 0.3001, 0.9999])
    q = cp.quantize(u, 10)
    assert np.all(np.diff(q) > 0) and q.min() >= 0 and q.max() < 10
    with pytest.raises(ValueError, match="cannot hold"):
        cp.quantize(np.linspace(0, 0.9, 11), 10)


def test_clean_contour_orients_and_checks():
    cw = _ellipse(20)[::-1]
    out = pg.clean_contour(np.vstack([cw, cw[:1]]))  # repeated closing point dropped
    assert len(out) == 20 and pg.signed_area(out) > 0
    with pytest.raises(ValueError, match="at least 3"):
        pg.clean_contour([[0, 0], [1, 1], [1, 1]])
    with pytest.raises(ValueError, match="self-intersecting"):
        pg.clean_contour([[0, 0], [10, 10], [10, 0], [0, 10]])
    with pytest.raises(ValueError, match="zero area"):
        pg.clean_contour([[0, 0], [1, 1], [2, 2]])


@pytest.mark.parametrize("seed", range(6))
def test_self_intersections_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = 25
    pts = rng.uniform(0, 10, (n, 2))
    got = {tuple(p) for p in pg.self_intersections(pts)}
    a, b = pts, np.roll(pts, -1, axis=0)

    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    want = set()
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            if (orient(a[i], b[i], a[j]) != orient(a[i], b[i], b[j])
                    and orient(a[j], b[j], a[i]) != orient(a[j], b[j], b[i])):
                want.add((i, j))
    assert got == want


def _kidney_like(n=400):
    """A bean bent almost into a ring (kidney phantom outline): rays cross its arms three times."""
    from datasets_synthetic.phantoms import make_phantom

    return make_phantom("kidney").outline(np.arange(n) / n)[0]


def test_support_point_is_the_outermost_crossing():
    pts = pg.clean_contour(_kidney_like())
    par = cp.parameterize(pts, 64)
    frac, xy = cp.ray_supports(pts, 64)
    np.testing.assert_allclose(xy, par.support, atol=1e-9)
    # brute force: every crossing of every ray with the polygon, the farthest one wins
    a, b = pts, np.roll(pts, -1, axis=0)
    for k in range(64):
        d = np.array([np.cos(2 * np.pi * k / 64), np.sin(2 * np.pi * k / 64)])
        o = par.center
        num = (a - o)[:, 0] * d[1] - (a - o)[:, 1] * d[0]
        den = (b - a)[:, 0] * d[1] - (b - a)[:, 1] * d[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -num / den
        hit = (t >= 0) & (t <= 1)
        r = np.einsum("ij,j->i", a[hit] + t[hit, None] * (b - a)[hit] - o, d)
        assert np.linalg.norm(xy[k] - o) == pytest.approx(r.max(), abs=1e-9)
    # the supports still follow the contour in the order of the rays
    assert np.all(np.diff(np.unwrap(2 * np.pi * frac) - 2 * np.pi * frac[0]) > 0)


def test_balanced_lattice_is_even_in_arc_length():
    pts = pg.clean_contour(_kidney_like(300))
    par = cp.parameterize(pts, 64)
    closed = np.vstack([par.support[:1], par.points, par.support[:1]])
    cum = np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))
    arc = cum[:-1] / cum[-1]
    m = 600
    values = cp.balanced_lattice_values([par.u], [arc], m)
    assert len(values) == m and values[0] == 0 and np.all(np.diff(values) > 0) and values[-1] < 1
    s = np.interp(values, np.r_[0.0, par.u, 1.0], np.r_[0.0, arc, 1.0])
    np.testing.assert_allclose(np.diff(s), 1.0 / m, atol=1e-9)
    # a folded outline packs its arms into few ray segments: uniform j / M would not be even
    s_uniform = np.interp(np.arange(m) / m, np.r_[0.0, par.u, 1.0], np.r_[0.0, arc, 1.0])
    assert np.diff(s_uniform).max() > 5.0 / m


def test_start_angle_keeps_supports_steady_across_slices():
    from datasets_synthetic.phantoms import make_phantom

    cs = make_phantom("kidney").contours(2.5, n_points=64, seed=1)
    conts = [pg.clean_contour(c["points"]) for c in cs]
    angle = cp.choose_start_angle(conts, 64)
    assert 0 <= angle < 2 * np.pi / 64

    def worst_shift(a):
        frac = np.stack([cp.ray_supports(c, 64, a)[0] for c in conts])
        shift = (np.diff(frac, axis=0) + 0.5) % 1.0 - 0.5
        return np.abs(shift - np.median(shift, axis=1, keepdims=True)).max()

    # no support point moves by more than 5 % of the perimeter between neighbouring slices,
    # while some rotations let a ray graze an arm's tip and its support jump across the fold
    assert worst_shift(angle) < 0.05
    assert max(worst_shift(2 * np.pi * o / (8 * 64)) for o in range(8)) > 0.1
    assert cp.choose_start_angle(conts[:1], 64) == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_quantize_and_isotonic_fit_equal_the_single_ones(seed):
    """Runs side by side come out exactly as each alone (no pooling across a run's start)."""
    rng = np.random.default_rng(seed)
    us = [np.sort(rng.choice(np.arange(200) / 200, size=k, replace=False)) for k in (5, 40, 17, 1, 60)]
    m = 64
    values = np.unique(np.concatenate([np.arange(m) / m + 0.002 * rng.random(m)]))[:m]
    for lv in (None, values):
        batched = cp._quantize_many(us, m, lv)
        for u, q in zip(us, batched):
            np.testing.assert_array_equal(q, cp.quantize(u, m, lv))
    ys = [rng.normal(size=k) for k in (7, 1, 30, 12)]
    starts = np.cumsum([0] + [len(y) for y in ys[:-1]])
    np.testing.assert_array_equal(cp._isotonic_fit_runs(np.concatenate(ys), starts),
                                  np.concatenate([cp.isotonic_fit(y) for y in ys]))
    assert cp.isotonic_fit([]).shape == (0,)


def _ragged_outlines():
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    star = np.stack([(10 + 4 * np.cos(5 * t)) * np.cos(t), (10 + 4 * np.cos(5 * t)) * np.sin(t)], 1)
    a = np.linspace(0.3, 2 * np.pi - 0.3, 70)
    c_shape = np.vstack([np.stack([12 * np.cos(a), 12 * np.sin(a)], 1),
                         np.stack([7 * np.cos(a[::-1]), 7 * np.sin(a[::-1])], 1)])
    square = np.array([[-1.0, -1], [1, -1], [1, 1], [-1, 1]])
    return [pg.clean_contour(p) for p in (star, c_shape, square, star[::3] + 3.0, c_shape[::2] * 0.5)]


def test_support_crossings_of_many_contours_equal_each_alone():
    """The batched rays give every contour what it gets alone, folded outlines included."""
    # a C-shaped outline among them: rays through the gap cross it several times (the outermost
    # crossing is the support)
    ps = _ragged_outlines()
    polars = cp._polars(ps)
    for n1, start in ((12, 0.0), (96, 0.05)):
        together = cp._support_crossings(polars, n1, start)
        for i, p in enumerate(ps):
            alone = cp._support_crossings(cp._polars([p]), n1, start)
            for x, y in zip(together, alone):
                np.testing.assert_array_equal(x[i], y[0])
        # every support point lies on its ray
        s_arc, xy, level, ang = together
        for i, center in enumerate(polars.centers):
            rel = xy[i] - center
            np.testing.assert_allclose(rel[:, 0] * np.sin(ang[i]) - rel[:, 1] * np.cos(ang[i]), 0, atol=1e-9)
            assert np.all(rel[:, 0] * np.cos(ang[i]) + rel[:, 1] * np.sin(ang[i]) > 0)


def test_polars_of_many_contours_equal_each_alone():
    ps = _ragged_outlines()
    together = cp._polars(ps)
    for i, p in enumerate(ps):
        alone = cp._polars([p])
        n = len(p)
        sl = slice(together.off3[i], together.off3[i] + 3 * n + 1)
        np.testing.assert_array_equal(together.centers[i], alone.centers[0])
        np.testing.assert_array_equal(together.phi[sl], alone.phi)
        np.testing.assert_array_equal(together.arc[sl], alone.arc)
        # closed forms: the centroid, three turns of polar angle, three perimeters
        if pg.points_in_polygon(pg.centroid(p)[None], p)[0]:  # else the rays start from an interior point
            np.testing.assert_allclose(alone.centers[0], pg.centroid(p), atol=1e-12)
        assert pg.points_in_polygon(alone.centers, p)[0]
        np.testing.assert_allclose(alone.phi[-1] - alone.phi[0], 6 * np.pi, atol=1e-9)
        perimeter = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum()
        np.testing.assert_allclose(alone.arc[[n, 2 * n, 3 * n]], perimeter * np.arange(1, 4), rtol=1e-12)


@pytest.mark.parametrize("n1", [16, 64, 512])
def test_crossings_crossed_once_pick_what_the_general_picks_do(n1):
    """Where every ray level is crossed once (:attr:`_Crossings.single`) the picks skip their gathers and
    the second pick; the general path on the same crossings gives the same values."""
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    convex = [np.stack([(8 + k) * np.cos(t), (5 + k) * np.sin(t)], 1) for k in range(4)]
    for ps, single in ((convex, True), (_ragged_outlines(), False)):
        polars = cp._polars([pg.clean_contour(p) for p in ps])
        cr = cp._crossings(polars, n1, 0.0)
        assert cr.single is single
        general = cr._replace(single=False, first=cr.first.copy())
        total = polars.arc[polars.off3 + polars.sizes]
        np.testing.assert_array_equal(cr.levels(), cr.level_k[cr.outer])
        for points in (False, True):
            fast = cp._pick_crossings(cr, cr.outer, cr.first, cr.levels(), total, 0.0, 2 * np.pi / n1, points)
            slow = cp._pick_crossings(general, general.outer, general.first, general.level_k[general.outer], total,
                                      0.0, 2 * np.pi / n1, points)
            for x, y in zip(fast, slow):
                np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("n1, start", [(12, 0.0), (64, 0.05), (96, 0.3)])
def test_parameters_of_many_contours_equal_each_alone(n1, start):
    ps = _ragged_outlines()
    polars = cp._polars(ps)
    together = cp._parameterize_many(polars, n1, start, cp._support_crossings(polars, n1, start))
    assert len(together) == len(ps)
    assert any(par.turning.any() for par in together)  # the folded outlines get turning points
    for p, par in zip(ps, together):
        alone = cp.parameterize(p, n1, start)
        for field in ("points", "u", "center", "support", "turning"):
            np.testing.assert_array_equal(getattr(par, field), getattr(alone, field))


def test_balanced_lattice_values_of_many_slices_equal_the_running_mean():
    rng = np.random.default_rng(5)
    us, arcs = [], []
    for n in (7, 12, 5, 9):
        us.append(np.sort(rng.uniform(0, 1, n)))
        arcs.append(np.sort(rng.uniform(0, 1, n)))
    m = 30
    grid = np.unique(np.concatenate([[0.0, 1.0], *us]))
    mean = np.zeros_like(grid)
    for u, a in zip(us, arcs):
        mean += np.interp(grid, np.r_[0.0, u, 1.0], np.r_[0.0, a, 1.0])
    mean /= len(us)
    expect = np.unique(np.interp(np.arange(m) / m, mean, grid))
    # the sum runs over slopes on the grid, not slice after slice: equal to rounding
    np.testing.assert_allclose(cp.balanced_lattice_values(us, arcs, m), expect[expect < 1.0], rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="arc_list"):
        cp.balanced_lattice_values(us, [a[:-1] for a in arcs], m)


@pytest.mark.parametrize("n1", [7, 8])
def test_start_angle_is_the_least_median_removed_shift(n1):
    ps = _ragged_outlines()[:2] + [pg.clean_contour(p) for p in _ragged_outlines()[:2]]
    ps = [p * (1.0 + 0.05 * i) + 0.3 * i for i, p in enumerate(ps)]
    r = 4
    frac = cp._ray_supports(cp._polars(ps), n1 * r, 0.0)[0].reshape(len(ps), n1, r)
    shift = (np.diff(frac, axis=0) + 0.5) % 1.0 - 0.5
    shift -= np.median(shift, axis=1, keepdims=True)
    expect = 2 * np.pi * int(np.argmin(np.abs(shift).max(axis=1).sum(axis=0))) / (n1 * r)
    assert cp.choose_start_angle(ps, n1, r) == expect


@pytest.mark.parametrize("n1, r", [(7, 4), (12, 8), (64, 8)])
def test_start_angle_crossings_are_those_of_the_chosen_rays(n1, r):
    """The chosen rotation's crossings, picked out of the pass over all rotations, are the ones a
    pass over its own rays finds (up to rounding of the rays' angles), folded outlines included."""
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    star = np.stack([(10 + 4 * np.cos(5 * t)) * np.cos(t), (10 + 4 * np.cos(5 * t)) * np.sin(t)], 1)
    a = np.linspace(0.3, 2 * np.pi - 0.3, 70)
    c_shape = np.vstack([np.stack([12 * np.cos(a), 12 * np.sin(a)], 1),
                         np.stack([7 * np.cos(a[::-1]), 7 * np.sin(a[::-1])], 1)])
    ps = [pg.clean_contour(p) for p in (star, c_shape, star[::2] + 3.0, c_shape * 0.5)] + _ragged_outlines()[:2]
    polars = cp._polars(ps)
    angle, got = cp._start_angle_crossings(polars, n1, r)
    assert angle == cp._start_angle(polars, n1, r)
    expect = cp._support_crossings(polars, n1, angle)
    np.testing.assert_array_equal(got[2], expect[2])
    for x, y in zip(got[:2] + got[3:], expect[:2] + expect[3:]):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-9)


def test_balanced_lattice_values_with_a_point_at_u_zero():
    # u = 0 repeats the start (0, 0) with the point's own arc: the running mean jumps there as np.interp does
    us = [np.array([0.0, 0.3, 0.6]), np.array([0.1, 0.5, 0.7, 0.9])]
    arcs = [np.array([0.05, 0.4, 0.7]), np.array([0.2, 0.45, 0.8, 0.85])]
    m = 12
    grid = np.unique(np.concatenate([[0.0, 1.0], *us]))
    mean = sum(np.interp(grid, np.r_[0.0, u, 1.0], np.r_[0.0, a, 1.0]) for u, a in zip(us, arcs)) / 2
    expect = np.unique(np.interp(np.arange(m) / m, mean, grid))
    np.testing.assert_allclose(cp.balanced_lattice_values(us, arcs, m), expect[expect < 1.0], rtol=0, atol=1e-14)
