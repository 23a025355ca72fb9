import json
import warnings

import numpy as np
import pytest

from photometric import calibrate, leds
from photometric import io as pio
from photometric import lights as lt
from photometric.normals import angular_error_deg
from tests.photometric._render import ring


def test_convention_stated_and_gradients_match_normal():
    assert "y up" in lt.CONVENTION
    # z = 0.3 x - 0.2 y  ->  p = 0.3, q = -0.2, n = (-p, -q, 1)/|.|
    n = np.array([-0.3, 0.2, 1.0]) / np.sqrt(1 + 0.09 + 0.04)
    assert np.isclose(-n[0] / n[2], 0.3) and np.isclose(-n[1] / n[2], -0.2)


@pytest.mark.parametrize("slant,azimuth", [(0, 0), (30, 0), (45, 90), (60, 200), (54.7356, -120)])
def test_slant_azimuth_roundtrip(slant, azimuth):
    light = lt.lights_from_angles([slant], [azimuth])[0]
    assert np.isclose(np.linalg.norm(light), 1)
    assert np.isclose(np.degrees(np.arccos(light[2])), slant)
    if slant > 0:
        s, a = lt.light_angles(light[None])
        assert np.isclose(s[0], slant) and np.isclose((a[0] - azimuth + 180) % 360 - 180, 0, atol=1e-9)
    # azimuth 90 deg means the light comes from the top of the image: +y (y up)
    if azimuth == 90:
        assert light[1] > 0 and abs(light[0]) < 1e-12
    # "tilt" is accepted as the other name of the azimuth
    np.testing.assert_array_equal(lt.lights_from_angles([slant], tilt_deg=[azimuth]), light[None])


def test_light_angles_round_trip_in_batches():
    s = np.array([[0.0, 10.0], [45.0, 80.0]])
    a = np.array([[0.0, -170.0], [30.0, 120.0]])
    s2, a2 = lt.light_angles(lt.lights_from_angles(s, a))
    assert s2.shape == (2, 2)
    np.testing.assert_allclose(s2, s, atol=1e-12)
    np.testing.assert_allclose(a2.ravel()[1:], a.ravel()[1:], atol=1e-12)


def test_angles_bad_input():
    with pytest.raises(ValueError, match="slant_deg"):
        lt.lights_from_angles([95.0], [0.0])
    with pytest.raises(ValueError, match="exactly one"):
        lt.lights_from_angles([45.0], [0.0], tilt_deg=[0.0])
    with pytest.raises(ValueError, match="broadcast"):
        lt.lights_from_angles([45.0, 30.0], [0.0, 1.0, 2.0])


@pytest.mark.parametrize("n, slant", [(3, 45.0), (4, 30.0), (8, 54.74), (1, 0.0)])
def test_ring_lights(n, slant):
    L = lt.ring_lights(n, slant)
    np.testing.assert_allclose(np.linalg.norm(L, axis=1), 1.0)
    s, a = lt.light_angles(L)
    np.testing.assert_allclose(s, slant, atol=1e-12)
    if slant > 0:
        np.testing.assert_allclose(np.mod(a - 90.0 + 1e-9, 360.0 / n), 0.0, atol=1e-6)
        assert L[0, 1] > 0.0  # azimuth 90: the first light comes from the top (y up)
    with pytest.raises(ValueError, match="n"):
        lt.ring_lights(0, slant)
    with pytest.raises(ValueError, match="slant_deg"):
        lt.ring_lights(n, -1.0)


@pytest.mark.parametrize("ds, da", [(2.0, 0.0), (-3.0, 0.0), (0.0, 5.0), (1.0, 2.0)])
def test_deviate_lights_angles(ds, da):
    slant = 45.0
    L = lt.ring_lights(3, slant)
    D = lt.deviate_lights(L, [[ds, da], [0, 0], [0, 0]])
    err = angular_error_deg(D, L)
    # spherical law of cosines between (s, a) and (s + ds, a + da)
    s0, s1, d = np.deg2rad(slant), np.deg2rad(slant + ds), np.deg2rad(da)
    expected = np.rad2deg(np.arccos(np.cos(s0) * np.cos(s1) + np.sin(s0) * np.sin(s1) * np.cos(d)))
    assert err[0] == pytest.approx(expected, abs=1e-9)
    np.testing.assert_allclose(err[1:], 0.0, atol=1e-9)


