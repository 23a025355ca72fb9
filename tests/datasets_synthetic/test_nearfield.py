"""Near-field renders: the contract's image formula against closed forms, flat fields, sensor, folders."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from datasets_synthetic.cameras import intersect, orthographic_camera, perspective_camera, vignetting_map
from datasets_synthetic.heightfields import AnalyticSurface, make_scene, plane, sphere_cap
from datasets_synthetic.nearfield import make_near_field_folder, render_near_field, write_near_field_folder
from datasets_synthetic.point_lights import point_lights, ring_point_lights
from photometric.io import read_folder, read_images

CAMERAS = {
    "orthographic": lambda: orthographic_camera((40, 50), 0.2),
    "perspective": lambda: perspective_camera((40, 50), 800.0, 200.0, principal_point_px=(26.0, 18.5)),
}


def _reference_plane_points(camera):
    """Closed form: what each pixel sees of z = 0 (the ray C + t (dx, dy, -1) at t = H)."""
    h, w = camera.shape
    rows, cols = np.mgrid[0:h, 0:w].astype(float)
    if camera.model == "orthographic":
        x, y = (cols - (w - 1) / 2) * camera.pixel_size_mm, ((h - 1) / 2 - rows) * camera.pixel_size_mm
    else:
        cx, cy = camera.principal_point_px
        f, height = camera.focal_length_px, camera.camera_height_mm
        x, y = height * (cols - cx) / f, height * (cy - rows) / f
    return np.stack([x, y, np.zeros_like(x)], axis=-1)


@pytest.mark.parametrize("model", CAMERAS)
def test_plane_under_an_isotropic_point_light_is_the_closed_form(model):
    """I = albedo e (d0 / r)^2 (z_P / r), r = |P - X|, exactly (float32)."""
    camera = CAMERAS[model]()
    lights = point_lights([[30.0, -20.0, 120.0], [-60.0, 5.0, 80.0]], intensities=[0.8, 1.3])
    out = render_near_field(plane(8, 0.1), camera, lights, albedo=0.7, exposure=0.5)
    X = _reference_plane_points(camera)
    for k, (P, e) in enumerate(zip(lights.positions, [0.8, 1.3])):
        r = np.linalg.norm(P - X, axis=-1)
        expected = 0.5 * 0.7 * e * (np.linalg.norm(P) / r) ** 2 * (P[2] / r)
        np.testing.assert_allclose(out.images[k], expected, rtol=2e-7)
    np.testing.assert_allclose(out.hits.points, X, atol=1e-12)
    assert out.exposure == 0.5 and not out.exposure_auto and out.saturated_fraction == 0.0


@pytest.mark.parametrize("mu", [1.0, 2.5])
def test_led_lobe_on_and_off_axis_follows_cos_mu(mu):
    camera = orthographic_camera((41, 41), 2.0)
    P = np.array([0.0, 0.0, 100.0])
    iso = render_near_field(plane(8, 0.1), camera, point_lights([P]), exposure=1.0).images[0]
    lobe = render_near_field(plane(8, 0.1), camera, point_lights([P], mu=mu), exposure=1.0).images[0]
    X = _reference_plane_points(camera)
    cos = P[2] / np.linalg.norm(P - X, axis=-1)  # the angle to the LED axis (aimed at the origin)
    assert lobe[20, 20] == pytest.approx(iso[20, 20], rel=1e-7)  # on the axis
    np.testing.assert_allclose(lobe / iso, cos**mu, rtol=1e-6)
    assert lobe[0, 0] / iso[0, 0] < 0.9 ** mu  # the corners are well off the axis
    # an axis aimed elsewhere: the lobe peaks where the axis points
    aimed = render_near_field(plane(8, 0.1), camera, point_lights([P], axes=[[0.3, 0.0, -1.0]], mu=mu),
                              exposure=1.0).images[0]
    ratio = aimed / iso
    assert np.unravel_index(np.argmax(ratio), ratio.shape)[1] > 30 and ratio.max() == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("model", CAMERAS)
def test_curved_part_uses_its_own_normals_and_points(model):
    camera = CAMERAS[model]()
    hf = sphere_cap(8, 0.5, radius_mm=6.0, height_mm=3.0)
    lights = point_lights([[40.0, 30.0, 150.0]], mu=1.5, intensities=[1.1])
    out = render_near_field(hf, camera, lights, albedo=0.6, exposure=1.0)
    hits = intersect(hf, camera)
    v = lights.positions[0] - hits.points
    r = np.linalg.norm(v, axis=-1)
    unit = v / r[..., None]
    expected = 0.6 * 1.1 * (lights.d0[0] / r) ** 2 * (-(unit @ lights.axes[0])) ** 1.5 * np.maximum(
        0.0, np.sum(hits.normals * unit, axis=-1))
    np.testing.assert_allclose(out.images[0], expected, rtol=2e-7, atol=1e-9)
    assert hits.inside.sum() > 100


@pytest.mark.parametrize("model", CAMERAS)
def test_flat_fields_equal_the_render_of_the_reference_plane(model):
    camera = CAMERAS[model]()
    vig = {"model": "cos4"} if model == "perspective" else {"model": "radial", "coefficients": [-0.2]}
    lights = ring_point_lights(3, 40.0, 150.0, mu=1.0, intensities=[1.0, 0.8, 1.2])
    part = render_near_field(make_scene("plate", (40, 50), 0.2), camera, lights, albedo=0.5, vignetting=vig,
                             flat_albedo=0.5, exposure=0.9)
    target = render_near_field(AnalyticSurface(), camera, lights, albedo=0.5, vignetting=vig, flat_albedo=0.5,
                               exposure=0.9)
    np.testing.assert_array_equal(part.flats, target.images)
    np.testing.assert_array_equal(target.flats, target.images)
    np.testing.assert_allclose(part.vignetting, vignetting_map(camera, vig))
    assert part.flats.std() > 0  # falloff and vignetting make the flat field uneven


def test_one_automatic_exposure_for_part_and_flats():
    camera = orthographic_camera((30, 30), 1.0)
    lights = ring_point_lights(3, 45.0, 60.0)
    out = render_near_field(make_scene("bumps", 30, 1.0), camera, lights, albedo=1.0, flat_albedo=0.5, peak=0.8)
    assert out.exposure_auto
    assert max(out.images.max(), out.flats.max()) == pytest.approx(0.8, rel=1e-6)
    twice = render_near_field(make_scene("bumps", 30, 1.0), camera, lights, albedo=1.0, flat_albedo=0.5,
                              exposure=2.0 * out.exposure)
    np.testing.assert_allclose(twice.flats, np.minimum(2.0 * out.flats, 1.0), rtol=1e-6)
    assert twice.saturated_fraction > 0 and twice.images.max() == 1.0


def test_noise_and_16_bit_quantisation_statistics():
    camera = orthographic_camera((200, 200), 0.5)
    lights = point_lights([[0.0, 0.0, 300.0]])
    clean = render_near_field(plane(8, 0.1), camera, lights, albedo=0.5, exposure=1.0)
    noisy = render_near_field(plane(8, 0.1), camera, lights, albedo=0.5, exposure=1.0, noise=0.003, seed=4)
    for a, b in ((noisy.images, clean.images), (noisy.flats, clean.flats)):
        assert np.std(a - b) == pytest.approx(0.003, rel=0.03)
        assert abs(np.mean(a - b)) < 3 * 0.003 / 200
    shot = render_near_field(plane(8, 0.1), camera, lights, albedo=0.5, exposure=1.0, shot_noise=1e-4, seed=4)
    assert np.var(shot.images - clean.images) == pytest.approx(1e-4 * clean.images.mean(), rel=0.05)
    q = render_near_field(plane(8, 0.1), camera, lights, albedo=0.5, exposure=1.0, noise=0.003, bit_depth=16, seed=4)
    counts = q.images.astype(np.float64) * 65535
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-3)
    assert np.abs(q.images - noisy.images).max() <= 0.5 / 65535 + 1e-7
    again = render_near_field(plane(8, 0.1), camera, lights, albedo=0.5, exposure=1.0, noise=0.003, seed=4)
    np.testing.assert_array_equal(again.images, noisy.images)


def test_albedo_is_painted_on_the_part():
    """A perspective camera sees the texture where the part is: bilinear on the reference grid, exact at z = 0."""
    camera = perspective_camera((40, 50), 800.0, 200.0)
    rng = np.random.default_rng(0)
    texture = rng.uniform(0.4, 0.9, (40, 50))
    lights = point_lights([[0.0, 0.0, 200.0]])
    out = render_near_field(plane(8, 0.1), camera, lights, albedo=texture, exposure=1.0)
    flat = render_near_field(plane(8, 0.1), camera, lights, albedo=1.0, exposure=1.0)
    np.testing.assert_allclose(out.images[0] / flat.images[0], texture, rtol=1e-6)
    rgb = render_near_field(plane(8, 0.1), orthographic_camera((40, 50), 0.2), point_lights(
        [[0.0, 0.0, 200.0]], intensities=[[1.0, 0.5, 0.25]]), albedo=texture, exposure=1.0)
    assert rgb.images.shape == (1, 40, 50, 3) and rgb.flats.shape == (1, 40, 50, 3)
    np.testing.assert_allclose(rgb.images[0, ..., 1] / rgb.images[0, ..., 0], 0.5, rtol=1e-6)


def test_cast_shadows_towards_the_light_position():
    """A tall bump shadows the pixels on its far side from the LED; a light overhead casts none."""
    hf = make_scene("bumps", 64, 0.1, seed=0)
    from datasets_synthetic.heightfields import gaussian_bumps

    hf = gaussian_bumps(64, 0.1, centers_px=[(32, 32)], amplitudes_mm=[1.5], sigmas_mm=[0.5])
    camera = orthographic_camera(64, 0.1)
    side = point_lights([[40.0, 0.0, 15.0]])  # low, to the right
    out = render_near_field(hf, camera, side, shadows="cast", exposure=1.0)
    attached = render_near_field(hf, camera, side, exposure=1.0)
    shadowed = (out.images[0] == 0) & (attached.images[0] > 0)
    cols = np.nonzero(shadowed[32])[0]
    assert len(cols) > 3 and cols.max() < 32  # on the far (left) side of the bump
    # the fraction counts every point whose segment to the LED meets the surface, lit or facing away
    darkened = np.mean(out.images[0] < attached.images[0])
    assert darkened > 0 and darkened <= out.shadow_fraction[0] <= np.mean(out.images[0] == 0)
    top = render_near_field(hf, camera, point_lights([[0.0, 0.0, 100.0]]), shadows="cast", exposure=1.0)
    assert top.shadow_fraction[0] == 0.0


def test_near_field_folder_layout_and_round_trip(tmp_path):
    scene = make_near_field_folder(tmp_path, scene="inspection_scratch", size=(120, 160), pixel_size=0.15,
                                   lights=4, slant=45.0, light_distance=150.0, led_mu=1.0, noise=0.0,
                                   shadows="attached", albedo=0.7, seed=3)
    names = ["001.png", "002.png", "003.png", "004.png"]
    flats = ["flat_001.png", "flat_002.png", "flat_003.png", "flat_004.png"]
    for name in names + flats + ["filenames.txt", "light_directions.txt", "light_positions.txt",
                                 "light_intensities.txt", "mask.png", "normal_gt.npy", "height_gt.npy",
                                 "xy_gt.npy", "scene.json"]:
        assert (tmp_path / name).is_file(), name
    stored = json.loads((tmp_path / "scene.json").read_text())
    assert stored["lights"]["model"] == "point"
    for key in ("positions_mm", "axes", "mu", "intensities", "d0_mm"):
        assert len(stored["lights"][key]) == 4
    assert stored["camera"] == {"model": "orthographic", "pixel_size_mm": 0.15}
    assert stored["flat_field"] == {"files": flats, "albedo": 0.8}
    assert "vignetting" not in stored and stored["defects"][0]["depth_mm"] == pytest.approx(0.1)
    assert stored["files"]["flat_field"] == flats and stored["pixel_size_mm"] == 0.15
    positions = np.loadtxt(tmp_path / "light_positions.txt")
    np.testing.assert_allclose(positions, ring_point_lights(4, 45.0, 150.0).positions, atol=1e-9)
    np.testing.assert_allclose(stored["lights"]["positions_mm"], positions, atol=1e-9)
    np.testing.assert_allclose(np.loadtxt(tmp_path / "light_directions.txt"), positions / 150.0, atol=1e-9)
    # the far-field reader still reads the folder; flats are extra files
    data = read_folder(tmp_path)
    assert data.names == tuple(names) and data.images.shape == (4, 120, 160)
    np.testing.assert_allclose(data.lights, positions / 150.0, atol=1e-9)
    np.testing.assert_allclose(data.normal_gt, np.load(tmp_path / "normal_gt.npy"), atol=1e-6)
    flat_images = read_images([tmp_path / f for f in flats])
    assert flat_images.shape == (4, 120, 160) and flat_images.min() > 0
    # what was written is the render, to 16 bits
    again = render_near_field(make_scene("inspection_scratch", (120, 160), 0.15), orthographic_camera((120, 160), 0.15),
                              ring_point_lights(4, 45.0, 150.0, mu=1.0), albedo=0.7, bit_depth=16)
    np.testing.assert_allclose(data.images, again.images, atol=1e-6)
    np.testing.assert_allclose(flat_images, again.flats, atol=1e-6)
    xy = np.load(tmp_path / "xy_gt.npy")
    assert xy.shape == (120, 160, 2) and np.load(tmp_path / "height_gt.npy").min() == pytest.approx(-0.1, abs=2e-3)
    assert scene["exposure"] == pytest.approx(again.exposure)
    assert cv2.imread(str(tmp_path / "flat_001.png"), cv2.IMREAD_UNCHANGED).dtype == np.uint16


def test_perspective_folder_with_deviated_leds_and_vignetting(tmp_path):
    scene = make_near_field_folder(tmp_path, scene="sphere", size=64, camera="perspective", focal_length_px=640.0,
                                   camera_height=200.0, lights=3, light_distance=200.0, deviate=[2.0, 0.0, 0.0],
                                   vignetting={"model": "cos4"}, noise=0.003, seed=1)
    stored = json.loads((tmp_path / "scene.json").read_text())
    assert stored["camera"] == {"model": "perspective", "focal_length_px": 640.0, "camera_height_mm": 200.0,
                                "principal_point_px": [31.5, 31.5]}
    assert stored["vignetting"] == {"model": "cos4"} and stored["pixel_size_mm"] == pytest.approx(200.0 / 640.0)
    nominal = np.loadtxt(tmp_path / "light_positions.txt")
    true = np.asarray(stored["lights"]["positions_mm"])
    np.testing.assert_allclose(nominal, ring_point_lights(3, 45.0, 200.0).positions, atol=1e-9)
    assert np.degrees(np.arccos(true[0, 2] / 200.0)) == pytest.approx(47.0)
    assert stored["light_error_deg"][0] == pytest.approx(2.0)
    assert stored["light_error_deg"][1] == pytest.approx(0.0, abs=1e-9)
    hits = intersect(make_scene("sphere", 64, 200.0 / 640.0), perspective_camera(64, 640.0, 200.0))
    np.testing.assert_allclose(np.load(tmp_path / "height_gt.npy"), hits.height)
    np.testing.assert_allclose(np.load(tmp_path / "xy_gt.npy"), hits.xy)
    np.testing.assert_allclose(np.load(tmp_path / "normal_gt.npy"), hits.normals)
    assert scene["saturated_fraction"] == 0.0


def test_write_near_field_folder_of_a_custom_render(tmp_path):
    camera = orthographic_camera((20, 30), 0.5)
    lights = point_lights([[10.0, 0.0, 100.0], [0.0, 10.0, 100.0], [-10.0, -10.0, 100.0]])
    out = render_near_field(plane(8, 0.1), camera, lights, bit_depth=16)
    content = write_near_field_folder(tmp_path, out, {"scene": "mine"})
    assert content["scene"] == "mine" and content["lights"]["d0_mm"][0] == pytest.approx(np.hypot(10, 100))
    with pytest.raises(ValueError, match="nominal"):
        write_near_field_folder(tmp_path, out, {}, nominal=point_lights([[0.0, 0.0, 10.0]]))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"camera": "perspective"}, "focal_length_px and camera_height"),
        ({"camera": "perspective", "focal_length_px": 100.0}, "camera_height"),
        ({"camera": "perspective", "focal_length_px": 100.0, "camera_height": 50.0, "pixel_size": 0.1},
         "pixel_size"),
        ({"focal_length_px": 100.0}, "perspective"),
        ({"camera": "fisheye"}, "camera"),
        ({"slant": 90.0}, "slant_deg"),
        ({"lights": [[0.0, 0.0, 100.0], [10.0, 0.0, 0.0], [0.0, 10.0, 50.0]]}, "not above the reference plane"),
        ({"shadows": "none"}, "shadows"),
        ({"deviate": [1.0, 2.0]}, "deviate"),
        ({"albedo": "paint"}, "albedo"),
        ({"scene": "sphere", "camera": "perspective", "focal_length_px": 4.0, "camera_height": 0.2}, "above the part"),
        ({"vignetting": {"model": "cos4"}}, "perspective"),
        ({"peak": 1.5}, "peak"),
    ],
)
def test_make_near_field_folder_rejects_bad_input(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make_near_field_folder(tmp_path, **{"size": 32, **kwargs})
    assert not (tmp_path / "scene.json").exists()


@pytest.mark.parametrize("tilt", [(0.0, 0.0), (0.05, -0.03)])
def test_cast_shadows_of_a_scratch_stay_in_the_scratch(tilt):
    """Only points below the plate can be shadowed on a scratched plate; a grazing LED shadows the scratch wall."""
    from datasets_synthetic.heightfields import inspection_part

    hf = inspection_part((200, 260), 0.06, defect="scratch", center_mm=(0.0, 0.0), length_mm=6.0, axis_deg=90.0,
                         tilt=tilt)
    camera = orthographic_camera((200, 260), 0.06)
    grazing = point_lights([[150.0, 0.0, 25.0]])  # 80.5 deg slant, across the scratch
    out = render_near_field(hf, camera, grazing, shadows="cast", exposure=1.0)
    attached = render_near_field(hf, camera, grazing, exposure=1.0)
    darkened = out.images[0] < attached.images[0]
    assert darkened.sum() > 50 and np.all(hf.defect_mask[darkened])
    # mirrored LED, mirrored shadow (the untilted scratch is symmetric about its axis x = 0)
    if tilt == (0.0, 0.0):
        mirrored = render_near_field(hf, camera, point_lights([[-150.0, 0.0, 25.0]]), shadows="cast", exposure=1.0)
        other = mirrored.images[0] < render_near_field(hf, camera, point_lights([[-150.0, 0.0, 25.0]]),
                                                       exposure=1.0).images[0]
        np.testing.assert_array_equal(other, darkened[:, ::-1])
    overhead = render_near_field(hf, camera, point_lights([[0.0, 0.0, 200.0]]), shadows="cast", exposure=1.0)
    assert overhead.shadow_fraction[0] == 0.0


@pytest.mark.slow
def test_a_5_mp_4_light_set_renders_well_under_a_minute():
    """Part and flat images of a 2048 x 2448 perspective rig with cast shadows: CPU time, so that other
    processes on the shared machine do not count."""
    import time

    shape = (2048, 2448)
    camera = perspective_camera(shape, 2448 * 300.0 / 60.0, 300.0)
    part = make_scene("inspection_scratch", shape, camera.reference_pixel_mm)
    start = time.process_time()
    out = render_near_field(part, camera, ring_point_lights(4, 45.0, 150.0, mu=1.0), albedo=0.8, shadows="cast",
                            noise=0.003, bit_depth=16)
    assert time.process_time() - start < 30.0
    assert out.images.shape == (4, 2048, 2448) and out.flats.shape == (4, 2048, 2448)
