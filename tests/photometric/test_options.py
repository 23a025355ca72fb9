"""photometric.options and the stages: one options object, checked once; reconstruct composes the stages."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from photometric import stages
from photometric.options import PhotometricOptions, photometric_options, split_keywords
from photometric.pipeline import reconstruct
from photometric.uncertainty import Tolerances
from surfaces.validate import InputError


@pytest.mark.parametrize("bad", [
    {"integrator": "spline"}, {"dark": 0.0}, {"saturation": -1}, {"highlight": np.inf}, {"max_iterations": 0},
    {"max_iterations": 2.5}, {"tolerance_mm": 0}, {"reference_height_mm": np.nan}, {"surface": "nurbs"},
    {"step": 0}, {"samples": -2}, {"surface_tolerance": -1e-3}, {"background": "none"}, {"light_model": "area"},
    {"outliers": "yes"}, {"uncertainty": 0.1},
])
def test_options_refuse_bad_values_when_made(bad):
    with pytest.raises(InputError, match=next(iter(bad))):
        PhotometricOptions(**bad)


def test_options_take_a_tolerance_dict_and_keywords_split():
    opts = PhotometricOptions(uncertainty={"noise_sigma": 0.01})
    assert isinstance(opts.uncertainty, Tolerances) and opts.uncertainty.noise_sigma == 0.01
    read, o = split_keywords({"mask": "m.png", "integrator": "lsq"}, opts)
    assert read == {"mask": "m.png"} and o.integrator == "lsq" and o.uncertainty is opts.uncertainty
    with pytest.raises(TypeError, match="no_such"):
        split_keywords({"no_such": 1})
    with pytest.raises(InputError, match="unknown"):
        photometric_options(mask=None)


def test_uncertainty_dict_takes_the_u_names():
    """``u`` names a standard uncertainty; the older ``tolerance`` names stay working."""
    new = PhotometricOptions(uncertainty={"light_u_deg": 0.3, "light_position_u_mm": 0.2, "intensity_u": 0.01,
                                          "pixel_size_u": 0.002})
    old = PhotometricOptions(uncertainty={"light_tolerance_deg": 0.3, "light_position_tolerance_mm": 0.2,
                                          "intensity_tolerance": 0.01, "pixel_size_tolerance": 0.002})
    assert new.uncertainty == old.uncertainty and new.uncertainty.light_tolerance_deg == 0.3
    with pytest.raises(InputError, match="light_u_deg and light_tolerance_deg"):
        PhotometricOptions(uncertainty={"light_u_deg": 0.3, "light_tolerance_deg": 0.3})


def test_reconstruct_is_the_composition_of_the_stages_in_at_most_60_lines():
    assert len(inspect.getsource(reconstruct).splitlines()) <= 60
    params = inspect.signature(reconstruct).parameters
    assert {"integrator", "rig", "uncertainty", "progress", "out"} <= set(params)
    assert params["max_iterations"].default == PhotometricOptions().max_iterations


def _triad(size=48):
    from datasets_synthetic.heightfields import make_scene
    from photometric.lights import ring_lights
    from photometric.normals import normals_from_slopes

    scene = make_scene("crack", (size, size), pixel_size=0.1)
    L = ring_lights(4, 40.0)
    n = normals_from_slopes(scene.p, scene.q)
    images = np.clip(np.einsum("kc,hwc->khw", L, n), 0, None) * 0.8
    return images.astype(np.float32), L


def test_stages_by_hand_give_reconstruct_s_result():
    """The stages composed by hand, without the surface, give the same arrays and defects."""
    images, L = _triad()
    opts = PhotometricOptions(background="plane")
    inp = stages.read(images, opts, lights=L, pixel_size=0.1)
    sol = stages.solve(inp, opts)
    height = stages.integrate(inp, sol, opts)
    found = stages.measure(inp, sol, height, opts)
    full = reconstruct(images, opts, lights=L, pixel_size=0.1)
    np.testing.assert_array_equal(height.height, full.height)
    assert found.defects and [d["max_depth_mm"] for d in found.defects] == [d["max_depth_mm"] for d in full.defects]
    summary = stages.summarize(inp, sol, height, found, opts)
    assert "mesh" not in summary and summary["n_defects"] == full.summary["n_defects"]
    assert summary["light_condition_number"] == full.summary["light_condition_number"]


def test_uncertainty_stage_needs_no_surface():
    images, L = _triad()
    opts = PhotometricOptions(uncertainty=Tolerances(noise_sigma=0.002, light_tolerance_deg=0.2))
    inp = stages.read(images, opts, lights=L, pixel_size=0.1)
    sol = stages.solve(inp, opts)
    height = stages.integrate(inp, sol, opts)
    found = stages.measure(inp, sol, height, opts)
    assert found.labels is not None
    unc = stages.uncertainty(inp, sol, height, found, opts)
    full = reconstruct(images, opts, lights=L, pixel_size=0.1)
    np.testing.assert_allclose(unc.height_u, full.uncertainty.height_u, rtol=1e-6)
    with pytest.raises(InputError, match="no input uncertainties"):
        stages.uncertainty(inp, sol, height, found, PhotometricOptions())
