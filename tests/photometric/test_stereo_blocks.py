"""photometric.stereo.solve with ``on_block``: row blocks, the same values as the whole-image solve."""

from __future__ import annotations

import numpy as np
import pytest

from photometric import stereo
from photometric.lights import ring_lights
from photometric.stereo import solve


def _blocks(images, lights, **options):
    parts = []
    res = solve(images, lights, on_block=lambda rows, part: parts.append((rows, part)), **options)
    return res, parts


@pytest.mark.parametrize("n, colour, outliers", [(3, False, False), (3, True, False), (4, False, True),
                                                 (5, True, True), (6, False, False)])
def test_blocks_equal_the_whole_image_solve(monkeypatch, n, colour, outliers):
    monkeypatch.setattr(stereo, "BLOCK_PIXELS", 4096)  # several blocks on a small image
    rng = np.random.default_rng(n)
    shape = (n, 90, 70, 3) if colour else (n, 90, 70)
    images = rng.uniform(0.0, 1.0, shape).astype(np.float32)
    mask = np.zeros((90, 70), bool)
    mask[40:85, 5:60] = True  # the first blocks select no pixel
    L = ring_lights(n, 45.0)
    whole = solve(images, L, mask=mask, outliers=outliers)
    res, parts = _blocks(images, L, mask=mask, outliers=outliers)
    assert len(parts) == 90 // (4096 // 70) + 1
    assert [r.start for r, _ in parts] == sorted(r.start for r, _ in parts)
    assert parts[0][0].start == 0 and parts[-1][0].stop == 90
    assert res.normals is None and res.albedo is None and res.outliers is None
    assert np.array_equal(res.valid, whole.valid)
    # triads: OpenCV passes per pixel, bit for bit; N > 3: the float32 matrix products of a block
    # may round in another order (BLAS kernels depend on the number of columns)
    tol = 0.0 if n == 3 else 1e-6
    close = {"rtol": tol, "atol": tol}
    assert np.allclose(np.concatenate([p.normals for _, p in parts]), whole.normals, **close)
    assert np.allclose(np.concatenate([p.albedo for _, p in parts]), whole.albedo, **close)
    for name in ("residual", "p", "q"):
        assert np.allclose(getattr(res, name), getattr(whole, name), **close), name


def test_blocks_name_the_whole_inputs_bad_values(monkeypatch):
    monkeypatch.setattr(stereo, "BLOCK_PIXELS", 100)
    images = np.full((3, 20, 10), 0.5, np.float32)
    images[0, 2, 3] = np.nan
    images[1, 15, 0] = np.inf
    with pytest.raises(ValueError, match="contains 2 NaN or infinite"):
        solve(images, ring_lights(3, 45.0), on_block=lambda rows, part: None)
