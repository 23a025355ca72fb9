"""Kinematic surfaces: a generatrix curve moved along a directrix curve (seed 004).

A kinematic surface is traced by a generatrix ``g(u)``, given in a local frame,
carried by a motion along a directrix ``D(v)`` (seed 004, eqs. 1-2)::

    X(u, v) = D(v) + s(v) * [ (l1 cos th - l2 sin th) N(v) + (l1 sin th + l2 cos th) B(v)
                              + l3 T(v) ]

with ``(l1, l2, l3)`` the generatrix point in local coordinates, ``th = twist(v)``
(radians), ``s = scale(v)`` and ``(T, N, B)`` a frame along the directrix
(:mod:`surfaces.frames`: ``"fixed"``, a translational surface; ``"frenet"``; or
``"rmf"``, rotation-minimising, the default). On a closed directrix the
rotation-minimising frame's holonomy angle is spread linearly over v so that it
closes.

A 2D generatrix ``(a, b)`` lies in the directrix's normal plane, ``(l1, l2, l3) =
(a, b, 0)`` (``plane="normal"``, sweeps and pipes), or in the plane through the
tangent, ``(a, 0, b)`` (``plane="axial"``: profiles ``(r, z)`` of surfaces of
revolution and screw surfaces, whose directrix is the z axis). A 3D generatrix is
used as it is.

Both curves are B-splines (:class:`surfaces.bspline.BSplineCurve`) or analytic
curves (:class:`surfaces.curves.ParametricCurve`: lines, circles, helices, any
callable of ``t in [0, 1]``). Moving the control points of a B-spline generatrix or directrix
deforms the surface (:meth:`KinematicSurface.deform`; seed 004's change of base,
including a convex profile turned concave).

The surface enters the shared model by bicubic B-spline interpolation of a
sampled grid (seed 003) and its exact conversion to Bezier patches
(:meth:`KinematicSurface.to_bezier`), so tessellation, area, volume and export
are the shared ones; :func:`surfaces.measure.area_and_volume` adds the flux of
cone caps closing the ends of a tube, so swept solids get a volume.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from surfaces.bspline import BSplineCurve, interpolate_surface
from surfaces.curves import as_3d, as_curve, circle, helix, line, parameters, thread_profile
from surfaces.frames import FRAMES, frames
from surfaces.validate import as_array, InputError, positive

if TYPE_CHECKING:
    from surfaces.bezier import BezierPatches
    from surfaces.bspline import BSplineSurface
    from surfaces.mesh import TriangleMesh

__all__ = [
    "KinematicSurface",
    "sweep",
    "pipe",
    "revolve",
    "helical_sweep",
    "helicoid",
    "coil_spring",
    "screw_thread",
    "cap_ends",
]

PLANES = ("normal", "axial")


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
        raise InputError(f"{name}: expected a number, (start, end) or a callable, got {value!r}")
    a, b = float(arr[0]), float(arr[1])
    return lambda v: a + (b - a) * v


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
            raise InputError(f"frame: expected one of {', '.join(FRAMES)}, got {self.frame!r}")
        if self.plane not in PLANES:
            raise InputError(f"plane: expected one of {', '.join(PLANES)}, got {self.plane!r}")
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
            raise InputError(f"generatrix: expected 2D or 3D points, got dimension {g.shape[1]}")
        zero = np.zeros(g.shape[0])
        if self.plane == "normal":
            return np.column_stack([g[:, 0], g[:, 1], zero])
        return np.column_stack([g[:, 0], zero, g[:, 1]])

    def motion(self, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin ``(M, 3)``, rotation ``(M, 3, 3)`` (columns N', B', T) and scale ``(M,)`` at v.

        ``N'``, ``B'`` are the frame's normal and binormal turned by the twist and, on a
        closed directrix with an RMF, by the holonomy correction.
        """
        vv = parameters(v)
        t, n, b = frames(self.directrix, vv, self.frame, self.up)
        th = _law(self.twist, "twist", 0.0)(vv) + self._holonomy() * vv
        cos, sin = np.cos(th)[:, None], np.sin(th)[:, None]
        rot = np.stack([cos * n + sin * b, -sin * n + cos * b, t], axis=2)
        if self.directrix is None:
            origin = np.zeros((vv.size, 3))
        else:
            origin = as_3d(self.directrix.evaluate(vv), "directrix")
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
        uu, vv = parameters(u), parameters(v)
        if uu.shape != vv.shape:
            raise InputError(f"u, v: expected equal shapes, got {uu.shape} and {vv.shape}")
        origin, rot, s = self.motion(vv)
        return origin + s[:, None] * np.einsum("mij,mj->mi", rot, self._local(uu))

    def evaluate_grid(self, u, v) -> np.ndarray:
        """Exact points on the grid ``u (K,) x v (M,)`` -> ``(K, M, 3)``."""
        uu, vv = parameters(u), parameters(v)
        origin, rot, s = self.motion(vv)
        local = self._local(uu)
        return origin[None] + s[None, :, None] * np.einsum("mij,kj->kmi", rot, local)

    def sample_parameters(self, n_u: int, n_v: int) -> tuple[np.ndarray, np.ndarray]:
        """Uniform sample parameters: ``[0, 1)`` when closed, ``[0, 1]`` when open."""
        nu, nv = int(n_u), int(n_v)
        if nu < 4 or nv < 4:
            raise InputError(f"samples: need at least 4 x 4 samples, got {nu} x {nv}")
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
                raise InputError(f"{name}_control: the {name} is not a B-spline curve")
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

    Examples
    --------
    A circle of radius 1 along a segment of length 2: a cylinder (area ``4 pi``,
    volume ``2 pi`` with its end caps).

    >>> from surfaces.curves import circle, line
    >>> from surfaces.measure import area_and_volume
    >>> tube = sweep(circle(1.0), line([0, 0, 0], [0, 0, 2]))
    >>> tube.evaluate([0.0], [0.5]).round(12).tolist()
    [[1.0, 0.0, 1.0]]
    >>> m = area_and_volume(tube.to_bezier(32, 4))
    >>> round(m["area"] / np.pi, 4), round(m["volume"] / np.pi, 4)
    (4.0, 2.0)
    """
    return KinematicSurface(generatrix, directrix, frame, "normal", scale, twist, up)


def pipe(directrix, radius: float, frame: str = "rmf", up=None) -> KinematicSurface:
    """Tube of circular section ``radius`` along a directrix (area ``2 pi r L`` when it does
    not overlap itself).

    Parameters
    ----------
    directrix : curve
        Path of the tube's axis (3D, or 2D in z = 0), see :func:`sweep`.
    radius : float
        Tube radius (> 0), in the directrix's length unit.
    frame : {"fixed", "frenet", "rmf"}
        Moving frame (default rotation-minimising).
    up : (3,) array_like of float, optional
        First normal at the start.

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

    Parameters
    ----------
    profile : curve
        2D curve ``(r(u), z(u))`` (``r >= 0``).
    angle : float, optional
        Angle of revolution in radians (default a full turn ``2 pi``).

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

    Parameters
    ----------
    profile : curve
        2D curve ``(r(u), z(u))``.
    pitch : float
        Rise per turn ``P`` (> 0), in the profile's length unit.
    turns : float
        Number of turns ``n`` (> 0).

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

    Parameters
    ----------
    inner, outer : float
        Inner and outer radius (``0 <= inner < outer``).
    pitch : float
        Rise per turn (> 0), same unit as the radii.
    turns : float
        Number of turns (> 0).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    if not outer > inner >= 0:
        raise InputError(f"inner, outer: need 0 <= inner < outer, got {inner}, {outer}")
    return helical_sweep(line([inner, 0.0], [outer, 0.0]), pitch, turns)


