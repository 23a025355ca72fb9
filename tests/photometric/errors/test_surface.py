"""photometric.errors.surface: a given height field's slopes through the error model."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import deviate_lights
from tests.photometric.errors._lights import TRIAD45


def test_surface_derivatives_convention():
    # z = 0.3 x + 0.2 y with x along columns and y UP (row 0 is the top row)
    ps = 0.05
    rows, cols = np.mgrid[0:6, 0:7]
    x, y = cols * ps, (5 - rows) * ps
    p, q = E.surface_derivatives(0.3 * x + 0.2 * y, ps)
    np.testing.assert_allclose(p, 0.3, atol=1e-12)
    np.testing.assert_allclose(q, 0.2, atol=1e-12)
    with pytest.raises(ValueError, match="height"):
        E.surface_derivatives(np.zeros((1, 5)))


def test_height_error_of_a_plane_is_a_plane():
    ps = 0.1
    rows, cols = np.mgrid[0:32, 0:40]
    h = 0.2 * cols * ps - 0.1 * (31 - rows) * ps
    dev = np.zeros((3, 2))
    res = E.height_error(TRIAD45, TRIAD45, h, ps)
    assert res["max_abs_dh_mm"] < 1e-9 and res["max_abs_dp"] < 1e-12
    dev[0, 0] = 2.0
    res = E.height_error(TRIAD45, deviate_lights(TRIAD45, dev), h, ps)
    # a plane maps to a plane: the height error is the plane of the slope errors
    ex = E.exact_error(TRIAD45, deviate_lights(TRIAD45, dev), 0.2, -0.1)
    expect = ex.dp * cols * ps + ex.dq * (31 - rows) * ps
    expect = expect - expect.mean()
    np.testing.assert_allclose(res["dh"], expect, atol=1e-6)


def test_height_error_mask_and_shapes():
    h = np.zeros((8, 9))
    with pytest.raises(ValueError, match="mask"):
        E.height_error(TRIAD45, TRIAD45, h, 0.1, mask=np.zeros((8, 9), bool))
    with pytest.raises(ValueError, match="lights_true"):
        E.height_error(TRIAD45, np.stack([TRIAD45, TRIAD45]), h, 0.1)
