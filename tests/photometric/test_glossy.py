"""The Lambertian + GGX lobe model against Mitsuba 3's lambertian_ggx renders and closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera
from datasets_synthetic.heightfields import gaussian_bumps, plane
from datasets_synthetic.point_lights import ring_point_lights
from photometric.glossy import fit_glossy, ggx_lobe, lobe_weight
from photometric.leds import light_field, point_lights
from photometric.normals import angular_error_deg
from surfaces.validate import InputError

SIZE, PIXEL_MM = 64, 0.5
UP = (0.0, 0.0, 1.0)


def test_lobe_closed_forms():
    n = np.zeros((1, 2, 3))
    n[..., 2] = 1.0
    # light straight above: D(0) = 1 / (pi alpha^2), G = 1; a light below the surface gives nothing
    s = np.array([[0.0, 0.0, 3.0], [0.0, 0.0, -1.0]])
    f = ggx_lobe(n, s, UP, 0.3)
    assert f[0] == pytest.approx(3.0 / (np.pi * 0.09) / 4.0)
    assert np.all(f[1] == 0.0)
    # off the mirror direction the lobe falls as GGX's D: half vector 20 deg from n
    t = np.radians(40.0)
    s = np.array([[np.sin(t), 0.0, np.cos(t)]])
    th = np.radians(20.0)
    a2 = 0.09
    d = a2 / (np.pi * (np.cos(th) ** 2 * (a2 - 1) + 1) ** 2)
    g1 = 2.0 / (1.0 + np.sqrt(1.0 + a2 * np.tan(t) ** 2))
    assert ggx_lobe(n, s, UP, 0.3)[0, 0, 0] == pytest.approx(d * g1 / 4.0)


def _render(surface, alpha, specular, n=8, seed=0):
    mitsuba_scenes = pytest.importorskip("datasets_synthetic.mitsuba_scenes")
    pytest.importorskip("mitsuba", reason="Mitsuba 3 renders the glossy plate")
    rig = ring_point_lights(n, 45.0, 100.0, 90.0, 0.0)
    r = mitsuba_scenes.render_mitsuba(surface, orthographic_camera((SIZE, SIZE), PIXEL_MM), rig,
                                      mitsuba_scenes.material("lambertian_ggx", 0.7, alpha=alpha, specular=specular),
                                      spp=16, flats=False, exposure=1.0, seed=seed)
    return r, light_field(point_lights(rig.positions), r.hits.points)


def _lambertian(images, s):
    A = np.einsum("khwi,khwj->hwij", s, s)
    g = np.linalg.solve(A, np.einsum("khw,khwi->hwi", images, s)[..., None])[..., 0]
    rho = np.linalg.norm(g, axis=-1)
    return g / rho[..., None], rho


def test_lobe_weight_of_a_level_reference_is_pi_times_the_lobe_reflectance():
    r, s = _render(plane((SIZE, SIZE), PIXEL_MM), 0.3, 0.3)
    c = lobe_weight(r.images, s, r.hits.normals, UP, 0.3)
    assert c == pytest.approx(np.pi * 0.3, rel=0.01)
    matte, s0 = _render(plane((SIZE, SIZE), PIXEL_MM), 0.3, 0.0)
    assert abs(lobe_weight(matte.images, s0, matte.hits.normals, UP, 0.3)) < 0.01


def test_fit_recovers_the_normals_a_lambertian_solve_tilts():
    bumps = gaussian_bumps((SIZE, SIZE), PIXEL_MM, seed=3)
    r, s = _render(bumps, 0.3, 0.3)
    n0, rho0 = _lambertian(r.images, s)
    before = angular_error_deg(n0, r.hits.normals)
    n, rho, rms = fit_glossy(r.images, s, UP, 0.3, np.pi * 0.3, n0, rho0)
    after = angular_error_deg(n, r.hits.normals)
    assert np.median(before) > 1.0
    assert np.median(after) < 0.1 * np.median(before) and np.median(after) < 0.2
    # the albedo is the diffuse one: 0.7 / pi per unit irradiance and exposure 1
    assert np.median(rho) == pytest.approx(0.7 / np.pi, rel=0.02)
    assert np.median(rms) < 0.01 * np.median(r.images)


def test_weight_zero_is_the_lambertian_least_squares():
    r, s = _render(plane((SIZE, SIZE), PIXEL_MM), 0.3, 0.0, seed=1)
    n0, rho0 = _lambertian(r.images, s)
    tilted = n0 + [0.05, -0.03, 0.0]
    tilted /= np.linalg.norm(tilted, axis=-1, keepdims=True)
    n, rho, _ = fit_glossy(r.images, s, UP, 0.3, 0.0, tilted, rho0 * 1.1)
    assert np.max(angular_error_deg(n, n0)) < 0.01
    np.testing.assert_allclose(rho, rho0, rtol=1e-4)


def test_bad_input():
    n = np.zeros((4, 4, 3))
    n[..., 2] = 1.0
    with pytest.raises(InputError, match="at least 4"):
        fit_glossy(np.ones((3, 4, 4)), np.ones((3, 3)), UP, 0.3, 1.0, n, np.ones((4, 4)))
    with pytest.raises(InputError, match="view"):
        ggx_lobe(n, np.ones((4, 3)), (0.0, 0.0, 0.0), 0.3)
    with pytest.raises(InputError, match="weight"):
        fit_glossy(np.ones((4, 4, 4)), np.ones((4, 3)), UP, 0.3, -1.0, n, np.ones((4, 4)))


def test_dark_observations_are_left_out():
    """A cast shadow (an observation read as black) tilts the fit unless it is left out."""
    r, s = _render(plane((SIZE, SIZE), PIXEL_MM), 0.3, 0.3, seed=2)
    images = r.images.copy()
    images[0, :, : SIZE // 2] = 0.0  # light 1 shadowed on the left half
    n0, rho0 = _lambertian(r.images, s)
    c = np.pi * 0.3
    n, _, _ = fit_glossy(images, s, UP, 0.3, c, n0, rho0)
    n_all, _, _ = fit_glossy(images, s, UP, 0.3, c, n0, rho0, dark=None)
    left = np.s_[:, : SIZE // 2]
    assert np.median(angular_error_deg(n[left], r.hits.normals[left])) < 0.2
    assert np.median(angular_error_deg(n_all[left], r.hits.normals[left])) > 2.0
