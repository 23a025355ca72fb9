"""Defect figures as functionals of the height: depth and volume against the fitted
background, their noise variance, and the pixel-grid terms of the budget (the outline's
quantisation, the depth's sampling, the outline's place in the volume)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft
from scipy import ndimage, special

from photometric.defects import _stadium_length
from photometric.uncertainty.budget import _H_POWER
from photometric.uncertainty.heights import _linear_variance, _mode_variance, _point_variance
from surfaces.validate import InputError

_QUANTISATION_OFFSETS = 96


#: Pixel-stadium evaluations of the quantisation of one defect, at most (bounds its cost).
_QUANTISATION_WORK = 1 << 20


_MAX_FIT_POINTS = 200_000
#: Sub-pixel placements of the groove model of the depth's grid error, and the pixels they
#: may integrate together at most (bounds its cost on large defects).
_DEPTH_GRID_OFFSETS = 24
_DEPTH_GRID_WORK = 1 << 20


@dataclass
class _Figures:
    """The linear functionals of one defect: depth and volume against the background fit."""

    sign: float
    peak: tuple[int, int]
    region: np.ndarray  # (n, 2) pixel indices
    d_peak: np.ndarray  # design row at the peak (terms,)
    d_region: np.ndarray  # summed design rows over the region (terms,)


class _Background:
    """A least-squares background (plane or polynomial) over fixed pixels: a linear projector."""

    def __init__(self, usable: np.ndarray, degree: int, shape):
        from photometric.defects import _design

        # flat indices (one index array, not two), picked, then split: the same pixels in
        # the same order as np.nonzero's, at half its cost on a full 4 MP mask
        flat = np.flatnonzero(usable)
        if flat.size > _MAX_FIT_POINTS:
            flat = flat[np.linspace(0, flat.size - 1, _MAX_FIT_POINTS).astype(np.int64)]
        rows, cols = np.divmod(flat, usable.shape[1])
        self.rows, self.cols, self.shape, self.degree = rows, cols, shape, degree
        self.A = _design(rows, cols, shape, degree)
        self.gram_inv = np.linalg.pinv(self.A.T @ self.A)

    def design(self, rows, cols) -> np.ndarray:
        from photometric.defects import _design

        return _design(np.atleast_1d(rows), np.atleast_1d(cols), self.shape, self.degree)

    def coef(self, z: np.ndarray) -> np.ndarray:
        """The fit's coefficients to ``z`` (NaN read as 0, at the fit's pixels only)."""
        return self.gram_inv @ (self.A.T @ np.nan_to_num(z[self.rows, self.cols]))

    def weights(self, d: np.ndarray) -> np.ndarray:
        """Image of the weights with which the fit's value ``d . coef`` takes each pixel."""
        w = np.zeros(self.shape, np.float32)
        w[self.rows, self.cols] = self.A @ (self.gram_inv @ d)  # the fit's pixels are distinct
        return w


def _grown(labels: np.ndarray, defects: list, margin: int) -> np.ndarray:
    """The defects' pixels grown by ``margin`` pixels (dilated within each bounding box)."""
    out = np.zeros(labels.shape, bool)
    for rec in defects:
        r0, c0, r1, c1 = rec["bbox_px"]
        r0, c0 = max(r0 - margin, 0), max(c0 - margin, 0)
        r1, c1 = min(r1 + margin, labels.shape[0]), min(c1 + margin, labels.shape[1])
        window = labels[r0:r1, c0:c1] == rec["id"] + 1
        out[r0:r1, c0:c1] |= ndimage.binary_dilation(window, iterations=margin)
    return out


def _figures(labels: np.ndarray, defects: list, height: np.ndarray, bg: _Background) -> list[_Figures]:
    coef = bg.coef(height)
    out = []
    for rec in defects:
        r0, c0, r1, c1 = rec["bbox_px"]
        region = np.argwhere(labels[r0:r1, c0:c1] == rec["id"] + 1) + (r0, c0)
        sign = -1.0 if rec.get("kind", "depression") == "depression" else 1.0
        design = bg.design(region[:, 0], region[:, 1])
        depth = sign * (height[region[:, 0], region[:, 1]] - design @ coef)
        i = int(np.argmax(depth))
        out.append(_Figures(sign, (int(region[i, 0]), int(region[i, 1])), region, design[i], design.sum(axis=0)))
    return out


