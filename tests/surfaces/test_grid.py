"""The pixel-grid convention (surfaces.grid): centred origin, x right, y up, mm."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.grid import GRID_CONVENTION, image_shape, pixel_axes, pixel_grid, xy_to_pixel


@pytest.mark.parametrize("size, pixel", [((4, 6), 0.5), ((5, 3), 2.0), (7, 0.1)])
def test_grid_is_centred_with_y_up(size, pixel):
    h, w = image_shape(size)
    x, y = pixel_grid(size, pixel)
    assert x.shape == y.shape == (h, w)
    # the centre of the image is the origin, and neighbours are one pixel size apart
    assert x.mean() == pytest.approx(0.0, abs=1e-12) and y.mean() == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(np.diff(x, axis=1), pixel) and np.allclose(np.diff(y, axis=0), -pixel)
    # row 0 is the top row (largest y); column 0 the left column (smallest x)
    assert y[0, 0] == pytest.approx((h - 1) / 2 * pixel) and x[0, 0] == pytest.approx(-(w - 1) / 2 * pixel)
    ax, ay = pixel_axes(size, pixel)
    np.testing.assert_array_equal(ax, x[0])
    np.testing.assert_array_equal(ay, y[:, 0])


def test_xy_to_pixel_inverts_pixel_grid():
    size, pixel = (9, 12), 0.25
    x, y = pixel_grid(size, pixel)
    row, col = xy_to_pixel(x, y, size, pixel)
    rows, cols = np.indices(image_shape(size))
    np.testing.assert_allclose(row, rows, atol=1e-12)
    np.testing.assert_allclose(col, cols, atol=1e-12)


def test_image_shape_errors():
    assert image_shape(np.int64(3)) == (3, 3) and image_shape([2.0, 5.0]) == (2, 5)
    for bad in (1, (2, 2.5), (2, 3, 4), "abc", (np.nan, 3)):
        with pytest.raises(ValueError, match="size"):
            image_shape(bad)
    with pytest.raises(ValueError, match="pixel_size"):
        pixel_grid(4, 0.0)


def test_convention_text_matches_the_formula():
    """The stated convention (written into scene.json) is the one the functions follow."""
    assert "x = (col - (W - 1) / 2) * pixel_size" in GRID_CONVENTION
    assert "y = ((H - 1) / 2 - row) * pixel_size" in GRID_CONVENTION
    x, y = pixel_grid((3, 5), 2.0)
    row, col, h, w = 0, 4, 3, 5
    assert x[row, col] == (col - (w - 1) / 2) * 2.0 and y[row, col] == ((h - 1) / 2 - row) * 2.0
