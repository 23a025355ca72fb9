"""Tests of kinematic surfaces (seed 004) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces import kinematic as K
from surfaces.bezier import BezierPatches
from surfaces.bspline import interpolate_curve
from surfaces.curves import ParametricCurve, circle, line
from surfaces.measure import area_and_volume
from tests.surfaces.test_frames import _curvy_path


@pytest.mark.parametrize("frame", ["fixed", "rmf"])
@pytest.mark.parametrize(
    "start, end", [([0, 0, 0], [0, 0, 4.0]), ([1, 2, 3], [3, -1, 6]), ([0, 0, 0], [5, 0, 0])]
)
def test_circle_along_line_is_cylinder(frame, start, end):
    r = 1.5
    h = float(np.linalg.norm(np.subtract(end, start)))
    surface = K.sweep(circle(r), line(start, end), frame=frame)
    # every point is at distance r from the axis
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, 1, (2, 200))
    x = surface.evaluate(u, v)
    axis = np.subtract(end, start) / h
    rel = x - np.asarray(start, float)
    radial = rel - np.outer(rel @ axis, axis)
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), r, rtol=1e-12)
    patches = surface.to_bezier(32, 6)
    assert isinstance(patches, BezierPatches) and patches.closed_u and not patches.closed_v
    m = area_and_volume(patches)
    np.testing.assert_allclose(m["area"], 2 * np.pi * r * h, rtol=1e-5)
    np.testing.assert_allclose(m["volume"], np.pi * r * r * h, rtol=1e-5)
    assert m["orientation"] == "outward"


def test_frenet_on_straight_line_is_refused():
    with pytest.raises(ValueError, match="Frenet frame is undefined"):
        K.sweep(circle(1.0), line([0, 0, 0], [0, 0, 1]), frame="frenet").evaluate([0.5], [0.5])


@pytest.mark.parametrize("big, small", [(3.0, 1.0), (2.0, 0.5)])
def test_torus_obeys_pappus(big, small):
    surface = K.revolve(circle(small, center=(big, 0.0)))
    patches = surface.to_bezier(32, 48)
    assert patches.closed_u and patches.closed_v
    m = area_and_volume(patches)
    np.testing.assert_allclose(m["area"], 2 * np.pi * big * 2 * np.pi * small, rtol=1e-5)
    np.testing.assert_allclose(m["volume"], 2 * np.pi * big * np.pi * small**2, rtol=1e-5)


def test_open_profile_revolution_area_obeys_pappus():
    """A slanted segment revolved: a frustum, area 2 pi * centroid radius * length."""
    a, b = np.array([1.0, 0.0]), np.array([2.5, 2.0])
    patches = K.revolve(line(a, b)).to_bezier(8, 48)
    length = np.linalg.norm(b - a)
    np.testing.assert_allclose(area_and_volume(patches)["area"], 2 * np.pi * (a[0] + b[0]) / 2 * length,
                               rtol=1e-5)
    assert area_and_volume(patches)["volume"] is None


def test_bspline_profile_revolution_obeys_pappus():
    """A closed B-spline profile: Pappus with the profile's own length, area and centroid."""
    pts = np.array([[2.0, 0.0], [3.0, 0.5], [3.2, 1.5], [2.5, 2.2], [1.8, 1.2]])
    profile = interpolate_curve(pts, closed=True)
    t = np.linspace(0, 1, 20001)[:-1]
    xy, d = profile.evaluate(t), profile.derivative(t)
    dt = 1.0 / t.size
    speed = np.linalg.norm(d, axis=1)
    length = speed.sum() * dt
    cross = xy[:, 0] * d[:, 1] - xy[:, 1] * d[:, 0]
    area2d = 0.5 * cross.sum() * dt
    # centroid radius of the curve (for the area) and of the region (for the volume)
    rc_curve = (xy[:, 0] * speed).sum() * dt / length
    rc_region = (xy[:, 0] ** 2 * d[:, 1]).sum() * dt / 2 / area2d
    m = area_and_volume(K.revolve(profile).to_bezier(40, 48))
    np.testing.assert_allclose(m["area"], 2 * np.pi * rc_curve * length, rtol=1e-5)
    np.testing.assert_allclose(m["volume"], 2 * np.pi * rc_region * abs(area2d), rtol=1e-5)


def test_sphere_by_revolution_closed_by_poles():
    """Half circle from pole to pole revolved: a sphere (rows collapse to poles)."""
    r = 1.3
    half = ParametricCurve(
        lambda t: np.stack([r * np.sin(np.pi * t), -r * np.cos(np.pi * t)], axis=1)
    )
    m = area_and_volume(K.revolve(half).to_bezier(24, 32))
    np.testing.assert_allclose(m["area"], 4 * np.pi * r * r, rtol=1e-5)
    np.testing.assert_allclose(m["volume"], 4 / 3 * np.pi * r**3, rtol=1e-5)
    assert m["volume_method"].endswith("poles)")