def _points(bg: _Background, figs: list) -> tuple[np.ndarray, np.ndarray, list]:
    """Every pixel a systematic field is read at: the background's, then per defect its peak
    and its region; with the slices of each defect's part."""
    rows, cols, parts = [bg.rows], [bg.cols], []
    start = bg.rows.size
    for fig in figs:
        rows += [np.array([fig.peak[0]]), fig.region[:, 0]]
        cols += [np.array([fig.peak[1]]), fig.region[:, 1]]
        parts.append((start, start + 1 + fig.region.shape[0]))
        start = parts[-1][1]
    return np.concatenate(rows), np.concatenate(cols), parts


def _sampler(rows: np.ndarray, cols: np.ndarray, r: int, coarse_shape) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices (n, 4) and weights (n, 4) that read a field of ``r x r`` block means at
    full-resolution pixels bilinearly, as :func:`photometric.nearfield._upsample` does."""
    hc, wc = coarse_shape
    out_i, out_w = [], []
    for pix, n in ((rows, hc), (cols, wc)):
        x = np.clip((pix + 0.5) / r - 0.5, 0.0, n - 1)
        i0 = np.floor(x).astype(np.int64)
        i1 = np.minimum(i0 + 1, n - 1)
        f = x - i0
        out_i.append((i0, i1))
        out_w.append((1.0 - f, f))
    (r0, r1), (c0, c1) = out_i
    (wr0, wr1), (wc0, wc1) = out_w
    idx = np.stack([r0 * wc + c0, r0 * wc + c1, r1 * wc + c0, r1 * wc + c1], axis=1)
    w = np.stack([wr0 * wc0, wr0 * wc1, wr1 * wc0, wr1 * wc1], axis=1)
    return idx, w


def _systematic(fig: _Figures, values: np.ndarray, part: tuple, coef: np.ndarray, h: float) -> tuple[float, float]:
    """Change of (depth, volume) for a systematic height field read at the defect's pixels
    (``values[part]``: peak, then region) with background ``coef``."""
    v = values[part[0]:part[1]]
    depth = fig.sign * (v[0] - fig.d_peak @ coef)
    volume = fig.sign * h * h * (v[1:].sum() - fig.d_region @ coef)
    return float(depth), float(volume)


def _noise_weights(fig: _Figures, bg: _Background, h: float) -> tuple[np.ndarray, np.ndarray]:
    w_depth = -fig.sign * bg.weights(fig.d_peak)
    w_depth[fig.peak] += fig.sign
    w_vol = -fig.sign * h * h * bg.weights(fig.d_region)
    w_vol[fig.region[:, 0], fig.region[:, 1]] += fig.sign * h * h  # distinct pixels
    return w_depth, w_vol


def _noise_functionals(fig: _Figures, bg: _Background, h: float, r: int, T: np.ndarray, var_p: float,
                       var_q: float, cache: dict) -> tuple[float, float]:
    """Noise variance of a defect's depth and volume against the background fit.

    ``r = 1``: exact (:func:`linear_variance` of the weights). Large images (``r > 1``):
    the weights summed over ``r x r`` blocks against the mode variances of the block-mean
    slopes (variance ``/ r^2`` on pixels ``r h``), which hold every scale of the
    background fit and the region; the depth adds the peak pixel's own variance at full
    resolution minus its block's (:func:`_point_variance`).
    """
    if r == 1:
        w_depth, w_vol = _noise_weights(fig, bg, h)
        return _linear_variance(w_depth, T), _linear_variance(w_vol, T)
    shape = (T.shape[0] // r, T.shape[1] // r)
    if "T" not in cache:
        cache["T"] = _mode_variance(shape, var_p / r**2, var_q / r**2, h * r)
    Tc = cache["T"]
    hc, wc = shape
    # block of each weighted pixel (trailing rows and columns belong to the last blocks)
    bg_block = np.minimum(bg.rows // r, hc - 1) * wc + np.minimum(bg.cols // r, wc - 1)
    region_block = (np.minimum(fig.region[:, 0] // r, hc - 1) * wc + np.minimum(fig.region[:, 1] // r, wc - 1))

    def blocks(fit_weights, own_blocks, own_weight):
        out = np.bincount(bg_block, weights=fit_weights, minlength=hc * wc)
        out += np.bincount(own_blocks, minlength=hc * wc) * own_weight
        return out.reshape(hc, wc)

    pr, pc = fig.peak
    peak_block = np.array([min(pr // r, hc - 1) * wc + min(pc // r, wc - 1)])
    b_depth = blocks(-fig.sign * (bg.A @ (bg.gram_inv @ fig.d_peak)), peak_block, fig.sign)
    b_vol = blocks(-fig.sign * h * h * (bg.A @ (bg.gram_inv @ fig.d_region)), region_block, fig.sign * h * h)
    rc, cc = min(pr // r, shape[0] - 1), min(pc // r, shape[1] - 1)
    vd = _linear_variance(b_depth, Tc) + _point_variance(T, pr, pc) - _point_variance(Tc, rc, cc)
    return max(vd, 0.0), _linear_variance(b_vol, Tc)


def _rasterised(width: float, length: float, axis_deg: float, h: float, offsets: np.ndarray) -> dict:
    """Width, length and area (as :func:`photometric.defects.measure_defects` measures them)
    of stadiums (``width``, ``length`` in pixels, axis in degrees) rasterised at sub-pixel
    offsets: the pixel centres inside a stadium are its region, measured as
    :func:`photometric.defects._measure` does (principal axis, the sub-pixel length of
    :func:`photometric.defects._stadium_length`, pixels of the central half per pixel of
    half the length), all stadiums at once.

    ``offsets`` is (n, 2) (``dx, dy``, pixels) or (n, 4) (also ``dwidth, dlength`` added to
    the stadium's width and length, pixels). Returns lists of the measures (mm, mm^2) and,
    under ``"model"``, each stadium's own ``(width, length, area)``; stadiums with fewer than
    two pixels are left out."""
    offsets = np.asarray(offsets, float)
    if offsets.shape[1] == 2:
        offsets = np.concatenate([offsets, np.zeros_like(offsets)], axis=1)
    widths = np.maximum(width + offsets[:, 2], 1.0)
    lengths = np.maximum(length + offsets[:, 3], widths)
    a = math.radians(axis_deg)
    ux, uy = math.cos(a), math.sin(a)
    reach = 0.5 * float(lengths.max()) + 2.0
    half_x = int(math.ceil(abs(ux) * reach + 0.5 * widths.max())) + 2
    half_y = int(math.ceil(abs(uy) * reach + 0.5 * widths.max())) + 2
    y0, x0 = np.meshgrid(-np.arange(-half_y, half_y + 1.0), np.arange(-half_x, half_x + 1.0),
                         indexing="ij")  # y up, rows down
    # only the pixels near the axis can be inside at any offset
    near = (np.abs(-x0 * uy + y0 * ux) < 0.5 * widths.max() + 1.0) & (np.abs(x0 * ux + y0 * uy) < reach)
    xs, ys = x0[near].astype(np.float32), y0[near].astype(np.float32)
    dx, dy = offsets[:, :1].astype(np.float32), offsets[:, 1:2].astype(np.float32)
    half = (0.5 * (lengths - widths)).astype(np.float32)[:, None]
    x, y = xs - dx, ys - dy
    along = np.clip(x * np.float32(ux) + y * np.float32(uy), -half, half)
    radius = (0.5 * widths).astype(np.float32)[:, None]
    inside = np.hypot(x - along * np.float32(ux), y - along * np.float32(uy)) < radius
    n = inside.sum(axis=1)
    keep = n >= 2
    inside, n, widths, lengths = inside[keep], n[keep], widths[keep], lengths[keep]
    values = {"mean_width_mm": [], "length_mm": [], "area_mm2": [], "model": []}
    if not keep.any():
        return values
    # the region's own principal axis (rows, cols of the pixel grid, as _measure takes them)
    w = inside.astype(np.float64)
    X, Y = xs.astype(np.float64), ys.astype(np.float64)
    mx, my = w @ X / n, w @ Y / n
    cxx = w @ (X * X) / n - mx * mx
    cyy = w @ (Y * Y) / n - my * my
    cxy = w @ (X * Y) / n - mx * my
    angle = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    s = np.cos(angle)[:, None] * X + np.sin(angle)[:, None] * Y
    s_max = np.where(inside, s, -np.inf).max(axis=1)
    s_min = np.where(inside, s, np.inf).min(axis=1)
    s_c = s - ((w * s).sum(axis=1) / n)[:, None]
    length_px = _stadium_length(n.astype(float), (w * s_c * s_c).sum(axis=1), s_max - s_min, 1.0)
    central = inside & (np.abs(s - 0.5 * (s_max + s_min)[:, None]) <= 0.25 * length_px[:, None])
    values["mean_width_mm"] = list(central.sum(axis=1) / np.maximum(0.5 * length_px, 1.0) * h)
    values["length_mm"] = list(length_px * h)
    values["area_mm2"] = list(n * h * h)
    areas = ((lengths - widths) * widths + 0.25 * math.pi * widths**2) * h * h
    values["model"] = list(zip(widths * h, lengths * h, areas))
    return values


def _quantisation(rec: dict, h: float, rng: np.random.Generator, grow_mm: float = 0.0) -> dict:
    """Pixel quantisation of the outline: width, length and area measured (as
    :func:`photometric.defects.measure_defects` does) on a stadium of the defect's axis
    rasterised at random sub-pixel offsets.

    The stadium stands for the true outline, so its width and length are first set so that
    their mean measures over a few offsets equal the defect's (one correction: the extent
    along the axis adds up to a pixel, the mean width of a round dent is below its
    diameter). The measures' errors over the offsets are bounded, flat-topped and skewed
    (the outline moves in steps of the pixel pitch projected on the axis), far from normal:
    they are returned as samples for :func:`_quantisation_term`, not as a standard deviation.

    ``grow_mm``: the blurred footprint's widening (:func:`_blur_widening`), taken off the
    measured width and length before the stadium is set (its errors then add to these).

    Returns ``{figure: errors}``: the errors ``measure - stadium`` over the offsets (mm or
    mm^2, shape (n,)); a defect too small to rasterise gets ``±h`` (``±h^2``), the pixel.
    """
    width = max((float(rec["mean_width_mm"]) - grow_mm) / h, 1.0)
    length = max((float(rec["length_mm"]) - grow_mm) / h, width)
    axis = float(rec["axis_deg"])
    first = _rasterised(width, length, axis, h, rng.uniform(-0.5, 0.5, (16, 4)))
    if len(first["mean_width_mm"]) > 2:
        bias_w, bias_l, _ = np.mean(np.asarray([first["mean_width_mm"], first["length_mm"], first["area_mm2"]]).T
                                    - np.asarray(first["model"]), axis=0)
        width = min(max(width - bias_w / h, 1.0), length)
        length = max(length - bias_l / h, width)
    # the true width and length are known to about a pixel only, and how the outline
    # falls on the grid depends on their fractions of a pixel: each stadium draws them
    # large outlines (many pixels) quantise finely: fewer stadiums bound the work
    count = int(np.clip(_QUANTISATION_WORK / ((length + 4.0) * (width + 3.0)), _QUANTISATION_OFFSETS // 3,
                        _QUANTISATION_OFFSETS))
    # plus the four placements on the grid's symmetry points (centre on a pixel centre or
    # between two, along each axis): an axis-aligned outline's largest errors lie there
    draws = np.concatenate([rng.uniform(-0.5, 0.5, (count, 4)),
                            [[dx, dy, *rng.uniform(-0.5, 0.5, 2)] for dx in (0.0, 0.5) for dy in (0.0, 0.5)
                             for _ in range(6)]])
    values = _rasterised(width, length, axis, h, draws)
    model = dict(zip(("mean_width_mm", "length_mm", "area_mm2"), np.asarray(values.pop("model")).T))
    out = {}
    for key, v in values.items():
        if len(v) > 2:
            out[key] = np.asarray(v) - model[key]
        else:
            out[key] = np.array([-1.0, 1.0]) * h ** _H_POWER[key]
    return out


def _coverage_half_width(errors, others: float, level: float = 0.95) -> float:
    """Half-width ``U`` of the interval ``±U`` that holds ``level`` of ``e + N(0, others^2)``,
    ``e`` drawn from the samples ``errors`` (their empirical distribution, bias included,
    convolved with the Gaussian of the other terms; GUM-S1 coverage interval).

    ``P(|e + n| <= U) = mean(Phi((U - e) / s) - Phi((-U - e) / s))`` is solved for ``U`` by
    bisection; with ``others = 0`` it is the ``level`` quantile of ``|e|`` (a uniform error
    of half-range ``a`` gives ``level * a``; no errors and a Gaussian give ``1.96 s``).
    """
    e = np.asarray(errors, float).ravel()
    if e.size == 0:
        raise InputError("errors: need at least one error sample")
    if others <= 0.0:
        return float(np.quantile(np.abs(e), level, method="inverted_cdf"))
    s = float(others)

    def held(U):
        return float(np.mean(special.ndtr((U - e) / s) - special.ndtr((-U - e) / s)))

    lo, hi = 0.0, float(np.abs(e).max()) + 10.0 * s
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if held(mid) < level else (lo, mid)
    return 0.5 * (lo + hi)


def _every_phase_half_width(errors, others: float, level: float = 0.95) -> float:
    """Half-width ``U`` that holds ``level`` of ``e + N(0, others^2)`` for EVERY sample ``e`` of
    ``errors``, not on average over them.

    The samples are a grid error at random sub-pixel places (phases) of one outline or groove.
    For one defect the phase is fixed, not random: an axis-aligned groove whose bottom or rim
    lies between two pixel rows reads the same error at every trial, the tail of the
    phase-averaged distribution. An interval that must hold at every phase is set by the
    largest error: the 95 % half-width of ``Normal(max |e|, others)`` (with ``others = 0``,
    ``max |e|``). Over random phases it then covers more than ``level``.
    """
    e = np.asarray(errors, float).ravel()
    if e.size == 0:
        raise InputError("errors: need at least one error sample")
    worst = float(np.abs(e).max())
    if others <= 0.0:
        return worst
    return 2.0 * math.sqrt(others * others + _bias_term(others, worst) ** 2)


def _quantisation_term(errors, others: float) -> float:
    """Effective standard uncertainty of the outline's quantisation next to the other terms'
    combined standard uncertainty ``others``: the ``u_q`` for which ``2 sqrt(others^2 +
    u_q^2)`` (k = 2, as the budget sums) is :func:`_coverage_half_width` of the errors
    convolved with the Gaussian of the others. A bounded, flat-topped error has a 95 %
    half-width below twice its standard deviation (a uniform one 0.95 x its half-range
    against 1.15), so this ``u_q`` is below the errors' spread there."""
    U = _every_phase_half_width(errors, others)
    return float(math.sqrt(max(0.25 * U * U - others * others, 0.0)))


