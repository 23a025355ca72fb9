"""Small PNG previews of photometric results (OpenCV only, no matplotlib).

``photometric`` sits below ``workbench`` in the package graph, so it keeps its own
tiny preview writers; ``workbench.images`` has the annotated figures.
"""

from __future__ import annotations


import cv2
import numpy as np

from surfaces.validate import as_array


def normals_rgb(normals, mask=None) -> np.ndarray:
    """Normal map as RGB: ``(n + 1) / 2 * 255``, black outside the mask.

    Parameters
    ----------
    normals : array_like, shape (H, W, 3)
        Unit normals (x right, y up, z to the camera).
    mask : array_like, shape (H, W), optional

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), uint8
    """
    n = as_array(normals, "normals", shape=(None, None, 3), dtype=np.float32)
    img = np.clip((n + 1.0) * 127.5, 0, 255).astype(np.uint8)
    if mask is not None:
        img[~as_array(mask, "mask", shape=n.shape[:2], dtype=bool)] = 0
    return img


def scaled(image, mask=None, percentile: float = 99.5, colormap: int | None = None) -> np.ndarray:
    """A scalar or RGB image stretched to 8 bits (optionally colour-mapped).

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3)
        Values; NaN is shown black.
    mask : array_like, shape (H, W), optional
        Pixels used for the stretch (others black).
    percentile : float, optional
        Upper value mapped to 255 (lower: the ``100 - percentile`` one for colour maps,
        0 otherwise).
    colormap : int, optional
        An OpenCV colour map (e.g. ``cv2.COLORMAP_VIRIDIS``) for scalar images.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3) or (H, W), uint8
    """
    a = as_array(image, "image", ndim=(2, 3), finite=False)
    good = np.isfinite(a) if a.ndim == 2 else np.isfinite(a).all(axis=2)
    if mask is not None:
        good &= as_array(mask, "mask", shape=a.shape[:2], dtype=bool)
    vals = a[good]
    if vals.size == 0:
        return np.zeros(a.shape[:2] + ((3,) if a.ndim == 3 or colormap is not None else ()), np.uint8)
    lo = float(np.percentile(vals, 100.0 - percentile)) if colormap is not None else 0.0
    hi = float(np.percentile(vals, percentile))
    span = hi - lo if hi > lo else 1.0
    out = np.clip((np.nan_to_num(a) - lo) / span * 255.0, 0, 255).astype(np.uint8)
    if colormap is not None and out.ndim == 2:
        out = cv2.applyColorMap(out, colormap)[..., ::-1].copy()
    out[~good] = 0
    return out
