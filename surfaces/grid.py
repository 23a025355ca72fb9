"""The one pixel-grid convention of the workbench: pixel centres in mm.

Every output that places pixels in space (synthetic scenes, height fields turned
into patches and meshes, ``xy.npy``, defect centres, overlays) uses this grid:
x to the right (column index), y **up** (row 0 is the top row), z towards the
camera, the origin at the image centre. Pixel ``(row, col)`` of an ``H x W``
image has its centre at::

    x = (col - (W - 1) / 2) * pixel_size
    y = ((H - 1) / 2 - row) * pixel_size
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import as_array, InputError, positive

__all__ = ["GRID_CONVENTION", "image_shape", "pixel_grid", "pixel_axes", "xy_to_pixel"]

GRID_CONVENTION = (
    "Pixel (row, col) of an H x W image has its centre at x = (col - (W - 1) / 2) * pixel_size, "
    "y = ((H - 1) / 2 - row) * pixel_size, in mm: x right, y up (row 0 is the top row), "
    "z towards the camera."
)


def image_shape(size, name: str = "size") -> tuple[int, int]:
    """``(H, W)`` from an int (square) or a pair of whole pixel counts.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels; each side at least 2.
    name : str, optional
        Argument name used in messages.

    Returns
    -------
    tuple of int
        ``(H, W)``.

    Examples
    --------
    >>> image_shape(4), image_shape((3, 5))
    ((4, 4), (3, 5))
    """
    dims = np.atleast_1d(np.asarray(size))
    if dims.ndim != 1 or len(dims) not in (1, 2):
        raise InputError(f"{name}: expected an int or (H, W), got {size!r}")
    if len(dims) == 1:
        dims = np.repeat(dims, 2)
    try:
        values = dims.astype(float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected whole numbers of pixels, got {size!r}") from None
    if not np.all(np.isfinite(values)) or np.any(values % 1 != 0):
        raise InputError(f"{name}: expected whole numbers of pixels, got {size!r}")
    h, w = int(values[0]), int(values[1])
    if h < 2 or w < 2:
        raise InputError(f"{name}: need at least 2 x 2 pixels, got {size!r}")
    return h, w


def pixel_axes(size, pixel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """The pixel-centre coordinates along each image axis, in mm.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm (> 0).

    Returns
    -------
    x : (W,) float64
        Column centres, increasing to the right.
    y : (H,) float64
        Row centres, decreasing down the image (y up).

    Examples
    --------
    >>> x, y = pixel_axes((2, 3), 0.5)
    >>> x.tolist(), y.tolist()
    ([-0.5, 0.0, 0.5], [0.25, -0.25])
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    x = (np.arange(w, dtype=np.float64) - (w - 1) / 2.0) * ps
    y = ((h - 1) / 2.0 - np.arange(h, dtype=np.float64)) * ps
    return x, y


def pixel_grid(size, pixel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of every pixel centre in mm, following :data:`GRID_CONVENTION`.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm (> 0).

    Returns
    -------
    x, y : (H, W) float64 arrays
        x grows with the column index, y decreases with the row index (y up).
    """
    x, y = pixel_axes(size, pixel_size)
    h, w = y.size, x.size
    return np.broadcast_to(x[None, :], (h, w)).copy(), np.broadcast_to(y[:, None], (h, w)).copy()


def xy_to_pixel(x, y, size, pixel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Fractional ``(row, col)`` pixel indices of mm coordinates (inverse of :func:`pixel_grid`).

    Parameters
    ----------
    x, y : array_like
        Coordinates in mm.
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm (> 0).

    Returns
    -------
    row, col : float64 arrays
        Same shape as ``x`` and ``y``.

    Examples
    --------
    >>> row, col = xy_to_pixel(0.0, 0.0, (3, 5), 1.0)
    >>> float(row), float(col)
    (1.0, 2.0)
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    x = as_array(x, "x")
    y = as_array(y, "y")
    return (h - 1) / 2.0 - y / ps, x / ps + (w - 1) / 2.0
