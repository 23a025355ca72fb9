"""The fold certificate of layered meshes (:func:`surfaces.folds.fold_suspects`) against the exact test.

Whatever the mesh, every pair of faces that :func:`self_intersections` finds
crossing must have both faces among the suspects; a mesh without suspects must
have no crossing at all. Checked on the body meshes of random star-shaped and
random wavy stacks, on the fold phantoms (whose surfaces fold), on meshes
folded on purpose by moving vertices within their level, and on meshes that are
not layered (where the certificate must decline).
"""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.fold_stacks import fold_stack
from slices.body import FALLBACKS, build_body_once
from slices.chaining import chain
from slices.io import Contour
from slices.options import SurfaceOptions
from surfaces.folds import fold_suspects, folded_faces, is_fold_free, layered_radial_graph
from surfaces.intersect import self_intersections
from tests.surfaces.test_intersect import uv_sphere


def _check(v: np.ndarray, t: np.ndarray) -> tuple[np.ndarray | None, int]:
    """Suspects and exact folded faces of a mesh, asserting the certificate's promise."""
    suspects = fold_suspects(v, t)
    exact = self_intersections(v, t)
    if suspects is not None:
        assert suspects[exact.pairs].all(), "a crossing pair outside the suspects"
        if not suspects.any():
            assert exact.n_faces == 0
    assert is_fold_free(v, t) == (exact.n_faces == 0)
    assert np.array_equal(folded_faces(v, t), exact.faces)
    return suspects, exact.n_faces


