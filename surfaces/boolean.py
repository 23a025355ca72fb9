"""Set operations on closed surfaces (seed 002(b)).

Union, intersection and difference of solids bounded by closed, consistently
and outward oriented triangle meshes: the tessellated Bezier/Coons model
(:func:`surfaces.mesh.tessellate`), CT reconstructions, or PLY/OBJ/STL files.

Seed 002(b) describes the classic pipeline: find intersecting triangle pairs
with bounding-box hierarchies, decide uncertain orientation signs by symbolic
perturbation or exact arithmetic, cut, keep the parts that the outward normals
select, merge. manifold3d implements exactly that (BVH broad phase, symbolic
perturbation for coplanar and touching cases) and guarantees an oriented
2-manifold result, so this module does not carry its own triangle intersector.
What it adds around the engine:

* checks that the inputs bound solids (closed: every edge shared by exactly two
  triangles; oriented: every directed edge used once; outward: positive
  signed volume) with errors that name the input and the defect, and an
  optional repair (:mod:`surfaces.repair`) that reports what it did;
* the intersection curve as ordered polylines, from the face provenance of the
  result (edges where a triangle that came from A meets one that came from B);
* volumes by the divergence theorem in float64 (:func:`surfaces.mesh.signed_volume`);
* :func:`compose`, structure-set composition ``base + plus - minus``.

Results stay closed under :func:`surfaces.smooth.loop_smooth`.

Precision: the meshes go to manifold3d as ``Mesh64`` (float64 vertex
positions; manifold3d computes in double internally), shifted to the centre of
the common bounding box first, so CT coordinates hundreds of millimetres from
the origin keep their precision. Through the float32 ``Mesh`` path every
coordinate is rounded to about 6e-8 of its magnitude (up to 6e-5 mm at
1250 mm): for two 10 mm spheres placed at CT coordinates (480, -310, 1250) mm
the identity ``vol(A u B) + vol(A n B) = vol(A) + vol(B)`` then fails by
1.2e-6 relative, against 2e-15 through this module's path
(``benchmarks/bench_boolean.py``); the tests require 1e-6.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from surfaces.mesh import TriangleMesh, as_mesh, compact, signed_volume
from surfaces.repair import check_solid, inward_problem, repair_mesh
from surfaces.topology import chain_edges, edge_table, shells
from surfaces.validate import InputError

__all__ = ["OPS", "BooleanResult", "boolean", "union", "intersection", "difference", "compose"]

OPS: tuple[str, ...] = ("union", "intersection", "difference")
FLAT_SHELL = 1e-13  # result shells enclosing less than this times (input bounding-box diagonal)^3 are sheets


def _to_manifold(mesh: TriangleMesh, centre: np.ndarray, name: str, hint: str):
    """The input as a manifold3d solid, its original id (face provenance) and its volume.

    manifold3d itself verifies that the mesh is an oriented 2-manifold while
    building its half-edge structure, so the full :func:`check_solid` runs only
    to explain a rejection; the outward orientation is checked here.
    """
    import manifold3d

    vertices, triangles = mesh.vertices, mesh.triangles
    if len(triangles) == 0:
        raise InputError(f"{name}: has no triangles")
    # an explicit original id tags every triangle of the results with its source (cheaper
    # than Manifold.as_original(), which rebuilds the faces)
    original_id = int(manifold3d.Manifold.reserve_ids(1))
    engine_mesh = manifold3d.Mesh64(
        vert_properties=np.ascontiguousarray(vertices - centre, dtype=np.float64),
        tri_verts=np.ascontiguousarray(triangles, dtype=np.uint64),
        run_index=np.array([0, triangles.size], dtype=np.uint64),
        run_original_id=np.array([original_id], dtype=np.uint32),
    )
    solid = manifold3d.Manifold(engine_mesh)
    status = solid.status()
    if status != manifold3d.Error.NoError:
        problems = check_solid(mesh, name)["problems"] or [f"{name}: manifold3d rejected the mesh ({status.name})"]
        raise InputError("; ".join(problems) + hint)
    volume = mesh.signed_volume()
    if not volume > 0:
        raise InputError(inward_problem(name, volume) + hint)
    return solid, original_id, volume


def _from_manifold(solid, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (float64, shifted back), triangles (int64) and original id per triangle."""
    out = solid.to_mesh64()
    props = np.asarray(out.vert_properties, dtype=np.float64)
    tris = np.asarray(out.tri_verts, dtype=np.int64).reshape(-1, 3)
    vertices = props[:, :3] + centre if len(props) else np.zeros((0, 3))
    merge_from = np.asarray(out.merge_from_vert, dtype=np.int64)
    if len(merge_from):
        remap = np.arange(len(vertices))
        remap[merge_from] = np.asarray(out.merge_to_vert, dtype=np.int64)
        tris = remap[tris]
    run_index = np.asarray(out.run_index, dtype=np.int64) // 3
    run_ids = np.asarray(out.run_original_id, dtype=np.int64)
    origin = np.repeat(run_ids, np.diff(run_index)) if len(run_ids) else np.zeros(0, np.int64)
    return vertices, tris, origin


