"""The one surface model: a grid of bicubic Bezier patches.

Every way into the workbench (Coons patches from a height field or a CT grid,
parabolic blending, B-spline interpolation, kinematic sweeps) ends in a
:class:`BezierPatches`. Evaluation, derivatives and normals are written once
here and vectorised over all patches and points at once.

Conventions
-----------
``control[i, j, a, b]`` is the Bezier control point ``b_ab`` of patch ``(i, j)``.
Index ``a`` runs along the patch parameter ``u`` and the patch-row index ``i``;
index ``b`` runs along ``v`` and the patch-column index ``j``::

    S_ij(u, v) = sum_a sum_b B_a(u) B_b(v) control[i, j, a, b],   u, v in [0, 1]

with the cubic Bernstein polynomials ``B_0 = (1-t)^3, B_1 = 3t(1-t)^2,
B_2 = 3t^2(1-t), B_3 = t^3``. Global parameters ``s in [0, R]``, ``t in [0, C]``
address the whole grid (``s = i + u``). The normal is ``S_u x S_v``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from surfaces.validate import as_array, InputError
from surfaces.vectors import cross, dot

#: Points per chunk in :meth:`BezierPatches.derivatives`; keeps the gathered
#: control points (chunk x 48 doubles) close to the CPU caches.
_CHUNK = 1 << 15

#: Relative tolerance for the join of a closed direction.
_JOIN_RTOL = 1e-9


class SurfaceDerivatives(NamedTuple):
    """Points and partial derivatives at ``N`` parameter locations, each ``(N, 3)``.

    Second derivatives are ``None`` unless asked for.
    """

    point: np.ndarray
    du: np.ndarray
    dv: np.ndarray
    duu: np.ndarray | None = None
    duv: np.ndarray | None = None
    dvv: np.ndarray | None = None


def bernstein(t, order: int = 0) -> np.ndarray:
    """Cubic Bernstein basis (or its derivative) at parameters ``t``.

    Parameters
    ----------
    t : array_like, shape (N,)
        Parameters, usually in [0, 1].
    order : {0, 1, 2}
        Derivative order.

    Returns
    -------
    numpy.ndarray, shape (N, 4)
        ``B_k^(order)(t)`` for ``k = 0..3``.
    """
    t = np.asarray(t, dtype=np.float64)
    s = 1.0 - t
    if order == 0:
        return np.stack([s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t], axis=-1)
    if order == 1:
        return np.stack([-3.0 * s * s, 3.0 * s * (s - 2.0 * t), 3.0 * t * (2.0 * s - t), 3.0 * t * t], axis=-1)
    if order == 2:
        return np.stack([6.0 * s, 6.0 * (3.0 * t - 2.0), 6.0 * (1.0 - 3.0 * t), 6.0 * t], axis=-1)
    raise InputError(f"order: must be 0, 1 or 2, got {order!r}")


def control_matrix(control) -> np.ndarray:
    """Control points of ``P`` patches laid out as one ``(16, P * 3)`` matrix.

    Parameters
    ----------
    control : numpy.ndarray, shape (P, 4, 4, 3)

    Returns
    -------
    numpy.ndarray, shape (16, P * 3)
        Row ``4 a + b`` holds ``control[:, a, b, :]`` of every patch.
    """
    n = len(control)
    return np.ascontiguousarray(control.reshape(n, 16, 3).transpose(1, 0, 2)).reshape(16, n * 3)


def tensor_evaluate(matrix, bu, bv) -> np.ndarray:
    """Evaluate many patches on a tensor grid with one matrix product.

    ``out[i, j, p] = sum_a sum_b bu[i, a] * bv[j, b] * control[p, a, b]``.

    Parameters
    ----------
    matrix : numpy.ndarray, shape (16, P * 3)
        Control points from :func:`control_matrix`.
    bu : numpy.ndarray, shape (Q, 4)
        Basis values (or derivatives) along ``u``.
    bv : numpy.ndarray, shape (S, 4)
        Basis values (or derivatives) along ``v``.

    Returns
    -------
    numpy.ndarray, shape (Q, S, P, 3)
        Grid-first layout (contiguous; cheap to combine point-wise).
    """
    weights = (bu[:, None, :, None] * bv[None, :, None, :]).reshape(len(bu) * len(bv), 16)
    return (weights @ matrix).reshape(len(bu), len(bv), -1, 3)


@dataclass(frozen=True)
class BezierPatches:
    """A grid of bicubic Bezier patches, the shared surface model.

    Parameters
    ----------
    control : array_like, shape (R, C, 4, 4, 3)
        Control points, float64; see the module docstring for the index order.
    closed_u : bool
        The ``u`` (patch-row) direction closes on itself: the ``u = 1`` edge of
        patch row ``R - 1`` is the ``u = 0`` edge of patch row 0.
    closed_v : bool
        The same for the ``v`` (patch-column) direction.

    Raises
    ------
    ValueError
        On a wrong shape, non-finite values, or a closed direction whose first
        and last edges do not join.
    """

    control: np.ndarray
    closed_u: bool = False
    closed_v: bool = False

    def __post_init__(self) -> None:
        ctrl = as_array(self.control, "control", shape=(None, None, 4, 4, 3), finite=False)
        if ctrl.shape[0] < 1 or ctrl.shape[1] < 1:
            raise InputError(f"control: needs at least one patch, got shape {ctrl.shape}")
        ctrl = np.ascontiguousarray(ctrl)
        # NaN and infinities reach the extremes: two reductions check finiteness and give the scale
        high, low = float(ctrl.max()), float(ctrl.min())
        if not (np.isfinite(high) and np.isfinite(low)):
            bad = int(ctrl.size - np.count_nonzero(np.isfinite(ctrl)))
            raise InputError(f"control: contains {bad} NaN or infinite value(s)")
        ctrl.setflags(write=False)
        object.__setattr__(self, "control", ctrl)
        scale = max(high, -low, 1.0)
        tol = _JOIN_RTOL * scale
        if self.closed_u:
            gap = float(np.max(np.abs(ctrl[-1, :, 3, :] - ctrl[0, :, 0, :])))
            if gap > tol:
                raise InputError(
                    f"closed_u: the last patch row does not join the first (gap {gap:.3g})"
                )
        if self.closed_v:
            gap = float(np.max(np.abs(ctrl[:, -1, :, 3] - ctrl[:, 0, :, 0])))
            if gap > tol:
                raise InputError(
                    f"closed_v: the last patch column does not join the first (gap {gap:.3g})"
                )

    @classmethod
    def unchecked(cls, control: np.ndarray, closed_u: bool = False, closed_v: bool = False) -> BezierPatches:
        """Patches over control points known to be valid (from checked patches), without the checks.

        The kernel path of code that builds patches from patches it has checked (a
        blend of finite curves, the side columns of a checked grid): no copy, no
        finiteness or closing test. Anything else should call the constructor.

        Parameters
        ----------
        control : numpy.ndarray, shape (R, C, 4, 4, 3), float64
            Finite control points (mm), closing where flagged; kept as a read-only
            view, not copied (a view of some columns of a grid too).
        closed_u, closed_v : bool
            Whether the patch rows (columns) close on themselves; not checked.

        Returns
        -------
        BezierPatches
            Over a view of ``control``.
        """
        ctrl = control.view()
        ctrl.setflags(write=False)
        out = object.__new__(cls)
        object.__setattr__(out, "control", ctrl)
        object.__setattr__(out, "closed_u", bool(closed_u))
        object.__setattr__(out, "closed_v", bool(closed_v))
        return out

    # ------------------------------------------------------------------ shape
    @property
    def shape(self) -> tuple[int, int]:
        """Number of patch rows and columns ``(R, C)``."""
        return self.control.shape[0], self.control.shape[1]

    @property
    def n_patches(self) -> int:
        """Total number of patches ``R * C``."""
        return self.control.shape[0] * self.control.shape[1]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box of the control points (contains the surface).

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            Minimum and maximum corner, each shape (3,).
        """
        pts = self.control.reshape(-1, 3)
        return pts.min(axis=0), pts.max(axis=0)

    # -------------------------------------------------------------- evaluation
    def _check_params(self, pi, pj, u, v):
        pi = np.asarray(pi)
        pj = np.asarray(pj)
        u = as_array(u, "u", ndim=1)
        v = as_array(v, "v", ndim=1)
        n = u.shape[0]
        pi = np.broadcast_to(pi, (n,)) if pi.ndim == 0 else pi
        pj = np.broadcast_to(pj, (n,)) if pj.ndim == 0 else pj
        if not (pi.shape == pj.shape == v.shape == (n,)):
            raise InputError(
                f"pi, pj, u, v: need equal lengths, got {pi.shape}, {pj.shape}, {u.shape}, {v.shape}"
            )
        if not (np.issubdtype(pi.dtype, np.integer) and np.issubdtype(pj.dtype, np.integer)):
            raise InputError("pi, pj: patch indices must be integers")
        rows, cols = self.shape
        if n and (pi.min() < 0 or pi.max() >= rows or pj.min() < 0 or pj.max() >= cols):
            raise InputError(f"pi, pj: patch index outside the {rows}x{cols} patch grid")
        return pi.astype(np.intp), pj.astype(np.intp), u, v

    def derivatives(self, pi, pj, u, v, order: int = 1) -> SurfaceDerivatives:
        """Points and partial derivatives at arbitrary patch parameters.

        Parameters
        ----------
        pi, pj : array_like of int, shape (N,)
            Patch row and column of each location (scalars broadcast).
        u, v : array_like of float, shape (N,)
            Parameters inside the patch, in [0, 1].
        order : {0, 1, 2}
            Highest derivative order wanted.

        Returns
        -------
        SurfaceDerivatives
            ``point``, ``du``, ``dv`` (and ``duu``, ``duv``, ``dvv`` for order 2),
            each shape (N, 3), per unit of patch parameter. For ``order=0`` the
            derivative fields hold empty arrays.
        """
        if order not in (0, 1, 2):
            raise InputError(f"order: must be 0, 1 or 2, got {order!r}")
        pi, pj, u, v = self._check_params(pi, pj, u, v)
        n = u.shape[0]
        flat = self.control.reshape(-1, 16, 3)
        patch = pi * self.shape[1] + pj
        wanted = [(0, 0)]
        if order >= 1:
            wanted += [(1, 0), (0, 1)]
        if order >= 2:
            wanted += [(2, 0), (1, 1), (0, 2)]
        out = [np.empty((n, 3)) for _ in wanted]
        for start in range(0, n, _CHUNK):
            sl = slice(start, min(start + _CHUNK, n))
            ctrl = flat[patch[sl]]  # (k, 16, 3)
            bu = [bernstein(u[sl], d) for d in range(order + 1)]
            bv = [bernstein(v[sl], d) for d in range(order + 1)]
            for slot, (du, dv) in enumerate(wanted):
                # tensor-product weights of the 16 control points, then one contraction (a stacked
                # product of (1, 16) by (16, 3) per point: twice as fast as einsum's loop)
                weights = (bu[du][:, :, None] * bv[dv][:, None, :]).reshape(-1, 1, 16)
                out[slot][sl] = (weights @ ctrl)[:, 0]
        if order == 0:
            empty = np.empty((n, 3))[:0]
            return SurfaceDerivatives(out[0], empty, empty)
        return SurfaceDerivatives(*out)

    def evaluate(self, pi, pj, u, v) -> np.ndarray:
        """Surface points at arbitrary patch parameters.

        Parameters
        ----------
        pi, pj : array_like of int, shape (N,)
            Patch row and column of each location.
        u, v : array_like of float, shape (N,)
            Parameters inside the patch, in [0, 1].

        Returns
        -------
        numpy.ndarray, shape (N, 3)
            Points.
        """
        return self.derivatives(pi, pj, u, v, order=0).point

    def normals(self, pi, pj, u, v) -> np.ndarray:
        """Unit normals ``S_u x S_v / |S_u x S_v|`` at arbitrary patch parameters.

        Where the cross product vanishes (a pole, a collapsed edge) the normal is
        taken a small step inside the patch, so every returned normal is unit.

        Parameters
        ----------
        pi, pj : array_like of int, shape (N,)
            Patch row and column of each location.
        u, v : array_like of float, shape (N,)
            Parameters inside the patch, in [0, 1].

        Returns
        -------
        numpy.ndarray, shape (N, 3)
            Unit normals.
        """
        d = self.derivatives(pi, pj, u, v, order=1)
        return self._unit_normals(pi, pj, np.asarray(u, float), np.asarray(v, float), d.du, d.dv)

    def _unit_normals(self, pi, pj, u, v, du, dv, return_degenerate: bool = False):
        normal = cross(du, dv)
        length2 = dot(normal, normal)
        scale2 = dot(du, du) * dot(dv, dv)
        # |du x dv| <= 1e-10 |du| |dv|: a pole or a collapsed edge
        degenerate = length2 <= 1e-20 * np.maximum(scale2, 1e-300)
        if np.any(degenerate):
            # step towards the patch centre: at a pole the limit normal is the
            # normal of the nearby regular points
            pi_d = np.broadcast_to(np.asarray(pi), u.shape)[degenerate]
            pj_d = np.broadcast_to(np.asarray(pj), u.shape)[degenerate]
            ud, vd = u[degenerate], v[degenerate]
            for step in (1e-6, 1e-4, 1e-2):
                us = ud + step * np.sign(0.5 - ud)
                vs = vd + step * np.sign(0.5 - vd)
                dd = self.derivatives(pi_d, pj_d, us, vs, order=1)
                alt = cross(dd.du, dd.dv)
                if np.all(np.linalg.norm(alt, axis=-1) > 0):
                    break
            normal[degenerate] = alt
            length2[degenerate] = dot(alt, alt)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = normal / np.sqrt(np.where(length2 > 0, length2, 1.0))[..., None]
        return (unit, degenerate) if return_degenerate else unit

    def evaluate_grid(self, n_u: int, n_v: int, order: int = 0):
        """Evaluate every patch on a regular ``n_u x n_v`` parameter grid.

        Both patch edges are included (``u = linspace(0, 1, n_u)``), so
        neighbouring patches repeat their shared edge.

        Parameters
        ----------
        n_u, n_v : int
            Samples per patch along ``u`` and ``v`` (at least 2).
        order : {0, 1}
            0 returns points only; 1 returns ``(points, du, dv)``.

        Returns
        -------
        numpy.ndarray or tuple of numpy.ndarray
            Shape (R, C, n_u, n_v, 3) each.
        """
        if int(n_u) < 2 or int(n_v) < 2:
            raise InputError(f"n_u, n_v: need at least 2 samples per patch, got {n_u}, {n_v}")
        if order not in (0, 1):
            raise InputError(f"order: must be 0 or 1, got {order!r}")
        tu = np.linspace(0.0, 1.0, int(n_u))
        tv = np.linspace(0.0, 1.0, int(n_v))
        bu0, bv0 = bernstein(tu), bernstein(tv)
        matrix = control_matrix(self.control.reshape(-1, 4, 4, 3))
        rows, cols = self.shape

        def grid(bu, bv):
            out = tensor_evaluate(matrix, bu, bv).reshape(int(n_u), int(n_v), rows, cols, 3)
            return out.transpose(2, 3, 0, 1, 4)

        pts = grid(bu0, bv0)
        if order == 0:
            return pts
        return pts, grid(bernstein(tu, 1), bv0), grid(bu0, bernstein(tv, 1))

    def locate(self, s, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Map global parameters to patch indices and local parameters.

        Parameters
        ----------
        s : array_like, shape (N,)
            Global ``u`` parameter in [0, R] (wrapped modulo R when closed in u).
        t : array_like, shape (N,)
            Global ``v`` parameter in [0, C] (wrapped modulo C when closed in v).

        Returns
        -------
        pi, pj : numpy.ndarray of int, shape (N,)
        u, v : numpy.ndarray of float, shape (N,)
        """
        s = as_array(s, "s", ndim=1)
        t = as_array(t, "t", ndim=1)
        rows, cols = self.shape
        out = []
        for x, n, closed, name in ((s, rows, self.closed_u, "s"), (t, cols, self.closed_v, "t")):
            if closed:
                x = np.mod(x, n)
            elif x.size and (x.min() < -1e-12 or x.max() > n + 1e-12):
                raise InputError(f"{name}: global parameters must lie in [0, {n}]")
            idx = np.clip(np.floor(x).astype(np.intp), 0, n - 1)
            out += [idx, np.clip(x - idx, 0.0, 1.0)]
        return out[0], out[2], out[1], out[3]

    def evaluate_global(self, s, t) -> np.ndarray:
        """Surface points at global parameters ``s in [0, R]``, ``t in [0, C]``.

        Parameters
        ----------
        s, t : array_like, shape (N,)
            Global parameters.

        Returns
        -------
        numpy.ndarray, shape (N, 3)
            Points.
        """
        pi, pj, u, v = self.locate(s, t)
        return self.evaluate(pi, pj, u, v)

    def transformed(self, matrix=None, offset=None) -> BezierPatches:
        """An affinely transformed copy (Bezier patches are affine invariant).

        Parameters
        ----------
        matrix : array_like, shape (3, 3), optional
            Linear part applied as ``x @ matrix.T``.
        offset : array_like, shape (3,), optional
            Translation added afterwards.

        Returns
        -------
        BezierPatches
        """
        ctrl = self.control
        if matrix is not None:
            ctrl = ctrl @ as_array(matrix, "matrix", shape=(3, 3)).T
        if offset is not None:
            ctrl = ctrl + as_array(offset, "offset", shape=(3,))
        return BezierPatches(ctrl, self.closed_u, self.closed_v)

    def flipped(self) -> BezierPatches:
        """The same surface with the opposite orientation (``u`` reversed).

        Returns
        -------
        BezierPatches
            Patch rows and the ``a`` index reversed, so ``S_u x S_v`` flips.
        """
        return BezierPatches(self.control[::-1, :, ::-1], self.closed_u, self.closed_v)


def control_net_segments(patches) -> np.ndarray:
    """Line segments of the Bezier control net (seed 001's "carcass").

    Parameters
    ----------
    patches : BezierPatches or array_like
        Patch model, or its ``control`` array of shape (R, C, 4, 4, 3).

    Returns
    -------
    (K, 2, 3) float64
        Segment end points: for every patch, the 4 control polygons along u and
        the 4 along v (3 segments each), K = 24 R C. Edges shared by two patches
        appear twice.

    Examples
    --------
    >>> control_net_segments(np.zeros((2, 3, 4, 4, 3))).shape
    (144, 2, 3)
    """
    ctrl = as_array(getattr(patches, "control", patches), "patches.control", shape=(None, None, 4, 4, 3))
    along_u = np.stack([ctrl[:, :, :-1, :], ctrl[:, :, 1:, :]], axis=-2)
    along_v = np.stack([ctrl[:, :, :, :-1], ctrl[:, :, :, 1:]], axis=-2)
    return np.concatenate([along_u.reshape(-1, 2, 3), along_v.reshape(-1, 2, 3)])
