"""Kinematic surfaces: a generatrix curve moved along a directrix curve (seed 004).

A kinematic surface is traced by a generatrix ``g(u)``, given in a local frame,
carried by a motion along a directrix ``D(v)`` (seed 004, eqs. 1-2)::

    X(u, v) = D(v) + s(v) * [ (l1 cos th - l2 sin th) N(v) + (l1 sin th + l2 cos th) B(v)
                              + l3 T(v) ]

with ``(l1, l2, l3)`` the generatrix point in local coordinates, ``th = twist(v)``
(radians), ``s = scale(v)`` and ``(T, N, B)`` a frame along the directrix:

* ``"fixed"``: the frame at ``v = 0`` carried without rotation (translational surface);
* ``"frenet"``: tangent, principal normal, binormal (undefined where the curvature
  vanishes: a ``ValueError`` says where; it also flips at inflections);
* ``"rmf"``: rotation-minimising frame by the double reflection method (Wang,
  Juettler, Zheng & Liu, "Computation of rotation minimizing frames", ACM TOG 27(1),
  2008, eqs. 4-5), computed on a fine sampling of the directrix; on a closed
  directrix the frame's holonomy angle is spread linearly over v so that it closes.

A 2D generatrix ``(a, b)`` lies in the directrix's normal plane, ``(l1, l2, l3) =
(a, b, 0)`` (``plane="normal"``, sweeps and pipes), or in the plane through the
tangent, ``(a, 0, b)`` (``plane="axial"``: profiles ``(r, z)`` of surfaces of
revolution and screw surfaces, whose directrix is the z axis). A 3D generatrix is
used as it is.

Both curves are B-splines (:class:`surfaces.bspline.BSplineCurve`) or analytic
curves (:class:`ParametricCurve`: lines, circles, helices, any callable of
``t in [0, 1]``). Moving the control points of a B-spline generatrix or directrix
deforms the surface (:meth:`KinematicSurface.deform`; seed 004's change of base,
including a convex profile turned concave).

The surface enters the shared model by bicubic B-spline interpolation of a
sampled grid (seed 003) and its exact conversion to Bezier patches
(:meth:`KinematicSurface.to_bezier`), so tessellation, area, volume and export
are the shared ones. :func:`measure` adds the flux of planar/cone caps closing
the ends of a tube, so swept solids get a volume.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

from surfaces.bspline import BSplineCurve, interpolate_curve, interpolate_surface
from surfaces.validate import as_array, positive

if TYPE_CHECKING:
    from surfaces.bezier import BezierPatches
    from surfaces.bspline import BSplineSurface

FRAMES = ("fixed", "frenet", "rmf")
PLANES = ("normal", "axial")
#: intervals of the directrix sampling on which the rotation-minimising frame is propagated
RMF_SAMPLES = 4096


class Curve(Protocol):
    """What the kinematic code needs from a curve: points and derivatives on ``[0, 1]``."""

    closed: bool

    def evaluate(self, t) -> np.ndarray: ...

    def derivative(self, t, order: int = 1) -> np.ndarray: ...


# ----------------------------------------------------------------------------- analytic curves
@dataclass(frozen=True)
class ParametricCurve:
    """A curve given by functions of ``t in [0, 1]``.

    Attributes
    ----------
    func : callable
        ``func(t (M,)) -> (M, d)`` points.
    derivatives : tuple of callables
        Exact first, second, ... derivatives with respect to ``t``; missing orders
        are central finite differences of ``func`` (step 1e-4 / 1e-3).
    closed : bool
        ``func(0) == func(1)`` and the curve is periodic.
    name : str
        Label used in summaries.
    """

    func: Callable[[np.ndarray], np.ndarray]
    derivatives: tuple = ()
    closed: bool = False
    name: str = "curve"

    def evaluate(self, t) -> np.ndarray:
        """Points ``(M, d)`` at ``t`` ``(M,)``."""
        return np.atleast_2d(np.asarray(self.func(_params(t)), dtype=np.float64))

    def derivative(self, t, order: int = 1) -> np.ndarray:
        """Derivative of the given order with respect to ``t`` -> ``(M, d)``."""
        x = _params(t)
        if order == 0:
            return self.evaluate(x)
        if order <= len(self.derivatives):
            return np.asarray(self.derivatives[order - 1](x), dtype=np.float64)
        h = 1e-4 if order == 1 else 1e-3
        lo, hi = self.evaluate(x - h), self.evaluate(x + h)
        if order == 1:
            return (hi - lo) / (2 * h)
        if order == 2:
            return (hi - 2 * self.evaluate(x) + lo) / (h * h)
        raise ValueError(f"order: finite differences give orders 1 and 2, got {order}")


def _params(t) -> np.ndarray:
    return np.atleast_1d(as_array(t, "t", ndim=(0, 1)))


def line(start, end) -> ParametricCurve:
    """Straight segment ``start + t (end - start)``, ``t in [0, 1]``.

    Parameters
    ----------
    start, end : (d,) array_like of float
        End points (2D or 3D, any unit).
    """
    a = as_array(start, "start", ndim=1)
    b = as_array(end, "end", shape=a.shape)
    d = b - a
    return ParametricCurve(
        lambda t: a + t[:, None] * d,
        (lambda t: np.tile(d, (t.size, 1)), lambda t: np.zeros((t.size, d.size))),
        False,
        "line",
    )


def circle(radius: float, center=(0.0, 0.0), normal=(0.0, 0.0, 1.0)) -> ParametricCurve:
    """Full circle, counter-clockwise about ``normal``, starting on the first in-plane axis.

    Parameters
    ----------
    radius : float
        Radius (> 0).
    center : (2,) or (3,) array_like of float
        Centre; a 2D centre gives a plane curve ``(cx + r cos 2 pi t, cy + r sin 2 pi t)``.
    normal : (3,) array_like of float
        Plane normal of a 3D circle (ignored in 2D).
    """
    r = positive(radius, "radius")
    c = as_array(center, "center", ndim=1)
    if c.size == 2:
        e1, e2 = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    elif c.size == 3:
        e1, e2 = _plane_axes(as_array(normal, "normal", shape=(3,)))
    else:
        raise ValueError(f"center: expected 2 or 3 coordinates, got {c.size}")
    w = 2 * np.pi

    def point(t, k=0):
        a = w * t[:, None]
        cos, sin = np.cos(a), np.sin(a)
        terms = [(cos, sin), (-sin, cos), (-cos, -sin)][k]
        return (c if k == 0 else 0.0) + r * w**k * (terms[0] * e1 + terms[1] * e2)

    return ParametricCurve(point, (lambda t: point(t, 1), lambda t: point(t, 2)), True, "circle")


def helix(radius: float, pitch: float, turns: float, center=(0.0, 0.0, 0.0)) -> ParametricCurve:
    """Right-handed helix about the z axis: ``(r cos 2 pi n t, r sin 2 pi n t, P n t)``.

    Parameters
    ----------
    radius : float
        Helix radius (> 0).
    pitch : float
        Rise per turn ``P`` (any sign; 0 gives a circle traversed ``turns`` times).
    turns : float
        Number of turns ``n`` (> 0).
    center : (3,) array_like of float
        Point on the axis at ``t = 0``.
    """
    r, n = positive(radius, "radius"), positive(turns, "turns")
    p = float(pitch)
    c = as_array(center, "center", shape=(3,))
    w = 2 * np.pi * n

    def point(t, k=0):
        a = w * t
        cos, sin = np.cos(a), np.sin(a)
        x, y = [(cos, sin), (-sin, cos), (-cos, -sin)][k]
        z = [p * n * t, np.full_like(t, p * n), np.zeros_like(t)][k]
        out = np.stack([r * w**k * x, r * w**k * y, z], axis=1)
        return out + c if k == 0 else out

    return ParametricCurve(point, (lambda t: point(t, 1), lambda t: point(t, 2)), False, "helix")


def thread_profile(minor_radius: float, depth: float, pitch: float) -> ParametricCurve:
    """One pitch of a round (sinusoidal) screw-thread profile in the ``(r, z)`` plane.

    ``r(t) = minor_radius + depth (1 - cos 2 pi t) / 2``, ``z(t) = pitch * t``: root at
    ``t = 0, 1``, crest (``minor_radius + depth``) at ``t = 1/2``. Swept helically with
    the same pitch (:func:`screw_thread`) the profile joins itself from turn to turn.
    """
    r0, h, p = positive(minor_radius, "minor_radius"), positive(depth, "depth"), float(pitch)
    w = 2 * np.pi

    def point(t, k=0):
        if k == 0:
            return np.stack([r0 + h * (1 - np.cos(w * t)) / 2, p * t], axis=1)
        if k == 1:
            return np.stack([h * w * np.sin(w * t) / 2, np.full_like(t, p)], axis=1)
        return np.stack([h * w * w * np.cos(w * t) / 2, np.zeros_like(t)], axis=1)

    return ParametricCurve(point, (lambda t: point(t, 1), lambda t: point(t, 2)), False, "thread")


def as_curve(obj) -> Curve:
    """Accept a B-spline curve, a :class:`ParametricCurve` or a callable ``f(t) -> (M, d)``."""
    if isinstance(obj, (BSplineCurve, ParametricCurve)):
        return obj
    if callable(obj):
        return ParametricCurve(obj, (), bool(getattr(obj, "closed", False)), "callable")
    raise ValueError(f"curve: expected a BSplineCurve, ParametricCurve or callable, got {obj!r}")


def _plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = normal / _norm_nonzero(normal, "normal")
    e1 = _perpendicular(n[None])[0]
    return e1, np.cross(n, e1)


def _norm_nonzero(vec: np.ndarray, name: str) -> float:
    length = float(np.linalg.norm(vec))
    if length == 0.0:
        raise ValueError(f"{name}: must not be the zero vector")
    return length


def _perpendicular(t: np.ndarray) -> np.ndarray:
    """Unit vectors perpendicular to the unit vectors ``t`` (M, 3), from the least aligned axis."""
    axis = np.eye(3)[np.argmin(np.abs(t), axis=1)]
    p = axis - np.sum(axis * t, axis=1, keepdims=True) * t
    return p / np.linalg.norm(p, axis=1, keepdims=True)


# ----------------------------------------------------------------------------- laws
def _law(value, name: str, default: float) -> Callable[[np.ndarray], np.ndarray]:
    """A law along v: None, a number, a (start, end) pair (linear) or a callable."""
    if value is None:
        return lambda v: np.full_like(v, default)
    if callable(value):
        return lambda v: np.broadcast_to(np.asarray(value(v), dtype=np.float64), v.shape).copy()
    arr = as_array(value, name, ndim=(0, 1))
    if arr.ndim == 0:
        a = float(arr)
        if name == "twist":  # a number is the total twist, reached linearly at v = 1
            return lambda v: a * v
        return lambda v: np.full_like(v, a)
    if arr.shape != (2,):
        raise ValueError(f"{name}: expected a number, (start, end) or a callable, got {value!r}")
    a, b = float(arr[0]), float(arr[1])
    return lambda v: a + (b - a) * v


# ----------------------------------------------------------------------------- frames
def _unit(vec: np.ndarray) -> np.ndarray:
    return vec / np.linalg.norm(vec, axis=-1, keepdims=True)


def _tangents(directrix: Curve, v: np.ndarray) -> np.ndarray:
    d1 = _as3(directrix.derivative(v, 1))
    speed = np.linalg.norm(d1, axis=1)
    bad = np.flatnonzero(speed <= 1e-12 * max(1.0, float(speed.max(initial=0.0))))
    if bad.size:
        raise ValueError(f"directrix: zero speed (no tangent) at v = {v[bad[0]]:.6g}")
    return d1 / speed[:, None]


def _frenet_normals(directrix: Curve, v: np.ndarray, t: np.ndarray) -> np.ndarray:
    d1 = _as3(directrix.derivative(v, 1))
    d2 = _as3(directrix.derivative(v, 2))
    n = d2 - np.sum(d2 * t, axis=1, keepdims=True) * t
    size = np.linalg.norm(n, axis=1)
    bad = np.flatnonzero(size <= 1e-9 * np.linalg.norm(d1, axis=1) ** 2)
    if bad.size:
        raise ValueError(
            f"frame: the Frenet frame is undefined where the directrix has zero curvature "
            f"(v = {v[bad[0]]:.6g}); use frame='rmf' or 'fixed'"
        )
    return n / size[:, None]


def _initial_normal(directrix: Curve, t0: np.ndarray, up) -> np.ndarray:
    if up is not None:
        u = as_array(up, "up", shape=(3,))
        n = u - np.dot(u, t0) * t0
        if np.linalg.norm(n) <= 1e-9 * max(np.linalg.norm(u), 1e-300):
            raise ValueError("up: must not be parallel to the directrix tangent at v = 0")
        return n / np.linalg.norm(n)
    try:
        return _frenet_normals(directrix, np.zeros(1), t0[None])[0]
    except ValueError:  # straight start: any perpendicular will do
        return _perpendicular(t0[None])[0]


def _prefix_products(mats: np.ndarray) -> np.ndarray:
    """Cumulative products ``M_i M_{i-1} ... M_0`` of (K, 3, 3) matrices by a doubling scan."""
    out = mats.copy()
    shift = 1
    while shift < out.shape[0]:
        out[shift:] = out[shift:] @ out[:-shift]
        shift *= 2
    return out


def _reflection(vec: np.ndarray) -> np.ndarray:
    """Householder matrices ``I - 2 w w^T / (w . w)`` (identity where ``w = 0``)."""
    c = np.sum(vec * vec, axis=1)
    safe = np.where(c > 0, c, 1.0)
    h = np.eye(3) - 2.0 * vec[:, :, None] * vec[:, None, :] / safe[:, None, None]
    h[c <= 0] = np.eye(3)
    return h


def rotation_minimizing_frames(
    directrix, v, up=None, samples: int = RMF_SAMPLES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotation-minimising frames by double reflection (Wang et al. 2008, eqs. 4-5).

    The frame is propagated on ``samples`` uniform intervals of ``[0, 1]`` plus the
    requested parameters; each step is the product of two reflections
    ``H2 H1`` (reflect in the bisector plane of ``x_i, x_{i+1}``, then in the plane
    that maps the reflected tangent onto ``t_{i+1}``). All steps are built at once
    and chained by a prefix product (no Python loop per sample).

    Parameters
    ----------
    directrix : curve
        The directrix (3D; a 2D one lies in the plane z = 0).
    v : (M,) array_like of float
        Parameters in ``[0, 1]``.
    up : (3,) array_like of float, optional
        Direction of the first normal at ``v = 0`` (projected onto the normal plane).
        Default: the Frenet normal there, or a perpendicular when the start is straight.
    samples : int, optional
        Propagation intervals (global error of the method is O(h^4)).

    Returns
    -------
    (T, N, B) : tuple of numpy.ndarray
        Unit tangent, normal and binormal, each ``(M, 3)``; ``B = T x N``.
    """
    curve = as_curve(directrix)
    vq = np.clip(_params(v), 0.0, 1.0)
    grid, inverse = np.unique(np.concatenate([np.linspace(0.0, 1.0, int(samples) + 1), vq]),
                              return_inverse=True)
    x = _as3(curve.evaluate(grid))
    t = _tangents(curve, grid)
    v1 = x[1:] - x[:-1]
    h1 = _reflection(v1)
    v2 = t[1:] - np.einsum("kij,kj->ki", h1, t[:-1])
    steps = _prefix_products(_reflection(v2) @ h1)
    r0 = _initial_normal(curve, t[0], up)
    r = np.concatenate([r0[None], np.einsum("kij,j->ki", steps, r0)])
    # re-orthonormalise against the exact tangents (removes the O(h^4) drift off the normal plane)
    r = _unit(r - np.sum(r * t, axis=1, keepdims=True) * t)
    idx = inverse[-vq.size :]
    tq, rq = t[idx], r[idx]
    return tq, rq, np.cross(tq, rq)


