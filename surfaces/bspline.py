"""Global B-spline interpolation of curves and surfaces (seed 003; Piegl & Tiller ch. 9).

A curve through points ``Q_0 .. Q_n`` gets parameters ``u_k`` (uniform, chord
length or centripetal; The NURBS Book eqs. 9.3-9.6), a clamped knot vector by
averaging (eq. 9.8), both from :mod:`surfaces.knots`, and control points from the collocation system
``sum_i N_{i,p}(u_k) P_i = Q_k`` (eq. 9.7), solved once for every coordinate
(and every row of a surface) as one sparse system with many right-hand sides.

A surface through a grid ``Q[k, l]`` (shape ``(R, C, 3)``) is built by the
two-stage method of seed 003 (The NURBS Book, Algorithm A9.4): interpolate
along the first index (u) for every column, then interpolate the resulting
control points along the second index (v). One parameter vector per direction
is the average of the per-line parameters (lines of zero length, i.e. a
collapsed row at a pole, are left out of the average).

Conventions
-----------
* ``points[k, l]``: ``k`` runs along **u** (axis 0), ``l`` along **v** (axis 1).
  For a CT contour stack pass the grid as ``(n_samples_around_contour,
  n_slices, 3)`` with ``closed_u=True``: u goes around the contour, v across
  the slices.
* Parameters of an open direction run over ``[0, 1]`` (``u = 1`` is the last
  data point). A closed (periodic) direction also uses ``[0, 1]`` with period 1:
  ``u = 0`` and ``u = 1`` are the first data point; the data points of a closed
  direction are given **without** repeating the first one at the end (a last
  point/row equal to the first is dropped, which is the stated rule).
* Closed knot vectors: periodic knots at the data parameters for odd degree and
  at the parameter midpoints for even degree (the periodic counterpart of the
  averaging of eq. 9.8; for odd degree it is also what
  ``scipy.interpolate.make_interp_spline(bc_type="periodic")`` uses).
* Degenerate input: repeated consecutive points in a curve (zero chord) raise
  ``ValueError``; in a surface a parameter step is zero only when the two rows
  (columns) coincide in every column (row), which raises ``ValueError`` naming
  them. A collapsed row (all its points equal: a pole) is allowed.

Conversion to the shared model (:class:`surfaces.bezier.BezierPatches`) is
exact (:func:`surfaces.knots.bezier_pieces`): every knot span becomes one Bezier piece whose control points are the
blossom values ``f(t_s, .., t_s, t_{s+1}, .., t_{s+1})`` (the result of
inserting every interior knot up to multiplicity ``p``, The NURBS Book
Algorithm A5.6). Degree 3 maps directly; degree 2 is elevated exactly to 3;
degrees 4 and 5 cannot be represented by bicubic patches and raise
``ValueError``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg
from scipy.interpolate import BSpline, NdBSpline

from surfaces.knots import (
    bezier_pieces,
    check_degree,
    cubic_pieces,
    data_parameters,
    interpolation_knots,
    span_parameters,
    to_knot_domain,
)
from surfaces.validate import as_array, drop_closing_repeat, InputError

if TYPE_CHECKING:
    from surfaces.bezier import BezierPatches

__all__ = [
    "BSplineCurve",
    "BSplineSurface",
    "interpolate_curve",
    "interpolate_surface",
    "interpolate_surface_patches",
]


# ----------------------------------------------------------------------------- collocation
class _Collocation:
    """Factorised (N, N) collocation matrix of eq. 9.7, solved for many right-hand sides.

    Open: the matrix is banded (at most ``p`` nonzeros per row, within ``p`` of the
    diagonal): LAPACK's banded solver via ``scipy.linalg.solve_banded``. Closed:
    periodic columns fold the band into the corners, so a sparse LU is used.
    """

    def __init__(self, params: np.ndarray, knots: np.ndarray, degree: int, closed: bool):
        n = params.size
        x = to_knot_domain(params, knots, degree) if closed else params
        dm = BSpline.design_matrix(x, knots, degree).tocoo()
        self.degree = degree
        self.lu = None
        if closed:
            mat = scipy.sparse.csc_matrix((dm.data, (dm.row, dm.col % n)), shape=(n, n))
            try:
                self.lu = scipy.sparse.linalg.splu(mat)
            except RuntimeError as exc:  # singular: Schoenberg-Whitney violated
                raise InputError(f"points: the interpolation system is singular ({exc})") from None
        else:
            self.band = np.zeros((2 * degree + 1, n))
            np.add.at(self.band, (degree + dm.row - dm.col, dm.col), dm.data)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve for all right-hand sides at once; ``rhs`` (N, ...) -> (N, ...)."""
        flat = np.ascontiguousarray(rhs.reshape(rhs.shape[0], -1))
        if self.lu is not None:
            out = self.lu.solve(flat)
        else:
            try:
                out = scipy.linalg.solve_banded((self.degree, self.degree), self.band, flat)
            except np.linalg.LinAlgError as exc:
                raise InputError(f"points: the interpolation system is singular ({exc})") from None
        return out.reshape(rhs.shape)


