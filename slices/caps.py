"""End caps of a body: none, flat, half a slice beyond, or a smooth dome.

* ``flat``: planar caps in the first and last contour planes.
* ``half``: the end contour extruded by half a slice spacing, then a flat cap
  (the volume treatment-planning systems count, which gives each contour a
  slab of one spacing).
* ``dome``: rings shrinking towards the contour's centre on a quarter ellipse
  of height half a slice spacing, blended with the side surface, so the body
  closes smoothly in a pole.
* ``none``: the surface stays open; volumes are still those closed by flat caps.

Planar caps are patch columns of degenerate fan patches from the cap centre to
the boundary curve, so the divergence-theorem volume of the patch grid is
exact for any outline (the flux through a fan over a plane is the signed area
it sweeps, also where the fan overlaps itself on a folded outline). Their area
is computed from the boundary curve with Green's theorem, and their triangles
by a constrained triangulation of the boundary polygon (manifold3d), which
stays inside non-convex outlines.
"""

from __future__ import annotations

import numpy as np

from surfaces.mesh import TriangleMesh
from surfaces.validate import as_array, positive

CAP_KINDS = ("none", "flat", "half", "dome")

#: Rings of a dome cap (more rings: closer to the quarter ellipse).
DOME_RINGS = 3


def _bezier_points(curve: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points of every Bezier segment at local parameters ``s``: (M, len(s), 3)."""
    s = s[None, :, None]
    c = curve[:, None]
    return (
        (1 - s) ** 3 * c[:, :, 0] + 3 * s * (1 - s) ** 2 * c[:, :, 1]
        + 3 * s**2 * (1 - s) * c[:, :, 2] + s**3 * c[:, :, 3]
    )


def fan_column(curve, center, toward_center: bool) -> np.ndarray:
    """One patch column of degenerate fan patches between a closed curve and a point.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed Bezier curve (segment ``j`` on patch row ``j``).
    center : array_like, shape (3,)
        Apex in mm (in the curve's plane for a flat cap).
    toward_center : bool
        ``v`` runs from the curve to the apex (top cap) instead of from the apex
        to the curve (bottom cap).

    Returns
    -------
    numpy.ndarray, shape (M, 1, 4, 4, 3)
        Control points; bilinear in ``v``, so each patch is planar when the curve is.
    """
    c = as_array(curve, "curve", shape=(None, 4, 3))
    p = as_array(center, "center", shape=(3,))
    w = np.arange(4) / 3.0
    if toward_center:
        w = w[::-1]
    ctrl = p[None, None, None, :] + w[None, None, :, None] * (c[:, :, None, :] - p)
    return ctrl[:, None]


def prism_column(curve, height: float) -> np.ndarray:
    """One patch column extruding a closed curve along z.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed Bezier curve.
    height : float
        Signed extrusion in mm: negative below the curve (``v`` runs up from
        ``z + height`` to the curve), positive above (``v`` runs up from the curve).

    Returns
    -------
    numpy.ndarray, shape (M, 1, 4, 4, 3)
    """
    c = as_array(curve, "curve", shape=(None, 4, 3))
    w = np.arange(4) / 3.0
    dz = height * (1.0 - w) if height < 0 else height * w
    ctrl = np.repeat(c[:, :, None, :], 4, axis=2).copy()
    ctrl[..., 2] += dz[None, None, :]
    return ctrl[:, None]


def dome_rings(curve, center, height: float, upward: bool, n_rings: int = DOME_RINGS) -> np.ndarray:
    """Virtual slice curves of a dome cap (quarter ellipse, closing in a pole).

    Ring ``k`` is ``c + (C - c) cos(t_k) +/- h sin(t_k) e_z`` with
    ``t_k = k pi / (2 n)``, so the last ring is the pole.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        End slice curve.
    center : array_like, shape (3,)
        Centre in the end plane (mm).
    height : float
        Dome height in mm (> 0).
    upward : bool
        Dome above the curve (top end) or below (bottom end).
    n_rings : int
        Number of rings.

    Returns
    -------
    numpy.ndarray, shape (n_rings, M, 4, 3)
        Rings from the one next to the curve to the pole.
    """
    c = as_array(curve, "curve", shape=(None, 4, 3))
    p = as_array(center, "center", shape=(3,))
    h = positive(height, "height")
    t = np.arange(1, int(n_rings) + 1) * np.pi / (2 * int(n_rings))
    rings = p + np.cos(t)[:, None, None, None] * (c[None] - p)
    rings[..., 2] += (1.0 if upward else -1.0) * h * np.sin(t)[:, None, None]
    rings[-1] = p + np.array([0.0, 0.0, (1.0 if upward else -1.0) * h])
    return rings


def curve_area(curve) -> float:
    """Signed area enclosed by a closed planar Bezier curve (Green's theorem).

    ``A = 1/2 * integral (x y' - y x') du``, a degree-5 polynomial per
    segment, integrated exactly with 3-point Gauss-Legendre.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed Bezier curve; the area is taken in the x-y plane.

    Returns
    -------
    float
        mm^2, positive for a counter-clockwise curve seen from +z.
    """
    c = as_array(curve, "curve", shape=(None, 4, 3))
    x, w = np.polynomial.legendre.leggauss(3)
    s = 0.5 * (x + 1.0)
    pts = _bezier_points(c, s)
    d = 3 * ((1 - s)[None, :, None] ** 2 * (c[:, None, 1] - c[:, None, 0])
             + (2 * s * (1 - s))[None, :, None] * (c[:, None, 2] - c[:, None, 1])
             + (s**2)[None, :, None] * (c[:, None, 3] - c[:, None, 2]))
    integrand = pts[..., 0] * d[..., 1] - pts[..., 1] * d[..., 0]
    return float(0.25 * np.sum(integrand * w[None, :]))


def planar_cap_mesh(curve, samples: int, outward_z: float) -> TriangleMesh:
    """Triangles of a flat cap whose boundary matches a tessellated surface edge.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed planar boundary curve (counter-clockwise seen from +z).
    samples : int
        Points per Bezier segment, as used by :func:`surfaces.mesh.tessellate`.
    outward_z : float
        +1 for a top cap (normal +z), -1 for a bottom cap.

    Returns
    -------
    TriangleMesh
        Boundary vertices at ``u = j + a / samples`` (the tessellation's); a fan
        from one centre vertex when the outline is star-shaped about its vertex
        mean, else a constrained triangulation of the boundary polygon.
    """
    import manifold3d

    c = as_array(curve, "curve", shape=(None, 4, 3))
    s = np.arange(int(samples)) / int(samples)
    ring = _bezier_points(c, s).reshape(-1, 3)
    xy = ring[:, :2]
    area = 0.5 * float(np.dot(xy[:, 0], np.roll(xy[:, 1], -1)) - np.dot(xy[:, 1], np.roll(xy[:, 0], -1)))
    n = len(xy)
    center = xy.mean(axis=0)
    rel = xy - center
    ang = np.arctan2(rel[:, 1], rel[:, 0])
    turn = (ang - np.roll(ang, 1) + np.pi) % (2 * np.pi) - np.pi
    if np.all(turn * np.sign(area) > 0) and abs(turn.sum()) > np.pi:
        # star-shaped about the vertex mean: a fan from an extra centre vertex
        ring = np.vstack([ring, np.append(center, ring[0, 2])])
        i = np.arange(n)
        tri = np.stack([np.full(n, n), i, (i + 1) % n], axis=1)
    else:
        tri = np.asarray(manifold3d.triangulate([xy if area > 0 else xy[::-1]]), dtype=np.int64)
        if area <= 0:
            tri = n - 1 - tri
    if len(tri) == 0:
        raise ValueError("cap: the end contour could not be triangulated")
    xy = ring[:, :2]
    # Both triangulations are consistently oriented as a whole; decide the orientation of all
    # triangles at once from their total signed area. Deciding per triangle would flip the
    # (near-)degenerate slivers a straight run of the outline can give the wrong way round, and
    # their edges would then disagree with the neighbouring triangles.
    corners = xy[tri]
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    up = float(np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])) > 0
    if up != (outward_z > 0):
        tri = tri[:, ::-1].copy()
    normal = np.zeros_like(ring)
    normal[:, 2] = 1.0 if outward_z > 0 else -1.0
    return TriangleMesh(ring, tri, normal)
