"""photometric.pipeline.reconstruct with ``out=`` arrays: the bounded-memory path gives the same result.

The streamed path solves in blocks of rows, hands the normals and albedo to the
caller's arrays, drops the image stack and integrates in float32 in place. Against
the whole-image solve and a float64 DCT integration of the same slopes, the normals,
albedo, slopes and validity are identical and the height differs by float32 rounding
only. Measured against main before the change (``reconstruct_to_folder``, every file
compared): a rendered 200 px scratch scene, height 9.5e-9 mm of a 0.034 mm range
(2.8e-7); DiLiGenT bear (triad), 1.3e-5 mm of a 68.5 mm range (1.9e-7); every other
array identical, the previews identical but one height-map pixel.
"""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.integrate import integrate
from photometric.pipeline import reconstruct


def _streamed(source, **options):
    arrays = {}

    def out(name, shape, dtype):
        arrays[name] = np.full(shape, np.nan, dtype)
        return arrays[name]

    return reconstruct(source, out=out, **options), arrays


def _check_same(source, rel_height: float, **options):
    res, arrays = _streamed(source, **options)
    whole = reconstruct(source, **options)
    assert res.normals is None and res.albedo is None
    assert np.array_equal(arrays["normals"], whole.normals)
    assert np.array_equal(arrays["albedo"], whole.albedo)
    for name in ("p", "q", "valid", "mask"):
        assert np.array_equal(getattr(res, name), getattr(whole, name)), name
    assert res.height.dtype == np.float32
    h = res.summary["pixel_size_mm"]
    ref = integrate(res.p, res.q, options.get("integrator", "dct"), mask=res.valid, pixel_size=h)
    assert ref.dtype == np.float64
    assert np.array_equal(np.isnan(res.height), np.isnan(ref))
    span = np.nanmax(ref) - np.nanmin(ref)
    worst = np.nanmax(np.abs(res.height - ref))
    assert worst <= rel_height * span, (worst, span)
    for key in ("valid_pixels", "invalid_fraction", "mean_residual", "n_defects", "patches"):
        assert res.summary[key] == whole.summary[key], key
    return worst / span


def test_streamed_matches_whole_image_on_a_rendered_scene(tmp_path):
    make_triad_folder(tmp_path / "in", scene="scratch", size=160, noise=0.002, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.05, seed=2)
    assert _check_same(tmp_path / "in", 1e-6) > 0  # float32 rounding, not the float64 solve itself


def test_streamed_matches_whole_image_on_diligent_bear(shared_data):
    _check_same(shared_data / "diligent_bear", 1e-6, select="triad")


@pytest.mark.parametrize("integrator", ["fc", "lsq"])
def test_streamed_other_integrators_round_to_float32(tmp_path, integrator):
    make_triad_folder(tmp_path / "in", scene="dent", size=64, noise=0.0, shadows="none", deviate=None,
                      albedo=0.8, pixel_size=0.1, seed=1)
    _check_same(tmp_path / "in", 1e-6, integrator=integrator)


def test_streamed_ground_truth_and_outliers(tmp_path):
    """The angular error against ground truth is gathered block by block; outlier mode per block."""
    make_triad_folder(tmp_path / "in", scene="bumps", size=96, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.1, seed=3)
    res, arrays = _streamed(tmp_path / "in", outliers=True)
    whole = reconstruct(tmp_path / "in", outliers=True)
    assert np.array_equal(arrays["normals"], whole.normals)
    for key in ("mean_angular_error_deg", "median_angular_error_deg"):
        assert res.summary[key] == whole.summary[key]


def test_out_with_uncertainty_gets_one_block(tmp_path):
    make_triad_folder(tmp_path / "in", scene="plate", size=48, noise=0.0, shadows="none", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    res, arrays = _streamed(tmp_path / "in", uncertainty={"noise_sigma": 0.002})
    whole = reconstruct(tmp_path / "in")
    assert res.normals is None and res.uncertainty is not None
    assert np.array_equal(arrays["normals"], whole.normals)
    assert np.array_equal(arrays["albedo"], whole.albedo)
