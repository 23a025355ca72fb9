"""Point lights of the near-field contract: positions, axes, lobes, falloff."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.point_lights import light_vectors, point_lights, ring_point_lights, shading
from photometric.lights import ring_lights


def test_ring_places_the_leds_on_their_slant_and_distance():
    lights = ring_point_lights(4, 40.0, 250.0, azimuth0_deg=30.0, mu=[0.0, 1.0, 2.0, 0.5], intensities=[1, 2, 3, 4])
    s, a = np.radians(40.0), np.radians(30.0)
    np.testing.assert_allclose(lights.positions[0], 250.0 * np.array([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a),
                                                                      np.cos(s)]), atol=1e-12)
    np.testing.assert_allclose(lights.directions, ring_lights(4, 40.0, 30.0), atol=1e-12)
    np.testing.assert_allclose(lights.d0, 250.0)
    np.testing.assert_allclose(lights.axes, -lights.directions, atol=1e-12)  # aimed at the origin
    d = lights.as_dict()
    assert d["model"] == "point" and d["mu"] == [0.0, 1.0, 2.0, 0.5] and d["intensities"] == [1, 2, 3, 4]
    assert d["d0_mm"] == pytest.approx([250.0] * 4)


def test_deviated_ring_moves_the_leds_on_their_sphere():
    lights = ring_point_lights(3, 45.0, 200.0, deviations_deg=[[2.0, 0.0], [0.0, 0.0], [0.0, 5.0]])
    np.testing.assert_allclose(lights.d0, 200.0)
    slant = np.degrees(np.arccos(lights.positions[:, 2] / 200.0))
    np.testing.assert_allclose(slant, [47.0, 45.0, 45.0], atol=1e-9)


def test_irradiance_is_inverse_square_times_the_lobe():
    lights = point_lights([[20.0, -10.0, 150.0]], axes=[[0.1, 0.0, -1.0]], mu=3.0, intensities=[2.0])
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(-30, 30, (50, 2)), rng.uniform(-1, 1, 50)])
    unit, g = light_vectors(lights, points)
    v = lights.positions[0] - points
    r = np.linalg.norm(v, axis=1)
    a = np.array([0.1, 0.0, -1.0]) / np.linalg.norm([0.1, 0.0, -1.0])
    np.testing.assert_allclose(unit[0], v / r[:, None], rtol=1e-14)
    cos = -(v / r[:, None]) @ a
    np.testing.assert_allclose(g[0], (np.linalg.norm(lights.positions[0]) / r) ** 2 * cos**3, rtol=1e-13)


@pytest.mark.parametrize("mu", [0.0, 1.0, 2.0, 1.7])
def test_shading_planes_equal_the_light_vectors(mu):
    lights = point_lights([[20.0, -10.0, 150.0], [-90.0, 40.0, 60.0]], axes=[[0.1, 0.0, -1.0], [1.0, -0.2, -0.8]],
                          mu=mu)
    rng = np.random.default_rng(2)
    points = np.column_stack([rng.uniform(-30, 30, (200, 2)), rng.uniform(-1, 1, 200)])
    normals = rng.normal(size=(200, 3)) + [0.0, 0.0, 2.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    unit, g = light_vectors(lights, points)
    for k in range(2):
        expected = g[k] * np.maximum(0.0, np.sum(normals * unit[k], axis=1))
        got = shading(lights, k, tuple(points.T.copy()), tuple(normals.T.copy()))
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
        assert (got == 0).any() or k == 0


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: point_lights([[0.0, 0.0, 0.0]]), "not above the reference plane"),
        (lambda: point_lights([[10.0, 0.0, 100.0], [0.0, 50.0, -1.0]]), r"light\(s\) \[2\]"),
        (lambda: point_lights([[0.0, 0.0, 10.0]], axes=[[0.0, 0.0, 0.0]]), "axes"),
        (lambda: point_lights([[0.0, 0.0, 10.0]], mu=-1.0), "mu"),
        (lambda: point_lights([[0.0, 0.0, 10.0]], intensities=[0.0]), "intensities"),
        (lambda: point_lights([[0.0, 10.0]]), "positions"),
        (lambda: ring_point_lights(3, 90.0, 100.0), "slant_deg"),
        (lambda: ring_point_lights(3, 45.0, 0.0), "distance_mm"),
    ],
)
def test_bad_lights_are_clear_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call()
