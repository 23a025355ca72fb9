"""Bicubic Bezier patches of mixed sizes on one square lattice (a quadtree of patches).

An adaptive fit (:mod:`surfaces.fit`) refines patches only where the data need it,
so its patches differ in size and meet at T-junctions: a large patch's edge is shared
by two (or four) smaller ones. :class:`MixedPatches` carries such a model as a flat
patch list in the shared :class:`surfaces.bezier.BezierPatches` form, control shape
``(n, 1, 4, 4, 3)``, plus the square each patch covers on an integer lattice::

    cells[k] = (row, col, size)   # patch k covers lattice rows row .. row + size,
                                  # columns col .. col + size

Its parameter ``u`` runs down the lattice rows and ``v`` along the columns, so two
patches whose squares touch share that piece of edge. Everything written for patch
grids keeps working on the flat list: area and volume (:mod:`surfaces.measure`, a
sum over patches), evaluation, normals and the control net; global parameters
(:meth:`MixedPatches.locate`, ``evaluate_global``) are lattice coordinates. What needs the
adjacency, tessellation, reads the lattice (:func:`surfaces.mesh.tessellate`
samples every patch on one global vertex lattice, so the vertices on a T-junction
are shared and the mesh has no cracks), and :func:`surfaces.io.save_patches`
stores ``cells`` beside ``control``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from surfaces.bezier import BezierPatches
from surfaces.validate import as_array, InputError

__all__ = ["MixedPatches"]


@dataclass(frozen=True)
class MixedPatches(BezierPatches):
    """A flat list of bicubic Bezier patches placed on squares of an integer lattice.

    Parameters
    ----------
    control : array_like, shape (n, 1, 4, 4, 3)
        Control points of the ``n`` patches (the ``BezierPatches`` layout with one
        patch column); ``control[k, 0, a, b]`` is ``b_ab`` of patch ``k``.
    closed_u, closed_v : bool
        Must be False: a quadtree of patches is an open sheet.
    cells : array_like of int, shape (n, 3)
        ``(row, col, size)`` of the lattice square of every patch: ``u`` runs from
        lattice row ``row`` to ``row + size``, ``v`` from column ``col`` to
        ``col + size``. Squares must not overlap (not checked; the fit never makes them).

    Raises
    ------
    ValueError
        On a wrong shape, a closure flag, or cells that do not match the patches
        (negative corners, sizes below 1).

    Examples
    --------
    A unit patch and two half-size patches beside it (a T-junction at lattice (1, 2)):

    >>> from surfaces.coons import from_grid
    >>> def flat(r, c, s):
    ...     y, x = np.meshgrid([r, r + s], [c, c + s], indexing="ij")
    ...     return from_grid(np.stack([x, -y, np.zeros_like(x)], axis=-1)).control[0, 0]
    >>> m = MixedPatches(np.stack([flat(0, 0, 2), flat(0, 2, 1), flat(1, 2, 1)])[:, None],
    ...                  cells=[[0, 0, 2], [0, 2, 1], [1, 2, 1]])
    >>> m.n_patches, m.lattice_shape
    (3, (2, 3))
    """

    cells: np.ndarray | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.closed_u or self.closed_v:
            raise InputError("closed_u, closed_v: patches of mixed sizes form an open sheet")
        if self.control.shape[1] != 1:
            raise InputError(f"control: expected shape (n, 1, 4, 4, 3), got {self.control.shape}")
        if self.cells is None:
            raise InputError("cells: required, (n, 3) lattice squares (row, col, size)")
        cells = np.asarray(self.cells)
        if cells.shape != (self.control.shape[0], 3) or not np.issubdtype(cells.dtype, np.integer):
            raise InputError(
                f"cells: expected integers of shape ({self.control.shape[0]}, 3), got {cells.shape} {cells.dtype}"
            )
        if cells.size and (cells[:, :2].min() < 0 or cells[:, 2].min() < 1):
            raise InputError("cells: corners must be >= 0 and sizes >= 1")
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        cells.setflags(write=False)
        object.__setattr__(self, "cells", cells)

    @property
    def lattice_shape(self) -> tuple[int, int]:
        """Lattice squares spanned ``(rows, cols)``: the largest ``row + size``, ``col + size``."""
        ends = self.cells[:, :2] + self.cells[:, 2:]
        return int(ends[:, 0].max()), int(ends[:, 1].max())

    @property
    def sizes(self) -> np.ndarray:
        """Patch sizes in lattice squares, shape (n,)."""
        return self.cells[:, 2]

    def patch_map(self) -> np.ndarray:
        """The patch covering every unit lattice square, -1 where none does.

        Returns
        -------
        numpy.ndarray, shape lattice_shape, int64
        """
        rows, cols = self.lattice_shape
        unit, coarse = self._unit_map
        return np.repeat(np.repeat(coarse.astype(np.int64), unit, axis=0), unit, axis=1)[:rows, :cols]

    @cached_property
    def _unit_map(self) -> tuple[int, np.ndarray]:
        """:meth:`patch_map` on squares of ``unit`` lattice squares, the largest unit that divides
        every corner and size: ``(unit, map)``, map int32 of shape ``ceil(lattice_shape / unit)``.

        A fit whose smallest patches are 8 pixels wide needs 64 times fewer entries than the
        lattice has squares (a 4 MP fit: 0.5 MB instead of 32 MB of int64, and no index
        arrays of the whole lattice while it is filled). Made once per model (the mesh
        locates its vertices block by block).
        """
        rows, cols = self.lattice_shape
        unit = int(np.gcd.reduce(self.cells.ravel()))
        out = np.full((-(-rows // unit), -(-cols // unit)), -1, np.int32)
        cells = self.cells // unit
        for size in np.unique(cells[:, 2]):
            k = np.flatnonzero(cells[:, 2] == size)
            r0, c0 = cells[k, 0], cells[k, 1]
            dr, dc = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
            out[r0[:, None, None] + dr, c0[:, None, None] + dc] = k[:, None, None]
        return unit, out

    def locate_lattice(self, row, col) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Patch and local parameters of lattice coordinates.

        Parameters
        ----------
        row, col : array_like of float, shape (N,)
            Lattice coordinates (``0 .. lattice_shape``); points on a seam go to the
            patch below/right of it, the outer edges to the last patch.

        Returns
        -------
        patch : numpy.ndarray of int, shape (N,)
            Patch index, -1 where no patch covers the point.
        u, v : numpy.ndarray of float, shape (N,)
            Parameters inside that patch (``(row - cells_row) / size``), in [0, 1].
        """
        r = as_array(row, "row", ndim=1)
        c = as_array(col, "col", ndim=1, shape=r.shape)
        rows, cols = self.lattice_shape
        unit, pmap = self._unit_map
        ir = np.clip(np.floor(r).astype(np.intp), 0, rows - 1) // unit
        ic = np.clip(np.floor(c).astype(np.intp), 0, cols - 1) // unit
        patch = pmap[ir, ic].astype(np.int64)
        cell = self.cells[np.maximum(patch, 0)]
        u = np.clip((r - cell[:, 0]) / cell[:, 2], 0.0, 1.0)
        v = np.clip((c - cell[:, 1]) / cell[:, 2], 0.0, 1.0)
        outside = (r < 0) | (c < 0) | (r > rows) | (c > cols)
        patch = np.where(outside, -1, patch)
        return patch, u, v

    def locate(self, s, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Global parameters are lattice coordinates: :meth:`locate_lattice` in the grid form.

        Parameters
        ----------
        s, t : array_like, shape (N,)
            Lattice row and column, ``0 .. lattice_shape``.

        Returns
        -------
        pi, pj : numpy.ndarray of int, shape (N,)
            Patch index and 0 (the one patch column).
        u, v : numpy.ndarray of float, shape (N,)

        Raises
        ------
        ValueError
            Where no patch covers a point.
        """
        patch, u, v = self.locate_lattice(s, t)
        if (patch < 0).any():
            i = int(np.flatnonzero(patch < 0)[0])
            raise InputError(f"s, t: no patch covers lattice point ({np.ravel(s)[i]}, {np.ravel(t)[i]})")
        return patch, np.zeros_like(patch), u, v

    def transformed(self, matrix=None, offset=None) -> MixedPatches:
        """An affinely transformed copy on the same lattice (see :meth:`BezierPatches.transformed`)."""
        moved = BezierPatches.transformed(self, matrix, offset)
        return MixedPatches(moved.control, cells=self.cells)

    def flipped(self) -> MixedPatches:
        """The same surface with the opposite orientation: ``u`` and the lattice rows reversed."""
        rows, _ = self.lattice_shape
        cells = self.cells.copy()
        cells[:, 0] = rows - cells[:, 0] - cells[:, 2]
        return MixedPatches(self.control[:, :, ::-1], cells=cells)
