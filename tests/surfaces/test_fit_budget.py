"""surfaces.fit.fit_height's patch budget (issue 33 item 9): a detailed height keeps to it."""

import numpy as np
import pytest
from scipy import ndimage

from surfaces.fit import fit_height
from surfaces.validate import InputError


def _rough(n=128, seed=0):
    """A height with detail at every scale the fit refines to (smoothed noise), and its slopes."""
    z = ndimage.gaussian_filter(np.random.default_rng(seed).normal(0.0, 1.0, (n, n)), 2.0) * 5.0
    gy, gx = np.gradient(z)
    return z, gx, -gy  # p = dz/dx, q = dz/dy with y up (rows down)


def test_budget_bounds_the_patches_and_says_so():
    z, p, q = _rough()
    free = fit_height(z, p, q, step=16, tolerance=1e-3)
    assert free.patches.n_patches > 2000 and not free.budget_reached and free.max_patches is None
    for budget in (300, 1000):
        fit = fit_height(z, p, q, step=16, tolerance=1e-3, max_patches=budget)
        assert 64 <= fit.patches.n_patches <= budget
        assert fit.budget_reached and fit.max_patches == budget
        assert fit.max_deviation > 1e-3  # the budget, not the tolerance, stopped it
        # the surface still follows the height in the mean better than one patch per level-0 cell
        coarse = fit_height(z, p, q, step=16, tolerance=1e-3, max_patches=64)
        assert coarse.patches.n_patches == 64 and fit.rms_deviation < coarse.rms_deviation


def test_a_budget_that_is_not_reached_changes_nothing():
    z, p, q = _rough(64, seed=3)
    free = fit_height(z, p, q, step=8, tolerance=0.05)
    same = fit_height(z, p, q, step=8, tolerance=0.05, max_patches=free.patches.n_patches + 100)
    assert same.patches.n_patches == free.patches.n_patches and not same.budget_reached
    assert same.max_deviation == free.max_deviation


@pytest.mark.parametrize("bad", [0, -5, 2.5, True])
def test_budget_must_be_a_positive_integer(bad):
    z, p, q = _rough(16)
    with pytest.raises(InputError, match="max_patches"):
        fit_height(z, p, q, max_patches=bad)