def frames(
    directrix, v, kind: str = "rmf", up=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Moving frame along a directrix: ``fixed``, ``frenet`` or ``rmf``.

    Parameters
    ----------
    directrix : curve or None
        The directrix; ``None`` is the z axis held at the origin (``T = z``,
        ``N = x``, ``B = y``), the frame of surfaces of revolution.
    v : (M,) array_like of float
        Parameters in ``[0, 1]``.
    kind : {"fixed", "frenet", "rmf"}
        Frame type (see the module docstring).
    up : (3,) array_like of float, optional
        First normal at ``v = 0`` for ``fixed`` and ``rmf``.

    Returns
    -------
    (T, N, B) : tuple of numpy.ndarray
        Each ``(M, 3)`` float64, orthonormal, ``B = T x N``.
    """
    if kind not in FRAMES:
        raise ValueError(f"frame: expected one of {', '.join(FRAMES)}, got {kind!r}")
    vv = _params(v)
    if directrix is None:
        ones = np.ones((vv.size, 1))
        return ones * [0.0, 0.0, 1.0], ones * [1.0, 0.0, 0.0], ones * [0.0, 1.0, 0.0]
    curve = as_curve(directrix)
    if kind == "rmf":
        return rotation_minimizing_frames(curve, vv, up)
    if kind == "fixed":
        t0 = _tangents(curve, np.zeros(1))[0]
        n0 = _initial_normal(curve, t0, up)
        ones = np.ones((vv.size, 1))
        return ones * t0, ones * n0, ones * np.cross(t0, n0)
    t = _tangents(curve, vv)
    n = _frenet_normals(curve, vv, t)
    return t, n, np.cross(t, n)


def _as3(points: np.ndarray) -> np.ndarray:
    points = np.atleast_2d(points)
    if points.shape[1] == 3:
        return points
    if points.shape[1] == 2:
        return np.column_stack([points, np.zeros(points.shape[0])])
    raise ValueError(f"directrix: expected 2D or 3D points, got dimension {points.shape[1]}")


# ----------------------------------------------------------------------------- the surface
@dataclass(frozen=True)
class KinematicSurface:
    """A generatrix carried along a directrix (seed 004); see the module docstring.

    Attributes
    ----------
    generatrix : curve
        ``g(u)``, 2D or 3D, in the local frame; ``u in [0, 1]``.
    directrix : curve or None
        ``D(v)``, 3D (2D lies in z = 0); ``None``: the z axis at the origin.
    frame : {"fixed", "frenet", "rmf"}
        Moving frame along the directrix.
    plane : {"normal", "axial"}
        Where a 2D generatrix lies: the normal plane ``(N, B)`` or the plane ``(N, T)``.
    scale, twist : law
        ``s(v)`` (default 1) and ``th(v)`` in radians (default 0): None, a number (a
        constant scale; a total twist reached linearly), a (start, end) pair or a callable.
    up : (3,) array_like of float or None
        First normal at ``v = 0`` (fixed and rmf frames).
    closed_v : bool or None
        The motion returns to its start (None: decided from the directrix, twist and scale).
    """

    generatrix: object
    directrix: object | None = None
    frame: str = "rmf"
    plane: str = "normal"
    scale: object = None
    twist: object = None
    up: object = None
    closed_v: bool | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "generatrix", as_curve(self.generatrix))
        if self.directrix is not None:
            object.__setattr__(self, "directrix", as_curve(self.directrix))
        if self.frame not in FRAMES:
            raise ValueError(f"frame: expected one of {', '.join(FRAMES)}, got {self.frame!r}")
        if self.plane not in PLANES:
            raise ValueError(f"plane: expected one of {', '.join(PLANES)}, got {self.plane!r}")
        if self.closed_v is None:
            object.__setattr__(self, "closed_v", self._motion_closes())

    # -------------------------------------------------------------- pieces of the motion
    @property
    def closed_u(self) -> bool:
        """The generatrix is closed (a tube around the directrix)."""
        return bool(self.generatrix.closed)

    def _motion_closes(self) -> bool:
        ends = np.array([0.0, 1.0])
        th = _law(self.twist, "twist", 0.0)(ends)
        s = _law(self.scale, "scale", 1.0)(ends)
        turns = (th[1] - th[0]) / (2 * np.pi)
        periodic_law = abs(turns - round(turns)) < 1e-12 and abs(s[1] - s[0]) < 1e-12
        if self.directrix is None:  # pure rotation about the axis
            return bool(periodic_law and round(turns) != 0)
        return bool(self.directrix.closed and periodic_law)

    def _local(self, u: np.ndarray) -> np.ndarray:
        g = np.atleast_2d(self.generatrix.evaluate(u))
        if g.shape[1] == 3:
            return g
        if g.shape[1] != 2:
            raise ValueError(f"generatrix: expected 2D or 3D points, got dimension {g.shape[1]}")
        zero = np.zeros(g.shape[0])
        if self.plane == "normal":
            return np.column_stack([g[:, 0], g[:, 1], zero])
        return np.column_stack([g[:, 0], zero, g[:, 1]])

    def motion(self, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin ``(M, 3)``, rotation ``(M, 3, 3)`` (columns N', B', T) and scale ``(M,)`` at v.

        ``N'``, ``B'`` are the frame's normal and binormal turned by the twist and, on a
        closed directrix with an RMF, by the holonomy correction.
        """
        vv = _params(v)
        t, n, b = frames(self.directrix, vv, self.frame, self.up)
        th = _law(self.twist, "twist", 0.0)(vv) + self._holonomy() * vv
        cos, sin = np.cos(th)[:, None], np.sin(th)[:, None]
        rot = np.stack([cos * n + sin * b, -sin * n + cos * b, t], axis=2)
        if self.directrix is None:
            origin = np.zeros((vv.size, 3))
        else:
            origin = _as3(self.directrix.evaluate(vv))
        return origin, rot, _law(self.scale, "scale", 1.0)(vv)

    def _holonomy(self) -> float:
        """Angle that closes an RMF on a closed directrix (spread linearly over v)."""
        if self.directrix is None or self.frame != "rmf" or not self.directrix.closed:
            return 0.0
        _, n, b = frames(self.directrix, np.array([0.0, 1.0]), "rmf", self.up)
        return float(np.arctan2(np.dot(b[1], n[0]), np.dot(n[1], n[0])))

    # -------------------------------------------------------------- evaluation
    def evaluate(self, u, v) -> np.ndarray:
        """Exact surface points ``X(u, v)`` for ``u, v`` ``(M,)`` in ``[0, 1]`` -> ``(M, 3)``."""
        uu, vv = _params(u), _params(v)
        if uu.shape != vv.shape:
            raise ValueError(f"u, v: expected equal shapes, got {uu.shape} and {vv.shape}")
        origin, rot, s = self.motion(vv)
        return origin + s[:, None] * np.einsum("mij,mj->mi", rot, self._local(uu))

    def evaluate_grid(self, u, v) -> np.ndarray:
        """Exact points on the grid ``u (K,) x v (M,)`` -> ``(K, M, 3)``."""
        uu, vv = _params(u), _params(v)
        origin, rot, s = self.motion(vv)
        local = self._local(uu)
        return origin[None] + s[None, :, None] * np.einsum("mij,kj->kmi", rot, local)

    def sample_parameters(self, n_u: int, n_v: int) -> tuple[np.ndarray, np.ndarray]:
        """Uniform sample parameters: ``[0, 1)`` when closed, ``[0, 1]`` when open."""
        nu, nv = int(n_u), int(n_v)
        if nu < 4 or nv < 4:
            raise ValueError(f"samples: need at least 4 x 4 samples, got {nu} x {nv}")
        u = np.arange(nu) / nu if self.closed_u else np.linspace(0.0, 1.0, nu)
        v = np.arange(nv) / nv if self.closed_v else np.linspace(0.0, 1.0, nv)
        return u, v

    def to_bspline(self, n_u: int = 32, n_v: int = 32) -> BSplineSurface:
        """Bicubic B-spline surface interpolating an ``n_u x n_v`` sample grid (seed 003).

        The sample parameters are used as the interpolation parameters, so the
        B-spline surface approximates ``X(u, v)`` in the same parametrisation
        (error O(h^4) for smooth motions).
        """
        u, v = self.sample_parameters(n_u, n_v)
        grid = self.evaluate_grid(u, v)
        return interpolate_surface(
            grid, degree=3, closed_u=self.closed_u, closed_v=self.closed_v, params_u=u, params_v=v
        )

    def to_bezier(self, n_u: int = 32, n_v: int = 32) -> BezierPatches:
        """The shared model: exact Bezier form of :meth:`to_bspline` (``(n_u', n_v')`` patches)."""
        return self.to_bspline(n_u, n_v).to_bezier()

    # -------------------------------------------------------------- deformation
    def deform(self, generatrix_control=None, directrix_control=None) -> KinematicSurface:
        """The same motion with moved control points of the generatrix or directrix (seed 004).

        Parameters
        ----------
        generatrix_control, directrix_control : (N, d) array_like of float, optional
            New control points for a B-spline generatrix / directrix (same shape as
            its ``control``); knots and degree are kept, so the curve changes locally.

        Returns
        -------
        KinematicSurface
            The deformed surface.
        """
        changes = {}
        for name, new in (("generatrix", generatrix_control), ("directrix", directrix_control)):
            if new is None:
                continue
            curve = getattr(self, name)
            if not isinstance(curve, BSplineCurve):
                raise ValueError(f"{name}_control: the {name} is not a B-spline curve")
            changes[name] = curve.with_control(new)
        return replace(self, closed_v=None, **changes) if changes else self


# ----------------------------------------------------------------------------- ready shapes
def sweep(
    generatrix, directrix, frame: str = "rmf", scale=None, twist=None, up=None
) -> KinematicSurface:
    """Generatrix swept along a directrix (seed 004): the general kinematic surface.

    Parameters
    ----------
    generatrix : curve
        Cross-section in the normal plane (2D ``(a, b)`` -> ``a N + b B``) or 3D local.
    directrix : curve
        Path (3D, or 2D in z = 0).
    frame : {"fixed", "frenet", "rmf"}
        Moving frame (default rotation-minimising).
    scale, twist : law, optional
        Scale ``s(v)`` and twist ``th(v)`` [rad] laws (see :class:`KinematicSurface`).
    up : (3,) array_like of float, optional
        First normal at the start.

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    return KinematicSurface(generatrix, directrix, frame, "normal", scale, twist, up)


def pipe(directrix, radius: float, frame: str = "rmf", up=None) -> KinematicSurface:
    """Tube of circular section ``radius`` along a directrix (area ``2 pi r L`` when it does
    not overlap itself).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    return sweep(circle(radius), directrix, frame, up=up)


def revolve(profile, angle: float = 2 * np.pi) -> KinematicSurface:
    """Surface of revolution of a profile ``(r(u), z(u))`` about the z axis.

    ``X(u, v) = (r cos(angle v), r sin(angle v), z)``; obeys Pappus' theorems
    (area ``2 pi r_c L``, volume ``2 pi r_c A`` for a full turn).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    return KinematicSurface(profile, None, "fixed", "axial", twist=float(angle))


def helical_sweep(profile, pitch: float, turns: float) -> KinematicSurface:
    """Screw motion of a profile ``(r(u), z(u))`` about the z axis.

    ``X(u, v) = (r cos(2 pi n v), r sin(2 pi n v), z + P n v)`` with ``n = turns``,
    ``P = pitch`` (> 0: right-handed; mirror the result for a left-handed screw):
    helicoids, screw threads.

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    n, p = positive(turns, "turns"), positive(pitch, "pitch")
    # the axis is the directrix; the fixed frame (T, N, B) = (z, x, y) and the twist turn it
    axis = line([0.0, 0.0, 0.0], [0.0, 0.0, p * n])
    twist = 2 * np.pi * n
    return KinematicSurface(profile, axis, "fixed", "axial", twist=twist, up=[1.0, 0.0, 0.0])


def helicoid(inner: float, outer: float, pitch: float, turns: float) -> KinematicSurface:
    """Helicoid ``(r cos th, r sin th, c th)``, ``c = pitch / 2 pi``, ``inner <= r <= outer``.

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    if not outer > inner >= 0:
        raise ValueError(f"inner, outer: need 0 <= inner < outer, got {inner}, {outer}")
    return helical_sweep(line([inner, 0.0], [outer, 0.0]), pitch, turns)


def coil_spring(radius: float, pitch: float, turns: float, wire_radius: float) -> KinematicSurface:
    """Coil spring: a circle of ``wire_radius`` swept along a helix with an RMF.

    Raises
    ------
    ValueError
        When the wire would overlap itself (``2 * wire_radius >= |pitch|``, or
        ``wire_radius >= radius``).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    a = positive(wire_radius, "wire_radius")
    r = positive(radius, "radius")
    if 2 * a >= abs(float(pitch)):
        raise ValueError(f"wire_radius: neighbouring turns overlap (2 * {a} >= pitch {pitch})")
    # the helix's radius of curvature (r^2 + c^2) / r is at least r: a < r suffices
    if a >= r:
        raise ValueError(f"wire_radius: must be smaller than the coil radius {r}")
    return pipe(helix(r, pitch, turns), a)


def screw_thread(major_radius: float, pitch: float, turns: float, depth: float) -> KinematicSurface:
    """Screw-thread surface: :func:`thread_profile` swept helically with its own pitch.

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    big, h = positive(major_radius, "major_radius"), positive(depth, "depth")
    if h >= big:
        raise ValueError(f"depth: must be smaller than the major radius {big}, got {h}")
    return helical_sweep(thread_profile(big - h, h, pitch), pitch, turns)


# ----------------------------------------------------------------------------- measures
def _gauss3() -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(3)
    return (x + 1) / 2, w / 2


def _vector_area(segments: np.ndarray) -> np.ndarray:
    """``1/2 closed-integral x cross dx`` of closed piecewise-cubic Bezier curves (S, 4, 3)."""
    from surfaces.bezier import bernstein

    t, w = _gauss3()  # the integrand has degree 5: three Gauss points are exact
    x = np.einsum("ta,sak->stk", bernstein(t), segments)
    dx = np.einsum("ta,sak->stk", bernstein(t, 1), segments)
    return 0.5 * np.einsum("t,stk->k", w, np.cross(x, dx))


def cap_flux(patches: BezierPatches) -> float:
    """Flux ``int x . n dA`` through cone caps closing the v-ends of a tube (closed in u).

    The cap of an end curve is the cone from its control-point centroid ``c``;
    its flux is ``c . A`` with ``A`` the curve's vector area, exact for planar ends
    (any cap with that boundary gives the same flux up to the volume between caps).
    Oriented to continue the patches' ``S_u x S_v`` orientation.

    Returns
    -------
    float
        Sum of both caps' fluxes (divide by 3 for their volume contribution).
    """
    if not patches.closed_u or patches.closed_v:
        raise ValueError("patches: caps close a surface that is closed in u and open in v")
    start = patches.control[:, 0, :, 0]  # (R, 4, 3): v = 0 boundary, u increasing
    end = patches.control[:, -1, :, 3]
    c0, c1 = start.reshape(-1, 3).mean(0), end.reshape(-1, 3).mean(0)
    return float(-np.dot(c0, _vector_area(start)) + np.dot(c1, _vector_area(end)))


def measure(patches: BezierPatches) -> dict:
    """Area and enclosed volume of a kinematic surface in the shared model.

    Volume: the divergence theorem over the patches (``surfaces.measure.volume``) plus
    :func:`cap_flux` / 3 for a tube open at its ends; ``None`` when the surface does
    not bound a solid (open in u and not closed off by poles, e.g. a helicoid).

    Returns
    -------
    dict
        ``area`` (model units^2), ``volume`` (units^3, absolute) or None,
        ``volume_method`` (str), ``orientation`` ("outward"/"inward"/None: of ``S_u x S_v``).
    """
    from surfaces.measure import area, volume

    out = {"area": float(area(patches)), "volume": None, "volume_method": None, "orientation": None}
    c = patches.control
    poles = all(np.ptp(e.reshape(-1, 3), axis=0).max() <= 1e-12 * max(1.0, np.abs(c).max())
                for e in (c[0, :, 0], c[-1, :, 3]))
    if patches.closed_u and patches.closed_v:
        signed, method = volume(patches), "divergence theorem (closed surface)"
    elif patches.closed_u:
        signed, method = volume(patches) + cap_flux(patches) / 3.0, "divergence theorem + end caps"
    elif patches.closed_v and poles:
        signed, method = volume(patches), "divergence theorem (closed by poles)"
    else:
        return out
    out.update(volume=abs(float(signed)), volume_method=method,
               orientation="outward" if signed >= 0 else "inward")
    return out


# ----------------------------------------------------------------------------- curve files
def load_curve(source) -> Curve:
    """Read a curve description (JSON file path or dict).

    Formats (lengths in any unit; the kind is ``"type"``, default ``"bspline"``)::

        {"type": "bspline", "points": [[x, y(, z)], ...], "degree": 3,
         "closed": false, "method": "chord"}              # interpolated (seed 003)
        {"type": "bspline", "control": [[...], ...], "knots": [...], "degree": 3,
         "closed": false}                                 # given B-spline (full knot vector)
        {"type": "line", "start": [...], "end": [...]}
        {"type": "circle", "radius": r, "center": [0, 0] or [0, 0, 0], "normal": [0, 0, 1]}
        {"type": "helix", "radius": r, "pitch": p, "turns": n, "center": [0, 0, 0]}

    Raises
    ------
    FileNotFoundError
        Missing file.
    ValueError
        Unreadable JSON, unknown type, missing or bad fields.
    """
    if isinstance(source, dict):
        spec, where = source, "curve"
    else:
        path = Path(source)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: curve file does not exist")
        try:
            spec = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: not valid JSON ({exc})") from None
        where = str(path)
    if not isinstance(spec, dict):
        raise ValueError(f"{where}: expected a JSON object")
    kind = spec.get("type", "bspline")
    try:
        if kind == "bspline":
            degree = int(spec.get("degree", 3))
            closed = bool(spec.get("closed", False))
            if "points" in spec:
                method = spec.get("method", "chord")
                return interpolate_curve(spec["points"], degree, method, closed)
            return _given_bspline(spec, degree, closed)
        if kind == "line":
            return line(spec["start"], spec["end"])
        if kind == "circle":
            center, normal = spec.get("center", (0.0, 0.0)), spec.get("normal", (0, 0, 1))
            return circle(spec["radius"], center, normal)
        if kind == "helix":
            center = spec.get("center", (0, 0, 0))
            return helix(spec["radius"], spec["pitch"], spec["turns"], center)
    except KeyError as exc:
        raise ValueError(f"{where}: a {kind!r} curve needs the field {exc.args[0]!r}") from None
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    raise ValueError(f"{where}: unknown curve type {kind!r}; use bspline, line, circle or helix")


def _given_bspline(spec: dict, degree: int, closed: bool) -> BSplineCurve:
    if "control" not in spec or "knots" not in spec:
        raise ValueError("a bspline curve needs 'points', or 'control' and 'knots'")
    control = as_array(spec["control"], "control", ndim=2)
    knots = as_array(spec["knots"], "knots", ndim=1)
    want = control.shape[0] + (2 * degree + 1 if closed else degree + 1)
    if knots.size != want:
        raise ValueError(
            f"knots: expected {want} knots for {control.shape[0]} control points, got {knots.size}"
        )
    if np.any(np.diff(knots) < 0):
        raise ValueError("knots: must be non-decreasing")
    if not (knots[degree] == 0.0 and knots[-degree - 1] == 1.0):
        raise ValueError("knots: the domain [t_p, t_{n+1}] must be [0, 1]")
    return BSplineCurve(degree, knots, control, np.empty(0), closed)
