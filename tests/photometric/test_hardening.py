"""Inputs that cannot give a result: saturated and black pixels and images, nearly coplanar
lights, lights from behind (issue 20)."""

from __future__ import annotations


import cv2
import numpy as np
import pytest

from photometric.io import PhotometricData
from photometric.lights import ring_lights
from photometric.pipeline import reconstruct
from photometric.stereo import (
    BLACK_FLOOR,
    MAX_CONDITION,
    SATURATED,
    WARN_CONDITION,
    check_light_matrix,
    screen_images,
)

SIZE = 48


def _sphere_images(lights, albedo=0.6):
    """A lit hemisphere over a flat plane, (N, H, W) in [0, 1], and its normals."""
    y, x = np.mgrid[-1:1:SIZE * 1j, -1:1:SIZE * 1j]
    r2 = (x / 0.8) ** 2 + (y / 0.8) ** 2
    nz = np.sqrt(np.clip(1 - r2, 0, None))
    n = np.where((r2 < 1)[..., None], np.stack([x / 0.8, -y / 0.8, nz], -1), [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    imgs = albedo * np.clip(np.einsum("hwc,kc->khw", n, np.asarray(lights, float)), 0, None)
    return imgs.astype(np.float32), n


def _write_pngs(folder, images, lights):
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k, img in enumerate(images):
        paths.append(folder / f"{k:03d}.png")
        cv2.imwrite(str(paths[-1]), np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16))
    np.savetxt(folder / "L.txt", lights)
    return [str(p) for p in paths], str(folder / "L.txt")


def test_screen_counts_saturated_and_black_pixels_per_image():
    imgs = np.full((4, 5, 6), 0.5, np.float32)
    imgs[0, 0, :3] = 1.0  # 3 saturated pixels
    imgs[1, 1, :2] = 0.0  # 2 black ones
    imgs[2] = 0.0  # a black image
    s = screen_images(imgs)
    np.testing.assert_allclose(s.saturated, [3 / 30, 0, 0, 0])
    np.testing.assert_allclose(s.black, [0, 2 / 30, 1, 0])
    assert s.usable.tolist() == [True, True, False, True]
    expected = np.ones((5, 6), bool)
    expected[0, :3] = expected[1, :2] = False  # 2 of the 3 usable images left there
    np.testing.assert_array_equal(s.enough, expected)
    assert s.problems(["a", "b", "c", "d"]) == ["'c' is black (100 % of the mask)"]
    # the thresholds are strict where they should be, and a mask restricts the fractions
    assert not screen_images(np.full((3, 2, 2), BLACK_FLOOR, np.float32)).black.any()
    assert screen_images(np.full((3, 2, 2), SATURATED, np.float32)).saturated.all()
    m = np.zeros((5, 6), bool)
    m[0] = True
    assert screen_images(imgs, m).saturated[0] == pytest.approx(0.5)


def test_saturated_pixels_are_invalid_and_counted(tmp_path):
    L = ring_lights(3, 45.0)
    images, _ = _sphere_images(L)
    clean = reconstruct(images, lights=L)
    images[1, 20:24, 20:30] = 1.0  # clipped highlight, 40 px
    paths, lights = _write_pngs(tmp_path, images, L)
    res = reconstruct(paths, lights=lights)
    assert not res.valid[20:24, 20:30].any()
    patch = np.zeros((SIZE, SIZE), bool)
    patch[20:24, 20:30] = True
    assert clean.valid[patch].all()
    expected = 1 - (clean.valid & ~patch).sum() / SIZE**2
    assert res.summary["invalid_fraction"] == pytest.approx(expected, abs=2 / SIZE**2)
    assert (res.p[20:24, 20:30] == 0).all()
    # float input has no known full scale: values near 1 are kept
    assert reconstruct(images, lights=L).valid[20:24, 20:30].all()


@pytest.mark.parametrize("value, kind", [(1.0, "saturated"), (0.0, "black")])
def test_a_whole_bad_image_of_a_triad_is_an_error(tmp_path, value, kind):
    L = ring_lights(3, 45.0)
    images, _ = _sphere_images(L)
    images[2] = value
    paths, lights = _write_pngs(tmp_path, images, L)
    with pytest.raises(ValueError, match=rf"only 2 of 3 images are usable \('002.png' is {kind}"):
        reconstruct(paths, lights=lights)


@pytest.mark.parametrize("value, kind", [(1.0, "saturated"), (0.0, "black")])
def test_a_whole_bad_image_among_four_is_left_out_with_a_warning(tmp_path, value, kind):
    L = ring_lights(4, 40.0)
    images, normals = _sphere_images(L)
    good = reconstruct(images[[0, 1, 3]], lights=L[[0, 1, 3]])
    images[2] = value
    paths, lights = _write_pngs(tmp_path, images, L)
    with pytest.warns(UserWarning, match=f"'002.png' is {kind}"):
        res = reconstruct(paths, lights=lights)
    assert res.summary["warnings"] == [f"images: '002.png' is {kind} (100 % of the mask): left out of the solve"]
    assert res.summary["images"] == ["000.png", "001.png", "003.png"]
    both = res.valid & good.valid
    assert both.mean() > 0.5
    cos = np.clip(np.sum(res.normals * normals, -1), -1, 1)
    assert np.degrees(np.arccos(cos[both])).mean() < 0.5  # 16-bit rounding only


def _coplanar(tilt_deg):
    """Three lights 120 deg apart in azimuth, all at slant 90 - tilt_deg: nearly coplanar for small tilts."""
    az = np.radians([0.0, 120.0, 240.0])
    t = np.radians(tilt_deg)
    return np.stack([np.cos(az) * np.cos(t), np.sin(az) * np.cos(t), np.full(3, np.sin(t))], 1)


def test_condition_number_thresholds():
    cond, notes = check_light_matrix(ring_lights(3, 45.0))
    assert cond < WARN_CONDITION and notes == []
    cond, notes = check_light_matrix(_coplanar(3.0))
    assert WARN_CONDITION < cond < MAX_CONDITION and len(notes) == 1 and "above 10" in notes[0]
    with pytest.raises(ValueError, match=r"condition number 810 .* above 100; spread the lights or use --force"):
        check_light_matrix(_coplanar(0.05))
    cond, notes = check_light_matrix(_coplanar(0.05), force=True)
    assert cond > MAX_CONDITION and notes[0].endswith("(forced)")


def test_data_subset_keeps_lights_and_names():
    imgs = np.ones((4, 2, 2), np.float32)
    data = PhotometricData(imgs, ring_lights(4, 40.0), np.ones((4, 3)), np.ones((2, 2), bool), None,
                           ("a", "b", "c", "d"), full_scale=1.0)
    sub = data.subset([True, False, True, True])
    assert sub.names == ("a", "c", "d") and sub.images.shape == (3, 2, 2)
    np.testing.assert_array_equal(sub.lights, data.lights[[0, 2, 3]])
    assert sub.full_scale == 1.0 and sub.mask is data.mask


def test_lights_with_negative_z_are_called_that():
    L = ring_lights(3, 45.0)
    images, _ = _sphere_images(L)
    L_bad = L.copy()
    L_bad[1, 2] *= -1
    with pytest.raises(ValueError, match=r"1 light\(s\) with z < 0 \(rows \[1\]"):
        reconstruct(images, lights=L_bad)
