"""Slice curves on a common lattice and side surfaces through them."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from slices.polygons import clean_contour
from slices.surface import LATTICE_MODES, METHODS, lattice_size, side_surface, slice_curves
from tests.slices._stacks import circle, phantom_stack


@pytest.fixture(scope="module")
def ellipsoid():
    _, conts, _ = phantom_stack("ellipsoid", a=15.0, b=10.0, c=12.0, n_points=48)
    return [c.points for c in conts], np.array([c.z for c in conts])


@pytest.mark.parametrize("mode", LATTICE_MODES)
def test_every_point_lies_on_its_slice_curve(ellipsoid, mode):
    conts, z = ellipsoid
    sc = slice_curves(conts, z, 32, lattice_mode=mode)
    for curve, nodes, pts in zip(sc.curves, sc.nodes, sc.points):
        np.testing.assert_allclose(curve[nodes, 0], pts, atol=1e-9)
        # closed and C0 between lattice segments
        np.testing.assert_allclose(np.roll(curve[:, 0], -1, axis=0), curve[:, 3], atol=1e-9)
    assert 0 <= sc.start_angle < 2 * np.pi / 32


def test_lattice_size_is_a_count_from_a_factor():
    assert lattice_size(10) == 20 and lattice_size(10, 1.5) == 15 and lattice_size(2) == 4
    with pytest.raises(ValueError, match="lattice_factor"):
        lattice_size(10, 0.5)
    conts = [circle(0, 0, 10, 30), circle(0, 0, 9, 24)]
    sc = slice_curves(conts, [0.0, 2.0], 16, n_lattice=45, lattice_mode="uniform", start_angle=0.0)
    assert sc.curves.shape == (2, 45, 4, 3) and sc.start_angle == 0.0


def test_bad_options_are_named(ellipsoid):
    conts, z = ellipsoid
    with pytest.raises(ValueError, match="correspondence"):
        slice_curves(conts, z, 32, correspondence="nearest")
    with pytest.raises(ValueError, match="lattice_mode"):
        slice_curves(conts, z, 32, lattice_mode="dense")
    with pytest.raises(ValueError, match="z"):
        slice_curves(conts, z[:-1], 32)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_side_surface_passes_through_the_lattice_nodes(ellipsoid, method):
    conts, z = ellipsoid
    sc = slice_curves(conts, z, 32)
    patches, node_eval = side_surface(sc.curves, method, v=z)
    assert patches.closed_u
    k = len(z)
    j = np.tile(np.arange(sc.curves.shape[1]), k)
    kk = np.repeat(np.arange(k), sc.curves.shape[1])
    np.testing.assert_allclose(node_eval(j, kk), sc.curves[kk, j, 0], atol=1e-8)


def test_blending_reproduces_a_cylinder_between_identical_slices():
    ring = circle(0, 0, 10, 48)
    sc = slice_curves([ring] * 3, [0.0, 1.0, 2.0], 16)
    patches, _ = side_surface(sc.curves)
    pts = patches.evaluate(np.zeros(5, int), np.array([0, 0, 1, 1, 1]), np.full(5, 0.3), np.linspace(0, 1, 5))
    # every point between identical slices lies on the slice curve's vertical extrusion
    np.testing.assert_allclose(pts[:, :2], np.broadcast_to(pts[0, :2], (5, 2)), atol=1e-12)


def test_side_surface_rejects_bad_input(ellipsoid):
    conts, z = ellipsoid
    curves = slice_curves(conts[:2], z[:2], 16).curves
    with pytest.raises(ValueError, match="method"):
        side_surface(curves, "nurbs")
    with pytest.raises(ValueError, match="at least 2 slices"):
        side_surface(curves[:1])
    with pytest.raises(ValueError, match="increase"):
        side_surface(curves, v=[1.0, 0.0])


@pytest.mark.parametrize("n_points", [64, 128])
def test_kidney_correspondence_follows_the_scaled_sections(n_points):
    # the kidney's sections are scaled copies of one outline: with the seed's parameters
    # (outermost supports, steady ray rotation, balanced lattice) the same u lands on the
    # same place of that outline on every slice
    ph = make_phantom("kidney")
    cs = ph.contours(2.5, n_points=n_points, seed=1)
    z = np.array([c["z"] for c in cs])
    sc = slice_curves([clean_contour(c["points"]) for c in cs], z, 64)
    scale = np.sqrt(1 - ((z - ph.center[2]) / ph.c) ** 2)
    base = sc.curves[:, :, 0, :2] / scale[:, None, None]
    shift = np.linalg.norm(np.diff(base, axis=0), axis=2) * scale[1:, None]
    assert shift.max() < 2.5  # mm; the perimeter is about 110 mm, the old record rule jumped 5-15 mm


def c_shape(turn: float, start: int) -> np.ndarray:
    """A C (an annulus opened by a wide channel, one outline) turned by ``turn`` radians; its
    point list starts ``start`` points further round."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)[3:-3]
    outer = np.stack([12 * np.cos(t), 12 * np.sin(t)], 1)
    pts = np.vstack([outer, 5 / 12 * outer[::-1]])
    c, s = np.cos(turn), np.sin(turn)
    return np.roll(pts @ np.array([[c, s], [-s, c]]), -start, axis=0)