def coil_spring(radius: float, pitch: float, turns: float, wire_radius: float) -> KinematicSurface:
    """Coil spring: a circle of ``wire_radius`` swept along a helix with an RMF.

    Parameters
    ----------
    radius : float
        Coil radius (> 0): distance of the wire's axis from the z axis.
    pitch : float
        Rise per turn of the wire's axis, same unit.
    turns : float
        Number of turns (> 0).
    wire_radius : float
        Radius of the wire's circular section (> 0).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.

    Raises
    ------
    ValueError
        When the wire would overlap itself (``2 * wire_radius >= |pitch|``, or
        ``wire_radius >= radius``).
    """
    a = positive(wire_radius, "wire_radius")
    r = positive(radius, "radius")
    if 2 * a >= abs(float(pitch)):
        raise InputError(f"wire_radius: neighbouring turns overlap (2 * {a} >= pitch {pitch})")
    # the helix's radius of curvature (r^2 + c^2) / r is at least r: a < r suffices
    if a >= r:
        raise InputError(f"wire_radius: must be smaller than the coil radius {r}")
    return pipe(helix(r, pitch, turns), a)


def screw_thread(major_radius: float, pitch: float, turns: float, depth: float,
                 closed: bool = False) -> KinematicSurface:
    """Screw-thread surface: :func:`thread_profile` swept helically with its own pitch.

    Parameters
    ----------
    major_radius : float
        Crest radius (> 0); the root lies at ``major_radius - depth``.
    pitch : float
        Rise per turn (> 0), same unit.
    turns : float
        Number of turns (> 0).
    depth : float
        Thread depth (``0 < depth < major_radius``).
    closed : bool
        Sweep the profile closed along its root chord (``thread_profile(..., closed=True)``):
        a tube around the thread's ridge, which :func:`cap_ends` closes into a solid of
        volume ``pi turns pitch ((r0 + depth / 2)^2 + depth^2 / 8 - r0^2)``
        (``r0 = major_radius - depth``; the screw motion keeps volume, so it is
        ``2 pi turns`` times the profile's ``integral r dr dz``).

    Returns
    -------
    KinematicSurface
        Evaluate exactly with ``evaluate``; ``to_bezier(n_u, n_v)`` gives the shared model.
    """
    big, h = positive(major_radius, "major_radius"), positive(depth, "depth")
    if h >= big:
        raise InputError(f"depth: must be smaller than the major radius {big}, got {h}")
    return helical_sweep(thread_profile(big - h, h, pitch, closed=closed), pitch, turns)