def _unwrap_control(control: np.ndarray, degree: int, axis: int) -> np.ndarray:
    """Append the first ``p`` control points along ``axis`` (periodic unwrapping)."""
    head = np.take(control, np.arange(degree), axis=axis)
    return np.concatenate([control, head], axis=axis)


def _domain_u(u, name: str, closed: bool, knots: np.ndarray, degree: int) -> np.ndarray:
    """Checked parameters of one direction mapped into its knot domain (periodic when closed)."""
    arr = np.atleast_1d(as_array(u, name, ndim=(0, 1)))
    if closed:
        return to_knot_domain(arr, knots, degree)
    if arr.size and (arr.min() < -1e-12 or arr.max() > 1 + 1e-12):
        raise InputError(f"{name}: parameters of an open direction must lie in [0, 1]")
    return np.clip(arr, 0.0, 1.0)


# ----------------------------------------------------------------------------- curves
@dataclass(frozen=True)
class BSplineCurve:
    """Non-rational B-spline curve (open or periodic) from :func:`interpolate_curve`.

    Attributes
    ----------
    degree : int
        Degree ``p``.
    knots : (K,) numpy.ndarray of float64
        Full knot vector: clamped ``(N + p + 1,)`` when open; the unwrapped periodic
        vector ``(N + 2p + 1,)`` when closed.
    control : (N, d) numpy.ndarray of float64
        Distinct control points (a closed curve repeats the first ``p`` implicitly).
    params : (M,) numpy.ndarray of float64
        Parameters of the interpolated data points (empty for a curve built from
        control points).
    closed : bool
        Periodic curve with period 1 in the parameter.
    """

    degree: int
    knots: np.ndarray
    control: np.ndarray
    params: np.ndarray
    closed: bool = False

    @property
    def dim(self) -> int:
        """Dimension ``d`` of the curve's points."""
        return int(self.control.shape[1])

    @property
    def full_control(self) -> np.ndarray:
        """Control points of the unwrapped spline, ``(len(knots) - p - 1, d)``."""
        if self.closed:
            return _unwrap_control(self.control, self.degree, 0)
        return self.control

    def _spline(self) -> BSpline:
        return BSpline(self.knots, self.full_control, self.degree, extrapolate=True)

    def evaluate(self, u) -> np.ndarray:
        """Points at parameters ``u`` (``(M,)`` in ``[0, 1]``, periodic if closed) -> ``(M, d)``."""
        x = _domain_u(u, "u", self.closed, self.knots, self.degree)
        return self._spline()(x)

    def derivative(self, u, order: int = 1) -> np.ndarray:
        """Derivative of the given order (1 .. p) with respect to u at ``u`` -> ``(M, d)``."""
        if not 0 <= int(order) <= self.degree:
            raise InputError(f"order: expected 0 to {self.degree}, got {order}")
        x = _domain_u(u, "u", self.closed, self.knots, self.degree)
        return self._spline()(x, nu=int(order))

    def with_control(self, control) -> BSplineCurve:
        """The same knots and degree with moved control points (deformation, seed 004).

        Parameters
        ----------
        control : (N, d) array_like of float
            New distinct control points, same shape as :attr:`control`.
        """
        c = as_array(control, "control", shape=self.control.shape)
        return BSplineCurve(self.degree, self.knots, c, np.empty(0), self.closed)

    def bezier_segments(self) -> np.ndarray:
        """Exact Bezier pieces of the curve, ``(S, p + 1, d)`` (knot insertion)."""
        return bezier_pieces(self.knots, self.degree, self.full_control)


