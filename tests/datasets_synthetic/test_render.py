"""Rendering: the Lambertian formula, cast shadows where geometry puts them, noise, files."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from datasets_synthetic.heightfields import gaussian_bumps, make_scene, plane, sphere_cap, tilted_plane
from datasets_synthetic.render import (
    cast_shadow_mask,
    make_triad_folder,
    render,
    texture_albedo,
    write_diligent_folder,
)
from photometric.io import read_folder
from photometric.lights import deviate_lights, ring_lights
from photometric.normals import angular_error_deg


def test_scene_records_the_deviated_lights(tmp_path):
    """scene.json states slant, azimuth and the angle between true and nominal lights."""
    scene = make_triad_folder(tmp_path, scene="plane", size=16, lights=3, slant=40.0, noise=0.0,
                              shadows="none", deviate=[[1.0, 0.0], [0.0, 3.0], [0.0, 0.0]], albedo=1.0)
    np.testing.assert_allclose(scene["slant_nominal_deg"], 40.0, atol=1e-12)
    np.testing.assert_allclose(np.mod(np.asarray(scene["azimuth_nominal_deg"]) - 90.0 + 1e-9, 120.0), 0.0, atol=1e-8)
    s = np.radians(40.0)
    expected = [1.0, np.degrees(np.arccos(np.cos(s) ** 2 + np.sin(s) ** 2 * np.cos(np.radians(3.0)))), 0.0]
    np.testing.assert_allclose(scene["light_error_deg"], expected, atol=1e-9)
    np.testing.assert_allclose(angular_error_deg(scene["lights_true"], scene["lights_nominal"]), expected, atol=1e-9)


@pytest.mark.parametrize("rgb", [False, True])
def test_rendered_values_match_the_formula_at_sampled_pixels(rgb):
    hf = make_scene("plate", 96, 0.05, seed=2)
    L = deviate_lights(ring_lights(3, 50.0), [[2, 1], [0, 0], [-1, 3]])
    rho = texture_albedo(96, seed=4)
    e = np.array([[0.9, 0.8, 1.0], [1.0, 1.0, 0.7], [0.6, 0.9, 0.9]]) if rgb else np.array([0.9, 1.0, 0.8])
    img = render(hf, L, e, rho, shadows="attached")
    assert img.dtype == np.float32
    assert img.shape == ((3, 96, 96, 3) if rgb else (3, 96, 96))
    rng = np.random.default_rng(0)
    rows, cols = rng.integers(0, 96, 200), rng.integers(0, 96, 200)
    for k in range(3):
        shade = np.maximum(hf.normals[rows, cols] @ L[k], 0.0) * rho[rows, cols]
        want = shade[:, None] * e[k][None, :] if rgb else shade * e[k]
        np.testing.assert_allclose(img[k][rows, cols], want, atol=1e-6)


def test_linear_model_without_shadows_keeps_negative_values():
    hf = tilted_plane(8, 0.1, slope_x=3.0, slope_y=0.0)  # faces away from a light on the right
    light = np.array([[np.sin(np.radians(60)), 0.0, np.cos(np.radians(60))]])
    raw = render(hf, light, shadows="none")
    assert np.all(raw < 0)
    np.testing.assert_allclose(raw[0], hf.normals @ light[0], atol=1e-6)
    assert np.all(render(hf, light, shadows="attached") == 0)


def _bump():
    return gaussian_bumps(96, 0.1, centers_px=[(48, 48)], amplitudes_mm=[3.0], sigmas_mm=[0.6])


def _exact_shadow_row(hf, row, light):
    """Shadow along one image row by dense sampling of the analytic bump (light in x-z)."""
    b = hf.params["bumps"][0]
    ps = hf.pixel_size
    cols = np.arange(hf.shape[1])
    x0 = (cols - (hf.shape[1] - 1) / 2) * ps
    y0 = ((hf.shape[0] - 1) / 2 - row) * ps
    tan_e = light[2] / abs(light[0])
    t = np.linspace(1e-6, 12.0, 40001)[None, :]
    xs = x0[:, None] + np.sign(light[0]) * t

    def z(x):
        return b["amplitude_mm"] * np.exp(-((x - b["center_mm"][0]) ** 2 + (y0 - b["center_mm"][1]) ** 2)
                                          / (2 * b["sigma_mm"] ** 2))

    return np.max(z(xs) - t * tan_e, axis=1) > z(x0)


@pytest.mark.parametrize("method", ["march", "raycast"])
@pytest.mark.parametrize("slant", [50.0, 65.0])
def test_tall_bump_shadows_the_pixels_behind_it(slant, method):
    hf = _bump()
    light = np.array([np.sin(np.radians(slant)), 0.0, np.cos(np.radians(slant))])  # from the right
    mask = cast_shadow_mask(hf.height, light, hf.pixel_size, method=method)
    exact = _exact_shadow_row(hf, 48, light)
    # the shadow lies on the far side (left of the bump), none on the lit side
    assert mask[48, :40].any() and not mask[48, 56:].any()
    assert np.sum(mask[48] != exact) <= 1
    finer = cast_shadow_mask(hf.height, light, hf.pixel_size, step=0.05, method="march")
    assert np.mean(finer != mask) < 0.002
    img = render(hf, light[None], shadows="cast")[0]
    mask = cast_shadow_mask(hf.height, light, hf.pixel_size)
    assert np.all(img[mask] == 0) and np.all(img[~mask & (hf.normals @ light > 0.05)] > 0)
    reused = render(hf, light[None], shadows="cast", cast_masks=mask[None])[0]
    np.testing.assert_array_equal(reused, img)


def test_shadow_of_a_light_from_the_top_falls_towards_the_bottom_rows():
    hf = _bump()
    light = np.array([0.0, np.sin(np.radians(60)), np.cos(np.radians(60))])  # +y is up
    mask = cast_shadow_mask(hf.height, light, hf.pixel_size)
    rows = np.nonzero(mask[:, 48])[0]
    assert len(rows) > 5 and rows.min() > 48


def test_cast_shadows_agree_with_open3d_ray_casting():
    import open3d as o3d

    hf = gaussian_bumps(64, 0.1, centers_px=[(30, 30), (40, 20)], amplitudes_mm=[2.0, 1.5],
                        sigmas_mm=[0.5, 0.4])
    light = deviate_lights(ring_lights(3, 60.0), np.zeros(3))[1]
    h, w = hf.shape
    rr, cc = np.mgrid[0:h, 0:w]
    verts = np.column_stack([cc.ravel() * hf.pixel_size, -rr.ravel() * hf.pixel_size,
                             hf.height.ravel()]).astype(np.float32)
    idx = (rr * w + cc)[:-1, :-1].ravel()
    tris = np.concatenate([np.column_stack([idx, idx + w, idx + 1]),
                           np.column_stack([idx + 1, idx + w, idx + w + 1])]).astype(np.uint32)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
    origins = verts + 1e-4 * light.astype(np.float32)
    rays = np.column_stack([origins, np.broadcast_to(light.astype(np.float32), origins.shape)])
    hit = np.isfinite(scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()).reshape(h, w)
    ours = cast_shadow_mask(hf.height, light, hf.pixel_size, method="march")
    lit_side = hf.normals @ light > 0.05  # attached shadows are shadows in both models
    assert ours.sum() > 50
    assert np.mean(ours[lit_side] != hit[lit_side]) < 0.01


def test_flat_and_overhead_cases_cast_no_shadow():
    hf = sphere_cap(64, 0.1)
    assert not cast_shadow_mask(hf.height, [0.0, 0.0, 1.0], 0.1).any()
    assert not cast_shadow_mask(plane(32, 0.1).height, ring_lights(1, 80.0)[0], 0.1).any()
    assert cast_shadow_mask(hf.height, [1.0, 0.0, 0.0], 0.1).all()
    with pytest.raises(ValueError, match="method"):
        cast_shadow_mask(hf.height, [0.0, 0.0, 1.0], 0.1, method="magic")


def test_noise_and_quantisation():
    hf = plane(128, 0.1)
    light = ring_lights(1, 0.0)
    clean = render(hf, light, albedo=0.5)
    noisy = render(hf, light, albedo=0.5, noise=0.01, seed=1)
    assert np.std(noisy - clean) == pytest.approx(0.01, rel=0.05)
    shot = render(hf, light, albedo=0.5, shot_noise=1e-3, seed=1)
    assert np.var(shot - clean) == pytest.approx(1e-3 * 0.5, rel=0.05)
    q8 = render(hf, light, albedo=0.4, noise=0.01, bit_depth=8, seed=2)
    np.testing.assert_allclose(q8 * 255, np.round(q8 * 255), atol=1e-4)
    again = render(hf, light, albedo=0.5, noise=0.01, seed=1)
    np.testing.assert_array_equal(again, noisy)


def test_specular_highlight_where_the_normal_bisects_light_and_view():
    hf = plane(8, 0.1)
    light = ring_lights(1, 40.0)
    img = render(hf, light, albedo=0.5, specular={"ks": 0.3, "shininess": 10.0})[0]
    half = light[0] + [0, 0, 1]
    half /= np.linalg.norm(half)
    expected = 0.5 * light[0, 2] + 0.3 * half[2] ** 10
    np.testing.assert_allclose(img, expected, atol=1e-6)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"lights": [[0, 0, 0.0]]}, "zero-length"),
        ({"lights": [[0, 0, 1.0, 0.0]]}, "shape"),
        ({"lights": [[0, 0, 1.0]], "shadows": "soft"}, "shadows"),
        ({"lights": [[0, 0, 1.0]], "bit_depth": 12}, "bit_depth"),
        ({"lights": [[0, 0, 1.0]], "intensities": [1.0, 2.0]}, "intensities"),
        ({"lights": [[0, 0, 1.0]], "albedo": np.ones((3, 3))}, "albedo"),
        ({"lights": [[0, 0, 1.0]], "specular": {"gloss": 1}}, "specular"),
    ],
)
def test_render_rejects_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        render(plane(8, 0.1), **kwargs)


def test_render_normalises_a_long_light_with_a_warning():
    hf = tilted_plane(8, 0.1, slope_x=0.3, slope_y=-0.1)
    with pytest.warns(UserWarning, match="not unit"):
        long = render(hf, [[0.0, 0.0, 2.0]])
    np.testing.assert_allclose(long, render(hf, [[0.0, 0.0, 1.0]]), atol=1e-7)


def test_triad_folder_round_trip(tmp_path):
    scene = make_triad_folder(tmp_path / "triad", scene="plane", size=32, lights=3, slant=45.0,
                              noise=0.0, shadows="cast", deviate=(2, 0, 0), albedo=1.0)
    out = tmp_path / "triad"
    names = (out / "filenames.txt").read_text().split()
    assert names == ["001.png", "002.png", "003.png"]
    nominal = np.loadtxt(out / "light_directions.txt")
    np.testing.assert_allclose(nominal, ring_lights(3, 45.0), atol=1e-9)
    assert np.loadtxt(out / "light_intensities.txt").shape == (3, 3)
    img = cv2.imread(str(out / "001.png"), cv2.IMREAD_UNCHANGED)
    assert img.dtype == np.uint16 and img.shape == (32, 32)
    # rendered with the TRUE light (slant 47 deg), recorded with the nominal one (45 deg)
    assert img[5, 5] / 65535 == pytest.approx(np.cos(np.radians(47.0)), abs=2e-5)
    assert cv2.imread(str(out / "002.png"), cv2.IMREAD_UNCHANGED)[5, 5] / 65535 == pytest.approx(
        np.cos(np.radians(45.0)), abs=2e-5)
    stored = json.loads((out / "scene.json").read_text())
    assert stored["light_error_deg"][0] == pytest.approx(2.0)
    np.testing.assert_allclose(stored["lights_true"], deviate_lights(nominal, [2, 0, 0]), atol=1e-9)
    assert stored["scene"] == scene["scene"] == "plane"
    assert np.load(out / "normal_gt.npy").shape == (32, 32, 3)
    assert np.load(out / "height_gt.npy").shape == (32, 32)
    assert cv2.imread(str(out / "mask.png"), cv2.IMREAD_UNCHANGED).min() == 255


def test_triad_folder_is_readable_by_the_photometric_reader(tmp_path):
    make_triad_folder(tmp_path, scene="plate", size=48, lights=3, slant=50.0, noise=0.0,
                      deviate=None, seed=1)
    data = read_folder(tmp_path)
    assert data.images.shape[0] == 3 and data.images.shape[1:3] == (48, 48)
    np.testing.assert_allclose(data.lights, ring_lights(3, 50.0), atol=1e-9)
    assert data.mask.all()
    np.testing.assert_allclose(data.normal_gt, make_scene("plate", 48, 0.05, 1).normals, atol=1e-6)


def test_rgb_folder_keeps_channel_order(tmp_path):
    hf = plane(8, 0.1)
    e = np.array([[1.0, 0.5, 0.25]])
    img = render(hf, ring_lights(1, 0.0), e)
    write_diligent_folder(tmp_path, img, ring_lights(1, 0.0), e, np.ones((8, 8), bool), hf.normals,
                          hf.height, {"scene": "plane"})
    bgr = cv2.imread(str(tmp_path / "001.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_allclose(bgr[0, 0] / 65535, [0.25, 0.5, 1.0], atol=2e-5)


@pytest.mark.parametrize(
    "kwargs, message",
    [({"deviate": (1, 2)}, "deviate"), ({"scene": "moon"}, "name"), ({"albedo": "paint"}, "albedo")],
)
def test_triad_folder_rejects_bad_input(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make_triad_folder(tmp_path, size=32, **kwargs)
