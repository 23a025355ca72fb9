"""Area and volume of the patch model (surfaces.measure) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.bezier import BezierPatches
from surfaces.curves import ParametricCurve, circle, line
from surfaces.kinematic import revolve, sweep
from surfaces.measure import area, area_and_volume, cap_flux, flux_z, integrals, volume


def flat_patches(width: float, height: float, z: float, rows: int = 2, cols: int = 3) -> BezierPatches:
    """The rectangle [0, width] x [0, height] at height z as rows x cols patches, normal +z."""
    u = np.linspace(0.0, width, 3 * rows + 1)
    v = np.linspace(0.0, height, 3 * cols + 1)
    X, Y = np.meshgrid(u, v, indexing="ij")
    grid = np.stack([X, Y, np.full_like(X, z)], -1)
    control = np.stack(
        [[grid[3 * i : 3 * i + 4, 3 * j : 3 * j + 4] for j in range(cols)] for i in range(rows)]
    )
    return BezierPatches(control)


def test_flat_rectangle_area_volume_and_flux():
    """A w x h rectangle at height c: area w h, flux of (0, 0, z) = c w h, volume term c w h / 3."""
    p = flat_patches(2.0, 3.0, 1.5)
    assert area(p) == pytest.approx(6.0, rel=1e-14)
    per = area(p, per_patch=True)
    assert per.shape == (2, 3) and np.allclose(per, 1.0)
    value, error = area(p, return_error=True)
    assert value == pytest.approx(6.0) and error < 1e-12
    assert flux_z(p) == pytest.approx(1.5 * 6.0, rel=1e-14)
    assert volume(p) == pytest.approx(1.5 * 6.0 / 3.0, rel=1e-14)
    vol, ar = integrals(p)
    assert vol == pytest.approx(volume(p), rel=1e-14) and ar == pytest.approx(6.0, rel=1e-12)
    assert volume(p.flipped()) == pytest.approx(-volume(p), rel=1e-14)


def test_quadrature_order_is_checked():
    with pytest.raises(ValueError, match="order"):
        area(flat_patches(1.0, 1.0, 0.0), order=0)
    with pytest.raises(ValueError, match="patches: expected BezierPatches"):
        volume(np.zeros((1, 1, 4, 4, 3)))


def test_cylinder_lateral_flux_alone():
    """Without caps, the lateral flux of a z-axis cylinder is (2/3) pi r^2 h."""
    r, h = 2.0, 3.0
    patches = sweep(circle(r), line([0, 0, 0], [0, 0, h])).to_bezier(32, 6)
    np.testing.assert_allclose(volume(patches), 2 / 3 * np.pi * r * r * h, rtol=1e-5)
    np.testing.assert_allclose(cap_flux(patches) / 3, np.pi * r * r * h / 3, rtol=1e-5)


@pytest.mark.parametrize("r, h", [(1.0, 2.0), (0.5, 4.0)])
def test_tube_closed_by_caps_is_a_cylinder(r, h):
    m = area_and_volume(sweep(circle(r), line([0, 0, 0], [0, 0, h])).to_bezier(32, 6))
    assert m["area"] == pytest.approx(2 * np.pi * r * h, rel=1e-5)
    assert m["volume"] == pytest.approx(np.pi * r * r * h, rel=1e-5)
    assert m["volume_method"] == "divergence theorem + end caps" and m["orientation"] == "outward"


def test_sphere_closed_by_poles_and_open_surfaces():
    """A half circle revolved: closed by its poles, volume 4/3 pi; a flat sheet bounds nothing."""
    half = ParametricCurve(lambda t: np.stack([np.sin(np.pi * t), -np.cos(np.pi * t)], axis=1))
    m = area_and_volume(revolve(half).to_bezier(24, 32))
    assert m["volume_method"] == "divergence theorem (closed by poles)"
    assert m["volume"] == pytest.approx(4 / 3 * np.pi, rel=1e-5) and m["area"] == pytest.approx(4 * np.pi, rel=1e-5)
    sheet = area_and_volume(flat_patches(1.0, 1.0, 0.0))
    assert sheet["volume"] is None and sheet["area"] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="caps close a surface"):
        cap_flux(flat_patches(1.0, 1.0, 0.0))


def test_gauss_nodes_cached_read_only_and_exact():
    from surfaces.measure import gauss_legendre

    t, w = gauss_legendre(5)
    t2, w2 = gauss_legendre(5)
    assert t is t2 and w is w2
    assert not t.flags.writeable and not w.flags.writeable
    x, v = np.polynomial.legendre.leggauss(5)
    np.testing.assert_array_equal(t, 0.5 * (x + 1.0))
    np.testing.assert_array_equal(w, 0.5 * v)
    with pytest.raises(ValueError, match="order"):
        gauss_legendre(0)


@pytest.mark.parametrize("shape", [(1, 1), (7, 3), (300, 2)])
def test_side_integrals_equal_flux_z_and_area_on_a_view_of_some_columns(shape):
    from surfaces.measure import side_integrals

    rng = np.random.default_rng(shape[0])
    grid = rng.normal(size=(shape[0], shape[1] + 2, 4, 4, 3))
    columns = grid[:, 1:-1]  # not contiguous
    patches = BezierPatches(columns)
    flux, ar = side_integrals(columns)
    assert flux == pytest.approx(flux_z(patches), rel=1e-12)
    assert ar == pytest.approx(area(patches, order=5), rel=1e-12)


@pytest.mark.parametrize("shape", [(1, 1), (9, 4), (400, 3)])
def test_side_integrals_of_layered_patches_equal_flux_z_and_area(shape):
    """Patches whose rows of control points lie at one height each (a side between planar slices) take
    the horizontal-S_u path; mixed with patches that do not, every chunk takes its own."""
    from surfaces.measure import side_integrals

    rng = np.random.default_rng(shape[0] + 1)
    grid = rng.normal(size=shape + (4, 4, 3))
    grid[..., 2] = rng.normal(size=shape + (1, 4))  # z by patch and v index alone
    patches = BezierPatches(grid)
    flux, ar = side_integrals(grid)
    assert flux == pytest.approx(flux_z(patches), rel=1e-12)
    assert ar == pytest.approx(area(patches, order=5), rel=1e-12)
    mixed = grid.copy()
    mixed[-1, -1, 1, 2, 2] += 0.5  # one patch's row no longer level
    patches = BezierPatches(mixed)
    flux, ar = side_integrals(mixed)
    assert flux == pytest.approx(flux_z(patches), rel=1e-12)
    assert ar == pytest.approx(area(patches, order=5), rel=1e-12)
