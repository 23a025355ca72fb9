"""photometric.nearfield against the independent near-field renderer of datasets_synthetic.

The renderer (datasets_synthetic.nearfield) writes its own forward model of the shared
rig contract: it intersects each pixel's ray with the closed-form scene, lights the seen
point with inverse-square falloff and the LED lobe, and adds sensor noise and 16-bit
quantisation. Here the solver must find that scene again: planes, a sphere cap, the
issue's scratched plate, orthographic and perspective, with a flat field instead of a
known LED lobe, and the far-field model shown to fail on the same images.
"""

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera, perspective_camera
from datasets_synthetic.heightfields import inspection_part, make_scene, sphere_cap
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import ring_point_lights
from photometric.camera import make_camera
from photometric.defects import measure_defects
from photometric.leds import point_lights
from photometric.nearfield import solve_nearfield
from photometric.normals import angular_error_deg
from photometric.rig import flat_field_gains


def _cameras(shape, pixel_mm, camera_height=300.0):
    """The renderer's camera and the solver's, built from the same numbers."""
    if camera_height is None:
        return orthographic_camera(shape, pixel_mm), make_camera("orthographic", pixel_size_mm=pixel_mm)
    f = camera_height / pixel_mm
    return (perspective_camera(shape, f, camera_height),
            make_camera("perspective", focal_length_px=f, camera_height_mm=camera_height))


def _render(surface, render_cam, n=4, distance=150.0, mu=1.0, noise=0.003, **kw):
    lights = ring_point_lights(n, 45.0, distance, 90.0, mu, kw.pop("intensities", None))
    return render_near_field(surface, render_cam, lights, kw.pop("albedo", 0.8), noise=noise, bit_depth=16,
                             seed=kw.pop("seed", 3), **kw)


def _background_rms(height, truth, use):
    """RMS of the height error on ``use`` after removing its best-fit plane (mm)."""
    rows, cols = np.nonzero(use)
    err = (height - truth)[use]
    A = np.stack([np.ones_like(err), rows, cols], axis=1).astype(float)
    coef, *_ = np.linalg.lstsq(A, err, rcond=None)
    return float(np.sqrt(np.mean((err - A @ coef) ** 2)))


@pytest.mark.parametrize("camera_height", [None, 300.0], ids=["orthographic", "perspective"])
def test_tilted_plane_recovered(camera_height):
    shape, px = (96, 128), 0.4
    rcam, cam = _cameras(shape, px, camera_height)
    scene = make_scene("tilted", shape, px)  # z = 0.1 x + 0.05 y
    r = _render(scene, rcam)
    res = solve_nearfield(r.images, point_lights(r.lights.positions, mu=1.0), cam, intensities=r.lights.intensities)
    truth = r.hits.height
    assert res.valid.all()
    assert res.depth_change_mm < 1e-3
    assert _background_rms(res.height, truth, res.valid) < 5e-3
    # the anchor: median height on the reference plane, as for the truth (a plane through the origin)
    assert abs(np.median(res.height) - np.median(truth)) < 5e-3
    assert np.sqrt(np.mean((res.height - truth) ** 2)) < 0.02
    assert np.sqrt(np.mean(np.sum((res.xy - r.hits.points[..., :2]) ** 2, axis=-1))) < 0.01
    assert angular_error_deg(res.normals, r.hits.normals).mean() < 0.5


@pytest.mark.parametrize("camera_height", [None, 250.0], ids=["orthographic", "perspective"])
def test_sphere_cap_recovered(camera_height):
    shape, px = (128, 128), 0.3
    rcam, cam = _cameras(shape, px, camera_height)
    cap = sphere_cap(shape, px, radius_mm=15.0, height_mm=3.0)
    r = _render(cap, rcam, distance=200.0, mu=0.0)
    res = solve_nearfield(r.images, point_lights(r.lights.positions, mu=0.0), cam, intensities=r.lights.intensities,
                          reference_height_mm=0.0)
    truth = r.hits.height
    err = angular_error_deg(res.normals, r.hits.normals)
    assert err[res.valid].mean() < 0.5
    # the cap covers less than half the field, so the median anchor puts the base on z = 0
    height_err = (res.height - truth)[res.valid]
    assert np.sqrt(np.mean(height_err**2)) < 0.03
    assert abs(float(np.nanmax(res.height)) - 3.0) < 0.05
    far = solve_nearfield(r.images, r.lights.directions, cam, intensities=r.lights.intensities)
    assert np.sqrt(np.nanmean((far.height - truth) ** 2)) > 10 * np.sqrt(np.mean(height_err**2))


