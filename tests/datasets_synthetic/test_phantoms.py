"""CT phantoms, every shape: exact volumes against numerical integrals, contours on the true outline."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from scipy.integrate import quad, simpson
from skimage.measure import points_in_poly

from datasets_synthetic.phantoms import SHAPES, Kidney, make_phantom, write_phantom
from slices.polygons import signed_area


def _plane_areas(contours):
    """Area per plane from polygons; a contour nested in an odd number of others is a hole."""
    planes = defaultdict(list)
    for c in contours:
        planes[c["z"]].append(c["points"])
    zs = np.array(sorted(planes))
    areas = []
    for z in zs:
        polys = planes[z]
        total = 0.0
        for i, p in enumerate(polys):
            depth = sum(points_in_poly(p[:1], q)[0] for j, q in enumerate(polys) if j != i)
            total += (-1) ** depth * abs(signed_area(p))
        areas.append(total)
    return zs, np.array(areas)


@pytest.mark.parametrize("shape", SHAPES)
def test_volume_between_end_planes_matches_the_section_integral(shape):
    ph = make_phantom(shape)
    lo, hi = ph.z_range
    assert ph.volume_between_mm3(lo, hi) == pytest.approx(ph.volume_mm3, rel=1e-10)
    assert ph.volume_between_mm3(lo - 5, hi + 5) == pytest.approx(ph.volume_mm3, rel=1e-10)
    a, b = lo + 0.3 * (hi - lo), lo + 0.8 * (hi - lo)
    numeric = quad(lambda z: float(ph.section_area_mm2(np.array([z]))[0]), a, b, limit=200,
                   epsrel=1e-11)[0]
    assert ph.volume_between_mm3(a, b) == pytest.approx(numeric, rel=1e-7)
    assert ph.volume_between_mm3(b, b) == 0.0


@pytest.mark.parametrize("shape", SHAPES)
def test_exact_volume_agrees_with_integrated_contour_areas(shape):
    ph = make_phantom(shape)
    contours = ph.contours(0.5, n_points=900, seed=1)
    zs, areas = _plane_areas(contours)
    np.testing.assert_allclose(areas, ph.section_area_mm2(zs), rtol=2e-3, atol=0.05)
    between = ph.volume_between_mm3(zs[0], zs[-1])
    assert simpson(areas, x=zs) == pytest.approx(between, rel=2e-3)
    truth = ph.truth(0.5)
    assert truth["volume_between_end_planes_mm3"] == pytest.approx(between)
    assert truth["z_first_contour_mm"] == zs[0] and truth["z_last_contour_mm"] == zs[-1]


@pytest.mark.parametrize("shape", SHAPES)
def test_inside_agrees_with_the_volume(shape):
    ph = make_phantom(shape)
    lower, upper = ph.bounds
    rng = np.random.default_rng(0)
    pts = lower + rng.random((200000, 3)) * (upper - lower)
    estimate = ph.inside(pts).mean() * np.prod(upper - lower)
    assert estimate == pytest.approx(ph.volume_mm3, rel=0.02)


def _on_boundary(ph, pts, eps=1e-6):
    rng = np.random.default_rng(5)
    dirs = rng.standard_normal((8, pts.shape[1]))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    if pts.shape[1] == 2:
        raise AssertionError("pass 3-D points")
    states = np.stack([ph.inside(pts + eps * d) for d in dirs])
    return states.any(axis=0) & ~states.all(axis=0)


@pytest.mark.parametrize("shape", SHAPES)
def test_contour_points_lie_on_the_true_outline(shape):
    ph = make_phantom(shape)
    contours = ph.contours(2.5, n_points=48, seed=2)
    counts = [len(c["points"]) for c in contours]
    assert len(set(counts)) > 1  # unequal numbers of points per contour
    for c in contours:
        assert c["points"].shape[1] == 2 and c["points"].dtype == np.float64
        assert signed_area(c["points"]) > 0  # counter-clockwise
    pts = np.concatenate([np.column_stack([c["points"], np.full(len(c["points"]), c["z"])])
                          for c in contours])
    assert _on_boundary(ph, pts).mean() > 0.97
    assert not _on_boundary(ph, pts + [0.05, 0.05, 0.0]).any()


@pytest.mark.parametrize("shape", SHAPES)
def test_surface_points_lie_on_the_surface(shape):
    ph = make_phantom(shape)
    pts = ph.surface_points(3000, seed=3)
    assert pts.shape == (3000, 3)
    assert _on_boundary(ph, pts).mean() > 0.97
    np.testing.assert_array_equal(pts, ph.surface_points(3000, seed=3))


def test_contour_noise_is_reproducible_and_of_the_stated_size():
    ph = make_phantom("ellipsoid")
    clean = ph.contours(5.0, n_points=200, seed=4)
    noisy = ph.contours(5.0, n_points=200, noise_mm=0.1, seed=4)
    diff = np.concatenate([n["points"] - c["points"] for n, c in zip(noisy, clean)])
    assert np.std(diff) == pytest.approx(0.1, rel=0.1)
    again = ph.contours(5.0, n_points=200, noise_mm=0.1, seed=4)
    np.testing.assert_array_equal(again[3]["points"], noisy[3]["points"])


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: make_phantom("cube"), "shape"),
        (lambda: make_phantom("ring", major_mm=5.0, minor_mm=6.0), "minor_mm"),
        (lambda: make_phantom("ellipsoid", radius=3.0), "params"),
        (lambda: make_phantom("lobes", centers_mm=((0, 0, 0), (50, 0, 0))), "centers_mm"),
        (lambda: make_phantom("tilted_cylinder", tilt_deg=0.0), "tilt_deg"),
        (lambda: Kidney(bend_radius_mm=5.0, thickness_mm=8.0), "bend_radius_mm"),
        (lambda: make_phantom("ellipsoid").contours(100.0, offset_mm=50.0), "spacing_mm"),
        (lambda: make_phantom("ellipsoid").contours(2.0, n_points=3), "n_points"),
        (lambda: make_phantom("ellipsoid").inside(np.zeros((4, 2))), "points"),
        (lambda: write_phantom("/tmp", make_phantom("ring"), 2.0, 1.0, fmt="nifti"), "fmt"),
    ],
)
def test_bad_input_names_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()