@pytest.mark.parametrize("pitch, turns", [(1.0, 2.0), (0.3, 1.5)])
def test_helicoid_points_on_closed_form(pitch, turns):
    inner, outer = 0.5, 2.0
    surface = K.helicoid(inner, outer, pitch, turns)
    c = pitch / (2 * np.pi)
    rng = np.random.default_rng(1)
    u, v = rng.uniform(0, 1, (2, 300))
    x = surface.evaluate(u, v)
    rad, th = inner + (outer - inner) * u, 2 * np.pi * turns * v
    expected = np.stack([rad * np.cos(th), rad * np.sin(th), c * th], axis=1)
    np.testing.assert_allclose(x, expected, atol=1e-12)
    # and the shared-model surface stays on it
    bs = surface.to_bspline(8, int(24 * turns))
    np.testing.assert_allclose(bs.evaluate(u, v), expected, atol=2e-4 * outer)


def test_helicoid_area_closed_form():
    """Area of a helicoid strip: integral of sqrt(r^2 + c^2) dr dtheta."""
    inner, outer, pitch, turns = 0.0, 2.0, 1.0, 1.0
    c = pitch / (2 * np.pi)

    def primitive(r):
        return 0.5 * (r * np.hypot(r, c) + c * c * np.arcsinh(r / c))

    expected = 2 * np.pi * turns * (primitive(outer) - primitive(inner))
    area = area_and_volume(K.helicoid(inner, outer, pitch, turns).to_bezier(8, 24))["area"]
    np.testing.assert_allclose(area, expected, rtol=1e-5)


def test_coil_spring_tube_formulas():
    radius, pitch, turns, wire = 2.0, 1.0, 3.0, 0.3
    length = turns * np.hypot(2 * np.pi * radius, pitch)
    m = area_and_volume(K.coil_spring(radius, pitch, turns, wire).to_bezier(24, 96))
    np.testing.assert_allclose(m["area"], 2 * np.pi * wire * length, rtol=1e-4)
    np.testing.assert_allclose(m["volume"], np.pi * wire**2 * length, rtol=1e-4)


def test_coil_spring_rejects_overlapping_wire():
    with pytest.raises(ValueError, match="overlap"):
        K.coil_spring(2.0, 0.5, 3, 0.3)


def test_screw_thread_profile_radii():
    major, pitch, depth = 3.0, 0.5, 0.2
    surface = K.screw_thread(major, pitch, 4.0, depth)
    g = surface.evaluate_grid(np.linspace(0, 1, 41), np.linspace(0, 1, 97))
    r = np.hypot(g[..., 0], g[..., 1])
    np.testing.assert_allclose([r.min(), r.max()], [major - depth, major], atol=1e-12)
    # one turn later the surface is the same point shifted by one pitch
    x0 = surface.evaluate([0.3], [0.1])
    x1 = surface.evaluate([0.3], [0.1 + 1 / 4.0])
    np.testing.assert_allclose(x1 - x0, [[0, 0, pitch]], atol=1e-12)


def test_closed_thread_profile_runs_back_along_the_root():
    from surfaces.curves import thread_profile

    open_, closed = thread_profile(2.0, 0.3, 0.5), thread_profile(2.0, 0.3, 0.5, closed=True)
    assert not open_.closed and closed.closed
    t = np.linspace(0, 1, 2001)
    pts = closed.evaluate(t)
    np.testing.assert_allclose(pts[0], pts[-1], atol=1e-12)
    np.testing.assert_allclose(pts[0], [2.0, 0.0], atol=1e-12)
    chord = pts[:, 0] <= 2.0 + 1e-12
    assert chord.sum() > 100 and np.all(np.diff(pts[chord & (t > 0.5), 1]) < 0)  # down along r = r0
    # the tooth part is the open profile, reparametrised; derivatives agree with differences away from the corners
    assert np.ptp(pts[:, 0]) == pytest.approx(0.3, rel=1e-3) and np.ptp(pts[:, 1]) == pytest.approx(0.5, rel=1e-3)
    u = np.array([0.2, 0.5, 0.9])
    fd = (closed.evaluate(u + 1e-6) - closed.evaluate(u - 1e-6)) / 2e-6
    np.testing.assert_allclose(closed.derivative(u), fd, rtol=1e-5, atol=1e-6)
    surface = K.screw_thread(2.3, 0.5, 2.0, 0.3, closed=True)
    assert surface.closed_u and not surface.closed_v