def _scratch_plate(shape, px, camera_height, **kw):
    """The issue's 0.10 mm deep, 12 mm long scratch, centred so that a 15 mm field holds it."""
    rcam, cam = _cameras(shape, px, camera_height)
    part = inspection_part(shape, px, "scratch", center_mm=(0.0, 0.0))
    return part, rcam, cam, _render(part, rcam, **kw)


@pytest.mark.parametrize("camera_height", [None, 300.0], ids=["orthographic", "perspective"])
def test_scratch_plate_depth_and_length(camera_height):
    shape, px = (256, 256), 60.0 / 1024
    part, rcam, cam, r = _scratch_plate(shape, px, camera_height, n=3)
    res = solve_nearfield(r.images, point_lights(r.lights.positions, mu=1.0), cam, intensities=r.lights.intensities)
    truth = r.hits.height
    assert _background_rms(res.height, truth, res.valid & ~r.hits.inside) < 5e-3
    on_points = {} if camera_height is None else {"xy": res.xy, "area": res.footprint_mm2}
    found = measure_defects(res.height, px, res.valid, background="plane", p=res.p, q=res.q, **on_points)
    assert len(found) >= 1
    scratch = found[0]
    truth_rec = part.defects[0]
    assert scratch["max_depth_mm"] == pytest.approx(truth_rec["depth_mm"], rel=0.05)
    assert scratch["length_mm"] == pytest.approx(truth_rec["length_mm"], rel=0.02)


def test_far_field_model_finds_a_bowl_not_the_scratch():
    shape, px = (256, 256), 60.0 / 1024
    part, rcam, cam, r = _scratch_plate(shape, px, None, n=3)
    far = solve_nearfield(r.images, r.lights.directions, cam, intensities=r.lights.intensities)
    truth = r.hits.height
    assert _background_rms(far.height, truth, far.valid & ~r.hits.inside) > 0.02
    near = solve_nearfield(r.images, point_lights(r.lights.positions, mu=1.0), cam,
                           intensities=r.lights.intensities)
    assert (_background_rms(far.height, truth, far.valid & ~r.hits.inside)
            > 20 * _background_rms(near.height, truth, near.valid & ~r.hits.inside))


@pytest.mark.parametrize("camera_height", [None, 300.0], ids=["orthographic", "perspective"])
def test_flat_field_replaces_an_unknown_lobe_vignetting_and_power(camera_height):
    """Rendered with mu = 2, unequal LED power and vignetting; solved with the positions and
    the rendered flat fields only (mu unknown, intensities not given)."""
    shape, px = (256, 256), 60.0 / 1024
    vignetting = {"model": "radial", "coefficients": [-0.25]}
    part, rcam, cam, r = _scratch_plate(shape, px, camera_height, n=4, mu=2.0, intensities=[1.0, 0.7, 1.3, 0.9],
                                        vignetting=vignetting)
    lights = point_lights(r.lights.positions)  # mu unknown
    gains = flat_field_gains(r.flats, lights, cam, r.flat_albedo)
    res = solve_nearfield(r.images, lights, cam, gains=gains)
    truth = r.hits.height
    background = res.valid & ~r.hits.inside
    rms = _background_rms(res.height, truth, background)
    assert rms < 5e-3
    # the albedo comes out relative to the flat target's: the part's 0.8 (one exposure for both)
    assert np.median(res.albedo[background]) == pytest.approx(0.8, rel=0.01)
    # without the flat field and without mu the same images give a worse surface
    bare = solve_nearfield(r.images, lights, cam)
    assert _background_rms(bare.height, truth, bare.valid & ~r.hits.inside) > 3 * rms


@pytest.mark.parametrize("camera_height", [None, 300.0], ids=["orthographic", "perspective"])
def test_issue_plate_60mm(camera_height):
    """The issue's rig: a 60 mm plate, three LEDs 150 mm away at 45 deg, the scratch at (3, -2) mm."""
    shape, px = (1024, 1024), 60.0 / 1024
    rcam, cam = _cameras(shape, px, camera_height)
    part = inspection_part(shape, px, "scratch")
    r = _render(part, rcam, n=3, mu=1.0)
    res = solve_nearfield(r.images, point_lights(r.lights.positions, mu=1.0), cam, intensities=r.lights.intensities)
    assert _background_rms(res.height, r.hits.height, res.valid & ~r.hits.inside) < 5e-3
    on_points = {} if camera_height is None else {"xy": res.xy, "area": res.footprint_mm2}
    found = measure_defects(res.height, px, res.valid, background="plane", p=res.p, q=res.q, **on_points)
    assert found[0]["max_depth_mm"] == pytest.approx(0.10, rel=0.05)
    assert found[0]["length_mm"] == pytest.approx(12.0, rel=0.02)