def _drop_flat_shells(vertices: np.ndarray, triangles: np.ndarray, origin: np.ndarray, scale: float):
    """Remove closed shells that enclose no volume; returns (triangles, origin, number removed).

    Where faces of A and B touch with partial overlap, manifold3d can return the
    touching patch as a closed double-sided sheet: a valid oriented 2-manifold
    with zero volume, not part of the solid. Shells enclosing at most
    ``FLAT_SHELL * scale**3`` are dropped (per-shell volumes by one bincount).
    """
    if len(triangles) == 0:
        return triangles, origin, 0
    shell = shells(triangles, len(vertices))
    volume = np.bincount(shell, weights=signed_volume(vertices, triangles, per_triangle=True))
    flat = np.abs(volume) <= FLAT_SHELL * scale**3
    if not np.any(flat[shell]):
        return triangles, origin, 0
    keep = ~flat[shell]
    return triangles[keep], origin[keep], int(np.count_nonzero(flat & (np.bincount(shell) > 0)))


def _curves_between(vertices, triangles, from_a: np.ndarray, edges) -> tuple[list[np.ndarray], list[bool]]:
    """Polylines along the edges where a triangle from A meets a triangle from B."""
    if len(triangles) == 0:
        return [], []
    directed, edge_id, counts, _ = edges
    face_a = np.repeat(from_a, 3)
    n_edges = len(counts)
    a_count = np.bincount(edge_id, weights=face_a, minlength=n_edges)
    mixed = (counts == 2) & (a_count == 1)
    # each curve edge once, in the direction of its A-side triangle
    sel = mixed[edge_id] & face_a
    chains, closed = chain_edges(directed[sel, 0], directed[sel, 1])
    return [vertices[c] for c in chains], closed


@dataclass(frozen=True)
class BooleanResult:
    """Result of :func:`boolean`.

    Attributes
    ----------
    mesh : TriangleMesh
        Closed, consistently and outward oriented result (may be empty, e.g.
        the intersection of disjoint solids or of solids that only touch;
        zero-volume sheets left where faces touch are removed and counted in
        ``check["flat_shells_removed"]``).
    op : str
        ``"union"``, ``"intersection"`` or ``"difference"`` (A minus B).
    volume_a, volume_b, volume : float
        Volumes of A, B and the result (divergence theorem, float64, cube of
        the vertex unit).
    curves : tuple of (K, 3) float64 arrays
        The intersection curve as polylines on the result, ordered; closed
        ones do not repeat their first point.
    curves_closed : tuple of bool
        Whether each polyline is closed.
    check : dict
        :func:`surfaces.repair.check_solid` of the result.
    repairs : dict
        ``{"A": report, "B": report}`` from :func:`surfaces.repair.repair_mesh`
        when repair was requested, else empty.
    """

    mesh: object
    op: str
    volume_a: float
    volume_b: float
    volume: float
    curves: tuple = ()
    curves_closed: tuple = ()
    check: dict = field(default_factory=dict)
    repairs: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """JSON-ready summary: op, volumes, sizes, watertightness, curves, repairs."""
        lengths = [
            float(np.sum(np.linalg.norm(np.diff(np.vstack([c, c[:1]]) if closed else c, axis=0), axis=1)))
            for c, closed in zip(self.curves, self.curves_closed)
        ]
        return {
            "op": self.op,
            "volume_a": self.volume_a,
            "volume_b": self.volume_b,
            "volume": self.volume,
            "n_vertices": self.check.get("n_vertices", 0),
            "n_triangles": self.check.get("n_triangles", 0),
            "watertight": bool(self.check.get("closed", False) or self.check.get("n_triangles", 0) == 0),
            "oriented": bool(self.check.get("oriented", False)),
            "n_curves": len(self.curves),
            "curve_points": [len(c) for c in self.curves],
            "curve_lengths": lengths,
            "curves_closed": list(self.curves_closed),
            "flat_shells_removed": self.check.get("flat_shells_removed", 0),
            "repairs": self.repairs,
        }


_REPAIR_HINT = "; pass repair=True (--repair) to fix it"


def _prepare(mesh, name: str, repair: bool) -> tuple[TriangleMesh, dict]:
    """An input as a mesh, repaired on request (checked later by :func:`_to_manifold`)."""
    if repair:
        return repair_mesh(mesh, name)
    return as_mesh(mesh, name), {}


