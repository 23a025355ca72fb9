"""Surface defects (cracks, scratches, dents) measured on a height field.

Seed 002(a) reconstructs surface defects from a triad of images; this module
turns the height field into numbers an inspector uses:

1. remove what is not the defect: a robust plane or smooth polynomial background
   (iterative refit excluding points beyond ``3 sigma`` of the residual, ``sigma``
   from the median absolute deviation);
2. segment: by depth with hysteresis (a region must reach the detection threshold
   somewhere and extends while deeper than the lower extent threshold), or, when the
   measured slopes ``p, q`` are given, by where the slope departs from the background's
   (sharper: integration spreads each slope kink over a few pixels of height), keeping
   the footprints that reach the detection depth;
3. measure each connected region in physical units (from sums over its pixels, read a block of rows
   of its bounding box at a time: nothing per region pixel is kept).

Directions follow :data:`photometric.lights.CONVENTION` (x right, y up). On a regular
pixel grid (orthographic camera) positions are the pixel centres times the pixel size.
With a perspective camera each pixel sees its own point: given ``xy`` (the ``x, y`` of
each pixel's surface point, mm) and ``area`` (each pixel's footprint on the ``x, y``
plane, mm^2), the background is fitted over those positions and lengths, widths, areas
and volumes are measured on them.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from photometric.options import BACKGROUND
from surfaces.validate import InputError, as_array, positive

_MAD_TO_SIGMA = 1.4826
_MAX_FIT_POINTS = 250_000


def _scaled(rows: np.ndarray, cols: np.ndarray, shape) -> tuple[np.ndarray, np.ndarray]:
    """x (right) and y (up) scaled to [-1, 1] over the image."""
    return 2.0 * cols / max(shape[1] - 1, 1) - 1.0, 1.0 - 2.0 * rows / max(shape[0] - 1, 1)


def _design(rows: np.ndarray, cols: np.ndarray, shape, degree: int, coords=None) -> np.ndarray:
    """Monomials ``x^a y^b`` (a + b <= degree) in coordinates scaled to [-1, 1]."""
    x, y = _scaled(rows, cols, shape) if coords is None else (coords[0][rows, cols], coords[1][rows, cols])
    # each column written in place: no list of columns beside the matrix
    out = np.empty((np.size(x), (degree + 1) * (degree + 2) // 2))
    k = 0
    for d in range(degree + 1):
        for a in range(d + 1):
            np.multiply(x**a, y ** (d - a), out=out[:, k])
            k += 1
    return out


def _scaled_xy(xy: np.ndarray, usable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and y of each pixel's point scaled to [-1, 1] over the usable pixels."""
    out = []
    for c in range(2):
        v = xy[..., c]
        lo, hi = float(v[usable].min()), float(v[usable].max())
        half = max(0.5 * (hi - lo), 1e-12)
        out.append((v - 0.5 * (lo + hi)) / half)
    return out[0], out[1]


def _spread_sample(ok: np.ndarray, most: int) -> np.ndarray:
    """Flat indices of the ``ok`` pixels, or of ``most`` of them evenly spread in raster order
    (``linspace`` over their ranks), found row block by row block: no index array of every
    pixel (8 bytes each) in memory."""
    n = int(np.count_nonzero(ok))
    if n <= most:
        return np.flatnonzero(ok)
    ranks = np.linspace(0, n - 1, most).astype(np.int64)
    out = np.empty(most, np.int64)
    seen = done = 0
    for rows in _row_blocks(ok.shape):
        idx = np.flatnonzero(ok[rows])
        stop = int(np.searchsorted(ranks, seen + idx.size))
        out[done:stop] = idx[ranks[done:stop] - seen] + rows.start * ok.shape[1]
        seen += idx.size
        done = stop
    return out


