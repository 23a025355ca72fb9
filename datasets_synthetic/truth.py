"""How far a reconstruction is from the ground truth a synthetic folder holds.

:func:`render.write_diligent_folder` and :func:`nearfield.make_near_field_folder` write
``height_gt.npy`` (H, W) z in mm and, near field, ``xy_gt.npy`` (H, W, 2) x, y in mm beside
the images; :func:`height_errors` compares a height map (and the points each pixel sees)
with them. The library pipeline (:func:`photometric.pipeline.reconstruct`) knows nothing of
them; the command line adds these figures to ``summary.json``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["read_truth", "height_errors"]


def read_truth(folder) -> dict:
    """The ground-truth arrays a synthetic folder holds.

    Parameters
    ----------
    folder : str or Path
        A folder of :mod:`datasets_synthetic` (or any folder: missing files are left out).

    Returns
    -------
    dict
        ``height_gt`` (H, W) and ``xy_gt`` (H, W, 2), mm, for those present.
    """
    root = Path(folder)
    return {name: np.load(root / f"{name}.npy", allow_pickle=False)
            for name in ("height_gt", "xy_gt") if (root / f"{name}.npy").is_file()}


def height_errors(height, valid, truth: dict, *, xy=None, anchored: bool = False) -> dict:
    """Errors of a height map (and its points) against the ground truth.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Reconstructed height, mm (NaN where not valid).
    valid : array_like, shape (H, W), bool
        Pixels to compare (finite heights among them).
    truth : dict
        :func:`read_truth`'s arrays.
    xy : array_like, shape (H, W, 2), optional
        ``x, y`` (mm) of the point each pixel sees (near-field and perspective solves).
    anchored : bool
        The height is absolute (a near-field solve anchors it to the reference plane):
        also report the mean error ``height_bias_mm`` and, with ``xy``, ``xy_rmse_mm``.

    Returns
    -------
    dict
        ``height_rmse_mm`` (RMS of the difference with both means removed) and, when
        ``anchored``, ``height_bias_mm`` and ``xy_rmse_mm``; empty when the truth has no
        ``height_gt`` of the height's shape or no pixel is valid.

    Examples
    --------
    >>> z = np.array([[1.0, 2.0], [3.0, 4.0]])
    >>> height_errors(z + 5.0, np.ones((2, 2), bool), {"height_gt": z}, anchored=True)
    {'height_rmse_mm': 0.0, 'height_bias_mm': 5.0}
    """
    z = np.asarray(height)
    gt = truth.get("height_gt")
    v = np.asarray(valid, bool) & np.isfinite(z)
    if gt is None or np.shape(gt) != z.shape or not v.any():
        return {}
    hv = z[v].astype(np.float64)
    diff = (hv - hv.mean()) - (gt[v] - gt[v].mean())
    out = {"height_rmse_mm": float(np.sqrt(np.mean(diff**2)))}
    if anchored:
        out["height_bias_mm"] = float(np.mean(hv - gt[v]))
        xy_gt = truth.get("xy_gt")
        if xy is not None and xy_gt is not None and np.shape(xy_gt) == z.shape + (2,):
            out["xy_rmse_mm"] = float(np.sqrt(np.mean(np.sum((np.asarray(xy)[v] - xy_gt[v]) ** 2, axis=1))))
    return out
