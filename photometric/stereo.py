"""Lambertian photometric stereo: per-pixel normal and albedo (seed 002(a)).

``I_k = rho * (l_k . n)``, k = 1..N: with the matrix ``L`` of unit light directions,
``rho n = L^-1 I`` for a triad and ``rho n = L^+ I`` (least squares) for ``N >= 4``.
The solve is one pass over whole image planes (OpenCV weighted sums, which run close to
memory speed); shadow/highlight outliers are handled by grouping the affected pixels by
their outlier pattern and solving once per distinct pattern, never per pixel.
Coordinates follow :data:`photometric.lights.CONVENTION`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from photometric.lights import as_intensities, validate_lights
from photometric.options import DARK, SATURATION
from surfaces.validate import as_array, InputError

#: Light sub-matrices worse conditioned than this give no trustworthy normal; a light
#: matrix above it is refused unless forced (8-bit noise of 0.4 % becomes ~40 % in ``rho n``).
MAX_CONDITION = 100.0
#: A light matrix worse conditioned than this is warned about (errors grow ~10x the noise).
WARN_CONDITION = 10.0
#: Values (full scale 1) below this are black: half an 8-bit step, no signal to solve with.
BLACK_FLOOR = 0.5 / 255
#: Values (full scale 1) at or above this are saturated: within half an 8-bit step of full scale.
SATURATED = 1.0 - 0.5 / 255
#: An image is unusable when at least this fraction of its mask pixels is saturated or black.
UNUSABLE_FRACTION = 0.99
#: Pixels per row block of a solve with ``on_block`` (:func:`solve`): the block's working
#: arrays are a few MB, whatever the image size.
BLOCK_PIXELS = 1 << 16


@dataclass(frozen=True)
class StereoResult:
    """Per-pixel output of :func:`solve`.

    Attributes
    ----------
    normals : numpy.ndarray or None, shape (H, W, 3), float32
        Unit normals in the lights' frame; ``(0, 0, 1)`` where no solution exists
        (outside the mask, or zero albedo). None when a solve with ``on_block`` passed
        them on block by block.
    albedo : numpy.ndarray or None, shape (H, W) or (H, W, 3), float32
        ``rho`` in image units divided by light intensity; RGB for colour input.
        Zero where no solution exists. None like ``normals``.
    valid : numpy.ndarray, shape (H, W), bool
        Inside the mask, positive albedo, normal facing the camera (``n_z > 0``), and,
        in outlier mode, at least 3 well-conditioned inlier observations (triad: none
        of the three is an outlier).
    residual : numpy.ndarray, shape (H, W), float32
        Root-mean-square of ``x_k - l_k . (rho n)`` over the observations used (grey,
        intensity-divided units); zero for an exactly determined triad.
    p, q : numpy.ndarray, shape (H, W), float32
        ``p = dz/dx = -n_x / n_z`` and ``q = dz/dy = -n_y / n_z`` (y up); zero where
        not valid.
    outliers : numpy.ndarray or None, shape (N, H, W), bool
        Observations flagged as shadow/highlight (outlier mode only; None with ``on_block``).
    """

    normals: np.ndarray | None
    albedo: np.ndarray | None
    valid: np.ndarray
    residual: np.ndarray
    p: np.ndarray
    q: np.ndarray
    outliers: np.ndarray | None = None


@dataclass(frozen=True)
class InputScreen:
    """Which observations can carry information (:func:`screen_images`).

    Attributes
    ----------
    saturated : numpy.ndarray, shape (N,), float
        Fraction of each image's mask pixels at or above the saturation level.
    black : numpy.ndarray, shape (N,), float
        Fraction of each image's mask pixels below :data:`BLACK_FLOOR`.
    usable : numpy.ndarray, shape (N,), bool
        Images with less than :data:`UNUSABLE_FRACTION` of their mask saturated or black.
    enough : numpy.ndarray, shape (H, W), bool
        Pixels with at least 3 valid observations among the usable images.
    """

    saturated: np.ndarray
    black: np.ndarray
    usable: np.ndarray
    enough: np.ndarray

    def problems(self, names) -> list[str]:
        """One phrase per unusable image, e.g. ``"'b.png' is saturated (100 % of the mask)"``."""
        out = []
        for k in np.flatnonzero(~self.usable):
            kind, frac = ("saturated", self.saturated[k]) if self.saturated[k] >= self.black[k] else (
                "black", self.black[k])
            out.append(f"{names[k]!r} is {kind} ({100 * frac:.0f} % of the mask)")
        return out


def screen_images(images, mask=None, saturation: float = SATURATED, floor: float = BLACK_FLOOR) -> InputScreen:
    """Find saturated and black observations, the images they ruin and the pixels left unsolvable.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        Linear images scaled to full scale 1 (:func:`photometric.io.read_image`).
    mask : array_like, shape (H, W), bool, optional
        Pixels that count (default all).
    saturation : float
        An observation is saturated when any channel is at or above this (default
        :data:`SATURATED`: full scale 1 minus half an 8-bit step; ``inf``: no test).
    floor : float
        An observation is black when every channel is below this (default
        :data:`BLACK_FLOOR`, half an 8-bit step).

    Returns
    -------
    InputScreen
        Per-image fractions, usable images and the pixels with at least 3 valid
        observations among the usable images.

    Notes
    -----
    One pass per image (no copy of the stack, no plane kept per image), so the memory
    is a few (H, W) planes whatever N is.

    Examples
    --------
    >>> imgs = np.full((4, 2, 2), 0.5, np.float32)
    >>> imgs[1] = 1.0
    >>> imgs[2, 0, 0] = 0.0
    >>> s = screen_images(imgs)
    >>> s.usable.tolist(), s.enough.tolist()
    ([True, False, True, True], [[False, True], [True, True]])
    """
    imgs = _check_images(images)
    n_img, height, width = imgs.shape[:3]
    m = None if mask is None else as_array(mask, "mask", shape=(height, width), dtype=bool)
    n_mask = max(int(m.sum()) if m is not None else height * width, 1)
    sat_frac, black_frac = np.zeros(n_img), np.zeros(n_img)
    count = np.zeros((height, width), np.uint16)

    def bad(k):
        top = imgs[k].max(axis=2) if imgs.ndim == 4 else imgs[k]
        return top >= saturation, top < floor

    for k in range(n_img):
        sat, black = bad(k)
        sat_frac[k] = np.count_nonzero(sat if m is None else sat & m) / n_mask
        black_frac[k] = np.count_nonzero(black if m is None else black & m) / n_mask
        count += ~(sat | black)
    usable = sat_frac + black_frac < UNUSABLE_FRACTION
    # an unusable image's few valid pixels are taken back out (recomputed: no plane is kept per image)
    for k in np.flatnonzero(~usable):
        sat, black = bad(k)
        count -= ~(sat | black)
    return InputScreen(sat_frac, black_frac, usable, count >= 3)


def restrict(result: StereoResult, enough: np.ndarray) -> StereoResult:
    """Mark pixels outside ``enough`` invalid (``p = q = 0`` there); normals and albedo are kept.

    Parameters
    ----------
    result : StereoResult
        A solve (its arrays are changed in place).
    enough : numpy.ndarray, shape (H, W), bool
        Pixels that may stay valid (:attr:`InputScreen.enough`).

    Returns
    -------
    StereoResult
        ``result`` with ``valid &= enough``.
    """
    drop = result.valid & ~enough
    if drop.any():
        result.valid[drop] = False
        result.p[drop] = 0.0
        result.q[drop] = 0.0
    return result


def check_light_matrix(lights, force: bool = False) -> tuple[float, list[str]]:
    """Condition number of the light matrix; refuse nearly coplanar or backward lights.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Unit light directions (:data:`photometric.lights.CONVENTION`, z towards the camera).
    force : bool
        Solve even above :data:`MAX_CONDITION` (100); the result is then a warning.

    Returns
    -------
    condition : float
        Ratio of the extreme singular values (1 is ideal, a 45 deg triad about 2.7).
    warnings : list of str
        One line each: condition above :data:`WARN_CONDITION` (10), or above
        :data:`MAX_CONDITION` when forced.

    Raises
    ------
    ValueError
        A light with ``z < 0`` (from behind the surface), or a condition number above
        :data:`MAX_CONDITION` (nearly coplanar lights: the error of ``rho n`` is that
        many times the image noise) unless ``force``.
    """
    return _light_matrix(validate_lights(lights), force)


def _light_matrix(L: np.ndarray, force: bool = False) -> tuple[float, list[str]]:
    """:func:`check_light_matrix` of unit lights already checked (the pipeline's stages)."""
    back = np.flatnonzero(L[:, 2] < 0)
    if back.size:
        raise InputError(
            f"lights: {back.size} light(s) with z < 0 (rows {back[:5].tolist()}, z = "
            f"{np.round(L[back[:5], 2], 4).tolist()}): they point away from the camera and light the surface "
            "from behind; z is towards the camera (flip the sign of z, or check the axes)")
    s = np.linalg.svd(L, compute_uv=False)
    cond = float(s[0] / s[-1])
    what = (f"lights: condition number {cond:,.0f} of the light matrix (nearly coplanar lights; errors in the "
            f"normals are up to {cond:,.0f}x the image noise)")
    if cond > MAX_CONDITION and not force:
        raise InputError(f"{what} is above {MAX_CONDITION:g}; spread the lights or use --force")
    if cond > WARN_CONDITION:
        return cond, [f"{what} is above {WARN_CONDITION:g}" + (" (forced)" if cond > MAX_CONDITION else "")]
    return cond, []


def _check_images(images) -> np.ndarray:
    """Images as float32 (N, H, W) or (N, H, W, 3); finiteness is checked after the solve."""
    arr = as_array(images, "images", ndim=(3, 4), dtype=np.float32, finite=False)
    if arr.ndim == 4 and arr.shape[3] not in (1, 3):
        raise InputError(f"images: expected 1 or 3 channels, got shape {arr.shape}")
    if arr.ndim == 4 and arr.shape[3] == 1:
        arr = arr[..., 0]
    if min(arr.shape[1:3]) < 1:
        raise InputError(f"images: empty image size {arr.shape[1:3]}")
    return np.ascontiguousarray(arr)


def _check_finite(rho: np.ndarray, imgs: np.ndarray) -> None:
    """A NaN or inf in any image reaches ``rho`` (``0 * nan`` is NaN), whose sum is a third of
    the work of summing the input; count the bad input values only when it fails."""
    if not np.isfinite(np.sum(rho, dtype=np.float32)):
        bad = int(imgs.size - np.count_nonzero(np.isfinite(imgs)))
        raise InputError(
            f"images: contains {bad} NaN or infinite value(s)"
            if bad
            else "images: values too large (the albedo overflows float32)"
        )


def _combine(weights: np.ndarray, planes: list[np.ndarray]) -> np.ndarray:
    """``sum_k weights[k] * planes[k]`` for (H, W) float32 planes, OpenCV passes."""
    out = cv2.addWeighted(planes[0], float(weights[0]), planes[1], float(weights[1]), 0.0)
    for w, plane in zip(weights[2:], planes[2:]):
        cv2.scaleAdd(plane, float(w), out, dst=out)
    return out


def _grey_planes(imgs: np.ndarray, intens: np.ndarray) -> list[np.ndarray]:
    """Intensity-divided grey planes: ``x_k = mean_c I_kc / E_kc`` (channels averaged)."""
    planes = []
    for k in range(imgs.shape[0]):
        if imgs.ndim == 4:
            w = (1.0 / (imgs.shape[3] * intens[k])).reshape(1, 3)
            planes.append(cv2.transform(imgs[k], w))
        else:
            e = float(intens[k].mean())
            planes.append(imgs[k] if e == 1.0 else imgs[k] * np.float32(1.0 / e))
    return planes


def _solve_patterns(
    X: np.ndarray, L: np.ndarray, out: np.ndarray, G: np.ndarray, ok: np.ndarray
) -> None:
    """Re-solve ``G`` (3, P) in place from the inlier observations of each pixel.

    Pixels are grouped by their outlier pattern (a bit code per pixel) and each distinct
    pattern is solved once with the pseudo-inverse of its light sub-matrix. ``ok`` (P,)
    is cleared where fewer than 3 inliers remain or the sub-matrix is ill-conditioned.
    """
    n = L.shape[0]
    sub = np.flatnonzero(out.any(axis=0))
    if sub.size == 0:
        return
    pat = out[:, sub]
    if n <= 62:
        codes = (np.uint64(1) << np.arange(n, dtype=np.uint64)) @ pat.astype(np.uint64)
        uniq, inverse = np.unique(codes, return_inverse=True)
        patterns = ((uniq[:, None] >> np.arange(n, dtype=np.uint64)) & np.uint64(1)).astype(bool)
    else:
        patterns, inverse = np.unique(pat.T, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(inverse, kind="stable")
    bounds = np.searchsorted(inverse[order], np.arange(len(patterns) + 1))
    for j, pattern in enumerate(patterns):
        cols = sub[order[bounds[j] : bounds[j + 1]]]
        keep = ~pattern
        if keep.sum() < 3:
            ok[cols] = False
            continue
        Lk = L[keep]
        s = np.linalg.svd(Lk, compute_uv=False)
        if s[-1] <= 0 or s[0] / s[-1] > MAX_CONDITION:
            ok[cols] = False
            continue
        G[:, cols] = (np.linalg.pinv(Lk).astype(np.float32) @ X[keep][:, cols]).astype(np.float32)


def solve(
    images,
    lights,
    intensities=None,
    mask=None,
    outliers: bool = False,
    *,
    dark: float = DARK,
    saturation: float = SATURATION,
    highlight: float | None = None,
    iterations: int = 2,
    on_block: Callable[[slice, StereoResult], None] | None = None,
) -> StereoResult:
    """Per-pixel normals and albedo from N >= 3 images under known lights.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        Linear images (float, typically in [0, 1]); colour in RGB order.
    lights : array_like, shape (N, 3)
        Unit light directions (:data:`photometric.lights.CONVENTION`).
    intensities : None, float or array_like, shape (N,) or (N, 3), optional
        Light intensities, divided out per channel (``None``: all ones).
    mask : array_like, shape (H, W), optional
        Pixels to solve (default all).
    outliers : bool, optional
        Shadow/highlight handling. An observation is an outlier when it is dark
        (``x_k < dark * rho``), saturated (any channel ``>= saturation`` in the input
        images) or, when ``highlight`` is given, brighter than the Lambertian
        prediction by more than ``highlight * rho``. With ``N >= 4`` outliers are
        dropped and the pixel re-solved from the rest (at least 3, well conditioned);
        with a triad the pixel becomes invalid.
    dark, saturation, highlight : float, optional
        Thresholds of the outlier test (see above).
    iterations : int, optional
        Detect/re-solve rounds in outlier mode (the albedo estimate improves after the
        first).
    on_block : callable, optional
        Solve in blocks of rows (about :data:`BLOCK_PIXELS` pixels each) and call
        ``on_block(rows, part)`` with each block's row slice and its
        :class:`StereoResult` (arrays of ``rows`` only) as soon as it is solved; the
        returned result then keeps only ``valid``, ``residual``, ``p`` and ``q``
        (normals, albedo and outlier flags are None), so the caller can stream the
        rest to files. Every pixel is solved on its own, so the values are the same
        (bit for bit for a triad; with N > 3 the float32 matrix products may round
        differently, about 1e-7).

    Returns
    -------
    StereoResult
        Normals, albedo, validity, residual, ``p``, ``q`` (and outlier flags).

    Notes
    -----
    Seed 002(a): ``rho n = L^-1 I``; for ``N >= 4`` the least-squares solution
    ``rho n = (L^T L)^-1 L^T I``. Colour images: channels are divided by the
    intensities and averaged to grey to solve for one normal; the albedo of channel
    ``c`` is then ``sum_k x_kc s_k / sum_k s_k^2`` with ``s_k = l_k . n`` over the
    observations used.

    Examples
    --------
    A 2 x 2 patch of slope ``p = 0.2``, ``q = -0.1`` and albedo 0.5 under the 45 deg triad:

    >>> from photometric.lights import ring_lights
    >>> from photometric.normals import normals_from_slopes
    >>> L = ring_lights(3, 45.0)
    >>> images = 0.5 * (L @ normals_from_slopes(0.2, -0.1))[:, None, None] * np.ones((3, 2, 2))
    >>> res = solve(images, L)
    >>> round(float(res.p[0, 0]), 5), round(float(res.q[0, 0]), 5), round(float(res.albedo[0, 0]), 5)
    (0.2, -0.1, 0.5)
    >>> bool(res.valid.all())
    True
    """
    imgs = _check_images(images)
    n_img, height, width = imgs.shape[:3]
    L = validate_lights(lights)
    if L.shape[0] != n_img:
        raise InputError(f"lights: {L.shape[0]} directions for {n_img} images")
    intens = as_intensities(intensities, n_img)
    m = None if mask is None else as_array(mask, "mask", shape=(height, width), dtype=bool)
    if m is not None and not m.any():
        raise InputError("mask: no pixel is selected")
    _check_options(dark, saturation, highlight, iterations)
    if on_block is not None:
        return _solve_rows(imgs, L, intens, m, outliers, dark, saturation, highlight, int(iterations), on_block)
    return _solve(imgs, L, intens, m, outliers, dark, saturation, highlight, int(iterations))


def _check_options(dark: float, saturation: float, highlight: float | None, iterations: int) -> None:
    """The thresholds of the outlier test: checked where they enter (solve, the pipeline)."""
    for value, name in ((dark, "dark"), (saturation, "saturation")):
        if not np.isfinite(value) or value <= 0:
            raise InputError(f"{name}: must be a positive number, got {value}")
    if highlight is not None and (not np.isfinite(highlight) or highlight <= 0):
        raise InputError(f"highlight: must be a positive number or None, got {highlight}")
    if int(iterations) < 1:
        raise InputError(f"iterations: must be at least 1, got {iterations}")


def _solve(
    imgs: np.ndarray,
    L: np.ndarray,
    intens: np.ndarray,
    m: np.ndarray | None,
    outliers: bool,
    dark: float,
    saturation: float,
    highlight: float | None,
    iterations: int,
) -> StereoResult:
    """:func:`solve` on validated input: images from :func:`_check_images`, unit lights (N, 3)
    matching them, intensities (N, 3), a boolean mask or None, checked thresholds."""
    n_img, height, width = imgs.shape[:3]
    planes = _grey_planes(imgs, intens)
    M = np.linalg.inv(L) if n_img == 3 else np.linalg.pinv(L)
    g = [_combine(M[i], planes) for i in range(3)]
    scratch = cv2.magnitude(g[0], g[1])
    rho = cv2.magnitude(scratch, g[2])
    _check_finite(rho, imgs)
    ok = rho > 0
    if m is not None:
        ok &= m

    residual = np.zeros((height, width), np.float32)
    out_flags = None
    inliers = None  # (N, P) over `idx` pixels, only when some observations are dropped
    idx = None
    if outliers or n_img > 3:
        idx = np.flatnonzero(m) if m is not None else slice(None)
        X = np.stack([pl.reshape(-1)[idx] for pl in planes])
        G = np.stack([gi.reshape(-1)[idx] for gi in g])
        L32 = L.astype(np.float32)
        ok_base = ok.reshape(-1)[idx]
        ok_m = ok_base.copy()
        if outliers:
            sat_src = imgs.max(axis=3) if imgs.ndim == 4 else imgs
            sat = sat_src.reshape(n_img, -1)[:, idx] >= saturation
            G_all = G.copy()
            for _ in range(int(iterations)):
                r = np.sqrt(np.einsum("ip,ip->p", G, G))
                out = (X < dark * r) | sat
                if highlight is not None:
                    out |= (X - L32 @ G) > highlight * r
                if n_img == 3:
                    ok_m &= ~out.any(axis=0)
                    break
                G = G_all.copy()
                ok_m = ok_base.copy()
                _solve_patterns(X, L, out, G, ok_m)
            inliers = ~out
            out_flags = np.zeros((n_img, height * width), bool)
            out_flags[:, idx] = out
            out_flags = out_flags.reshape(n_img, height, width)
        if n_img > 3:
            err = X - L32 @ G
            if inliers is not None:
                err = np.where(inliers, err, 0.0)
                count = np.maximum(inliers.sum(axis=0), 1)
            else:
                count = n_img
            residual.reshape(-1)[idx] = np.sqrt((err * err).sum(axis=0) / count)
        for i in range(3):
            g[i].reshape(-1)[idx] = G[i]
        cv2.magnitude(g[0], g[1], scratch)
        rho = cv2.magnitude(scratch, g[2])
        ok.reshape(-1)[idx] = ok_m & (rho.reshape(-1)[idx] > 0)
        del X, G

    # Normalise in place (multi-threaded OpenCV passes, buffers reused: fewer fresh pages).
    # Where rho == 0 the reciprocal is inf and the products NaN; those pixels are blanked
    # right after.
    inv = cv2.divide(1.0, rho, dst=scratch)
    for gi in g:
        cv2.multiply(gi, inv, dst=gi)
    del inv, scratch
    # No solution: a flat normal and zero albedo, so downstream sums stay finite.
    if idx is None and m is None:
        blank = ~ok  # fast path: ok is exactly rho > 0
    else:
        blank = rho <= 0 if m is None else (rho <= 0) | ~m
    if blank.any():
        g[2][blank] = 1.0
        g[0][blank] = 0.0
        g[1][blank] = 0.0
        rho[blank] = 0.0
    ok &= g[2] > 0
    normals = cv2.merge(g)
    # p and q overwrite the x and y planes, which the merge has copied.
    p = cv2.divide(g[0], g[2], dst=g[0], scale=-1.0)
    q = cv2.divide(g[1], g[2], dst=g[1], scale=-1.0)
    del g
    if not ok.all():
        bad = ~ok
        p[bad] = 0.0
        q[bad] = 0.0

    albedo = rho
    if imgs.ndim == 4:
        albedo = _colour_albedo(imgs, intens, L, normals, inliers, idx, blank)
    return StereoResult(
        normals=normals, albedo=albedo, valid=ok, residual=residual, p=p, q=q, outliers=out_flags
    )


def _solve_rows(
    imgs: np.ndarray,
    L: np.ndarray,
    intens: np.ndarray,
    m: np.ndarray | None,
    outliers: bool,
    dark: float,
    saturation: float,
    highlight: float | None,
    iterations: int,
    on_block: Callable[[slice, StereoResult], None],
) -> StereoResult:
    """:func:`_solve` block of rows by block of rows (see ``on_block`` of :func:`solve`).

    Only the four planes the later stages need are kept (10 bytes per pixel); a block's
    normals, albedo and working arrays are dropped once ``on_block`` has them.
    """
    height, width = imgs.shape[1:3]
    valid = np.empty((height, width), bool)
    # a triad's residual is zero: left as calloc'ed pages that are never touched (no memory)
    residual = np.zeros((height, width), np.float32)
    exact = imgs.shape[0] == 3
    p = np.empty((height, width), np.float32)
    q = np.empty((height, width), np.float32)
    step = max(1, BLOCK_PIXELS // width)
    for r0 in range(0, height, step):
        rows = slice(r0, min(r0 + step, height))
        try:
            part = _solve(imgs[:, rows], L, intens, None if m is None else m[rows], outliers, dark, saturation,
                          highlight, iterations)
        except ValueError:
            # name the whole input's count of bad values, not the block's
            _check_finite(np.full(1, np.nan, np.float32), imgs)
            raise
        valid[rows], p[rows], q[rows] = part.valid, part.p, part.q
        if not exact:
            residual[rows] = part.residual
        on_block(rows, part)
        del part
    return StereoResult(normals=None, albedo=None, valid=valid, residual=residual, p=p, q=q)


def _colour_albedo(imgs, intens, L, normals, inliers, idx, blank) -> np.ndarray:
    """Per-channel albedo given the normal: ``sum_k x_kc s_k / sum_k s_k^2``."""
    n_img, height, width = imgs.shape[:3]
    shading = (normals.reshape(-1, 3) @ L.T.astype(np.float32)).T  # (N, P)
    if inliers is not None:
        used = np.ones((n_img, height * width), bool)
        used[:, idx] = inliers
        shading = np.where(used, shading, 0.0).astype(np.float32)
    num = np.zeros((height * width, 3), np.float32)
    for k in range(n_img):
        num += imgs[k].reshape(-1, 3) * (shading[k][:, None] / intens[k].astype(np.float32))
    den = np.einsum("kp,kp->p", shading, shading)
    albedo = np.divide(num, den[:, None], out=np.zeros_like(num), where=den[:, None] > 0)
    albedo = albedo.reshape(height, width, 3)
    albedo[blank] = 0.0
    return albedo