def test_deviate_lights_batches_and_slant_only():
    L = lt.ring_lights(3, 50.0)
    dev = np.zeros((4, 2, 3, 2))
    dev[..., 0, 0] = np.linspace(-2, 2, 4)[:, None]
    dev[..., 2, 1] = np.array([-1.0, 1.0])[None, :]
    batch = lt.deviate_lights(L, dev)
    assert batch.shape == (4, 2, 3, 3)
    np.testing.assert_allclose(batch[3, 0], lt.deviate_lights(L, dev[3, 0]), atol=1e-15)
    np.testing.assert_allclose(lt.deviate_lights(L, [2.0, 0.0, -1.0]),
                               lt.deviate_lights(L, [[2.0, 0.0], [0.0, 0.0], [-1.0, 0.0]]), atol=1e-15)
    with pytest.raises(ValueError, match="deviations_deg"):
        lt.deviate_lights(L, np.zeros((2, 2)))


@pytest.mark.parametrize("delta", [0.5, 3.0, -4.0])
def test_rotate_lights_moves_by_the_angle(delta):
    lights = lt.lights_from_angles([40.0, 35.0, 50.0, 45.0], [0.0, 100.0, 190.0, 280.0])
    phi = np.linspace(0, 300, lights.shape[0])
    out = lt.rotate_lights(lights, np.full(lights.shape[0], delta), phi)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(angular_error_deg(out, lights), abs(delta), atol=1e-9)
    # direction 0 is the slant increment, direction 90 turns towards increasing azimuth
    dev = np.zeros((lights.shape[0], 2))
    dev[:, 0] = delta
    np.testing.assert_allclose(
        lt.rotate_lights(lights, np.full(lights.shape[0], delta), 0.0), lt.deviate_lights(lights, dev), atol=1e-14
    )
    turned = lt.rotate_lights(lights, np.full(lights.shape[0], abs(delta)), 90.0)
    _, a0 = lt.light_angles(lights)
    _, a1 = lt.light_angles(turned)
    assert np.all(np.sin(np.radians(a1 - a0)) > 0)


def test_tangent_basis_is_orthonormal_and_the_slant_derivative():
    L = lt.lights_from_angles([10.0, 45.0, 70.0], [30.0, 150.0, -90.0])
    e_s, e_a = lt.tangent_basis(L)
    frame = np.stack([L, e_s, e_a], axis=1)  # (N, 3, 3), rows l, e_s, e_a
    np.testing.assert_allclose(frame @ np.swapaxes(frame, 1, 2), np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-14)
    h = 1e-6
    s, a = lt.light_angles(L)
    ds = (lt.lights_from_angles(s + h, a) - lt.lights_from_angles(s - h, a)) / np.radians(2 * h)
    np.testing.assert_allclose(ds, e_s, atol=1e-8)


