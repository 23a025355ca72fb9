"""photometric.io: images, masks and DiLiGenT / RobustPhotometricStereo folders."""

import cv2
import numpy as np
import pytest

from photometric.io import read_folder, read_image, read_images, read_mask
from photometric.lights import ring_lights


def test_read_image_keeps_16_bits_and_rgb_order(tmp_path):
    img = np.zeros((4, 5, 3), np.uint16)
    img[..., 0] = 1000  # red
    img[..., 2] = 65535  # blue
    cv2.imwrite(str(tmp_path / "a.png"), img[..., ::-1])
    back = read_image(tmp_path / "a.png")
    assert back.dtype == np.float32
    assert np.allclose(back[0, 0], [1000 / 65535, 0, 1.0])


def test_read_images_and_mask_check_shapes(tmp_path):
    np.save(tmp_path / "a.npy", np.zeros((4, 5), np.float32))
    np.save(tmp_path / "b.npy", np.zeros((4, 6), np.float32))
    with pytest.raises(ValueError, match="b.npy"):
        read_images([tmp_path / "a.npy", tmp_path / "b.npy"])
    cv2.imwrite(str(tmp_path / "m.png"), np.array([[0, 255, 3]], np.uint8))
    assert read_mask(tmp_path / "m.png").tolist() == [[False, True, True]]
    with pytest.raises(ValueError, match="mask"):
        read_mask(tmp_path / "m.png", (2, 3))
    with pytest.raises(FileNotFoundError, match="image"):
        read_image(tmp_path / "missing.png")


def test_robust_ps_layout(tmp_path):
    """lights.npy row NNN belongs to imageNNN.npy; the rows are validated once, as unit lights."""
    lights = ring_lights(5, 40.0)
    np.save(tmp_path / "lights.npy", 2.0 * lights)  # not unit: normalised with a warning
    for k in (1, 3, 4):
        np.save(tmp_path / f"image{k:03d}.npy", np.full((3, 4), k / 10, np.float32))
    with pytest.warns(UserWarning, match="not unit"):
        data = read_folder(tmp_path)
    assert data.names == ("image001.npy", "image003.npy", "image004.npy")
    np.testing.assert_allclose(data.lights, lights[[1, 3, 4]], atol=1e-12)
    np.testing.assert_allclose(data.images[:, 0, 0], [0.1, 0.3, 0.4], atol=1e-7)
    assert data.mask.all() and data.normal_gt is None


def test_read_folder_select_and_bear(shared_data):
    data = read_folder(shared_data / "diligent_bear", select=["048.png", "033.png", "091.png"])
    assert data.names == ("048.png", "033.png", "091.png")
    assert data.intensities.shape == (3, 3) and data.mask.dtype == bool
    assert data.images.max() <= 1.0 and data.images.dtype == np.float32
    with pytest.raises(ValueError, match="select"):
        read_folder(shared_data / "diligent_bear", select=["nope.png"])
