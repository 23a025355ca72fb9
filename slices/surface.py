"""From the contours of one body to one closed grid of bicubic Bezier patches.

Seed 000, section III. Every contour gets the seed's parameters
(:mod:`slices.control_points`), and every slice its closed parabolic-blending
curve through all of its points. To make the curves of all slices cubic on
the same breakpoints, the parameters are moved onto a common lattice of
``M`` values (at least twice the largest point count), spaced evenly in the
slices' mean arc length so that folds, which the seed packs into one ray
segment, get enough values; support points keep ``u_k = k / N1`` up to half
a lattice step. Each curve is then cut exactly at every lattice value. The
rays' common rotation is chosen so that support points do not jump across a
fold from one slice to the next. The curves are blended across slices
(eqs. 13-19) into one closed-in-``u`` grid of patches that passes through
every control point, or the lattice nodes are handed to Coons patches
(seed 001) or to the B-spline interpolation of :mod:`surfaces.bspline`.
Caps are extra patch columns (:mod:`slices.caps`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from slices.control_points import (
    START_CANDIDATES,
    _balanced_values,
    _parameterize_flat,
    _polars,
    _quantize_flat,
    _start_angle_crossings,
    _support_crossings,
    lattice_values,
)
from slices.options import SurfaceOptions
from surfaces import blending, coons
from surfaces.bezier import BezierPatches
from surfaces.validate import as_array, InputError, positive

#: Common ``u`` lattices of :func:`slice_curves`.
LATTICE_MODES = ("balanced", "uniform", "adaptive", "union")

#: Which ``u`` links the slices in :func:`slice_curves`.
CORRESPONDENCES = ("seed", "arc", "aligned")

#: Arc-length samples per slice with which ``correspondence="aligned"`` matches neighbouring slices.
ALIGN_SAMPLES = 512


@dataclass(frozen=True)
class SliceCurves:
    """The slice curves of one body on a common lattice.

    Attributes
    ----------
    curves : numpy.ndarray, shape (K, M, 4, 3)
        Bezier points of each slice curve on the lattice intervals ``[j/M, (j+1)/M]``.
    nodes : list of numpy.ndarray
        Per slice, lattice index ``j`` of each control point, shape (n_k,) int64.
    points : list of numpy.ndarray
        Per slice, the control points in the same order, shape (n_k, 3) mm.
    params : list of ContourParameters
        The seed's parameters before they were moved onto the lattice.
    start_angle : float
        Direction of ray 0 in radians from +x, common to all slices.
    """

    curves: np.ndarray
    nodes: list
    points: list
    params: list
    start_angle: float = 0.0


def lattice_size(max_points: int, lattice_factor: float = SurfaceOptions.lattice_factor) -> int:
    """Lattice size ``M`` (a count) for the common ``u`` breakpoints.

    Parameters
    ----------
    max_points : int
        Largest number of points of a contour.
    lattice_factor : float
        Lattice values per point of the largest contour (>= 1).

    Returns
    -------
    int
        ``ceil(lattice_factor * max_points)``, at least ``max_points`` and 4.

    Examples
    --------
    >>> lattice_size(10), lattice_size(10, 2.5), lattice_size(1)
    (20, 25, 4)
    """
    f = positive(lattice_factor, "lattice_factor")
    if f < 1:
        raise InputError(f"lattice_factor: must be at least 1, got {lattice_factor}")
    return max(4, int(max_points), int(np.ceil(f * max_points)))


def _geometry_parameters(points: np.ndarray, start: np.ndarray, sizes: np.ndarray, kind: str) -> np.ndarray:
    """Parameters that shape each closed contour between its points: chord length or centripetal.

    ``points`` (2, N) holds the contours' x and y one after the other, contour ``c`` the
    ``sizes[c]`` columns from ``start[c]``; each gets parameters in ``[0, 1)``.
    """
    if kind not in ("centripetal", "chord"):
        raise InputError(f"geometry: must be 'chord' or 'centripetal', got {kind!r}")
    n_c = len(sizes)
    n = points.shape[1]
    curve = np.arange(n_c).repeat(sizes)
    local = np.arange(n) - start[curve]
    nxt = np.arange(1, n + 1)
    nxt[start + sizes - 1] = start
    dx, dy = points.take(nxt, axis=1) - points
    seg = np.sqrt(dx * dx + dy * dy)
    if kind == "centripetal":
        seg = np.sqrt(seg)
    # one row per contour, so that every running sum starts afresh at its contour
    width = int(sizes.max()) + 1
    cum = np.zeros((n_c, width))
    at = curve * width + local  # flat positions (one index: faster than two)
    cum.reshape(-1)[at + 1] = seg
    cum.cumsum(axis=1, out=cum)
    return cum.reshape(-1)[at] / cum.reshape(-1)[np.arange(n_c) * width + sizes][curve]


def _support_arcs(support0: np.ndarray, points: np.ndarray, start: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    """The contours' points' arc length from their support point 0 (the same ray on every slice),
    as a fraction of the perimeter; ``points`` (N, 2) the contours one after the other (``start``,
    ``sizes``), ``support0`` (C, 2) their support points 0; shape (N,)."""
    n_c = len(sizes)
    n = len(points)
    # contour c's support point 0, then its points, from column start[c] + c; the last edge returns
    # to the first (x and y apart: operations along all points)
    first = start + np.arange(n_c)
    closed = np.empty((2, n + n_c))
    at_vertex = np.arange(n) + np.arange(1, n_c + 1).repeat(sizes)
    for xy in (0, 1):  # scatters of single floats: faster than of columns
        closed[xy][first] = support0[:, xy]
        closed[xy][at_vertex] = points[:, xy]
    nxt = np.arange(1, n + n_c + 1)
    nxt[first + sizes] = first
    dx, dy = closed.take(nxt, axis=1) - closed
    curve = np.arange(n_c).repeat(sizes + 1)
    local = np.arange(n + n_c) - first[curve]
    width = int(sizes.max()) + 1
    cum = np.zeros((n_c, width))
    at = curve * width + local  # flat positions (one index: faster than two)
    cum.reshape(-1)[at] = np.sqrt(dx * dx + dy * dy)
    cum.cumsum(axis=1, out=cum)  # one row per contour: every running sum starts afresh
    at_point = local < sizes[curve]
    return cum.reshape(-1)[at[at_point]] / cum.reshape(-1)[np.arange(n_c) * width + sizes][curve[at_point]]


def aligned_arcs(points, arcs) -> list:
    """Arc-length parameters whose origin turns with the shape from slice to slice.

    Every slice's outline is sampled at :data:`ALIGN_SAMPLES` equal steps of arc
    length (about its mean), and the shift of each slice's origin against the
    slice below is the one that brings the two outlines closest in the least-squares
    sense (the peak of their circular cross-correlation, by FFT). Arc length from a
    common ray can start at different features of a crescent on two slices (the
    ray meets it on either horn), and every straight or blended link between the
    slices then twists; the shifted origins follow the shape instead.

    Parameters
    ----------
    points : sequence of numpy.ndarray, each shape (n_k, 2)
        Closed outlines in mm, counter-clockwise.
    arcs : sequence of numpy.ndarray, each shape (n_k,)
        Their points' arc length from the slice's origin as a fraction of the
        perimeter, strictly increasing in ``[0, 1)``.

    Returns
    -------
    list of numpy.ndarray
        Per slice, ``(arc - shift) mod 1`` (shape (n_k,), not sorted: the point of
        smallest value starts the outline); slice 0 keeps its origin.

    Examples
    --------
    A square's points, the second slice's list starting one corner later:

    >>> sq = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    >>> a = np.arange(4) / 4
    >>> [u.tolist() for u in aligned_arcs([sq, np.roll(sq, -1, axis=0)], [a, a])]
    [[0.0, 0.25, 0.5, 0.75], [0.25, 0.5, 0.75, 0.0]]
    """
    grid = np.arange(ALIGN_SAMPLES) / ALIGN_SAMPLES
    shapes = []
    for pts, arc in zip(points, arcs):
        a = np.concatenate([arc - 1.0, arc, arc + 1.0])
        w = np.interp(grid, a, np.tile(pts[:, 0], 3)) + 1j * np.interp(grid, a, np.tile(pts[:, 1], 3))
        shapes.append(np.fft.fft(w - w.mean()))
    # shift d of slice k against k - 1 maximises sum_i Re(conj(w_{k-1}[i]) w_k[i + d])
    corr = np.real(np.fft.ifft(np.conj(np.stack(shapes[:-1])) * np.stack(shapes[1:]), axis=1))
    shift = np.concatenate([[0.0], (np.argmax(corr, axis=1) / ALIGN_SAMPLES).cumsum()]) if len(shapes) > 1 else [0.0]
    return [np.mod(arc - s, 1.0) for arc, s in zip(arcs, shift)]


def slice_curves(contours, z, n_rays: int, n_lattice: int | None = None,
                 start_angle: float | None = None, geometry: str = "centripetal",
                 correspondence: str = SurfaceOptions.correspondence,
                 lattice_mode: str = SurfaceOptions.lattice_mode) -> SliceCurves:
    """Closed parabolic-blending curve of every slice, cut on a common lattice.

    Parameters
    ----------
    contours : sequence of array_like, each shape (n_k, 2)
        Counter-clockwise contours in mm, one per slice.
    z : array_like, shape (K,)
        Slice positions in mm.
    n_rays : int
        Rays per contour (seed 000, eq. 1).
    n_lattice : int, optional
        Lattice size ``M`` (a count); default :func:`lattice_size` of the largest contour.
    start_angle : float, optional
        Direction of ray 0 (radians from +x), common to all slices; by default
        the rotation of the rays that keeps the support points steadiest from
        slice to slice (:func:`slices.control_points.choose_start_angle`).
    geometry : {"centripetal", "chord"}
        Parameters that shape each slice's parabolic-blending curve between its
        points (eqs. 6-12). The seed's ``u`` of eqs. 1-5 can crowd many points
        into a short parameter range where a contour folds, which makes the
        blended parabolas overshoot; the curve is therefore built on
        centripetal (default) or chord-length parameters and reparameterised
        piecewise linearly onto ``u``, so every point still sits at its ``u``.
    correspondence : {"seed", "arc", "aligned"}
        Which ``u`` links the slices: the seed's parameters (eqs. 1-5, default),
        normalised arc length from support point 0, or normalised arc length
        whose origin follows the shape from slice to slice (:func:`aligned_arcs`).
    lattice_mode : {"balanced", "uniform", "adaptive", "union"}
        Common lattice: ``balanced`` (default) spaces the values evenly in the
        slices' mean arc length as a function of ``u``
        (:func:`slices.control_points.balanced_lattice_values`), so a fold that
        the seed packs into one ray segment gets as many values as its length
        needs; ``uniform`` is ``j / M``; ``adaptive`` is half uniform, half
        quantiles of the pooled parameters; ``union`` takes every slice's
        parameters (no quantisation at all; ``M`` = all points of the body,
        which grows with the number of slices squared in patches).

    Returns
    -------
    SliceCurves
    """
    zz = as_array(z, "z", shape=(len(contours),))
    if correspondence not in CORRESPONDENCES:
        raise InputError(f"correspondence: must be one of {CORRESPONDENCES}, got {correspondence!r}")
    if lattice_mode not in LATTICE_MODES:
        raise InputError(f"lattice_mode: must be one of {LATTICE_MODES}, got {lattice_mode!r}")
    # finite values checked once over all contours (below), the contour named only on failure; the
    # shapes checked in one pass, as_array naming the contour only where one is wrong
    try:
        ps = [np.asarray(c, dtype=np.float64) for c in contours]
    except (TypeError, ValueError):
        ps = []
    if len(ps) != len(contours) or any([p.ndim != 2 or p.shape[1] != 2 for p in ps]):
        ps = [as_array(c, f"contours[{i}]", shape=(None, 2), finite=False) for i, c in enumerate(contours)]
    n1 = int(n_rays)
    if n1 < 3:
        raise InputError(f"n_rays: need at least 3 rays (seed 000, eq. 1), got {n_rays}")
    if ps and min(map(len, ps)) < 3:
        i = next(i for i, p in enumerate(ps) if len(p) < 3)
        raise InputError(f"contours[{i}]: needs at least 3 points, got {len(ps[i])}")
    joined = np.concatenate(ps)
    if not np.isfinite(joined).all():
        for i, c in enumerate(ps):
            as_array(c, f"contours[{i}]")
    # the ray origin, polar angles and arc lengths serve both the rotation's choice and the parameters
    polars = _polars(ps, joined)
    if start_angle is None and len(ps) > 1:
        # the chosen rotation's rays are among those tried: their crossings come from the same pass
        start_angle, crossings = _start_angle_crossings(polars, n1, START_CANDIDATES)
    else:
        start_angle = 0.0 if start_angle is None else float(start_angle)
        crossings = _support_crossings(polars, n1, start_angle)
    params, flat, u_flat, support_xy = _parameterize_flat(polars, n1, start_angle, crossings)
    # every contour keeps its point count: the tables of the polars place the outlines, too
    ns, start = polars.sizes, polars.start
    n_c = len(ns)
    bounds = list(zip(start.tolist(), (start + ns).tolist()))
    m = n_lattice or lattice_size(int(ns.max()))
    arc_flat = _support_arcs(support_xy[:, 0], flat, start, ns)
    if correspondence == "aligned":
        # each outline starts at its point of smallest shifted arc length, so u increases along it
        us = aligned_arcs([flat[lo:hi] for lo, hi in bounds], [arc_flat[lo:hi] for lo, hi in bounds])
        first = [int(np.argmin(u)) for u in us]
        flat = np.concatenate([np.roll(flat[lo:hi], -f, axis=0) for (lo, hi), f in zip(bounds, first)])
        u_flat = arc_flat = np.concatenate([np.roll(u, -f) for u, f in zip(us, first)])
    elif correspondence == "arc":
        u_flat = arc_flat
    if lattice_mode == "union":
        values = np.unique(u_flat)
    elif lattice_mode == "balanced":
        values = _balanced_values(u_flat, arc_flat, ns, m)
    else:
        values = (lattice_values([u_flat[lo:hi] for lo, hi in bounds], m) if lattice_mode == "adaptive"
                  else np.arange(m) / m)
    m = len(values)
    longest = int(ns.max())
    if longest > m:
        raise InputError(f"n_lattice: {m} lattice values cannot hold {longest} distinct parameters")
    q = _quantize_flat(u_flat, start, ns, m, values)
    nodes = [q[lo:hi] for lo, hi in bounds]
    curve = np.arange(n_c).repeat(ns)
    # coordinate by coordinate, so that every operation of the curves and their cut runs along all points
    flat_xy = np.ascontiguousarray(flat.T)
    # in the plane only: every Bezier point of a slice's curve lies at its z exactly
    t, _, _ = blending.closed_curve_parameters(flat, _geometry_parameters(flat_xy, start, ns, geometry), ns)
    by_coordinate, knots = blending.overhauser_closed_by_coordinate(flat_xy, t, start, ns)
    # lattice node j sits at t(j), t piecewise linear through (q_i, t_i) (np.interp's formula): on
    # every lattice interval the curve is one cubic piece, cut exactly (Bezier points do not depend
    # on the affine parameter of the interval); the period starts at node q0, so lattice interval
    # L of slice c is [x, x + 1] with x = L, or L + M before q0
    # the nodes' lattice indices as floats (exact), converted before they are gathered
    x_node = q.astype(np.float64)
    x_next = np.empty(len(q))
    x_next[:-1] = x_node[1:]
    x_next[start + ns - 1] = q[start] + m
    lattice = np.arange(m)
    before = lattice < q[start][:, None]  # (C, M)
    x = (lattice + m * before).ravel().astype(np.float64)
    # the node that starts each interval's segment: the last at or before L (a running count of the
    # nodes passed), or the last node of the slice before q0 (the closing segment)
    passed = np.zeros((n_c, m), dtype=np.int64)
    passed.reshape(-1)[curve * m + q] = 1
    passed.cumsum(axis=1, out=passed)
    g = np.where(before, (start + ns - 1)[:, None], start[:, None] + passed - 1).ravel()
    at_knot = g + curve[g]
    k_lo, k_hi = knots[at_knot], knots[at_knot + 1]
    x_lo, x_hi = x_node[g], x_next[g]
    slope = (k_hi - k_lo) / (x_hi - x_lo)
    b_lo = np.where(x == x_lo, k_lo, slope * (x - x_lo) + k_lo)
    b_hi = np.where(x + 1.0 == x_hi, k_hi, slope * (x + 1.0 - x_lo) + k_lo)
    cut = np.empty((n_c, m, 4, 3))
    cut[..., 2] = zz[:, None, None]
    blending.restrict_closed_rows(by_coordinate.take(g, axis=2), k_lo, k_hi, b_lo, b_hi, m,
                            cut.reshape(n_c * m, 4, 3)[..., :2])
    p3 = np.empty((len(flat), 3))
    p3[:, :2] = flat
    p3[:, 2] = zz[curve]
    return SliceCurves(cut, nodes, [p3[lo:hi] for lo, hi in bounds], params, float(start_angle))


# ------------------------------------------------------------------ methods
# Each method turns the curve stack (K, M, 4, 3) into side patches and a function that
# evaluates the surface at lattice node j of slice k (to measure control-point deviation).
NodeEval = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _corner_eval(patches: BezierPatches, n_slices: int) -> NodeEval:
    # node (j, k) is a patch corner, u = 0 and v = 0 (or 1 on the last slice): there the surface is
    # the corner's control point exactly (the other Bernstein weights are 0), so a gather evaluates it
    corners = patches.control[:, :, 0, ::3]  # (M, K - 1, 2, 3): v = 0 and v = 1
    last = n_slices - 2

    def at(j: np.ndarray, k: np.ndarray) -> np.ndarray:
        kk = np.asarray(k)
        return corners[j, np.minimum(kk, last), (kk > last).astype(np.intp)]

    return at


def _side_blending(curves: np.ndarray, v: np.ndarray, monotone: bool = False,
                   out: np.ndarray | None = None) -> tuple[BezierPatches, NodeEval]:
    # side_surface has checked the curves (finite) and v (strictly increasing)
    patches, limited = blending.blend_validated(curves, True, v, bool(monotone), trusted=True, out=out)
    if monotone and len(curves) >= 3:
        _last_overshoot[:] = [curves.copy(), v.copy(), _overshoot_count(limited)]
    return patches, _corner_eval(patches, len(curves))


#: The curves and ``v`` of the last monotone blend and their :func:`blend_overshoot`: a body
#: blends its side surface, then reports the overshoot of the same curves, which is then a
#: comparison instead of the limit a second time (by value, so a changed array misses).
_last_overshoot: list = []


def _overshoot_count(limited: np.ndarray) -> int:
    """(curve, Bezier point) pairs of a (K, M, 4, 3) limit mask with x or y limited."""
    return int(np.count_nonzero(limited[..., 0] | limited[..., 1]))


def blend_overshoot(curves, v=None) -> int:
    """How many tangents the monotone limit of the blend in ``v`` shortens.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        Slice curves on a common lattice (``K >= 2``).
    v : array_like, shape (K,), optional
        Slice positions (uniform when omitted).

    Returns
    -------
    int
        (slice, Bezier point of a curve) pairs whose x or y tangent
        :func:`surfaces.blending.limit_monotone` shortens or zeroes: where the
        seed's parabolic blend would overshoot between slices.
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    k = len(c)
    if k < 3:
        return 0
    vv = None if v is None else as_array(v, "v", shape=(k,))
    last = _last_overshoot[:]
    if (vv is not None and last and last[0].shape == c.shape and np.array_equal(last[1], vv)
            and np.array_equal(last[0], c)):
        return last[2]
    return _overshoot_count(blending.monotone_blend(c, closed_u=True, params=vv)[1])


