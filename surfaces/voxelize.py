"""Voxel grids: a closed triangle mesh or planar polygons rasterised (which voxel centres lie inside).

The grid follows the NIfTI convention of an affine: voxel ``(i, j, k)`` (array
axes i, j, k) has its centre at ``affine @ (i, j, k, 1)``. :func:`occupancy`
decides inside by open3d's ray-casting occupancy (a parity of crossings, robust
on closed meshes), in chunks so memory stays bounded. :func:`fill_polygons`
fills planar rings by the even-odd rule (holes and overlaps toggle), exactly at
the pixel centres, vectorised over all edges. :class:`VoxelGrid` is a grid's
affine and shape; :func:`lps_to_ras` turns a DICOM patient (LPS) affine into
the RAS affine every NIfTI reader expects.
"""

from __future__ import annotations

import numpy as np

from dataclasses import dataclass

from surfaces.validate import InputError, as_array, positive

__all__ = ["VoxelGrid", "fill_polygons", "grid_affine", "grid_occupancy", "lps_to_ras", "occupancy"]

#: DICOM patient coordinates (LPS: +x left, +y posterior, +z head) to RAS (NIfTI): x and y negated.
LPS_TO_RAS = np.diag([-1.0, -1.0, 1.0, 1.0])

#: Voxel centres tested per call of the ray caster.
_CHUNK = 2_000_000


def grid_affine(lower, spacing) -> np.ndarray:
    """Affine of an axis-aligned grid whose voxel (0, 0, 0) is centred at ``lower``.

    Parameters
    ----------
    lower : array_like, shape (3,)
        x, y, z of the first voxel centre (mm).
    spacing : array_like, shape (3,)
        Voxel size along x, y, z (mm, > 0).

    Returns
    -------
    numpy.ndarray, shape (4, 4)

    Examples
    --------
    >>> grid_affine([1, 2, 3], [0.5, 0.5, 2]).tolist()[2]
    [0.0, 0.0, 2.0, 3.0]
    """
    lo = as_array(lower, "lower", shape=(3,))
    sp = np.array([positive(s, "spacing") for s in as_array(spacing, "spacing", shape=(3,))])
    affine = np.diag(np.append(sp, 1.0))
    affine[:3, 3] = lo
    return affine


