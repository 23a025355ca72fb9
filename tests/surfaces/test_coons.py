"""Coons patches (seed 001): exactness, closed form of the Bezier conversion, sphere."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from surfaces.bezier import BezierPatches
from surfaces.coons import N_B, N_C, coons_to_bezier, from_grid
from surfaces.measure import area, volume
from surfaces.mesh import tessellate


def _bicubic(coeffs, s, t):
    """Vector bicubic polynomial sum c_kl s^k t^l and its partial derivatives."""
    k = np.arange(4)
    ps, pt = s[..., None] ** k, t[..., None] ** k
    dps = np.where(k > 0, k * s[..., None] ** np.maximum(k - 1, 0), 0.0)
    dpt = np.where(k > 0, k * t[..., None] ** np.maximum(k - 1, 0), 0.0)
    value = np.einsum("...k,...l,klx->...x", ps, pt, coeffs)
    ds = np.einsum("...k,...l,klx->...x", dps, pt, coeffs)
    dt = np.einsum("...k,...l,klx->...x", ps, dpt, coeffs)
    dst = np.einsum("...k,...l,klx->...x", dps, dpt, coeffs)
    return value, ds, dt, dst


def test_bicubic_polynomial_reproduced_between_samples():
    rng = np.random.default_rng(1)
    coeffs = rng.normal(size=(4, 4, 3)) * 0.1
    i, j = np.meshgrid(np.arange(6.0), np.arange(5.0), indexing="ij")
    pts, pu, pv, puv = _bicubic(coeffs, i, j)
    patches = from_grid(pts, pu, pv, twist=puv)
    assert patches.shape == (5, 4)
    s = rng.uniform(0, 5, 2000)
    t = rng.uniform(0, 4, 2000)
    s[:5] = [0, 5, 2, 3.5, 5]
    t[:5] = [0, 4, 1, 4, 0]
    truth = _bicubic(coeffs, s, t)[0]
    np.testing.assert_allclose(patches.evaluate_global(s, t), truth, atol=1e-10)
    # derivatives too (per unit of patch parameter = per unit of grid index)
    pi, pj, u, v = patches.locate(s, t)
    d = patches.derivatives(pi, pj, u, v, order=2)
    _, ds, dt, _ = _bicubic(coeffs, s, t)
    np.testing.assert_allclose(d.du, ds, atol=1e-10)
    np.testing.assert_allclose(d.dv, dt, atol=1e-10)


def test_finite_differences_reproduce_quadratics_with_nonuniform_spacing():
    # a quadratic surface sampled at uneven x: chord-free three-point differences are exact
    x = np.array([0.0, 0.7, 1.9, 2.4, 4.0])
    y = np.array([0.0, 1.0, 2.0, 3.0])
    X, Y = np.meshgrid(x, y, indexing="ij")
    pts = np.stack([X, Y, 0.3 * X**2 - 0.2 * X * Y + 0.1 * Y**2], -1)
    patches = from_grid(pts, twist="fd")
    pi, pj, u, v = np.zeros(1, int), np.zeros(1, int), np.zeros(1), np.zeros(1)
    d = patches.derivatives(pi + 1, pj + 1, u, v)
    # at grid point (1, 1) the u tangent is parallel to the exact surface tangent
    exact = np.array([1.0, 0.0, 0.6 * x[1] - 0.2 * y[1]])
    cos = d.du[0] @ exact / np.linalg.norm(d.du[0]) / np.linalg.norm(exact)
    assert cos == pytest.approx(1.0, abs=1e-3)


def test_uniform_grid_matches_seed_central_differences():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(5, 6, 3))
    patches = from_grid(pts, twist="fd", chord_length=False)
    b = patches.control[1, 2]
    p = pts
    pu = (p[2, 2] - p[0, 2]) / 2
    pv = (p[1, 3] - p[1, 1]) / 2
    twist = (p[2, 3] - p[2, 1] - p[0, 3] + p[0, 1]) / 4
    np.testing.assert_allclose(b[0, 0], p[1, 2], atol=1e-14)
    np.testing.assert_allclose(b[1, 0], p[1, 2] + pu / 3, atol=1e-14)
    np.testing.assert_allclose(b[0, 1], p[1, 2] + pv / 3, atol=1e-14)
    np.testing.assert_allclose(b[1, 1], p[1, 2] + (pu + pv) / 3 + twist / 9, atol=1e-14)


def _closed_form(geom):
    """Rogers & Adams closed form of the Coons -> Bezier conversion."""
    P = geom[:2, :2]
    Pv = geom[:2, 2:]
    Pu = geom[2:, :2]
    T = geom[2:, 2:]
    out = np.empty((4, 4, 3))
    su = np.array([1.0, -1.0])  # sign of the tangent step at u = 0 and u = 1
    for a in range(2):
        for b in range(2):
            ia, ib = 3 * a, 3 * b
            da, db = 1 - 2 * a, 1 - 2 * b  # step direction into the patch
            out[ia, ib] = P[a, b]
            out[ia + da, ib] = P[a, b] + su[a] * Pu[a, b] / 3
            out[ia, ib + db] = P[a, b] + su[b] * Pv[a, b] / 3
            out[ia + da, ib + db] = (
                P[a, b] + su[a] * Pu[a, b] / 3 + su[b] * Pv[a, b] / 3 + su[a] * su[b] * T[a, b] / 9
            )
    return out


finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, (4, 4, 3), elements=finite))
def test_conversion_equals_closed_form(geom):
    np.testing.assert_allclose(coons_to_bezier(geom), _closed_form(geom), atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, (4, 4, 3), elements=finite),
    arrays(np.float64, (16,), elements=st.floats(0, 1)),
    arrays(np.float64, (16,), elements=st.floats(0, 1)),
)
def test_bezier_equals_coons_at_random_parameters(geom, u, v):
    patch = BezierPatches(coons_to_bezier(geom)[None, None])
    U = np.stack([u**3, u**2, u, np.ones_like(u)], -1)
    V = np.stack([v**3, v**2, v, np.ones_like(v)], -1)
    coons = np.einsum("na,ab,bcx,dc,nd->nx", U, N_C, geom, N_C, V)
    bez = patch.evaluate(np.zeros(16, int), np.zeros(16, int), u, v)
    scale = max(1.0, float(np.abs(geom).max()))
    np.testing.assert_allclose(bez, coons, atol=1e-12 * scale * 10)
    # and the matrix relation of eq. 7 itself
    K = np.linalg.solve(N_B, N_C)
    np.testing.assert_allclose(np.einsum("ab,bcx,dc->adx", K, geom, K), coons_to_bezier(geom), atol=1e-9)


def _sphere_grid(r, nu=32, nv=16):
    th = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    ph = np.linspace(np.pi, 0, nv + 1)  # south pole to north pole: du x dv points out
    TH, PH = np.meshgrid(th, ph, indexing="ij")
    s, c = np.sin(PH), np.cos(PH)
    pts = r * np.stack([s * np.cos(TH), s * np.sin(TH), c], -1)
    dth, dph = 2 * np.pi / nu, -np.pi / nv
    pu = r * np.stack([-s * np.sin(TH), s * np.cos(TH), 0 * PH], -1) * dth
    pv = r * np.stack([c * np.cos(TH), c * np.sin(TH), -s], -1) * dph
    puv = r * np.stack([-c * np.sin(TH), c * np.cos(TH), 0 * PH], -1) * dth * dph
    return pts, pu, pv, puv


@pytest.mark.parametrize("twist", ["zero", "exact"])
def test_sphere_area_volume_watertight(twist):
    r = 3.0
    pts, pu, pv, puv = _sphere_grid(r)
    patches = from_grid(pts, pu, pv, twist=puv if twist == "exact" else "zero", closed_u=True)
    a, err = area(patches, return_error=True)
    assert err < 1e-9 * a
    assert a == pytest.approx(4 * np.pi * r**2, rel=1e-3)
    assert volume(patches) == pytest.approx(4 / 3 * np.pi * r**3, rel=1e-3)
    mesh = tessellate(patches, 6)
    assert mesh.is_watertight()
    assert mesh.is_oriented()
    assert mesh.signed_volume() > 0  # consistently outward
    outward = np.einsum("ij,ij->i", mesh.vertex_normals, mesh.vertices / r)
    assert outward.min() > 0.999
    np.testing.assert_allclose(np.linalg.norm(mesh.vertices, axis=1), r, rtol=1e-3)
    # face normals agree with the patch normals
    fn = mesh.face_normals()
    vn = mesh.vertex_normals[mesh.triangles].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", fn, vn) > 0.9)


def test_closed_grid_may_repeat_its_first_row():
    pts, pu, pv, _ = _sphere_grid(1.0)
    a = from_grid(pts, pu, pv, closed_u=True)
    b = from_grid(np.concatenate([pts, pts[:1]]), np.concatenate([pu, pu[:1]]),
                  np.concatenate([pv, pv[:1]]), closed_u=True)
    np.testing.assert_array_equal(a.control, b.control)


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((3, 3)), "expected shape"),
        (np.zeros((1, 4, 3)), "at least 2x2"),
        (np.full((3, 3, 3), np.nan), "NaN"),
    ],
)
def test_bad_grids_raise(points, message):
    with pytest.raises(ValueError, match=message):
        from_grid(points)


def test_bad_tangent_shape_and_twist():
    pts = np.random.default_rng(0).normal(size=(4, 4, 3))
    with pytest.raises(ValueError, match="pu"):
        from_grid(pts, pu=np.zeros((3, 4, 3)))
    with pytest.raises(ValueError, match="twist"):
        from_grid(pts, twist="nope")


def test_collapsed_row_pole_without_tangents():
    # a cone apex: the whole first row is one point; finite differences must not divide by zero
    th = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    h = np.linspace(0, 1, 5)
    TH, H = np.meshgrid(th, h, indexing="ij")
    pts = np.stack([H * np.cos(TH), H * np.sin(TH), 1 - H], -1)
    patches = from_grid(pts, closed_u=True)
    assert np.all(np.isfinite(patches.control))
    mesh = tessellate(patches, 4)
    assert np.all(np.isfinite(mesh.vertex_normals))
    np.testing.assert_allclose(np.linalg.norm(mesh.vertex_normals, axis=1), 1.0)
