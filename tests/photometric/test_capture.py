"""Capture realities: Bayer mosaics, dark frames, dark or low-bit captures."""

import cv2
import numpy as np
import pytest

from photometric.io import BAYER_PATTERNS, exposure_note, read_ambient, read_images, subtract_ambient
from surfaces.validate import InputError

COLOUR = np.array([180, 90, 30], np.uint16) * 200  # RGB, 16 bit


def _mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """Each sensor site keeps the channel its filter passes (the pattern's top-left 2 x 2 cell, row by row)."""
    index = {"R": 0, "G": 1, "B": 2}
    out = np.empty(rgb.shape[:2], rgb.dtype)
    for k, letter in enumerate(pattern):
        r, c = divmod(k, 2)
        out[r::2, c::2] = rgb[r::2, c::2, index[letter]]
    return out


@pytest.mark.parametrize("pattern", BAYER_PATTERNS)
def test_bayer_mosaic_comes_back_in_its_colours(tmp_path, pattern):
    rgb = np.broadcast_to(COLOUR, (16, 20, 3)).copy()
    rgb[:, 10:] = COLOUR[::-1]  # a second colour on the right half
    path = tmp_path / f"raw_{pattern}.png"
    cv2.imwrite(str(path), _mosaic(rgb, pattern))
    img = read_images([path], bayer=pattern)[0]
    assert img.shape == (16, 20, 3)
    assert np.allclose(img[4:12, 2:7], COLOUR / 65535, atol=1e-6)
    assert np.allclose(img[4:12, 13:18], COLOUR[::-1] / 65535, atol=1e-6)
    wrong = next(p for p in BAYER_PATTERNS if p[0] != pattern[0])
    assert not np.allclose(read_images([path], bayer=wrong)[0][4:12, 2:7], COLOUR / 65535, atol=0.05)


def test_bayer_errors(tmp_path):
    path = tmp_path / "rgb.png"
    cv2.imwrite(str(path), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(InputError, match="one channel"):
        read_images([path], bayer="RGGB")
    with pytest.raises(InputError, match="bayer"):
        read_images([path], bayer="RGBG")


def test_ambient_one_frame_or_one_per_image(tmp_path):
    imgs = np.stack([np.full((4, 5, 3), v, np.float32) for v in (0.2, 0.5, 0.8)])
    dark = np.full((4, 5, 3), 0.3, np.float32)
    out = subtract_ambient(imgs.copy(), dark)
    assert np.allclose(out[:, 0, 0, 0], [0.0, 0.2, 0.5])  # clipped at 0
    per = np.stack([np.full((4, 5), v, np.float32) for v in (0.1, 0.2, 0.3)])  # grey, per image
    assert np.allclose(subtract_ambient(imgs.copy(), per)[:, 0, 0, 1], [0.1, 0.3, 0.5])
    with pytest.raises(InputError, match="ambient: shape"):
        subtract_ambient(imgs.copy(), np.zeros((4, 6)))
    # from files: one 8-bit frame for every image
    cv2.imwrite(str(tmp_path / "dark.png"), np.full((4, 5), 51, np.uint8))
    assert np.allclose(read_ambient(tmp_path / "dark.png", imgs.copy())[:, 0, 0, 2], [0.0, 0.3, 0.6], atol=1e-6)
    with pytest.raises(InputError, match="2 dark frames for 3 images"):
        read_ambient([tmp_path / "dark.png"] * 2, imgs.copy())


def test_dark_capture_warns():
    rng = np.random.default_rng(0)
    dark8 = np.round(rng.uniform(10, 118, (8, 30, 40))) / 255  # peaks of about 118 DN of 255
    note = exposure_note(dark8.astype(np.float32), bits=8)
    assert note is not None and "of 255 DN" in note and "dark capture" in note
    assert exposure_note(np.clip(dark8 * 2.2, 0, 1).astype(np.float32)) is None
    assert exposure_note(dark8.astype(np.float32), full_scale=None) is None  # float input: no full scale
    # a 16-bit capture peaking at 14 % of full scale still uses ~9,000 grey levels: no warning
    dark16 = np.round(rng.uniform(100, 9100, (8, 30, 40))) / 65535
    assert exposure_note(dark16.astype(np.float32)) is None
    assert exposure_note((dark16 / 100).astype(np.float32)) is not None  # ~91 of 65535 levels: dark


def test_read_subtracts_an_array_ambient_without_touching_the_input():
    from photometric import stages

    images = np.full((3, 6, 6), 0.5, np.float32)
    lights = np.array([[0.5, 0.0, 0.866], [-0.25, 0.433, 0.866], [-0.25, -0.433, 0.866]])
    inp = stages.read(images, lights=lights, ambient=np.full((6, 6), 0.2, np.float32))
    assert np.allclose(inp.data.images, 0.3) and np.all(images == 0.5)
    assert inp.info["ambient"] == "array"
