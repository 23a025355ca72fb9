"""The torus: closed forms, sections with holes, exact signed distance, area-uniform surface samples."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from skimage.measure import points_in_poly

from datasets_synthetic.phantoms.ring import Ring


def test_torus_closed_forms_and_signed_distance():
    ring = Ring(major_mm=20.0, minor_mm=5.0)
    assert ring.volume_mm3 == pytest.approx(2 * np.pi**2 * 20 * 25)
    assert ring.area_mm2 == pytest.approx(4 * np.pi**2 * 20 * 5)
    np.testing.assert_allclose(ring.signed_distance([[20, 0, 0], [30, 0, 0], [0, 0, 0]]), [-5, 5, 15])
    moved = Ring(major_mm=20.0, minor_mm=5.0, center=(1.0, 2.0, 3.0))
    np.testing.assert_allclose(moved.signed_distance([[21, 2, 3], [1, 2, 3]]), [-5, 15])


def test_sections_have_holes():
    contours = Ring().contours(2.0, n_points=64)
    per_plane = defaultdict(list)
    for c in contours:
        per_plane[c["z"]].append(c["points"])
    assert all(len(v) == 2 for v in per_plane.values())
    outer, inner = per_plane[0.0]
    assert points_in_poly(inner, outer).all()


def test_section_area_and_volume_between_planes():
    ring = Ring(major_mm=25.0, minor_mm=10.0)
    # the annulus between R -+ w, w = sqrt(r^2 - t^2): area 4 pi R w
    np.testing.assert_allclose(ring.section_area_mm2(np.array([0.0, 6.0, 10.0])), 4 * np.pi * 25 * np.array([10, 8, 0]))
    assert ring.volume_between_mm3(0.0, 10.0) == pytest.approx(ring.volume_mm3 / 2, rel=1e-14)
    assert ring._curves(10.0) == []


def test_surface_points_are_uniform_by_area():
    ring = Ring(major_mm=25.0, minor_mm=10.0)
    pts = ring.surface_points(40000, seed=0)
    outer = np.hypot(pts[:, 0], pts[:, 1]) > 25.0
    assert outer.mean() == pytest.approx((np.pi * 25 + 20) / (2 * np.pi * 25), abs=0.01)


def test_tube_must_fit():
    with pytest.raises(ValueError, match="minor_mm: must be below major_mm"):
        Ring(major_mm=5.0, minor_mm=6.0)