def occupancy(mesh, spacing, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Voxels of an axis-aligned grid whose centres lie inside a closed mesh.

    Parameters
    ----------
    mesh : TriangleMesh
        Closed, consistently oriented mesh (mm).
    spacing : array_like, shape (3,)
        Voxel size along x, y, z (mm).
    margin : float
        Empty border around the mesh's bounding box (mm).

    Returns
    -------
    mask : numpy.ndarray, shape (nx, ny, nz) uint8
        1 inside, 0 outside (array axes x, y, z, as NIfTI stores them).
    affine : numpy.ndarray, shape (4, 4)
        Voxel indices to mm (:func:`grid_affine`).

    Examples
    --------
    A 2 mm cube on a 0.5 mm grid: 4 x 4 x 4 voxel centres inside.

    >>> from surfaces.mesh import TriangleMesh
    >>> v = np.array([[x, y, z] for x in (0, 2) for y in (0, 2) for z in (0, 2)], float)
    >>> t = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    >>> mask, affine = occupancy(TriangleMesh(v, t), [0.5, 0.5, 0.5])
    >>> int(mask.sum()), float(affine[0, 3])
    (64, 0.25)
    """
    import open3d as o3d

    sp = np.array([positive(s, "spacing") for s in as_array(spacing, "spacing", shape=(3,))])
    m = positive(margin, "margin", allow_zero=True)
    lo = mesh.vertices.min(axis=0) - m
    hi = mesh.vertices.max(axis=0) + m
    shape = np.maximum(np.floor((hi - lo) / sp).astype(int), 1)
    first = lo + 0.5 * (hi - lo - (shape - 1) * sp)  # centre the grid on the box
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    axes = [first[a] + sp[a] * np.arange(shape[a]) for a in range(3)]
    mask = np.zeros(tuple(shape), dtype=np.uint8)
    per_x = int(shape[1] * shape[2])
    step = max(1, _CHUNK // max(per_x, 1))
    yy, zz = np.meshgrid(axes[1], axes[2], indexing="ij")
    for i0 in range(0, shape[0], step):
        xs = axes[0][i0:i0 + step]
        pts = np.stack([np.repeat(xs, per_x), np.tile(yy.ravel(), len(xs)), np.tile(zz.ravel(), len(xs))], axis=1)
        occ = scene.compute_occupancy(o3d.core.Tensor(pts.astype(np.float32))).numpy()
        mask[i0:i0 + len(xs)] = occ.reshape(len(xs), shape[1], shape[2]).astype(np.uint8)
    return mask, grid_affine(first, sp)


def lps_to_ras(affine) -> np.ndarray:
    """A voxel-to-LPS affine (DICOM patient mm) as the voxel-to-RAS affine NIfTI stores.

    The same matrix turns a RAS affine back into LPS (it is its own inverse).

    Parameters
    ----------
    affine : array_like, shape (4, 4)

    Returns
    -------
    numpy.ndarray, shape (4, 4)
        ``diag(-1, -1, 1, 1) @ affine``.

    Examples
    --------
    >>> lps_to_ras(np.diag([0.5, 0.5, 2.0, 1.0]))[:3, :3].diagonal().tolist()
    [-0.5, -0.5, 2.0]
    """
    return LPS_TO_RAS @ as_array(affine, "affine", shape=(4, 4))


@dataclass(frozen=True)
class VoxelGrid:
    """A voxel grid: voxel ``(i, j, k)`` centred at ``affine @ (i, j, k, 1)``.

    Attributes
    ----------
    affine : numpy.ndarray, shape (4, 4)
        Voxel indices to mm (in the frame of the data, e.g. DICOM LPS).
    shape : tuple of int
        ``(ni, nj, nk)`` voxels.
    """

    affine: np.ndarray
    shape: tuple

    @property
    def n_voxels(self) -> int:
        """Number of voxels (a Python int: no overflow however large)."""
        return int(self.shape[0]) * int(self.shape[1]) * int(self.shape[2])

    @property
    def spacing(self) -> np.ndarray:
        """Voxel size along i, j, k (mm), shape (3,)."""
        return np.linalg.norm(self.affine[:3, :3], axis=0)

    @property
    def planes(self) -> np.ndarray:
        """World z (mm) of the planes k = 0 ... nk-1 (axial grids), shape (nk,)."""
        return self.affine[2, 3] + self.affine[2, 2] * np.arange(int(self.shape[2]))

    def check_axial(self, label: str = "grid") -> None:
        """Raise :class:`InputError` unless k runs along world z and i, j lie in axial planes.

        Parameters
        ----------
        label : str
            Names the grid in the message.
        """
        a = self.affine[:3, :3]
        scale = float(np.abs(a).max())
        if abs(a[2, 0]) > 1e-6 * scale or abs(a[2, 1]) > 1e-6 * scale or np.abs(a[:2, 2]).max() > 1e-6 * scale \
                or a[2, 2] == 0:
            raise InputError(f"{label}: its planes are not axial (affine {a.round(6).tolist()}); "
                             "masks are written on axial grids")


def fill_polygons(rings, shape) -> np.ndarray:
    """Pixels whose centres lie inside planar rings, by the even-odd rule.

    Coordinates are continuous pixel indices: pixel ``(i, j)`` is centred at
    ``(i, j)``. A centre is inside when a ray towards +i crosses the rings an odd
    number of times, so holes (and overlaps) toggle. Edges are half-open in j, so
    a vertex on a row of centres is counted once.

    Parameters
    ----------
    rings : sequence of array_like, each shape (n, 2)
        Closed rings (the last vertex joins the first), in pixel indices ``(i, j)``.
    shape : tuple of int
        ``(ni, nj)`` pixels.

    Returns
    -------
    numpy.ndarray, shape (ni, nj), bool

    Examples
    --------
    A 4 x 4 square with a 2 x 2 hole on a 6 x 6 grid: 16 - 4 centres.

    >>> sq = np.array([[0.5, 0.5], [4.5, 0.5], [4.5, 4.5], [0.5, 4.5]])
    >>> hole = np.array([[1.5, 1.5], [1.5, 3.5], [3.5, 3.5], [3.5, 1.5]])
    >>> int(fill_polygons([sq, hole], (6, 6)).sum())
    12
    """
    ni, nj = int(shape[0]), int(shape[1])
    toggles = np.zeros((nj, ni + 1), dtype=np.int32)
    for ring in rings:
        p = np.asarray(ring, dtype=np.float64)
        if len(p) < 3:
            continue
        a, b = p, np.roll(p, -1, axis=0)
        lo, hi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
        first = np.maximum(np.ceil(lo), 0).astype(np.int64)  # rows j with lo <= j < hi
        last = np.minimum(np.ceil(hi) - 1, nj - 1).astype(np.int64)
        count = np.maximum(last - first + 1, 0)
        if not count.any():
            continue
        edge = np.repeat(np.arange(len(p)), count)
        row = first[edge] + (np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count))
        t = (row - a[edge, 1]) / (b[edge, 1] - a[edge, 1])
        x = a[edge, 0] + t * (b[edge, 0] - a[edge, 0])
        col = np.clip(np.ceil(x), 0, ni).astype(np.int64)  # first centre at or right of the crossing
        np.add.at(toggles, (row, col), 1)
    return (np.cumsum(toggles[:, :ni], axis=1) % 2).astype(bool).T


def grid_occupancy(mesh, grid: VoxelGrid) -> np.ndarray:
    """Voxels of any grid (:class:`VoxelGrid`) whose centres lie inside a closed mesh (open3d ray parity).

    Parameters
    ----------
    mesh : TriangleMesh
        Closed, consistently oriented mesh, in the grid's frame (mm).
    grid : VoxelGrid

    Returns
    -------
    numpy.ndarray, shape grid.shape, uint8
    """
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    ni, nj, nk = (int(s) for s in grid.shape)
    mask = np.zeros((ni, nj, nk), dtype=np.uint8)
    jj, ii = np.meshgrid(np.arange(nj), np.arange(ni))
    plane = np.column_stack([ii.ravel(), jj.ravel()]).astype(np.float64)
    for k in range(nk):
        idx = np.column_stack([plane, np.full(len(plane), k), np.ones(len(plane))])
        pts = idx @ grid.affine[:3].T
        occ = scene.compute_occupancy(o3d.core.Tensor(pts.astype(np.float32))).numpy()
        mask[:, :, k] = occ.reshape(ni, nj).astype(np.uint8)
    return mask
