"""Triangle meshes from the shared patch model.

Tessellation samples every patch on a regular grid in one vectorised call,
lays the samples on one global vertex grid so that neighbouring patches share
their seam vertices, wraps closed directions, and welds the vertices that
coincide (poles, collapsed edges). A closed patch grid therefore gives a
watertight, consistently oriented mesh. Vertex normals come from the patches
(``S_u x S_v``), not from the triangles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from surfaces.bezier import BezierPatches, bernstein, control_matrix, tensor_evaluate
from surfaces.validate import as_array


@dataclass
class TriangleMesh:
    """An indexed triangle mesh.

    Parameters
    ----------
    vertices : numpy.ndarray, shape (V, 3)
        Vertex positions, float64.
    triangles : numpy.ndarray, shape (T, 3)
        Vertex indices, int64, counter-clockwise seen from the side the normals point to.
    vertex_normals : numpy.ndarray, shape (V, 3), optional
        Unit vertex normals.
    vertex_colors : numpy.ndarray, shape (V, 3), optional
        RGB colours in [0, 1].
    """

    vertices: np.ndarray
    triangles: np.ndarray
    vertex_normals: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.vertices = as_array(self.vertices, "vertices", shape=(None, 3))
        tri = np.asarray(self.triangles)
        if tri.size == 0:
            tri = tri.reshape(0, 3)
        if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
            raise ValueError(f"triangles: expected an integer array of shape (T, 3), got {tri.shape} {tri.dtype}")
        if tri.size and (tri.min() < 0 or tri.max() >= len(self.vertices)):
            raise ValueError(f"triangles: indices must lie in [0, {len(self.vertices)})")
        self.triangles = tri.astype(np.int64, copy=False)
        for name in ("vertex_normals", "vertex_colors"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, as_array(value, name, shape=(len(self.vertices), 3)))

    @property
    def n_vertices(self) -> int:
        """Number of vertices ``V``."""
        return len(self.vertices)

    @property
    def n_triangles(self) -> int:
        """Number of triangles ``T``."""
        return len(self.triangles)

    def triangle_corners(self) -> np.ndarray:
        """Corner positions of every triangle, shape (T, 3, 3)."""
        return self.vertices[self.triangles]

    def face_normals(self, normalize: bool = True) -> np.ndarray:
        """Triangle normals ``(b - a) x (c - a)``, shape (T, 3); unit when ``normalize``."""
        c = self.triangle_corners()
        n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        if not normalize:
            return n
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return n / np.where(length > 0, length, 1.0)

    def surface_area(self) -> float:
        """Sum of triangle areas (same units as the vertices, squared)."""
        return float(0.5 * np.linalg.norm(self.face_normals(normalize=False), axis=1).sum())

    def signed_volume(self) -> float:
        """Enclosed volume by the divergence theorem over the triangles.

        Positive when the triangles are counter-clockwise seen from outside.
        Meaningful only for a closed mesh.
        """
        c = self.triangle_corners()
        return float(np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6.0)

    def _directed_edges(self) -> np.ndarray:
        t = self.triangles
        return np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])

    def edge_counts(self) -> tuple[np.ndarray, np.ndarray]:
        """Undirected edges and how many triangles use each.

        Returns
        -------
        edges : numpy.ndarray, shape (E, 2)
            Sorted vertex pairs.
        counts : numpy.ndarray, shape (E,)
            Number of triangles sharing each edge.
        """
        e = np.sort(self._directed_edges(), axis=1).astype(np.int64)
        n = np.int64(max(self.n_vertices, 1))
        # one int64 key per edge: a 1-D unique is many times faster than unique(axis=0)
        keys, counts = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
        return np.stack([keys // n, keys % n], axis=1), counts

    def is_watertight(self) -> bool:
        """True when every edge is shared by exactly two triangles."""
        if self.n_triangles == 0:
            return False
        _, counts = self.edge_counts()
        return bool(np.all(counts == 2))

    def is_oriented(self) -> bool:
        """True when no directed edge appears twice (neighbours agree on orientation)."""
        e = self._directed_edges().astype(np.int64)
        keys = e[:, 0] * np.int64(max(self.n_vertices, 1)) + e[:, 1]
        return len(np.unique(keys)) == len(keys)

    def boundary_edges(self) -> np.ndarray:
        """Undirected edges used by exactly one triangle, shape (B, 2)."""
        edges, counts = self.edge_counts()
        return edges[counts == 1]

    def copy(self) -> TriangleMesh:
        """A deep copy."""
        return TriangleMesh(
            self.vertices.copy(),
            self.triangles.copy(),
            None if self.vertex_normals is None else self.vertex_normals.copy(),
            None if self.vertex_colors is None else self.vertex_colors.copy(),
            dict(self.metadata),
        )


def weld(mesh: TriangleMesh, tolerance: float | None = None, candidates=None) -> TriangleMesh:
    """Merge coincident vertices and drop the triangles that collapse.

    Parameters
    ----------
    mesh : TriangleMesh
        Input mesh (not modified).
    tolerance : float, optional
        Distance under which vertices merge; default ``1e-9`` times the
        bounding-box diagonal.
    candidates : array_like of int, optional
        Only these vertex indices may merge (a speed-up when the caller knows
        where duplicates can be, e.g. patch seams).

    Returns
    -------
    TriangleMesh
        Mesh without duplicate vertices, degenerate (repeated-index) triangles
        or unreferenced vertices.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    verts = mesh.vertices
    n = len(verts)
    if n == 0:
        return mesh.copy()
    if tolerance is None:
        diag = float(np.linalg.norm(verts.max(axis=0) - verts.min(axis=0)))
        tolerance = 1e-9 * max(diag, 1e-300)
    idx = np.arange(n) if candidates is None else np.unique(np.asarray(candidates, dtype=np.int64))
    pairs = cKDTree(verts[idx]).query_pairs(tolerance, output_type="ndarray")
    tri = mesh.triangles
    if len(pairs):
        a, b = idx[pairs[:, 0]], idx[pairs[:, 1]]
        graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
        # representative of each component: its smallest vertex index
        rep = np.full(labels.max() + 1, n, dtype=np.int64)
        np.minimum.at(rep, labels, np.arange(n))
        tri = rep[labels][tri]
    keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])
    if len(pairs) == 0 and keep.all() and candidates is not None:
        return mesh  # nothing to merge (the common case of an open or flagged-closed grid)
    tri = tri[keep]
    used = np.zeros(n, dtype=bool)
    used[tri.ravel()] = True
    new_index = np.cumsum(used) - 1
    return TriangleMesh(
        verts[used],
        new_index[tri],
        None if mesh.vertex_normals is None else mesh.vertex_normals[used],
        None if mesh.vertex_colors is None else mesh.vertex_colors[used],
        dict(mesh.metadata),
    )