def interpolate_curve(
    points,
    degree: int = 3,
    method: str = "chord",
    closed: bool = False,
    params=None,
) -> BSplineCurve:
    """Global B-spline interpolation of a curve (The NURBS Book sec. 9.2.1, seed 003).

    Parameters
    ----------
    points : (N, d) array_like of float
        Data points (any unit), ``d >= 1``. Open: ``N >= degree + 1``. Closed: the
        first point is not repeated at the end (a repeated last point is dropped).
    degree : int, optional
        Degree 2 to 5 (default 3).
    method : {"chord", "uniform", "centripetal"}, optional
        Parameterisation (eqs. 9.3, 9.4-9.5, 9.6).
    closed : bool, optional
        Periodic interpolation (C^{p-1} everywhere, period 1).
    params : (N,) array_like of float, optional
        Explicit data parameters instead of ``method``: strictly increasing, ``[0, 1]``
        with both ends when open, ``[0, 1)`` starting at 0 when closed.

    Returns
    -------
    BSplineCurve
        The curve with ``curve.evaluate(curve.params) == points``.

    Raises
    ------
    ValueError
        Bad shape, too few points, repeated consecutive points (zero chord), bad degree.

    Examples
    --------
    The NURBS Book, Example 9.1: chords 5, 4, 5, 3 give the parameters ``(0, 5, 9, 14, 17) / 17``
    and the averaged knots ``(0, 0, 0, 0, 28/51, 1, 1, 1, 1)``.

    >>> curve = interpolate_curve([[0, 0], [3, 4], [-1, 4], [-4, 0], [-4, -3]], degree=3)
    >>> (curve.params * 17).round(12).tolist()
    [0.0, 5.0, 9.0, 14.0, 17.0]
    >>> (curve.knots * 51).round(12).tolist()
    [0.0, 0.0, 0.0, 0.0, 28.0, 51.0, 51.0, 51.0, 51.0]
    >>> bool(np.allclose(curve.evaluate(curve.params), [[0, 0], [3, 4], [-1, 4], [-4, 0], [-4, -3]]))
    True
    """
    p = check_degree(degree)
    q = as_array(points, "points", ndim=2)
    if closed:
        q = drop_closing_repeat(q, 0)
    if q.shape[0] < p + 1:
        raise InputError(f"points: degree {p} needs at least {p + 1} points, got {q.shape[0]}")
    u = data_parameters(q[None], method, closed, params, "params", "points")
    knots = interpolation_knots(u, p, closed)
    control = _Collocation(u, knots, p, closed).solve(q)
    return BSplineCurve(p, knots, control, u, bool(closed))


