"""Colour maps for scalars on surfaces and images, and the colour bar drawn beside them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from surfaces.validate import as_array, InputError, positive

__all__ = ["apply_colormap", "scalar_range", "colorbar_image"]


def apply_colormap(
    values: np.ndarray,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    nan_color: Sequence[float] = (0.6, 0.6, 0.6),
) -> np.ndarray:
    """Map scalars to RGB through a matplotlib colour map.

    Parameters
    ----------
    values : array_like, any shape
        Scalars; NaN allowed (drawn in ``nan_color``).
    cmap : str
        Matplotlib colour-map name.
    vmin, vmax : float, optional
        Value range mapped to the ends of the colour map; the finite minimum
        and maximum of ``values`` when omitted.

    Returns
    -------
    (..., 3) float32
        RGB in [0, 1], same leading shape as ``values``.
    """
    import matplotlib

    vals = as_array(values, "values", finite=False)
    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError:
        raise InputError(f"cmap: unknown matplotlib colour map {cmap!r}") from None
    lo, hi = scalar_range(vals, vmin, vmax)
    finite = np.isfinite(vals)
    t = np.clip((np.where(finite, vals, lo) - lo) / (hi - lo), 0.0, 1.0)
    rgb = colormap(t)[..., :3].astype(np.float32)
    rgb[~finite] = np.asarray(nan_color, np.float32)
    return rgb


def scalar_range(values: np.ndarray, vmin: float | None = None, vmax: float | None = None) -> tuple[float, float]:
    """Value range for a colour map: given ends, else the finite min/max (never empty).

    Parameters
    ----------
    values : array_like
        Scalars (NaN ignored).
    vmin, vmax : float, optional
        Explicit ends.

    Returns
    -------
    (float, float)
        ``lo < hi``.
    """
    vals = np.asarray(values, float)
    finite = vals[np.isfinite(vals)]
    lo = float(vmin) if vmin is not None else (float(finite.min()) if finite.size else 0.0)
    hi = float(vmax) if vmax is not None else (float(finite.max()) if finite.size else 1.0)
    if not hi > lo:
        pad = max(abs(lo), 1.0) * 1e-6
        lo, hi = lo - pad, hi + pad
    return lo, hi


def colorbar_image(
    height: int,
    vmin: float,
    vmax: float,
    cmap: str = "viridis",
    label: str = "",
    width: int = 120,
    background: Sequence[float] = (1.0, 1.0, 1.0),
) -> np.ndarray:
    """A vertical colour bar with tick labels, to place beside a picture.

    Parameters
    ----------
    height : int
        Picture height in pixels.
    vmin, vmax : float
        Values at the bottom and the top of the bar.
    cmap : str
        Matplotlib colour-map name.
    label : str
        Short title written above the bar (units included, e.g. ``"mm"``).
    width : int
        Strip width in pixels.
    background : (3,) float
        RGB background in [0, 1].

    Returns
    -------
    (height, width, 3) uint8
        RGB strip.
    """
    import cv2

    height = int(positive(height, "height"))
    width = int(positive(width, "width"))
    strip = np.empty((height, width, 3), np.uint8)
    strip[:] = (np.asarray(background) * 255).astype(np.uint8)
    top, bottom = min(40, height // 6), max(height - min(14, height // 10), 2)
    bar_h = max(bottom - top, 2)
    values = np.linspace(vmax, vmin, bar_h)
    bar_w = max(min(22, width // 4), 4)
    x0 = 8
    colors = apply_colormap(values, cmap, vmin, vmax)
    strip[top : top + bar_h, x0 : x0 + bar_w] = (colors[:, None, :] * 255).astype(np.uint8)
    ink = (30, 30, 30)
    cv2.rectangle(strip, (x0, top), (x0 + bar_w - 1, top + bar_h - 1), ink, 1)
    # OpenCV's simplex font at 0.5 draws digits 11 px high: legible where a report shows the
    # picture at its own size (0.3 on short bars gave 7 px, issue 37)
    scale = 0.5 if height >= 120 else 0.4
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(6 if bar_h > 150 else 3).tick_values(vmin, vmax)
    span = vmax - vmin
    for value in ticks[(ticks >= vmin - 1e-9 * span) & (ticks <= vmax + 1e-9 * span)]:
        frac = (vmax - value) / span
        y = int(round(top + frac * (bar_h - 1)))
        cv2.line(strip, (x0 + bar_w, y), (x0 + bar_w + 4, y), ink, 1, cv2.LINE_AA)
        value = 0.0 if abs(value) < 1e-9 * span else value
        cv2.putText(strip, f"{value:.3g}", (x0 + bar_w + 7, y + 4), cv2.FONT_HERSHEY_SIMPLEX,
                    scale, ink, 1, cv2.LINE_AA)
    if label:
        cv2.putText(strip, label[:16], (4, max(top - 10, 10)), cv2.FONT_HERSHEY_SIMPLEX, scale, ink,
                    1, cv2.LINE_AA)
    return strip


def vertex_values(n_vertices: int, colors=None, scalars=None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Validated per-vertex colours or per-vertex scalars (at most one of them).

    Parameters
    ----------
    n_vertices : int
        Number of vertices ``V``.
    colors : (V, 3) array_like, optional
        RGB per vertex.
    scalars : (V,) array_like, optional
        One value per vertex (NaN allowed), to be mapped through a colour map.

    Returns
    -------
    colors : (V, 3) float64 or None
    scalars : (V,) float64 or None

    Raises
    ------
    ValueError
        Both given, or a wrong shape (naming the argument).

    Examples
    --------
    >>> vertex_values(2, scalars=[0.0, 1.0])[1].tolist()
    [0.0, 1.0]
    """
    if colors is not None and scalars is not None:
        raise InputError("colors, scalars: give per-vertex colours or scalars, not both")
    if colors is not None:
        colors = as_array(colors, "colors", shape=(n_vertices, 3))
    if scalars is not None:
        scalars = as_array(scalars, "scalars", shape=(n_vertices,), finite=False)
    return colors, scalars