def test_outlier_mode_drops_cast_and_attached_shadows():
    """A tall cap under six low LEDs: shadowed observations bend the plain solve; the outlier
    mode drops them per pixel and re-solves from the rest."""
    shape, px = (128, 128), 0.3
    rcam, cam = _cameras(shape, px, None)
    cap = sphere_cap(shape, px, radius_mm=15.0, height_mm=9.0)
    lights = ring_point_lights(6, 55.0, 150.0, 90.0, 1.0)
    r = render_near_field(cap, rcam, lights, 0.8, shadows="cast", noise=0.003, bit_depth=16)
    assert r.shadow_fraction.max() > 0.01
    pl = point_lights(lights.positions, mu=1.0)
    plain = solve_nearfield(r.images, pl, cam)
    robust = solve_nearfield(r.images, pl, cam, outliers=True)
    err_plain = angular_error_deg(plain.normals, r.hits.normals).mean()
    err_robust = angular_error_deg(robust.normals, r.hits.normals)[robust.valid].mean()
    assert err_robust < 0.5 < 5.0 < err_plain
    assert robust.valid.mean() > 0.99 and robust.outliers.any()
    height_err = (robust.height - r.hits.height)[robust.valid]
    assert np.sqrt(np.mean(height_err**2)) < 0.1


def test_distant_lights_with_a_perspective_lens():
    """LEDs 100 m away are distant lights; the perspective camera still needs the log-depth
    integration: one far-field solve, heights and x, y of each pixel's point."""
    shape, px = (128, 128), 0.3
    rcam, cam = _cameras(shape, px, 120.0)  # a short lens: the field is wide for the distance
    cap = sphere_cap(shape, px, radius_mm=15.0, height_mm=3.0)
    r = _render(cap, rcam, distance=1e5, mu=0.0)
    res = solve_nearfield(r.images, r.lights.directions, cam)
    assert res.iterations == 1 and res.depth_change_mm is None
    assert angular_error_deg(res.normals, r.hits.normals)[res.valid].mean() < 0.5
    rmse = np.sqrt(np.mean((res.height - r.hits.height)[res.valid] ** 2))
    assert rmse < 0.01
    assert np.sqrt(np.mean(np.sum((res.xy - r.hits.points[..., :2]) ** 2, axis=-1))) < 0.005
    # the same normals integrated as if the lens were telecentric: the cap comes out too low
    flat = solve_nearfield(r.images, r.lights.directions, make_camera("orthographic", pixel_size_mm=px))
    assert np.sqrt(np.mean((flat.height - r.hits.height)[flat.valid] ** 2)) > 3 * rmse


@pytest.mark.parametrize("outliers", [False, True])
def test_partial_resolve_matches_whole_passes(monkeypatch, outliers):
    """Later passes re-solve only the pixels whose height moved; forcing whole-image passes gives
    the same surface, normals, albedo (colour), residual and outliers."""
    import photometric.nearfield as nf

    shape, px = (128, 128), 0.3
    rcam, cam = _cameras(shape, px, 250.0)
    cap = sphere_cap(shape, px, radius_mm=15.0, height_mm=6.0)
    lights = ring_point_lights(6, 50.0, 150.0, 90.0, 1.0)
    rgb = np.stack([np.full(shape, 0.8), np.full(shape, 0.6), np.full(shape, 0.4)], axis=-1)
    r = render_near_field(cap, rcam, lights, rgb, shadows="cast", noise=0.003, bit_depth=16)
    pl = point_lights(lights.positions, mu=1.0)
    part = solve_nearfield(r.images, pl, cam, outliers=outliers)
    assert part.iterations >= 2 and part.history[-1]["resolved_fraction"] < 0.5
    monkeypatch.setattr(nf, "RESOLVE_FRACTION", -1.0)  # every pixel counts as moved: whole passes
    whole = solve_nearfield(r.images, pl, cam, outliers=outliers)
    assert all(h["resolved_fraction"] == 1.0 for h in whole.history)
    assert np.nanmax(np.abs(part.height - whole.height)) < 1e-3
    assert angular_error_deg(part.normals, whole.normals).max() < 0.05
    np.testing.assert_allclose(part.albedo, whole.albedo, atol=1e-3)
    np.testing.assert_allclose(part.residual, whole.residual, atol=1e-4)
    np.testing.assert_array_equal(part.valid, whole.valid)
    if outliers:
        assert part.outliers.any() and (part.outliers != whole.outliers).mean() < 1e-3