def _grid_index(n_patches: int, n: int, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """Patch index and sample index of every global sample along one direction."""
    count = n_patches * n if closed else n_patches * n + 1
    g = np.arange(count)
    patch = np.minimum(g // n, n_patches - 1)
    return patch, g - patch * n


def _grid_triangles(rows: int, cols: int, closed_u: bool, closed_v: bool) -> np.ndarray:
    """Two triangles per grid cell, oriented so that the face normal is ``du x dv``."""
    gu = np.arange(rows if closed_u else rows - 1)
    gv = np.arange(cols if closed_v else cols - 1)
    g0, h0 = np.meshgrid(gu, gv, indexing="ij")
    g1, h1 = (g0 + 1) % rows, (h0 + 1) % cols
    a, b, c, d = g0 * cols + h0, g1 * cols + h0, g1 * cols + h1, g0 * cols + h1
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def tessellate(patches: BezierPatches, samples: int = 8, weld_seams: bool = True) -> TriangleMesh:
    """Triangle mesh of a patch grid with shared seam vertices.

    Parameters
    ----------
    patches : BezierPatches
        The surface.
    samples : int
        Subdivisions per patch side (``samples x samples`` quads, twice as many
        triangles per patch); at least 1.
    weld_seams : bool
        Merge vertices on patch seams that coincide in space (poles, edges that
        meet without a closure flag). Keeps closed surfaces watertight.

    Returns
    -------
    TriangleMesh
        Vertices on the surface, vertex normals from the patches, triangles
        counter-clockwise about ``S_u x S_v``.
    """
    if not isinstance(patches, BezierPatches):
        raise ValueError(f"patches: expected BezierPatches, got {type(patches).__name__}")
    n = int(samples)
    if n < 1:
        raise ValueError(f"samples: need at least 1 subdivision per patch side, got {samples}")
    rows, cols = patches.shape
    pi, a = _grid_index(rows, n, patches.closed_u)
    pj, b = _grid_index(cols, n, patches.closed_v)
    PI, PJ = np.meshgrid(pi, pj, indexing="ij")
    A, B = np.meshgrid(a, b, indexing="ij")
    # grid-first layout (n+1, n+1, R, C, 3): one matrix product per quantity
    t = np.linspace(0.0, 1.0, n + 1)
    b0, b1 = bernstein(t), bernstein(t, 1)
    matrix = control_matrix(patches.control.reshape(-1, 4, 4, 3))
    shape = (n + 1, n + 1, rows, cols, 3)
    index = (A, B, PI, PJ)
    verts = tensor_evaluate(matrix, b0, b0).reshape(shape)[index].reshape(-1, 3)
    dus = tensor_evaluate(matrix, b1, b0).reshape(shape)[index].reshape(-1, 3)
    dvs = tensor_evaluate(matrix, b0, b1).reshape(shape)[index].reshape(-1, 3)
    normals, collapsed = patches._unit_normals(
        PI.ravel(), PJ.ravel(), (A / n).ravel(), (B / n).ravel(), dus, dvs, return_degenerate=True
    )
    tri = _grid_triangles(len(pi), len(pj), patches.closed_u, patches.closed_v)
    mesh = TriangleMesh(verts, tri, normals)
    if weld_seams:
        # Seams inside the grid are shared by construction; only the grid's open
        # outer edges and collapsed rows (poles: S_u x S_v = 0) can coincide.
        edge = np.zeros(A.shape, dtype=bool)
        if not patches.closed_u:
            edge[[0, -1], :] = True
        if not patches.closed_v:
            edge[:, [0, -1]] = True
        mesh = weld(mesh, candidates=np.flatnonzero(edge.ravel() | collapsed))
    return mesh


def merge_meshes(meshes, weld_vertices: bool = False) -> TriangleMesh:
    """Concatenate meshes into one.

    Parameters
    ----------
    meshes : sequence of TriangleMesh
        Meshes to join; normals/colours are kept only when every mesh has them.
    weld_vertices : bool
        Merge coincident vertices afterwards (e.g. a surface and its caps).

    Returns
    -------
    TriangleMesh
    """
    meshes = list(meshes)
    if not meshes:
        raise ValueError("meshes: need at least one mesh")
    offsets = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
    verts = np.concatenate([m.vertices for m in meshes])
    tri = np.concatenate([m.triangles + o for m, o in zip(meshes, offsets)])
    normals = (
        np.concatenate([m.vertex_normals for m in meshes])
        if all(m.vertex_normals is not None for m in meshes)
        else None
    )
    colors = (
        np.concatenate([m.vertex_colors for m in meshes])
        if all(m.vertex_colors is not None for m in meshes)
        else None
    )
    out = TriangleMesh(verts, tri, normals, colors)
    return weld(out) if weld_vertices else out
