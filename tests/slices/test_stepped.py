"""Stepped slabs: the last resort where every fallback surface folds (issue 19, Lt Lung's causes)."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.fold_stacks import FOLD_STACKS, closing_c_stack, fold_stack, hook_stack
from slices.body import FALLBACKS, build_body, build_stepped
from slices.caps import end_kinds
from slices.chaining import chain
from slices.polygons import signed_area
from slices.options import surface_options
from slices.structure import SLIVER_FRACTIONS, _collapse_slivers, _unfold_slivers, reconstruct_contours
from slices.summary import chaining_text
from surfaces.intersect import self_intersections
from surfaces.mesh import TriangleMesh
from tests.slices._stacks import circle
from tests.slices.test_solids import assert_clean_solid

OPTIONS = surface_options(None, caps="half", samples=2)

#: Per phantom: the coarsest mesh on which every surface folds, and the pieces the steps leave (the hook
#: is on plane 2 of 5: slabs 1-2 and 2-3 fold, 0-1 and 3-4 keep their blend; the C closes between 1 and 2).
CASES = {"hook": (1, [2, 1, 2]), "closing_c": (2, [2, 2])}


@pytest.mark.parametrize("name", sorted(CASES))
def test_stepped_slabs_unfold_the_fold_phantoms(name):
    samples, sizes = CASES[name]
    conts = fold_stack(name)
    (body,) = chain(conts, 3.0)
    whole = build_body(body, 3.0, surface_options(OPTIONS, samples=samples))
    # the cleanest of all fallback surfaces still folds: the cause is reproduced
    assert whole.self_intersecting_faces > 0
    assert whole.surface in [n for n, _ in FALLBACKS] + ["blending (seed)"]
    rec = reconstruct_contours(conts, surface_path="coons", caps="half", samples=samples)
    pieces = rec.bodies
    assert [len(p.body.contours) for p in pieces] == sizes
    assert all(p.self_intersecting_faces == 0 for p in pieces)
    # the pieces cover the chain in order; cuts are "step" ends with half caps, the true ends stay
    ordered = [c for p in pieces for c in p.body.contours]
    assert len(ordered) == len(body.contours) and all(a is b for a, b in zip(ordered, body.contours))
    assert pieces[0].body.start == "end" and pieces[-1].body.stop == "end"
    for low, high in zip(pieces[:-1], pieces[1:]):
        assert low.body.stop == high.body.start == "step"
        assert low.caps_used[1] == high.caps_used[0] == "half"
    n = len(sizes) - 1
    assert f"{n} {'slab' if n == 1 else 'slabs'} stepped" in chaining_text(rec)
    # a stepped slab encloses what the blend did, to the trapezoid rule
    assert rec.volume_mm3 == pytest.approx(whole.volume_mm3, rel=0.01)
    solid, united = rec.solid_mesh()
    assert united
    assert_clean_solid(solid)
    assert solid.signed_volume() == pytest.approx(rec.volume_mm3, rel=0.01)


def test_a_clean_body_is_not_stepped():
    (body,) = chain([c for c in closing_c_stack(n_open=1, n_closed=3)[1:]], 3.0)
    pieces = build_stepped(body, 3.0, OPTIONS)
    assert len(pieces) == 1 and pieces[0].body is body and pieces[0].self_intersecting_faces == 0
    # without the fold check there is nothing to step
    (folding,) = chain(hook_stack(), 3.0)
    coarse = surface_options(OPTIONS, samples=1)
    assert len(build_stepped(folding, 3.0, surface_options(coarse, unfold=False))) == 1
    assert len(build_stepped(folding, 3.0, coarse, mesh=False)) == 1


def test_step_ends_get_half_caps_under_every_cap_option():
    for caps in ("none", "flat", "half", "dome"):
        assert end_kinds(caps, "step", "step", n_contours=3) == ("half", "half")
        assert end_kinds(caps, "end", "step", n_contours=1)[1] == "half"


def test_fold_phantoms_check_their_parameters():
    with pytest.raises(ValueError, match="n_planes"):
        hook_stack(n_planes=2)
    with pytest.raises(ValueError, match="neck"):
        hook_stack(neck=2.0, gap=3.0, height=4.0)
    with pytest.raises(ValueError, match="cavity"):
        closing_c_stack(cavity=13.0)
    with pytest.raises(ValueError, match="unknown fold phantom"):
        fold_stack("slit")
    # counter-clockwise outlines, as the readers give them
    assert all(signed_area(c.points) > 0 for name in FOLD_STACKS for c in fold_stack(name))
    assert sorted(FOLD_STACKS) == sorted(CASES)


def _tetrahedron() -> TriangleMesh:
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    return TriangleMesh(v, np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]))


def test_point_sized_slivers_are_collapsed():
    tet = _tetrahedron()
    # a vertex a hair from vertex 0 splits the bottom face into a fan: two of its faces are needles
    v = np.vstack([tet.vertices, tet.vertices[0] + [1e-13, 2e-13, 0.0]])
    t = np.vstack([tet.triangles[1:], [[0, 2, 4], [2, 1, 4], [1, 0, 4]]])
    split = TriangleMesh(v, t)
    assert split.is_watertight()
    out = _collapse_slivers(split, 1e-10)
    assert len(out.triangles) == 4 and len(out.vertices) == 4
    assert out.is_watertight() and out.is_oriented()
    assert out.signed_volume() == pytest.approx(tet.signed_volume())
    # nothing below the threshold: the mesh comes back as it is
    assert _collapse_slivers(split, 1e-14) is split
    assert _collapse_slivers(tet, 1e-10) is tet


def _split_octahedron(offset) -> TriangleMesh:
    """An octahedron whose top vertex is split in two ``offset`` (mm) apart, two faces of its fan on each."""
    v = np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, -1]])
    v = np.vstack([v, v[0] + offset])
    ring = [1, 2, 3, 4, 1]
    t = [[0 if i < 2 else 6, ring[i], ring[i + 1]] for i in range(4)] + [[5, ring[i + 1], ring[i]] for i in range(4)]
    return TriangleMesh(v, np.array(t + [[6, 0, 3], [0, 6, 1]]))


@pytest.mark.parametrize("scale, level", [(2e-8, 0), (3e-7, 1)], ids=["needle", "wider-needle"])
def test_sliver_needles_that_fold_are_collapsed(scale, level):
    # needle: the breast BODY's cause, an edge between the first two thresholds whose needle pierces
    # its neighbours (collapsed more widely); wider-needle: BODY with dome caps, a needle longer than
    # the second threshold within the bodies' overlap (collapsed only around its folds)
    extent = 100.0
    folded = _split_octahedron(scale * np.array([2.0, 1.0, 0.4]))
    length = np.linalg.norm(folded.vertices[6] - folded.vertices[0])
    assert SLIVER_FRACTIONS[level] * extent < length < SLIVER_FRACTIONS[level + 1] * extent
    assert folded.is_watertight() and folded.is_oriented()
    assert self_intersections(folded.vertices, folded.triangles).n_faces > 0
    assert _collapse_slivers(folded, SLIVER_FRACTIONS[level] * extent) is folded
    out = _unfold_slivers(folded, extent)
    assert len(out.triangles) == 8 and len(out.vertices) == 6
    assert out.is_watertight() and out.is_oriented()
    assert self_intersections(out.vertices, out.triangles).n_faces == 0
    assert out.signed_volume() == pytest.approx(4 / 3)
    # a sliver of the same length that folds nothing is kept: such meshes come back as they were
    flat = _split_octahedron(np.array([0.0, length, 0.0]))
    assert self_intersections(flat.vertices, flat.triangles).n_faces == 0
    assert _unfold_slivers(flat, extent) is flat
    tet = _tetrahedron()
    assert _unfold_slivers(tet, extent) is tet


def test_single_contour_bodies_skip_the_fallbacks():
    # one contour's side is a prism whatever the blend; the aligned arc length needs two contours
    (body,) = chain(fold_stack("hook")[2:3], 3.0)
    pieces = build_stepped(body, 3.0, surface_options(OPTIONS, samples=1))
    assert len(pieces) == 1 and pieces[0].self_intersecting_faces == 0
    disc = chain([type(body.contours[0])(0.0, circle(0, 0, 5, 32))], 3.0)[0]
    assert build_body(disc, 3.0, OPTIONS).surface == "blending (seed)"
