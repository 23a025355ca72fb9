"""A height field and its measured slopes fitted by hierarchical cubic B-splines, as Bezier patches.

:func:`fit_height` chooses the control points of bicubic patches by least squares
against the height **and** the slopes ``p = dz/dx``, ``q = dz/dy`` of every pixel they
cover, instead of interpolating a decimated grid (the Hermite construction of
:func:`photometric.integrate.height_to_patches`, whose tangents come from single pixels
and overshoot where the slope changes within a patch). :func:`surfaces.fit_mesh.fit_mesh` tessellates the
result on the pixel lattice and trims it along the sub-pixel outline of the fitted
region.

The model
---------
The surface is a sum of tensor-product cubic B-splines over the pixel parameter domain
``(s, t)`` (``s`` the row, ``t`` the column, pixel centres at whole numbers), with
uniform knots on the pixel edges ``-0.5 + i k`` (Forsey & Bartels 1988, hierarchical
B-splines):

* level 0 has knot spacing ``k0 = step`` pixels over the whole image;
* level ``l`` (spacing ``k0 / 2^l``) is an overlay whose B-splines all lie inside a
  refined region ``R_l`` (a union of level ``l - 1`` cells, ``R_l`` inside
  ``R_{l-1}``). Outside its region an overlay vanishes with all its derivatives, so the
  sum is C2 everywhere, also where patches of different sizes meet.

Fitting and refinement
----------------------
Each level minimises, over its coefficients, with the coarser levels fixed::

    sum_pixels w (S - z)^2 + lambda w ((S_s - z_s)^2 + (S_t - z_t)^2) + mu k^2 sum m (Delta^4 c)^2

``z_s = -q h`` and ``z_t = p h`` are the measured slopes per pixel step (``h`` the
pixel size), ``w`` is 1 on fitted pixels and 0 elsewhere. The last term, fourth
differences of the coefficients along each direction weighted by the fraction ``m`` of
a B-spline's support without data, fills masked and invalid pixels smoothly; its null
space is the bicubic polynomials, so bicubic data are reproduced exactly wherever data
are missing. The normal equations are assembled cell by cell (identical pixel offsets
in every cell, so full cells share one 16 x 16 block, summed per B-spline piece; partial
cells use two GEMMs each) and solved by sparse LU. The one-pixel level weighs slopes by
:data:`FINE_SLOPE`. Cells of level ``l`` whose largest deviation ``|S - z|`` exceeds
the tolerance, with a margin of one cell, become the region of level ``l + 1``; the
refinement stops at one-pixel knots. Flat background therefore keeps the large level-0
patches, cracks and edges get small ones. Where the height's noise sets the default
tolerance, a slope check also refines cells whose normals miss the measured ones by
more than the height's own normals do (``slope_angle`` of :func:`fit_height`).

Patches
-------
Every leaf cell (a level-``l`` cell of ``R_l`` not refined further) is one bicubic
Bezier patch: the sum of every level's B-spline restricted to it, converted exactly
(blossoms of the uniform B-spline pieces over the leaf's interval). The patches are
returned as a :class:`surfaces.mixed.MixedPatches` whose lattice unit is one pixel:
lattice ``(row, col)`` is the pixel-edge point ``(s, t) = (row - 0.5, col - 0.5)``.
Patch ``u`` runs down the rows, ``v`` along the columns, so ``S_u x S_v`` points up.

Coordinates
-----------
By default x and y follow :data:`surfaces.grid.GRID_CONVENTION` (orthographic pixels:
``x = (t - (W - 1) / 2) h``, ``y = ((H - 1) / 2 - s) h``), exactly linear in the
parameters, so only z is fitted. A camera whose pixels see points at known ``x, y``
(a perspective camera) passes them as ``xy``: then x, y and z are all fitted over the
same pixel parameter domain with the same normal equations (three right-hand sides),
the slope targets of z become ``z_s = p x_s + q y_s`` and ``z_t = p x_t + q y_t`` with
``x_s`` ... differences of ``xy``, and the deviation is the 3-D distance.

Borders
-------
Patches exist only over cells with fitted pixels (and a margin of one level-0 cell),
so none reaches into the background. Two neighbouring pixels whose height difference
the trapezoidal slope prediction misses by more than ``jump`` are a depth
discontinuity: both become border pixels, left out of the fit and of the mesh.
:func:`surfaces.fit_mesh.fit_mesh` trims along the 0.5 level line of the slightly smoothed region mask
(the outline :func:`skimage.measure.find_contours` draws), by marching squares on the
pixel lattice, so borders follow the outline to a fraction of a pixel instead of
stair-stepping.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.linalg import splu

from surfaces.mixed import MixedPatches
from surfaces.threads import one_blas_thread
from surfaces.validate import as_array, InputError, positive

__all__ = [
    "NOISE_TOLERANCE",
    "RELATIVE_TOLERANCE",
    "SLOPE_ANGLE",
    "SurfaceFit",
    "default_step",
    "fit_height",
    "find_discontinuities",
    "height_noise",
    "percentiles",
]

#: Default tolerance as a fraction of the height range (0.5th to 99.5th percentile) of
#: the fitted pixels; never below ``MIN_TOLERANCE_PX`` pixel sizes.
RELATIVE_TOLERANCE = 0.005
MIN_TOLERANCE_PX = 0.01
#: Default tolerance never below this many robust standard deviations of the height's noise
#: at the scale of the largest patches (:func:`height_noise`): a measured height carries the
#: integrated image noise, and chasing it refines the whole surface to tiny patches (a noisy
#: 1 MP near-field plate: 76,000 patches and 8.7 s at 0.6 um, where the noise is 0.3 um).
NOISE_TOLERANCE = 4.0
#: Default depth-discontinuity threshold, in pixel sizes.
JUMP_PX = 4.0
#: Weight ``mu`` of the fourth-difference smoothness term where data are missing. Small:
#: it only has to fix the coefficients no pixel determines; at weight 1 it also fought the
#: data beside a depth discontinuity (a step across a two-pixel gap was missed by 13 %).
SMOOTHING = 1e-3
#: Pixels per block of the whole-image passes of the fit (a few MB of float64 working arrays).
BLOCK_PIXELS = 1 << 18
#: Largest number of entries per pair of a dense :class:`_Lookup` map (beyond it: binary search).
DENSE_LOOKUP = 16
#: Slope weight of the one-pixel level relative to ``slope_weight``: there a pixel's slope
#: is a point sample of a kink (a crack's floor or rim) that no C2 cubic follows inside
#: the pixel, and full weight trades height for it (overshoot beside the kink).
FINE_SLOPE = 0.25
#: A cell whose fitted normals leave the measured normals by a mean angle more than this
#: (degrees) above the height's own normals (central differences) is refined even within
#: the height tolerance: on a detailed real object (the DiLiGenT bear) the noise term sets
#: the tolerance near 1 % of the depth, and 8 px patches within it add about 0.8 deg to
#: the normals' mean angle. See ``slope_angle`` of :func:`fit_height`.
SLOPE_ANGLE = 1.0
#: The slope check refines cells of at least this many pixels (down to half of it): below,
#: the slopes of a kink (a crack's wall) are point samples no cubic follows, and with the
#: check forced on down to one pixel a 4 MP plate's one-pixel patches and fit time doubled.
SLOPE_CELL_PX = 4

# Monomial coefficients (columns x^0 .. x^3) of the four pieces b_a (rows) of the uniform
# cubic B-spline on one knot span, local x in [0, 1]: in cell CI the B-spline CI + a is b_a.
_MONO = np.array([[1.0, -3.0, 3.0, -1.0], [4.0, 0.0, -6.0, 3.0], [1.0, 3.0, 3.0, -3.0], [0.0, 0.0, 0.0, 1.0]]) / 6.0
_DELTA4 = np.array([1.0, -4.0, 6.0, -4.0, 1.0])


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SurfaceFit:
    """What :func:`fit_height` returns.

    Attributes
    ----------
    patches : surfaces.mixed.MixedPatches
        The bicubic Bezier patches (mixed sizes), lattice unit one pixel: lattice
        ``(row, col)`` is the pixel-edge point ``(s, t) = (row - 0.5, col - 0.5)``.
    deviation : numpy.ndarray, shape (H, W)
        Surface minus measured height at the fitted pixels (the 3-D distance when ``xy``
        was given), NaN elsewhere.
    region : numpy.ndarray, shape (H, W), bool
        The fitted pixels: the mask without the depth-discontinuity borders; the mesh of
        :func:`surfaces.fit_mesh.fit_mesh` is trimmed to its outline.
    tolerance : float
        The tolerance the refinement aimed at (height unit).
    max_deviation, rms_deviation : float
        Largest and root-mean-square ``|deviation|`` over the fitted pixels.
    levels : tuple of dict
        Per level: ``spacing_px``, ``cells`` (cells in its region), ``unknowns``,
        ``refined`` (cells that missed the tolerance).
    step : int
        Knot spacing of level 0 (the largest patch side) in pixels.
    pixel_size : float
        Pixel size (the unit of x, y and z).
    covered : numpy.ndarray, shape (H, W), bool
        Pixels under a patch.
    values : tuple of numpy.ndarray
        The fitted coordinates and their derivatives per pixel step along rows and
        columns at the pixel centres, three ``(H, W, d)`` arrays (``d = 1``: z only;
        ``d = 3`` with ``xy``); :attr:`surface` and :attr:`normals` are built from them.
    max_patches : int or None
        The patch budget the refinement kept to (None: none).
    budget_reached : bool
        The budget stopped the refinement: some cells miss the tolerance
        (``max_deviation`` says by how much).
    """

    patches: MixedPatches
    deviation: np.ndarray
    region: np.ndarray
    tolerance: float
    max_deviation: float
    rms_deviation: float
    levels: tuple
    step: int
    pixel_size: float
    covered: np.ndarray
    values: tuple
    max_patches: int | None = None
    budget_reached: bool = False

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(H, W)``."""
        return self.region.shape

    def patch_sizes(self) -> dict:
        """Number of patches of each side length in pixels, ``{size_px: count}``, largest first."""
        sizes, counts = np.unique(self.patches.sizes, return_counts=True)
        return {int(s): int(c) for s, c in zip(sizes[::-1], counts[::-1])}

    @cached_property
    def surface(self) -> np.ndarray:
        """Surface points at the pixel centres, ``(H, W, 3)`` (NaN where no patch is)."""
        S = self.values[0]
        if S.shape[-1] == 3:
            out = S.copy()
        else:
            from surfaces.grid import pixel_grid

            x, y = pixel_grid(self.shape, self.pixel_size)
            out = np.stack([x, y, S[..., 0]], axis=2)
        out[~self.covered] = np.nan
        return out

    @cached_property
    def normals(self) -> np.ndarray:
        """Unit normals ``S_u x S_v`` at the pixel centres, ``(H, W, 3)``.

        Upwards (+z) for a height field; NaN where no patch is.
        """
        _, Ss, St = self.values
        if Ss.shape[-1] == 3:
            from surfaces.vectors import cross, unit

            out = unit(cross(Ss, St))
        else:
            # S_s = (0, -h, z_s), S_t = (h, 0, z_t): S_s x S_t = h (-z_t, z_s, h)
            h = self.pixel_size
            out = np.empty((*self.shape, 3))
            out[..., 0] = -St[..., 0]
            out[..., 1] = Ss[..., 0]
            out[..., 2] = h
            out /= np.sqrt(St[..., 0] ** 2 + Ss[..., 0] ** 2 + h * h)[..., None]
        out[~self.covered] = np.nan
        return out


