"""``volume`` on a closed surface oriented inward: the sign is kept and a warning says so (issue 37)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from surfaces.coons import from_grid
from surfaces.measure import InwardOrientationWarning, area_and_volume, encloses, integrals, volume

SPHERE = 4.0 / 3.0 * np.pi * 8.0  # radius 2: 33.51


def _sphere(around_first: bool):
    """A radius-2 sphere grid, the angle around first (closed in u, poles on the v ends) or second."""
    a, p = np.meshgrid(np.linspace(0, 2 * np.pi, 32, endpoint=False), np.linspace(0, np.pi, 17), indexing="ij")
    g = 2 * np.stack([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)], -1)
    return from_grid(g, closed_u=True) if around_first else from_grid(g.transpose(1, 0, 2), closed_v=True)


def test_inward_sphere_warns_and_keeps_its_sign():
    inward = _sphere(around_first=True)
    with pytest.warns(InwardOrientationWarning, match=r"signed volume is -33\.5.*orient it: 33\.5"):
        v = volume(inward)
    assert v == pytest.approx(-SPHERE, rel=1e-3)
    with pytest.warns(InwardOrientationWarning):
        v2, _ = integrals(inward)
    assert v2 == pytest.approx(v)


def test_outward_and_open_and_per_patch_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert volume(_sphere(around_first=False)) == pytest.approx(SPHERE, rel=1e-3)
        assert volume(_sphere(around_first=True).flipped()) == pytest.approx(SPHERE, rel=1e-3)
        per = volume(_sphere(around_first=True), per_patch=True)
        assert per.sum() == pytest.approx(-SPHERE, rel=1e-3)
        out = area_and_volume(_sphere(around_first=True))
    assert out["orientation"] == "inward" and out["volume"] == pytest.approx(SPHERE, rel=1e-3)


def test_encloses():
    closed = _sphere(around_first=True)
    assert encloses(closed) and encloses(_sphere(around_first=False))
    band = from_grid(np.asarray(closed.control[:, 2:-2, 0, 0]), closed_u=True)  # no poles: a tube
    assert not encloses(band)
