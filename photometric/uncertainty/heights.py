"""Height uncertainty: the mode variances of white slope noise under DCT integration, their
per-pixel and linear-functional sums, and the systematic slope fields integrated like the
height (:mod:`photometric.uncertainty`, "Linear propagation")."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from surfaces.validate import as_array


def _mode_variance(shape, var_p: float, var_q: float, h: float) -> np.ndarray:
    """``T_kl``: variance of each DCT-II mode of the integrated height (module docstring), float32."""
    rows, cols = shape
    ar = np.pi * np.arange(rows) / (2 * rows)
    ac = np.pi * np.arange(cols) / (2 * cols)
    sr = 4.0 * np.sin(ar) ** 2
    sc = 4.0 * np.sin(ac) ** 2
    num_r = (h * h * var_q * sr * np.cos(ar) ** 2).astype(np.float32)[:, None]
    num_c = (h * h * var_p * sc * np.cos(ac) ** 2).astype(np.float32)[None, :]
    den = sr.astype(np.float32)[:, None] + sc.astype(np.float32)[None, :]
    den[0, 0] = 1.0
    np.square(den, out=den)
    T = num_r + num_c
    T /= den
    T[0, 0] = 0.0
    return T


def _squared_basis_sum(T: np.ndarray, axis: int) -> np.ndarray:
    """``sum_k a_k(r)^2 T_k`` along ``axis`` for the orthonormal DCT-II basis ``a_k``.

    ``a_k(r)^2 = c_k^2 (1 + cos(pi 2k (2 r + 1) / 2n)) / 2``: a constant plus a cosine sum at
    the even frequencies ``j = 2k``; those with ``j >= n`` fold back to ``2n - j`` with a
    minus sign (``cos(pi (2r + 1) - x) = -cos x``), so the sum is one DCT-III of length
    ``n``.
    """
    n = T.shape[axis]
    c2 = np.full(n, 2.0 / n, np.float32)
    c2[0] = 1.0 / n
    shape = [1, 1]
    shape[axis] = n
    Y = np.moveaxis(T * c2.reshape(shape), axis, 0)
    const = 0.5 * Y.sum(axis=0, keepdims=True)
    folded = np.zeros_like(Y)
    low = np.arange(0, (n + 1) // 2)  # j = 2k < n
    folded[2 * low] += Y[low]
    high = np.arange((n + 2) // 2, n)  # j = 2n - 2k, 0 < j < n (j = n: cos = 0)
    folded[2 * n - 2 * high] -= Y[high]
    folded[1:] *= 0.5  # scipy's DCT-III doubles every term but the first
    S = sfft.dct(folded, type=3, axis=0, workers=-1, overwrite_x=True)
    return np.moveaxis(const + 0.5 * S, 0, axis)


def height_noise_variance(shape, var_p: float, var_q: float, pixel_size: float = 1.0) -> np.ndarray:
    """Per-pixel variance of the DCT-integrated height for white slope noise.

    Parameters
    ----------
    shape : (H, W)
        Image size.
    var_p, var_q : float
        Variances of the slope noise (independent between pixels).
    pixel_size : float
        Pixel size (mm); the variance is in mm^2.

    Returns
    -------
    numpy.ndarray, shape (H, W), float64
        ``sum_kl a_k(r)^2 b_l(c)^2 T_kl`` (module docstring); the height's zero mean over
        the image is the datum, as :func:`photometric.integrate.dct_poisson` returns it.
    """
    T = _mode_variance(shape, float(var_p), float(var_q), float(pixel_size))
    return np.maximum(_squared_basis_sum(_squared_basis_sum(T, 0), 1), 0.0).astype(np.float64)


def linear_variance(weights, var_p: float, var_q: float, pixel_size: float = 1.0) -> float:
    """Variance of ``sum_i w_i z_i`` (a linear figure of the DCT-integrated height).

    Parameters
    ----------
    weights : array_like, shape (H, W)
        ``w`` (e.g. +1 at a defect's deepest pixel and minus the background fit's weights).
    var_p, var_q, pixel_size :
        As :func:`height_noise_variance`.

    Returns
    -------
    float
        ``sum_kl T_kl DCT(w)_kl^2`` (mm^2 times the unit of ``w`` squared).
    """
    w = as_array(weights, "weights", ndim=2)
    return _linear_variance(w, _mode_variance(w.shape, float(var_p), float(var_q), float(pixel_size)))


def _linear_variance(w: np.ndarray, T: np.ndarray) -> float:
    W = sfft.dctn(w.astype(np.float32), type=2, norm="ortho", workers=-1)
    return float(np.sum(T * W * W, dtype=np.float64))


def _bin(a: np.ndarray, r: int) -> np.ndarray:
    """Means of ``r x r`` blocks (trailing rows and columns dropped, as
    :func:`photometric.nearfield._upsample` expects); OpenCV's area resampling."""
    import cv2

    h, w = a.shape[0] // r, a.shape[1] // r
    return cv2.resize(a[: h * r, : w * r], (w, h), interpolation=cv2.INTER_AREA)


def _integrate_field(dp: np.ndarray, dq: np.ndarray, integrator: str, ok: np.ndarray, h: float) -> np.ndarray:
    """A systematic slope field (zero outside ``ok``) integrated like the height: float32 DCT
    for ``dct`` (uncertainties need no more digits), zero mean over ``ok``, zero outside."""
    from photometric.integrate import dct_poisson, integrate

    if integrator == "dct":
        z = dct_poisson(dp, dq, None, h, dtype=np.float32).astype(np.float32)
    else:
        z = np.nan_to_num(integrate(dp, dq, integrator, mask=ok, pixel_size=h)).astype(np.float32)
    if not ok.all():
        z -= np.float32(z[ok].mean())
        z[~ok] = 0.0
    return z


def _point_variance(T: np.ndarray, row: int, col: int) -> float:
    """Variance of the integrated height at one pixel: ``a(row)^2 . T . b(col)^2``."""
    h, w = T.shape
    a = np.cos(np.pi * np.arange(h) * (2 * row + 1) / (2 * h)) ** 2 * (2.0 / h)
    a[0] = 1.0 / h
    b = np.cos(np.pi * np.arange(w) * (2 * col + 1) / (2 * w)) ** 2 * (2.0 / w)
    b[0] = 1.0 / w
    return float(a.astype(np.float32) @ T @ b.astype(np.float32))
