"""Bicubic Coons (Hermite / Ferguson) patches through a grid of points (seed 001).

Each quadrilateral cell of a point grid becomes the patch

    Q(u, v) = [U] [N_C] [B] [N_C]^T [V]^T,     U = [u^3 u^2 u 1]       (seed 001, eq. 1)

with the geometry matrix (eq. 2)

    B = [[P00,  P01,  Pv00,  Pv01 ],
         [P10,  P11,  Pv10,  Pv11 ],
         [Pu00, Pu01, Puv00, Puv01],
         [Pu10, Pu11, Puv10, Puv11]]

(``P_ab`` the corner at ``u = a, v = b``; tangents and twists per unit of the
patch parameter), converted exactly into Bezier form by

    P_B = N_B^-1 N_C B N_C^T N_B^-T = K B K^T                          (eq. 7)

Tangents are given by the caller or estimated by finite differences: a
three-point difference in the chord-length parameter (central inside,
one-sided at open edges, wrapped in a closed direction), multiplied by the
chord of the patch edge, so that non-uniform spacing does not kink the surface.
With uniform spacing this is exactly the seed's ``(P[i+1] - P[i-1]) / 2`` and
the twist ``(P[i+1,j+1] - P[i+1,j-1] - P[i-1,j+1] + P[i-1,j-1]) / 4``.
"""

from __future__ import annotations

import numpy as np

from surfaces.bezier import BezierPatches
from surfaces.knots import chord_lengths
from surfaces.validate import as_array, drop_closing_repeat, InputError