def test_aligned_arcs_follow_a_turning_shape():
    from slices.body import build_body_once
    from slices.chaining import chain
    from slices.io import Contour
    from slices.options import SurfaceOptions
    from slices.surface import aligned_arcs
    from surfaces.intersect import self_intersections

    # the same outline on every slice, its point list starting at a different point each time
    base = c_shape(0.0, 0)
    arc = np.arange(len(base)) / len(base)  # one parameter per point, as the shifts are whole points
    us = aligned_arcs([np.roll(base, -k, axis=0) for k in (0, 17, 40, 41)], [arc] * 4)
    for k, u in zip((0, 17, 40, 41), us):
        # every point gets the u it has on the first slice (to a sample of the alignment)
        np.testing.assert_allclose(np.mod(u - np.roll(arc, -k) + 0.5, 1) - 0.5, 0, atol=2.0 / 512)
    # a C turning from plane to plane: arc length from ray 0 and the seed's rays twist the links
    # between the slices and fold the surface; the aligned links follow the C
    body = chain([Contour(2.0 * k, c_shape(0.15 * k, 13 * k)) for k in range(5)], 2.0)[0]
    area = np.pi * (12**2 - 5**2) * 54 / 60  # the annulus' sectors the C keeps (to its polygons)
    for ruled in (False, True):
        twisted = build_body_once(body, 2.0, SurfaceOptions(correspondence="arc", samples=2, caps="flat"), ruled=ruled)
        assert self_intersections(twisted.mesh.vertices, twisted.mesh.triangles).n_faces > 0
        b = build_body_once(body, 2.0, SurfaceOptions(correspondence="aligned", samples=2, caps="flat"), ruled=ruled)
        assert self_intersections(b.mesh.vertices, b.mesh.triangles).n_faces == 0
        assert b.max_deviation_mm < 1e-9 and b.mesh.is_watertight()
        assert b.volume_mm3 == pytest.approx(area * 8.0, rel=0.01)

def test_isotonic_fit_matches_scipy():
    from scipy.optimize import isotonic_regression

    from slices.control_points import isotonic_fit, quantize

    rng = np.random.default_rng(7)
    for n in (1, 2, 5, 40, 400):
        y = np.round(rng.normal(size=n) * 4 + np.arange(n) * rng.random())
        np.testing.assert_allclose(isotonic_fit(y), isotonic_regression(y).x, atol=1e-12)
    # crowded parameters still get strictly increasing lattice indices
    q = quantize(np.array([0.0, 0.3, 0.3001, 0.3002, 0.9]), 10)
    assert np.all(np.diff(q) > 0) and q.tolist() == [0, 2, 3, 4, 9]


def test_slice_curves_share_the_public_parameters_and_rotation():
    """The batched path (one polar pass per contour) gives what the public functions give."""
    from slices.control_points import choose_start_angle, parameterize

    _, conts, _ = phantom_stack("kidney", n_points=60)
    pts, z = [c.points for c in conts], np.array([c.z for c in conts])
    sc = slice_curves(pts, z, 24)
    assert sc.start_angle == choose_start_angle(pts, 24)
    for got, p in zip(sc.params, pts):
        want = parameterize(p, 24, sc.start_angle)
        for field in ("points", "u", "center", "support", "turning"):
            np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
    with pytest.raises(ValueError, match="n_rays"):
        slice_curves(pts, z, 2)
    with pytest.raises(ValueError, match=r"contours\[1\]"):
        slice_curves([pts[0], pts[1][:2]], z[:2], 24)


def test_blend_overshoot_after_side_surface_is_by_value():
    """The side surface's limit serves the overshoot count of the same curves, never of others."""
    from slices.surface import blend_overshoot, side_surface
    from surfaces import blending

    rng = np.random.default_rng(7)
    curves = rng.normal(size=(6, 8, 4, 3))
    curves[:, -1, 3] = curves[:, 0, 0]  # closed in u
    v = np.arange(6.0) * 2.5

    def fresh(c):
        limited = blending.monotone_blend(c, params=v)[1]
        return int(np.count_nonzero(limited[..., :2].any(axis=-1)))

    side_surface(curves, "blending", v=v, monotone=True)
    assert blend_overshoot(curves, v) == fresh(curves) > 0
    changed = curves.copy()
    changed[2, :, 1:3, :2] *= 3.0
    assert fresh(changed) != fresh(curves)
    assert blend_overshoot(changed, v) == fresh(changed)
    curves[2, :, 1:3, :2] *= 3.0  # the same array, changed in place after the blend
    assert blend_overshoot(curves, v) == fresh(changed)