# ----------------------------------------------------------------------------- B-spline pieces
def _pieces(x: np.ndarray, derivative: bool = False) -> np.ndarray:
    """``b_a(x)`` or ``b_a'(x)`` per unit of local parameter, shape (len(x), 4)."""
    x = np.asarray(x, float)
    if derivative:
        powers = np.stack([np.zeros_like(x), np.ones_like(x), 2.0 * x, 3.0 * x * x], axis=-1)
    else:
        powers = np.stack([np.ones_like(x), x, x * x, x**3], axis=-1)
    return powers @ _MONO.T


def _blossom_matrix(x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """Bezier points over ``[x0, x1]`` of the pieces: ``out[n, j, a]`` is point ``j`` of ``b_a``.

    Point ``j`` of a cubic over ``[x0, x1]`` is its blossom ``F(x0^(3-j), x1^j)``; for a
    monomial basis the blossom is the elementary symmetric mean of the arguments.
    """
    x0 = np.asarray(x0, float)[:, None]
    x1 = np.asarray(x1, float)[:, None]
    j = np.arange(4.0)[None, :]
    i = 3.0 - j
    e1 = (i * x0 + j * x1) / 3.0
    e2 = (i * (i - 1) / 2 * x0 * x0 + i * j * x0 * x1 + j * (j - 1) / 2 * x1 * x1) / 3.0
    e3 = x0**i * x1**j
    e = np.stack([np.ones_like(e1), e1, e2, e3], axis=-1)
    return e @ _MONO.T


class _Level:
    """One uniform knot grid: spacing ``k`` pixels, ``ns x nt`` cells over the padded image."""

    def __init__(self, k: int, ns: int, nt: int, slope_weight: float):
        self.k, self.ns, self.nt, self.lam = k, ns, nt, slope_weight
        x = (np.arange(k) + 0.5) / k
        self.V = _pieces(x)  # (k, 4) values at the pixel centres of a cell
        self.D = _pieces(x, derivative=True) / k  # (k, 4) derivatives per pixel step
        self.VV = (self.V[:, :, None] * self.V[:, None, :]).reshape(k, 16)
        self.DD = (self.D[:, :, None] * self.D[:, None, :]).reshape(k, 16)
        ones = np.ones((1, k, k))
        self.full_block = self.blocks(ones)[0]
        # what piece (a, b) of a full cell adds to its B-spline's 7 x 7 stencil of offsets
        # (c - a, d - b): rows (a, b), columns the offsets from (-3, -3), row-major
        fs = np.zeros((4, 4, 7, 7))
        for a in range(4):
            for b in range(4):
                fs[a, b, 3 - a:7 - a, 3 - b:7 - b] = self.full_block[a, b]
        self.full_stencil = fs.reshape(16, 49)

    def cells(self, a: np.ndarray) -> np.ndarray:
        """``(..., ns k, nt k)`` pixel array as ``(..., ns, nt, k, k)`` cells (a view)."""
        k = self.k
        return np.swapaxes(a.reshape(*a.shape[:-2], self.ns, k, self.nt, k), -3, -2)

    def blocks(self, w: np.ndarray) -> np.ndarray:
        """Normal-equation blocks ``(n, 4, 4, 4, 4)`` ``[a, b, c, d]`` of cells with weights ``(n, k, k)``.

        ``sum_op w_op (e_op e_op^T)`` with ``e = V_o (x) V_p``, ``lambda D_o (x) V_p``,
        ``lambda V_o (x) D_p``: rows ``(a, b)`` and columns ``(c, d)`` are B-splines.
        """
        n, k = len(w), self.k
        flat = w.reshape(n * k, k)
        wv = (flat @ self.VV).reshape(n, k, 16)  # column offsets contracted: [n, o, (b, d)]
        wd = (flat @ self.DD).reshape(n, k, 16)
        rows = np.concatenate([self.VV, self.lam * self.DD, self.lam * self.VV], axis=1)  # (k, 48)
        stacked = np.concatenate([wv, wv, wd], axis=2)  # (n, k, 48)
        out = np.zeros((n, 16, 16))
        for part in range(3):
            r = rows[:, 16 * part:16 * (part + 1)]  # (k, 16) [o, (a, c)]
            s = stacked[:, :, 16 * part:16 * (part + 1)]  # (n, k, 16) [n, o, (b, d)]
            out += (r.T @ s.transpose(1, 0, 2).reshape(k, n * 16)).reshape(16, n, 16).transpose(1, 0, 2)
        return out.reshape(n, 4, 4, 4, 4).transpose(0, 1, 3, 2, 4)

    def project(self, x: np.ndarray, along_s: np.ndarray, along_t: np.ndarray) -> np.ndarray:
        """``sum_op along_s[o, a] x[n, o, p] along_t[p, b]``: ``(n, k, k)`` -> ``(n, 4, 4)``."""
        n, k = len(x), self.k
        y = (x.reshape(n * k, k) @ along_t).reshape(n, k, 4)  # [n, o, b]
        return (y.transpose(0, 2, 1).reshape(n * 4, k) @ along_s).reshape(n, 4, 4).transpose(0, 2, 1)

    def expand(self, c: np.ndarray, along_s: np.ndarray, along_t: np.ndarray) -> np.ndarray:
        """``sum_ab along_s[o, a] c[n, a, b] along_t[p, b]``: ``(n, 4, 4)`` -> ``(n, k, k)``."""
        n, k = len(c), self.k
        y = (c.reshape(n * 4, 4) @ along_t.T).reshape(n, 4, k)  # [n, a, p]
        return (y.transpose(0, 2, 1).reshape(n * k, 4) @ along_s.T).reshape(n, k, k).transpose(0, 2, 1)


    def project_grid(self, x: np.ndarray, along_s: np.ndarray, along_t: np.ndarray) -> np.ndarray:
        """:meth:`project` of every cell of ``(n k, nt k)`` rows of the image (``n`` cell rows, all
        ``ns`` for the whole image): ``(n, nt, 4, 4)``."""
        k, nt = self.k, self.nt
        ns = x.shape[-2] // k
        y = (x.reshape(ns * k * nt, k) @ along_t).reshape(ns, k, nt * 4)  # [CI, o, (CJ, b)]
        return (along_s.T[None] @ y).reshape(ns, 4, nt, 4).transpose(0, 2, 1, 3)

    def expand_grid(self, coef: np.ndarray, along_s: np.ndarray, along_t: np.ndarray) -> np.ndarray:
        """:meth:`expand` over every cell of coefficient rows ``(n + 3, nt + 3)`` (``n`` cell rows, all
        ``ns`` for the whole grid): ``(n k, nt k)``."""
        k, nt = self.k, self.nt
        ns = coef.shape[0] - 3
        shifted = np.stack([coef[:, b:b + nt] for b in range(4)], axis=2)  # [i, CJ, b]
        u = (shifted @ along_t.T).reshape(ns + 3, nt * k)  # [i, (CJ, p)]
        rows = np.stack([u[a:a + ns] for a in range(4)], axis=1)  # [CI, a, (CJ, p)]
        return (along_s[None] @ rows).reshape(ns * k, nt * k)


class _Lookup:
    """Position of integer pairs ``(i, j)`` in a list of distinct pairs, -1 where absent.

    A dense map over the pairs' bounding box (with a margin: lookups reach a few entries
    beyond it, and within the grid ``shape`` and its margin) while that box holds at most
    :data:`DENSE_LOOKUP` entries per pair; otherwise sorted keys and a binary search, so
    that the thin refined region of a fine level costs memory per cell, not per pixel of
    the image (a one-pixel level over a 64 MP image: 256 MB per dense map).
    """

    def __init__(self, i: np.ndarray, j: np.ndarray, shape: tuple[int, int]):
        offset = 8  # lookups reach a few entries beyond the grid
        i, j = np.asarray(i), np.asarray(j)
        n = int(np.size(i))
        lo_i, lo_j = (int(i.min()), int(j.min())) if n else (0, 0)
        hi_i, hi_j = (int(i.max()), int(j.max())) if n else (-1, -1)
        self.i0, self.j0 = max(lo_i, 0) - offset, max(lo_j, 0) - offset
        self.rows = min(hi_i + 1 + offset, shape[0] + offset) - self.i0
        self.cols = min(hi_j + 1 + offset, shape[1] + offset) - self.j0
        at = np.arange(n, dtype=np.int32)
        if self.rows * self.cols <= DENSE_LOOKUP * n + 4096:
            self.map = np.full((self.rows, self.cols), -1, np.int32)
            self.map[i - self.i0, j - self.j0] = at
        else:
            self.map = None
            keys = (i - self.i0).astype(np.int64) * self.cols + (j - self.j0)
            order = np.argsort(keys, kind="stable")
            self.keys, self.at = keys[order], at[order]

    def __call__(self, i, j) -> np.ndarray:
        i = np.asarray(i) - self.i0
        j = np.asarray(j) - self.j0
        rows, cols = self.rows, self.cols
        if self.map is None:
            inside = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
            key = np.where(inside, i.astype(np.int64) * cols + j, -1)
            if self.keys.size == 0:
                return np.full(key.shape, -1, np.int32)
            pos = np.minimum(np.searchsorted(self.keys, key), self.keys.size - 1)
            return np.where(inside & (self.keys[pos] == key), self.at[pos], -1).astype(np.int32, copy=False)
        if i.size == 0 or j.size == 0 or (i.min() >= 0 and i.max() < rows and j.min() >= 0 and j.max() < cols):
            # the usual case: four reductions instead of a clip, a mask and a select per entry
            return self.map[i, j]
        inside = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        return np.where(inside, self.map[np.clip(i, 0, rows - 1), np.clip(j, 0, cols - 1)], -1)


_A4 = np.arange(4)


def _window_index(lookup: _Lookup, CI: np.ndarray, CJ: np.ndarray) -> np.ndarray:
    """Index (or -1) of the 16 B-splines acting on cells ``(CI, CJ)``, ``(n, 4, 4)``.

    Entry ``[a, b]`` is B-spline ``(CI + a, CJ + b)``.
    """
    return lookup(CI[:, None, None] + _A4[None, :, None], CJ[:, None, None] + _A4[None, None, :])


def _gather(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``values[index]`` with zero where ``index`` is -1 (B-splines not solved for are zero)."""
    out = values[np.maximum(index, 0)]
    out[index < 0] = 0.0
    return out


# ----------------------------------------------------------------------------- one level
def _assemble(level: _Level, CI, CJ, n_data, wc, cell_rhs, fi, fj, missing, ridge):
    """Sparse normal equations of one level over its B-splines ``(fi, fj)``.

    ``CI, CJ``: cells that carry data or smoothing; ``n_data`` their numbers of fitted
    pixels; ``wc`` the level's pixel weights as cells ``(ns, nt, k, k)`` (0 or 1);
    ``cell_rhs`` ``(d, n, 4, 4)`` each cell's share of the right-hand sides;
    ``missing`` ``(len(fi),)`` the fraction of each B-spline's support without data.
    """
    k = level.k
    n = fi.size
    lookup = _Lookup(fi, fj, (level.ns + 3, level.nt + 3))
    with_data = n_data > 0
    full = n_data[with_data] == k * k
    cell_f = _window_index(lookup, CI[with_data], CJ[with_data])
    # Full cells all add the same block: B-spline (fi, fj) is piece (a, b) of cell
    # (fi - a, fj - b) and meets there piece (c, d), the B-spline at offset (c - a, d - b).
    # Summing per piece over the B-splines costs 256 vector operations, not 256 scattered
    # entries per cell (most cells of the fine levels are full).
    is_full = _Lookup(CI[with_data][full], CJ[with_data][full], (level.ns, level.nt))
    here = (is_full(fi[:, None, None] - _A4[None, :, None], fj[:, None, None] - _A4[None, None, :]) >= 0)
    stencil = here.reshape(n, 16).astype(float) @ level.full_stencil  # (n, 49)
    if not full.all():
        # partial cells: their own blocks, scattered; entries of B-splines not solved for go
        # to a discarded slot n * 49
        part_f = cell_f[~full].astype(np.int64)  # keys reach n * 49
        blocks = level.blocks(wc[CI[with_data][~full], CJ[with_data][~full]])
        row = np.broadcast_to(part_f[:, :, :, None, None], blocks.shape)
        col = np.broadcast_to(part_f[:, None, None, :, :], blocks.shape)
        da = _A4[None, :] - _A4[:, None] + 3  # [a, c] -> c - a + 3
        slot = np.broadcast_to(da[:, None, :, None] * 7 + da[None, :, None, :], blocks.shape)
        keys = np.where((row >= 0) & (col >= 0), row * 49 + slot, n * 49)
        stencil += np.bincount(keys.ravel(), weights=blocks.ravel(), minlength=n * 49 + 1)[: n * 49].reshape(n, 49)
    off = np.arange(-3, 4)
    cols = lookup(fi[:, None, None] + off[None, :, None], fj[:, None, None] + off[None, None, :]).reshape(n, 49)
    nz = cols >= 0
    # B-splines are numbered row-major, so each row's columns come out sorted: CSR directly
    indptr = np.concatenate([[0], np.cumsum(nz.sum(axis=1))])
    A = sp.csr_matrix((stencil[nz], cols[nz], indptr), shape=(n, n))
    d = len(cell_rhs)
    rhs = np.zeros((n, d))
    ok = cell_f >= 0
    for c in range(d):
        rhs[:, c] = np.bincount(cell_f[ok], weights=cell_rhs[c][with_data][ok], minlength=n)
    # Fourth differences along s and t where data are missing, centred on every B-spline
    # whose four neighbours along the line are solved for too; a row weighs as much as the
    # emptiest support among its five coefficients.
    weight = SMOOTHING * k * k * missing
    parts = []
    sh = np.arange(-2, 3)
    for di, dj in ((1, 0), (0, 1)):
        nb = lookup(fi[:, None] + di * sh, fj[:, None] + dj * sh)  # (n, 5)
        whole = (nb >= 0).all(axis=1)
        wrow = np.zeros(n)
        wrow[whole] = weight[nb[whole]].max(axis=1)
        use = np.flatnonzero(wrow > 0)
        vals = _DELTA4[None, :] * np.sqrt(wrow[use])[:, None]
        r = np.repeat(np.arange(use.size), 5)
        parts.append(sp.csr_matrix((vals.ravel(), (r, nb[use].ravel())), shape=(use.size, n)))
    Dm = sp.vstack(parts).tocsr()
    A = (A + Dm.T @ Dm).tocsr()
    if ridge:
        A = A + sp.diags(np.full(n, ridge * max(float(A.diagonal().mean()), 1e-300)))
    return A, rhs, lookup


def _solve(A: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
    """The symmetric positive definite system, by sparse LU (one factorisation, ``d`` right-hand sides).

    SuperLU with minimum-degree ordering on ``A + A^T`` is single-threaded, so it does not
    stall on a busy machine as threaded dense LAPACK (a banded Cholesky) does; measured on
    the levels of a 4 MP fit it is faster than Jacobi-preconditioned CG on the finest,
    thin overlays (whose conditioning follows their width) and never much slower.
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros((0, b.shape[1]))
    # SPD: diagonal pivots and the symmetric ordering kept (SymmetricMode) skip the
    # partial-pivoting search; measured on the levels of a 4 MP fit, the factorisations
    # take about half the time of the default threshold pivoting, same fill
    opts = {"permc_spec": "MMD_AT_PLUS_A", "diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}}
    try:
        return splu(A.tocsc(), **opts).solve(b)
    except RuntimeError:  # exactly singular: a part without data or smoothing; a ridge fixes it
        ridge = sp.diags(np.full(n, 1e-10 * max(float(A.diagonal().mean()), 1e-300)))
        return splu((A + ridge).tocsc(), **opts).solve(b)


# ----------------------------------------------------------------------------- input
def height_noise(height, mask, scale_px: float) -> float:
    """Robust standard deviation of a height field's detail below a scale (its noise there).

    The height minus its Gaussian-smoothed copy (masked: normalised convolution) keeps
    what varies within about ``scale_px`` pixels; the median absolute deviation of that
    detail over the mask's interior is the noise level. Sparse features (a crack, a
    scratch, a silhouette) hardly move the median, and a smooth curved surface leaves a
    slowly varying detail whose spread is small.

    Parameters
    ----------
    height : numpy.ndarray, shape (H, W)
        Heights (any unit; finite inside ``mask``).
    mask : numpy.ndarray, shape (H, W), bool
        Pixels with data.
    scale_px : float
        Standard deviation of the Gaussian, pixels (> 0).

    Returns
    -------
    float
        ``1.4826 * median |d - median d|`` of the detail ``d`` (height unit); 0 when no
        interior pixel is left.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> z = 0.01 * np.arange(64.0)[None, :] + rng.normal(0.0, 0.002, (64, 64))
    >>> 0.0015 < height_noise(z, np.ones((64, 64), bool), 4.0) < 0.0025
    True
    """
    m = np.asarray(mask, bool)
    z = np.asarray(height)
    dt = _work_dtype(z)
    H, W = m.shape
    # zero outside the image, so that the border pixels' weight drops and they are left out
    if m.all():
        # a full mask's weights are separable: two 1-D filters instead of two image passes
        w_rows, w_cols = (ndimage.gaussian_filter1d(np.ones(n), scale_px, mode="constant") for n in m.shape)
        smooth = _gaussian(z, scale_px, dt)

        def weight(r: slice) -> np.ndarray:
            return np.multiply.outer(w_rows[r], w_cols)
    else:
        w = _gaussian(m, scale_px, dt)
        smooth = _gaussian(z, scale_px, dt, where=m)

        def weight(r: slice) -> np.ndarray:
            return np.asarray(w[r], np.float64)
    # the detail per block of rows, in float64, written over the smoothed plane
    inner = np.empty(m.shape, bool)
    step = max(1, BLOCK_PIXELS // W)
    for r0 in range(0, H, step):
        r = slice(r0, r0 + step)
        wr = weight(r)
        inner[r] = m[r] & (wr > 0.99)
        smooth[r] = np.asarray(z[r], np.float64) - smooth[r] / np.maximum(wr, 1e-12)
    weight = w = None  # the weights are not needed past the detail (4 bytes per pixel with a mask)
    if not inner.any():
        return 0.0
    # the detail gathered a block of rows at a time into float64: no float32 copy of it beside
    detail = np.empty(int(np.count_nonzero(inner)))
    n = 0
    for r0 in range(0, H, step):
        part = smooth[r0:r0 + step][inner[r0:r0 + step]]
        detail[n:n + part.size] = part
        n += part.size
    del smooth, inner
    # the medians reorder ``detail`` in place, which leaves both medians as they are
    centre = np.median(detail, overwrite_input=True)
    detail -= centre
    return float(1.4826 * np.median(np.abs(detail, out=detail), overwrite_input=True))


def percentiles(values: np.ndarray, q) -> np.ndarray:
    """``np.percentile(values.astype(np.float64), q)`` (linear method), bit for bit, without the
    float64 copy: the order statistics are found by partitioning ``values`` (a 1-D array that
    may be reordered, in its own float type) and interpolated in float64 as numpy does.

    Parameters
    ----------
    values : numpy.ndarray, shape (n,)
        Finite values, n >= 1; reordered in place.
    q : sequence of float
        Percentiles in [0, 100].

    Returns
    -------
    numpy.ndarray, shape (len(q),), float64
    """
    n = values.size
    virtual = (n - 1) * np.true_divide(np.asarray(q, np.float64), 100)
    lo = np.floor(virtual).astype(np.intp)
    hi = np.minimum(lo + 1, n - 1)
    values.partition(np.unique(np.concatenate([lo, hi])))
    a, b = values[lo].astype(np.float64), values[hi].astype(np.float64)
    t = virtual - lo
    diff = b - a
    # numpy's _lerp: from the nearer end
    return np.where(t >= 0.5, b - diff * (1 - t), a + diff * t)


def _gaussian(a: np.ndarray, sigma: float, dtype=np.float64, where: np.ndarray | None = None) -> np.ndarray:
    """``ndimage.gaussian_filter(a, sigma, mode="constant")`` (kernel truncated at 4 sigma, zero
    outside the image) as one FFT convolution per axis: equal to rounding (1e-15), and on the
    129-tap kernels of a 4 MP fit's noise estimate about 40 % less CPU time than direct sums.

    The convolutions run in float64 on blocks of columns (then of rows, in place), so that the
    only whole-image array is the result, in ``dtype``; ``where`` (bool, the shape of ``a``)
    zeroes ``a`` outside it first.
    """
    import scipy.fft as sfft

    radius = int(4.0 * sigma + 0.5)
    x = np.arange(-radius, radius + 1)
    k = np.exp(-0.5 / (sigma * sigma) * x * x)
    k /= k.sum()
    out = np.empty(a.shape, dtype)
    for axis in (0, 1):
        n = a.shape[axis]
        # zero padding to the full linear convolution: no wrap-around
        size = sfft.next_fast_len(n + 2 * radius, real=True)
        kernel = np.expand_dims(sfft.rfft(k, size), 1 - axis)
        span = max(1, BLOCK_PIXELS // size)
        for b0 in range(0, a.shape[1 - axis], span):
            part = (slice(None), slice(b0, b0 + span)) if axis == 0 else (slice(b0, b0 + span), slice(None))
            block = np.asarray((a if axis == 0 else out)[part], np.float64)
            if axis == 0 and where is not None:
                block = np.where(where[part], block, 0.0)
            spec = sfft.rfft(block, size, axis=axis)
            spec *= kernel
            keep = (slice(radius, radius + n), slice(None)) if axis == 0 else (slice(None), slice(radius, radius + n))
            out[part] = sfft.irfft(spec, size, axis=axis)[keep]
    return out


def default_step(shape) -> int:
    """Default level-0 knot spacing: a power of two giving about 64 patches across the longer side.

    Parameters
    ----------
    shape : (H, W)
        Image size in pixels.

    Returns
    -------
    int
        ``2^round(log2(max(H, W) / 64))``, from 1 to 64.

    Examples
    --------
    >>> default_step((512, 612)), default_step((2048, 2048)), default_step((40, 40))
    (8, 32, 1)
    """
    n = max(int(shape[0]), int(shape[1]))
    return int(2 ** np.clip(np.round(np.log2(n / 64.0)), 0, 6))


def _step(step, shape) -> int:
    if step is None:
        return default_step(shape)
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or int(step) < 1:
        raise InputError(f"step: expected a positive whole number of pixels, got {step!r}")
    return 1 << (int(step).bit_length() - 1)


def _work_dtype(*arrays) -> type:
    """float32 when every input is a float32 array (kept as it is), float64 otherwise."""
    return np.float32 if all(getattr(a, "dtype", None) == np.float32 for a in arrays) else np.float64


def _slope_targets(p, q, xy, valid):
    """Per-pixel-step derivative targets ``(z_s, z_t)`` of a perspective camera and those ``(f_s, f_t)`` of x, y."""
    fs = _differences(xy, valid, axis=0)
    ft = _differences(xy, valid, axis=1)
    zs = p * fs[..., 0] + q * fs[..., 1]
    zt = p * ft[..., 0] + q * ft[..., 1]
    return zs, zt, fs, ft


def _differences(a: np.ndarray, valid: np.ndarray, axis: int) -> np.ndarray:
    """Central differences along ``axis`` where both neighbours are valid, one-sided otherwise."""
    a = np.moveaxis(a, axis, 0)
    v = np.moveaxis(valid, axis, 0)
    fwd = np.zeros_like(a)
    bwd = np.zeros_like(a)
    ok_f = np.zeros(v.shape, bool)
    ok_b = np.zeros(v.shape, bool)
    fwd[:-1] = a[1:] - a[:-1]
    ok_f[:-1] = v[1:] & v[:-1]
    bwd[1:] = fwd[:-1]
    ok_b[1:] = ok_f[:-1]
    both = (ok_f & ok_b)[..., None]
    out = np.where(both, 0.5 * (fwd + bwd), np.where(ok_f[..., None], fwd, bwd))
    return np.moveaxis(out, 0, axis)


def find_discontinuities(height, p, q, mask, pixel_size: float = 1.0, jump: float | None = None, xy=None):
    """Pixels beside a height jump that the measured slopes do not explain.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height (unit of ``pixel_size``); only pixels in ``mask`` are read.
    p, q : array_like, shape (H, W)
        Slopes ``dz/dx``, ``dz/dy`` (y up).
    mask : array_like of bool, shape (H, W)
        Pixels with data.
    pixel_size : float
        Pixel size ``h``.
    jump : float, optional
        Largest height difference between neighbouring pixels that the slopes may leave
        unexplained; default ``4 h``.
    xy : array_like, shape (H, W, 2), optional
        Per-pixel x, y (a perspective camera); the slope prediction then uses their
        differences instead of ``h``.

    Returns
    -------
    numpy.ndarray, shape (H, W), bool
        Both pixels of every 4-neighbour pair inside ``mask`` whose height difference
        differs from the trapezoidal prediction ``(g_a + g_b) / 2`` by more than ``jump``.
    """
    dt = _work_dtype(height, p, q)
    z = as_array(height, "height", ndim=2, finite=False, dtype=dt)
    m = as_array(mask, "mask", shape=z.shape, dtype=bool)
    pp = as_array(p, "p", shape=z.shape, finite=False, dtype=dt)
    qq = as_array(q, "q", shape=z.shape, finite=False, dtype=dt)
    h = positive(pixel_size, "pixel_size")
    limit = JUMP_PX * h if jump is None else positive(jump, "jump")
    border = np.zeros(z.shape, bool)
    # per block of rows, so that the temporaries stay a few MB
    step = max(1, BLOCK_PIXELS // z.shape[1])
    for r0 in range(0, z.shape[0], step):
        for axis in (0, 1):
            # the pairs across rows reach one row into the next block
            rows = slice(r0, min(r0 + step + (axis == 0), z.shape[0]))
            mb, pb, qb, bb = m[rows], pp[rows], qq[rows], border[rows]
            zz = np.where(mb, z[rows], 0.0)
            lo = [slice(None), slice(None)]
            hi = [slice(None), slice(None)]
            lo[axis], hi[axis] = slice(None, -1), slice(1, None)
            lo, hi = tuple(lo), tuple(hi)
            if xy is None:
                # one pixel step: along the rows y falls by h (only q counts), along the columns
                # x grows by h (only p counts)
                g = qb if axis == 0 else pb
                predicted = g[lo] + g[hi]
                predicted *= -0.5 * h if axis == 0 else 0.5 * h
            else:
                xb = xy[rows]
                dx = xb[hi + (0,)] - xb[lo + (0,)]
                dy = xb[hi + (1,)] - xb[lo + (1,)]
                predicted = 0.5 * (pb[lo] + pb[hi]) * dx + 0.5 * (qb[lo] + qb[hi]) * dy
            both = mb[lo] & mb[hi]
            with np.errstate(invalid="ignore"):
                miss = zz[hi] - zz[lo]
                miss -= predicted
                bad = both & (np.abs(miss, out=miss) > limit)
            bb[lo] |= bad
            bb[hi] |= bad
    return border


# ----------------------------------------------------------------------------- the fit
def fit_height(
    height,
    p,
    q,
    *,
    mask=None,
    pixel_size: float = 1.0,
    tolerance: float | None = None,
    step: int | None = None,
    xy=None,
    jump: float | None = None,
    slope_weight: float = 1.0,
    slope_angle: float | None = None,
    keep_pixels: bool = True,
    max_patches: int | None = None,
) -> SurfaceFit:
    """Fit bicubic patches to a height field and its slopes, refining until within a tolerance.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height in the unit of ``pixel_size`` (mm); must be finite inside ``mask``.
    p, q : array_like, shape (H, W)
        Measured slopes ``dz/dx``, ``dz/dy`` (y up, dimensionless); finite inside ``mask``.
    mask : array_like of bool, shape (H, W), optional
        Pixels with data (default: all). Patches cover only cells with data.
    pixel_size : float
        Pixel size ``h`` (mm).
    tolerance : float, optional
        Largest deviation ``|S - z|`` aimed at (unit of ``h``, > 0); cells that miss it
        are refined, down to one-pixel patches. Default: :data:`RELATIVE_TOLERANCE` of the
        height range (0.5th to 99.5th percentile) inside the mask, at least
        :data:`MIN_TOLERANCE_PX` pixel sizes and :data:`NOISE_TOLERANCE` times the height's
        noise at half the largest patch size (:func:`height_noise`).
    step : int, optional
        Largest patch side (level-0 knot spacing) in pixels, rounded down to a power of
        two; default :func:`default_step`.
    xy : array_like, shape (H, W, 2), optional
        The x, y (unit of ``h``) each pixel sees (a perspective camera); default: the
        orthographic grid of :data:`surfaces.grid.GRID_CONVENTION`. With ``xy`` all
        three coordinates are fitted (see the module notes).
    jump : float, optional
        Depth-discontinuity threshold of :func:`find_discontinuities` (default ``4 h``).
    slope_weight : float
        ``lambda``, the weight of the slope residuals (per pixel step) against the
        height residuals (> 0).
    slope_angle : float, optional
        Slope check of the refinement (degrees, > 0): a cell of at least
        :data:`SLOPE_CELL_PX` pixels whose fitted normals leave the measured normals
        (``p``, ``q``) by a mean angle more than ``slope_angle`` above the height's own
        normals (central differences, over the pixels whose four neighbours are fitted) is
        refined even within the tolerance. Orthographic fits only (ignored with ``xy``).
        Default: :data:`SLOPE_ANGLE` when the height's noise sets the default tolerance
        (the noise term then loosens the tolerance, and the normals keep the detail it
        lets go), no check otherwise.
    keep_pixels : bool
        False: the result keeps no per-pixel surface and deviation (``values=()``,
        ``deviation=None``; every other field the same), for callers that need only the
        patches, the region and the statistics: the fit's running surface is let go before
        the patches are built and no deviation map is made (16 bytes per pixel less at the
        end of a float32 fit).
    max_patches : int, optional
        Patch budget (at least the level-0 cells with data): a level refines only the
        cells that miss the tolerance worst, as many as keep the patch count within the
        budget, and the refinement stops when none fits (``budget_reached``; the fit then
        misses the tolerance where the budget ran out). Bounds the time of a big image
        with much detail: a 5.5 MP capture's fit took 108 s with 305,796 patches.

    Returns
    -------
    SurfaceFit
        Patches, the surface and its normals at the pixel centres, deviations.

    Raises
    ------
    ValueError
        Wrong shapes, ``tolerance <= 0``, NaN heights or slopes inside the mask, an empty
        mask (each naming the input).

    Notes
    -----
    While it runs, numpy's bundled OpenBLAS is held to one thread (the count is restored
    after): the fit's products are thin, and threads only cost time on them.
    ``slope_weight`` stays 1 by default: heavier weights barely move the normals while the
    fit follows the height (see ``benchmarks/results/surface_fit.md``, slope weighting).

    Examples
    --------
    A plane is one patch per level-0 cell, exactly:

    >>> r, c = np.mgrid[0:16, 0:16]
    >>> fit = fit_height(0.5 * c - 0.25 * r, np.full((16, 16), 0.5), np.full((16, 16), 0.25), step=8)
    >>> fit.patches.n_patches, fit.max_deviation < 1e-9
    (4, True)
    """
    # float32 inputs stay float32 (no float64 copy of the whole grid); float64 only per block
    dt = _work_dtype(height, p, q)
    z = as_array(height, "height", ndim=2, finite=False, dtype=dt)
    H, W = z.shape
    if min(H, W) < 2:
        raise InputError(f"height: needs at least 2 x 2 pixels, got {z.shape}")
    pp = as_array(p, "p", shape=z.shape, finite=False, dtype=dt)
    qq = as_array(q, "q", shape=z.shape, finite=False, dtype=dt)
    h = positive(pixel_size, "pixel_size")
    lam = positive(slope_weight, "slope_weight")
    angle = None if slope_angle is None else positive(slope_angle, "slope_angle")
    m = np.ones(z.shape, bool) if mask is None else as_array(mask, "mask", shape=z.shape, dtype=bool)
    if not m.any():
        raise InputError("mask: no pixel is selected")
    for name, arr in (("height", z), ("p", pp), ("q", qq)):
        bad = m & ~np.isfinite(arr)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            raise InputError(
                f"{name}: {int(bad.sum())} non-finite value(s) inside the mask (first at row {r}, column {c}); "
                "leave such pixels out of the mask"
            )
    xyv = None
    if xy is not None:
        xyv = as_array(xy, "xy", shape=(H, W, 2), finite=False)
        if (m & ~np.isfinite(xyv).all(axis=2)).any():
            raise InputError("xy: non-finite values inside the mask")
    k0 = _step(step, z.shape)
    if tolerance is None:
        lo, hi = percentiles(z[m], (0.5, 99.5))
        tol = max(RELATIVE_TOLERANCE * float(hi - lo), MIN_TOLERANCE_PX * h)
        noise = NOISE_TOLERANCE * height_noise(z, m, k0 / 2.0)
        if noise > tol:
            tol = noise
            # the height's detail, noise or not, loosened the tolerance: the normals keep it
            angle = SLOPE_ANGLE if angle is None else angle
    else:
        tol = positive(tolerance, "tolerance")
    region = m & ~find_discontinuities(z, pp, qq, m, h, jump, xyv)
    if not region.any():
        raise InputError("height: every pixel of the mask lies on a depth discontinuity")
    budget = None
    if max_patches is not None:
        if isinstance(max_patches, bool) or int(max_patches) != max_patches or int(max_patches) < 1:
            raise InputError(f"max_patches: must be an integer of at least 1, got {max_patches!r}")
        budget = int(max_patches)
    with one_blas_thread():
        return _fit(z, pp, qq, region, h, tol, k0, xyv, lam, angle, bool(keep_pixels), budget)


def _cell_angles(fs, ft, ts, tt, h: float, weight: np.ndarray) -> np.ndarray:
    """Angle (degrees) between fitted and measured normals, times ``weight``, elementwise.

    ``fs, ft`` and ``ts, tt`` are the fitted and target height slopes per pixel step along
    rows (``s``) and columns (``t``); the normal of slopes ``(a_s, a_t)`` is ``(-a_t, a_s, h)``.
    """
    dot = h * h + ft * tt + fs * ts
    norm = np.sqrt((h * h + ft * ft + fs * fs) * (h * h + tt * tt + ts * ts))
    return np.degrees(np.arccos(np.clip(dot / norm, -1.0, 1.0))) * weight


def _own_angles(z, region, targets, h: float, padded: tuple[int, int]):
    """Pixels of the slope check and the angle of the height's own normals there (degrees).

    The height's own normals are its central differences, at the fitted pixels whose four
    neighbours are fitted too (the checked pixels); no surface within the tolerance of the
    height follows the measured normals much more closely than they do (non-integrable
    slopes, noise), so the check asks only for what the height allows. ``targets``: the
    :class:`_Targets` of :func:`_fit` (orthographic). Made per block of rows (a row of halo
    on each side keeps the central differences exact). Returns the checked pixels (bool) and
    their angles (float32, 0 elsewhere), both padded to ``padded`` ``(HP, WP)``.
    """
    H, W = z.shape
    wa = np.zeros(padded, bool)
    wa[:H, :W] = ndimage.binary_erosion(region, border_value=0)
    own = np.zeros(padded, np.float32)
    rows = max(1, BLOCK_PIXELS // W)
    for r0 in range(0, H, rows):
        r1 = min(r0 + rows, H)
        a, b = max(r0 - 1, 0), min(r1 + 1, H)
        gs, gt = np.gradient(np.where(region[a:b], np.asarray(z[a:b], np.float64), 0.0))
        _, ts, tt = targets.rows(r0, r1)
        inner = slice(r0 - a, r1 - a)
        own[r0:r1, :W] = _cell_angles(gs[inner], gt[inner], ts[0][:, :W], tt[0][:, :W], h, wa[r0:r1, :W])
    return wa, own


class _Targets:
    """The value, s-slope and t-slope targets of the fit (component first, zero off the fitted
    pixels), made in float64 per block of rows or of cells from the inputs instead of held as
    whole padded float64 planes.

    ``sources``: per target a tuple of ``(H, W)`` component planes; ``scales``: per target the
    factor on its components (``-h`` for ``z_s = -q h``).
    """

    def __init__(self, sources, scales, region: np.ndarray, width: int):
        self.sources, self.scales, self.region, self.width = sources, scales, region, width

    def rows(self, r0: int, r1: int, parts: int = 3) -> list:
        """Padded rows ``r0:r1`` (``WP`` columns; zero beyond the image), ``(d, r1 - r0, WP)`` each."""
        H, W = self.region.shape
        end = min(r1, H)
        fitted = self.region[r0:end]
        out = []
        for src, scale in zip(self.sources[:parts], self.scales):
            t = np.zeros((len(src), r1 - r0, self.width))
            for c, comp in enumerate(src):
                np.multiply(np.asarray(comp[r0:end], np.float64), scale, out=t[c, :end - r0, :W], where=fitted)
            out.append(t)
        return out

    def cells(self, ci: np.ndarray, cj: np.ndarray, k: int, weight: np.ndarray, parts: int = 3) -> list:
        """Cells ``(ci, cj)`` of side ``k`` with their weights ``(n, k, k)``: ``(d, n, k, k)`` each."""
        H, W = self.region.shape
        # pixels beyond the image have weight 0: any index in range does
        r = np.minimum(ci[:, None] * k + np.arange(k), H - 1)[:, :, None]
        c = np.minimum(cj[:, None] * k + np.arange(k), W - 1)[:, None, :]
        return [np.stack([np.where(weight, np.asarray(comp[r, c], np.float64) * scale, 0.0) for comp in src])
                for src, scale in zip(self.sources[:parts], self.scales)]


def _budget_refine(CI, CJ, fail, worst, region_here, leaves_so_far: int, budget: int) -> np.ndarray | None:
    """The cells to refine within a patch budget: the failing cells' 3 x 3 neighbourhoods (inside the
    level's region), the worst failing cells first, as many as keep ``leaves + 4 x refined + kept``
    within ``budget``; None when not even the worst cell fits."""
    di, dj = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
    allowed = (budget - leaves_so_far - CI.size) // 3  # each refined cell adds three patches
    if allowed < 1:
        return None
    order = np.flatnonzero(fail)[np.argsort(-worst[fail], kind="stable")]
    m = min(order.size, max(1, allowed))
    while m >= 1:
        take = order[:m]
        pos = region_here((CI[take][:, None] + di.ravel()).ravel(), (CJ[take][:, None] + dj.ravel()).ravel())
        refine = np.zeros(CI.size, bool)
        refine[pos[pos >= 0]] = True
        if int(refine.sum()) <= allowed:
            return refine
        m = m // 2 if m > 1 else 0
    return None


def _fit(z, p, q, region, h, tol, k0, xy, lam, angle=None, keep_pixels: bool = True,
         budget: int | None = None) -> SurfaceFit:
    H, W = z.shape
    ns, nt = -(-H // k0), -(-W // k0)
    HP, WP = ns * k0, nt * k0
    d = 1 if xy is None else 3
    # the weights are 0 or 1: one padded byte per pixel
    w = np.zeros((HP, WP), bool)
    w[:H, :W] = region
    if xy is None:
        # z, z_s = -q h, z_t = p h
        targets = _Targets(((z,), (q,), (p,)), (1.0, -h, h), region, WP)
    else:
        zs, zt, fs, ft = _slope_targets(p, q, xy, region)
        sources = ((xy[..., 0], xy[..., 1], z), (fs[..., 0], fs[..., 1], zs), (ft[..., 0], ft[..., 1], zt))
        targets = _Targets(sources, (1.0, 1.0, 1.0), region, WP)
    # running S, S_s, S_t in the inputs' precision: 12 bytes per pixel for float32 heights
    fitted = [np.zeros((d, HP, WP), z.dtype) for _ in range(3)]
    band = max(1, BLOCK_PIXELS // (k0 * WP))  # level-0 cell rows per block
    levels, solved, leaves = [], [], []
    budget_reached = False
    top = int(np.log2(k0))
    slopes_checked = angle is not None and d == 1
    if slopes_checked:
        wa, own = _own_angles(z, region, targets, h, (HP, WP))
    for lev in range(top + 1):
        k = k0 >> lev
        lv = _Level(k, ns << lev, nt << lev, lam * FINE_SLOPE if k == 1 and lev else lam)
        check_slopes = slopes_checked and k >= SLOPE_CELL_PX
        V, D = lv.V, lv.D
        wc = lv.cells(w)
        if lev == 0:
            count = wc.sum(axis=(2, 3))
            # patches over the cells with data and a margin of one cell; B-splines that
            # touch them; cells where those live
            patch = ndimage.binary_dilation(count > 0, np.ones((3, 3), bool))
            act = ndimage.maximum_filter(np.pad(patch, 3), size=4, origin=(-2, -2))[: ns + 3, : nt + 3]
            fi, fj = np.nonzero(act)
            CI, CJ = np.nonzero(patch)
            WI, WJ = np.nonzero(ndimage.binary_dilation(patch, np.ones((7, 7), bool)))
            covered = np.repeat(np.repeat(patch, k, axis=0), k, axis=1)[:H, :W]
            # the targets are zero off the fitted pixels: weighting by w changes nothing
            grid = np.empty((d, ns, nt, 4, 4))
            for b0 in range(0, ns, band):
                tz, ts, tt = targets.rows(b0 * k, min(b0 + band, ns) * k)
                for c in range(d):
                    grid[c, b0:b0 + band] = lv.project_grid(tz[c], V, V) + lv.lam * (
                        lv.project_grid(ts[c], D, V) + lv.project_grid(tt[c], V, D))
            cell_rhs = grid[:, WI, WJ]
            del grid, tz, ts, tt
            ridge = 0.0
        else:
            # an overlay B-spline lies wholly inside the region; outside the image the
            # region continues its edge cells
            here = _Lookup(CI, CJ, (lv.ns, lv.nt))
            ci, cj = np.broadcast_arrays(CI[:, None, None] + _A4[None, :, None], CJ[:, None, None] + _A4[None, None, :])
            keys = np.unique(ci.ravel() * (lv.nt + 3) + cj.ravel())
            ci, cj = keys // (lv.nt + 3), keys % (lv.nt + 3)
            si = np.clip(ci[:, None, None] - 3 + _A4[None, :, None], 0, lv.ns - 1)
            sj = np.clip(cj[:, None, None] - 3 + _A4[None, None, :], 0, lv.nt - 1)
            inside = (here(si, sj) >= 0).reshape(ci.size, 16).all(axis=1)
            fi, fj = ci[inside], cj[inside]
            WI, WJ = CI, CJ
            ww = wc[CI, CJ]
            per = max(1, BLOCK_PIXELS // (k * k))  # cells per block
            chunks = [slice(a, a + per) for a in range(0, CI.size, per)]
            cell_rhs = np.empty((d, CI.size, 4, 4))
            for sl in chunks:
                res = [(t - lv.cells(f)[:, CI[sl], CJ[sl]]) * ww[sl]
                       for t, f in zip(targets.cells(CI[sl], CJ[sl], k, ww[sl]), fitted)]
                cell_rhs[:, sl] = np.stack([lv.project(res[0][c], V, V) + lv.lam * (lv.project(res[1][c], D, V)
                                            + lv.project(res[2][c], V, D)) for c in range(d)])
            del res
            ridge = 1e-9
        # data pixels per cell, without gathering every working cell's k x k weights (only
        # partial cells need theirs, in _assemble)
        if lev == 0:
            n_data = count[WI, WJ]
        else:  # the refined cells' weights are at hand: no pass over the whole image
            n_data = ww.reshape(len(WI), -1).sum(axis=1)
        counts = _Lookup(WI, WJ, (lv.ns, lv.nt))
        support = counts(fi[:, None, None] - 3 + _A4[None, :, None], fj[:, None, None] - 3 + _A4[None, None, :])
        sup = _gather(n_data, support)
        missing = np.clip(1.0 - sup.reshape(len(fi), 16).mean(axis=1) / (k * k), 0.0, 1.0)
        A, b, lookup = _assemble(lv, WI, WJ, n_data, wc, cell_rhs, fi, fj, missing, ridge)
        values = _solve(A, b)
        solved.append((lookup, values))
        if lev == 0:
            coef = np.zeros((ns + 3, nt + 3, d))
            coef[fi, fj] = values
            # evaluated and compared with the targets per block of cell rows
            cell_max = np.empty((ns, nt))
            if check_slopes:
                cell_excess, cell_checked = np.empty((ns, nt)), np.empty((ns, nt))
            for b0 in range(0, ns, band):
                b1 = min(b0 + band, ns)
                for arr, (ps, pt) in zip(fitted, ((V, V), (D, V), (V, D))):
                    for c in range(d):
                        arr[c, b0 * k:b1 * k] = lv.expand_grid(coef[b0:b1 + 3, :, c], ps, pt)
                diff = fitted[0][:, b0 * k:b1 * k] - targets.rows(b0 * k, b1 * k, parts=1)[0]
                dist = np.abs(diff[0]) if d == 1 else np.sqrt((diff * diff).sum(axis=0))
                dist *= w[b0 * k:b1 * k]
                cell_max[b0:b1] = dist.reshape(b1 - b0, k, nt, k).max(axis=(1, 3))
                if check_slopes:
                    r0, r1 = b0 * k, b1 * k
                    _, ts, tt = targets.rows(r0, r1)
                    ang = _cell_angles(fitted[1][0, r0:r1], fitted[2][0, r0:r1], ts[0], tt[0], h,
                                       wa[r0:r1]) - own[r0:r1]
                    cell_excess[b0:b1] = ang.reshape(b1 - b0, k, nt, k).sum(axis=(1, 3))
                    cell_checked[b0:b1] = wa[r0:r1].reshape(b1 - b0, k, nt, k).sum(axis=(1, 3))
            worst = cell_max[CI, CJ]
            if check_slopes:
                slope_miss = cell_excess[CI, CJ] > angle * cell_checked[CI, CJ]
        else:
            block = _gather(values, _window_index(lookup, CI, CJ))  # (n, 4, 4, d)
            worst = np.empty(CI.size)
            if check_slopes:
                slope_miss = np.empty(CI.size, bool)
            for sl in chunks:
                ci, cj = CI[sl], CJ[sl]
                for arr, (ps, pt) in zip(fitted, ((V, V), (D, V), (V, D))):
                    view = lv.cells(arr)
                    for c in range(d):
                        view[c, ci, cj] += lv.expand(block[sl, ..., c], ps, pt)
                # the new S - z on the fitted pixels, from S as stored
                diff = (lv.cells(fitted[0])[:, ci, cj] - targets.cells(ci, cj, k, ww[sl], parts=1)[0]) * ww[sl]
                dist = np.abs(diff[0]) if d == 1 else np.sqrt((diff * diff).sum(axis=0))
                worst[sl] = dist.reshape(len(ci), -1).max(axis=1)
                if check_slopes:
                    _, ts, tt = targets.cells(ci, cj, k, ww[sl])
                    wac = lv.cells(wa)[ci, cj]
                    excess = _cell_angles(lv.cells(fitted[1])[0, ci, cj], lv.cells(fitted[2])[0, ci, cj], ts[0], tt[0],
                                          h, wac) - lv.cells(own)[ci, cj]
                    slope_miss[sl] = (excess.reshape(len(ci), -1).sum(axis=1)
                                      > angle * wac.reshape(len(ci), -1).sum(axis=1))
        del diff, dist
        fail = worst > tol
        if check_slopes:
            fail |= slope_miss
        levels.append({"spacing_px": k, "cells": int(CI.size), "unknowns": int(fi.size), "refined": int(fail.sum())})
        if lev == top or not fail.any():
            leaves.append((lev, CI, CJ))
            break
        # the failing cells and their neighbours inside this level's region are refined
        region_here = _Lookup(CI, CJ, (lv.ns, lv.nt))
        di, dj = np.meshgrid(np.arange(-1, 2), np.arange(-1, 2), indexing="ij")
        pos = region_here((CI[fail][:, None] + di.ravel()).ravel(), (CJ[fail][:, None] + dj.ravel()).ravel())
        refine = np.zeros(CI.size, bool)
        refine[pos[pos >= 0]] = True
        if budget is not None:
            n_leaves = sum(len(c) for _, c, _ in leaves)
            if n_leaves + CI.size + 3 * int(refine.sum()) > budget:
                refine = _budget_refine(CI, CJ, fail, worst, region_here, n_leaves, budget)
                budget_reached = True
                if refine is None:
                    leaves.append((lev, CI, CJ))
                    break
        leaves.append((lev, CI[~refine], CJ[~refine]))
        CI = (2 * CI[refine][:, None] + np.array([0, 0, 1, 1])).ravel()
        CJ = (2 * CJ[refine][:, None] + np.array([0, 1, 0, 1])).ravel()
    del w, wc  # the weights are the region's; the deviations below read it
    arr = view = None  # the refinement's loop names, views of the running surface
    if slopes_checked:
        del wa, own
    # per block of rows on the contiguous fitted arrays (a boolean gather from the strided
    # (H, W, d) views of ``values`` cost more than the rest of the bookkeeping)
    deviation = np.empty((H, W), z.dtype) if keep_pixels else None
    max_dev = squares = 0.0
    rows = max(1, BLOCK_PIXELS // WP)
    for r0 in range(0, H, rows):
        r1 = min(r0 + rows, H)
        diff = fitted[0][:, r0:r1, :W] - targets.rows(r0, r1, parts=1)[0][:, :, :W]
        dv = diff[0] if d == 1 else np.sqrt((diff * diff).sum(axis=0))
        off = ~region[r0:r1]
        dv[off] = 0.0
        max_dev = max(max_dev, float(dv.max()), -float(dv.min()))
        squares += float(np.vdot(dv, dv))
        if keep_pixels:
            dv[off] = np.nan
            deviation[r0:r1] = dv
    if keep_pixels:
        values = tuple(np.moveaxis(f[:, :H, :W], 0, -1) for f in fitted)
    else:
        values = ()
    del fitted  # without keep_pixels the running surface goes before the patches are built
    patches = _patches(leaves, solved, k0, (H, W), h, xy is None)
    n_fitted = int(np.count_nonzero(region))
    rms_dev = float(np.sqrt(squares / n_fitted))
    return SurfaceFit(
        patches=patches,
        deviation=deviation,
        region=region,
        tolerance=float(tol),
        max_deviation=max_dev,
        rms_deviation=rms_dev,
        levels=tuple(levels),
        step=k0,
        pixel_size=float(h),
        covered=covered,
        values=values,
        max_patches=budget,
        budget_reached=budget_reached,
    )


def _patches(leaves, solved, k0: int, shape, h: float, orthographic: bool) -> MixedPatches:
    """Exact Bezier patches of the leaf cells: the sum of every level's B-spline over each leaf."""
    H, W = shape
    d = solved[0][1].shape[-1]
    ctrl, cells = [], []
    for lev, CI, CJ in leaves:
        if CI.size == 0:
            continue
        k = k0 >> lev
        bez = np.zeros((CI.size, 4, 4, d))
        for coarse in range(lev + 1):
            km = k0 >> coarse
            Im, Jm = (CI * k) // km, (CJ * k) // km
            s0 = (CI * k - Im * km) / km
            t0 = (CJ * k - Jm * km) / km
            # the leaf's interval inside the coarse cell takes few values: one matrix each
            starts, s_at = np.unique(s0, return_inverse=True)
            Ts = _blossom_matrix(starts, starts + k / km)[s_at]
            starts, t_at = np.unique(t0, return_inverse=True)
            Tt = _blossom_matrix(starts, starts + k / km).transpose(0, 2, 1)[t_at]
            lookup, values = solved[coarse]
            block = _gather(values, _window_index(lookup, Im, Jm))  # (n, 4, 4, d)
            for c in range(d):
                bez[..., c] += Ts @ block[..., c] @ Tt
        c = np.empty((CI.size, 4, 4, 3))
        if orthographic:
            s = (CI[:, None] * k - 0.5) + k * np.arange(4)[None, :] / 3.0
            t = (CJ[:, None] * k - 0.5) + k * np.arange(4)[None, :] / 3.0
            c[..., 0] = ((t - (W - 1) / 2.0) * h)[:, None, :]
            c[..., 1] = (((H - 1) / 2.0 - s) * h)[:, :, None]
            c[..., 2] = bez[..., 0]
        else:
            c[:] = bez
        ctrl.append(c)
        cells.append(np.stack([CI * k, CJ * k, np.full(CI.size, k)], axis=1))
    return MixedPatches(np.concatenate(ctrl)[:, None], cells=np.concatenate(cells))



def __getattr__(name: str):
    # the trimmed mesh of a fit has its own module (surfaces.fit_mesh, which imports this one);
    # ``surfaces.fit.fit_mesh`` stays importable without a circular import
    if name == "fit_mesh":
        from surfaces.fit_mesh import fit_mesh

        return fit_mesh
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
