"""Errors of a given surface: its slopes through the error model, and its integrated height."""

from __future__ import annotations

import numpy as np

from photometric.errors.model import _exact, _nominal, _true
from photometric.integrate import integrate
from surfaces.validate import as_array, InputError, positive

__all__ = ["surface_derivatives", "height_error"]


def surface_derivatives(height, pixel_size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives ``p = dz/dx``, ``q = dz/dy`` of a height field in the DiLiGenT frame.

    x runs along the columns; y runs up, i.e. along the rows reversed, so
    ``q = -dz/d(row)``. Central differences inside, one-sided at the edges.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height, same length unit as ``pixel_size`` (mm).
    pixel_size : float
        Pixel pitch (mm).

    Returns
    -------
    p, q : numpy.ndarray, shape (H, W), float64
        Slopes.

    Examples
    --------
    >>> z = np.array([[1.0, 1.5, 2.0], [0.0, 0.5, 1.0]])  # rises to the right and upwards
    >>> p, q = surface_derivatives(z, 0.5)
    >>> p[0].tolist(), q[0].tolist()
    ([1.0, 1.0, 1.0], [2.0, 2.0, 2.0])
    """
    h = as_array(height, "height", ndim=2)
    if min(h.shape) < 2:
        raise InputError(f"height: needs at least 2 x 2 pixels, got {h.shape}")
    ps = positive(pixel_size, "pixel_size")
    p = np.gradient(h, ps, axis=1)
    q = -np.gradient(h, ps, axis=0)
    return p, q


def height_error(lights_nominal, lights_true, height, pixel_size: float = 1.0, mask=None) -> dict:
    """Error of a height field's derivatives and of its integrated height.

    The slopes of ``height`` (:func:`surface_derivatives`) are mapped through the exact
    model; both the true and the erroneous slopes are integrated with
    ``photometric.integrate.integrate(method="dct")`` so that the integration error of
    the method itself cancels; the height error is taken after removing its mean.

    Parameters
    ----------
    lights_nominal : array_like, shape (N, 3)
        Nominal unit lights.
    lights_true : array_like, shape (N, 3)
        True unit lights.
    height : array_like, shape (H, W)
        Height field, mm.
    pixel_size : float
        Pixel pitch, mm.
    mask : array_like of bool, shape (H, W), optional
        Pixels the statistics run over (default all).

    Returns
    -------
    dict
        ``dp``, ``dq`` (H, W), ``dh`` (H, W) mm, and the scalars ``max_abs_dp``,
        ``max_abs_dq``, ``rms_dp``, ``rms_dq``, ``rms_dh_mm``, ``max_abs_dh_mm``,
        ``max_angle_deg``.
    """
    L = _nominal(lights_nominal, "lights_nominal")
    Lt = _true(lights_true, L.shape[0])
    if Lt.ndim != 2:
        raise InputError(f"lights_true: expected shape (N, 3), got {Lt.shape}")
    p, q = surface_derivatives(height, pixel_size)
    m = np.ones(p.shape, bool) if mask is None else as_array(mask, "mask", shape=p.shape, dtype=bool)
    if not m.any():
        raise InputError("mask: selects no pixels")
    ex = _exact(L, Lt, p, q)
    h_true = integrate(p, q, method="dct", pixel_size=pixel_size)
    h_est = integrate(ex.p_est, ex.q_est, method="dct", pixel_size=pixel_size)
    dh = h_est - h_true
    dh = dh - dh[m].mean()
    return {
        "dp": ex.dp,
        "dq": ex.dq,
        "dh": dh,
        "max_abs_dp": float(np.abs(ex.dp[m]).max()),
        "max_abs_dq": float(np.abs(ex.dq[m]).max()),
        "rms_dp": float(np.sqrt(np.mean(ex.dp[m] ** 2))),
        "rms_dq": float(np.sqrt(np.mean(ex.dq[m] ** 2))),
        "rms_dh_mm": float(np.sqrt(np.mean(dh[m] ** 2))),
        "max_abs_dh_mm": float(np.abs(dh[m]).max()),
        "max_angle_deg": float(ex.angle_deg[m].max()),
    }
