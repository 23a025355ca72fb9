"""Textured plates: the stated RMS height, slopes that are the heights' exact derivatives, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.textures import KINDS, textured_plate
from photometric.integrate import integrate
from surfaces.validate import InputError


@pytest.mark.parametrize("kind", KINDS)
def test_rms_and_exact_slopes(kind):
    hf = textured_plate(kind, size=(96, 128), pixel_size=0.004, sq_um=1.7, seed=2)
    assert hf.height.std() * 1000 == pytest.approx(1.7, rel=1e-12)
    # the spectral (Frankot-Chellappa) integral of the slopes gives the heights back: the slopes are the
    # derivatives of the same trigonometric series, not finite differences
    z = integrate(hf.p, hf.q, "fc", pixel_size=0.004)
    assert np.abs((z - z.mean()) - (hf.height - hf.height.mean())).max() < 1e-6 * np.abs(hf.height).max()
    assert np.allclose(np.linalg.norm(hf.normals, axis=2), 1.0)


def test_tilt_and_anisotropy():
    hf = textured_plate("ground", size=128, pixel_size=0.005, sq_um=1.0, tilt=(0.02, -0.01), seed=0)
    assert hf.p.mean() == pytest.approx(0.02, abs=1e-12) and hf.q.mean() == pytest.approx(-0.01, abs=1e-12)
    flat = textured_plate("ground", size=128, pixel_size=0.005, sq_um=1.0, seed=0)
    # ground: long correlation along x (the grinding direction), short across
    assert np.abs(flat.p).std() < 0.5 * np.abs(flat.q).std()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"kind": "milled"}, "kind"),
        ({"size": 8}, "size"),
        ({"pixel_size": 0.0}, "pixel_size"),
        ({"sq_um": -1.0}, "sq_um"),
        ({"kind": "turned", "feed_mm": 0.0333}, "whole number of feeds"),
    ],
)
def test_bad_input(kwargs, message):
    with pytest.raises(InputError, match=message):
        textured_plate(**{"size": 64, "pixel_size": 0.005, **kwargs})
