"""Tests of surfaces.topology: edge tables, shells and chains of edges."""

from __future__ import annotations

import numpy as np

from surfaces.topology import chain_edges, directed_edges, edge_keys, edge_table, shells
from tests.surfaces._shapes import box, icosphere


def test_chain_edges_cycles_and_paths():
    rng = np.random.default_rng(0)
    cyc1 = np.arange(0, 50)
    cyc2 = np.arange(100, 107)
    path = np.arange(200, 230)
    src = np.concatenate([cyc1, cyc2, path[:-1]])
    dst = np.concatenate([np.roll(cyc1, -1), np.roll(cyc2, -1), path[1:]])
    perm = rng.permutation(len(src))
    chains, closed = chain_edges(src[perm], dst[perm])
    got = sorted(((int(c.min()), len(c), cl) for c, cl in zip(chains, closed)))
    assert got == [(0, 50, True), (100, 7, True), (200, 30, False)]
    for c, cl in zip(chains, closed):
        step = np.diff(np.append(c, c[0]) if cl else c)
        if c.min() == 0:
            assert np.all((step == 1) | (step == -49))
        if c.min() == 200:
            assert np.all(step == 1)


def test_chain_edges_figure_eight_vertex():
    # two triangles' loops through the shared vertex 0: degree 4 there, still closed chains
    src = np.array([0, 1, 2, 0, 3, 4])
    dst = np.array([1, 2, 0, 3, 4, 0])
    chains, closed = chain_edges(src, dst)
    assert all(closed) and sum(len(c) for c in chains) == 6


def test_edge_table_of_a_closed_mesh():
    """A closed triangle mesh has E = 3T/2 edges, each used twice (Euler: V - E + F = 2)."""
    m = icosphere(level=2)
    table = edge_table(m.triangles, len(m.vertices))
    assert len(table.counts) == 3 * len(m.triangles) // 2 and np.all(table.counts == 2)
    assert len(m.vertices) - len(table.counts) + len(m.triangles) == 2
    # every directed edge points to its undirected key
    keys = edge_keys(table.directed, len(m.vertices))
    np.testing.assert_array_equal(table.keys[table.edge_id], keys)
    # rows 3t .. 3t+2 are the edges of triangle t, head to tail
    d = directed_edges(m.triangles).reshape(-1, 3, 2)
    np.testing.assert_array_equal(d[:, :, 1], np.roll(d[:, :, 0], -1, axis=1))


def test_shells_separate_disjoint_solids():
    a, b = box([0, 0, 0], [1, 1, 1]), icosphere(1.0, (5, 0, 0), 1)
    tris = np.vstack([a.triangles, b.triangles + len(a.vertices)])
    label = shells(tris, len(a.vertices) + len(b.vertices))
    assert set(label[: len(a.triangles)]) == {0} and set(label[len(a.triangles) :]) == {1}