# ----------------------------------------------------------------------------- surfaces
@dataclass(frozen=True)
class BSplineSurface:
    """Tensor-product B-spline surface from :func:`interpolate_surface`.

    Attributes
    ----------
    degree_u, degree_v : int
        Degrees in u (axis 0 of the data grid) and v (axis 1).
    knots_u, knots_v : numpy.ndarray of float64
        Full knot vectors (clamped when open, unwrapped periodic when closed).
    control : (n_u, n_v, 3) numpy.ndarray of float64
        Distinct control points (closed directions repeat the first ``p`` implicitly).
    params_u, params_v : numpy.ndarray of float64
        Parameters of the data rows (u) and columns (v).
    closed_u, closed_v : bool
        Periodic directions (period 1).
    """

    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    control: np.ndarray
    params_u: np.ndarray
    params_v: np.ndarray
    closed_u: bool = False
    closed_v: bool = False

    @property
    def full_control(self) -> np.ndarray:
        """Unwrapped control net ``(len(knots_u) - p_u - 1, len(knots_v) - p_v - 1, 3)``."""
        c = self.control
        if self.closed_u:
            c = _unwrap_control(c, self.degree_u, 0)
        if self.closed_v:
            c = _unwrap_control(c, self.degree_v, 1)
        return c

    def _domain(self, u, v) -> np.ndarray:
        x = _domain_u(u, "u", self.closed_u, self.knots_u, self.degree_u)
        y = _domain_u(v, "v", self.closed_v, self.knots_v, self.degree_v)
        if x.shape != y.shape:
            raise InputError(f"u, v: expected equal shapes, got {x.shape} and {y.shape}")
        return np.stack([x, y], axis=1)

    def evaluate(self, u, v) -> np.ndarray:
        """Surface points ``S(u, v)``.

        Parameters
        ----------
        u, v : (N,) array_like of float
            Parameters in ``[0, 1]`` (periodic in a closed direction).

        Returns
        -------
        numpy.ndarray
            ``(N, 3)`` float64 points.
        """
        return self.derivative(u, v, 0, 0)

    def derivative(self, u, v, nu: int = 1, nv: int = 0) -> np.ndarray:
        """Partial derivative ``d^(nu+nv) S / du^nu dv^nv`` at ``(u, v)`` -> ``(N, 3)``.

        ``nu <= degree_u``, ``nv <= degree_v``; evaluated by scipy's ``NdBSpline``
        (tensor-product de Boor, vectorised over all points).
        """
        if not (0 <= nu <= self.degree_u and 0 <= nv <= self.degree_v):
            raise InputError(f"nu, nv: expected 0..{self.degree_u} and 0..{self.degree_v}")
        xi = self._domain(u, v)
        spline = NdBSpline(
            (self.knots_u, self.knots_v), self.full_control, (self.degree_u, self.degree_v)
        )
        return spline(xi, nu=(int(nu), int(nv)))

    def normals(self, u, v) -> np.ndarray:
        """Unit normals along ``Su x Sv`` at ``(u, v)`` -> ``(N, 3)`` (zero where degenerate)."""
        n = np.cross(self.derivative(u, v, 1, 0), self.derivative(u, v, 0, 1))
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, length, out=np.zeros_like(n), where=length > 0)

    def evaluate_grid(self, u, v) -> np.ndarray:
        """Points on the grid ``u (M,) x v (K,)`` -> ``(M, K, 3)``."""
        uu = np.atleast_1d(as_array(u, "u", ndim=(0, 1)))
        vv = np.atleast_1d(as_array(v, "v", ndim=(0, 1)))
        gu, gv = np.meshgrid(uu, vv, indexing="ij")
        return self.evaluate(gu.ravel(), gv.ravel()).reshape(uu.size, vv.size, 3)

    def patch_parameters(self, u, v):
        """Map global ``(u, v)`` to ``(pi, pj, s, t)`` of :meth:`to_bezier`'s patches.

        Returns
        -------
        tuple of numpy.ndarray
            ``pi, pj`` (N,) int64 patch indices and ``s, t`` (N,) local parameters in
            ``[0, 1]`` such that ``to_bezier().evaluate(pi, pj, s, t) == evaluate(u, v)``.
        """
        xi = self._domain(u, v)
        pi, s = span_parameters(self.knots_u, self.degree_u, xi[:, 0])
        pj, t = span_parameters(self.knots_v, self.degree_v, xi[:, 1])
        return pi, pj, s, t

    def bezier_control(self) -> np.ndarray:
        """Exact bicubic Bezier control points ``(R, C, 4, 4, 3)`` by knot insertion.

        Patch ``(i, j)`` covers the i-th non-empty u span and the j-th v span of the
        knot domains; ``control[i, j, a, b]`` has ``a`` along u and ``b`` along v.
        Neighbouring patches share their boundary control points bit for bit (and
        so do the first and last patches of a closed direction).

        Raises
        ------
        ValueError
            When a degree is not 2 or 3 (no exact bicubic representation).
        """
        c = cubic_pieces(self.knots_u, self.degree_u, self.full_control)  # (Su, 4, nv, 3)
        c = cubic_pieces(self.knots_v, self.degree_v, np.moveaxis(c, 2, 0))  # (Sv, 4, Su, 4, 3)
        c = np.ascontiguousarray(c.transpose(2, 0, 3, 1, 4))
        # shared seams must be identical, not equal up to rounding
        c[1:, :, 0] = c[:-1, :, 3]
        c[:, 1:, :, 0] = c[:, :-1, :, 3]
        if self.closed_u:
            c[-1, :, 3] = c[0, :, 0]
        if self.closed_v:
            c[:, -1, :, 3] = c[:, 0, :, 0]
        return c

    def to_bezier(self) -> BezierPatches:
        """Exact conversion to the shared :class:`surfaces.bezier.BezierPatches` model."""
        from surfaces.bezier import BezierPatches

        return BezierPatches(
            control=self.bezier_control(), closed_u=self.closed_u, closed_v=self.closed_v
        )