def _bias_term(spread: float, bias: float) -> float:
    """Standard uncertainty of an uncorrected bias ``b`` next to a spread ``s``: the ``u_b`` for
    which ``2 sqrt(s^2 + u_b^2)`` is the half-width that holds 95 % of ``Normal(b, s)``."""
    b, s = abs(bias), spread
    if b == 0.0:
        return 0.0
    if s <= 0.0:
        return 0.5 * b

    def held(U):
        return 0.5 * (math.erf((U - b) / (s * math.sqrt(2.0))) - math.erf((-U - b) / (s * math.sqrt(2.0))))

    lo, hi = 0.0, b + 10.0 * s
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if held(mid) < 0.95 else (lo, mid)
    return float(math.sqrt(max((0.25 * (lo + hi)) ** 2 - s * s, 0.0)))


#: Standard deviation (pixels) of a box pixel's own area, and its sample offsets in the groove model.
_BOX_SIGMA = 1.0 / math.sqrt(12.0)
_AREA_SAMPLES = (np.arange(4, dtype=np.float32) + np.float32(0.5)) / np.float32(4.0) - np.float32(0.5)


def _groove_slopes(x, y, ux: float, uy: float, half, w: float, depth: float, h: float, section: float):
    """Exact slopes ``(p, q)`` of the groove model of :func:`_groove_depth_errors` at points
    ``x, y`` (pixels, float32), with the squared distance to its central segment and its footprint."""
    f = np.float32
    along = np.clip(x * f(ux) + y * f(uy), -half, half)
    ex, ey = x - along * f(ux), y - along * f(uy)
    d2 = ex * ex + ey * ey
    inside = d2 < f(0.25 * w * w)
    if section == 2.0:
        # dz/dd = 8 D d / w^2 along (ex, ey) / d: the slope is 8 D / (w^2 h) (ex, ey)
        g = np.where(inside, f(8.0 * depth / (w * w * h)), f(0.0))
    else:
        # dz/dd = D p (2 / w)^p d^(p - 1) along (ex, ey) / d (d floored: (ex, ey) is 0 there)
        d = np.maximum(np.sqrt(d2), f(1e-6))
        g = np.where(inside, f(depth * section * (2.0 / w) ** section / h) * d ** f(section - 2.0), f(0.0))
    return g * ex, g * ey, d2, inside


