"""A Y (trouser) phantom: one trunk branching into two legs, with its volume in closed form.

Every horizontal section is the union of two discs of radius ``r`` whose
centres sit at ``x = -s(z)`` and ``x = +s(z)``, ``s(z) = max(0, k (z - z_b))``:
one disc (the trunk) below ``z_b``, a waist-pinched outline while the discs
overlap, two separate circles (the legs) above ``z_b + r / k``. Between two
planes the volume is ``integral (2 pi r^2 - L(s(z))) dz`` with the lens
``L(s) = 2 r^2 (acos u - u sqrt(1 - u^2))``, ``u = s / r`` (centre distance
``2 s``), integrated in closed form: ``integral (acos u - u sqrt(1 - u^2)) du
= u acos u - sqrt(1 - u^2) + (1 - u^2)^(3/2) / 3``.
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import InputError, positive


def _lens_antiderivative(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * np.arccos(u) - np.sqrt(1 - u**2) + (1 - u**2) ** 1.5 / 3


def trouser_volume(z0: float, z1: float, r: float = 6.0, z_branch: float = 10.0, slope: float = 0.5) -> float:
    """Exact volume of the trouser phantom between the planes ``z0 < z1`` (mm^3).

    Parameters
    ----------
    z0, z1 : float
        Planes in mm.
    r : float
        Radius of the trunk and of each leg in mm.
    z_branch : float
        Where the legs start to move apart (mm).
    slope : float
        How fast each leg's centre moves away from the axis (mm per mm of z).

    Returns
    -------
    float

    Examples
    --------
    Below the branching the trunk is a cylinder:

    >>> round(trouser_volume(0.0, 10.0) / (np.pi * 36 * 10), 12)
    1.0
    """
    r, k = positive(r, "r"), positive(slope, "slope")
    if not z1 > z0:
        raise InputError(f"z1: must be above z0, got {z0} and {z1}")
    # the lens between the discs: the whole disc below z_branch, then the closed form in u = s / r
    trunk = np.pi * r**2 * max(0.0, min(z1, z_branch) - z0)
    u0, u1 = (max(0.0, k * (z - z_branch)) / r for z in (z0, z1))
    lens = trunk + 2 * r**2 * (r / k) * float(_lens_antiderivative(np.array(u1)) - _lens_antiderivative(np.array(u0)))
    return float(2 * np.pi * r**2 * (z1 - z0) - lens)


def trouser_contours(spacing: float, height: float = 40.0, r: float = 6.0, z_branch: float = 10.0,
                     slope: float = 0.5, n_points: int = 96) -> list[tuple[float, np.ndarray]]:
    """Sections of the trouser phantom every ``spacing`` mm from ``z = 0`` to ``height``.

    Parameters
    ----------
    spacing : float
        Slice spacing in mm.
    height : float
        Top plane in mm.
    r, z_branch, slope : float
        As :func:`trouser_volume`.
    n_points : int
        Points per disc outline (the pinched outline keeps those outside the other disc).

    Returns
    -------
    list of (float, numpy.ndarray)
        ``(z, points (n, 2))`` per contour, counter-clockwise, points ON the true outline.
    """
    d, r, k = positive(spacing, "spacing"), positive(r, "r"), positive(slope, "slope")
    t = np.linspace(0, 2 * np.pi, int(n_points), endpoint=False)
    out = []
    for z in np.arange(0.0, float(height) + 1e-9, d):
        s = max(0.0, k * (z - z_branch))
        discs = [np.stack([cx + r * np.cos(t), r * np.sin(t)], axis=1) for cx in (-s, s)]
        if s >= r:
            out += [(float(z), p) for p in discs]
            continue
        if s == 0:
            out.append((float(z), discs[0]))
            continue
        # the union's outline: each disc's points outside the other, star-shaped about the origin
        keep = np.vstack([p[np.linalg.norm(p - (-cx, 0.0), axis=1) >= r] for p, cx in zip(discs, (-s, s))])
        out.append((float(z), keep[np.argsort(np.arctan2(keep[:, 1], keep[:, 0]))]))
    return out
