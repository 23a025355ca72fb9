"""Contour stacks on which every interpolating side surface folds (issue 19's Lt Lung causes).

Two shapes the breast structure set draws, made small: a bulb on a narrow neck
(a hook) drawn on one plane only, and a C whose channel closes so that its area
more than doubles between two planes (an area-doubling merge). Every surface of
:data:`slices.body.FALLBACKS` self-intersects on them; they are the phantoms of
the stepped-slab tests (:func:`slices.body.build_stepped`). They have no
closed-form volume: the stacks' slab volume (``d`` times the areas) is the
reference.
"""

from __future__ import annotations

import numpy as np

from slices.io import Contour
from surfaces.validate import InputError

__all__ = ["FOLD_STACKS", "closing_c_stack", "fold_stack", "hook_stack"]


def _circle(radius: float, n: int) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return radius * np.stack([np.cos(t), np.sin(t)], 1)


def _densify(corners: np.ndarray, step: float) -> np.ndarray:
    """Points every ``step`` mm or less along the open polyline ``corners`` (last corner left out)."""
    seg = np.diff(corners, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / step).astype(int), 1)
    k = np.repeat(np.arange(len(seg)), n)
    s = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return corners[k] + s[:, None] * seg[k]


def hook_stack(radius: float = 10.0, neck: float = 0.3, length: float = 8.0, height: float = 4.0,
               gap: float = 1.0, spacing: float = 3.0, n_planes: int = 5) -> list[Contour]:
    """Circles with, on the middle plane only, a thin finger whose end curls back over it (a hook).

    Parameters
    ----------
    radius : float
        Circle radius (mm).
    neck : float
        Width of the finger (mm).
    length : float
        Length of the finger beyond the circle (mm).
    height : float
        Height of the hook above the finger's axis (mm).
    gap : float
        Gap between the finger and the hook's returning arm (mm).
    spacing : float
        Plane spacing (mm).
    n_planes : int
        Planes, at least 3 (the hook is on plane ``n_planes // 2``).

    Returns
    -------
    list of Contour
        Counter-clockwise outlines, increasing ``z`` from 0.

    Examples
    --------
    >>> from slices.polygons import signed_area
    >>> s = hook_stack()
    >>> len(s), [round(signed_area(c.points)) for c in s[1:4]]
    (5, [314, 334, 314])
    """
    if n_planes < 3:
        raise InputError(f"n_planes: need at least 3 planes for a one-plane hook, got {n_planes}")
    if not 0 < neck < gap + neck < height < radius or length <= 2.0 + neck:
        raise InputError("hook_stack: need 0 < neck < neck + gap < height < radius and length > 2 + neck (mm)")
    a = np.arcsin(neck / 2 / radius)
    t = np.linspace(a, 2 * np.pi - a, 90)[:-1]
    rim = radius * np.stack([np.cos(t), np.sin(t)], 1)
    x0, w = radius * np.cos(a), neck / 2
    # along the finger, up its end, back over it, down, and out again along the arm's underside
    path = np.array([[x0, -w], [x0 + length, -w], [x0 + length, height], [x0 + 2, height], [x0 + 2, w + gap],
                     [x0 + length - neck, w + gap], [x0 + length - neck, w], [x0, w]])
    hooked = np.vstack([rim, _densify(path, 0.7)])
    plain = _circle(radius, 90)
    return [Contour(spacing * k, hooked if k == n_planes // 2 else plain) for k in range(n_planes)]


def closing_c_stack(radius: float = 12.0, cavity: float = 9.0, channel_deg: float = 5.7, spacing: float = 3.0,
                    n_open: int = 2, n_closed: int = 2) -> list[Contour]:
    """A C (a disc whose round cavity opens through a narrow channel) that closes into the full disc.

    Parameters
    ----------
    radius : float
        Disc radius (mm).
    cavity : float
        Cavity radius (mm); the cavity touches the rim's inside at the channel.
    channel_deg : float
        Half-angle of the channel at the disc's centre (degrees).
    spacing : float
        Plane spacing (mm).
    n_open, n_closed : int
        Planes with the C, then with the disc.

    Returns
    -------
    list of Contour
        Counter-clockwise outlines, increasing ``z`` from 0.

    Examples
    --------
    The disc encloses more than twice the C:

    >>> from slices.polygons import signed_area
    >>> s = closing_c_stack()
    >>> round(signed_area(s[-1].points) / signed_area(s[0].points), 2)
    2.3
    """
    if not 0 < cavity < radius or n_open < 1 or n_closed < 1:
        raise InputError("closing_c_stack: need 0 < cavity < radius (mm) and at least one plane of each")
    gap = np.radians(channel_deg)
    t = np.linspace(gap, 2 * np.pi - gap, 90)
    outer = radius * np.stack([np.cos(t), np.sin(t)], 1)
    b = np.arcsin(min(radius * np.sin(gap) / cavity, 0.99))
    ti = np.linspace(2 * np.pi - b, b, 60)
    inner = np.stack([radius - 0.5 - cavity + cavity * np.cos(ti), cavity * np.sin(ti)], 1)
    c_shape, disc = np.vstack([outer, inner]), _circle(radius, 90)
    return [Contour(spacing * k, c_shape if k < n_open else disc) for k in range(n_open + n_closed)]


#: The fold phantoms by name.
FOLD_STACKS = {"hook": hook_stack, "closing_c": closing_c_stack}


def fold_stack(name: str, **params) -> list[Contour]:
    """A fold phantom by name (:data:`FOLD_STACKS`), with its keyword parameters.

    Parameters
    ----------
    name : str
        ``"hook"`` or ``"closing_c"``.
    **params
        Keyword arguments of :func:`hook_stack` or :func:`closing_c_stack` (mm).

    Returns
    -------
    list of Contour
    """
    if name not in FOLD_STACKS:
        raise InputError(f"name: unknown fold phantom {name!r}; choose from {sorted(FOLD_STACKS)}")
    return FOLD_STACKS[name](**params)