def test_closed_directrix_rmf_closes():
    """Pipe around a non-planar closed curve: the corrected RMF closes, C0 seam in v."""
    phi = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    pts = np.stack([3 * np.cos(phi), 2 * np.sin(phi), np.sin(2 * phi)], axis=1)
    path = interpolate_curve(pts, closed=True)
    surface = K.pipe(path, 0.3)
    assert surface.closed_v and surface.closed_u
    u = np.linspace(0, 1, 9)
    np.testing.assert_allclose(surface.evaluate(u, np.zeros(9)), surface.evaluate(u, np.ones(9)),
                               atol=1e-9)
    patches = surface.to_bezier(16, 48)
    assert patches.closed_u and patches.closed_v
    assert area_and_volume(patches)["volume_method"].startswith("divergence theorem (closed")


def test_scale_and_twist_laws():
    surface = K.sweep(line([0.5, 0], [1.0, 0]), line([0, 0, 0], [0, 0, 2]), frame="fixed",
                      scale=(1.0, 2.0), twist=np.pi / 2, up=[1, 0, 0])
    x = surface.evaluate([1.0, 1.0], [0.0, 1.0])
    np.testing.assert_allclose(x, [[1, 0, 0], [0, 2, 2]], atol=1e-12)


def _signed_curvature(curve, u):
    d1, d2 = curve.derivative(u, 1), curve.derivative(u, 2)
    return (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.linalg.norm(d1, axis=1) ** 3


def test_moving_control_points_turns_convex_profile_concave():
    """Seed 004: moving the generatrix basis turns a convex barrel into a waisted one."""
    pts = np.array([[1.0, 0.0], [1.3, 0.5], [1.4, 1.0], [1.3, 1.5], [1.0, 2.0]])
    profile = interpolate_curve(pts)
    barrel = K.revolve(profile)
    ctrl = profile.control.copy()
    ctrl[1:-1, 0] = 2.0 - ctrl[1:-1, 0]  # mirror the inner control points about r = 1
    waist = barrel.deform(generatrix_control=ctrl)
    mid = np.array([0.5])
    k_before = _signed_curvature(barrel.generatrix, mid)[0]
    k_after = _signed_curvature(waist.generatrix, mid)[0]
    assert k_before * k_after < 0
    # the surface follows: normal curvature along u at the middle changes sign
    signs = []
    for surf in (barrel, waist):
        bs = surf.to_bspline(24, 32)
        n = bs.normals(mid, [0.25])
        signs.append(np.sign(np.sum(bs.derivative(mid, [0.25], 2, 0) * n)))
    assert signs[0] * signs[1] < 0
    # the ends (control points not moved) stay put
    np.testing.assert_allclose(waist.evaluate([0.0, 1.0], [0.3, 0.3]),
                               barrel.evaluate([0.0, 1.0], [0.3, 0.3]), atol=1e-12)


def test_moving_directrix_control_points_moves_surface_locally():
    path = _curvy_path()
    surface = K.pipe(path, 0.2)
    ctrl = path.control.copy()
    ctrl[-2] += [0.0, 0.0, 1.0]
    moved = surface.deform(directrix_control=ctrl)
    u = np.linspace(0, 1, 5)
    # cubic: the first control points' spans are untouched near v = 0
    np.testing.assert_allclose(moved.evaluate(u, np.zeros(5)), surface.evaluate(u, np.zeros(5)),
                               atol=1e-12)
    # near the moved control point the tube follows its new centreline
    ring = np.linspace(0, 1, 64, endpoint=False)
    centre = moved.evaluate(ring, np.full(64, 0.85)).mean(axis=0)
    np.testing.assert_allclose(centre, moved.directrix.evaluate([0.85])[0], atol=1e-9)
    assert np.linalg.norm(centre - path.evaluate([0.85])[0]) > 0.2


def test_deform_needs_bspline():
    with pytest.raises(ValueError, match="not a B-spline"):
        K.pipe(line([0, 0, 0], [0, 0, 1]), 0.1).deform(directrix_control=np.zeros((2, 3)))


def test_callable_generatrix_uses_finite_differences():
    ellipse = ParametricCurve(
        lambda t: np.stack([2 * np.cos(2 * np.pi * t), np.sin(2 * np.pi * t)], axis=1), closed=True
    )
    surface = K.sweep(ellipse, line([0, 0, 0], [0, 0, 1.0]))
    m = area_and_volume(surface.to_bezier(48, 6))
    np.testing.assert_allclose(m["volume"], np.pi * 2 * 1 * 1.0, rtol=1e-5)