def _groove_depth_errors(depth: float, width: float, length: float, axis_deg: float, h: float,
                         offsets: np.ndarray, integrator: str = "dct", section: float = 2.0,
                         blur_px: float = 0.0, pixel_area: bool = False) -> np.ndarray:
    """Errors of the measured depth (mm) of a groove on the pixel grid.

    The groove ``z = -D (1 - (2 d / w)^p)`` for ``d < w / 2``, ``p = section`` (2: a
    parabolic section, as a U-scratch; 1: a V, as a crack; ``d`` the distance to its
    central segment of length ``L - w``; a stadium outline, ``width``, ``length`` in pixels)
    is sampled as the solve sees it: its exact slopes at the pixel centres, integrated by
    ``integrator`` on a window with a flat margin of 8 pixels (at least half a width), measured as
    :func:`photometric.defects.measure_defects` does: the deepest pixel against a plane fitted
    to the flat plate (3 pixels clear of the rim). Both grid effects are in the error: the
    deepest pixel centre misses the bottom line by up to half a pixel (shallower), and the
    slope's step at the rim, sampled at pixel centres, integrates with a first-order error
    that depends on where the rim falls between two centres; it wanders along the groove
    and the deepest pixel picks its largest excursion (deeper on average; strongest for
    axes near 45 deg and other small rational slopes of the grid).

    ``pixel_area``: each pixel sees the slopes' mean over its area (4 x 4 samples), as a
    camera's pixel (and a render with several samples per pixel) does; ``blur_px`` (Gaussian
    standard deviation, pixels) then blurs them further, as the optics blur the images (for
    small slopes the images are linear in the slopes): a narrow groove reads shallower still.

    ``offsets`` is (n, 4): ``dx, dy`` of the centre and ``dwidth, dlength`` (pixels).
    Returns the n errors (measured minus ``depth``).
    """
    from photometric.integrate import dct_poisson, integrate

    offsets = np.asarray(offsets, float)
    a = math.radians(axis_deg)
    ux, uy = math.cos(a), math.sin(a)
    w_max = width + max(float(offsets[:, 2].max()), 0.0)
    l_max = max(length + max(float(offsets[:, 3].max()), 0.0), w_max)
    margin = int(math.ceil(max(8.0, 0.5 * w_max)))
    hx = int(math.ceil(abs(ux) * 0.5 * (l_max - w_max) + 0.5 * w_max)) + margin + 1
    hy = int(math.ceil(abs(uy) * 0.5 * (l_max - w_max) + 0.5 * w_max)) + margin + 1
    # fast transform lengths: the window grows by a few flat pixels on one side
    rows, cols = sfft.next_fast_len(2 * hy + 1, real=True), sfft.next_fast_len(2 * hx + 1, real=True)
    f = np.float32
    ys, xs = np.meshgrid(f(hy) - np.arange(rows, dtype=f), np.arange(cols, dtype=f) - f(hx),
                         indexing="ij")  # y up, rows down
    errors = np.empty(offsets.shape[0])
    for i, (dx, dy, dw, dl) in enumerate(offsets):
        w = max(width + dw, 1.0)
        half = f(0.5 * (max(length + dl, w) - w))
        x, y = xs - f(dx), ys - f(dy)
        gx, gy, d2, inside = _groove_slopes(x, y, ux, uy, half, w, depth, h, section)
        if pixel_area:
            # each pixel sees the slopes' mean over its area (4 x 4 samples)
            gx, gy = np.zeros_like(gx), np.zeros_like(gy)
            for oy in _AREA_SAMPLES:
                for ox in _AREA_SAMPLES:
                    sx, sy, _, _ = _groove_slopes(x + ox, y + oy, ux, uy, half, w, depth, h, section)
                    gx += sx / f(_AREA_SAMPLES.size ** 2)
                    gy += sy / f(_AREA_SAMPLES.size ** 2)
        if blur_px > 0:
            # the optics' blur, on the slopes (the images are linear in the slopes for small ones)
            gx = ndimage.gaussian_filter(gx, blur_px, mode="nearest")
            gy = ndimage.gaussian_filter(gy, blur_px, mode="nearest")
        if integrator == "dct":
            z = dct_poisson(gx, gy, None, h, dtype=np.float32)
        else:
            z = integrate(gx, gy, integrator, pixel_size=h)
        plate = d2 > f((0.5 * w + 3.0) ** 2)
        # the plane's normal equations (the window's coordinates are centred: well conditioned)
        px, py, pz = xs[plate].astype(float), ys[plate].astype(float), z[plate].astype(float)
        gram = np.array([[px.size, px.sum(), py.sum()], [px.sum(), px @ px, px @ py], [py.sum(), px @ py, py @ py]])
        coef = np.linalg.solve(gram, [pz.sum(), px @ pz, py @ pz])
        measured = coef[0] + coef[1] * xs[inside] + coef[2] * ys[inside] - z[inside]
        errors[i] = float(measured.max()) - depth
    return errors


