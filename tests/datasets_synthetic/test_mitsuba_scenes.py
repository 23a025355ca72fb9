"""The Mitsuba 3 harness against the project's own Lambertian model, OpenCV's lens model and itself."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

pytest.importorskip("mitsuba", reason="Mitsuba 3 (pip install mitsuba) renders these scenes")

from datasets_synthetic.cameras import orthographic_camera, perspective_camera  # noqa: E402
from datasets_synthetic.heightfields import inspection_part, plane  # noqa: E402
from datasets_synthetic.mitsuba_scenes import (  # noqa: E402
    camera_effects,
    distort_image,
    lens_matrix,
    material,
    plate_mesh,
    render_mitsuba,
    write_mitsuba_folder,
    write_ply,
)
from datasets_synthetic.nearfield import render_near_field  # noqa: E402
from datasets_synthetic.point_lights import point_lights  # noqa: E402
from surfaces.validate import InputError  # noqa: E402

SHAPE = (96, 128)


def _cameras():
    return [orthographic_camera(SHAPE, 0.5), perspective_camera(SHAPE, 400.0, 200.0)]


@pytest.mark.parametrize("camera", _cameras(), ids=["orthographic", "perspective"])
@pytest.mark.parametrize("position", [[30.0, 20.0, 60.0], [-200.0, 150.0, 400.0]], ids=["near", "far"])
def test_matte_plate_matches_the_lambertian_model(camera, position):
    """Mitsuba's diffuse plate = rho / pi * the project's point-light shading, per pixel (axes, mm, falloff)."""
    hf = plane(SHAPE, 0.5)
    lights = point_lights([position])
    mine = render_near_field(hf, camera, lights, 0.8, exposure=0.5).images[0]
    r = render_mitsuba(hf, camera, lights, material("diffuse", 0.8), spp=8, exposure=0.5 * np.pi, seed=1)
    ratio = r.images[0] / mine
    dev = np.abs(ratio - 1.0)
    # a pixel's box footprint against its centre, and Mitsuba's rare lost sample on a triangle edge
    assert np.median(dev) < 0.003
    assert np.quantile(dev, 0.999) < 0.02
    assert r.flats is not None and np.quantile(np.abs(r.flats[0] / mine - 1.0), 0.999) < 0.02


def test_disc_led_is_a_cosine_lobe():
    """A small Lambertian disc facing the origin = a point LED with mu = 1 (not mu = 0)."""
    camera = orthographic_camera(SHAPE, 0.5)
    hf = plane(SHAPE, 0.5)
    lights = point_lights([[60.0, -10.0, 40.0]], mu=1.0)
    r = render_mitsuba(hf, camera, lights, material("diffuse", 0.8), led_radius_mm=1.0, spp=16,
                       exposure=0.5 * np.pi, flats=False)
    assert r.lights.mu.tolist() == [1.0]
    lobe = render_near_field(hf, camera, lights, 0.8, exposure=0.5).images[0]
    iso = render_near_field(hf, camera, point_lights(lights.positions), 0.8, exposure=0.5).images[0]
    dev = np.abs(r.images[0] / lobe - 1.0)
    assert np.median(dev) < 0.01
    assert np.max(np.abs(r.images[0] / iso - 1.0)) > 0.1


def test_a_gloss_lobe_of_weight_zero_is_the_matte_plate():
    camera = orthographic_camera(SHAPE, 0.5)
    lights = point_lights([[10.0, 5.0, 80.0]])
    args = dict(spp=4, exposure=1.0, flats=False)
    matte = render_mitsuba(plane(SHAPE, 0.5), camera, lights, material("diffuse", 0.7), **args).images[0]
    none = render_mitsuba(plane(SHAPE, 0.5), camera, lights, material("lambertian_ggx", 0.7, specular=0.0), **args)
    np.testing.assert_allclose(none.images[0], matte, rtol=1e-5)


def test_point_leds_with_a_lobe_are_refused():
    camera = orthographic_camera(SHAPE, 0.5)
    with pytest.raises(InputError, match="isotropic"):
        render_mitsuba(plane(SHAPE, 0.5), camera, point_lights([[0.0, 0.0, 100.0]], mu=2.0))


@pytest.mark.parametrize("kind, specular", [("roughplastic", 1.25), ("lambertian_ggx", 0.3)])
def test_gloss_peaks_at_the_mirror_point(kind, specular):
    """A glossy plate under a point LED above the field: the gloss excess peaks where n is the half vector."""
    camera = orthographic_camera(SHAPE, 0.5)
    hf = plane(SHAPE, 0.5)
    lights = point_lights([[10.0, 5.0, 80.0]])
    matte = render_mitsuba(hf, camera, lights, material("diffuse", 0.8), spp=4, exposure=1.0, flats=False)
    gloss = render_mitsuba(hf, camera, lights, material(kind, 0.8, alpha=0.2, specular=specular), spp=16,
                           exposure=1.0, flats=False)
    excess = gloss.images[0] / matte.images[0]
    row, col = np.unravel_index(np.argmax(excess), SHAPE)
    # orthographic view (0, 0, 1): the half vector is the plate normal right under the LED
    assert abs(row - ((SHAPE[0] - 1) / 2 - 5.0 / 0.5)) <= 3 and abs(col - ((SHAPE[1] - 1) / 2 + 10.0 / 0.5)) <= 3
    # the coat also darkens the base by its Fresnel transmission: compare the peak with the rest
    assert excess.max() > 1.2 * excess.min()


def test_scratch_is_dark_under_grazing_light_and_truth_is_in_mm():
    camera = orthographic_camera(SHAPE, 0.25)
    part = inspection_part(SHAPE, 0.25, "scratch", depth_mm=0.5, width_mm=2.0, length_mm=12.0, center_mm=(0.0, 0.0),
                           axis_deg=90.0)
    lights = point_lights([[-300.0, 0.0, 100.0]])
    r = render_mitsuba(part, camera, lights, spp=4, flats=False)
    assert r.defects[0]["depth_mm"] == 0.5
    np.testing.assert_allclose(r.hits.height, part.height, atol=1e-12)
    # the groove's far wall (x > 0) faces the light at x < 0 and is brighter than the plate; the near one darker
    rows = slice(40, 56)
    col0 = (SHAPE[1] - 1) / 2
    near = r.images[0][rows, int(col0 - 2)].mean()
    far = r.images[0][rows, int(col0 + 3)].mean()
    flat = r.images[0][rows, 10].mean()
    assert near < flat < far


def test_mesh_file_round_trip(tmp_path):
    import trimesh

    part = inspection_part(SHAPE, 0.5, "dent", center_mm=(0.0, 0.0))
    v, n, f = plate_mesh(part, (-10.0, 10.0), (-8.0, 8.0), 0.5)
    path = write_ply(tmp_path / "plate.ply", v, n, f)
    mesh = trimesh.load(path, process=False)
    np.testing.assert_allclose(mesh.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(mesh.faces, f)
    # faces are counter-clockwise seen from +z: their normals agree with the surface's
    assert np.all(mesh.face_normals[:, 2] > 0.5)
    assert abs(float(v[:, 2].min()) + part.defects[0]["depth_mm"]) < 0.01


def test_distortion_moves_points_where_opencv_projects_them():
    camera = perspective_camera((120, 160), 200.0, 200.0)
    K = lens_matrix(camera)
    d = np.array([-0.2, 0.05, 0.002, -0.001, 0.0])
    rows, cols = np.mgrid[0:120, 0:160].astype(float)
    u0, v0 = 140.0, 20.0  # an ideal spot near a corner
    spot = np.exp(-((cols - u0) ** 2 + (rows - v0) ** 2) / (2 * 1.5**2))
    out = distort_image(spot, K, d)
    import cv2

    ray = np.array([[(u0 - K[0, 2]) / K[0, 0], (v0 - K[1, 2]) / K[1, 1], 1.0]])
    (u1, v1), = cv2.projectPoints(ray, np.zeros(3), np.zeros(3), K, d)[0][:, 0, :]
    w = out / out.sum()
    assert abs(float((w * cols).sum()) - u1) < 0.05 and abs(float((w * rows).sum()) - v1) < 0.05
    assert np.hypot(u1 - u0, v1 - v0) > 1.5  # the test would see a missing distortion


def test_sensor_noise_and_quantisation():
    camera = orthographic_camera((64, 64), 0.1)
    img = np.full((2, 64, 64), 0.4)
    out = camera_effects(img, camera, 3, shot_noise=1e-3, read_noise=2e-3, bit_depth=12)
    levels = out * 4095.0
    np.testing.assert_allclose(levels, np.round(levels), atol=1e-3)
    var = 1e-3 * 0.4 + 2e-3**2 + 1.0 / (12 * 4095.0**2)
    assert abs(float(out.var()) / var - 1.0) < 0.1
    assert abs(float(out.mean()) - 0.4) < 1e-3
    vig = camera_effects(np.full((64, 64), 0.5), camera, vignetting={"model": "radial", "coefficients": [-0.3]},
                         bit_depth=None)
    assert vig[32, 32] > 0.49 and vig[0, 0] < 0.36
    with pytest.raises(InputError, match="distortion"):
        camera_effects(img, camera, distortion={"k9": 1.0})


def test_folder_reads_as_a_near_field_capture(tmp_path):
    from photometric.io import read_folder

    camera = orthographic_camera((64, 64), 0.5)
    lights = point_lights([[100.0, 0.0, 100.0], [-50.0, 86.6, 100.0], [-50.0, -86.6, 100.0]])
    r = render_mitsuba(plane((64, 64), 0.5), camera, lights, spp=2, effects={"bit_depth": 12, "read_noise": 1e-3})
    scene = write_mitsuba_folder(tmp_path / "set", r)
    assert scene["renderer"]["spp"] == 2 and scene["shadow_fraction"] is None
    json.loads((tmp_path / "set" / "scene.json").read_text())
    data = read_folder(tmp_path / "set")
    np.testing.assert_allclose(np.asarray(data.images, float), r.images, atol=1.0 / 65535)


def test_path_tracing_adds_light_only_where_the_surface_sees_itself():
    camera = orthographic_camera((64, 64), 0.25)
    part = inspection_part((64, 64), 0.25, "crack", depth_mm=2.0, width_mm=4.0, length_mm=12.0, center_mm=(0.0, 0.0),
                           axis_deg=90.0)
    lights = point_lights([[0.0, 0.0, 100.0]])
    args = dict(spp=32, exposure=1.0, flats=False, seed=2)
    direct = render_mitsuba(part, camera, lights, integrator="direct", **args).images[0]
    path = render_mitsuba(part, camera, lights, integrator="path", max_depth=3, **args).images[0]
    inside = part.defect_mask
    flat = ~binary_dilation(inside, iterations=3)
    assert np.median(np.abs(path[flat] / direct[flat] - 1.0)) < 0.01
    assert np.median(path[inside] / direct[inside]) > 1.05
