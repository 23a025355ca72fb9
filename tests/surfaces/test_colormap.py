"""Colour maps and colour bars (surfaces.colormap)."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.colormap import apply_colormap, colorbar_image, scalar_range, vertex_values


def test_colormap_and_colorbar_ends():
    """The colour map reaches matplotlib's end colours; the bar runs top=vmax to bottom=vmin."""
    import matplotlib

    rgb = apply_colormap(np.array([0.0, 5.0, 10.0, np.nan]), "viridis", 0.0, 10.0)
    cm = matplotlib.colormaps["viridis"]
    assert np.allclose(rgb[0], cm(0.0)[:3], atol=1e-6) and np.allclose(rgb[2], cm(1.0)[:3], atol=1e-6)
    assert np.allclose(rgb[3], 0.6)
    bar = colorbar_image(300, -1.0, 2.0, "viridis", "mm")
    column = bar[:, 15].astype(float) / 255
    inside = np.nonzero(np.abs(column - np.asarray(cm(1.0)[:3])).sum(axis=1) < 0.03)[0]
    bottom = np.nonzero(np.abs(column - np.asarray(cm(0.0)[:3])).sum(axis=1) < 0.03)[0]
    assert inside.size and bottom.size and inside.mean() < bottom.mean()


def test_scalar_range_ignores_nan_and_never_collapses():
    assert scalar_range(np.array([2.0, np.nan, -1.0])) == (-1.0, 2.0)
    assert scalar_range(np.array([0.0, 1.0]), vmin=-5.0) == (-5.0, 1.0)
    lo, hi = scalar_range(np.array([3.0, 3.0]))
    assert lo < 3.0 < hi and hi - lo == pytest.approx(6e-6)
    assert scalar_range(np.array([np.nan])) == (0.0, 1.0)


def test_apply_colormap_clips_outside_the_range():
    rgb = apply_colormap(np.array([-10.0, 0.0, 1.0, 10.0]), "gray", 0.0, 1.0)
    assert rgb.dtype == np.float32 and rgb.shape == (4, 3)
    assert np.allclose(rgb[0], 0.0) and np.allclose(rgb[1], 0.0) and np.allclose(rgb[2:], 1.0)
    with pytest.raises(ValueError, match="cmap"):
        apply_colormap(np.zeros(2), "no-such-map")


def test_vertex_values_checks_shapes():
    colors, scalars = vertex_values(3, colors=np.zeros((3, 3)))
    assert colors.shape == (3, 3) and scalars is None
    with pytest.raises(ValueError, match="not both"):
        vertex_values(3, np.zeros((3, 3)), np.zeros(3))
    with pytest.raises(ValueError, match="scalars"):
        vertex_values(3, scalars=np.zeros(4))


@pytest.mark.parametrize("height", [256, 384, 900])
def test_colorbar_tick_labels_are_at_least_11_px_high(height):
    """Tick digits drawn at least 11 px high on every bar of 120 px and more (7 px before, issue 37)."""
    bar = colorbar_image(height, -0.04, 0.04, "coolwarm", "")
    ink = bar[:, 40:].min(axis=2) < 128  # right of the bar and its tick marks: the labels only
    rows = np.flatnonzero(ink.any(axis=1))
    runs = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    assert len(runs) >= 3
    # the digit '0' and the minus sign's row: the tallest run of a label
    assert max(len(r) for r in runs) >= 11