def _star(rng: np.random.Generator, n: int, wavy: float) -> np.ndarray:
    """A random star-shaped contour about a random centre: radius a positive trigonometric series."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 10.0 + sum(rng.uniform(-wavy, wavy) * np.cos(k * t + rng.uniform(0, 2 * np.pi)) for k in range(1, 6))
    return rng.uniform(-3, 3, 2) + np.maximum(r, 1.0)[:, None] * np.stack([np.cos(t), np.sin(t)], 1)


def _body_meshes(contours: list[Contour], spacing: float, caps: str, surfaces=FALLBACKS[:1]):
    for body in chain(contours, spacing):
        for name, change in surfaces:
            opts = SurfaceOptions(caps=caps, **{k: val for k, val in change.items() if k != "method"})
            b = build_body_once(body, spacing, opts, ruled=change.get("method") == "ruled")
            yield name, b.mesh


@pytest.mark.parametrize("wavy, least", [(1.0, 7), (2.5, 4), (4.0, 0)])
def test_random_star_shaped_stacks(wavy, least):
    """Random stacks, star-shaped to wildly wavy: ordinary ones proven outright, never a crossing outside the
    suspects."""
    rng = np.random.default_rng(int(wavy * 10))
    proven = 0
    for trial in range(8):
        n_planes = int(rng.integers(2, 7))
        spacing = float(rng.uniform(1.0, 4.0))
        contours = [Contour(spacing * k, _star(rng, int(rng.integers(24, 80)), wavy)) for k in range(n_planes)]
        caps = ("flat", "half", "dome")[trial % 3]
        for _, mesh in _body_meshes(contours, spacing, caps):
            suspects, folded = _check(mesh.vertices, mesh.triangles)
            assert suspects is not None  # closed, oriented, layered: the certificate applies
            proven += not suspects.any()
    assert proven >= least  # the certificate does its job on ordinary shapes


@pytest.mark.parametrize("name", ["hook", "closing_c"])
def test_fold_phantoms_are_never_proven(name):
    """Every surface of the fold phantoms folds; no such mesh is proven, each crossing is a suspect pair."""
    contours = fold_stack(name)
    for surface, mesh in _body_meshes(contours, 3.0, "half", FALLBACKS):
        suspects, folded = _check(mesh.vertices, mesh.triangles)
        if folded:
            assert not layered_radial_graph(mesh.vertices, mesh.triangles), surface
            assert suspects is None or suspects.any()


@pytest.mark.slow
def test_meshes_folded_on_purpose():
    """Vertices moved within their level (the mesh stays layered) fold it; the suspects hold every crossing."""
    rng = np.random.default_rng(7)
    contours = [Contour(2.0 * k, _star(rng, 48, 1.5)) for k in range(5)]
    _, mesh = next(_body_meshes(contours, 2.0, "half"))
    n_folded = 0
    for _ in range(60):
        v = mesh.vertices.copy()
        moved = rng.choice(len(v), size=int(rng.integers(1, 6)), replace=False)
        v[moved, :2] += rng.normal(0, rng.choice([0.5, 3.0, 12.0]), (len(moved), 2))
        suspects, folded = _check(v, mesh.triangles)
        n_folded += folded > 0
        if folded:
            assert suspects is None or suspects.any()
    assert n_folded >= 10  # the test sees real folds


def test_meshes_that_are_not_layered_are_declined():
    v, t = uv_sphere(12)
    tilted = v @ np.array([[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]])
    assert fold_suspects(tilted, t) is None  # faces span three levels
    assert fold_suspects(v, t[1:]) is None  # open
    assert fold_suspects(v, np.vstack([t[:1, ::-1], t[1:]])) is None  # not oriented
    creeping = v + np.array([0.0, 0.0, 3e-14]) * np.arange(len(v))[:, None]
    assert fold_suspects(creeping, t) is None  # steps below the level tolerance that add up to a slope
    assert is_fold_free(tilted, t) and is_fold_free(v, t)
    with pytest.raises(ValueError, match="triangles"):
        fold_suspects(v, t.astype(float))
    with pytest.raises(ValueError, match="indices"):
        fold_suspects(v, t + len(v))


def test_a_uv_sphere_is_proven():
    """Rings on levels, fans to the poles (a band's axis is its apex): a radial graph everywhere."""
    v, t = uv_sphere(20)
    suspects = fold_suspects(v, t)
    assert suspects is not None and not suspects.any() and layered_radial_graph(v, t)
    # two spheres side by side: every band's cut winds twice, so nothing is proven
    v2, t2 = np.vstack([v, v + [3.0, 0, 0]]), np.vstack([t, t + len(v)])
    s2 = fold_suspects(v2, t2)
    assert s2 is None or s2.all()


def test_closed_and_oriented_against_counting_the_directed_edges():
    from collections import Counter

    from surfaces.folds import _closed_and_oriented

    def by_counting(t):
        edges = Counter((int(a), int(b)) for tri in t for a, b in zip(tri, np.roll(tri, -1)))
        return all(c == 1 and edges.get((b, a)) == 1 for (a, b), c in edges.items())

    # a closed octahedron, then broken: one face flipped, one removed, one repeated, two joined ones
    octa = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    flipped = octa.copy()
    flipped[0] = flipped[0, ::-1]
    cases = [octa, flipped, octa[1:], np.vstack([octa, octa[:1]]), np.vstack([octa, octa[:2, ::-1]])]
    rng = np.random.default_rng(5)
    cases += [rng.integers(0, 6, size=(8, 3)) for _ in range(20)]
    for t in cases:
        assert _closed_and_oriented(np.asarray(t, dtype=np.int64), 6) == by_counting(t)
    assert _closed_and_oriented(octa, 6)


def _both_forms(monkeypatch, v: np.ndarray, t: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Suspects of the lattice form (where it applies) and of the general form alone."""
    import surfaces.folds as si
    lattice = fold_suspects(v, t)
    with monkeypatch.context() as m:
        m.setattr(si, "_lattice_shape", lambda t, n: None)
        general = fold_suspects(v, t)
    return lattice, general


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


def test_lattice_form_clears_what_the_general_form_clears(monkeypatch):
    """On the body meshes (side lattice and caps), perturbed copies and the fold phantoms the lattice form
    gives the general form's suspects, face for face."""
    import surfaces.folds as si
    from surfaces.folds import _lattice_shape
    monkeypatch.setattr(si, "LATTICE_MIN_FACES", 0)  # the small meshes here take the lattice form too
    rng = np.random.default_rng(11)
    meshes = []
    for trial in range(6):
        contours = [Contour(2.0 * k, _star(rng, int(rng.integers(24, 60)), 1.0 + trial)) for k in range(4)]
        meshes += [m for _, m in _body_meshes(contours, 2.0, ("flat", "half", "dome")[trial % 3])]
    for name in ("hook", "closing_c"):
        meshes += [m for _, m in _body_meshes(fold_stack(name), 3.0, "half", FALLBACKS)]
    n_lattice = n_suspect = 0
    for mesh in meshes:
        t = mesh.triangles
        n_lattice += _lattice_shape(t.astype(np.int64), len(mesh.vertices)) is not None
        for scale in (0.0, 0.01, 0.3, 3.0):
            v = mesh.vertices.copy()
            moved = rng.choice(len(v), size=4, replace=False)
            v[moved, :2] += rng.normal(0, scale, (4, 2))
            lattice, general = _both_forms(monkeypatch, v, t)
            assert _same(lattice, general)
            n_suspect += general is not None and bool(general.any())
    assert n_lattice >= len(meshes) // 2  # the lattice form is exercised
    assert n_suspect >= 5  # on meshes with suspects too


def test_few_bad_arcs_compared_directly_give_the_table_of_taken_bins(monkeypatch):
    """The suspects from the direct comparison of every arc with a few bad ones are the suspects from the
    table of taken bins, in both forms, on perturbed body meshes with bad faces."""
    import surfaces.folds as si
    monkeypatch.setattr(si, "LATTICE_MIN_FACES", 0)
    rng = np.random.default_rng(5)
    n_bad = 0
    for trial in range(6):
        contours = [Contour(2.0 * k, _star(rng, int(rng.integers(24, 60)), 1.0 + trial)) for k in range(4)]
        for _, mesh in _body_meshes(contours, 2.0, ("flat", "half", "dome")[trial % 3]):
            for scale in (0.05, 0.3, 1.0):
                v = mesh.vertices.copy()
                moved = rng.choice(len(v), size=int(rng.integers(1, 12)), replace=False)
                v[moved, :2] += rng.normal(0, scale, (len(moved), 2))
                got = []
                for pairs in (-1, 10**12):  # the table always, the direct comparison always
                    with monkeypatch.context() as m:
                        m.setattr(si, "DIRECT_ARC_PAIRS", pairs)
                        got.append(_both_forms(monkeypatch, v, mesh.triangles))
                assert _same(got[0][0], got[1][0]) and _same(got[0][1], got[1][1])
                n_bad += got[0][1] is not None and bool(got[0][1].any())
    assert n_bad >= 5  # exercised on meshes with bad faces


def test_lattice_form_declines_what_is_not_a_lattice(monkeypatch):
    """A lattice whose triangles are shuffled or whose rings leave their level goes to the general form."""
    import surfaces.folds as si
    from surfaces.folds import _lattice_shape
    monkeypatch.setattr(si, "LATTICE_MIN_FACES", 0)
    rng = np.random.default_rng(3)
    contours = [Contour(2.0 * k, _star(rng, 40, 1.0)) for k in range(4)]
    _, mesh = next(_body_meshes(contours, 2.0, "flat"))
    t = mesh.triangles.astype(np.int64)
    assert _lattice_shape(t, len(mesh.vertices)) is not None
    shuffled = t[rng.permutation(len(t))]
    assert _lattice_shape(shuffled, len(mesh.vertices)) is None
    v = mesh.vertices.copy()
    v[5, 2] += 0.5  # off its level: the mesh is no longer layered
    lattice, general = _both_forms(monkeypatch, v, t)
    assert general is None and lattice is None


def test_crossing_winding_equals_the_summed_angle_steps():
    """The certificate's windings (signed crossings of a half-line) against the angle steps summed over
    2 pi, on random closed chains about the origin that wind 0, 1, 2 times either way or wander."""
    from surfaces.folds import _crossings

    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(3, 60))
        turns = int(rng.integers(-2, 3))
        angle = np.sort(rng.uniform(0, 2 * np.pi * max(abs(turns), 1), n)) * (1 if turns >= 0 else -1)
        radius = rng.uniform(0.2, 3.0, n)
        x, y = radius * np.cos(angle), radius * np.sin(angle)
        if turns == 0 or trial % 5 == 0:  # off-centre chains, the origin inside or out
            x, y = x + rng.uniform(-3, 3), y + rng.uniform(-3, 3)
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        expected = np.arctan2(x * yn - y * xn, x * xn + y * yn).sum() / (2 * np.pi)
        (at,), step = _crossings(x, y, xn, yn)
        assert int(step.sum()) == round(expected), trial


def test_the_certificate_is_still_found_in_surfaces_intersect():
    """The fold certificate moved to surfaces.folds (issue 30); its names stay importable from surfaces.intersect."""
    import surfaces.folds as folds
    import surfaces.intersect as intersect
    from surfaces.intersect import is_fold_free as old_name

    assert old_name is folds.is_fold_free
    for name in intersect.MOVED_TO_FOLDS:
        assert getattr(intersect, name) is getattr(folds, name)
    with pytest.raises(AttributeError, match="no_such_name"):
        intersect.no_such_name  # noqa: B018
