"""End caps of a body: the contours' own trend, none, flat, half a slice beyond, or a smooth dome.

* ``trend`` (the default): the structure beyond each end plane estimated from
  the contours' own area trend (:func:`trend_profile`): a quadratic through the
  areas of the last three planes (two planes: a sphere's curvature; one plane:
  a sphere through its outline), extrapolated until the area vanishes
  (:func:`trend_cap_volume`: exact for spheres and ellipsoids, whatever the
  planes' offset). Where it does not vanish within one slice spacing (a
  structure cut off, a cylinder's end), the end is unknown between the end
  plane and the next: the half cap, the expected end. The surface is shaped
  as the trend says (:func:`trend_rings`: the end contour scaled about its
  centroid so that each ring's area follows the trend, closing in an apex;
  :func:`add_cap_rings`), so it encloses the trend's volume to the blend's
  accuracy and follows the true surface's slope; where the trend does not
  close, the end contour is extruded by that volume over its area
  (:func:`resolve_trend`). :mod:`slices.volume` integrates the same model
  over the whole structure's areas.
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
it sweeps, also where the fan overlaps itself on a folded outline). The apex
is moved into the outline's kernel where the centre does not see the whole
outline (:func:`fan_apex`), so the fan covers the cap once and the patches'
area is the cap's; an outline without a kernel (a deep notch) still folds
there. The cap's area is computed from the boundary curve with Green's
theorem, and its triangles by a constrained triangulation of the boundary
polygon (manifold3d), which stays inside non-convex outlines, with a ring of
vertices just inside the boundary that carries the cap's own normal (so the
written mesh shades flat caps flat).

A body's caps are put together in three steps: :func:`end_kinds` (which cap
each end gets), :func:`add_dome_rings` (virtual slices of dome caps, before
the side surface is built over the stack) and :func:`close_side` (half-cap
extrusions and fan columns around the side surface); :func:`weld_flat_caps`
joins the flat caps' triangles to the tessellated side.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from surfaces.mesh import TriangleMesh, weld_tolerance, compact, merge_meshes, points_apart, weld
from surfaces.validate import as_array, InputError, positive

CAP_KINDS = ("none", "flat", "half", "dome", "trend")

#: Cap kinds extruded beyond the end curve (a prism, then a flat cap): half a spacing, or the trend's volume.
PRISM_KINDS = ("half", "trend")

#: Rings of a dome cap (more rings: closer to the quarter ellipse).
DOME_RINGS = 3


#: Points per Bezier segment at which :func:`fan_apex` tests that a fan does not fold.
APEX_SAMPLES = 8


def _bezier_weights(s: np.ndarray) -> tuple:
    """Bernstein weights of the points (4) and of the tangents over 3 (3) at parameters ``s``, read-only.

    A point is ``k0 P0 + k1 P1 + k2 P2 + k3 P3``, a tangent ``3 (d0 (P1 - P0) + d1 (P2 - P1) + d2 (P3 - P2))``.
    """
    out = ((1 - s) ** 3, 3 * s * (1 - s) ** 2, 3 * s**2 * (1 - s), s**3, (1 - s) ** 2, 2 * s * (1 - s), s**2)
    for w in out:
        w.flags.writeable = False
    return out


def _sample_matrix(weights: tuple) -> np.ndarray:
    """The points and tangents at the parameters of ``weights`` (:func:`_bezier_weights`) as one matrix
    (4, 2 S), read-only.

    A coordinate ``x`` (M, 4) of Bezier segments times it gives their values (the first ``S``
    columns) and tangents (the last ``S``) at the parameters of ``weights`` in one product.
    """
    k0, k1, k2, k3, d0, d1, d2 = weights
    out = np.vstack([np.hstack([k0, -3 * d0]), np.hstack([k1, 3 * (d0 - d1)]), np.hstack([k2, 3 * (d1 - d2)]),
                     np.hstack([k3, 3 * d2])])
    out.flags.writeable = False
    return out


_APEX_MATRIX = _sample_matrix(_bezier_weights(np.arange(APEX_SAMPLES) / APEX_SAMPLES))

#: Rounds of added half-planes, and half-planes added per round, with which :func:`fan_apex`
#: tries to prove a kernel empty before it solves the whole linear programme.
APEX_ROUNDS = 6
APEX_ADDED = 24


def fan_apex(curve, hint) -> np.ndarray:
    """Apex of a flat cap's fan from which the closed curve is seen turning one way.

    A fan of straight lines from the apex to a curve covers the enclosed region
    once only when every tangent turns the same way seen from the apex (the apex
    lies in the curve's kernel). Otherwise the fan folds over itself: its
    volume stays exact (signed), but the area of the patches counts the fold
    twice and their normals flip there.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed planar Bezier curve.
    hint : array_like, shape (2,)
        Preferred apex x, y in mm (the contour's centre).

    Returns
    -------
    numpy.ndarray, shape (2,)
        ``hint`` when it sees the whole curve (at :data:`APEX_SAMPLES` points
        per segment), else the point deepest inside the kernel (a linear
        programme: the largest distance to every tangent line), else ``hint``
        (an outline with an empty kernel, such as a deep notch).
    """
    return _fan_apex(as_array(curve, "curve", shape=(None, 4, 3)), as_array(hint, "hint", shape=(2,)))


def _fan_apex(c: np.ndarray, p: np.ndarray) -> np.ndarray:
    """:func:`fan_apex` of a validated curve (M, 4, 3) and hint (2,) (a closed grid's own end curves)."""
    # x and y of the points and tangents at the samples, (M * APEX_SAMPLES,) each (segment-major): one
    # product for both coordinates
    sampled = c[:, :, :2].transpose(2, 0, 1) @ _APEX_MATRIX
    (qx, qy), (tx, ty) = (sampled[:, :, :APEX_SAMPLES].reshape(2, -1), sampled[:, :, APEX_SAMPLES:].reshape(2, -1))
    length = np.sqrt(tx * tx + ty * ty)
    keep = (length > 1e-12 * max(1.0, float(length.max(initial=0.0)))).nonzero()[0]
    if len(keep) < len(length):  # tangents that vanish (cusps, repeated points) say nothing
        qx, qy, length, tx, ty = qx[keep], qy[keep], length[keep], tx[keep], ty[keep]
    tx, ty = tx / length, ty / length
    orient = 1.0 if _curve_area(c) > 0 else -1.0
    # seen from p, the curve turns counter-clockwise (for a counter-clockwise curve) where
    # cross(q - p, t) > 0, i.e. a . p < b with a = (t_y, -t_x), b = cross(q, t); the half-planes
    # a are built only when p is not inside them all
    b = orient * (qx * ty - qy * tx)
    if (orient * (ty * p[0] - tx * p[1]) < b).all():
        return p
    a = np.empty((len(keep), 2))
    a[:, 0], a[:, 1] = orient * ty, orient * -tx
    extent = max(float(np.ptp(qx)), float(np.ptp(qy)))
    # fewer constraints allow a larger margin: where the tangents at the segments' starts (and the
    # few more that cutting planes add) leave no kernel by more than the solver's tolerance, the
    # whole programme has none and returns the hint; convex hulls decide that in a fraction of the
    # solver's set-up time (most outlines that reach this point, folded ones, have no kernel)
    if _no_kernel(a, b, keep % APEX_SAMPLES == 0, 1e-6 * max(1.0, extent, float(np.abs(b).max()))):
        return p
    from scipy.optimize import linprog  # most caps see their curve from the hint: scipy is loaded only here

    res = linprog([0.0, 0.0, -1.0], A_ub=np.hstack([a, np.ones((len(a), 1))]), b_ub=b,
                  bounds=[(None, None), (None, None), (None, extent)], method="highs")
    if res.status == 0 and res.x[2] > 0:
        return np.asarray(res.x[:2], dtype=np.float64)
    return p


def kernel_margin(normals, offsets) -> tuple[float, np.ndarray]:
    """Largest margin ``max_p min_i (offsets_i - normals_i . p)`` of half-planes ``normals_i . p <= offsets_i``.

    The value of :func:`fan_apex`'s linear programme without its bound on the
    margin: positive when the half-planes share a region (and the radius of
    the largest disc inside it), zero or negative when they do not. By linear
    programming duality it is the lower convex hull of the lifted points
    ``(normals_i, offsets_i)`` at the origin, taken from one convex hull
    (scipy.spatial, qhull) as the highest of the lower facets' planes there.

    Parameters
    ----------
    normals : array_like, shape (n, 2)
        Unit normals of the half-planes.
    offsets : array_like, shape (n,)
        Offsets in mm.

    Returns
    -------
    margin : float
        The margin in mm; ``inf`` when the margin is unbounded (the normals
        leave a half-circle of directions empty), fewer than 3 half-planes are
        given, or qhull cannot build the hull even from joggled input.
    point : numpy.ndarray, shape (2,)
        A point ``p`` where the margin is reached (NaN where it is ``inf``).

    Examples
    --------
    The box ``|x| <= 1, -2 <= y <= 1`` holds a disc of radius 1 about (0, -1); with ``x >= 3``
    instead of ``x >= -1`` its sides leave no room:

    >>> n = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    >>> margin, point = kernel_margin(n, [1.0, 1.0, 1.0, 2.0])
    >>> float(margin), point.tolist()
    (1.0, [0.0, -1.0])
    >>> float(kernel_margin(n, [1.0, -3.0, 1.0, 2.0])[0])
    -1.0
    """
    from scipy.spatial import ConvexHull, QhullError

    a = as_array(normals, "normals", shape=(None, 2))
    b = as_array(offsets, "offsets", shape=(len(a),))
    unknown = (float("inf"), np.full(2, np.nan))
    if len(a) < 3:
        return unknown
    angle = np.sort(np.arctan2(a[:, 1], a[:, 0]))
    if np.max(np.diff(np.append(angle, angle[0] + 2 * np.pi))) >= np.pi - 1e-9:
        return unknown
    lifted = np.column_stack([a, b])
    try:
        plane = ConvexHull(lifted).equations
    except QhullError:
        # lifted points in one plane (offsets affine in the normals, e.g. all equal): qhull's joggled
        # input moves them by ~1e-11 of their extent, far below the margins asked about
        try:
            plane = ConvexHull(lifted, qhull_options="QJ").equations
        except QhullError:
            return unknown
    lower = plane[plane[:, 2] < -1e-9]
    if not len(lower):
        return unknown
    # the facet plane z = c0 + c . n lies below every lifted point: offsets - normals . c >= c0
    best = lower[np.argmax(-lower[:, 3] / lower[:, 2])]
    return float(-best[3] / best[2]), -best[:2] / best[2]


def _no_kernel(a: np.ndarray, b: np.ndarray, start: np.ndarray, tol: float) -> bool:
    """Whether the half-planes ``a . p <= b`` surely leave no margin above ``-tol`` (cutting planes).

    Fewer half-planes allow a larger margin, so a subset whose margin is below ``-tol`` proves the
    whole set's. Starting from ``start`` (a mask), the half-planes the subset's best point violates
    most are added until the subset proves it, or its best point satisfies them all (then the
    subset's margin is the whole set's, and the answer is known to be no).
    """
    subset = np.flatnonzero(start)
    for _ in range(APEX_ROUNDS):
        margin, point = kernel_margin(a[subset], b[subset])
        if margin < -tol:
            return True
        if not np.isfinite(margin):
            # the subset's normals leave directions open (or qhull failed): all of them, once
            if len(subset) == len(a):
                return False
            subset = np.arange(len(a))
            continue
        slack = b - a @ point
        violated = np.flatnonzero(slack < margin - tol)
        if not len(violated):
            return False
        worst = violated[np.argsort(slack[violated])[:APEX_ADDED]]
        subset = np.union1d(subset, worst)
    return False


def _fan_points(curve: np.ndarray, center: np.ndarray, toward_center: bool) -> np.ndarray:
    """Control points (M, 4, 4, 3) of :func:`fan_column`: ``center + w_b (curve_a - center)``.

    One product with the weights of the four ``b`` laid out per coordinate (each output is a single
    weighted value: the same rounding as the product itself), then the centre added.
    """
    rows = (curve - center).reshape(-1, 3) @ _FAN_MATRIX[bool(toward_center)]
    rows.reshape(-1, 4, 3)[...] += center  # broadcast over the four b (np.tile's copy costs more)
    return rows.reshape(len(curve), 4, 4, 3)


def _prism_points(curve: np.ndarray, height: float) -> np.ndarray:
    """Control points (M, 4, 4, 3) of :func:`prism_column`: the curve repeated for the four ``b``, z raised."""
    rows = curve.reshape(-1, 3) @ _FAN_MATRIX[2]
    rows[:, 2::3] += height * (1.0 - _FAN_WEIGHTS) if height < 0 else height * _FAN_WEIGHTS
    return rows.reshape(len(curve), 4, 4, 3)


#: ``v`` of the control points of a fan or prism column (bilinear in ``v``).
_FAN_WEIGHTS = np.arange(4) / 3.0
_FAN_WEIGHTS.flags.writeable = False

#: (3, 12) matrices taking a point's x, y, z to the four ``b`` of a control-point row: weighted from the
#: apex to the curve (:func:`_fan_points`), from the curve to the apex, and repeated (:func:`_prism_points`).
_FAN_MATRIX = tuple(np.kron(w[None, :], np.eye(3)) for w in (_FAN_WEIGHTS, _FAN_WEIGHTS[::-1], np.ones(4)))
for _m in _FAN_MATRIX:
    _m.flags.writeable = False


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
    return _fan_points(c, p, toward_center)[:, None]


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
    return _prism_points(c, float(height))[:, None]


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


#: Curvature of a sphere's section area, d^2 A / dz^2 (mm^2 per mm^2): the prior of one- and two-plane ends.
SPHERE_CURVATURE = -2.0 * np.pi


def trend_profile(areas, spacing: float) -> tuple[float, float, float] | None:
    """The section area beyond an end plane, ``A(t) = a0 + a1 t + a2 t^2``, from the last planes' areas.

    ``t`` is the distance beyond the end plane (mm). Three or more planes: the
    quadratic through the last three areas; two planes: the line through them
    bent by a sphere's curvature (:data:`SPHERE_CURVATURE`); one plane: a sphere
    whose equator is the contour (``a1 = 0``). Exact for spheres and ellipsoids
    (their section areas are quadratic in z) at any plane offset.

    Parameters
    ----------
    areas : array_like, shape (K,)
        Areas (mm^2) of the end plane first, then the planes inward (K >= 1; only
        the first three are used).
    spacing : float
        Plane spacing (mm).

    Returns
    -------
    (a0, a1, a2) or None
        The coefficients, or None when the area does not vanish within one
        spacing (the structure is cut off between this plane and the next:
        :func:`trend_cap_volume` then counts the half cap).

    Examples
    --------
    A sphere of radius 5 mm cut at z = 4, 2 and 0 mm (end plane at 4): it closes 1 mm beyond.

    >>> a = [np.pi * (25 - z * z) for z in (4.0, 2.0, 0.0)]
    >>> c = trend_profile(a, 2.0)
    >>> round(c[0] / np.pi, 9), round(c[1] / np.pi, 9), round(c[2] / np.pi, 9), round(trend_height(c), 9)
    (9.0, -8.0, -1.0, 1.0)
    >>> trend_profile([100.0, 100.0, 100.0], 1.0) is None  # a cylinder: cut off
    True
    """
    a = np.abs(np.asarray(areas, dtype=np.float64).ravel())
    d = positive(spacing, "spacing")
    if len(a) == 0 or a[0] <= 0:
        return None
    if len(a) >= 3:
        # through (0, a0), (-d, a1), (-2d, a2)
        c2 = (a[0] - 2 * a[1] + a[2]) / (2 * d * d)
        c1 = (a[0] - a[1]) / d + c2 * d
    elif len(a) == 2:
        c2 = SPHERE_CURVATURE / 2
        c1 = (a[0] - a[1]) / d + c2 * d
    else:
        c2, c1 = SPHERE_CURVATURE / 2, 0.0
    r = _first_root(a[0], c1, c2)
    if r is None or r > d:
        return None
    return float(a[0]), float(c1), float(c2)


def _first_root(c0: float, c1: float, c2: float) -> float | None:
    """The smallest t > 0 with c0 + c1 t + c2 t^2 = 0 (c0 > 0), None when there is none."""
    if abs(c2) < 1e-12 * max(abs(c1), c0, 1e-300):
        return -c0 / c1 if c1 < 0 else None
    disc = c1 * c1 - 4 * c2 * c0
    if disc < 0:
        return None
    q = np.sqrt(disc)
    roots = [t for t in ((-c1 - q) / (2 * c2), (-c1 + q) / (2 * c2)) if t > 0]
    return float(min(roots)) if roots else None


def trend_height(profile) -> float:
    """Where the trend's area vanishes (mm beyond the end plane).

    Parameters
    ----------
    profile : (float, float, float)
        :func:`trend_profile`'s coefficients.

    Returns
    -------
    float
    """
    return float(_first_root(*profile))


def trend_cap_volume(areas, spacing: float) -> float:
    """Volume beyond an end plane under the trend model (mm^3).

    Parameters
    ----------
    areas : array_like, shape (K,)
        Areas of the end plane first, then inward (:func:`trend_profile`).
    spacing : float
        Plane spacing (mm).

    Returns
    -------
    float
        ``integral_0^r A(t) dt`` up to the trend's closing height ``r``; the
        half cap (end area x half a spacing) where the trend does not close
        within one spacing.

    Examples
    --------
    >>> a = [np.pi * (25 - z * z) for z in (4.0, 2.0, 0.0)]  # sphere of radius 5: cap of height 1 mm
    >>> round(trend_cap_volume(a, 2.0) / np.pi, 9)  # pi h^2 (3 R - h) / 3
    4.666666667
    """
    prof = trend_profile(areas, spacing)
    if prof is None:
        return float(abs(np.asarray(areas, float).ravel()[0]) * positive(spacing, "spacing") / 2)
    r = trend_height(prof)
    return float(prof[0] * r + prof[1] * r * r / 2 + prof[2] * r**3 / 3)


#: Rings of a trend cap (:func:`trend_rings`): virtual slices between the end plane and the apex.
TREND_RINGS = 4


def curve_centroid(curve) -> np.ndarray:
    """Centroid (x, y) of the polygon through a closed planar Bezier curve's segment ends (mm).

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed planar Bezier curve.

    Returns
    -------
    numpy.ndarray, shape (2,)
        The polygon's area centroid; the mean of its points when its area vanishes.
    """
    return _curve_centroid(as_array(curve, "curve", shape=(None, 4, 3)))


def _curve_centroid(c: np.ndarray) -> np.ndarray:
    """:func:`curve_centroid` of a validated curve."""
    x, y = c[:, 0, 0], c[:, 0, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = cross.sum() / 2
    if abs(a) <= 1e-12 * max(1.0, float(np.abs(cross).sum())):
        return np.array([x.mean(), y.mean()])
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6 * a)


def trend_rings(curves, spacing: float, upward: bool, n_rings: int = TREND_RINGS) -> np.ndarray | None:
    """Virtual slice curves of a trend cap: the end curve scaled so that each ring's area follows the trend.

    Ring ``k`` (``k = 1 .. n``) is the end curve scaled about its centroid (moved
    into the curve's kernel, :func:`fan_apex`) by ``s_k = cos(k pi / (2 n))`` at the
    height ``t_k`` beyond the end plane where the trend's area
    (:func:`trend_profile`) is ``s_k^2`` times the end area; the last ring is the
    apex, where the trend's area vanishes. The surface blended through them
    encloses (to the blend's accuracy) the trend's volume beyond the end plane
    (:func:`trend_cap_volume`), and follows its shape instead of a flat-topped prism.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        The end curve first, then the curves inward (K >= 1; the first three are used).
    spacing : float
        Plane spacing (mm).
    upward : bool
        The cap lies above the end curve (a body's high end) or below it.
    n_rings : int
        Number of rings.

    Returns
    -------
    numpy.ndarray, shape (n_rings, M, 4, 3) or None
        Rings from the one next to the end curve to the apex; None where the trend
        does not close within one spacing, or where no point sees the whole end
        curve (no kernel: scaled copies would fold); the end then gets a prism of
        the trend's volume (:func:`resolve_trend`).
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    return _trend_rings(c[:3], positive(spacing, "spacing"), upward, int(n_rings))


def _sees_all(c: np.ndarray, p: np.ndarray) -> bool:
    """Whether the point ``p`` (2,) sees the whole closed curve (M, 4, 3) turning one way (it lies in the
    curve's kernel, tested at :data:`APEX_SAMPLES` points per segment as :func:`fan_apex` tests it)."""
    sampled = c[:, :, :2].transpose(2, 0, 1) @ _APEX_MATRIX
    (qx, qy), (tx, ty) = (sampled[:, :, :APEX_SAMPLES].reshape(2, -1), sampled[:, :, APEX_SAMPLES:].reshape(2, -1))
    length = np.sqrt(tx * tx + ty * ty)
    keep = length > 1e-12 * max(1.0, float(length.max(initial=0.0)))
    orient = 1.0 if _curve_area(c) > 0 else -1.0
    cross = orient * ((qx - p[0]) * ty - (qy - p[1]) * tx)
    return bool((cross[keep] > 0).all())


def _trend_rings(c: np.ndarray, d: float, upward: bool, n_rings: int) -> np.ndarray | None:
    """:func:`trend_rings` of validated curves (end first); None also where no point sees the whole end curve
    (scaled copies of it would fold: the end gets the prism)."""
    areas = [abs(_curve_area(x)) for x in c[:3]]
    prof = trend_profile(areas, d)
    if prof is None or n_rings < 1:
        return None
    a0, c1, c2 = prof
    end = c[0]
    p2 = _fan_apex(end, _curve_centroid(end))
    if not _sees_all(end, p2):
        return None
    p = np.array([p2[0], p2[1], end[0, 0, 2]])
    s = np.cos(np.arange(1, n_rings + 1) * np.pi / (2 * n_rings))
    s[-1] = 0.0
    t = np.empty(n_rings)
    for k in range(n_rings):
        root = _first_root(a0 * (1.0 - s[k] * s[k]), c1, c2)
        t[k] = trend_height(prof) if root is None else root
    t = np.maximum.accumulate(t)  # rounding: never below the previous ring
    rings = p + s[:, None, None, None] * (end[None] - p)
    rings[..., 2] = end[0, 0, 2] + (1.0 if upward else -1.0) * t[:, None, None]
    rings[-1] = p
    rings[-1, ..., 2] = end[0, 0, 2] + (1.0 if upward else -1.0) * t[-1]
    return rings


def mid_ring(lower, upper) -> np.ndarray:
    """A virtual slice half-way between two slice curves whose area follows a sphere's curvature.

    The mean of the two curves (on their common lattice), scaled about its centroid so that
    its area is ``(A0 + A1) / 2 - c h^2 / 8`` with ``c`` = :data:`SPHERE_CURVATURE`: the
    parabola :mod:`slices.volume` integrates between the planes of a two-plane structure.
    Blended through it, the side bulges as that parabola does instead of running straight.

    Parameters
    ----------
    lower, upper : array_like, shape (M, 4, 3)
        The two slice curves (lower first).

    Returns
    -------
    numpy.ndarray, shape (M, 4, 3)
    """
    a = as_array(lower, "lower", shape=(None, 4, 3))
    b = as_array(upper, "upper", shape=a.shape)
    return _mid_ring(a, b)


def _mid_ring(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`mid_ring` of validated curves."""
    mid = (a + b) / 2
    h = float(b[0, 0, 2] - a[0, 0, 2])
    target = (abs(_curve_area(a)) + abs(_curve_area(b))) / 2 - SPHERE_CURVATURE * h * h / 8
    area = abs(_curve_area(mid))
    if area <= 0 or target <= 0:
        return mid
    p = np.append(_fan_apex(mid, _curve_centroid(mid)), mid[0, 0, 2])
    return p + np.sqrt(target / area) * (mid - p)


def add_cap_rings(curves, centers, spacing: float, low: str, high: str) -> tuple[np.ndarray, int, int, str, str]:
    """The slice curves with the rings of dome and trend caps added below and above.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        Slice curves on a common lattice.
    centers : array_like, shape (K, 3)
        Centre of each slice (mm, in its plane).
    spacing : float
        Plane spacing (mm); dome caps are half of it high.
    low, high : str
        Cap kinds of the two ends (:func:`end_kinds`).

    Returns
    -------
    stack : numpy.ndarray, shape (K', M, 4, 3)
        Rings of the low cap (apex first), the curves, rings of the high cap.
    prepend, append : int
        Rings below the first and above the last slice curve.
    low_shape, high_shape : str
        The shape each end is built with: ``"dome"`` for an end closed by rings (a dome,
        or a trend cap that closes within one spacing, :func:`trend_rings`), else its kind
        (a trend cap that does not close, and those of a single contour, are prisms).
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    p = as_array(centers, "centers", shape=(len(c), 3))
    stack, prepend, append, lo, hi = _add_cap_rings(c, p, positive(spacing, "spacing"), low, high)
    return (stack.copy() if stack is c else stack), prepend, append, lo, hi


def _add_cap_rings(c: np.ndarray, p: np.ndarray, d: float, low: str, high: str) -> tuple[np.ndarray, int, int, str,
                                                                                         str]:
    """:func:`add_cap_rings` of validated inputs; the curves themselves when no end has rings."""
    parts, shapes = [], []
    for end, kind in enumerate((low, high)):
        rings = None
        if kind == "dome":
            rings = dome_rings(c[0] if end == 0 else c[-1], p[0] if end == 0 else p[-1], d / 2, upward=end == 1)
        elif kind == "trend" and len(c) >= 2:  # a single contour keeps its prisms (the slab it is reported as)
            rings = _trend_rings(c[:3] if end == 0 else c[::-1][:3], d, upward=end == 1, n_rings=TREND_RINGS)
        parts.append(rings)
        shapes.append("dome" if rings is not None else kind)
    if parts[0] is None and parts[1] is None:
        return c, 0, 0, shapes[0], shapes[1]
    empty = np.zeros((0,) + c.shape[1:])
    low_rings = empty if parts[0] is None else parts[0][::-1]
    high_rings = empty if parts[1] is None else parts[1]
    return (np.concatenate([low_rings, c, high_rings]), len(low_rings), len(high_rings), shapes[0], shapes[1])


def resolve_trend(curves, spacing: float, low: str, high: str) -> tuple[float, float]:
    """Extrusion heights of a body's ends: a trend cap's volume as a prism over the end curve.

    A ``"trend"`` end is extruded (as a half cap is) by ``V / A``: the trend's
    volume beyond the end plane (:func:`trend_cap_volume`) over the end curve's
    area, so the written surface encloses the trend's volume; at most one
    spacing. Other ends keep half a spacing (used by half caps only).

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        The body's slice curves, lowest first.
    spacing : float
        Plane spacing (mm).
    low, high : str
        Cap kinds from :func:`end_kinds`.

    Returns
    -------
    (float, float)
        Heights in mm of the low and the high end's extrusion.
    """
    d = positive(spacing, "spacing")
    heights = [d / 2, d / 2]
    for end, kind in enumerate((low, high)):
        if kind != "trend":
            continue
        c = curves[:3] if end == 0 else curves[::-1][:3]
        areas = [abs(_curve_area(x)) for x in c]
        if areas[0] > 0:
            heights[end] = float(min(trend_cap_volume(areas, d) / areas[0], d))
    return heights[0], heights[1]


#: ``H`` of :func:`curve_area`: the area ``1/2 integral (x y' - y x')`` of one cubic Bezier segment is
#: ``x^T H y`` for the x and y (4,) of its control points (one matrix product for every segment, instead
#: of the quadrature's sixteen small products).
_AREA_FORM = np.array([[0.0, 6.0, 3.0, 1.0], [-6.0, 0.0, 3.0, 3.0], [-3.0, -3.0, 0.0, 6.0],
                       [-1.0, -3.0, -6.0, 0.0]]) / 20.0
_AREA_FORM.flags.writeable = False


def curve_area(curve) -> float:
    """Signed area enclosed by a closed planar Bezier curve (Green's theorem).

    ``A = 1/2 * integral (x y' - y x') du``, a degree-5 polynomial per
    segment whose integral is a bilinear form of the segment's control points,
    ``x^T H y`` (:data:`_AREA_FORM`, exact).

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed Bezier curve; the area is taken in the x-y plane.

    Returns
    -------
    float
        mm^2, positive for a counter-clockwise curve seen from +z.
    """
    return _curve_area(as_array(curve, "curve", shape=(None, 4, 3)))


def _curve_area(c: np.ndarray) -> float:
    """:func:`curve_area` of a validated curve (M, 4, 3) (one built from checked ones)."""
    return float(((c[:, :, 0] @ _AREA_FORM) * c[:, :, 1]).sum())


#: Width of the flat band round a flat cap's inner ring, as a fraction of the median boundary edge.
CAP_INSET = 0.05


def _following(x: np.ndarray) -> np.ndarray:
    """The rows of a closed ring starting at the second: ``np.roll(x, -1, axis=0)`` in one call."""
    return np.concatenate((x[1:], x[:1]))


def _previous(x: np.ndarray) -> np.ndarray:
    """The rows of a closed ring starting at the last: ``np.roll(x, 1, axis=0)`` in one call."""
    return np.concatenate((x[-1:], x[:-1]))


def _lengths(v: np.ndarray) -> np.ndarray:
    """Lengths of 2D vectors (N, 2), as ``np.linalg.norm(v, axis=1)`` (the same sum of squares)."""
    return np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1])


#: Turns ``(y, x)`` into the left normal ``(-y, x)`` of ``(x, y)``.
_LEFT = np.array([-1.0, 1.0])
_LEFT.flags.writeable = False


@lru_cache(maxsize=64)
def _fan(n: int) -> np.ndarray:
    """Triangles ``(n, i, i + 1)`` of a fan from an extra vertex ``n`` round a ring of ``n`` (read-only)."""
    i = np.arange(n)
    out = np.stack([np.full(n, n), i, (i + 1) % n], axis=1)
    out.flags.writeable = False
    return out


@lru_cache(maxsize=64)
def _banded_fan(n: int) -> np.ndarray:
    """:func:`_strip` of ``n`` and the fan of :func:`_fan` over the inner ring (its centre ``2 n``), read-only."""
    out = np.concatenate([_strip(n), _fan(n) + n])
    out.flags.writeable = False
    return out


@lru_cache(maxsize=64)
def _strip(n: int) -> np.ndarray:
    """Triangles of the band between a ring of ``n`` and the inner ring ``n .. 2n - 1`` (read-only)."""
    i = np.arange(n)
    out = np.concatenate([np.stack([i, (i + 1) % n, n + (i + 1) % n], 1), np.stack([i, n + (i + 1) % n, n + i], 1)])
    out.flags.writeable = False
    return out


def _triangulate_ccw(xy: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Triangles of a counter-clockwise simple polygon, counter-clockwise, shape (T, 3).

    A fan from an extra vertex ``len(xy)`` at the vertex mean ``mean`` (``xy.sum(axis=0) / len(xy)``,
    which the caller keeps for that vertex) when the outline is star-shaped about it (then the last
    returned row of points is needed: see :func:`_cap_polygon`), else a constrained triangulation (manifold3d).
    """
    import manifold3d

    rel = xy - mean
    ang = np.arctan2(rel[:, 1], rel[:, 0])
    turn = (ang - _previous(ang) + np.pi) % (2 * np.pi) - np.pi
    if (turn > 0).all() and turn.sum() > np.pi:
        return _fan(len(xy))
    return np.asarray(manifold3d.triangulate([xy]), dtype=np.int64).reshape(-1, 3)


def _signed_areas(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Twice the signed area of every triangle of a planar mesh, shape (T,)."""
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    e1, e2 = b - a, c - a
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def _inset_directions(step: np.ndarray, edge: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mitre directions of a counter-clockwise ring and their lengths' floors, for :func:`_inset_ring`.

    ``step`` (N, 2) are the ring's edges (from each point to the next) and ``edge`` (N,) their lengths.
    Point ``i`` moves inward along ``direction[i]`` by ``distance / scale[i]`` (mitred, the mitre
    limited to 4x); the same for every distance tried.
    """
    t_out = step / np.maximum(edge, 1e-300)[:, None]
    t_in = _previous(t_out)
    # inward (left) normals of the incoming and outgoing edges
    n_in, n_out = t_in[:, ::-1] * _LEFT, t_out[:, ::-1] * _LEFT
    bis = n_in + n_out
    half = _lengths(bis) / 2
    direction = np.where(half[:, None] > 1e-9, bis / np.maximum(2 * half, 1e-300)[:, None], n_out)
    return direction, np.maximum(half, 0.25)


def _inset_ring(xy: np.ndarray, distance: float, mitre: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """A counter-clockwise ring moved inward by ``distance`` along its mitres (:func:`_inset_directions`)."""
    direction, scale = mitre
    return xy + direction * (distance / scale)[:, None]


def _median(x: np.ndarray) -> float:
    """``np.median`` of an array's values (the mean of the two middle ones for an even count), by one partition."""
    x = x.ravel()
    half = len(x) // 2
    part = np.partition(x, half)
    if len(x) % 2:
        return float(part[half])
    # the sorted value before the middle one: the largest of those the partition puts before it
    return float((part[:half].max() + part[half]) / 2.0)


def _cap_polygon(xy: np.ndarray, inset: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Points and counter-clockwise triangles of a flat cap over a counter-clockwise ring.

    The ring's own points come first (``n``), then an inner ring moved inward
    by :data:`CAP_INSET` of the median edge and any fan centre. The inner ring
    is what makes the written mesh shade flat: every boundary vertex is shared
    with the side surface and carries its normal, so a cap made of boundary
    vertices only interpolates the side's normals over the whole cap; the
    inner ring carries the cap's own normal, and the band of side normals is
    a twentieth of an edge wide. Where the inset is not a valid polygon
    (outlines narrower than the band) the band is halved, and at last left out.
    """
    n = len(xy)
    following = _following(xy)
    step = following - xy
    edge = _lengths(step)
    # the fan from the mean: the outline's area (sum over count: numpy's mean, without its wrappers)
    mean = xy.sum(axis=0) / n
    d0, d1 = xy - mean, following - mean
    total = 0.5 * float((d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]).sum())
    distance = CAP_INSET * _median(edge) if inset else 0.0
    smallest = 1e-9 * max(1.0, float(np.abs(xy).max()))
    mitre = _inset_directions(step, edge) if distance > smallest else None
    for _ in range(4):
        if distance <= smallest:
            break
        inner = _inset_ring(xy, distance, mitre)
        inner_mean = inner.sum(axis=0) / n
        tri = _triangulate_ccw(inner, inner_mean)
        if tri.max(initial=0) >= n:  # the fan from the inner ring's mean
            pts, tri = np.vstack([xy, inner, inner_mean[None]]), _banded_fan(n)
        else:
            pts, tri = np.vstack([xy, inner]), np.concatenate([_strip(n), tri + n])
        s = _signed_areas(pts, tri)
        # a valid inset: no triangle turned over and no overlap (the areas add up to the outline's)
        if (s > 0).all() and abs(0.5 * float(s.sum()) - total) <= 1e-9 * abs(total) + 1e-12:
            return pts, tri
        distance /= 2
    tri = _triangulate_ccw(xy, mean)
    return (np.vstack([xy, xy.mean(axis=0)[None]]) if tri.max(initial=0) >= n else xy), tri


def planar_cap_mesh(curve, samples: int, outward_z: float, inset: bool = True) -> TriangleMesh:
    """Triangles of a flat cap whose boundary matches a tessellated surface edge.

    Parameters
    ----------
    curve : array_like, shape (M, 4, 3)
        Closed planar boundary curve (counter-clockwise seen from +z).
    samples : int
        Points per Bezier segment, as used by :func:`surfaces.mesh.tessellate`.
    outward_z : float
        +1 for a top cap (normal +z), -1 for a bottom cap.
    inset : bool
        Add the inner ring (False: boundary vertices and any fan centre only).

    Returns
    -------
    TriangleMesh
        Boundary vertices first, at ``u = j + a / samples`` (the tessellation's),
        then a ring just inside them (a band of :data:`CAP_INSET` of an edge) and
        the inside: a fan from one centre vertex when the inner ring is
        star-shaped about its vertex mean, else a constrained triangulation.
        Every vertex normal is ``(0, 0, outward_z)``; once the boundary is welded
        to the side (:func:`weld_flat_caps`) the inner ring keeps the cap's normal.
    """
    return _planar_cap_mesh(as_array(curve, "curve", shape=(None, 4, 3)), samples, outward_z, inset)


def _planar_cap_mesh(c: np.ndarray, samples: int, outward_z: float, inset: bool = True) -> TriangleMesh:
    """:func:`planar_cap_mesh` of a validated curve (M, 4, 3) (a closed grid's own flat cap)."""
    ring = (c.reshape(len(c), 12) @ _ring_matrix(int(samples))).reshape(-1, 3)
    xy = ring[:, :2]
    n = len(xy)
    following = _following(xy)
    area = 0.5 * float(np.dot(xy[:, 0], following[:, 1]) - np.dot(xy[:, 1], following[:, 0]))
    # work on a counter-clockwise copy; the boundary vertices keep the curve's order
    if area > 0:
        pts, tri = _cap_polygon(np.ascontiguousarray(xy), inset)
        tri = np.array(tri)  # the cap's own (the fan's triangles are kept read-only)
        vertices = np.empty((len(pts), 3))
        vertices[:, :2] = pts
    else:
        order = np.arange(n)[::-1]
        pts, tri = _cap_polygon(xy[order], inset)
        index = np.concatenate([order, np.arange(n, len(pts))])
        tri = index[tri]
        vertices = np.empty((len(pts), 3))
        vertices[index, :2] = pts
    if len(tri) == 0:
        raise InputError("cap: the end contour could not be triangulated")
    vertices[:, 2] = ring[0, 2]
    vertices[:n] = ring
    # every triangle is counter-clockwise seen from +z: one flip for a bottom cap
    if outward_z < 0:
        tri = tri[:, ::-1].copy()
    normal = np.zeros_like(vertices)
    normal[:, 2] = 1.0 if outward_z > 0 else -1.0
    # from a checked curve: finite points, the triangles of its own ring
    return TriangleMesh.unchecked(vertices, tri, normal)


@lru_cache(maxsize=16)
def _ring_matrix(samples: int) -> np.ndarray:
    """(12, 3 S): a Bezier segment's control points (4, 3) flattened to its ``S`` points at ``u = a / S``, read-only.

    The Bernstein weights of :func:`_bezier_weights` laid out per coordinate: one product for a whole
    curve's boundary samples.
    """
    k = np.stack(_bezier_weights(np.arange(samples) / samples)[:4])  # (4, S)
    out = np.einsum("ks,xy->kxsy", k, np.eye(3)).reshape(12, 3 * samples)
    out.flags.writeable = False
    return out


def end_kinds(caps: str, start: str, stop: str, n_contours: int = 2) -> tuple[str, str]:
    """Cap of the low and the high end of a body.

    Parameters
    ----------
    caps : {"none", "flat", "half", "dome", "trend"}
        The requested caps.
    start, stop : str
        Why the body's chain starts and stops (:class:`slices.chaining.Body`):
        ``"end"``, ``"branch"``, ``"merge"``, ``"split"`` or ``"step"`` (a stepped slab, half caps).
    n_contours : int
        Contours in the body. A single contour has no thickness with none/flat
        caps; it gets half caps there instead (the slab of one spacing that
        planning systems count), so no body is dropped and holes are always
        subtracted.

    Returns
    -------
    (str, str)
        The requested caps at a true end; ``"half"`` where the chain splits
        without a split contour (branching or merging contours), so
        neighbouring bodies meet half-way between the planes; ``"flat"`` at a
        split joint (the parts of a split contour and the contour itself meet in
        one plane, and the union removes the coincident caps). A single contour
        with a flat joint at one end gets a half cap at its other end where the
        requested cap would leave it without thickness.

    Examples
    --------
    >>> end_kinds("flat", "end", "branch")
    ('flat', 'half')
    >>> end_kinds("flat", "end", "end", n_contours=1)
    ('half', 'half')
    >>> end_kinds("dome", "split", "end"), end_kinds("none", "end", "split", n_contours=1)
    (('flat', 'dome'), ('half', 'flat'))
    """
    if caps not in CAP_KINDS:
        raise InputError(f"caps: must be one of {CAP_KINDS}, got {caps!r}")

    def kind(why: str) -> str:
        return caps if why == "end" else ("flat" if why == "split" else "half")

    low, high = kind(start), kind(stop)
    if int(n_contours) == 1 and low in ("none", "flat") and high in ("none", "flat"):
        if "split" in (start, stop) and start != stop:
            return ("flat", "half") if start == "split" else ("half", "flat")
        return "half", "half"
    return low, high


def add_dome_rings(curves, centers, height: float, low: str, high: str) -> tuple[np.ndarray, int]:
    """The slice curves with the rings of dome caps added below and above.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        Slice curves on a common lattice.
    centers : array_like, shape (K, 3)
        Centre of each slice (mm, in its plane).
    height : float
        Dome height in mm (half a slice spacing).
    low, high : str
        Cap kinds of the two ends (:func:`end_kinds`); only ``"dome"`` adds rings.

    Returns
    -------
    stack : numpy.ndarray, shape (K', M, 4, 3)
        Rings of the low dome (pole first), the curves, rings of the high dome.
    prepend : int
        Number of rings below the first slice curve.
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    stack, prepend = _add_dome_rings(c, as_array(centers, "centers", shape=(len(c), 3)), height, low, high)
    return (stack.copy() if stack is c else stack), prepend


def _add_dome_rings(c: np.ndarray, p: np.ndarray, height: float, low: str, high: str) -> tuple[np.ndarray, int]:
    """:func:`add_dome_rings` of validated curves (K, M, 4, 3) and centres (K, 3); the curves themselves,
    not a copy, when neither end is a dome (the callers only read the stack)."""
    if low != "dome" and high != "dome":
        return c, 0
    low_rings = high_rings = np.zeros((0,) + c.shape[1:])
    if low == "dome":
        low_rings = dome_rings(c[0], p[0], height, upward=False)[::-1]
    if high == "dome":
        high_rings = dome_rings(c[-1], p[-1], height, upward=True)
    return np.concatenate([low_rings, c, high_rings]), len(low_rings)


@dataclass(frozen=True)
class CappedGrid:
    """A body's patch grid: side columns closed by cap columns.

    Attributes
    ----------
    control : numpy.ndarray, shape (M, C, 4, 4, 3)
        Control points of the closed grid (fan columns of flat caps first and
        last; with ``caps="none"`` they are there too, so the grid encloses the
        volume between the end planes).
    side_columns : slice
        Patch columns of the open side surface (with half-cap extrusions and domes).
    flat_caps : tuple of (numpy.ndarray, float)
        Boundary curve ``(M, 4, 3)`` and outward z (+1 top, -1 bottom) of every
        flat cap that is part of the surface (not those of ``caps="none"``).
    end_planes : (float, float)
        z of the lowest and highest side boundary in mm (where caps can meet the side).
    extrusions : (float, float)
        Heights in mm of the half caps' extrusions (:func:`prism_column`) at the low and the
        high end, 0 where there is none; they are the first and the last of ``side_columns``.
    """

    control: np.ndarray
    side_columns: slice
    flat_caps: tuple
    end_planes: tuple[float, float]
    extrusions: tuple[float, float] = (0.0, 0.0)

    @property
    def flat_cap_area(self) -> float:
        """Area of the flat caps in mm^2 (:func:`curve_area`)."""
        return float(sum(abs(_curve_area(c)) for c, _ in self.flat_caps))


def close_side(side, bottom, top, low_center, high_center, height: float, low: str, high: str) -> CappedGrid:
    """Close a side surface with its caps.

    Parameters
    ----------
    side : array_like, shape (M, S, 4, 4, 3) or None
        Side patch columns; None for a single slice (no side surface).
    bottom, top : array_like, shape (M, 4, 3)
        The side's lowest and highest boundary curves (the single slice curve
        when ``side`` is None).
    low_center, high_center : array_like, shape (2,)
        x, y of the preferred fan apex of the low and the high cap (mm); moved
        into the end curve's kernel where the fan would fold (:func:`fan_apex`).
    height : float or (float, float)
        Extrusion of half and trend caps in mm (half a slice spacing; per end as
        (low, high) from :func:`resolve_trend`).
    low, high : str
        Cap kinds of the two ends (:func:`end_kinds`).

    Returns
    -------
    CappedGrid
    """
    bottom = as_array(bottom, "bottom", shape=(None, 4, 3))
    top = as_array(top, "top", shape=bottom.shape)
    low_center = as_array(low_center, "low_center", shape=(2,))
    high_center = as_array(high_center, "high_center", shape=(2,))
    n_mid = 0
    if side is not None:
        side = as_array(side, "side", shape=(len(bottom), None, 4, 4, 3))
        n_mid = side.shape[1]
    if not n_mid and low not in PRISM_KINDS and high not in PRISM_KINDS:
        raise InputError("side: a single slice has no side surface; it needs a half cap at one end at least")
    # every column (fans, extrusions, side) written into the grid in place: the side is copied once
    control, mid = _grid_buffer(len(bottom), n_mid, low, high)
    if side is not None:
        control[:, mid] = side
    return _close_grid(control, bottom, top, low_center, high_center, height, low, high)


def _grid_buffer(m: int, n_mid: int, low: str, high: str) -> tuple[np.ndarray, slice]:
    """An unwritten capped grid (M, C, 4, 4, 3) for ``n_mid`` side columns, and the slice of those columns.

    The side surface written into those columns (:func:`slices.surface.side_surface`'s blend can), then
    :func:`_close_grid` fills the caps' columns around it: the side's points are written once.
    """
    first = int(low != "dome") + (low in PRISM_KINDS)
    return (np.empty((m, first + n_mid + (high in PRISM_KINDS) + (high != "dome"), 4, 4, 3)),
            slice(first, first + n_mid))


def _close_grid(control: np.ndarray, bottom: np.ndarray, top: np.ndarray, low_center, high_center, height: float,
                low: str, high: str) -> CappedGrid:
    """:func:`close_side` on a :func:`_grid_buffer` whose side columns hold the side (validated inputs)."""
    first = int(low != "dome")
    stop = control.shape[1] - (high != "dome")
    h_low, h_high = (float(height), float(height)) if np.ndim(height) == 0 else (float(height[0]), float(height[1]))
    if low in PRISM_KINDS:
        control[:, first] = _prism_points(bottom, -h_low)
        bottom = control[:, first, :, 0]  # the curve lowered by the height, as the extrusion's own edge
    if high in PRISM_KINDS:
        control[:, stop - 1] = _prism_points(top, h_high)
        top = control[:, stop - 1, :, 3]
    flat = []
    if low != "dome":
        control[:, 0] = _fan_points(bottom, np.concatenate((_fan_apex(bottom, low_center), bottom[0, 0, 2:])), False)
        if low != "none":
            flat.append((bottom, -1.0))
    if high != "dome":
        control[:, stop] = _fan_points(top, np.concatenate((_fan_apex(top, high_center), top[0, 0, 2:])), True)
        if high != "none":
            flat.append((top, 1.0))
    return CappedGrid(control, slice(first, stop), tuple(flat), (float(bottom[0, 0, 2]), float(top[0, 0, 2])),
                      (h_low if low in PRISM_KINDS else 0.0, h_high if high in PRISM_KINDS else 0.0))


@lru_cache(maxsize=8)
def _gauss_tangents(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Weights (4, order) of a cubic Bezier segment's control values for its tangent at the ``order``
    Gauss nodes of [0, 1] (``3 (d0 (P1 - P0) + d1 (P2 - P1) + d2 (P3 - P2))``), and the nodes' weights,
    read-only."""
    at_nodes, weights = _gauss_bezier(order)
    tangent = np.ascontiguousarray(_sample_matrix(at_nodes)[:, order:])
    tangent.flags.writeable = False
    return tangent, weights


@lru_cache(maxsize=8)
def _gauss_bezier(order: int) -> tuple[tuple, np.ndarray]:
    """Bernstein weights (:func:`_bezier_weights`) at the ``order`` Gauss nodes of [0, 1], and the nodes' weights
    (the patch quadrature's own rule, :func:`surfaces.measure.gauss_legendre`)."""
    from surfaces.measure import gauss_legendre

    nodes, weights = gauss_legendre(order)
    return _bezier_weights(nodes), weights


def grid_integrals(grid: CappedGrid, order: int = 5) -> tuple[float, float]:
    """Enclosed volume and area of a capped grid, with quadrature on the blended side columns only.

    The sums of :func:`surfaces.measure.integrals` over the whole grid (volume) and over
    ``side_columns`` plus :attr:`CappedGrid.flat_cap_area` (area), the same up to rounding: the volume
    is the flux of ``(0, 0, z)`` through the closed grid (:func:`surfaces.measure.side_integrals`),
    whose cap columns have closed forms. Through a fan over the plane ``z`` it is ``z A`` with ``A`` the
    signed area of its curve (Green's theorem, :func:`curve_area`; negative below, where ``v`` runs
    from the apex), through a vertical extrusion nothing; the extrusion's area is its height times its
    curve's length (Gauss-Legendre of ``order`` points a segment, as the patch quadrature).

    Parameters
    ----------
    grid : CappedGrid
        From :func:`close_side`.
    order : int
        Quadrature points per direction (5: exact volume).

    Returns
    -------
    volume, area : float
        mm^3 (signed: positive when the patches face outward) and mm^2.
    """
    from surfaces.measure import side_integrals

    ctrl = grid.control
    side = grid.side_columns
    low_h, high_h = grid.extrusions
    first, stop = side.start + (low_h > 0), side.stop - (high_h > 0)
    volume, area = side_integrals(ctrl[:, first:stop], order) if stop > first else (0.0, 0.0)
    # the side's end curves (the extrusions' far ends), the caps' outlines, copied coordinate-major:
    # x and y (2 ends, M, 4) each contiguous, for their areas (curve_area's) and their tangents
    n_seg = ctrl.shape[0]
    ends = np.empty((2, 2, n_seg, 4))
    ends[:, 0] = ctrl[:, side.start, :, 0, :2].transpose(2, 0, 1)
    ends[:, 1] = ctrl[:, side.stop - 1, :, 3, :2].transpose(2, 0, 1)
    x, y = ends.reshape(2, 2 * n_seg, 4)
    a_low, a_high = ((x @ _AREA_FORM) * y).reshape(2, -1).sum(axis=1).tolist()
    if side.start > 0:
        volume -= float(ctrl[0, side.start, 0, 0, 2]) * a_low
    if side.stop < ctrl.shape[1]:
        volume += float(ctrl[0, side.stop - 1, 0, 3, 2]) * a_high
    if low_h or high_h:
        # the tangents of both curves at the Gauss nodes, one product a coordinate, (2 M, order) each
        tangent, node_weights = _gauss_tangents(int(order))
        tx, ty = x @ tangent, y @ tangent
        length = np.sqrt(tx * tx + ty * ty) @ node_weights
        area += low_h * float(np.sum(length[:n_seg])) + high_h * float(np.sum(length[n_seg:]))
    area += sum(abs(a_low if out_z < 0 else a_high) for _, out_z in grid.flat_caps)
    return float(volume), float(area)


def cap_volumes(grid: CappedGrid, curves, prepend: int, append: int, order: int = 5) -> tuple[float, float]:
    """Volume a capped grid encloses beyond its low and its high end plane (mm^3, positive outward).

    Prisms (half caps, trend caps that do not close): the end curve's area times the
    extrusion. Rings (trend caps that close, domes; :func:`add_cap_rings`): the flux
    of ``(0, 0, z)`` through the ring columns (:func:`surfaces.measure.side_integrals`)
    plus that through the end curve's plane, closing them. Flat caps and none: 0.

    Parameters
    ----------
    grid : CappedGrid
        From :func:`close_side`.
    curves : array_like, shape (K, M, 4, 3)
        The body's slice curves (without the rings), lowest first.
    prepend, append : int
        Rings below the first and above the last curve (:func:`add_cap_rings`).
    order : int
        Quadrature points per direction (5: exact for the patches).

    Returns
    -------
    (float, float)
    """
    from surfaces.measure import side_integrals

    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    side = grid.side_columns
    out = []
    for end, (rings, h) in enumerate(zip((int(prepend), int(append)), grid.extrusions)):
        curve = c[0] if end == 0 else c[-1]
        a = _curve_area(curve)
        if h > 0:
            out.append(abs(a) * h)
        elif rings > 0:
            cols = slice(side.start, side.start + rings) if end == 0 else slice(side.stop - rings, side.stop)
            flux = side_integrals(grid.control[:, cols], order)[0]
            z0 = float(curve[0, 0, 2])
            out.append(float(flux + (z0 * a if end == 0 else -z0 * a)))
        else:
            out.append(0.0)
    return out[0], out[1]


def weld_flat_caps(side: TriangleMesh, grid: CappedGrid, samples: int,
                   inset: bool = True) -> tuple[TriangleMesh, TriangleMesh]:
    """The side's triangles with the flat caps' triangles joined to them.

    Parameters
    ----------
    side : TriangleMesh
        Tessellation of the side columns (:func:`surfaces.mesh.tessellate` at ``samples``).
    grid : CappedGrid
        The body's grid (its flat caps and end planes).
    samples : int
        Subdivisions per patch side used for ``side`` (the caps' boundary matches it).
    inset : bool
        Give the caps the inner ring that shades them flat (:func:`planar_cap_mesh`).
        Holes go without: their caps are cut away or hidden inside the solid, and
        where they lie in an outer body's cap plane the extra ring only gives the
        set operations coplanar slivers to resolve.

    Returns
    -------
    mesh : TriangleMesh
        Caps welded to the side (watertight when the body is capped).
    display : TriangleMesh
        The same triangles with the caps' vertices kept apart, so that flat caps
        shade with their own +-z normals.
    """
    if not grid.flat_caps:
        return side, side
    # only vertices in the end planes can be shared with the caps
    zv = side.vertices[:, 2]
    tol = 1e-7 * max(1.0, float(side.vertices.max()), -float(side.vertices.min()))
    low, high = grid.end_planes
    rim = ((np.abs(zv - low) < tol) | (np.abs(zv - high) < tol)).nonzero()[0]
    caps = [_planar_cap_mesh(c, samples, s, inset) for c, s in grid.flat_caps]
    merged = merge_meshes([side] + caps)
    candidates = np.concatenate([rim, np.arange(side.n_vertices, merged.n_vertices)])
    rep = _rim_weld_map(merged, side, caps, grid.flat_caps, int(samples), rim)
    if rep is None:
        return weld(merged, candidates=candidates), merged
    return _welded(merged, side, rep), merged


def _welded(merged: TriangleMesh, side: TriangleMesh, rep: np.ndarray) -> TriangleMesh:
    """``compact`` of ``merged`` with its vertices mapped by ``rep`` (its collapsed triangles dropped).

    ``rep`` moves cap vertices only; when the side's triangles use every side vertex (a lattice),
    the side's vertices and triangles are taken as they are and only the caps' are renumbered.
    """
    n_side, t_side = side.n_vertices, side.n_triangles
    cap_tri = rep[merged.triangles[t_side:]]
    keep = (cap_tri[:, 0] != cap_tri[:, 1]) & (cap_tri[:, 1] != cap_tri[:, 2]) & (cap_tri[:, 2] != cap_tri[:, 0])
    cap_tri = cap_tri[keep]
    # every side vertex used: a count per vertex costs half of marking them in a mask. The triangles'
    # middle corners alone cover a lattice closed around (tessellate's side): counting them proves it at
    # a third of the work; where they do not, every corner is counted
    side_tri = side.triangles
    if merged.vertex_colors is not None or not (np.bincount(side_tri[:, 1], minlength=n_side).all()
                                                or np.bincount(side_tri.ravel(), minlength=n_side).all()):
        tri = rep[merged.triangles]
        keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])
        return compact(TriangleMesh.unchecked(merged.vertices, tri[keep], merged.vertex_normals, merged.vertex_colors,
                                    dict(merged.metadata)))
    # the side's vertices keep their numbers, the caps' used ones follow
    used = np.zeros(merged.n_vertices - n_side, dtype=bool)
    cap_vertex = cap_tri.ravel()
    used[cap_vertex[cap_vertex >= n_side] - n_side] = True
    new_index = np.concatenate([np.arange(n_side), n_side - 1 + np.cumsum(used)])
    normals = merged.vertex_normals
    return TriangleMesh.unchecked(
        np.concatenate([side.vertices, merged.vertices[n_side:][used]]),
        np.concatenate([side.triangles, new_index[cap_tri]]),
        None if normals is None else np.concatenate([side.vertex_normals, normals[n_side:][used]]),
        None, dict(merged.metadata))


def _rim_weld_map(merged: TriangleMesh, side: TriangleMesh, caps: list, flat_caps: tuple, samples: int,
                  rim: np.ndarray) -> np.ndarray | None:
    """The map of :func:`surfaces.mesh.weld` on ``merged`` (side, then caps) by index arithmetic, or None.

    The side of :func:`surfaces.mesh.tessellate` is a lattice, ring sample ``i`` on row ``i``, the
    low end plane in its first column and the high one in its last; a cap's boundary vertex ``i``
    is that ring's sample ``i`` (the same points). The map sends every cap boundary vertex to its
    rim vertex; it is what the spatial weld gives when every boundary vertex lies within half the
    weld tolerance of its rim vertex and no two other candidates (rim, rim partners, the caps' other
    vertices) lie within three tolerances (then no other pair is close enough to merge), checked by
    :func:`surfaces.mesh.points_apart`. None when either check fails (a side that is not such a
    lattice, points that nearly coincide): then the spatial weld decides. ``rim``: distinct indices of
    the side's vertices in its end planes.
    """
    verts = merged.vertices
    tol = weld_tolerance(verts)  # the spatial weld's own
    rep = np.arange(len(verts))
    n_side = side.n_vertices
    boundary, partner, others = [], [], [rim]
    offset = n_side
    for cap, (curve, out_z) in zip(caps, flat_caps):
        n_ring = len(curve) * samples  # the boundary vertices come first (planar_cap_mesh)
        if n_ring == 0 or n_side % n_ring:
            return None
        n_v = n_side // n_ring
        boundary.append(offset + np.arange(n_ring))
        partner.append(np.arange(n_ring) * n_v + (0 if out_z < 0 else n_v - 1))
        others.append(offset + np.arange(n_ring, cap.n_vertices))
        offset += cap.n_vertices
    boundary, partner = np.concatenate(boundary), np.concatenate(partner)
    in_rim = np.zeros(n_side, dtype=bool)
    in_rim[rim] = True
    if not in_rim[partner].all():  # the spatial weld joins candidates only
        return None
    d = verts[boundary] - verts[partner]
    if not (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] <= (tol / 2) ** 2).all():
        return None
    # the partners are rim vertices (checked above): the candidates are the rim (distinct indices, as
    # weld_flat_caps finds them) and the caps' other vertices, each once
    if not points_apart(verts[np.concatenate(others)], 3 * tol):
        return None
    rep[boundary] = partner
    return rep
