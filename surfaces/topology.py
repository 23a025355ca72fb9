"""Topology of triangle meshes: edges, shells and chains of edges.

The edge tables here serve every check and repair of meshes in ``surfaces``
(:class:`surfaces.mesh.TriangleMesh`, :mod:`surfaces.repair`,
:mod:`surfaces.boolean`). Edges are keyed by one int64 per edge
(``lo * V + hi``), so that a 1-D sort groups them, many times faster than a
``unique(axis=0)`` over vertex pairs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surfaces.validate import as_array, InputError

__all__ = ["EdgeTable", "directed_edges", "edge_keys", "edge_table", "shells", "chain_edges"]


class EdgeTable(NamedTuple):
    """The directed edges of a triangle mesh grouped into undirected edges.

    Attributes
    ----------
    directed : (3T, 2) int64
        Directed edges; row ``3 t + k`` is edge ``k`` of triangle ``t`` (see :func:`directed_edges`).
    edge_id : (3T,) int64
        Undirected edge of every directed edge, an index into ``counts`` and ``keys``.
    counts : (E,) int64
        Number of triangles using each undirected edge (2 on a closed manifold).
    keys : (E,) int64
        Sorted undirected keys ``lo * V + hi``.
    """

    directed: np.ndarray
    edge_id: np.ndarray
    counts: np.ndarray
    keys: np.ndarray


def directed_edges(triangles: np.ndarray) -> np.ndarray:
    """Directed edges of every triangle.

    Parameters
    ----------
    triangles : (T, 3) int array
        Vertex indices.

    Returns
    -------
    (3T, 2) array
        Row ``3 t + k`` is edge ``k`` of triangle ``t`` (k = 0: v0 -> v1, 1: v1 -> v2,
        2: v2 -> v0), so ``row // 3`` is the triangle of a row.

    Examples
    --------
    >>> directed_edges(np.array([[0, 1, 2]])).tolist()
    [[0, 1], [1, 2], [2, 0]]
    """
    return np.asarray(triangles)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)


def edge_keys(edges: np.ndarray, n_vertices: int, directed: bool = False) -> np.ndarray:
    """One int64 key per edge: ``a * V + b`` (directed) or ``min * V + max`` (undirected).

    Parameters
    ----------
    edges : (E, 2) int array
        Vertex pairs.
    n_vertices : int
        Number of vertices ``V`` (at least 1 is used).
    directed : bool
        Keep the direction (``a -> b`` and ``b -> a`` get different keys).

    Returns
    -------
    (E,) int64

    Examples
    --------
    >>> edge_keys(np.array([[2, 1], [1, 2]]), 10).tolist()
    [12, 12]
    >>> edge_keys(np.array([[2, 1], [1, 2]]), 10, directed=True).tolist()
    [21, 12]
    """
    e = np.asarray(edges, dtype=np.int64)
    n = np.int64(max(int(n_vertices), 1))
    if directed:
        return e[:, 0] * n + e[:, 1]
    return np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])


def edge_table(triangles: np.ndarray, n_vertices: int) -> EdgeTable:
    """Group the directed edges of a mesh into undirected edges and count their triangles.

    Parameters
    ----------
    triangles : (T, 3) int array
        Vertex indices.
    n_vertices : int
        Number of vertices.

    Returns
    -------
    EdgeTable

    Examples
    --------
    >>> table = edge_table(np.array([[0, 1, 2], [0, 2, 3]]), 4)
    >>> table.counts.tolist()  # the diagonal 0-2 is shared
    [1, 2, 1, 1, 1]
    """
    directed = directed_edges(np.asarray(triangles, dtype=np.int64))
    keys, edge_id, counts = _group(edge_keys(directed, n_vertices))
    return EdgeTable(directed, edge_id, counts, keys)


def _group(key: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.unique(key, return_inverse=True, return_counts=True)`` by one argsort (faster)."""
    if len(key) == 0:
        return key, np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.argsort(key)
    ordered = key[order]
    starts = np.flatnonzero(np.concatenate([[True], ordered[1:] != ordered[:-1]]))
    group = np.zeros(len(key), np.int64)
    group[starts[1:]] = 1
    inverse = np.empty(len(key), np.int64)
    inverse[order] = np.cumsum(group)
    counts = np.diff(np.append(starts, len(key)))
    return ordered[starts], inverse, counts


