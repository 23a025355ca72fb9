"""Argument checks (surfaces.validate): errors name the argument and say what is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.validate import as_array, drop_closing_repeat, positive


def test_as_array_converts_and_checks():
    arr = as_array([[1, 2, 3]], "points", shape=(None, 3))
    assert arr.dtype == np.float64 and arr.shape == (1, 3)
    same = np.zeros((2, 3))
    assert as_array(same, "points") is same  # no copy when nothing changes
    assert as_array([1, 2], "idx", dtype=np.int64).dtype == np.int64
    assert as_array(np.array([np.nan]), "v", finite=False).shape == (1,)


@pytest.mark.parametrize(
    "value, kwargs, message",
    [
        ([[1, 2]], dict(shape=(None, 3)), r"points: expected shape \(N, 3\), got \(1, 2\)"),
        ([1, 2], dict(ndim=2), "points: expected 2 dimensions"),
        ([1, 2], dict(ndim=(0, 2)), "points: expected 0 or 2 dimensions"),
        ([np.nan, 1.0, np.inf], {}, r"points: contains 2 NaN or infinite"),
        ([1.0], dict(min_size=2), "points: needs at least 2 values"),
        (["a", "b"], {}, "points: cannot be read as a numeric array"),
    ],
)
def test_as_array_errors_name_the_argument(value, kwargs, message):
    with pytest.raises(ValueError, match=message):
        as_array(value, "points", **kwargs)


def test_positive():
    assert positive("2.5", "size") == 2.5
    assert positive(0, "gap", allow_zero=True) == 0.0
    for bad, message in ((0, "size: must be a finite positive"), (-1, "positive"), (np.inf, "finite"),
                         ("x", "size: expected a number")):
        with pytest.raises(ValueError, match=message):
            positive(bad, "size")


def test_drop_closing_repeat():
    ring = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    assert drop_closing_repeat(np.vstack([ring, ring[:1]])).shape == (4, 2)
    assert drop_closing_repeat(ring).shape == (4, 2)
    grid = np.stack([ring, 2 * ring, 3 * ring], axis=1)  # (4, 3, 2): closed along axis 0
    assert drop_closing_repeat(np.concatenate([grid, grid[:1]]), 0).shape == (4, 3, 2)
    cols = np.concatenate([grid, grid[:, :1]], axis=1)
    assert drop_closing_repeat(cols, 1).shape == (4, 3, 2)
    # a nearly equal end within 1e-12 of the scale counts as a repeat; a real point does not
    assert drop_closing_repeat(np.vstack([ring, ring[:1] + 1e-14])).shape == (4, 2)
    assert drop_closing_repeat(np.vstack([ring, ring[:1] + 1e-6])).shape == (5, 2)
    assert drop_closing_repeat(ring[:2]).shape == (2, 2)
