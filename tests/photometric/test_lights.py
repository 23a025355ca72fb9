import json
import warnings

import numpy as np
import pytest

from photometric import lights as lt
from tests.photometric._render import render, ring, sphere_normals


def test_convention_stated_and_gradients_match_normal():
    assert "y up" in lt.CONVENTION
    # z = 0.3 x - 0.2 y  ->  p = 0.3, q = -0.2, n = (-p, -q, 1)/|.|
    n = np.array([-0.3, 0.2, 1.0]) / np.sqrt(1 + 0.09 + 0.04)
    assert np.isclose(-n[0] / n[2], 0.3) and np.isclose(-n[1] / n[2], -0.2)


@pytest.mark.parametrize("slant,tilt", [(0, 0), (30, 0), (45, 90), (60, 200), (54.7356, -120)])
def test_slant_tilt_roundtrip(slant, tilt):
    light = lt.lights_from_slant_tilt([slant], [tilt])[0]
    assert np.isclose(np.linalg.norm(light), 1)
    assert np.isclose(np.degrees(np.arccos(light[2])), slant)
    if slant > 0:
        s, t = lt.slant_tilt_from_lights(light[None])
        assert np.isclose(s[0], slant) and np.isclose((t[0] - tilt + 180) % 360 - 180, 0, atol=1e-9)
    # tilt 90 deg means the light comes from the top of the image: +y (y up)
    if tilt == 90:
        assert light[1] > 0 and abs(light[0]) < 1e-12


def test_validate_errors_and_warning():
    with pytest.raises(ValueError, match="at least 3"):
        lt.validate_lights(np.eye(3)[:2])
    with pytest.raises(ValueError, match="coplanar"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [0.7071, 0.7071, 0]])
    with pytest.raises(ValueError, match="NaN"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [np.nan, 0, 1]])
    with pytest.raises(ValueError, match="zero-length"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [0, 0, 0]])
    with pytest.warns(UserWarning, match="not unit"):
        out = lt.validate_lights([[2, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert np.allclose(np.linalg.norm(out, axis=1), 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lt.validate_lights(np.eye(3))


def test_condition_number_best_triad():
    # three lights 120 deg apart at tan(slant) = sqrt(2): all singular values equal
    best = ring(3, np.degrees(np.arctan(np.sqrt(2))))
    assert np.isclose(lt.condition_number(best), 1.0, atol=1e-9)
    assert lt.condition_number(ring(3, 20)) > 2


@pytest.mark.parametrize("fmt", ["txt", "npy", "json", "json_st", "st_txt"])
def test_load_lights_formats(tmp_path, fmt):
    lights = ring(4, 40)
    if fmt == "txt":
        path = tmp_path / "l.txt"
        np.savetxt(path, lights)
    elif fmt == "npy":
        path = tmp_path / "l.npy"
        np.save(path, lights)
    elif fmt == "json":
        path = tmp_path / "l.json"
        path.write_text(json.dumps({"lights": lights.tolist()}))
    else:
        s, t = lt.slant_tilt_from_lights(lights)
        if fmt == "json_st":
            path = tmp_path / "l.json"
            path.write_text(json.dumps({"slant_deg": s.tolist(), "tilt_deg": t.tolist()}))
        else:
            path = tmp_path / "st.txt"
            np.savetxt(path, np.stack([s, t], 1))
    assert np.allclose(lt.load_lights(path), lights, atol=1e-12)


def test_load_lights_missing(tmp_path):
    with pytest.raises(FileNotFoundError):
        lt.load_lights(tmp_path / "nope.txt")


@pytest.mark.parametrize(
    "values,expected",
    [(None, np.ones((3, 3))), (2.0, np.full((3, 3), 2.0)),
     ([1, 2, 3], np.repeat([[1.0], [2.0], [3.0]], 3, 1)), (np.arange(1, 10).reshape(3, 3), None)],
)
def test_intensities(tmp_path, values, expected):
    out = lt.as_intensities(values, 3)
    assert out.shape == (3, 3)
    if expected is not None:
        assert np.allclose(out, expected)
    if values is not None and np.ndim(values) > 0:
        path = tmp_path / "i.txt"
        np.savetxt(path, np.atleast_1d(values))
        assert np.allclose(lt.load_intensities(path, 3), out)
    with pytest.raises(ValueError):
        lt.as_intensities([1, 2], 3)
    with pytest.raises(ValueError, match="positive"):
        lt.as_intensities([1, -2, 3], 3)


def _mirror_sphere(lights, size=201, radius=80.0, blob=1.5):
    """Mirror sphere: mask plus a small Gaussian highlight where 2(n.v)n - v = l."""
    rows, cols = np.mgrid[0:size, 0:size].astype(float)
    r0, c0 = 101.3, 98.6
    mask = (rows - r0) ** 2 + (cols - c0) ** 2 <= radius**2
    images = []
    for light in lights:
        h = light + np.array([0.0, 0.0, 1.0])
        h /= np.linalg.norm(h)  # the normal that reflects v into l
        hr, hc = r0 - radius * h[1], c0 + radius * h[0]
        img = np.exp(-((rows - hr) ** 2 + (cols - hc) ** 2) / (2 * blob**2))
        images.append(np.where(mask, 0.05 + img, 0.0))
    return np.array(images, np.float32), mask


@pytest.mark.parametrize("slant", [20.0, 45.0, 60.0])
def test_mirror_sphere_calibration(slant):
    truth = ring(6, slant, 17.0)
    images, mask = _mirror_sphere(truth)
    est, info = lt.calibrate_mirror_sphere(images, mask)
    err = np.degrees(np.arccos(np.clip(np.sum(est * truth, 1), -1, 1)))
    assert err.max() < 0.5, err
    assert abs(info["radius_px"] - 80.0) < 0.5
    # the classic bug (returning the sphere normal) would be off by about slant / 2
    normal_bug = truth + [0, 0, 1]
    normal_bug /= np.linalg.norm(normal_bug, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(est * normal_bug, 1), -1, 1))).min() > slant / 2 - 1


def test_sphere_lambertian_render_sanity():
    n, mask = sphere_normals(32)
    imgs = render(n, ring(3, 45))
    assert imgs.shape == (3, 32, 32) and mask.sum() > 100