def shells(triangles: np.ndarray, n_vertices: int) -> np.ndarray:
    """Connected component (shell) of every triangle; triangles sharing a vertex share a shell.

    Parameters
    ----------
    triangles : (T, 3) int array
        Vertex indices.
    n_vertices : int
        Number of vertices.

    Returns
    -------
    (T,) int
        Shell label per triangle, numbered in the order of the shells' smallest vertex.

    Examples
    --------
    >>> shells(np.array([[0, 1, 2], [3, 4, 5], [2, 1, 6]]), 7).tolist()
    [0, 1, 0]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = directed_edges(triangles)
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices))
    _, label = connected_components(graph, directed=False)
    return label[np.asarray(triangles)[:, 0]]


def chain_edges(src: np.ndarray, dst: np.ndarray) -> tuple[list[np.ndarray], list[bool]]:
    """Chain directed edges into polylines (vertex index sequences).

    At every vertex the k-th incoming edge is joined to the k-th outgoing edge;
    where each vertex has as many incoming as outgoing edges (the boundary of a
    region on an oriented closed surface) every chain is closed. Chains are
    ordered by list ranking (pointer jumping, log2(n) vectorised rounds), not
    by walking edge by edge.

    Parameters
    ----------
    src, dst : (E,) array_like of int
        Start and end vertex of each directed edge.

    Returns
    -------
    chains : list of (K,) int64 arrays
        Vertex indices in order; a closed chain does not repeat its first
        vertex, an open one includes both end vertices.
    closed : list of bool
        Whether each chain is closed.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    src = as_array(src, "src", ndim=1, dtype=np.int64)
    dst = as_array(dst, "dst", ndim=1, dtype=np.int64)
    if src.shape != dst.shape:
        raise InputError(f"src, dst: lengths differ ({len(src)} and {len(dst)})")
    n = len(src)
    if n == 0:
        return [], []
    # rank of each edge among the incoming edges of its end vertex / outgoing of its start
    in_order = np.lexsort((np.arange(n), dst))
    out_order = np.lexsort((np.arange(n), src))
    in_rank = np.empty(n, np.int64)
    out_rank = np.empty(n, np.int64)
    d_sorted, s_sorted = dst[in_order], src[out_order]
    in_rank[in_order] = np.arange(n) - np.searchsorted(d_sorted, d_sorted, side="left")
    out_rank[out_order] = np.arange(n) - np.searchsorted(s_sorted, s_sorted, side="left")
    # successor of edge e: the outgoing edge of dst[e] with the same rank
    out_keys = np.column_stack([src, out_rank])[out_order]
    want = np.column_stack([dst, in_rank])
    pos = np.searchsorted(out_keys[:, 0] * (n + 1) + out_keys[:, 1], want[:, 0] * (n + 1) + want[:, 1])
    pos = np.minimum(pos, n - 1)
    hit = (out_keys[pos, 0] == want[:, 0]) & (out_keys[pos, 1] == want[:, 1])
    succ = np.where(hit, out_order[pos], -1)

    linked = succ >= 0
    graph = coo_matrix((np.ones(np.count_nonzero(linked)), (np.flatnonzero(linked), succ[linked])), shape=(n, n))
    n_comp, comp = connected_components(graph, directed=False)
    has_pred = np.zeros(n, bool)
    has_pred[succ[linked]] = True
    # open chains start at the edge without predecessor; cycles are cut before their smallest edge
    start = np.full(n_comp, n, dtype=np.int64)
    np.minimum.at(start, comp[~has_pred], np.flatnonzero(~has_pred))
    is_cycle = start == n
    first_edge = np.full(n_comp, n, dtype=np.int64)
    np.minimum.at(first_edge, comp, np.arange(n))
    start = np.where(is_cycle, first_edge, start)
    nxt = succ.copy()
    nxt[(succ >= 0) & (succ == start[comp])] = -1  # cut the edge that closes each cycle
    # Wyllie list ranking: distance of every edge to the end of its chain
    rank = (nxt >= 0).astype(np.int64)
    jump = nxt.copy()
    while np.any(jump >= 0):
        live = jump >= 0
        rank[live] += rank[jump[live]]
        jump[live] = jump[jump[live]]
    order = np.lexsort((-rank, comp))
    bounds = np.flatnonzero(np.diff(comp[order])) + 1
    chains, closed = [], []
    for c, edges in zip(np.unique(comp[order]), np.split(order, bounds)):
        verts = src[edges]
        if not is_cycle[c]:
            verts = np.append(verts, dst[edges[-1]])
        chains.append(verts)
        closed.append(bool(is_cycle[c]))
    return chains, closed
