"""Slice curves on a common lattice and side surfaces through them."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from slices.control_points import clean_contour
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
