"""Is a triangle mesh the boundary of a solid? Diagnosis, and repair into one.

A solid's boundary is *closed* (every edge shared by exactly two triangles),
*consistently oriented* (every directed edge used once) and *outward*
(positive signed volume): the input conditions of the set operations of seed
002(b) (:mod:`surfaces.boolean`). :func:`check_solid` says which condition
fails and where; :func:`repair_mesh` welds, drops degenerate and duplicate
triangles, orients every shell consistently, fills small holes and turns
shells outward (nested shells inward), reporting what it did.
"""

from __future__ import annotations

import numpy as np

from surfaces.mesh import TriangleMesh, as_mesh, compact, signed_volume, weld_map
from surfaces.topology import EdgeTable, edge_keys, edge_table, shells
from surfaces.validate import InputError, positive

__all__ = ["check_solid", "require_solid", "repair_mesh"]


def check_solid(mesh, name: str = "mesh", *, edges: EdgeTable | None = None) -> dict:
    """Diagnose whether a triangle mesh bounds a solid.

    A solid's boundary is *closed* (every edge is shared by exactly two
    triangles), *consistently oriented* (every directed edge occurs once, so
    the two triangles at an edge traverse it in opposite directions) and
    *outward* (positive signed volume), the input conditions of seed 002(b).

    Parameters
    ----------
    mesh : TriangleMesh or mesh-like
        Mesh with ``vertices`` (V, 3) float and ``triangles`` (T, 3) int (see
        :func:`surfaces.mesh.as_mesh`).
    name : str, optional
        Name used in the ``problems`` messages.
    edges : EdgeTable, optional
        The mesh's :func:`surfaces.topology.edge_table`, when the caller has it.

    Returns
    -------
    dict
        ``n_vertices, n_triangles, boundary_edges`` (used by one triangle),
        ``nonmanifold_edges`` (used by more than two), ``misoriented_edges``
        (directed edges used twice), ``degenerate_triangles`` (a repeated
        vertex index), ``signed_volume``, booleans ``closed, oriented,
        outward, solid`` and ``problems``: list of str, empty for a solid.
        An empty mesh is reported as not closed.

    Examples
    --------
    >>> open_box = ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2]])
    >>> info = check_solid(open_box, "tetra")
    >>> info["boundary_edges"], info["problems"][0][:22]
    (3, 'tetra: not closed: 3 b')
    """
    m = as_mesh(mesh, name)
    vertices, triangles = m.vertices, m.triangles
    info: dict = {"n_vertices": len(vertices), "n_triangles": len(triangles)}
    directed, _, counts, _ = edges if edges is not None else edge_table(triangles, len(vertices))
    info["boundary_edges"] = int(np.count_nonzero(counts == 1))
    info["nonmanifold_edges"] = int(np.count_nonzero(counts > 2))
    dkey = edge_keys(directed, len(vertices), directed=True)
    dkey.sort()
    info["misoriented_edges"] = int(np.count_nonzero(dkey[1:] == dkey[:-1]))
    info["degenerate_triangles"] = int(
        np.count_nonzero(
            (triangles[:, 0] == triangles[:, 1])
            | (triangles[:, 1] == triangles[:, 2])
            | (triangles[:, 2] == triangles[:, 0])
        )
    )
    info["signed_volume"] = m.signed_volume()
    info["closed"] = bool(len(triangles) > 0 and info["boundary_edges"] == 0 and info["nonmanifold_edges"] == 0)
    info["oriented"] = bool(info["misoriented_edges"] == 0)
    info["outward"] = bool(info["signed_volume"] > 0)
    problems = []
    if len(triangles) == 0:
        problems.append(f"{name}: has no triangles")
    if info["boundary_edges"]:
        problems.append(
            f"{name}: not closed: {info['boundary_edges']} boundary edge(s) used by one triangle only "
            "(holes, or duplicate vertices that are not welded)"
        )
    if info["nonmanifold_edges"]:
        problems.append(
            f"{name}: not a manifold: {info['nonmanifold_edges']} edge(s) shared by more than two triangles"
        )
    if info["misoriented_edges"]:
        problems.append(
            f"{name}: not consistently oriented: {info['misoriented_edges']} edge(s) traversed in the same "
            "direction by both of their triangles"
        )
    if info["degenerate_triangles"]:
        problems.append(f"{name}: {info['degenerate_triangles']} degenerate triangle(s) with a repeated vertex")
    if len(triangles) and not problems and not info["outward"]:
        problems.append(inward_problem(name, info["signed_volume"]))
    info["problems"] = problems
    info["solid"] = not problems
    return info


def inward_problem(name: str, volume: float) -> str:
    """The problem message for a closed, oriented mesh whose normals point inward.

    Parameters
    ----------
    name : str
        Name of the mesh.
    volume : float
        Its signed volume (not positive).

    Returns
    -------
    str
    """
    return f"{name}: oriented inward (signed volume {volume:.6g} <= 0); normals must point outward"


