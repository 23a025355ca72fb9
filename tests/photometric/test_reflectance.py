"""``reflectance="glossy"`` in the near-field solve and the ``quality`` of summary.json (issue 32)."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.cameras import orthographic_camera
from datasets_synthetic.heightfields import plane
from datasets_synthetic.nearfield import render_near_field
from datasets_synthetic.point_lights import ring_point_lights
from photometric.glossy import lobe_weight
from photometric.leds import light_field, point_lights
from photometric.options import PhotometricOptions
from photometric.pipeline import reconstruct
from surfaces.validate import InputError

SIZE, PIXEL_MM = 96, 0.5


def _run(images, rig, **kw):
    return reconstruct(images, lights=rig.directions, light_positions=rig.positions, led_mu=rig.mu,
                       camera="orthographic", pixel_size=PIXEL_MM, flat_field=False, surface="coons", **kw)


def test_options_check_the_reflectance():
    assert PhotometricOptions().reflectance is None
    with pytest.raises(InputError, match="reflectance"):
        PhotometricOptions(reflectance="phong")
    with pytest.raises(InputError, match="gloss_alpha"):
        PhotometricOptions(gloss_alpha=1.5)
    with pytest.raises(InputError, match="gloss_weight"):
        PhotometricOptions(gloss_weight=-0.1)


def test_summary_states_the_quality_of_a_matte_solve():
    rig = ring_point_lights(6, 45.0, 150.0, 90.0, 0.0)
    r = render_near_field(plane((SIZE, SIZE), PIXEL_MM), orthographic_camera((SIZE, SIZE), PIXEL_MM), rig, 0.7,
                          noise=0.002, bit_depth=16)
    res = _run(r.images, rig)
    q = res.summary["quality"]
    assert q["trusted"] and q["failed"] == [] and q["limits_source"] == "default"
    assert 0 < q["figures"]["background_rms_mm"] < 1e-3 and res.summary["reflectance"] == {"model": "lambertian"}
    # the limits are the caller's to tighten: a 0.1 um background limit fails this render with its reason
    from photometric import stages
    from photometric.options import photometric_options

    opts = photometric_options()
    inp = stages.read(r.images, opts, lights=rig.directions, light_positions=rig.positions, led_mu=rig.mu,
                      camera="orthographic", pixel_size=PIXEL_MM, flat_field=False)
    sol = stages.solve(inp, opts)
    h = stages.integrate(inp, sol, opts)
    d = stages.measure(inp, sol, h, opts)
    tight = stages.quality(inp, sol, h, d, opts, limits={"background_rms_mm": 1e-4}, reference_slopes=(0.0, 0.0))
    assert not tight["trusted"] and tight["failed"][0]["figure"] == "background_rms_mm"
    assert tight["limits_source"] == "option" and tight["figures"]["slope_bias_mrad"][2] < 1.0
    with pytest.raises(InputError, match="gloss-alpha"):
        _run(r.images, rig, reflectance="glossy")
    with pytest.raises(InputError, match="at least 4 lights"):
        three = ring_point_lights(3, 45.0, 150.0, 90.0, 0.0)
        _run(r.images[:3], three, reflectance="glossy", gloss_alpha=0.3, gloss_weight=0.3)


@pytest.mark.slow
def test_glossy_reflectance_flattens_a_mitsuba_rough_plastic_plate():
    """8 LEDs, Mitsuba 3 roughplastic (alpha 0.3, specular 0.3): the Lambertian solve bends the plate and its
    quality says so; the glossy model with the lobe weight of a reference plate brings it within 5 um."""
    pytest.importorskip("mitsuba", reason="Mitsuba 3 renders the glossy plate")
    from datasets_synthetic.mitsuba_scenes import material, render_mitsuba

    rig = ring_point_lights(8, 45.0, 200.0, 90.0, 0.0)
    cam = orthographic_camera((SIZE, SIZE), PIXEL_MM)
    bsdf = material("roughplastic", 0.7, alpha=0.3, specular=0.3)
    fx = {"read_noise": 0.002, "bit_depth": 12}
    ref = render_mitsuba(plane((SIZE, SIZE), PIXEL_MM), cam, rig, bsdf, spp=8, flats=False, effects=fx, seed=1)
    s = light_field(point_lights(ref.lights.positions, mu=ref.lights.mu), ref.hits.points)
    c = lobe_weight(ref.images, s, ref.hits.normals, (0.0, 0.0, 1.0), 0.3)
    part = render_mitsuba(plane((SIZE, SIZE), PIXEL_MM), cam, rig, bsdf, spp=8, flats=False, effects=fx, seed=2)
    lam = _run(part.images, rig)
    gl = _run(part.images, rig, reflectance="glossy", gloss_alpha=0.3, gloss_weight=c)
    bl = lam.summary["quality"]["figures"]["background_rms_mm"]
    bg = gl.summary["quality"]["figures"]["background_rms_mm"]
    assert not lam.summary["quality"]["trusted"] and bl > 0.02
    assert gl.summary["quality"]["trusted"] and bg < 0.005 and bg < bl / 5
    assert gl.summary["reflectance"] == {"model": "glossy", "alpha": 0.3, "weight": c, "source": "option"}
    # against truth too (the plate is level: z = 0), not only the solver's own figure
    z = gl.height[gl.valid]
    A = np.c_[gl.xy[gl.valid], np.ones(z.size)]
    resid = z - A @ np.linalg.lstsq(A, z, rcond=None)[0]
    assert np.sqrt(np.mean(resid ** 2)) < 0.005