def ruled_surface(curves) -> tuple[BezierPatches, NodeEval]:
    """Side surface of straight lines between neighbouring slice curves (linear in ``v``).

    The fallback of a body whose blended surface folds: between two slices the
    surface never leaves the convex hull of the two curves' segments.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        Slice curves on a common lattice (``K >= 2``).

    Returns
    -------
    patches : BezierPatches
        ``M x (K - 1)`` patches, closed in ``u``.
    node_eval : callable
        As for :func:`side_surface`.
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    if len(c) < 2:
        raise InputError(f"curves: need at least 2 slices for a side surface, got {len(c)}")
    w = np.arange(4) / 3.0
    pieces = c[:-1, None] + w[None, :, None, None, None] * (c[1:] - c[:-1])[:, None]  # (K-1, 4, M, 4, 3)
    patches = BezierPatches(np.ascontiguousarray(pieces.transpose(2, 0, 3, 1, 4)), closed_u=True)
    return patches, _corner_eval(patches, len(c))


def _side_coons(curves: np.ndarray, v: np.ndarray, monotone: bool = False) -> tuple[BezierPatches, NodeEval]:
    nodes = curves[:, :, 0].transpose(1, 0, 2)  # (M, K, 3); chord-length tangents follow v
    patches = coons.from_grid(nodes, closed_u=True)
    return patches, _corner_eval(patches, len(curves))


def _side_bspline(curves: np.ndarray, v: np.ndarray, monotone: bool = False) -> tuple[BezierPatches, NodeEval]:
    from surfaces import bspline  # scipy.interpolate: loaded when this method is used

    nodes = curves[:, :, 0].transpose(1, 0, 2)
    m = nodes.shape[0]
    surf = bspline.interpolate_surface(
        nodes, degree=3, closed_u=True, params_u=np.arange(m) / m, params_v=(v - v[0]) / (v[-1] - v[0])
    )

    def at(j: np.ndarray, kk: np.ndarray) -> np.ndarray:
        return np.asarray(surf.evaluate(surf.params_u[j], surf.params_v[kk]))

    return surf.to_bezier(), at


#: Surface methods over the slice curves; adding one is one line here.
#: ``monotone`` (limit the blend in ``v``) applies to blending; Coons and B-spline ignore it.
METHODS: dict[str, Callable[..., tuple[BezierPatches, NodeEval]]] = {
    "blending": _side_blending,
    "coons": _side_coons,
    "bspline": _side_bspline,
}


def side_surface(curves, method: str = "blending", v=None, monotone: bool = False) -> tuple[BezierPatches, NodeEval]:
    """Side surface through a stack of slice curves.

    Parameters
    ----------
    curves : array_like, shape (K, M, 4, 3)
        Slice curves on a common lattice (``K >= 2``).
    method : {"blending", "coons", "bspline"}
        Seed 000 parabolic blending (exact through the curves), seed 001 Coons
        patches over the lattice nodes, or B-spline interpolation of the nodes.
    v : array_like, shape (K,), optional
        Slice positions (strictly increasing); uniform when omitted. Unequal
        positions give the non-uniform parabolas in ``v``.
    monotone : bool
        Blending only: limit the blend in ``v`` where it would overshoot between
        slices (:func:`surfaces.blending.limit_monotone`), so a protrusion present
        on one slice only does not fold the surface.

    Returns
    -------
    patches : BezierPatches
        ``M x (K - 1)`` patches (B-spline: one per knot span), closed in ``u``.
    node_eval : callable
        ``node_eval(j, k) -> (N, 3)``: the surface at lattice node ``j`` of slice ``k``.
    """
    return _side_surface(curves, method, v, monotone)


def _side_surface(curves, method: str, v, monotone: bool,
                  out: np.ndarray | None = None) -> tuple[BezierPatches, NodeEval]:
    """:func:`side_surface`; with ``out`` (blending only) the patches are written there and are a view of it.

    ``out``: float64 (M, K - 1, 4, 4, 3), its last three axes contiguous: the side columns of a capped
    grid (:func:`slices.caps._grid_buffer`), so that the side's points are written once.
    """
    c = as_array(curves, "curves", shape=(None, None, 4, 3))
    if method not in METHODS:
        raise InputError(f"method: must be one of {tuple(METHODS)}, got {method!r}")
    if len(c) < 2:
        raise InputError(f"curves: need at least 2 slices for a side surface, got {len(c)}")
    vv = np.arange(len(c), dtype=np.float64) if v is None else as_array(v, "v", shape=(len(c),))
    if (vv[1:] <= vv[:-1]).any():
        raise InputError("v: slice positions must increase strictly")
    if out is not None:
        if method != "blending":
            raise InputError(f"out: only the blending method writes into a given array, not {method!r}")
        return _side_blending(c, vv, monotone=bool(monotone), out=out)
    return METHODS[method](c, vv, monotone=bool(monotone))
