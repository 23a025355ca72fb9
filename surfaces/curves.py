"""Curves for kinematic surfaces: analytic curves, any callable, B-splines, and curve files.

Everything here is a curve on ``t in [0, 1]`` with ``evaluate(t) -> (M, d)`` and
``derivative(t, order) -> (M, d)`` (the :class:`Curve` protocol): the analytic
:class:`ParametricCurve` (lines, circles, helices, the round screw-thread
profile, any callable) and :class:`surfaces.bspline.BSplineCurve`.
:func:`load_curve` reads the JSON curve files of ``workbench surfaces sweep``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from surfaces.bspline import BSplineCurve, interpolate_curve
from surfaces.validate import as_array, InputError, positive
from surfaces.vectors import perpendicular

__all__ = [
    "Curve",
    "ParametricCurve",
    "parameters",
    "as_3d",
    "line",
    "circle",
    "helix",
    "thread_profile",
    "as_curve",
    "load_curve",
]


class Curve(Protocol):
    """What the kinematic code needs from a curve: points and derivatives on ``[0, 1]``."""

    closed: bool

    def evaluate(self, t) -> np.ndarray: ...

    def derivative(self, t, order: int = 1) -> np.ndarray: ...


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
        return np.atleast_2d(np.asarray(self.func(parameters(t)), dtype=np.float64))

    def derivative(self, t, order: int = 1) -> np.ndarray:
        """Derivative of the given order with respect to ``t`` -> ``(M, d)``."""
        x = parameters(t)
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
        raise InputError(f"order: finite differences give orders 1 and 2, got {order}")


def parameters(t, name: str = "t") -> np.ndarray:
    """Curve parameters as a 1-D float64 array (a scalar becomes one value).

    Parameters
    ----------
    t : float or (M,) array_like
        Parameters, usually in ``[0, 1]``.
    name : str, optional
        Argument name used in error messages.

    Returns
    -------
    (M,) float64

    Examples
    --------
    >>> parameters(0.5).tolist()
    [0.5]
    """
    return np.atleast_1d(as_array(t, name, ndim=(0, 1)))


def as_3d(points: np.ndarray, name: str = "points") -> np.ndarray:
    """Points of a 2D or 3D curve as 3D points (a 2D curve lies in the plane z = 0).

    Parameters
    ----------
    points : (M, 2) or (M, 3) array
        Curve points or derivatives.
    name : str, optional
        Argument name used in error messages.

    Returns
    -------
    (M, 3) array

    Examples
    --------
    >>> as_3d(np.array([[1.0, 2.0]])).tolist()
    [[1.0, 2.0, 0.0]]
    """
    points = np.atleast_2d(points)
    if points.shape[1] == 3:
        return points
    if points.shape[1] == 2:
        return np.column_stack([points, np.zeros(points.shape[0])])
    raise InputError(f"{name}: expected 2D or 3D points, got dimension {points.shape[1]}")


def line(start, end) -> ParametricCurve:
    """Straight segment ``start + t (end - start)``, ``t in [0, 1]``.

    Parameters
    ----------
    start, end : (d,) array_like of float
        End points (2D or 3D, any unit).

    Returns
    -------
    ParametricCurve
        ``evaluate(t)`` and exact ``derivative(t, k)`` for ``t`` in ``[0, 1]``, shape ``(M, d)``.
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

    Returns
    -------
    ParametricCurve
        ``evaluate(t)`` and exact ``derivative(t, k)`` for ``t`` in ``[0, 1]``, shape ``(M, d)``.
    """
    r = positive(radius, "radius")
    c = as_array(center, "center", ndim=1)
    if c.size == 2:
        e1, e2 = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    elif c.size == 3:
        e1, e2 = _plane_axes(as_array(normal, "normal", shape=(3,)))
    else:
        raise InputError(f"center: expected 2 or 3 coordinates, got {c.size}")
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

    Returns
    -------
    ParametricCurve
        ``evaluate(t)`` and exact ``derivative(t, k)`` for ``t`` in ``[0, 1]``, shape ``(M, d)``.
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


def thread_profile(minor_radius: float, depth: float, pitch: float, closed: bool = False) -> ParametricCurve:
    """One pitch of a round (sinusoidal) screw-thread profile in the ``(r, z)`` plane.

    ``r(t) = minor_radius + depth (1 - cos 2 pi t) / 2``, ``z(t) = pitch * t``: root at
    ``t = 0, 1``, crest (``minor_radius + depth``) at ``t = 1/2``. Swept helically with
    the same pitch (:func:`surfaces.kinematic.screw_thread`) the profile joins itself from turn to turn.

    Parameters
    ----------
    minor_radius : float
        Root radius (> 0).
    depth : float
        Thread depth (> 0): the crest lies at ``minor_radius + depth``.
    pitch : float
        Rise per pitch, same unit (any sign).
    closed : bool
        Close the profile along its axis-side chord (the root line ``r = minor_radius``
        from ``z = pitch`` back to 0): the cross-section of the thread's ridge, a closed
        curve whose helical sweep is a tube that flat end caps make a solid. The
        parameter runs over the tooth, then the chord, in proportion to their lengths.

    Returns
    -------
    ParametricCurve
        ``evaluate(t)`` and exact ``derivative(t, k)`` for ``t`` in ``[0, 1]``, shape ``(M, d)``
        (piecewise for ``closed``: one-sided at the two corners).
    """
    r0, h, p = positive(minor_radius, "minor_radius"), positive(depth, "depth"), float(pitch)
    w = 2 * np.pi

    def point(t, k=0):
        if k == 0:
            return np.stack([r0 + h * (1 - np.cos(w * t)) / 2, p * t], axis=1)
        if k == 1:
            return np.stack([h * w * np.sin(w * t) / 2, np.full_like(t, p)], axis=1)
        return np.stack([h * w * w * np.cos(w * t) / 2, np.zeros_like(t)], axis=1)

    if not closed:
        return ParametricCurve(point, (lambda t: point(t, 1), lambda t: point(t, 2)), False, "thread")
    t = np.linspace(0.0, 1.0, 257)
    tooth = float(np.trapezoid(np.linalg.norm(point(t, 1), axis=1), t))
    f = tooth / (tooth + abs(p))  # share of the parameter on the tooth

    def closed_point(u, k=0):
        u = np.asarray(u, np.float64)
        on_tooth = u <= f
        tooth_part = point(np.minimum(u / f, 1.0), k) / f**k
        s = np.clip((u - f) / (1 - f), 0.0, 1.0)
        chord = np.stack([np.full_like(s, r0), p * (1 - s)], axis=1) if k == 0 else \
            np.stack([np.zeros_like(s), np.full_like(s, -p / (1 - f) if k == 1 else 0.0)], axis=1)
        return np.where(on_tooth[:, None], tooth_part, chord)

    return ParametricCurve(closed_point, (lambda u: closed_point(u, 1), lambda u: closed_point(u, 2)), True,
                           "thread (closed along the root)")


def as_curve(obj) -> Curve:
    """Accept a B-spline curve, a :class:`ParametricCurve` or a callable ``f(t) -> (M, d)``.

    Parameters
    ----------
    obj : BSplineCurve, ParametricCurve or callable
        A callable maps ``(M,)`` parameters in ``[0, 1]`` to ``(M, d)`` points; its
        derivatives are then central differences.

    Returns
    -------
    Curve
        ``obj`` itself, or the callable wrapped in a :class:`ParametricCurve`.
    """
    if isinstance(obj, (BSplineCurve, ParametricCurve)):
        return obj
    if callable(obj):
        return ParametricCurve(obj, (), bool(getattr(obj, "closed", False)), "callable")
    raise InputError(f"curve: expected a BSplineCurve, ParametricCurve or callable, got {obj!r}")


def _plane_axes(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    length = float(np.linalg.norm(normal))
    if length == 0.0:
        raise InputError("normal: must not be the zero vector")
    n = normal / length
    e1 = perpendicular(n[None])[0]
    return e1, np.cross(n, e1)


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

    Parameters
    ----------
    source : str, os.PathLike or dict
        A JSON file or the already parsed description.

    Returns
    -------
    Curve
        A :class:`~surfaces.bspline.BSplineCurve` or :class:`ParametricCurve`.

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
            raise InputError(f"{path}: not valid JSON ({exc})") from None
        where = str(path)
    if not isinstance(spec, dict):
        raise InputError(f"{where}: expected a JSON object")
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
        raise InputError(f"{where}: a {kind!r} curve needs the field {exc.args[0]!r}") from None
    except ValueError as exc:
        raise InputError(f"{where}: {exc}") from None
    raise InputError(f"{where}: unknown curve type {kind!r}; use bspline, line, circle or helix")


def _given_bspline(spec: dict, degree: int, closed: bool) -> BSplineCurve:
    if "control" not in spec or "knots" not in spec:
        raise InputError("a bspline curve needs 'points', or 'control' and 'knots'")
    control = as_array(spec["control"], "control", ndim=2)
    knots = as_array(spec["knots"], "knots", ndim=1)
    want = control.shape[0] + (2 * degree + 1 if closed else degree + 1)
    if knots.size != want:
        raise InputError(
            f"knots: expected {want} knots for {control.shape[0]} control points, got {knots.size}"
        )
    if np.any(np.diff(knots) < 0):
        raise InputError("knots: must be non-decreasing")
    if not (knots[degree] == 0.0 and knots[-degree - 1] == 1.0):
        raise InputError("knots: the domain [t_p, t_{n+1}] must be [0, 1]")
    return BSplineCurve(degree, knots, control, np.empty(0), closed)
