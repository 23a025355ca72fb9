"""Self-intersection test of triangle meshes: broad phase against brute force, closed forms, a fold."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.intersect import candidate_pairs, self_intersections


def uv_sphere(n: int, radius: float = 1.0, centre=(0.0, 0.0, 0.0)):
    """A closed, outward-oriented UV sphere: (vertices, triangles)."""
    th = np.linspace(0, np.pi, n)[1:-1]
    ph = np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    v = np.vstack([v, [[0, 0, 1], [0, 0, -1]]]) * radius + np.asarray(centre)
    rows, cols = t.shape
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1], idx[1:]
    c, d = np.roll(idx[1:], -1, 1), np.roll(idx[:-1], -1, 1)
    tri = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    top = np.stack([np.full(cols, rows * cols), idx[0], np.roll(idx[0], -1)], -1)
    bottom = np.stack([np.full(cols, rows * cols + 1), np.roll(idx[-1], -1), idx[-1]], -1)
    return v, np.vstack([tri, top, bottom])


def test_closed_sphere_has_none():
    v, t = uv_sphere(30)
    r = self_intersections(v, t)
    assert r.n_faces == 0 and len(r.pairs) == 0 and r.n_candidates > len(t)


def test_two_overlapping_spheres_intersect_along_their_circle():
    v1, t1 = uv_sphere(30)
    v2, t2 = uv_sphere(30, 0.8, (1.0, 0.1, 0.05))
    v, t = np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)])
    r = self_intersections(v, t)
    assert r.n_faces > 0
    # every flagged face lies near both spheres' surfaces (the intersection circle)
    centres = v[t[r.faces]].mean(axis=1)
    d1 = np.abs(np.linalg.norm(centres, axis=1) - 1.0)
    d2 = np.abs(np.linalg.norm(centres - [1.0, 0.1, 0.05], axis=1) - 0.8)
    assert np.all(np.minimum(d1, d2) < 0.02) and np.all(np.maximum(d1, d2) < 0.25)
    # pairs always join one face of each sphere
    assert np.all((r.pairs[:, 0] < len(t1)) & (r.pairs[:, 1] >= len(t1)))
    # apart, they do not touch
    far = np.vstack([v1, v2 + [5.0, 0, 0]])
    assert self_intersections(far, t).n_faces == 0


@pytest.mark.parametrize("n, path", [(40, "pairs"), (300, "sweep"), (300, "grid")])
def test_broad_phase_matches_brute_force(monkeypatch, n, path):
    import surfaces.intersect as intersect

    assert (n <= intersect.SMALL_BROAD_PHASE) == (path == "pairs")
    # the sweep along one axis while it makes few raw pairs, else the grid
    monkeypatch.setattr(intersect, "SWEEP_PAIRS_PER_FACE", 10**6 if path == "sweep" else 0)
    rng = np.random.default_rng(3)
    corners = rng.uniform(0, 10, (n, 1, 3)) + rng.normal(0, 0.6, (n, 3, 3))
    corners[:5] *= [1.0, 1.0, 0.0]  # a few long flat slivers, like cap fans
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    a, b = np.triu_indices(len(corners), 1)
    brute = np.all((lo[a] <= hi[b]) & (lo[b] <= hi[a]), axis=1)
    expected = set(zip(a[brute].tolist(), b[brute].tolist()))
    got = candidate_pairs(corners)
    assert len(got) == len(expected) and set(map(tuple, got.tolist())) == expected


def test_shared_vertex_and_fold():
    # two triangles sharing vertex 0; the second dives through the first
    v = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [3, 0.5, -1], [0.5, 1.5, 1.0]])
    r = self_intersections(v, np.array([[0, 1, 2], [0, 3, 4]]))
    assert r.faces.tolist() == [True, True]
    # a fan that only touches at the shared vertex does not count
    v2 = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [-3, 1, 1], [-1, -3, 1.0]])
    assert self_intersections(v2, np.array([[0, 1, 2], [0, 3, 4]])).n_faces == 0
    # neighbours across an edge never count, even folded flat onto each other
    v3 = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [3, 3, 0.0]])
    assert self_intersections(v3, np.array([[0, 1, 2], [1, 2, 3]])).n_faces == 0


def test_bad_input():
    with pytest.raises(ValueError, match="triangles"):
        self_intersections(np.zeros((3, 3)), np.array([[0, 1, 5]]))
    with pytest.raises(ValueError, match="vertices"):
        self_intersections(np.zeros((3, 2)), np.array([[0, 1, 2]]))
    # a negative index of a narrow integer type, beside more vertices than that type's unsigned range
    with pytest.raises(ValueError, match="indices must lie"):
        self_intersections(np.zeros((300, 3)), np.array([[0, 1, -1]], dtype=np.int8))
    assert self_intersections(np.zeros((0, 3)), np.zeros((0, 3), dtype=int)).n_faces == 0


def test_first_stops_at_a_fold_and_keeps_clean_meshes_clean():
    v1, t1 = uv_sphere(40)
    v2, t2 = uv_sphere(40, 0.8, (1.0, 0.1, 0.05))
    v, t = np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)])
    full = self_intersections(v, t)
    some = self_intersections(v, t, first=True)
    assert 0 < some.n_faces <= full.n_faces and not np.any(some.faces & ~full.faces)
    assert self_intersections(v1, t1, first=True).n_faces == 0


def test_first_makes_fewer_candidate_pairs_on_a_fold_and_all_on_a_clean_mesh():
    """With ``first``, the broad phase stops with the narrow phase: a fold early in the sweep is found
    without making every pair; a clean mesh still has every pair tested."""
    v1, t1 = uv_sphere(60)
    v2, t2 = uv_sphere(60, 0.8, (1.0, 0.1, 0.05))
    v, t = np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)])
    full = self_intersections(v, t)
    some = self_intersections(v, t, first=True)
    assert full.n_candidates == len(candidate_pairs(v[t]))
    assert some.n_faces > 0 and some.n_candidates < full.n_candidates
    clean = self_intersections(v1, t1, first=True)
    assert clean.n_faces == 0 and clean.n_candidates == len(candidate_pairs(v1[t1]))


def test_pairs_sharing_a_vertex_count_only_beyond_it():
    """A fan of two triangles sharing one vertex: flat (they meet in the vertex only) reads 0; the
    second tilted through the first's interior reads both."""
    v = np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0], [-2, -1, 0], [-1, -2, 0]])
    assert self_intersections(v, [[0, 1, 2], [0, 3, 4]]).n_faces == 0
    # the second triangle's far edge, from (0.6, 0.6, 1) to (0.6, 0.6, -1), pierces the first one
    w = np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0], [0.6, 0.6, 1], [0.6, 0.6, -1]])
    assert self_intersections(w, [[0, 1, 2], [0, 3, 4]]).n_faces == 2