def boolean(a, b, op: str = "union", *, repair: bool = False, names: Sequence[str] = ("A", "B")) -> BooleanResult:
    """Union, intersection or difference of two solids bounded by closed triangle meshes.

    Seed 002(b): set operations on free-form solids bounded by closed,
    oriented, non-self-intersecting surfaces; the outward normals decide
    which parts are kept. The engine is manifold3d (bounding-volume
    hierarchy for the intersecting triangle pairs, symbolic perturbation for
    coplanar and touching configurations, guaranteed 2-manifold output).

    Parameters
    ----------
    a, b : TriangleMesh or BezierPatches
        Closed, consistently and outward oriented meshes (vertices (V, 3)
        float64 in any length unit, triangles (T, 3) int64); a closed patch
        model is tessellated with :data:`surfaces.mesh.PATCH_SAMPLES`
        subdivisions per side (any input of :func:`surfaces.mesh.as_mesh` works).
    op : {"union", "intersection", "difference"}
        The operation; ``"difference"`` is A minus B.
    repair : bool, optional
        Repair the inputs with :func:`surfaces.repair.repair_mesh` first instead
        of refusing meshes that are not solids; what was repaired is in ``repairs``.
    names : pair of str, optional
        Names of the inputs in error messages and in ``repairs``.

    Returns
    -------
    BooleanResult
        The result mesh, volumes, intersection-curve polylines and checks.

    Raises
    ------
    ValueError
        Unknown ``op``; an input that is not closed, not consistently
        oriented, inward or degenerate (naming the input and the defect).
    RuntimeError
        When the engine's result fails the closed-and-oriented check (not
        expected: manifold3d guarantees manifold output).

    Examples
    --------
    A tetrahedron (volume 1/6) inside a larger one (volume 27/6):

    >>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> small, big = TriangleMesh(v, t), TriangleMesh(3 * v - 0.5, t)
    >>> result = boolean(big, small, "difference")
    >>> round(result.volume, 12), round(result.volume_a - result.volume_b, 12)
    (4.333333333333, 4.333333333333)
    >>> len(boolean(big, small, "intersection").curves)  # the surfaces do not cross
    0
    """
    if op not in OPS:
        raise InputError(f"op: must be one of {', '.join(OPS)}, got {op!r}")
    if len(names) != 2:
        raise InputError(f"names: expected two names, got {len(names)}")
    name_a, name_b = str(names[0]), str(names[1])
    mesh_a, rep_a = _prepare(a, name_a, repair)
    mesh_b, rep_b = _prepare(b, name_b, repair)
    lo = np.minimum(mesh_a.vertices.min(axis=0), mesh_b.vertices.min(axis=0))
    hi = np.maximum(mesh_a.vertices.max(axis=0), mesh_b.vertices.max(axis=0))
    centre = 0.5 * (lo + hi)
    solid_a, id_a, vol_a = _to_manifold(mesh_a, centre, name_a, _REPAIR_HINT)
    solid_b, _, vol_b = _to_manifold(mesh_b, centre, name_b, _REPAIR_HINT)
    result = {
        "union": solid_a + solid_b,
        "intersection": solid_a ^ solid_b,
        "difference": solid_a - solid_b,
    }[op]
    vertices, triangles, origin = _from_manifold(result, centre)
    scale = float(np.linalg.norm(hi - lo))
    triangles, origin, n_flat = _drop_flat_shells(vertices, triangles, origin, scale)
    mesh = compact(TriangleMesh(vertices, triangles))
    vertices, triangles = mesh.vertices, mesh.triangles
    edges = edge_table(triangles, len(vertices))
    info = check_solid(mesh, f"{op} result", edges=edges)
    info["flat_shells_removed"] = n_flat
    if len(triangles) and not (info["closed"] and info["oriented"]):
        raise RuntimeError("; ".join(info["problems"]))
    curves, closed = _curves_between(vertices, triangles, origin == id_a, edges)
    return BooleanResult(
        mesh=mesh,
        op=op,
        volume_a=vol_a,
        volume_b=vol_b,
        volume=info["signed_volume"],
        curves=tuple(curves),
        curves_closed=tuple(closed),
        check=info,
        repairs={name_a: rep_a, name_b: rep_b} if repair else {},
    )


def union(a, b, **options) -> BooleanResult:
    """``boolean(a, b, "union", **options)``: the solid inside A or B.

    Parameters
    ----------
    a, b : TriangleMesh or BezierPatches
        Closed, outward-oriented solids (see :func:`boolean`).
    **options
        ``repair`` and ``names``, as for :func:`boolean`.

    Returns
    -------
    BooleanResult
        The resulting solid and its checks, see :func:`boolean`.
    """
    return boolean(a, b, "union", **options)


