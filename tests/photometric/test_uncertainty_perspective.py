"""Linear uncertainty of a perspective (pinhole) near-field rig, against the independent
near-field renderer (datasets_synthetic.nearfield): the stated depth U of a scratch covers
the true error over small random trials (depth, orientation, placement, noise and LED
position errors varied)."""

import dataclasses

import numpy as np
import pytest

from datasets_synthetic.cameras import perspective_camera
from datasets_synthetic.heightfields import u_scratch
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import point_lights, ring_point_lights
from photometric.pipeline import reconstruct

SIZE, PIXEL_MM, CAMERA_MM, LED_U_MM = 96, 0.05, 60.0, 1.0


def _trial(seed: int, plate_mm: float = 0.0):
    """One rendered scratch on a plate at height ``plate_mm``, solved with the nominal LEDs:
    (true depth, measured depth, U, its record, the reconstruction)."""
    rng = np.random.default_rng(seed)
    depth = rng.uniform(0.03, 0.08)
    centre = tuple((SIZE - 1) / 2 + rng.uniform(-8.0, 8.0, 2))
    hf = u_scratch(SIZE, PIXEL_MM, depth_mm=depth, width_mm=0.5, length_mm=2.5, center_px=centre,
                   axis_deg=rng.uniform(0.0, 180.0))
    nominal = ring_point_lights(4, 45.0, 150.0, 90.0, 1.0)
    # the rig's true LEDs are off their nominal places by LED_U_MM (standard) per coordinate
    true = point_lights(nominal.positions + rng.normal(0.0, LED_U_MM, nominal.positions.shape), nominal.axes, 1.0,
                        nominal.intensities)
    f = CAMERA_MM / PIXEL_MM
    surface = dataclasses.replace(hf.surface, plane=(plate_mm, 0.0, 0.0))
    r = render_near_field(surface, perspective_camera(SIZE, f, CAMERA_MM), true, 0.8, noise=rng.uniform(0.001, 0.005),
                          bit_depth=16, seed=int(rng.integers(1 << 30)))
    res = reconstruct(r.images, light_positions=nominal.positions, led_mu=1.0, intensities=nominal.intensities,
                      camera="perspective", focal_length_px=f, camera_height_mm=CAMERA_MM,
                      reference_height_mm=plate_mm, uncertainty={"light_position_tolerance_mm": LED_U_MM})
    assert res.defects, f"seed {seed}: the scratch was not found"
    rec = max(res.defects, key=lambda d: d["max_depth_mm"])
    unc = next(d for d in res.uncertainty.defects if d["id"] == rec["id"])
    return depth, rec["max_depth_mm"], unc["uncertainty_k2"]["max_depth_mm"], unc, res


def test_perspective_point_lights_get_a_linear_budget():
    _, _, U, unc, res = _trial(0)
    assert res.summary["camera"]["model"] == "perspective"
    assert res.uncertainty.summary["method"] == "linear"
    sources = unc["budget"]["max_depth_mm"]["sources"]
    assert {"light_position", "image_noise"} <= set(sources)
    assert 0.0 < U < 0.01
    assert np.all(np.isfinite(res.uncertainty.height_u[res.valid]))


@pytest.mark.parametrize("plate_mm", [0.0, -15.0], ids=["on_the_reference_plane", "15mm_below"])
def test_perspective_depth_interval_covers_the_rendered_scratch(plate_mm):
    """20 trials: a k = 2 interval holds the truth in about 95 % of them (at least 17 of 20).

    15 mm below the reference plane (75 mm from the camera instead of 60) a pixel covers
    1.25 reference pixels: the budget takes the pixels' footprint (with the reference
    pixel it covered 15 of 20)."""
    rows = [_trial(100 + t, plate_mm) for t in range(20)]
    err = np.array([m - d for d, m, _, _, _ in rows])
    U = np.array([u for _, _, u, _, _ in rows])
    covered = int(np.sum(np.abs(err) <= U))
    assert covered >= 17, f"covered {covered}/20; errors {err * 1e3} um, U {U * 1e3} um"
    # not padded: the interval stays a few micrometres on these 30-80 um scratches
    assert np.median(U) < 0.005
    # the spacing the budget used: the pixel's side at the plate, (H_c - z) / f
    assert rows[0][4].uncertainty.summary["pixel_size_mm"] == pytest.approx(
        PIXEL_MM * (CAMERA_MM - plate_mm) / CAMERA_MM, rel=0.01)


def test_distant_lights_with_a_perspective_camera_still_need_monte_carlo():
    from photometric.lights import ring_lights

    L = ring_lights(4, 45.0)
    images = np.full((4, 32, 32), 0.5, np.float32)
    with pytest.raises(ValueError, match="montecarlo"):
        reconstruct(images, lights=L, camera="perspective", focal_length_px=2000.0, camera_height_mm=300.0,
                    uncertainty={"noise_sigma": 0.001})
