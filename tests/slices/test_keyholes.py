"""Keyholes (issue 19): a hole reached by a zero-width cut is opened into an outer contour and a hole."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slices.polygons import clean_contour, signed_area
from slices.io import Contour, open_keyholes, read_contour_json
from slices.structure import reconstruct_contours


def _ring(r, n, cx=0.0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([cx + r * np.cos(t), r * np.sin(t)], axis=1)


def _keyhole(outer, hole, cut_points=0):
    """The outer loop from its vertex 0, in along a straight cut to the hole's vertex 0, round the hole the
    other way, and back along the cut: every cut vertex comes twice."""
    a, b = outer[0], hole[0]
    cut = a + np.linspace(0, 1, cut_points + 2)[1:-1, None] * (b - a)
    return np.concatenate([outer, outer[:1], cut, hole[:1], hole[:0:-1], hole[:1], cut[::-1]])


@pytest.mark.parametrize("cut_points", [0, 3])
def test_keyhole_opens_into_outer_and_hole(cut_points):
    outer, hole = _ring(20.0, 64), _ring(6.0, 32, cx=4.0)
    loops = open_keyholes(_keyhole(outer, hole, cut_points))
    assert len(loops) == 2
    assert [len(q) for q in loops] == [64, 32]
    # the same vertices (the cut's are gone), in the same cyclic order
    np.testing.assert_allclose(loops[0], np.roll(outer, -int(np.argmin(np.linalg.norm(outer - loops[0][0], axis=1))),
                                                 axis=0))
    assert signed_area(loops[0]) == pytest.approx(signed_area(outer))
    assert signed_area(loops[1]) == pytest.approx(-signed_area(hole))  # traversed the other way round


def test_a_simple_contour_is_left_alone():
    ring = _ring(5.0, 12)
    (loop,) = open_keyholes(ring)
    assert loop is ring or np.array_equal(loop, ring)
    with pytest.raises(ValueError, match="self-intersecting"):  # a real crossing is still refused
        clean_contour([[0, 0], [2, 2], [2, 0], [0, 2]])


def test_keyhole_stack_reconstructs_like_outer_and_hole(tmp_path):
    outer, hole = _ring(20.0, 64), _ring(6.0, 32, cx=4.0)
    planes = np.arange(0.0, 22.0, 2.0)
    path = tmp_path / "keyhole.json"
    path.write_text(json.dumps({"contours": [{"z": z, "points": _keyhole(outer, hole, 2).tolist()}
                                             for z in planes]}))
    stack = read_contour_json(path)
    assert len(stack.contours) == 2 * len(planes)
    assert any("keyhole" in n for n in stack.notes)
    keyed = reconstruct_contours(stack.contours, surface_path="coons", caps="half", mesh=False, n_rays=32)
    pair = reconstruct_contours([Contour(z, clean_contour(c)) for z in planes for c in (outer, hole)],
                                surface_path="coons", caps="half", mesh=False, n_rays=32)
    assert [b.body.kind for b in keyed.bodies] == ["outer", "hole"]
    assert keyed.volume_mm3 == pytest.approx(pair.volume_mm3, rel=5e-3)
    # half caps: each polygon section times one spacing per plane
    exact = (signed_area(outer) - signed_area(hole)) * len(planes) * 2.0
    assert keyed.volume_mm3 == pytest.approx(exact, rel=5e-3)
