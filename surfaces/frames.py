"""Moving frames along a curve: fixed, Frenet, and rotation-minimising (seed 004).

* ``"fixed"``: the frame at ``v = 0`` carried without rotation;
* ``"frenet"``: tangent, principal normal, binormal (undefined where the curvature
  vanishes: a ``ValueError`` says where; it also flips at inflections);
* ``"rmf"``: rotation-minimising frame by the double reflection method (Wang,
  Juettler, Zheng & Liu, "Computation of rotation minimizing frames", ACM TOG 27(1),
  2008, eqs. 4-5), computed on a fine sampling of the curve.

Frames are ``(T, N, B)`` with ``B = T x N``, each ``(M, 3)``; a 2D curve lies in
the plane z = 0.
"""

from __future__ import annotations

import numpy as np

from surfaces.curves import Curve, as_3d, as_curve, parameters
from surfaces.validate import as_array, InputError
from surfaces.vectors import perpendicular, unit

__all__ = ["FRAMES", "RMF_SAMPLES", "frames", "rotation_minimizing_frames"]

FRAMES = ("fixed", "frenet", "rmf")
#: intervals of the directrix sampling on which the rotation-minimising frame is propagated
RMF_SAMPLES = 4096


def _tangents(directrix: Curve, v: np.ndarray) -> np.ndarray:
    d1 = as_3d(directrix.derivative(v, 1), "directrix")
    speed = np.linalg.norm(d1, axis=1)
    bad = np.flatnonzero(speed <= 1e-12 * max(1.0, float(speed.max(initial=0.0))))
    if bad.size:
        raise InputError(f"directrix: zero speed (no tangent) at v = {v[bad[0]]:.6g}")
    return d1 / speed[:, None]


def _frenet_normals(directrix: Curve, v: np.ndarray, t: np.ndarray) -> np.ndarray:
    d1 = as_3d(directrix.derivative(v, 1), "directrix")
    d2 = as_3d(directrix.derivative(v, 2), "directrix")
    n = d2 - np.sum(d2 * t, axis=1, keepdims=True) * t
    size = np.linalg.norm(n, axis=1)
    bad = np.flatnonzero(size <= 1e-9 * np.linalg.norm(d1, axis=1) ** 2)
    if bad.size:
        raise InputError(
            f"frame: the Frenet frame is undefined where the directrix has zero curvature "
            f"(v = {v[bad[0]]:.6g}); use frame='rmf' or 'fixed'"
        )
    return n / size[:, None]


def _initial_normal(directrix: Curve, t0: np.ndarray, up) -> np.ndarray:
    if up is not None:
        u = as_array(up, "up", shape=(3,))
        n = u - np.dot(u, t0) * t0
        if np.linalg.norm(n) <= 1e-9 * max(np.linalg.norm(u), 1e-300):
            raise InputError("up: must not be parallel to the directrix tangent at v = 0")
        return n / np.linalg.norm(n)
    try:
        return _frenet_normals(directrix, np.zeros(1), t0[None])[0]
    except ValueError:  # straight start: any perpendicular will do
        return perpendicular(t0[None])[0]


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
    vq = np.clip(parameters(v), 0.0, 1.0)
    grid, inverse = np.unique(np.concatenate([np.linspace(0.0, 1.0, int(samples) + 1), vq]),
                              return_inverse=True)
    x = as_3d(curve.evaluate(grid), "directrix")
    t = _tangents(curve, grid)
    v1 = x[1:] - x[:-1]
    h1 = _reflection(v1)
    v2 = t[1:] - np.einsum("kij,kj->ki", h1, t[:-1])
    steps = _prefix_products(_reflection(v2) @ h1)
    r0 = _initial_normal(curve, t[0], up)
    r = np.concatenate([r0[None], np.einsum("kij,j->ki", steps, r0)])
    # re-orthonormalise against the exact tangents (removes the O(h^4) drift off the normal plane)
    r = unit(r - np.sum(r * t, axis=1, keepdims=True) * t)
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
        raise InputError(f"frame: expected one of {', '.join(FRAMES)}, got {kind!r}")
    vv = parameters(v)
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
