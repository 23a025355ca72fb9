"""Defaults for real captures: the outlier mode on from 6 images (issue 33), off with fewer or when asked."""

import numpy as np
import pytest

from photometric.options import OUTLIER_MIN_IMAGES, PhotometricOptions
from photometric.pipeline import reconstruct


def _images(n: int):
    """A hemisphere under ``n`` distant lights (Lambertian, attached shadows): closed form."""
    size = 48
    y, x = np.mgrid[-1:1:size * 1j, -1:1:size * 1j]
    r2 = x**2 + y**2
    inside = r2 < 0.8
    nz = np.sqrt(np.clip(1 - r2, 0, None))
    normals = np.stack([x, -y, nz], axis=-1) * inside[..., None] + np.array([0, 0, 1.0]) * ~inside[..., None]
    az = np.linspace(0, 2 * np.pi, n, endpoint=False)
    lights = np.stack([0.6 * np.cos(az), 0.6 * np.sin(az), np.full(n, 0.8)], axis=1)
    images = np.clip(normals @ lights.T, 0, None).transpose(2, 0, 1).astype(np.float32) * 0.7
    return images, lights


@pytest.mark.parametrize("n", [OUTLIER_MIN_IMAGES - 1, OUTLIER_MIN_IMAGES])
def test_outliers_follow_the_image_count(n):
    images, lights = _images(n)
    assert reconstruct(images, lights=lights).summary["outliers"] is (n >= 6)
    assert reconstruct(images, lights=lights, outliers=False).summary["outliers"] is False
    assert reconstruct(images, lights=lights, outliers=True).summary["outliers"] is True


def test_resolved_keeps_what_was_given():
    opts = PhotometricOptions(outliers=False, integrator="robust")
    assert opts.resolved(n_images=20, masked=True) == opts
    auto = PhotometricOptions(integrator="auto")
    assert auto.resolved(n_images=3, masked=False).integrator == "dct"
    assert auto.resolved(n_images=3, masked=True).integrator == "lsq"
    assert PhotometricOptions().outliers is None and PhotometricOptions().integrator == "dct"


def test_diligent_bear_default_is_the_outlier_figure(shared_data):
    """14 images: the default now gives the --outliers figure (7.736 deg; plain least squares 9.600)."""
    res = reconstruct(shared_data / "diligent_bear", surface="coons")
    assert res.summary["outliers"] is True
    assert res.summary["mean_angular_error_deg"] == pytest.approx(7.736, abs=0.0015)