# ----------------------------------------------------------------------------- end caps
def cap_ends(mesh: TriangleMesh) -> tuple[TriangleMesh, float]:
    """Close every boundary loop of a tube's mesh with a flat cap (a fan from the loop's centre).

    A sweep or coil spring with a closed cross-section is a tube open at its two
    ends; each end is a closed loop in one plane (the directrix's normal plane).
    The fan triangles are oriented like their neighbours, so a consistently
    oriented tube becomes a watertight solid whose :meth:`TriangleMesh.signed_volume`
    is its volume.

    Parameters
    ----------
    mesh : TriangleMesh
        A consistently oriented mesh whose boundary consists of closed loops
        (e.g. :func:`surfaces.mesh.tessellate` of a tube's patches).

    Returns
    -------
    capped : TriangleMesh
        The mesh with one new vertex per loop (its centroid) and one triangle per boundary edge.
    cap_area : float
        Total area of the caps (model units^2).

    Raises
    ------
    ValueError
        When the mesh has no boundary (nothing to cap) or a boundary that is not
        made of simple closed loops.

    Examples
    --------
    An open cylinder of radius 1 and height 2 becomes a closed solid of volume ~ 2 pi:

    >>> from surfaces.mesh import TriangleMesh
    >>> a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    >>> ring = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], -1)
    >>> k = np.arange(64)
    >>> quads = np.stack([k, (k + 1) % 64, 64 + (k + 1) % 64, 64 + k], -1)
    >>> tube = TriangleMesh(np.vstack([ring, ring + [0, 0, 2]]), np.vstack([quads[:, :3], quads[:, [0, 2, 3]]]))
    >>> capped, cap_area = cap_ends(tube)
    >>> capped.is_watertight(), round(capped.signed_volume(), 3), round(cap_area, 3)
    (True, 6.273, 6.273)
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from surfaces.mesh import TriangleMesh
    from surfaces.topology import directed_edges, edge_keys
    from surfaces.vectors import cross

    n = mesh.n_vertices
    edges = directed_edges(mesh.triangles)
    keys = edge_keys(edges, n, directed=True)
    reverse = edge_keys(edges[:, ::-1], n, directed=True)
    boundary = edges[~np.isin(reverse, keys)]
    if len(boundary) == 0:
        raise InputError("mesh: has no open ends to cap")
    starts = np.bincount(boundary[:, 0], minlength=n)
    ends = np.bincount(boundary[:, 1], minlength=n)
    if starts.max() > 1 or np.any(starts != ends):
        raise InputError("mesh: its open ends are not simple closed loops (a tube's ends); cannot cap them")
    graph = coo_matrix((np.ones(len(boundary)), (boundary[:, 0], boundary[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    loops, loop_of_edge = np.unique(label[boundary[:, 0]], return_inverse=True)
    counts = np.bincount(loop_of_edge, minlength=len(loops))[:, None]
    centres = np.zeros((len(loops), 3))
    np.add.at(centres, loop_of_edge, mesh.vertices[boundary[:, 0]])
    centres /= counts
    # the neighbour runs a -> b along the edge; the cap runs b -> a to agree with it
    fans = np.stack([boundary[:, 1], boundary[:, 0], n + loop_of_edge], axis=1)
    vertices = np.vstack([mesh.vertices, centres])
    fan_normals = cross(vertices[fans[:, 1]] - vertices[fans[:, 0]], vertices[fans[:, 2]] - vertices[fans[:, 0]])
    cap_area = 0.5 * float(np.linalg.norm(fan_normals, axis=1).sum())
    normals = None
    if mesh.vertex_normals is not None:
        loop_normal = np.zeros((len(loops), 3))
        np.add.at(loop_normal, loop_of_edge, fan_normals)
        loop_normal /= np.maximum(np.linalg.norm(loop_normal, axis=1, keepdims=True), 1e-300)
        normals = np.vstack([mesh.vertex_normals, loop_normal])
    return TriangleMesh(vertices, np.vstack([mesh.triangles, fans]), normals), cap_area