#: Hermite basis in power form, rows act on [P0, P1, P0', P1'] (seed 001).
N_C = np.array([[2.0, -2.0, 1.0, 1.0], [-3.0, 3.0, -2.0, -1.0], [0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
#: Bernstein basis in power form.
N_B = np.array([[-1.0, 3.0, -3.0, 1.0], [3.0, -6.0, 3.0, 0.0], [-3.0, 3.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
#: ``K = N_B^-1 N_C``; exact in floating point as the closed form below.
K = np.array([[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 1.0 / 3.0, 0.0], [0.0, 1.0, 0.0, -1.0 / 3.0], [0.0, 1.0, 0.0, 0.0]])


def coons_to_bezier(geometry) -> np.ndarray:
    """Convert Coons geometry matrices to Bezier control points (seed 001, eq. 7).

    Parameters
    ----------
    geometry : array_like, shape (..., 4, 4, 3)
        Geometry matrices ``B`` (corners, tangents, twists; see module docstring).

    Returns
    -------
    numpy.ndarray, shape (..., 4, 4, 3)
        ``P_B = K B K^T`` for every matrix at once.
    """
    geom = as_array(geometry, "geometry")
    if geom.ndim < 3 or geom.shape[-3:] != (4, 4, 3):
        raise InputError(f"geometry: expected shape (..., 4, 4, 3), got {geom.shape}")
    return np.einsum("ab,...bcx,dc->...adx", K, geom, K)


def _take(a: np.ndarray, axis: int, index) -> np.ndarray:
    sl = [slice(None)] * a.ndim
    sl[axis] = index
    return a[tuple(sl)]


def _derivative(values: np.ndarray, h: np.ndarray, axis: int, closed: bool) -> np.ndarray:
    """Three-point derivative of ``values`` along ``axis`` with spacings ``h``.

    ``values`` has shape (R, C, 3); ``h`` holds the spacing between neighbours
    along ``axis`` (length n - 1 open, n closed). Exact for quadratics.
    """
    n = values.shape[axis]
    hh = h[..., None]
    if n == 2 and not closed:
        d = (_take(values, axis, slice(1, 2)) - _take(values, axis, slice(0, 1))) / _take(hh, axis, slice(0, 1))
        return np.concatenate([d, d], axis=axis)
    if closed:
        prev = np.roll(values, 1, axis=axis)
        nxt = np.roll(values, -1, axis=axis)
        h0 = np.roll(hh, 1, axis=axis)  # spacing to the previous point
        h1 = hh  # spacing to the next point
    else:
        prev = _take(values, axis, slice(0, -2))
        nxt = _take(values, axis, slice(2, None))
        h0 = _take(hh, axis, slice(0, -1))
        h1 = _take(hh, axis, slice(1, None))
    mid = values if closed else _take(values, axis, slice(1, -1))
    inner = (
        -h1 / (h0 * (h0 + h1)) * prev
        + (h1 - h0) / (h0 * h1) * mid
        + h0 / (h1 * (h0 + h1)) * nxt
    )
    if closed:
        return inner
    # one-sided three-point differences at the open ends
    f0, f1, f2 = (_take(values, axis, slice(k, k + 1)) for k in (0, 1, 2))
    a, b = _take(hh, axis, slice(0, 1)), _take(hh, axis, slice(1, 2))
    first = -(2 * a + b) / (a * (a + b)) * f0 + (a + b) / (a * b) * f1 - a / (b * (a + b)) * f2
    g0, g1, g2 = (_take(values, axis, slice(k, k + 1 if k != -1 else None)) for k in (-3, -2, -1))
    a, b = _take(hh, axis, slice(-2, -1)), _take(hh, axis, slice(-1, None))
    last = b / (a * (a + b)) * g0 - (a + b) / (a * b) * g1 + (2 * b + a) / (b * (a + b)) * g2
    return np.concatenate([first, inner, last], axis=axis)


def _safe_spacing(h: np.ndarray) -> np.ndarray:
    """Replace zero chords (repeated points, poles) by a tiny positive spacing."""
    positive = h[h > 0]
    floor = 1e-12 * (float(positive.mean()) if positive.size else 1.0)
    return np.maximum(h, floor)


def from_grid(
    points,
    pu=None,
    pv=None,
    twist="zero",
    *,
    closed_u: bool = False,
    closed_v: bool = False,
    chord_length: bool = True,
) -> BezierPatches:
    """Bicubic Coons patches through every point of a grid, as Bezier patches.

    Parameters
    ----------
    points : array_like, shape (R, C, 3)
        Grid of points; axis 0 runs along ``u``, axis 1 along ``v``. In a closed
        direction the grid may or may not repeat its first row at the end.
    pu, pv : array_like, shape (R, C, 3), optional
        Tangents ``dP/di`` and ``dP/dj`` per unit of grid index (= per unit of
        patch parameter), e.g. exact slopes of a height field. Estimated by
        finite differences when omitted.
    twist : {"zero", "fd"} or array_like, shape (R, C, 3)
        Twist vectors ``d2P/didj``: zero (seed 001's choice), finite
        differences of the tangents, or given per unit of grid index.
    closed_u, closed_v : bool
        The direction closes on itself (patches wrap from the last row to the first).
    chord_length : bool
        Scale estimated tangents by the chord of each patch edge (default);
        False gives uniform-parameter differences.

    Returns
    -------
    BezierPatches
        ``(R - 1) x (C - 1)`` patches (``R`` resp. ``C`` in a closed direction).

    Raises
    ------
    ValueError
        On a wrong shape, NaN/inf, fewer than 2x2 points, or tangents/twists of
        the wrong shape.

    Examples
    --------
    A flat 3 x 3 grid of unit spacing: 2 x 2 patches, the 2 x 2 square exactly.

    >>> x, y = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0, 2.0], indexing="ij")
    >>> patches = from_grid(np.stack([x, y, np.zeros_like(x)], axis=-1))
    >>> patches.shape
    (2, 2)
    >>> patches.evaluate_global([1.5], [0.5]).tolist()
    [[1.5, 0.5, 0.0]]
    """
    pts = as_array(points, "points")
    if pts.ndim != 3 or pts.shape[-1] != 3:
        raise InputError(f"points: expected shape (R, C, 3), got {pts.shape}")
    full_rows, full_cols = pts.shape[:2]
    if closed_u:
        pts = drop_closing_repeat(pts, 0)
    if closed_v:
        pts = drop_closing_repeat(pts, 1)
    rows, cols = pts.shape[:2]
    if rows < 2 or cols < 2:
        raise InputError(f"points: need at least 2x2 grid points, got {rows}x{cols}")
    if isinstance(twist, str) and twist not in ("zero", "fd"):
        raise InputError(f"twist: must be 'zero', 'fd' or an (R, C, 3) array, got {twist!r}")
    given = {}
    for name, value in (("pu", pu), ("pv", pv), ("twist", None if isinstance(twist, str) else twist)):
        if value is not None:
            # given per point of the grid as passed, repeated closing row included
            given[name] = as_array(value, name, shape=(full_rows, full_cols, 3))[:rows, :cols]

    # chord spacings along u (shape (nu, C)) and v (shape (R, nv))
    if chord_length:
        hu = _safe_spacing(chord_lengths(pts, 0, closed_u))
        hv = _safe_spacing(chord_lengths(pts, 1, closed_v))
    else:
        hu = np.ones((rows if closed_u else rows - 1, cols))
        hv = np.ones((rows, cols if closed_v else cols - 1))
    # derivatives with respect to the chord parameter
    mu = _derivative(pts, hu, 0, closed_u)
    mv = _derivative(pts, hv, 1, closed_v)
    muv = _derivative(mu, hv, 1, closed_v) if isinstance(twist, str) and twist == "fd" else None

    i0 = np.arange(rows if closed_u else rows - 1)
    j0 = np.arange(cols if closed_v else cols - 1)
    i1 = (i0 + 1) % rows
    j1 = (j0 + 1) % cols
    I0, J0 = np.meshgrid(i0, j0, indexing="ij")
    I1, J1 = np.meshgrid(i1, j1, indexing="ij")

    def corners(values):
        """Values at the patch corners (u, v) = (0, 0), (0, 1), (1, 0), (1, 1)."""
        return values[I0, J0], values[I0, J1], values[I1, J0], values[I1, J1]

    su0 = hu[I0, J0][..., None]  # chord of the u-edge at v = 0
    su1 = hu[I0, J1][..., None]  # chord of the u-edge at v = 1
    sv0 = hv[I0, J0][..., None]  # chord of the v-edge at u = 0
    sv1 = hv[I1, J0][..., None]  # chord of the v-edge at u = 1
    # estimated derivatives per unit chord become tangents per unit of patch parameter
    su = (su0, su1, su0, su1)
    sv = (sv0, sv0, sv1, sv1)

    if "pu" in given:
        pu00, pu01, pu10, pu11 = corners(given["pu"])
    else:
        pu00, pu01, pu10, pu11 = (m * s for m, s in zip(corners(mu), su))
    if "pv" in given:
        pv00, pv01, pv10, pv11 = corners(given["pv"])
    else:
        pv00, pv01, pv10, pv11 = (m * s for m, s in zip(corners(mv), sv))
    if "twist" in given:
        t00, t01, t10, t11 = corners(given["twist"])
    elif muv is not None:
        t00, t01, t10, t11 = (m * a * b for m, a, b in zip(corners(muv), su, sv))
    else:
        t00 = t01 = t10 = t11 = np.zeros_like(pu00)

    p00, p01, p10, p11 = corners(pts)
    geometry = np.stack(
        [
            np.stack([p00, p01, pv00, pv01], axis=-2),
            np.stack([p10, p11, pv10, pv11], axis=-2),
            np.stack([pu00, pu01, t00, t01], axis=-2),
            np.stack([pu10, pu11, t10, t11], axis=-2),
        ],
        axis=-3,
    )
    return BezierPatches(coons_to_bezier(geometry), closed_u=closed_u, closed_v=closed_v)