#: The slope footprint's threshold where a record does not state it (the floor of
#: :func:`photometric.defects._slope_footprint`'s automatic one).
_FOOTPRINT_SLOPE = 0.02


def _blur_widening(rec: dict, h: float, blur_px: float, section: float, pixel_area: bool = False) -> float:
    """How much wider (and longer) the blurred footprint reads than the groove, pixels.

    The footprint is where the slope exceeds its threshold ``t``. Blurred by a Gaussian of
    ``blur_px``, the rim's step of the slope (``s = p D / (w / 2)``, ``p`` the section's
    exponent) becomes the ramp ``s Phi(d / blur_px)``, above ``t`` from ``d = blur_px
    Phi^-1(t / s)`` outside the rim: both rims move out by ``-blur_px Phi^-1(t / s)``. The
    groove's width ``w`` is solved from the measured one (a few fixed-point steps). A pixel that
    integrates its area (``pixel_area``) adds its box's variance, ``1/12`` px^2, to the blur's
    (the ramp taken as a Gaussian of the summed variance). 0 without blur.
    """
    blur_px = math.sqrt(blur_px**2 + (_BOX_SIGMA**2 if pixel_area else 0.0))
    if blur_px <= 0:
        return 0.0
    measured = max(float(rec["mean_width_mm"]) / h, 1.0)
    depth = max(float(rec["max_depth_mm"]), 0.0) / h  # pixels, as the width
    threshold = float(rec.get("slope_threshold", _FOOTPRINT_SLOPE))
    width, grow = measured, 0.0
    for _ in range(6):
        rim = section * depth / max(0.5 * width, 0.5)
        if rim <= threshold:
            return 0.0
        grow = -2.0 * blur_px * float(special.ndtri(threshold / rim))
        width = max(measured - grow, 1.0)
    return max(grow, 0.0)