def interpolate_surface(
    points,
    degree: int | tuple[int, int] = 3,
    method: str = "chord",
    closed_u: bool = False,
    closed_v: bool = False,
    params_u=None,
    params_v=None,
) -> BSplineSurface:
    """Global B-spline surface interpolation through a grid (seed 003; The NURBS Book A9.4).

    Parameters
    ----------
    points : (R, C, 3) array_like of float
        Grid ``Q[k, l]``; ``k`` runs along u, ``l`` along v. Any length unit.
    degree : int or (int, int), optional
        Degrees ``(p_u, p_v)``, each 2 to 5 (default 3, bicubic).
    method : {"chord", "uniform", "centripetal"}, optional
        Parameterisation; per-line parameters are averaged over all lines of the
        other direction, lines of zero length (poles) excluded.
    closed_u, closed_v : bool, optional
        Periodic direction(s). Give the grid without repeating the first row
        (column) at the end; a repeated one is dropped.
    params_u, params_v : array_like of float, optional
        Explicit data parameters (``(R,)`` and ``(C,)``) instead of ``method``.

    Returns
    -------
    BSplineSurface
        Surface with ``S(params_u[k], params_v[l]) == Q[k, l]``.

    Raises
    ------
    ValueError
        Bad shape, too few rows/columns for the degree, coincident rows or columns.

    Examples
    --------
    A bicubic surface reproduces a bicubic function exactly (here ``z = x y^2``).

    >>> x, y = np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 6), indexing="ij")
    >>> surf = interpolate_surface(np.stack([x, y, x * y**2], axis=-1), method="uniform")
    >>> surf.evaluate([0.3], [0.7]).round(12).tolist()
    [[0.3, 0.7, 0.147]]
    """
    pu, pv = (degree, degree) if not isinstance(degree, (tuple, list)) else tuple(degree)
    pu, pv = check_degree(pu, "degree_u"), check_degree(pv, "degree_v")
    q = as_array(points, "points", shape=(None, None, 3))
    if closed_u:
        q = drop_closing_repeat(q, 0)
    if closed_v:
        q = drop_closing_repeat(q, 1)
    r, c = q.shape[:2]
    if r < pu + 1 or c < pv + 1:
        raise InputError(
            f"points: degrees ({pu}, {pv}) need at least {pu + 1} x {pv + 1} grid points, "
            f"got {r} x {c}"
        )
    u = data_parameters(q.transpose(1, 0, 2), method, closed_u, params_u, "params_u", "rows")
    v = data_parameters(q, method, closed_v, params_v, "params_v", "columns")
    ku = interpolation_knots(u, pu, closed_u)
    kv = interpolation_knots(v, pv, closed_v)
    # stage 1: along u for every column at once; stage 2: along v for every row of controls
    stage1 = _Collocation(u, ku, pu, closed_u).solve(q)
    control = _Collocation(v, kv, pv, closed_v).solve(stage1.transpose(1, 0, 2))
    return BSplineSurface(
        pu, pv, ku, kv, np.ascontiguousarray(control.transpose(1, 0, 2)), u, v,
        bool(closed_u), bool(closed_v),
    )


def interpolate_surface_patches(points, **kwargs) -> BezierPatches:
    """Interpolate a grid and convert it exactly to bicubic Bezier patches.

    Parameters
    ----------
    points : (R, C, 3) array_like of float
        Grid, axis 0 along u, axis 1 along v (see :func:`interpolate_surface`).
    **kwargs
        Passed to :func:`interpolate_surface` (``degree`` must be 2 or 3).

    Returns
    -------
    surfaces.bezier.BezierPatches
        One patch per knot span pair; closure flags as requested.
    """
    return interpolate_surface(points, **kwargs).to_bezier()