def test_rotation_matrix_turns_about_the_axis():
    R = lt.rotation_matrix((1, 1, 0), 30.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(R @ np.array([1.0, 1.0, 0.0]), [1.0, 1.0, 0.0], atol=1e-15)
    z = R @ np.array([0.0, 0.0, 1.0])
    assert np.degrees(np.arccos(z[2])) == pytest.approx(30.0)
    with pytest.raises(ValueError, match="axis"):
        lt.rotation_matrix((0, 0, 0), 10.0)


def test_validate_errors_and_warning():
    with pytest.raises(ValueError, match="at least 3"):
        lt.validate_lights(np.eye(3)[:2])
    with pytest.raises(ValueError, match="coplanar"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [0.7071, 0.7071, 0]])
    with pytest.raises(ValueError, match="NaN"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [np.nan, 0, 1]])
    with pytest.raises(ValueError, match="zero-length"):
        lt.validate_lights([[1, 0, 0], [0, 1, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="shape"):
        lt.validate_lights(np.ones((3, 2)))
    with pytest.warns(UserWarning, match="not unit"):
        out = lt.validate_lights([[2, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert np.allclose(np.linalg.norm(out, axis=1), 1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lt.validate_lights(np.eye(3))
        # within the one tolerance: normalised silently
        near = lt.validate_lights(np.eye(3) * (1 + 0.5 * lt.UNIT_TOLERANCE))
    np.testing.assert_allclose(near, np.eye(3), atol=1e-15)
    with pytest.warns(UserWarning, match="not unit"):
        lt.validate_lights(np.eye(3) * (1 + 2 * lt.UNIT_TOLERANCE))


def test_validate_options_single_lights_and_batches():
    one = lt.validate_lights([[0.0, 0.0, 1.0]], min_lights=1)
    assert one.shape == (1, 3)
    with pytest.raises(ValueError, match="at least 3"):
        lt.validate_lights([[0.0, 0.0, 1.0]])
    sets = np.stack([lt.ring_lights(3, 45.0), lt.ring_lights(3, 60.0)])
    assert lt.validate_lights(sets, batched=True).shape == (2, 3, 3)
    with pytest.raises(ValueError, match="shape"):
        lt.validate_lights(sets)
    flat = sets.copy()
    flat[1] = [[1, 0, 0], [0, 1, 0], [0.6, 0.8, 0]]
    with pytest.raises(ValueError, match=r"coplanar in set\(s\) \[\[1\]\]"):
        lt.validate_lights(flat, batched=True)


def test_condition_number_best_triad():
    # three lights 120 deg apart at tan(slant) = sqrt(2): all singular values equal
    best = ring(3, np.degrees(np.arctan(np.sqrt(2))))
    assert np.isclose(lt.condition_number(best), 1.0, atol=1e-9)
    assert lt.condition_number(ring(3, 20)) > 2


@pytest.mark.parametrize("fmt", ["txt", "npy", "json", "json_list", "json_sa", "json_st", "sa_txt"])
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
    elif fmt == "json_list":
        path = tmp_path / "l.json"
        path.write_text(json.dumps(lights.tolist()))
    else:
        s, a = lt.light_angles(lights)
        if fmt == "json_sa":
            path = tmp_path / "l.json"
            path.write_text(json.dumps({"slant_deg": s.tolist(), "azimuth_deg": a.tolist()}))
        elif fmt == "json_st":  # "tilt" is the azimuth's other name
            path = tmp_path / "l.json"
            path.write_text(json.dumps({"slant_deg": s.tolist(), "tilt_deg": a.tolist()}))
        else:
            path = tmp_path / "sa.txt"
            np.savetxt(path, np.stack([s, a], 1))
    assert np.allclose(pio.load_lights(path), lights, atol=1e-12)


def test_load_lights_bad_content(tmp_path):
    path = tmp_path / "l.json"
    path.write_text(json.dumps({"slant_deg": [40, 40, 40]}))
    with pytest.raises(ValueError, match="azimuth_deg"):
        pio.load_lights(path)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="JSON"):
        pio.load_lights(path)
    text = tmp_path / "l.txt"
    text.write_text("0 0 1\n0 0 1\n0 0 1\n")
    with pytest.raises(ValueError, match="coplanar"):
        pio.load_lights(text)


def test_load_lights_missing(tmp_path):
    with pytest.raises(FileNotFoundError):
        pio.load_lights(tmp_path / "nope.txt")


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
        assert np.allclose(pio.load_intensities(path, 3), out)
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
    est, info = calibrate.calibrate_mirror_sphere(images, mask)
    err = np.degrees(np.arccos(np.clip(np.sum(est * truth, 1), -1, 1)))
    assert err.max() < 0.5, err
    assert abs(info["radius_px"] - 80.0) < 0.5
    # the classic bug (returning the sphere normal) would be off by about slant / 2
    normal_bug = truth + [0, 0, 1]
    normal_bug /= np.linalg.norm(normal_bug, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(est * normal_bug, 1), -1, 1))).min() > slant / 2 - 1


@pytest.mark.parametrize("r0, c0, radius", [(50.3, 47.8, 30.0), (40.0, 61.5, 12.5)])
def test_sphere_from_mask_recovers_the_circle(r0, c0, radius):
    rows, cols = np.mgrid[0:100, 0:110]
    mask = (rows - r0) ** 2 + (cols - c0) ** 2 <= radius**2
    r, c, rad = calibrate.sphere_from_mask(mask)
    assert abs(r - r0) < 0.05 and abs(c - c0) < 0.05
    assert rad == pytest.approx(radius, abs=0.1)
    with pytest.raises(ValueError, match="mask"):
        calibrate.sphere_from_mask(np.zeros((10, 10), bool))


# ----------------------------------------------------------------------------- point lights


def test_point_lights_defaults_and_directions():
    pos = 150.0 * ring(3, 45.0)
    lights = leds.point_lights(pos)
    np.testing.assert_allclose(lights.axes, -ring(3, 45.0))
    np.testing.assert_allclose(lights.d0, 150.0)
    np.testing.assert_allclose(lights.directions, ring(3, 45.0))
    assert lights.mu.tolist() == [0.0, 0.0, 0.0] and not lights.mu_known and len(lights) == 3
    known = leds.point_lights(pos, axes=[[0, 0, -1]] * 3, mu=[1.0, 2.0, 0.0])
    assert known.mu_known and known.mu.tolist() == [1.0, 2.0, 0.0]
    np.testing.assert_allclose(known.axes, [[0, 0, -1]] * 3)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"positions": [[100, 0, 100], [0, 100, 100], [-100, 0, -5]]}, "light 2 at z = -5 mm is at or below"),
        ({"positions": [[100, 0, 100], [0, 100, 100]]}, "at least 3 lights"),
        ({"positions": [[100, 0, 100], [200, 0, 200], [300, 0, 300]]}, "coplanar"),
        ({"positions": [[100, 0, 100], [0, 100, 100], [-100, 0, 100]], "mu": -1.0}, "led_mu"),
        ({"positions": [[100, 0, 100], [0, 100, 100], [-100, 0, 100]], "mu": [1.0, 2.0]}, "led_mu"),
        ({"positions": [[100, 0, 100], [0, 100, 100], [-100, 0, 100]], "axes": [[0, 0, 1]] * 3}, "point down"),
        ({"positions": [[100, 0, 100], [0, 100, 100], [-100, 0, 100]], "axes": [[0, 0, 0]] * 3}, "zero-length"),
        ({"positions": [[100, 0, np.nan], [0, 100, 100], [-100, 0, 100]]}, "NaN"),
    ],
)
def test_point_lights_errors(kwargs, message):
    with pytest.raises(ValueError, match=message):
        leds.point_lights(**kwargs)


