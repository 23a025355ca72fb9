"""Pictures of photometric results: normal maps, albedo, height and error maps with colour bars.

All functions take numpy arrays and return RGB ``uint8`` pictures of shape
``(H, W', 3)`` (``W' > W`` when a colour bar is appended); :func:`surfaces.io.write_png`
saves them atomically. The previews of ``workbench photometric reconstruct``
(``normals.png``, ``albedo.png``, ``height.png``) are :func:`normal_map`,
:func:`albedo_image` and :func:`scalar_image` without a colour bar. Normal maps use the usual encoding
``RGB = 255 * (n + 1) / 2`` with the image convention of the data (DiLiGenT:
x right, y up, z towards the camera), so a surface facing the camera is
(128, 128, 255) light blue.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from surfaces.validate import as_array, InputError, positive

#: width of the colour bar :func:`scalar_image` appends, pixels
COLORBAR_PX = 110


def _mask(mask, shape: tuple[int, int]) -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    m = np.asarray(mask)
    if m.shape != shape:
        raise InputError(f"mask: expected shape {shape}, got {m.shape}")
    return m.astype(bool)


def normal_map(
    normals: np.ndarray, mask: np.ndarray | None = None, background: Sequence[int] = (0, 0, 0)
) -> np.ndarray:
    """Encode unit normals as RGB: ``255 (n + 1) / 2`` per component.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Unit normals (x, y, z in the image convention of the data).
    mask : (H, W) bool, optional
        Pixels to draw; the rest get ``background``.
    background : (3,) int
        RGB of masked-out pixels.

    Returns
    -------
    (H, W, 3) uint8
        The normal map.
    """
    n = as_array(normals, "normals", shape=(None, None, 3), finite=False)
    m = _mask(mask, n.shape[:2]) & np.all(np.isfinite(n), axis=2)
    rgb = np.clip(np.round((np.nan_to_num(n) + 1.0) * 127.5), 0, 255).astype(np.uint8)
    rgb[~m] = np.asarray(background, np.uint8)
    return rgb


def to_uint8(image: np.ndarray, vmax: float | None = None, percentile: float = 99.5) -> np.ndarray:
    """Scale a grey or RGB intensity image to ``uint8`` for display.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) array_like
        Intensities (float in any range, or integers).
    vmax : float, optional
        Intensity shown as white; the ``percentile`` of the finite values when
        omitted (so a few specular pixels do not darken the rest).
    percentile : float
        Percentile used when ``vmax`` is omitted.

    Returns
    -------
    (H, W, 3) uint8
        RGB picture (grey inputs repeated over the channels).
    """
    img = as_array(image, "image", ndim=(2, 3), finite=False)
    if img.ndim == 3 and img.shape[2] != 3:
        raise InputError(f"image: expected (H, W) or (H, W, 3), got {img.shape}")
    if vmax is not None:
        top = float(vmax)
    else:
        finite = img[np.isfinite(img)]
        top = float(np.percentile(finite, percentile)) if finite.size else 1.0
    if top <= 0:
        top = 1.0
    # in place on one float64 array; NaN -> 0 and +-inf -> the ends, as nan_to_num before dividing gave
    out = np.true_divide(img, top, dtype=np.float64)
    np.nan_to_num(out, copy=False, nan=0.0)
    np.clip(out, 0.0, 1.0, out=out)
    out *= 255
    out += 0.5
    out = out.astype(np.uint8)
    return np.repeat(out[..., None], 3, axis=2) if out.ndim == 2 else out


def albedo_image(albedo: np.ndarray, mask: np.ndarray | None = None, percentile: float = 99.5) -> np.ndarray:
    """Albedo as a grey (or colour) picture scaled to its ``percentile``.

    Parameters
    ----------
    albedo : (H, W) or (H, W, 3) array_like
        Recovered albedo ``rho`` (arbitrary units).
    mask : (H, W) bool, optional
        Pixels to draw; the rest are black.
    percentile : float
        Percentile of the masked albedo shown as white.

    Returns
    -------
    (H, W, 3) uint8
    """
    a = as_array(albedo, "albedo", ndim=(2, 3), finite=False)
    m = _mask(mask, a.shape[:2])
    vals = a[m]
    vals = vals[np.isfinite(vals)]
    top = float(np.percentile(vals, positive(percentile, "percentile"))) if vals.size else 1.0
    out = to_uint8(a, vmax=top if top > 0 else 1.0)
    out[~m] = 0
    return out


def scalar_image(
    values: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    label: str = "",
    colorbar: bool = True,
    min_height: int = 256,
    background: Sequence[float] = (1.0, 1.0, 1.0),
    percentile: float | None = None,
) -> np.ndarray:
    """A scalar map through a colour map, with a colour bar on the right.

    Parameters
    ----------
    values : (H, W) array_like
        Scalars (NaN drawn as background).
    mask : (H, W) bool, optional
        Pixels to draw; the rest get ``background``.
    cmap : str
        Matplotlib colour map.
    vmin, vmax : float, optional
        Colour range; the masked finite min/max when omitted.
    percentile : float, optional
        When given, an omitted ``vmin``/``vmax`` is the ``100 - percentile`` /
        ``percentile`` percentile of the masked finite values instead (a few outliers do
        not wash out the map).
    label : str
        Colour-bar title with units.
    colorbar : bool
        Append the colour bar.
    min_height : int
        Small maps are enlarged (nearest neighbour, integer factor) to at least
        this height so that the bar's labels stay legible.
    background : (3,) float
        RGB in [0, 1] for masked-out pixels and the bar strip.

    Returns
    -------
    (H', W', 3) uint8
        The picture; ``H' = k H`` for the enlargement factor ``k``.
    """
    from surfaces.colormap import apply_colormap, colorbar_image, scalar_range

    vals = as_array(values, "values", ndim=2, finite=False)
    m = _mask(mask, vals.shape) & np.isfinite(vals)
    if percentile is not None and m.any():
        pct = positive(percentile, "percentile")
        if vmin is None:
            vmin = float(np.percentile(vals[m], 100.0 - pct))
        if vmax is None:
            vmax = float(np.percentile(vals[m], pct))
    lo, hi = scalar_range(vals[m], vmin, vmax)
    rgb = apply_colormap(np.where(m, vals, np.nan), cmap, lo, hi, nan_color=background)
    out = (rgb * 255 + 0.5).astype(np.uint8)
    k = max(1, int(np.ceil(int(min_height) / vals.shape[0])))
    if k > 1:
        out = np.repeat(np.repeat(out, k, axis=0), k, axis=1)
    if colorbar:
        bar = colorbar_image(out.shape[0], lo, hi, cmap, label, width=COLORBAR_PX, background=background)
        out = np.concatenate([out, bar], axis=1)
    return out


def height_image(
    height: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    label: str = "height mm",
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
) -> np.ndarray:
    """Height field with a colour bar (see :func:`scalar_image`).

    Parameters
    ----------
    height : (H, W) array_like
        Heights (mm, or the units named in ``label``).
    mask : (H, W) bool, optional
        Pixels to draw.
    label, cmap, vmin, vmax
        Colour-bar title and colour map settings.

    Returns
    -------
    (H', W', 3) uint8
    """
    return scalar_image(height, mask, cmap=cmap, vmin=vmin, vmax=vmax, label=label)


def error_image(
    error: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    vmax: float | None = None,
    label: str = "error deg",
    cmap: str = "magma",
) -> np.ndarray:
    """Non-negative error map (angular error, height error) with a colour bar from 0.

    Parameters
    ----------
    error : (H, W) array_like
        Errors (NaN for pixels without a value).
    mask : (H, W) bool, optional
        Pixels to draw.
    vmax : float, optional
        Top of the colour bar; the 99th percentile of the masked errors when
        omitted (so outliers do not wash out the map).
    label, cmap
        Colour-bar title and colour map.

    Returns
    -------
    (H', W', 3) uint8
    """
    err = as_array(error, "error", ndim=2, finite=False)
    m = _mask(mask, err.shape) & np.isfinite(err)
    if vmax is None:
        vmax = float(np.percentile(err[m], 99)) if m.any() else 1.0
    return scalar_image(err, m, cmap=cmap, vmin=0.0, vmax=max(float(vmax), 1e-12), label=label)


def fit(values: np.ndarray, max_side: int) -> np.ndarray:
    """Shrink a map (nearest neighbour: values and NaN kept) or a uint8 picture (area average) to ``max_side``.

    Parameters
    ----------
    values : (H, W[, C]) array
        Map or picture.
    max_side : int
        Largest height and width in pixels (> 0).

    Returns
    -------
    (H', W'[, C]) array
        ``values`` itself when it already fits, else a copy scaled by ``max_side / max(H, W)``.

    Examples
    --------
    >>> fit(np.zeros((512, 256)), 128).shape, fit(np.zeros((100, 50)), 128).shape
    ((128, 64), (100, 50))
    """
    import cv2

    a = np.asarray(values)
    if a.ndim not in (2, 3) or min(a.shape[:2]) == 0:
        raise InputError(f"values: expected (H, W) or (H, W, C), got {a.shape}")
    side = int(positive(max_side, "max_side"))
    scale = side / max(a.shape[:2])
    if scale >= 1:
        return a
    size = (max(1, round(a.shape[1] * scale)), max(1, round(a.shape[0] * scale)))
    work = a.astype(np.float32) if a.dtype == np.float64 or a.dtype == bool else a
    # a uint8 picture is averaged over each output pixel's area; maps keep their own values (and NaN)
    out = cv2.resize(work, size, interpolation=cv2.INTER_AREA if a.dtype == np.uint8 else cv2.INTER_NEAREST)
    return out.astype(a.dtype) if out.dtype != a.dtype else out


def enlarge(image: np.ndarray, min_height: int = 256) -> np.ndarray:
    """Enlarge a small picture by an integer factor (nearest neighbour) to at least ``min_height``.

    Parameters
    ----------
    image : (H, W[, 3]) array
        Picture.
    min_height : int
        Required height in pixels; pictures at least this tall are returned as they are.

    Returns
    -------
    (k H, k W[, 3]) array
        With ``k = ceil(min_height / H)`` (1 when ``H >= min_height``).
    """
    img = np.asarray(image)
    if img.ndim not in (2, 3) or img.shape[0] == 0:
        raise InputError(f"image: expected (H, W) or (H, W, 3), got {img.shape}")
    k = max(1, int(np.ceil(int(min_height) / img.shape[0])))
    return img if k == 1 else np.repeat(np.repeat(img, k, axis=0), k, axis=1)


def label_image(image: np.ndarray, text: str, scale: float = 0.5) -> np.ndarray:
    """Copy of an RGB picture with ``text`` on a light band at its top left.

    Parameters
    ----------
    image : (H, W, 3) uint8
        Picture.
    text : str
        Caption.
    scale : float
        OpenCV font scale.

    Returns
    -------
    (H, W, 3) uint8
    """
    import cv2

    img = np.array(image, dtype=np.uint8, order="C", copy=True)
    if img.ndim != 3 or img.shape[2] != 3:
        raise InputError(f"image: expected (H, W, 3) uint8, got {img.shape}")
    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    img[: th + base + 6, : tw + 8] = (255 + img[: th + base + 6, : tw + 8].astype(int)) // 2
    cv2.putText(img, text, (4, th + 3), cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 1, cv2.LINE_AA)
    return img


def montage(
    images: Sequence[np.ndarray],
    cols: int | None = None,
    labels: Sequence[str] | None = None,
    pad: int = 4,
    background: int = 255,
) -> np.ndarray:
    """Tile pictures into a grid (row-major), each cell the size of the largest picture.

    Parameters
    ----------
    images : sequence of (H_i, W_i, 3) uint8
        Pictures (grey (H, W) ones are repeated over RGB).
    cols : int, optional
        Columns; ``ceil(sqrt(n))`` when omitted.
    labels : sequence of str, optional
        One caption per picture (see :func:`label_image`).
    pad : int
        Gap in pixels between cells.
    background : int
        Grey level of the gaps.

    Returns
    -------
    (rows * (H + pad) - pad, cols * (W + pad) - pad, 3) uint8
    """
    if len(images) == 0:
        raise InputError("images: give at least one picture")
    if labels is not None and len(labels) != len(images):
        raise InputError(f"labels: expected {len(images)} captions, got {len(labels)}")
    pics = []
    for k, im in enumerate(images):
        a = np.asarray(im)
        if a.dtype != np.uint8 or a.ndim not in (2, 3):
            raise InputError(f"images[{k}]: expected a uint8 (H, W[, 3]) picture, got {a.dtype} {a.shape}")
        pics.append(np.repeat(a[..., None], 3, axis=2) if a.ndim == 2 else a)
    n = len(pics)
    cols = int(cols) if cols else int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    h = max(p.shape[0] for p in pics)
    w = max(p.shape[1] for p in pics)
    out = np.full((rows * (h + pad) - pad, cols * (w + pad) - pad, 3), background, np.uint8)
    for k, pic in enumerate(pics):
        if labels is not None:
            pic = label_image(pic, labels[k])
        r, c = divmod(k, cols)
        y, x = r * (h + pad), c * (w + pad)
        out[y : y + pic.shape[0], x : x + pic.shape[1]] = pic
    return out


def plot_map(
    values: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    *,
    xlabel: str,
    ylabel: str,
    title: str = "",
    label: str = "",
    cmap: str = "magma",
    vmin: float | None = None,
    vmax: float | None = None,
    contours: Sequence[float] = (),
    size: tuple[int, int] = (480, 400),
) -> np.ndarray:
    """A scalar map over two parameters with labelled axes and a colour bar (matplotlib, Agg).

    Parameters
    ----------
    values : (Ny, Nx) array_like
        Map values; ``values[i, j]`` belongs to ``(x[j], y[i])``.
    x, y : (Nx,), (Ny,) array_like
        Axis coordinates (increasing).
    xlabel, ylabel, title, label : str
        Axis titles, picture title and colour-bar title (units included).
    cmap, vmin, vmax
        Colour map and range (finite min/max when omitted).
    contours : sequence of float
        Levels drawn as labelled contour lines (e.g. tolerances).
    size : (width, height)
        Picture size in pixels.

    Returns
    -------
    (height, width, 3) uint8
        The rendered plot.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from surfaces.colormap import scalar_range

    v = as_array(values, "values", ndim=2, finite=False)
    xs = as_array(x, "x", shape=(v.shape[1],))
    ys = as_array(y, "y", shape=(v.shape[0],))
    lo, hi = scalar_range(v, vmin, vmax)
    w, h = int(size[0]), int(size[1])
    fig = Figure(figsize=(w / 100, h / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    mesh = ax.pcolormesh(xs, ys, v, cmap=cmap, vmin=lo, vmax=hi, shading="nearest")
    bar = fig.colorbar(mesh, ax=ax)
    bar.set_label(label)
    levels = sorted(c for c in contours if lo < c < hi)
    if levels:
        cs = ax.contour(xs, ys, v, levels=levels, colors="white", linewidths=0.9)
        ax.clabel(cs, fmt="%g", fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    canvas.draw()
    rgb = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return rgb
