"""Two overlapping spheres: lens closed forms, branching sections, signed distance of a union."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from datasets_synthetic.phantoms.lobes import Lobes


def test_lobes_closed_forms():
    lobes = Lobes(radii_mm=(10.0, 10.0), centers_mm=((0, 0, 0), (10.0, 0, 0)))
    # two equal spheres at distance r: each buried cap has height r/2
    r = 10.0
    lens = 2 * np.pi * (r / 2) ** 2 * (3 * r - r / 2) / 3
    assert lobes.volume_mm3 == pytest.approx(2 * 4 / 3 * np.pi * r**3 - lens)
    assert lobes.area_mm2 == pytest.approx(2 * (4 * np.pi * r * r - 2 * np.pi * r * r / 2))


def test_sections_branch():
    n_per_plane = defaultdict(int)
    for c in Lobes().contours(1.0, n_points=64):
        n_per_plane[c["z"]] += 1
    assert set(n_per_plane.values()) == {1, 2}


def test_signed_distance_of_the_union():
    lobes = Lobes(radii_mm=(10.0, 10.0), centers_mm=((0, 0, 0), (10.0, 0, 0)))
    pts = np.array([[-10.0, 0, 0], [-15.0, 0, 0], [0, 0, 0], [5.0, 0, 0], [5.0, 0, 5 * np.sqrt(3)]])
    # the pole, 5 mm beyond it, a sphere's centre (10 from its far wall), the midpoint (nearest: the
    # rim of the intersection circle at radius 5 sqrt 3), a point on that rim
    np.testing.assert_allclose(lobes.signed_distance(pts), [0, 5, -10, -5 * np.sqrt(3), 0], atol=1e-12)
    rng = np.random.default_rng(0)
    q = rng.uniform(-15, 25, (5000, 3))
    np.testing.assert_array_equal(lobes.inside(q), lobes.signed_distance(q) <= 0)


def test_spheres_must_overlap():
    with pytest.raises(ValueError, match="centers_mm"):
        Lobes(centers_mm=((0, 0, 0), (50, 0, 0)))
    with pytest.raises(ValueError, match="radii_mm"):
        Lobes(radii_mm=(10.0, -1.0))