def _depth_grid(rec: dict, h: float, integrator: str, rng: np.random.Generator,
                blur_px: float = 0.0, pixel_area: bool = False) -> tuple[float, float, np.ndarray]:
    """The depth's pixel-grid error on the model of the defect (:func:`_groove_depth_errors`
    with the measured depth, mean width, length and axis; random sub-pixel centre, width and
    length, the blurred footprint's widening taken off them (:func:`_blur_widening`); the
    slopes averaged over each pixel with ``pixel_area``, blurred by ``blur_px``):
    ``(mean, spread, errors)``, mm. The mean is the method's bias at this axis (not
    corrected: the model's section is an assumption), the spread the discretisation's
    standard uncertainty; the errors themselves (one per placement) bound the bias at the
    defect's own, unknown phase (:func:`_every_phase_half_width`)."""
    section = _section_exponent(rec)
    grow = _blur_widening(rec, h, blur_px, section, pixel_area)
    width = max(float(rec["mean_width_mm"]) / h - grow, 1.0)
    length = max(float(rec["length_mm"]) / h - grow, width)
    a = math.radians(float(rec["axis_deg"]))
    frame = width + 2.0 * max(8.0, 0.5 * width) + 4.0
    window = (abs(math.cos(a)) * (length - width) + frame) * (abs(math.sin(a)) * (length - width) + frame)
    count = int(np.clip(_DEPTH_GRID_WORK / window, _DEPTH_GRID_OFFSETS // 3, _DEPTH_GRID_OFFSETS))
    errors = _groove_depth_errors(float(rec["max_depth_mm"]), width, length, float(rec["axis_deg"]), h,
                                  rng.uniform(-0.5, 0.5, (count, 4)), integrator, section, blur_px,
                                  pixel_area)
    if pixel_area:
        # the images are not linear in steep slopes: the mean intensity over a pixel is not that
        # of its mean slope. Two linearisations bracket it (the slopes' mean over the pixel; the
        # centre's slopes under a Gaussian of the box's variance): both models' errors count
        errors = np.concatenate([errors, _groove_depth_errors(
            float(rec["max_depth_mm"]), width, length, float(rec["axis_deg"]), h, rng.uniform(-0.5, 0.5, (count, 4)),
            integrator, section, math.sqrt(blur_px**2 + _BOX_SIGMA**2), False)])
    # the errors are linear in the depth and the model ran at the measured one: the true depth is
    # measured / (1 + mean relative error), so are the errors' scale (a V's -9 % then reads -10 %)
    depth = float(rec["max_depth_mm"])
    if depth > 0:
        errors = errors / max(1.0 + float(errors.mean()) / depth, 0.5)
    return float(errors.mean()), float(errors.std(ddof=1)), errors


def _section_exponent(rec: dict) -> float:
    """The exponent ``p`` of the defect's section ``D (1 - (2 d / w)^p)``: 1 (a V, as a crack)
    or 2 (a parabola, as a U-scratch or a round dent), whichever its measured fullness
    ``R = volume / (area * depth)`` is nearer.

    A stadium groove of width ``w`` and length ``L`` with that section (its round ends the
    section turned about the end centres) has ``R(p) = ((L - w) w p / (p + 1) + pi w^2 / 4
    p / (p + 2)) / ((L - w) w + pi w^2 / 4)``: 1/2 for a V over a long groove, 2/3 for a
    parabola. The measured ``R`` of a V reads a little fuller (its bottom, missed by up to
    half a pixel, reads shallow), of a parabola a little leaner (the rim's grid error): the
    two are told apart by the mid-point, not fitted in between. 2 when a figure is missing.
    The depth's grid error depends on the section: a V's bottom reads shallower by up to
    its slope times half a pixel, a parabola's hardly.
    """
    try:
        depth, volume, area = (float(rec[k]) for k in ("max_depth_mm", "volume_mm3", "area_mm2"))
        w, L = float(rec["mean_width_mm"]), float(rec["length_mm"])
    except (KeyError, TypeError, ValueError):
        return 2.0
    if not (depth > 0 and volume > 0 and area > 0 and w > 0 and L >= w):
        return 2.0
    side, ends = (L - w) * w, math.pi * w * w / 4.0

    def fullness(p: float) -> float:
        return (side * p / (p + 1.0) + ends * p / (p + 2.0)) / (side + ends)

    return 1.0 if volume / (area * depth) < 0.5 * (fullness(1.0) + fullness(2.0)) else 2.0


def _volume_edge(z: np.ndarray, fig: _Figures, bg: _Background, coef: np.ndarray, h: float) -> float:
    """Standard uncertainty of the volume from the outline's place: the outline moves together
    by up to a quarter of a pixel (rectangular; it is where the slope crosses its
    threshold, inside a pixel), each outline pixel's volume with it:
    ``h^2 sum(depth) / (4 sqrt(3))`` over the outline pixels, mm^3."""
    rows, cols = fig.region[:, 0], fig.region[:, 1]
    r0, c0 = rows.min() - 1, cols.min() - 1
    inside = np.zeros((rows.max() - r0 + 2, cols.max() - c0 + 2), bool)
    inside[rows - r0, cols - c0] = True
    edge = inside & ~ndimage.binary_erosion(inside)
    er, ec = np.nonzero(edge)
    er, ec = er + r0, ec + c0
    depth = fig.sign * (z[er, ec] - bg.design(er, ec) @ coef)
    return float(0.25 * h * h * np.clip(np.nan_to_num(depth), 0.0, None).sum() / math.sqrt(3.0))