def require_solid(mesh, name: str = "mesh", hint: str = "") -> dict:
    """:func:`check_solid`, raising when the mesh does not bound a solid.

    Parameters
    ----------
    mesh : TriangleMesh or mesh-like
        The mesh.
    name : str, optional
        Name of the input in the message.
    hint : str, optional
        Appended to the message (what the caller can do about it).

    Returns
    -------
    dict
        The :func:`check_solid` diagnosis of a solid.

    Raises
    ------
    ValueError
        Listing every problem found, naming ``name``.
    """
    info = check_solid(mesh, name)
    if not info["solid"]:
        raise InputError("; ".join(info["problems"]) + hint)
    return info


def _orient_consistently(triangles: np.ndarray, n_vertices: int) -> tuple[np.ndarray, int]:
    """Flip triangles so that neighbours agree; returns (triangles, number flipped).

    Two triangles sharing a manifold edge agree when they traverse it in
    opposite directions. A flip assignment is a two-colouring of the face graph
    with "same" and "different" constraints: on the doubled graph (face, state)
    an agreeing pair links equal states and a disagreeing pair links opposite
    states; its connected components give every face's state relative to the
    smallest face of its shell in one vectorised pass. Non-orientable shells
    (a face linked to its own opposite state) are left as they are.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n_tri = len(triangles)
    directed, edge_id, counts, _ = edge_table(triangles, n_vertices)
    shared = counts[edge_id] == 2
    rows = np.flatnonzero(shared)
    order = np.argsort(edge_id[rows], kind="stable")
    pairs = rows[order].reshape(-1, 2)  # the two directed edges of each manifold edge
    f0, f1 = pairs[:, 0] // 3, pairs[:, 1] // 3
    same_direction = directed[pairs[:, 0], 0] == directed[pairs[:, 1], 0]  # disagree
    s = same_direction.astype(np.int64)
    # node (f, state) -> f + state * n_tri; agree: (f0,0)-(f1,0), (f0,1)-(f1,1); disagree: crossed
    a = np.concatenate([f0, f0 + n_tri])
    b = np.concatenate([f1 + s * n_tri, f1 + (1 - s) * n_tri])
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(2 * n_tri, 2 * n_tri))
    _, label = connected_components(graph, directed=False)
    _, shell = connected_components(coo_matrix((np.ones(len(f0)), (f0, f1)), shape=(n_tri, n_tri)), directed=False)
    first = np.full(shell.max() + 1 if n_tri else 0, n_tri, dtype=np.int64)
    np.minimum.at(first, shell, np.arange(n_tri))
    reference = label[first[shell]]
    orientable = label[:n_tri] != label[n_tri:]
    flip = orientable & (label[:n_tri] != reference)
    out = triangles.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(np.count_nonzero(flip))


def _fill_holes(vertices: np.ndarray, triangles: np.ndarray, max_hole_edges: int):
    """Fan-fill boundary loops of at most ``max_hole_edges`` edges from their centroid.

    Boundary edges are taken in the direction of their (consistently oriented)
    triangle and reversed, so the fill triangles ``(q, p, centre)`` traverse
    every boundary edge opposite to its neighbour, keeping the orientation.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    directed, edge_id, counts, _ = edge_table(triangles, len(vertices))
    open_edges = directed[counts[edge_id] == 1]
    if len(open_edges) == 0:
        return vertices, triangles, 0, 0, 0
    n_v = len(vertices)
    graph = coo_matrix((np.ones(len(open_edges)), (open_edges[:, 0], open_edges[:, 1])), shape=(n_v, n_v))
    _, label = connected_components(graph, directed=False)
    loop = label[open_edges[:, 0]]
    loops, loop_index, n_edges = np.unique(loop, return_inverse=True, return_counts=True)
    small = n_edges <= max_hole_edges
    keep = small[loop_index]
    edges = open_edges[keep]
    if len(edges) == 0:
        return vertices, triangles, 0, 0, len(loops)
    idx = loop_index[keep]
    fill_ids = np.flatnonzero(small)
    local = np.searchsorted(fill_ids, idx)
    centres = np.zeros((len(fill_ids), 3))
    np.add.at(centres, local, vertices[edges[:, 0]])
    centres /= np.bincount(local, minlength=len(fill_ids))[:, None]
    new_tris = np.column_stack([edges[:, 1], edges[:, 0], n_v + local])
    return (
        np.vstack([vertices, centres]),
        np.vstack([triangles, new_tris]),
        len(fill_ids),
        len(new_tris),
        int(np.count_nonzero(~small)),
    )


