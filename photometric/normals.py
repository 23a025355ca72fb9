"""Unit normals from slopes, and the angle between two directions.

Frame of :data:`photometric.lights.CONVENTION`: a height field ``z(x, y)`` with slopes
``p = dz/dx``, ``q = dz/dy`` (y up) has the unit normal
``n = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``. :func:`angular_error_deg` is the one angular
error of the workbench (normal maps against ground truth, true against nominal lights).
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import as_array, InputError

__all__ = ["normals_from_slopes", "angular_error_deg"]


def normals_from_slopes(p, q) -> np.ndarray:
    """Unit normals ``n = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``.

    Parameters
    ----------
    p, q : array_like, shape S
        Slopes ``dz/dx`` and ``dz/dy`` (y up), dimensionless.

    Returns
    -------
    numpy.ndarray, shape S + (3,), float64
        Unit normals pointing towards the camera (``n_z > 0``).

    Examples
    --------
    >>> normals_from_slopes(0.75, 0.0).tolist()
    [-0.6, -0.0, 0.8]
    """
    p = as_array(p, "p")
    q = as_array(q, "q")
    if p.shape != q.shape:
        raise InputError(f"p, q: shapes differ ({p.shape} vs {q.shape})")
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    return n / np.sqrt(1.0 + p * p + q * q)[..., None]


def angular_error_deg(a, b) -> np.ndarray:
    """Angle between corresponding directions, degrees.

    ``atan2(|a x b|, a . b)``: independent of the vectors' lengths (no normalisation
    needed) and accurate for small angles, where ``arccos(a . b)`` loses half the digits.

    Parameters
    ----------
    a, b : array_like, shape (..., 3)
        Directions (normal maps ``(H, W, 3)``, light sets ``(N, 3)``, ...); shapes
        broadcast against each other. NaN propagates; a zero vector gives 0.

    Returns
    -------
    numpy.ndarray, shape (...), float64
        Angles in [0, 180] degrees. Select pixels with a mask afterwards:
        ``angular_error_deg(normals, truth)[mask]``.

    Examples
    --------
    >>> float(angular_error_deg([0.0, 0.0, 1.0], [0.0, 1.0, 1.0]))
    45.0
    >>> angular_error_deg(np.eye(3), [[2.0, 0.0, 0.0]]).tolist()
    [0.0, 90.0, 90.0]
    """
    u = as_array(a, "a", finite=False)
    v = as_array(b, "b", finite=False)
    if u.ndim < 1 or u.shape[-1] != 3 or v.ndim < 1 or v.shape[-1] != 3:
        raise InputError(f"a, b: expected shapes (..., 3), got {u.shape} and {v.shape}")
    try:
        np.broadcast_shapes(u.shape, v.shape)
    except ValueError:
        raise InputError(f"a, b: shapes {u.shape} and {v.shape} do not broadcast") from None
    cross = np.linalg.norm(np.cross(u, v), axis=-1)
    dot = np.einsum("...i,...i->...", u, v)
    return np.degrees(np.arctan2(cross, dot))
