"""Small structures (issue 19): the planning systems' slab count beside ours, on lens- and chiasm-sized phantoms."""

from __future__ import annotations


import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from slices.chaining import planning_volumes, slab_volume
from slices.polygons import clean_contour
from slices.io import Contour


def _stack(shape: str, spacing: float, n_points: int = 256):
    ph = make_phantom(shape)
    conts = [Contour(c["z"], clean_contour(c["points"])) for c in ph.contours(spacing, n_points=n_points)]
    return ph, conts


@pytest.mark.parametrize("shape", ["lens", "chiasm"])
@pytest.mark.parametrize("spacing", [2.0, 2.5, 3.0])
def test_planning_counts_match_their_closed_forms(shape, spacing):
    ph, conts = _stack(shape, spacing)
    assert 1 <= len(conts) <= 5
    z = np.array([c.z for c in conts])
    sections = ph.section_area_mm2(z)  # the exact ellipse areas of the cut planes
    got = planning_volumes(conts, spacing)
    assert got["small_structure"] and got["n_planes"] == len(conts)
    # polygons of 256 points on ellipses inscribe them to about 1e-4 of the area
    assert got["slab_full_ends"] == pytest.approx(sections.sum() * spacing, rel=2e-3)
    weight = np.ones(len(z))
    weight[[0, -1]] = 0.5  # a single plane: half a slab
    half = float(np.sum(weight * sections)) * spacing
    assert got["slab_half_ends"] == pytest.approx(half, rel=2e-3)
    assert got["slab_half_ends"] == slab_volume(conts, spacing)


@pytest.mark.parametrize("shape", ["lens", "chiasm"])
def test_whole_end_slabs_count_a_small_ellipsoid_close_to_its_volume(shape):
    # the midpoint rule of the ellipsoid's sections: within a few percent at CT spacings, while half
    # end slabs lose a quarter or more (what separates the planning systems on a lens)
    ph = make_phantom(shape)
    for spacing in (2.0, 2.5):  # at 3 mm the chiasm is a single contour: no rule recovers its volume
        _, conts = _stack(shape, spacing)
        got = planning_volumes(conts, spacing)
        assert got["slab_full_ends"] == pytest.approx(ph.volume_mm3, rel=0.07)
        assert got["slab_half_ends"] < 0.85 * ph.volume_mm3


def test_holes_and_uneven_planes():
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    disc = np.stack([np.cos(t), np.sin(t)], 1)
    conts = [Contour(z, clean_contour(r * disc)) for z in (0.0, 1.0, 3.0) for r in (10.0, 4.0)]
    area = abs(0.5 * np.sum(disc[:, 0] * np.roll(disc[:, 1], -1) - disc[:, 1] * np.roll(disc[:, 0], -1)))
    ring = area * (100 - 16)
    got = planning_volumes(conts, None)
    # slabs reach half-way to the neighbours; the ends' outer halves use the median gap (1.5 mm)
    assert got["slab_full_ends"] == pytest.approx(ring * ((0.75 + 0.5) + (0.5 + 1.0) + (1.0 + 0.75)), rel=1e-12)
    assert got["slab_half_ends"] == pytest.approx(slab_volume(conts, None), rel=1e-12)
    single = planning_volumes(conts[:2], 2.0)
    assert single["slab_full_ends"] == pytest.approx(ring * 2.0, rel=1e-12) and single["n_planes"] == 1