def _winding_number(point: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Generalised winding number of a closed oriented mesh at a point (Van Oosterom-Strackee)."""
    a = vertices[triangles[:, 0]] - point
    b = vertices[triangles[:, 1]] - point
    c = vertices[triangles[:, 2]] - point
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (
        la * lb * lc
        + np.einsum("ij,ij->i", a, b) * lc
        + np.einsum("ij,ij->i", b, c) * la
        + np.einsum("ij,ij->i", c, a) * lb
    )
    return float(np.sum(np.arctan2(det, den)) / (2.0 * np.pi))


def _orient_outward(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, int]:
    """Turn every closed shell outward; a shell nested inside an odd number of others inward.

    Returns the triangles and the number of shells flipped. The loop runs over
    shells (a handful), each step vectorised over triangles.
    """
    shell = shells(triangles, len(vertices))
    out = triangles.copy()
    members = [np.flatnonzero(shell == s) for s in np.unique(shell)]
    volumes = [signed_volume(vertices, out[m]) for m in members]
    flipped = 0
    for i, m in enumerate(members):
        point = vertices[out[m[0], 0]]
        depth = 0
        for j, other in enumerate(members):
            if j != i:
                sign = 1.0 if volumes[j] > 0 else -1.0
                depth += round(sign * _winding_number(point, vertices, out[other]))
        want_positive = depth % 2 == 0
        if (volumes[i] > 0) != want_positive:
            out[m] = out[m][:, ::-1]
            flipped += 1
    return out, flipped


def repair_mesh(
    mesh,
    name: str = "mesh",
    *,
    weld_tolerance: float | None = None,
    max_hole_edges: int = 32,
):
    """Repair a triangle mesh into the boundary of a solid, reporting what was done.

    Steps, in order: weld vertices closer than ``weld_tolerance``; drop
    triangles with a repeated vertex and duplicate triangles (same vertex set);
    orient every shell consistently (flip triangles that disagree with their
    neighbours); fan-fill boundary loops of at most ``max_hole_edges`` edges;
    turn each shell outward (nested shells inward, by winding number).

    Parameters
    ----------
    mesh : TriangleMesh
        Input mesh, vertices (V, 3) float, triangles (T, 3) int.
    name : str, optional
        Name of the input in error messages.
    weld_tolerance : float, optional
        Distance (vertex units) below which vertices are merged; default
        1e-9 of the bounding-box diagonal (coordinates that went through a
        float32 file format still weld exactly when they were equal).
    max_hole_edges : int, optional
        Largest boundary loop (in edges) that is filled (default 32).

    Returns
    -------
    mesh : TriangleMesh
        The repaired mesh.
    report : dict
        ``welded_vertices, removed_degenerate_triangles,
        removed_duplicate_triangles, flipped_triangles, filled_holes,
        fill_triangles, unfilled_holes, flipped_shells`` (counts) and
        ``repaired`` (True when anything changed).

    Raises
    ------
    ValueError
        When the mesh is empty or still not a solid after repair (for example
        edges shared by more than two triangles, or holes larger than
        ``max_hole_edges``), naming the input and the remaining defects.
    """
    source = as_mesh(mesh, name)
    vertices, triangles = source.vertices, source.triangles
    if len(triangles) == 0:
        raise InputError(f"{name}: has no triangles, nothing to repair")
    max_hole_edges = int(max_hole_edges)
    if max_hole_edges < 0:
        raise InputError(f"max_hole_edges: must be >= 0, got {max_hole_edges}")
    used = vertices[np.unique(triangles)]
    diagonal = float(np.linalg.norm(used.max(axis=0) - used.min(axis=0)))
    tol = 1e-9 * diagonal if weld_tolerance is None else positive(weld_tolerance, "weld_tolerance", allow_zero=True)
    report: dict = {}

    # weld: exact duplicates first (cheap), then clusters of points closer than tol
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    if tol > 0 and len(unique) > 1:
        first, group = np.unique(weld_map(unique, tol), return_inverse=True)
        unique, inverse = unique[first], group[inverse]
    tris = inverse[triangles]
    report["welded_vertices"] = int(len(np.unique(triangles)) - len(np.unique(tris)))
    vertices = unique

    degenerate = (tris[:, 0] == tris[:, 1]) | (tris[:, 1] == tris[:, 2]) | (tris[:, 2] == tris[:, 0])
    tris = tris[~degenerate]
    report["removed_degenerate_triangles"] = int(np.count_nonzero(degenerate))
    _, keep = np.unique(np.sort(tris, axis=1), axis=0, return_index=True)
    report["removed_duplicate_triangles"] = int(len(tris) - len(keep))
    tris = tris[np.sort(keep)]
    if len(tris) == 0:
        raise InputError(f"{name}: no triangles left after removing degenerate and duplicate ones")

    tris, report["flipped_triangles"] = _orient_consistently(tris, len(vertices))
    vertices, tris, filled, fill_tris, unfilled = _fill_holes(vertices, tris, max_hole_edges)
    report["filled_holes"], report["fill_triangles"], report["unfilled_holes"] = (
        filled,
        fill_tris,
        unfilled,
    )
    info = check_solid(TriangleMesh(vertices, tris), name)
    if info["closed"] and info["oriented"]:
        tris, report["flipped_shells"] = _orient_outward(vertices, tris)
    else:
        report["flipped_shells"] = 0
    report["repaired"] = any(report[k] for k in report)
    repaired = compact(TriangleMesh(vertices, tris))
    require_solid(repaired, name, " (after repair)")
    return repaired, report