def test_a_smooth_body_keeps_the_seed_blend_unlimited():
    # the monotone limit flattens every extremum across the slices: by default it is kept for bodies
    # whose blend folds, and a smooth ellipsoid keeps the seed's blend, closer to its true volume
    from datasets_synthetic.phantoms import make_phantom
    from slices.polygons import clean_contour
    from slices.io import Contour
    from slices.structure import reconstruct_contours

    ph = make_phantom("ellipsoid")
    exact = ph.truth(2.5)["volume_between_end_planes_mm3"]
    cs = [Contour(c["z"], clean_contour(c["points"])) for c in ph.contours(2.5, n_points=64, seed=1)]
    plain = reconstruct_contours(cs, caps="flat")
    limited = reconstruct_contours(cs, caps="flat", monotone=True)
    assert plain.bodies[0].n_limited == 0 and plain.bodies[0].surface.startswith("blending")
    assert limited.bodies[0].n_limited > 1000
    assert plain.bodies[0].self_intersecting_faces == 0
    assert abs(plain.volume_mm3 - exact) < abs(limited.volume_mm3 - exact)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_node_eval_is_the_surface_at_the_patch_corners(ellipsoid, method):
    conts, z = ellipsoid
    sc = slice_curves(conts, z, 32)
    patches, node_eval = side_surface(sc.curves, method, v=z)
    rows, cols = patches.shape
    k = len(z)
    j = np.tile(np.arange(sc.curves.shape[1]), k)
    kk = np.repeat(np.arange(k), sc.curves.shape[1])
    if method == "bspline":
        return  # evaluated from the spline itself, not at patch corners
    at = patches.evaluate(j, np.minimum(kk, cols - 1), np.zeros(len(j)), (kk > cols - 1).astype(float))
    np.testing.assert_array_equal(node_eval(j, kk), at)


def test_side_blend_equals_the_checked_blend_and_checks_the_closing(ellipsoid):
    from surfaces.blending import blend_curves

    conts, z = ellipsoid
    sc = slice_curves(conts, z, 32)
    patches, _ = side_surface(sc.curves, "blending", v=z)
    np.testing.assert_array_equal(patches.control, blend_curves(sc.curves, params=z).control)
    open_curves = sc.curves.copy()
    open_curves[:, -1, 3] += 1.0
    with pytest.raises(ValueError, match="closed_u"):
        side_surface(open_curves, "blending", v=z)
    with pytest.raises(ValueError, match="NaN"):
        side_surface(np.where(open_curves > 5, np.nan, open_curves), "blending", v=z)


@pytest.mark.parametrize("monotone", [False, True])
@pytest.mark.parametrize("low, high", [("flat", "flat"), ("half", "half"), ("half", "none"), ("dome", "flat")])
def test_side_written_into_the_capped_grid_is_close_side_of_the_blend(monotone, low, high):
    """The blend written straight into a capped grid's side columns gives close_side's grid, bit for bit."""
    from slices import caps
    from slices.surface import _side_surface

    rng = np.random.default_rng(3)
    curves = rng.normal(size=(5, 7, 4, 3))
    curves[:, -1, 3] = curves[:, 0, 0]  # closed in u
    curves[..., 2] = np.arange(5.0)[:, None, None] * 2.0  # planar slices
    v = curves[:, 0, 0, 2]
    side, at = side_surface(curves, "blending", v=v, monotone=monotone)
    want = caps.close_side(side.control, side.control[:, 0, :, 0], side.control[:, -1, :, 3], (0.1, 0.2),
                           (0.0, -0.1), 1.0, low, high)
    buffer, mid = caps._grid_buffer(7, 4, low, high)
    into, at_into = _side_surface(curves, "blending", v, monotone, out=buffer[:, mid])
    assert np.shares_memory(into.control, buffer) and np.array_equal(into.control, side.control)
    got = caps._close_grid(buffer, into.control[:, 0, :, 0], into.control[:, -1, :, 3], (0.1, 0.2), (0.0, -0.1),
                           1.0, low, high)
    assert np.array_equal(got.control, want.control) and got.side_columns == want.side_columns
    assert got.end_planes == want.end_planes and got.extrusions == want.extrusions
    assert all(np.array_equal(a, b) and s == t for (a, s), (b, t) in zip(got.flat_caps, want.flat_caps))
    j, k = np.array([0, 3, 6]), np.array([0, 2, 4])
    assert np.array_equal(at_into(j, k), at(j, k))
    with pytest.raises(ValueError, match="out"):
        _side_surface(curves, "coons", v, monotone, out=buffer[:, mid])
