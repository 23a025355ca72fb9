"""The phantom base: curve and surface samplers, plane grids, truth records, signed distances."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from datasets_synthetic.phantoms import MIN_SECTION_FRACTION, DistancePhantom, Phantom, make_phantom
from datasets_synthetic.phantoms.base import (
    _perimeter,
    _sample_closed,
    clamped_unit,
    ellipse_curve,
    rejection_sample,
    uniform_sphere,
)


def test_ellipse_curve_and_perimeter():
    circle = ellipse_curve(1.0, -1.0, 2.0, 2.0)
    np.testing.assert_allclose(circle(np.array([0.0, 0.25, 0.5])), [[3, -1], [1, 1], [-1, -1]], atol=1e-12)
    assert _perimeter(circle) == pytest.approx(4 * np.pi, rel=1e-5)


def test_samples_are_equally_spaced_in_arc_length():
    # on an ellipse parameterised by angle, equal steps in t are unequal in arc length
    curve = ellipse_curve(0.0, 0.0, 10.0, 2.0)
    pts = _sample_closed(curve, 50, 0.3)
    fine = curve(np.arange(200001) / 200000)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(fine, axis=0), axis=1))])
    s = arc[cKDTree(fine).query(pts)[1]]
    steps = np.diff(np.append(s, s[0] + arc[-1]))
    assert steps.std() < 1e-3 * steps.mean()
    # the phase moves the start by that fraction of a step
    start = _sample_closed(curve, 50, 0.0)
    assert np.linalg.norm(pts[0] - start[0]) == pytest.approx(0.3 * steps.mean(), rel=0.05)


def test_uniform_sphere_and_rejection():
    rng = np.random.default_rng(0)
    v = uniform_sphere(rng, 20000)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0)
    assert np.abs(v.mean(axis=0)).max() < 0.02

    def propose(rng, m):  # upper hemisphere only: density 1 for z > 0, else 0
        p = uniform_sphere(rng, m)
        return p, (p[:, 2] > 0).astype(float)

    kept = rejection_sample(rng, 5000, propose, 1.0)
    assert kept.shape == (5000, 3) and np.all(kept[:, 2] > 0)


def test_clamped_unit():
    np.testing.assert_allclose(clamped_unit([-20.0, 0.0, 5.0, 20.0], 5.0, 10.0), [-1.0, -0.5, 0.0, 1.0])


def test_every_shape_is_a_phantom():
    for shape in ("ellipsoid", "kidney", "ring", "lobes", "tilted_cylinder"):
        assert isinstance(make_phantom(shape), Phantom)
    assert {s for s in ("ring", "lobes", "tilted_cylinder") if isinstance(make_phantom(s), DistancePhantom)} == {
        "ring", "lobes", "tilted_cylinder"}
    assert not isinstance(make_phantom("ellipsoid"), DistancePhantom)


def test_plane_grid_offset_and_truth_record():
    ph = make_phantom("ellipsoid", a=10.0, b=8.0, c=6.0, center=(0.0, 0.0, 1.0))
    z = ph.plane_positions(2.0, offset_mm=0.5)
    np.testing.assert_allclose(z, [-4.5, -2.5, -0.5, 1.5, 3.5, 5.5])
    truth = ph.truth(2.0, 0.5)
    assert truth["planes_mm"] == z.tolist() and truth["n_planes"] == 6 and truth["offset_mm"] == 0.5
    assert truth["skipped_planes_mm"] == [] and truth["shape"] == "ellipsoid"
    assert truth["params"] == {"center_mm": [0.0, 0.0, 1.0], "a_mm": 10.0, "b_mm": 8.0, "c_mm": 6.0}
    assert truth["volume_between_end_planes_mm3"] == pytest.approx(ph.volume_between_mm3(-4.5, 5.5))
    np.testing.assert_allclose(truth["section_areas_mm2"], ph.section_area_mm2(z))
    assert f"{MIN_SECTION_FRACTION:g}" in truth["skipped_planes_rule"]


def test_surface_points_need_a_count():
    with pytest.raises(ValueError, match="n: expected a whole number"):
        make_phantom("ring").surface_points(0)


@pytest.mark.parametrize("shape", ["ring", "lobes", "tilted_cylinder"])
def test_signed_distance_against_a_dense_surface_sample(shape):
    from scipy.spatial import cKDTree

    ph = make_phantom(shape)
    surface = ph.surface_points(200000, seed=1)
    lower, upper = ph.bounds
    pts = lower - 3 + np.random.default_rng(2).random((2000, 3)) * (upper - lower + 6)
    sd = ph.signed_distance(pts)
    np.testing.assert_array_equal(sd <= 0, ph.inside(pts))
    nearest = cKDTree(surface).query(pts)[0]
    # the sample spacing is ~0.3 mm: the sample's distance is never smaller, and close
    assert np.all(nearest >= np.abs(sd) - 1e-9)
    assert np.all(nearest - np.abs(sd) < 0.5)
    assert np.mean(nearest - np.abs(sd)) < 0.15


def test_signed_distance_checks_its_points():
    with pytest.raises(ValueError, match="points"):
        make_phantom("ring").signed_distance(np.zeros((3, 2)))