def intersection(a, b, **options) -> BooleanResult:
    """``boolean(a, b, "intersection", **options)``: inside A and B.

    Parameters
    ----------
    a, b : TriangleMesh or BezierPatches
        Closed, outward-oriented solids (see :func:`boolean`).
    **options
        ``repair`` and ``names``, as for :func:`boolean`.

    Returns
    -------
    BooleanResult
        The resulting solid and its checks, see :func:`boolean`.
    """
    return boolean(a, b, "intersection", **options)


def difference(a, b, **options) -> BooleanResult:
    """``boolean(a, b, "difference", **options)``: inside A, outside B.

    Parameters
    ----------
    a, b : TriangleMesh or BezierPatches
        Closed, outward-oriented solids (see :func:`boolean`).
    **options
        ``repair`` and ``names``, as for :func:`boolean`.

    Returns
    -------
    BooleanResult
        The resulting solid and its checks, see :func:`boolean`.
    """
    return boolean(a, b, "difference", **options)


def compose(
    base,
    minus: Sequence = (),
    plus: Sequence = (),
    *,
    repair: bool = False,
    names: dict | None = None,
):
    """Structure-set composition ``(base u plus_1 u ...) minus (minus_1 u ...)``.

    For CT structure sets: an organ minus a tumour bed, the union of lobes.
    The operations run inside the engine without round trips to arrays.

    Parameters
    ----------
    base : TriangleMesh
        The solid to start from.
    minus, plus : sequence of TriangleMesh, optional
        Solids subtracted from / added to ``base`` (added first).
    repair : bool, optional
        Repair every input with :func:`surfaces.repair.repair_mesh` first.
    names : dict, optional
        ``{"base": str, "minus": [str, ...], "plus": [str, ...]}`` names used
        in error messages and the summary (default ``base``, ``minus[0]``, ...).

    Returns
    -------
    mesh : TriangleMesh
        The closed result (possibly empty).
    summary : dict
        ``volume_base``, ``volumes_minus``, ``volumes_plus`` (lists),
        ``volume`` (result), ``removed_volume`` (volume of base u plus minus
        the result), ``names``, ``repairs``, ``n_triangles``, ``watertight``,
        ``flat_shells_removed``.
    """
    import manifold3d

    names = dict(names or {})
    minus, plus = list(minus), list(plus)
    base_name = str(names.get("base", "base"))
    minus_names = [str(n) for n in names.get("minus", [f"minus[{i}]" for i in range(len(minus))])]
    plus_names = [str(n) for n in names.get("plus", [f"plus[{i}]" for i in range(len(plus))])]
    if len(minus_names) != len(minus) or len(plus_names) != len(plus):
        raise InputError("names: needs one name per minus and plus mesh")
    prepared = [_prepare(m, n, repair) for m, n in zip([base, *plus, *minus], [base_name, *plus_names, *minus_names])]
    all_v = np.vstack([p[0].vertices for p in prepared])
    centre = 0.5 * (all_v.min(axis=0) + all_v.max(axis=0))
    built = [
        _to_manifold(m, centre, n, _REPAIR_HINT) for (m, _), n in zip(prepared, [base_name, *plus_names, *minus_names])
    ]
    solids, vols = [b[0] for b in built], [b[2] for b in built]
    grown = manifold3d.Manifold.batch_boolean(solids[: 1 + len(plus)], manifold3d.OpType.Add)
    result = grown
    if minus:
        result = manifold3d.Manifold.batch_boolean([grown, *solids[1 + len(plus) :]], manifold3d.OpType.Subtract)
    vertices, triangles, origin = _from_manifold(result, centre)
    scale = float(np.linalg.norm(all_v.max(axis=0) - all_v.min(axis=0)))
    triangles, _, n_flat = _drop_flat_shells(vertices, triangles, origin, scale)
    mesh = compact(TriangleMesh(vertices, triangles))
    info = check_solid(mesh, "composition")
    if len(mesh.triangles) and not (info["closed"] and info["oriented"]):
        raise RuntimeError("; ".join(info["problems"]))
    gv, gt, _ = _from_manifold(grown, centre)
    volume = info["signed_volume"]
    summary = {
        "names": {"base": base_name, "minus": minus_names, "plus": plus_names},
        "volume_base": vols[0],
        "volumes_plus": vols[1 : 1 + len(plus)],
        "volumes_minus": vols[1 + len(plus) :],
        "volume": volume,
        "removed_volume": signed_volume(gv, gt) - volume,
        "n_triangles": len(mesh.triangles),
        "watertight": bool(info["closed"] or len(mesh.triangles) == 0),
        "flat_shells_removed": n_flat,
        "repairs": {n: p[1] for n, p in zip([base_name, *plus_names, *minus_names], prepared)} if repair else {},
    }
    return mesh, summary
