"""Small vector helpers over the last axis of ``(..., 3)`` arrays, used across ``surfaces``.

Every module that crosses, dots or normalises vectors calls these, so a zero
vector is handled the same way everywhere: :func:`unit` leaves it zero instead
of dividing by zero.
"""

from __future__ import annotations

import numpy as np

__all__ = ["cross", "dot", "unit", "perpendicular"]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis, component-wise (faster than ``np.cross`` on big arrays).

    Parameters
    ----------
    a, b : numpy.ndarray, shape (..., 3)

    Returns
    -------
    numpy.ndarray, shape (..., 3), float64

    Examples
    --------
    >>> cross(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])).tolist()
    [0.0, 0.0, 1.0]
    """
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis.

    Parameters
    ----------
    a, b : numpy.ndarray, shape (..., d)

    Returns
    -------
    numpy.ndarray, shape (...)

    Examples
    --------
    >>> dot(np.array([[1.0, 2.0, 3.0]]), np.array([[4.0, 5.0, 6.0]])).tolist()
    [32.0]
    """
    return np.einsum("...x,...x->...", a, b)


def unit(v: np.ndarray) -> np.ndarray:
    """Vectors scaled to unit length over the last axis; zero vectors stay zero.

    Parameters
    ----------
    v : numpy.ndarray, shape (..., d)
        Float vectors; the dtype is kept (float32 stays float32).

    Returns
    -------
    numpy.ndarray, shape (..., d)

    Examples
    --------
    >>> unit(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])).tolist()
    [[0.6, 0.8, 0.0], [0.0, 0.0, 0.0]]
    """
    n = np.sqrt(dot(v, v))[..., None]
    return v / np.where(n > 0, n, 1.0)


def perpendicular(t: np.ndarray) -> np.ndarray:
    """Unit vectors perpendicular to unit vectors ``t``, built from the least aligned axis.

    Parameters
    ----------
    t : numpy.ndarray, shape (M, 3)
        Unit vectors.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        Unit vectors ``p`` with ``p . t = 0``.

    Examples
    --------
    >>> perpendicular(np.array([[0.0, 0.0, 1.0]])).tolist()
    [[1.0, 0.0, 0.0]]
    """
    axis = np.eye(3)[np.argmin(np.abs(t), axis=1)]
    p = axis - np.sum(axis * t, axis=1, keepdims=True) * t
    return p / np.linalg.norm(p, axis=1, keepdims=True)
