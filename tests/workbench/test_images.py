"""Image helpers (workbench.images): encodings, colour bars, error maps."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces.io import write_png
from workbench import images


@pytest.mark.parametrize(
    "normal,rgb",
    [((0, 0, 1), (128, 128, 255)), ((1, 0, 0), (255, 128, 128)), ((0, -1, 0), (128, 0, 128)),
     ((0, 0.6, 0.8), (128, 204, 230))],
)
def test_normal_map_encoding(normal, rgb):
    """RGB = round(255 (n + 1) / 2); masked pixels get the background."""
    n = np.broadcast_to(np.asarray(normal, float), (4, 5, 3))
    mask = np.ones((4, 5), bool)
    mask[0, 0] = False
    out = images.normal_map(n, mask, background=(7, 7, 7))
    assert out.dtype == np.uint8 and out.shape == (4, 5, 3)
    assert tuple(out[2, 2]) == rgb
    assert tuple(out[0, 0]) == (7, 7, 7)


def test_normal_map_nan_is_background():
    n = np.zeros((3, 3, 3))
    n[..., 2] = 1
    n[1, 1] = np.nan
    assert tuple(images.normal_map(n)[1, 1]) == (0, 0, 0)


def test_albedo_scaled_to_percentile():
    a = np.linspace(0, 2, 100).reshape(10, 10)
    out = images.albedo_image(a, percentile=50)
    assert out.shape == (10, 10, 3) and out[-1, -1, 0] == 255 and out[0, 0, 0] == 0
    assert np.all(out[..., 0] == out[..., 1])


@pytest.mark.parametrize("shape", [(40, 60), (300, 200)])
def test_height_image_has_bar_and_range(shape):
    """The map spans the colour map ends; a colour bar strip is appended; small maps enlarge."""
    import matplotlib

    h = np.add.outer(np.arange(shape[0]), np.arange(shape[1])).astype(float)
    out = images.height_image(h, label="mm")
    k = max(1, int(np.ceil(256 / shape[0])))
    assert out.shape[0] == shape[0] * k and out.shape[1] == shape[1] * k + 110
    cm = matplotlib.colormaps["viridis"]
    assert np.allclose(out[0, 0] / 255, cm(0.0)[:3], atol=0.01)
    assert np.allclose(out[shape[0] * k - 1, shape[1] * k - 1] / 255, cm(1.0)[:3], atol=0.01)
    bar = out[:, shape[1] * k :]
    assert len(np.unique(bar.reshape(-1, 3), axis=0)) > 40


def test_error_image_clips_at_vmax_and_masks():
    err = np.linspace(0, 10, 300 * 300).reshape(300, 300)
    mask = np.ones_like(err, bool)
    mask[:10] = False
    out = images.error_image(err, mask, vmax=5.0)
    import matplotlib

    top = matplotlib.colormaps["magma"](1.0)[:3]
    assert np.allclose(out[-1, 299] / 255, top, atol=0.01)
    assert np.all(out[0, 0] == 255)
    # default vmax: the 99th percentile of the masked errors
    auto = images.error_image(err, mask)
    assert auto.shape == out.shape


def test_scalar_image_percentile_range_without_bar():
    """The preview of height.png: range from the masked percentiles, black outside, no bar."""
    import matplotlib

    v = np.linspace(0.0, 1.0, 40 * 50).reshape(40, 50)
    v[0, 0] = 100.0  # one outlier does not wash out the map
    mask = np.ones(v.shape, bool)
    mask[-1, -1] = False
    out = images.scalar_image(v, mask, percentile=99.0, colorbar=False, min_height=1, background=(0, 0, 0))
    assert out.shape == (40, 50, 3)
    assert tuple(out[-1, -1]) == (0, 0, 0)
    cm = matplotlib.colormaps["viridis"]
    lo, hi = np.percentile(v[mask], [1.0, 99.0])
    assert np.allclose(out[0, 0] / 255, cm(1.0)[:3], atol=0.01)  # the outlier clips to the top
    assert np.allclose(out[20, 25] / 255, cm((v[20, 25] - lo) / (hi - lo))[:3], atol=0.01)
    plain = images.scalar_image(v, mask, colorbar=False, min_height=1)
    assert np.allclose(plain[20, 25] / 255, cm(v[20, 25] / 100.0)[:3], atol=0.01)  # min/max range


def test_montage_layout_and_labels():
    tiles = [np.full((10, 20, 3), v, np.uint8) for v in (0, 100, 200)]
    out = images.montage(tiles, cols=2, pad=2)
    assert out.shape == (22, 42, 3)
    assert out[0, 0, 0] == 0 and out[0, 22, 0] == 100 and out[12, 0, 0] == 200 and out[12, 22, 0] == 255
    labelled = images.montage([np.full((40, 120, 3), 0, np.uint8)], labels=["abc"])
    assert labelled.max() > 0
    with pytest.raises(ValueError, match="labels"):
        images.montage(tiles, labels=["a"])
    with pytest.raises(ValueError, match="images"):
        images.montage([np.zeros((3, 3), float)])


def test_to_uint8_and_write(tmp_path):
    import cv2

    img = np.random.default_rng(0).random((16, 16)).astype(np.float32)
    out = images.to_uint8(img, vmax=1.0)
    assert out.shape == (16, 16, 3) and abs(int(out[3, 3, 0]) - round(255 * img[3, 3])) <= 1
    path = write_png(tmp_path / "x.png", out)
    assert np.array_equal(cv2.imread(str(path))[..., ::-1], out)


@pytest.mark.parametrize(
    "call,match",
    [
        (lambda: images.normal_map(np.zeros((3, 3))), "normals"),
        (lambda: images.height_image(np.zeros((3, 3)), np.ones((2, 2), bool)), "mask"),
        (lambda: images.to_uint8(np.zeros((3, 3, 2))), "image"),
        (lambda: images.height_image(np.zeros((3, 3)), cmap="nope"), "cmap"),
    ],
)
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("shape,k", [((10, 7, 3), 26), ((300, 20), 1), ((128, 5), 2)])
def test_enlarge_integer_factor(shape, k):
    img = (np.arange(np.prod(shape)) % 251).astype(np.uint8).reshape(shape)
    out = images.enlarge(img, 256)
    assert out.shape[:2] == (shape[0] * k, shape[1] * k)
    assert np.array_equal(out[::k, ::k], img)


def test_fit_keeps_nan_dtype_and_small_inputs():
    from workbench.images import fit

    values = np.arange(512 * 256, dtype=np.float64).reshape(512, 256)
    values[:64] = np.nan
    out = fit(values, 128)
    assert out.shape == (128, 64) and out.dtype == np.float64
    assert np.isnan(out[:16]).all() and np.isfinite(out[16:]).all()
    assert fit(values > 10, 128).dtype == bool
    small = np.ones((40, 30, 3), np.uint8)
    assert fit(small, 128) is small