def test_light_field_falloff_and_lobe():
    lights = leds.point_lights([[0, 0, 100], [100, 0, 100], [0, 100, 100]], mu=2.0)
    # straight below the first LED at 50 and 200 mm: inverse square, lobe 1
    s = leds.light_field(lights, [[0, 0, 50], [0, 0, -100]], intensities=[2.0, 1.0, 1.0])
    np.testing.assert_allclose(s[0], [[0, 0, 8.0], [0, 0, 0.5]])
    # off axis: cos of the angle to the LED axis, squared
    s = leds.light_field(lights, [[100, 0, 0]])
    d = np.array([-100.0, 0.0, 100.0])
    r = np.linalg.norm(d)
    expect = (100.0 / r) ** 2 * (np.cos(np.pi / 4) ** 2) * d / r
    np.testing.assert_allclose(s[0, 0], expect)
    with pytest.raises(ValueError, match="at or above the height of a light"):
        leds.light_field(lights, [[0, 0, 100]])
    with pytest.raises(ValueError, match="PointLights"):
        leds.light_field(np.eye(3), [[0, 0, 0]])


def test_load_light_positions(tmp_path):
    pos = 150.0 * ring(4, 30.0)
    np.savetxt(tmp_path / "light_positions.txt", pos)
    np.testing.assert_allclose(pio.load_light_positions(tmp_path / "light_positions.txt"), pos)
    (tmp_path / "p.json").write_text(json.dumps({"positions_mm": pos.tolist()}))
    np.testing.assert_allclose(pio.load_light_positions(tmp_path / "p.json"), pos)
    np.savetxt(tmp_path / "low.txt", pos * [1, 1, -1])
    with pytest.raises(ValueError, match=r"light_positions \(low.txt\): light 0 .* below the reference plane"):
        pio.load_light_positions(tmp_path / "low.txt")
    with pytest.raises(FileNotFoundError, match="light_positions"):
        pio.load_light_positions(tmp_path / "missing.txt")
    (tmp_path / "bad.json").write_text(json.dumps({"lights": []}))
    with pytest.raises(ValueError, match="positions_mm"):
        pio.load_light_positions(tmp_path / "bad.json")