def _least_squares(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of ``A c = b`` (A: (n, k) float64, n >> k) by the normal equations.

    The columns are monomials of coordinates scaled to [-1, 1] (:func:`_design`), so the
    (k, k) Gram matrix is well conditioned (about 3 for a plane, 80 for degree 3): its
    solution equals LAPACK's SVD least squares to ~1e-14 at a tenth of the time. A Gram
    matrix conditioned worse than 1e8 (squaring the condition would cost digits) goes to
    :func:`numpy.linalg.lstsq`.
    """
    gram = A.T @ A
    if np.linalg.cond(gram) > 1e8:
        return np.linalg.lstsq(A, b, rcond=None)[0]
    return np.linalg.solve(gram, A.T @ b)


def fit_background(
    height, mask=None, method: str = "plane", *, degree: int = 3, iterations: int = 6, xy=None
) -> tuple[np.ndarray, float]:
    """Robust background of a height field (plane or smooth polynomial).

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height (any unit, e.g. mm); NaN is ignored.
    mask : array_like, shape (H, W), optional
        Pixels that may belong to the background (default: all finite ones).
    method : {"plane", "smooth"}
        A plane ``a + b x + c y``, or a polynomial of total degree ``degree``.
    degree : int, optional
        Degree of the smooth background.
    iterations : int, optional
        Refits; each excludes points with ``|r| > 3 sigma``, ``sigma = 1.4826 MAD``.
    xy : array_like, shape (H, W, 2), optional
        ``x, y`` (mm) of each pixel's point (perspective camera); the background is a
        polynomial in these instead of the pixel grid.

    Returns
    -------
    background : numpy.ndarray, shape (H, W), float64
        The fitted surface, evaluated everywhere.
    sigma : float
        Robust standard deviation of the background residual (same unit as height).
    """
    background, sigma, _ = _fit(height, mask, method, degree, iterations, xy)
    return background, sigma


def _fit(height, mask, method, degree, iterations, xy, full: bool = True):
    """:func:`fit_background`, also returning the grid background's separable terms.

    The terms are pairs ``(column, row)`` of 1-D arrays, shapes (H,) and (W,), with
    ``background = sum(outer(column, row))`` (``None`` with ``xy``): its slopes follow
    from 1-D gradients without a full-image :func:`numpy.gradient`. ``full=False`` on the
    grid: the background image is not built (None), only its terms.
    """
    z = _height(height)
    if method not in ("plane", "smooth"):
        raise InputError(f"method: expected 'plane' or 'smooth', got {method!r}")
    deg = 1 if method == "plane" else int(degree)
    if deg < 1:
        raise InputError(f"degree: must be at least 1, got {degree}")
    ok = np.isfinite(z)
    if mask is not None:
        ok &= as_array(mask, "mask", shape=z.shape, dtype=bool)
    coords = None
    if xy is not None:
        pts = as_array(xy, "xy", shape=z.shape + (2,), finite=False)
        ok &= np.isfinite(pts).all(axis=2)
        if not ok.any():
            raise InputError("height: no usable pixel for the background")
        coords = _scaled_xy(pts, ok)
    flat = _spread_sample(ok, _MAX_FIT_POINTS)
    n_terms = (deg + 1) * (deg + 2) // 2
    if flat.size < 3 * n_terms:
        raise InputError(f"height: only {flat.size} usable pixels for a degree-{deg} background")
    rows, cols = np.divmod(flat, z.shape[1])
    A = _design(rows, cols, z.shape, deg, coords)
    values = z.ravel()[flat].astype(np.float64)  # a float32 height: the fit in float64 all the same
    del rows, cols, flat
    use = np.ones(values.size, bool)
    sigma = 0.0
    for _ in range(int(iterations)):
        coef = _least_squares(A if use.all() else A[use], values[use])
        r = values - A @ coef
        sigma = _MAD_TO_SIGMA * float(np.median(np.abs(r[use] - np.median(r[use]))))
        new = np.abs(r) <= max(3.0 * sigma, 1e-12 * (np.abs(values).max() + 1.0))
        if new.sum() < 3 * n_terms or np.array_equal(new, use):
            break
        use = new
    if coords is not None:
        # powers built by repeated products (no pow on whole images, no ones for x^0 y^0)
        xs, ys = [None, coords[0]], [None, coords[1]]
        for _ in range(2, deg + 1):
            xs.append(xs[-1] * coords[0])
            ys.append(ys[-1] * coords[1])
        background = np.full(z.shape, float(coef[0]))
        k = 1
        for d in range(1, deg + 1):
            for a in range(d + 1):
                term = ys[d] if a == 0 else xs[a] if a == d else xs[a] * ys[d - a]
                background += coef[k] * term
                k += 1
        return background, sigma, None
    # Grouped by the power of y, term = outer(y^b, sum_a c x^a): deg + 1 full-image
    # products and no (H * W, terms) design matrix in memory.
    x, _ = _scaled(0.0, np.arange(z.shape[1], dtype=float), z.shape)
    _, y = _scaled(np.arange(z.shape[0], dtype=float), 0.0, z.shape)
    rows_of = [np.zeros(z.shape[1]) for _ in range(deg + 1)]
    k = 0
    for d in range(deg + 1):
        for a in range(d + 1):
            rows_of[d - a] += coef[k] * x**a
            k += 1
    terms = [(y**b, rows_of[b]) for b in range(deg + 1)]
    if not full:
        return None, sigma, terms
    background = np.outer(terms[0][0], terms[0][1])
    for col, row in terms[1:]:
        background += np.outer(col, row)
    return background, sigma, terms


def measure_defects(
    height,
    pixel_size: float = 1.0,
    mask=None,
    *,
    background: str = BACKGROUND,
    degree: int = 3,
    threshold_mm: float | None = None,
    extent_mm: float | None = None,
    min_area_px: int = 20,
    polarity: str = "depression",
    p=None,
    q=None,
    slope_threshold: float | None = None,
    xy=None,
    area=None,
    return_labels: bool = False,
) -> list[dict] | tuple[list[dict], np.ndarray]:
    """Segment and measure defects of a height field.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height in mm (e.g. :func:`photometric.integrate.integrate` with the pixel size);
        NaN outside the inspected area.
    pixel_size : float, optional
        Pixel size in mm.
    mask : array_like, shape (H, W), optional
        Inspected area (default: finite pixels).
    background : {"plane", "smooth", "none"}
        What to remove first (see :func:`fit_background`).
    degree : int, optional
        Degree of the smooth background.
    threshold_mm : float, optional
        Detection depth; default ``max(6 sigma, 5 %`` of the deepest point``)``.
    extent_mm : float, optional
        Depth down to which a detected region extends; default
        ``max(2 sigma, 0.5 %`` of the deepest point``)``.
    min_area_px : int, optional
        Smaller regions are ignored.
    polarity : {"depression", "bump", "both"}
        Defects below the background (cracks, scratches, dents), above it, or both.
    p, q : array_like, shape (H, W), optional
        Measured slopes ``dz/dx``, ``dz/dy`` (y up). When given, a defect's footprint
        is where the slope differs from the background's by more than
        ``slope_threshold`` (holes filled: flat crack bottoms and dent centres), which
        is sharper than a depth threshold on the integrated height (integration spreads
        the error of each slope kink over a few pixels). Regions must still reach the
        detection depth.
    slope_threshold : float, optional
        Default ``max(0.02, 6 sigma)`` of the background slope residual.
    xy : array_like, shape (H, W, 2), optional
        ``x, y`` (mm) of the point each pixel sees (perspective camera); positions,
        lengths and widths are measured on these, and each defect gets ``center_mm``.
    area : float or array_like, shape (H, W), optional
        Each pixel's footprint on the ``x, y`` plane, mm^2 (with ``xy``; default
        ``pixel_size^2``); areas and volumes sum it.

    Returns
    -------
    list of dict
        One dict per defect, deepest first, with ``id``, ``kind`` ("depression" or
        "bump"), ``max_depth_mm`` (for a bump: its height), ``mean_width_mm`` (area of
        the central half of the length divided by that half-length),
        ``max_width_mm`` (extent across the axis), ``length_mm`` (along the
        principal axis: the stadium with the region's area and second moment along the
        axis, between the extent of its pixel centres and that plus two pixels; sub-pixel,
        see :func:`_stadium_length`), ``area_mm2``, ``volume_mm3`` (``sum depth * h^2``),
        ``axis_deg`` (principal axis, from +x towards +y, in (-90, 90]),
        ``center_px`` (row, col, depth-weighted), ``bbox_px`` (min_row, min_col,
        max_row, max_col), ``area_px`` and the thresholds used; with ``xy`` also
        ``center_mm`` (x, y, depth-weighted).
    labels : numpy.ndarray, shape (H, W), int32
        Only with ``return_labels``: ``id + 1`` on each defect's pixels, 0 elsewhere.
    """
    z = _height(height)
    h = positive(pixel_size, "pixel_size")
    if polarity not in ("depression", "bump", "both"):
        raise InputError(f"polarity: expected 'depression', 'bump' or 'both', got {polarity!r}")
    inspect = np.isfinite(z)
    if mask is not None:
        inspect &= as_array(mask, "mask", shape=z.shape, dtype=bool)
    if not inspect.any():
        raise InputError("height: no finite pixel to inspect")
    pts = foot = None
    if xy is not None:
        pts = as_array(xy, "xy", shape=z.shape + (2,), finite=False)
        foot = np.broadcast_to(np.float64(h * h), z.shape) if area is None else np.broadcast_to(
            as_array(area, "area", ndim=(0, 2), finite=False), z.shape)
        inspect &= np.isfinite(pts).all(axis=2) & np.isfinite(foot)
        if not inspect.any():
            raise InputError("xy: no finite point to inspect")
    elif area is not None:
        raise InputError("area: per-pixel footprints need xy (the points they belong to)")
    if background == "none":
        terms = []  # flat: the slopes' background is zero
        values = z[inspect].astype(np.float64, copy=False)
        base = _Background(None, [], float(np.nanmedian(values)))
        sigma = _MAD_TO_SIGMA * float(np.median(np.abs(values - base.constant)))
        del values
    elif background in ("plane", "smooth"):
        # on the pixel grid only the separable terms: residuals are formed block by block
        bg, sigma, terms = _fit(z, inspect, background, degree, 6, pts, full=pts is not None)
        base = _Background(bg, terms or [], 0.0)
    else:
        raise InputError(f"background: expected 'plane', 'smooth' or 'none', got {background!r}")

    footprint = None
    if p is not None or q is not None:
        if p is None or q is None:
            raise InputError("p, q: give both slopes or neither")
        footprint = _slope_footprint(
            _slopes(p, "p", z.shape), _slopes(q, "q", z.shape),
            _background_slopes(base.image, terms), inspect, h, slope_threshold, pts,
        )

    signs = {"depression": (-1.0,), "bump": (1.0,), "both": (-1.0, 1.0)}[polarity]
    results: list[dict] = []
    candidates = objects = None
    if footprint is not None:
        candidates = _label(footprint)
        del footprint
        objects = ndimage.find_objects(candidates)
    labels_out = np.zeros(z.shape, np.int32) if return_labels else None
    for sign in signs:
        # one residual pass: the deepest point, and the float32 depth image (hysteresis) or each
        # slope-footprint component's deepest point (footprint)
        depth = np.zeros(z.shape, np.float32) if candidates is None else None
        reach = None if candidates is None else np.full(len(objects) + 1, -np.inf)
        deepest = -np.inf
        for res, ok, rows in _residual_blocks(z, base, inspect):
            d = np.multiply(sign, res, out=res)
            deepest = max(deepest, float(np.max(d, where=ok, initial=-np.inf)))
            if depth is not None:
                np.copyto(depth[rows], d, where=ok, casting="unsafe")
            else:
                cand = candidates[rows]
                sel = ok & (cand > 0)
                np.maximum.at(reach, cand[sel], d[sel])
        if not inspect.all():
            deepest = max(deepest, 0.0)  # pixels outside the inspected area count as depth 0
        if deepest <= 0:
            continue
        high = threshold_mm if threshold_mm is not None else max(6.0 * sigma, 0.05 * deepest)
        low = extent_mm if extent_mm is not None else max(2.0 * sigma, 0.005 * deepest)
        high = positive(high, "threshold_mm")
        low = min(positive(low, "extent_mm"), high)
        if depth is not None:
            kept = _hysteresis(depth, low, high)
            del depth
            kept &= inspect
            labels = _label(kept)
            del kept
            regions = _regions_in(labels, ndimage.find_objects(labels), None, z, base, sign)
        else:
            hit = np.flatnonzero(reach > high)
            regions = _regions_in(candidates, objects, hit, z, base, sign)
        kind = "depression" if sign < 0 else "bump"
        for reg in regions:
            if reg.area < min_area_px:
                continue
            if pts is None:
                results.append(_measure(reg, z, base, sign, h, kind, low, high, sigma))
            else:
                results.append(_measure_points(reg, z, base, sign, pts, foot, kind, low, high, sigma))
            if labels_out is not None:
                labels_out[reg.box][reg.mask] = len(results)  # renumbered below
    order = sorted(range(len(results)), key=lambda i: -results[i]["max_depth_mm"])
    results = [results[i] for i in order]
    for i, rec in enumerate(results):
        rec["id"] = i
    if labels_out is None:
        return results
    lut = np.zeros(len(results) + 1, np.int32)
    lut[np.asarray(order, np.int64) + 1] = np.arange(1, len(results) + 1)
    for rows in _row_blocks(z.shape):
        labels_out[rows] = lut[labels_out[rows]]
    return results, labels_out


#: pixels per row block of the whole-image passes (their float64 temporaries stay in the CPU cache)
_BLOCK_PIXELS = 1 << 16
# 8-connected regions, as skimage's label(connectivity=2)
_EIGHT = np.ones((3, 3), bool)


@dataclass(frozen=True)
class _Background:
    """The removed background: a full image (on points), separable grid terms, or a constant."""

    image: np.ndarray | None
    terms: list
    constant: float

    def block(self, rows: slice, cols: slice = slice(None)):
        """The background over ``[rows, cols]`` (float64, or the constant)."""
        if self.image is not None:
            return self.image[rows, cols]
        if not self.terms:
            return self.constant
        (col, row), *rest = self.terms
        out = np.outer(col[rows], row[cols])
        for col, row in rest:
            out += np.outer(col[rows], row[cols])
        return out

    def at(self, rows: np.ndarray, cols: np.ndarray):
        """The background at pixels ``(rows, cols)`` (the values :meth:`block` gives there)."""
        if self.image is not None:
            return self.image[rows, cols]
        if not self.terms:
            return self.constant
        (col, row), *rest = self.terms
        out = col[rows] * row[cols]
        for col, row in rest:
            out += col[rows] * row[cols]
        return out


@dataclass(frozen=True)
class _Region:
    """One connected defect region: a boolean crop of its bounding box and the box's place.

    No per-pixel coordinates or depths are kept (they were 40 bytes per region pixel, with
    float64 copies in the measures): :meth:`pixels` gives them a block of rows at a time.
    """

    mask: np.ndarray  # (h, w) bool, the region's pixels inside its bounding box
    row0: int
    col0: int

    @property
    def area(self) -> int:
        return int(np.count_nonzero(self.mask))

    @property
    def box(self) -> tuple[slice, slice]:
        return (slice(self.row0, self.row0 + self.mask.shape[0]), slice(self.col0, self.col0 + self.mask.shape[1]))

    @property
    def bbox(self) -> tuple[int, int, int, int]:
        """(min_row, min_col, max_row + 1, max_col + 1)."""
        return (self.row0, self.col0, self.row0 + self.mask.shape[0], self.col0 + self.mask.shape[1])

    def pixels(self):
        """``(rows, cols)`` (image coordinates, int64) of the region's pixels in raster order, a block
        of rows of its box at a time."""
        for rows in _row_blocks(self.mask.shape):
            r, c = np.nonzero(self.mask[rows])
            yield r + (self.row0 + rows.start), c + self.col0


def _height(value) -> np.ndarray:
    """Height checked for two dimensions, kept in its float type: a float32 height (the pipeline's)
    is not copied to float64 (8 bytes per pixel); every residual is formed in float64 from it, so the
    figures are those of the float64 copy."""
    arr = as_array(value, "height", ndim=2, dtype=None, finite=False)
    return arr if np.issubdtype(arr.dtype, np.floating) else arr.astype(np.float64)


def _slopes(value, name: str, shape) -> np.ndarray:
    """Slopes checked for shape, kept in their float type (a float32 map is not copied to float64:
    the excess over the background is formed in float64 block by block)."""
    arr = as_array(value, name, shape=shape, dtype=None, finite=False)
    return arr if np.issubdtype(arr.dtype, np.floating) else arr.astype(np.float64)


def _median(values: np.ndarray) -> float:
    """``np.median`` of a large 1-D array, exactly, without partitioning all of it.

    The two middle ranks lie, but for a rare sample, between two order statistics of an evenly
    spread sample of about 20 000 values (4 standard deviations of a sample rank on either
    side of its middle): one count below that bracket and a partition of the few values inside
    it give them (when the bracket misses, or a value is NaN: the full :func:`numpy.median`).
    About 4 passes over the values instead of a partition of all of them (a third of the time
    at 5 MP).
    """
    n = values.size
    if n < 1 << 16:
        return float(np.median(values))
    sample = np.sort(values[:: n // 20_000])
    m = sample.size
    spread = 4.0 * np.sqrt(m)
    a, b = sample[max(0, int(m / 2 - spread))], sample[min(m - 1, int(m / 2 + spread))]
    lo, hi = (n - 1) // 2, n // 2
    if np.isfinite(a) and np.isfinite(b):
        # counted and gathered a block at a time: no boolean arrays of every value
        below = above = 0
        parts = []
        for start in range(0, n, _BLOCK_PIXELS):
            v = values[start:start + _BLOCK_PIXELS]
            below += int(np.count_nonzero(v < a))
            above += int(np.count_nonzero(v > b))
            parts.append(v[(v >= a) & (v <= b)])
        inside = np.concatenate(parts)
        del parts
        # NaN is in none of the three parts (np.median then gives NaN)
        whole = below + inside.size + above == n
        if whole and below <= lo and hi < below + inside.size:
            middle = np.partition(inside, [lo - below, hi - below])[[lo - below, hi - below]]
            return float(np.mean(middle))  # as np.median: the mean of the two in the array's dtype
    return float(np.median(values))


def _row_blocks(shape):
    step = max(1, _BLOCK_PIXELS // max(shape[1], 1))
    return [slice(r0, min(shape[0], r0 + step)) for r0 in range(0, shape[0], step)]


def _residual_blocks(z: np.ndarray, base: _Background, inspect: np.ndarray):
    """``(z - background, inspect, rows)`` over blocks of rows (float64, NaN where not inspected):
    no full-image residual or background in memory."""
    for rows in _row_blocks(z.shape):
        yield np.subtract(z[rows], base.block(rows), dtype=np.float64), inspect[rows], rows


def _label(mask: np.ndarray) -> np.ndarray:
    """8-connected labels of a mask, int32 (half of skimage's int64)."""
    return ndimage.label(mask, structure=_EIGHT, output=np.int32)[0]


def _hysteresis(depth: np.ndarray, low: float, high: float) -> np.ndarray:
    """:func:`skimage.filters.apply_hysteresis_threshold` (the same comparisons and 4-connected
    components, the same pixels) without its float64 and int64 copies of the image: the
    components that hold a pixel above ``high`` are marked from those pixels' labels."""
    low = np.clip(low, a_min=None, a_max=high)  # a float64 scalar, compared as skimage does
    labels, _ = ndimage.label(depth > low)
    hit = np.zeros(int(labels.max()) + 1, bool)
    hit[labels[depth > high]] = True
    return hit[labels]


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """:func:`scipy.ndimage.binary_fill_holes` (4-connected background) by one OpenCV flood fill
    of the background from outside the image: one pass instead of iterated dilations."""
    h, w = mask.shape
    pad = np.zeros((h + 2, w + 2), np.uint8)
    pad[1:-1, 1:-1] = mask
    cv2.floodFill(pad, None, (0, 0), 2, flags=4)
    return pad[1:-1, 1:-1] != 2


def _regions_in(labels: np.ndarray, objects: list, ids, z: np.ndarray, base: _Background, sign: float):
    """The :class:`_Region` of each label ``k`` in ``ids`` (every label with ``ids=None``), in order.

    With ``ids`` (the slope footprints that reach the detection depth) each region is split into
    its 8-connected parts where ``sign (z - bg) > 0``, found inside its bounding box (the residual
    a block of rows at a time: no float64 box in memory).
    """
    for k in range(1, len(objects) + 1) if ids is None else ids:
        box = objects[k - 1]
        if box is None:
            continue
        part = labels[box] == k
        if ids is None:
            yield _Region(part, box[0].start, box[1].start)
            continue
        for rows in _row_blocks(part.shape):
            image_rows = slice(box[0].start + rows.start, box[0].start + rows.stop)
            res = np.subtract(z[image_rows, box[1]], base.block(image_rows, box[1]), dtype=np.float64)
            part[rows] &= np.multiply(sign, res, out=res) > 0
        sub = _label(part)
        del part
        for j, piece in enumerate(ndimage.find_objects(sub), start=1):
            if piece is not None:
                yield _Region(sub[piece] == j, box[0].start + piece[0].start, box[1].start + piece[1].start)


def _background_slopes(background, terms):
    """``d/d row`` and ``d/d col`` of the background, as :func:`numpy.gradient` on the pixel grid.

    With the separable terms of :func:`_fit` the gradient of each term is the outer product
    of a 1-D gradient with the other factor (central differences are linear); constant
    factors stay scalars, so a plane's slopes broadcast from one row and one column
    instead of two full images. Without terms (a background on points): ``np.gradient``.
    """
    if terms is None:
        return np.gradient(background)
    d_row = d_col = 0.0
    for col, row in terms:
        g_col, g_row = np.gradient(col), np.gradient(row)
        col_c = col[0] if np.all(col == col[0]) else col[:, None]
        row_c = row[0] if np.all(row == row[0]) else row[None, :]
        if g_row.any():
            d_col = d_col + col_c * g_row[None, :]
        if g_col.any():
            d_row = d_row + g_col[:, None] * row_c
    return d_row, d_col


def _slope_footprint(p, q, slopes, inspect, h, slope_threshold, xy=None) -> np.ndarray:
    """Pixels whose slope differs from the background's (``slopes``: its ``d/d row, d/d col``,
    broadcastable); enclosed flat parts included.

    Row block by row block, in float32: the slope excess is formed twice (for the threshold's
    medians and for the comparison) instead of being kept as a full image.
    """
    d_row, d_col = slopes
    if xy is None:
        dx_col, dy_row = h, -h
    else:
        # chain rule on the pixel grid: x runs along the columns, y (up) against the rows
        dx_col = np.gradient(np.nan_to_num(xy[..., 0]), axis=1)
        dy_row = np.gradient(np.nan_to_num(xy[..., 1]), axis=0)
        dx_col = np.where(np.abs(dx_col) > 0, dx_col, h)
        dy_row = np.where(np.abs(dy_row) > 0, dy_row, -h)

    def part(a, rows):
        return a[rows] if np.ndim(a) == 2 and a.shape[0] != 1 else a

    def excess(rows):
        # float32 (the slopes' own precision): the background's slopes broadcast from a row and a
        # column on the grid, the difference's length in one OpenCV pass
        with np.errstate(over="ignore"):  # a huge (non-finite input) excess is inf in float32
            dp = np.subtract(p[rows], part(d_col, rows) / part(dx_col, rows), dtype=np.float32)
            dq = np.subtract(q[rows], part(d_row, rows) / part(dy_row, rows), dtype=np.float32)
        out = cv2.magnitude(np.ascontiguousarray(dp), np.ascontiguousarray(dq))
        # one finiteness test instead of nan_to_num's three passes (solvers give finite slopes)
        if not np.isfinite(out.sum()):
            out = cv2.magnitude(np.nan_to_num(dp), np.nan_to_num(dq))
        return out

    blocks = _row_blocks(p.shape)
    if slope_threshold is None:
        # the inspected slopes once, compact float32, partitioned in place by both medians
        values = np.empty(np.count_nonzero(inspect), np.float32)
        n = 0
        for rows in blocks:
            v = excess(rows)[inspect[rows]]
            values[n:n + v.size] = v
            n += v.size
        med = _median(values)
        values -= np.float32(med)
        sigma = _MAD_TO_SIGMA * _median(np.abs(values, out=values))
        del values
        slope_threshold = max(0.02, med + 6.0 * sigma)
    thr = positive(slope_threshold, "slope_threshold")
    above = np.empty(p.shape, bool)
    for rows in blocks:
        np.greater(excess(rows), thr, out=above[rows])
    above &= inspect
    return _fill_holes(above)



def _stadium_length(area, second, extent, pitch):
    """Sub-pixel length of regions from their area and second moment along their axis.

    Pixel counts are unbiased samples of a shape's area and of its second moment
    ``sum s^2`` along an axis (at a random sub-pixel place), where the extent of the pixel
    centres is not: the true ends lie beyond the outermost centres by a gap that depends
    on the axis against the grid (the former ``extent + 1`` pixel read about 0.4 pixel long
    on oblique axes). The length is that of the stadium (a rectangle of length ``c`` and
    width ``w`` with half-disc ends: area ``c w + pi w^2 / 4``, second moment
    ``w c^3 / 12 + pi w^2 c^2 / 16 + c w^3 / 6 + pi w^4 / 64``) with the region's area and
    second moment, ``c + w``; kept between the extent of the centres and that extent plus
    two pitches (each end lies within a pitch beyond its outermost centre), so that a
    region far from a stadium keeps a length near its extent.

    Parameters
    ----------
    area : float or numpy.ndarray, shape (n,)
        Area of each region (pixels, or mm^2 on points), > 0.
    second : float or numpy.ndarray, shape (n,)
        ``sum s^2`` (times each pixel's area on points) about the centroid along the axis.
    extent : float or numpy.ndarray, shape (n,)
        ``s.max() - s.min()`` of the pixel centres (pixels or mm).
    pitch : float or numpy.ndarray
        Pixel pitch in the same unit (1 on the grid).

    Returns
    -------
    numpy.ndarray or float
        The length (same unit as ``extent``), the shape of the inputs.
    """
    A, second = np.asarray(area, float), np.asarray(second, float)
    w_max = np.sqrt(4.0 * A / np.pi)

    def moment(w):
        c = (A - 0.25 * np.pi * w * w) / w
        return w * c**3 / 12.0 + np.pi * w * w * c * c / 16.0 + c * w**3 / 6.0 + np.pi * w**4 / 64.0

    # the moment falls monotonically from a thin bar (w -> 0) to the disc (w = w_max)
    lo, hi = 1e-6 * w_max, w_max.copy()
    for _ in range(48):
        mid = 0.5 * (lo + hi)
        thick = moment(mid) <= second
        hi = np.where(thick, mid, hi)
        lo = np.where(thick, lo, mid)
    w = 0.5 * (lo + hi)
    length = (A - 0.25 * np.pi * w * w) / w + w
    out = np.clip(length, extent, np.asarray(extent, float) + 2.0 * np.asarray(pitch, float))
    return float(out) if out.ndim == 0 else out


def _axis_angle(cov: np.ndarray) -> tuple[np.ndarray, float]:
    """Principal axis (unit vector, x right, y up) of a 2 x 2 covariance and its angle from +x
    towards +y in degrees, in (-90, 90]."""
    axis = np.linalg.eigh(cov)[1][:, 1]
    angle = float(np.degrees(np.arctan2(axis[1], axis[0])))
    angle = (angle + 90.0) % 180.0 - 90.0
    return axis, 90.0 if angle == -90.0 else angle


def _axis_extents(reg, along, second_of) -> tuple[float, float, float, float, float]:
    """Extents of a region along and across its axis, and its second moment along it.

    ``along(r, c)`` gives the pixels' ``(s, t)`` (along, across the axis) for a block of
    the region's rows and columns (``reg.pixels()``); ``second_of(r, c, s)`` the block's
    share of the second moment. Returns ``s_lo, s_hi, t_lo, t_hi, second``.
    """
    s_lo = t_lo = np.inf
    s_hi = t_hi = -np.inf
    second = 0.0
    for r, c in reg.pixels():
        s, t = along(r, c)
        s_lo, s_hi = min(s_lo, float(s.min())), max(s_hi, float(s.max()))
        t_lo, t_hi = min(t_lo, float(t.min())), max(t_hi, float(t.max()))
        second += second_of(r, c, s)
    return s_lo, s_hi, t_lo, t_hi, second


def _measure(reg: _Region, z: np.ndarray, base: _Background, sign: float, h: float, kind: str, low: float,
             high: float, sigma: float) -> dict:
    """Physical measures of one region on the pixel grid.

    Three passes over the region's pixels, a block of rows of its box at a time, so that nothing
    per region pixel is kept: (1) the count, the sums of rows, columns and their products as exact
    integers (Python ``int``: the covariance is exact before its one rounding) and the float64
    depth sums; (2) the extents along and across the principal axis and the second moment along
    it; (3) the pixels of the central half of the length. Depths are the float64 residual
    ``sign (z - background)`` at each pixel.
    """
    n = sr = sc = srr = scc = src = 0
    wsum = wr = wc = 0.0
    deepest = -np.inf
    for r, c in reg.pixels():
        d = np.subtract(z[r, c], base.at(r, c), dtype=np.float64)
        d *= sign
        n += r.size
        sr, sc = sr + int(r.sum()), sc + int(c.sum())
        srr, scc, src = srr + int(r @ r), scc + int(c @ c), src + int(r @ c)
        deepest = max(deepest, float(d.max()))
        wsum += float(d.sum())
        wr, wc = wr + float(r @ d), wc + float(c @ d)
    mean_r, mean_c = sr / n, sc / n
    if n > 1:
        # x = col - mean, y = -(row - mean): cov(x, y) = -cov(col, row)
        cxy = -(n * src - sr * sc) / (n * (n - 1))
        cov = np.array([[(n * scc - sc * sc) / (n * (n - 1)), cxy], [cxy, (n * srr - sr * sr) / (n * (n - 1))]])
    else:
        cov = np.eye(2)
    axis, angle = _axis_angle(cov)

    def along(r, c):
        x, y = c - mean_c, mean_r - r
        return x * axis[0] + y * axis[1], y * axis[0] - x * axis[1]

    s_lo, s_hi, t_lo, t_hi, second = _axis_extents(reg, along, lambda r, c, s: float(s @ s))
    length_px = _stadium_length(float(n), second, s_hi - s_lo, 1.0)
    mid, half = 0.5 * (s_hi + s_lo), 0.25 * length_px
    central = sum(int(np.count_nonzero(np.abs(along(r, c)[0] - mid) <= half)) for r, c in reg.pixels())
    mean_width_px = float(central / max(0.5 * length_px, 1.0))
    return {
        "kind": kind,
        "max_depth_mm": deepest,
        "mean_width_mm": mean_width_px * h,
        "max_width_mm": float(t_hi - t_lo + 1.0) * h,
        "length_mm": length_px * h,
        "area_mm2": float(n) * h * h,
        "volume_mm3": wsum * h * h,
        "axis_deg": angle,
        "center_px": [wr / wsum, wc / wsum],
        "bbox_px": [int(v) for v in reg.bbox],
        "area_px": int(n),
        "threshold_mm": float(high),
        "extent_mm": float(low),
        "background_sigma_mm": float(sigma),
    }


def _measure_points(reg: _Region, z: np.ndarray, base: _Background, sign: float, xy: np.ndarray,
                    foot: np.ndarray, kind: str, low: float, high: float, sigma: float) -> dict:
    """:func:`_measure` on each pixel's own point ``xy`` and footprint area ``foot`` (perspective).

    The same three passes; the point sums are float64 about the region's first point (no
    cancellation of a region far from the origin).
    """
    first = next(reg.pixels())
    ref_x, ref_y = float(xy[first[0][0], first[1][0], 0]), float(xy[first[0][0], first[1][0], 1])
    n = 0
    su = sv = suu = svv = suv = 0.0
    a_sum = a_u = a_v = 0.0
    wsum = wr = wc = wx = wy = volume = 0.0
    deepest = -np.inf
    for r, c in reg.pixels():
        d = np.subtract(z[r, c], base.at(r, c), dtype=np.float64)
        d *= sign
        px, py, a = xy[r, c, 0], xy[r, c, 1], foot[r, c]
        u, v = px - ref_x, py - ref_y
        n += r.size
        su, sv = su + float(u.sum()), sv + float(v.sum())
        suu, svv, suv = suu + float(u @ u), svv + float(v @ v), suv + float(u @ v)
        a_sum, a_u, a_v = a_sum + float(a.sum()), a_u + float(a @ u), a_v + float(a @ v)
        deepest = max(deepest, float(d.max()))
        wsum += float(d.sum())
        wr, wc = wr + float(r @ d), wc + float(c @ d)
        wx, wy = wx + float(px @ d), wy + float(py @ d)
        volume += float(d @ a)
    side = float(np.sqrt(a_sum / n))
    mean_u, mean_v = su / n, sv / n
    if n > 1:
        cuv = (suv - su * sv / n) / (n - 1)
        cov = np.array([[(suu - su * su / n) / (n - 1), cuv], [cuv, (svv - sv * sv / n) / (n - 1)]])
    else:
        cov = np.eye(2)
    axis, angle = _axis_angle(cov)
    # the area-weighted centroid along the axis, from the first pass's sums
    s_mean = (axis[0] * (a_u - mean_u * a_sum) + axis[1] * (a_v - mean_v * a_sum)) / a_sum

    def along(r, c):
        x, y = xy[r, c, 0] - ref_x - mean_u, xy[r, c, 1] - ref_y - mean_v
        return x * axis[0] + y * axis[1], y * axis[0] - x * axis[1]

    s_lo, s_hi, t_lo, t_hi, second = _axis_extents(
        reg, along, lambda r, c, s: float(foot[r, c] @ ((s - s_mean) * (s - s_mean))))
    length = _stadium_length(a_sum, second, s_hi - s_lo, side)
    mid, half = 0.5 * (s_hi + s_lo), 0.25 * length
    central = 0.0
    for r, c in reg.pixels():
        central += float(foot[r, c][np.abs(along(r, c)[0] - mid) <= half].sum())
    return {
        "kind": kind,
        "max_depth_mm": deepest,
        "mean_width_mm": central / max(0.5 * length, side),
        "max_width_mm": float(t_hi - t_lo) + side,
        "length_mm": length,
        "area_mm2": a_sum,
        "volume_mm3": volume,
        "axis_deg": angle,
        "center_px": [wr / wsum, wc / wsum],
        "center_mm": [wx / wsum, wy / wsum],
        "bbox_px": [int(v) for v in reg.bbox],
        "area_px": int(n),
        "threshold_mm": float(high),
        "extent_mm": float(low),
        "background_sigma_mm": float(sigma),
    }


def _line_length(dark: np.ndarray, rows: np.ndarray, cols: np.ndarray, ux: float, uy: float, s_lo: float,
                 s_hi: float) -> float:
    """Length (pixels) of a thin dark line from its darkening profile along its axis.

    The darkening summed across the line per pixel of its length is the same at every phase
    (each pixel darkens by the part of it the line covers): the pixels within 1.5 px of the
    component's axis are binned by their centre's place along it (1 px bins, from 3 px before
    its extent to 3 px after), the profile's plateau is its median over the component's
    extent, and each end is where the profile falls to half the plateau (linear between the
    bins). The extent of the centres plus one pixel when the profile has no clear plateau."""
    r0, r1 = max(int(rows.min()) - 4, 0), min(int(rows.max()) + 5, dark.shape[0])
    c0, c1 = max(int(cols.min()) - 4, 0), min(int(cols.max()) + 5, dark.shape[1])
    rr, cc = np.mgrid[r0:r1, c0:c1]
    mr, mc = rows.mean(), cols.mean()
    x, y = cc - mc, -(rr - mr)
    s = x * ux + y * uy
    t = -x * uy + y * ux
    near = (np.abs(t) <= 1.5) & (s >= s_lo - 3.0) & (s <= s_hi + 3.0)
    edges = np.arange(np.floor(s_lo) - 3.0, np.ceil(s_hi) + 4.0)
    profile = np.histogram(s[near], edges, weights=dark[rr[near], cc[near]])[0]
    centres = 0.5 * (edges[:-1] + edges[1:])
    inside = (centres >= s_lo) & (centres <= s_hi)
    plateau = float(np.median(profile[inside])) if inside.any() else 0.0
    fallback = s_hi - s_lo + 1.0
    if not plateau > 0:
        return fallback
    above = np.flatnonzero(profile >= 0.5 * plateau)
    if above.size == 0:
        return fallback
    i, j = int(above[0]), int(above[-1])

    def crossing(k_in: int, k_out: int) -> float:
        if k_out < 0 or k_out >= profile.size:
            return float(centres[k_in])
        a, b = profile[k_in], profile[k_out]
        f = (a - 0.5 * plateau) / max(a - b, 1e-12)
        return float(centres[k_in] + np.clip(f, 0.0, 1.0) * (centres[k_out] - centres[k_in]))

    return max(crossing(j, j + 1) - crossing(i, i - 1), 1.0)


#: Ridge scale (pixels) of :func:`find_hairline_cracks`: a line narrower than a pixel blurs
#: to about a pixel in the images.
_HAIRLINE_SCALE_PX = 1.0


def find_hairline_cracks(
    albedo: np.ndarray,
    pixel_size: float,
    *,
    mask: np.ndarray | None = None,
    exclude: np.ndarray | None = None,
    threshold: float = 6.0,
    min_length_px: float = 8.0,
    min_elongation: float = 4.0,
) -> list[dict]:
    """Cracks narrower than the pixel, found as dark lines in the albedo (or a shading residual).

    A hairline crack a fraction of a pixel wide leaves no groove the height can resolve: its
    walls fall between the pixel centres, so the slopes and the integrated height miss it.
    Each pixel that covers part of it still sees it dark (its walls shadow and absorb), so it
    is a dark line in every image and in the solved albedo. It is found there: the relative
    darkening ``1 - albedo / local mean`` (a Gaussian of 4 px), its ridges at the scale of a
    pixel (:func:`skimage.filters.sato`, bright ridges of the darkening), thresholded with
    hysteresis at ``threshold`` and half of it times the ridge response's robust standard
    deviation (median absolute deviation over the inspected pixels), 8-connected; a component
    is a crack when it is at least ``min_length_px`` long and ``min_elongation`` times longer
    than wide. Its length runs between the points where the darkening summed across it falls
    to half its plateau along its principal axis (:func:`_line_length`); its depth is not
    measured (``max_depth_mm`` None, ``depth_status`` ``"not resolved"``).

    Parameters
    ----------
    albedo : numpy.ndarray, shape (H, W) or (H, W, C)
        Albedo (or any image in which the crack is dark: a shading residual's magnitude
        negated, one of the images divided by its shading); channels are averaged.
    pixel_size : float
        Pixel size, mm (> 0).
    mask : numpy.ndarray of bool, shape (H, W), optional
        Pixels to inspect (default: every finite pixel).
    exclude : numpy.ndarray of bool, shape (H, W), optional
        Pixels of defects the height already resolves (their components are left out).
    threshold : float
        Detection threshold in robust standard deviations of the ridge response (> 0).
    min_length_px, min_elongation : float
        Smallest length (pixels) and length / width of a crack.

    Returns
    -------
    list of dict
        Longest first, each: ``kind`` ("crack"), ``length_mm``, ``mean_width_mm`` (an upper
        bound: the line's pixel footprint), ``axis_deg`` (from +x towards +y, y up, in
        [0, 180)), ``center_px`` (row, col), ``bbox_px`` (r0, c0, r1, c1), ``area_px``,
        ``contrast`` (mean relative darkening on the line), ``max_depth_mm`` (None),
        ``depth_status`` ("not resolved"), ``source`` ("albedo").

    Raises
    ------
    InputError
        A bad shape, pixel size or threshold.
    """
    from skimage.filters import apply_hysteresis_threshold, sato

    a = np.asarray(albedo, dtype=np.float64)
    if a.ndim == 3:
        a = a.mean(axis=2)
    if a.ndim != 2 or min(a.shape) < 8:
        raise InputError(f"albedo: expected an (H, W) or (H, W, C) image of at least 8 x 8 pixels, got {a.shape}")
    h = positive(pixel_size, "pixel_size")
    thr = positive(threshold, "threshold")
    ok = np.isfinite(a)
    if mask is not None:
        m = np.asarray(mask, bool)
        if m.shape != a.shape:
            raise InputError(f"mask: expected shape {a.shape}, got {m.shape}")
        ok &= m
    if ok.sum() < 64:
        return []
    filled = np.where(ok, a, 0.0)
    weight = ndimage.gaussian_filter(ok.astype(np.float64), 4.0)
    local = ndimage.gaussian_filter(filled, 4.0) / np.maximum(weight, 1e-9)
    dark = np.where(ok, 1.0 - filled / np.maximum(local, 1e-9), 0.0)
    ridge = sato(dark, sigmas=[_HAIRLINE_SCALE_PX], black_ridges=False, mode="nearest")
    inner = ndimage.binary_erosion(ok, iterations=3, border_value=0)  # the filters' edges left out
    values = ridge[inner]
    med = float(np.median(values))
    sigma = _MAD_TO_SIGMA * float(np.median(np.abs(values - med)))
    if not sigma > 0:
        return []
    lines = apply_hysteresis_threshold(np.where(inner, ridge - med, 0.0), 0.5 * thr * sigma, thr * sigma)
    lines &= dark > 0
    labels, count = ndimage.label(lines, structure=np.ones((3, 3), bool))
    if exclude is not None:
        ex = np.asarray(exclude, bool)
        if ex.shape != a.shape:
            raise InputError(f"exclude: expected shape {a.shape}, got {ex.shape}")
        drop = np.unique(labels[ex & (labels > 0)])
        labels[np.isin(labels, drop)] = 0
    out = []
    for i, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None:
            continue
        rr, cc = np.nonzero(labels[box] == i)
        n = rr.size
        if n < 3:
            continue
        rows, cols = rr + box[0].start, cc + box[1].start
        x, y = cols - cols.mean(), -(rows - rows.mean())
        cov = np.cov(np.stack([x, y]))
        evals, evecs = np.linalg.eigh(cov)
        ux, uy = evecs[:, 1]
        s = x * ux + y * uy
        length_px = _line_length(dark, rows, cols, ux, uy, float(s.min()), float(s.max()))
        width_px = n / max(float(s.max() - s.min()) + 1.0, 1.0)
        if length_px < min_length_px or length_px < min_elongation * width_px:
            continue
        out.append({
            "kind": "crack",
            "length_mm": length_px * h,
            "mean_width_mm": width_px * h,
            "axis_deg": float(np.degrees(np.arctan2(uy, ux)) % 180.0),
            "center_px": [float(rows.mean()), float(cols.mean())],
            "bbox_px": [int(box[0].start), int(box[1].start), int(box[0].stop), int(box[1].stop)],
            "area_px": int(n),
            "contrast": float(dark[rows, cols].mean()),
            "max_depth_mm": None,
            "depth_status": "not resolved",
            "source": "albedo",
        })
    out.sort(key=lambda r: -r["length_mm"])
    return out
