"""ISO 25178-2 texture parameters: closed forms, the surfalize peer, filters, and the photometric path."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import ndimage

from datasets_synthetic.render import render
from datasets_synthetic.textures import textured_plate
from photometric.integrate import integrate
from photometric.lights import ring_lights
from photometric.stereo import solve
from photometric.texture import (
    UNITS,
    autocorrelation,
    gaussian_filter,
    integrator_transfer,
    parameters,
    remove_form,
    texture,
)
from photometric.uncertainty.slopes import slope_noise_covariance
from surfaces.validate import InputError

SHARED = ["Sa", "Sq", "Sp", "Sv", "Sz", "Ssk", "Sku", "Sdq", "Sdr", "Sal", "Str", "Sk", "Spk", "Svk", "Smr1",
          "Smr2", "Vmp", "Vmc", "Vvc", "Vvv"]


def _random_field(shape, corr_px, sq_mm, seed):
    f = ndimage.gaussian_filter(np.random.default_rng(seed).standard_normal(shape), corr_px, mode="wrap")
    return f / f.std() * sq_mm


# ------------------------------------------------------------------------------------------------ closed forms
@pytest.mark.parametrize("amplitude_um", [0.5, 2.0])
def test_sinusoid_closed_forms(amplitude_um):
    # two whole periods of 2500 px: the sampled mean of |sin| is 2 / pi within 3e-7
    n, periods = 5000, 2
    x = np.arange(n) + 0.5
    z = amplitude_um * np.sin(2 * np.pi * periods * x / n)[None, :].repeat(8, axis=0)
    v, _ = parameters(z, 0.001)
    A = amplitude_um
    assert v["Sq"] == pytest.approx(A / math.sqrt(2), rel=1e-6)
    assert v["Sa"] == pytest.approx(2 * A / math.pi, rel=1e-6)
    assert abs(v["Ssk"]) < 1e-6
    assert v["Sku"] == pytest.approx(1.5, rel=1e-6)
    assert v["Sp"] == pytest.approx(A, rel=1e-6) and v["Sv"] == pytest.approx(A, rel=1e-6)


def test_gaussian_random_surface():
    z = _random_field((512, 512), 2.0, 1.0, seed=3)
    v, _ = parameters(z, 0.001)
    assert abs(v["Ssk"]) < 0.05
    assert v["Sku"] == pytest.approx(3.0, abs=0.1)
    # a Gaussian height distribution: Sa / Sq = sqrt(2 / pi)
    assert v["Sa"] / v["Sq"] == pytest.approx(math.sqrt(2 / math.pi), rel=0.01)


def test_material_ratio_of_a_uniform_distribution():
    # heights uniform in [-1, 1] um: the material ratio curve is a straight line, Sk = 2, Spk = Svk = 0-ish,
    # Smr(0) = 50 %, Vmp = p^2 / 2 * slope ...: Vm(p) = integral of mr over the peak zone = 2 p^2 / 2 / 100^2
    z = np.linspace(-1.0, 1.0, 64 * 64).reshape(64, 64)
    z = np.random.default_rng(0).permutation(z.ravel()).reshape(64, 64)
    v, _ = parameters(z, 0.001)
    assert v["Sk"] == pytest.approx(2.0, rel=1e-3)
    assert v["Smr"] == pytest.approx(50.0, abs=0.05)
    assert v["Vmp"] == pytest.approx(0.1**2, rel=2e-3)  # 2 um * (0.1)^2 / 2
    assert v["Vvv"] == pytest.approx(2.0 * 0.2**2 / 2, rel=2e-3)
    assert v["Vmc"] == pytest.approx(2.0 * (0.8**2 - 0.1**2) / 2, rel=2e-3)


def test_sdr_and_sdq_of_a_tilted_plane():
    # a plane of slope g: Sdq = g, Sdr = 100 (sqrt(1 + g^2) - 1)
    y, x = np.mgrid[:40, :50]
    g = 0.2
    v, _ = parameters(g * x * 1.0, 0.001)  # um per um pixel
    assert v["Sdq"] == pytest.approx(g, rel=1e-6)
    assert v["Sdr"] == pytest.approx(100 * (math.sqrt(1 + g * g) - 1), rel=1e-5)


# ------------------------------------------------------------------------------------------------ filters, form
def test_form_removal_is_exact():
    y, x = np.mgrid[:40, :60] * 0.01
    plane = 0.3 * x - 0.2 * y + 1.0
    quad = plane + 0.05 * x * x - 0.02 * x * y + 0.03 * y * y
    assert np.abs(remove_form(plane, form="plane")).max() < 1e-12
    assert np.abs(remove_form(quad, form="poly2")).max() < 1e-12
    assert np.abs(remove_form(quad, form="plane")).max() > 1e-3
    mask = np.ones(quad.shape, bool)
    mask[10:20, 10:30] = False
    r = remove_form(quad, mask, form="poly2")
    assert np.isnan(r[15, 15]) and np.nanmax(np.abs(r)) < 1e-12


@pytest.mark.parametrize("cutoff", [0.08, 0.25])
def test_gaussian_transmission_is_half_at_the_cutoff(cutoff):
    d = 0.002
    x = np.arange(2000) * d
    z = np.sin(2 * np.pi * x / cutoff)[None, :].repeat(8, axis=0)
    lo = gaussian_filter(z, d, cutoff)
    inner = slice(500, 1500)
    assert np.abs(lo[:, inner]).max() == pytest.approx(0.5, abs=2e-3)
    # and the kernel is the ISO one: a wavelength of 2 lambda_c passes exp(-pi alpha^2 / 4) = 2^(-1/4)
    z2 = np.sin(2 * np.pi * x / (2 * cutoff))[None, :].repeat(8, axis=0)
    assert np.abs(gaussian_filter(z2, d, cutoff)[:, inner]).max() == pytest.approx(2 ** -0.25, abs=2e-3)


def test_normalised_convolution_ignores_invalid_pixels():
    z = _random_field((200, 200), 3.0, 1.0, seed=1)
    mask = np.ones(z.shape, bool)
    mask[80:120, 80:120] = False
    spoilt = z.copy()
    spoilt[~mask] = 1e6  # values under the mask must carry no weight
    lo = gaussian_filter(spoilt, 0.01, 0.1, mask=mask)
    assert np.isnan(lo[100, 100])
    assert np.nanmax(np.abs(lo)) < 5.0
    full = gaussian_filter(z, 0.01, 0.1)
    # far from the hole (beyond the kernel) the result is the unmasked one
    far = np.zeros(z.shape, bool)
    far[:40, :] = True
    assert np.abs(lo[far] - full[far]).max() < 1e-5


def test_integrator_transfer_matches_the_integrators():
    n = 256
    for lam in (6, 12, 32):
        w = 2 * np.pi / lam
        r = np.arange(n)
        z = np.sin(w * r)[None, :].repeat(n, axis=0)
        p = (w * np.cos(w * r))[None, :].repeat(n, axis=0)
        for method in ("dct", "lsq"):
            zz = integrate(p, np.zeros_like(p), method)
            ratio = zz[64:192, 64:192].std() / z[64:192, 64:192].std()
            assert ratio == pytest.approx(float(integrator_transfer(w, 0.0)), rel=2e-3)


def test_autocorrelation_is_the_direct_sum():
    z = np.random.default_rng(2).standard_normal((24, 30))
    acf, (cy, cx) = autocorrelation(z)
    for ty, tx in [(0, 0), (3, -5), (-7, 2), (12, 15)]:
        a = z[max(0, -ty): 24 - max(0, ty), max(0, -tx): 30 - max(0, tx)]
        b = z[max(0, ty): 24 + min(0, ty), max(0, tx): 30 + min(0, tx)]
        assert acf[cy + ty, cx + tx] == pytest.approx(np.mean(a * b), rel=1e-4, abs=1e-5)


# ------------------------------------------------------------------------------------------------ surfalize
def _surfalize(height_mm, d_mm, s_mm, l_mm, band):
    surfalize = pytest.importorskip("surfalize")
    from surfalize.filter import GaussianFilter

    s = surfalize.Surface(height_mm * 1000, d_mm * 1000, d_mm * 1000).level()
    s = GaussianFilter(s_mm * 1000, "lowpass")(s)
    s = GaussianFilter(l_mm * 1000, "highpass")(s)
    inner = s.data[band:-band, band:-band]
    s2 = surfalize.Surface(inner, d_mm * 1000, d_mm * 1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = {k: float(getattr(s2, k)()) for k in SHARED if not k.startswith("V")}
        abbott = s2.get_abbott_firestone_curve()
        ref.update(Vmp=abbott.vmp(), Vmc=abbott.vmc(), Vvc=abbott.vvc(), Vvv=abbott.vvv())
        ref["Smr"] = float(s2.Smr(inner.mean() + 0.5))
    return ref


@pytest.mark.parametrize("kind", ["shot_blasted", "ground", "turned"])
def test_surfalize_agrees_within_0_1_percent(kind):
    d = 0.002
    hf = textured_plate(kind, size=(240, 320), pixel_size=d, sq_um=2.0, corr_mm=0.012, feed_mm=0.064,
                        tilt=(0.01, -0.02), seed=4)
    t = texture(hf.height, d, s_filter_mm=0.008, l_filter_mm=0.2, form="plane", edge="drop", smr_c_um=0.5)
    ref = _surfalize(hf.height, d, 0.008, 0.2, t.filters["edge_band_px"])
    for name, r in ref.items():
        if math.isnan(r):
            assert math.isnan(t.values[name]), name
            continue
        assert t.values[name] == pytest.approx(r, rel=1e-3), name


# ------------------------------------------------------------------------------------------------ the chain
def test_texture_states_band_filters_and_units():
    d = 0.005
    hf = textured_plate("turned", size=128, pixel_size=d, sq_um=1.0, seed=0)
    t = texture(hf.height, d, s_filter_mm=0.0025, l_filter_mm=0.25, form="poly2")
    out = t.as_dict()
    assert out["band"]["short_mm"] == 2 * d and out["band"]["short_limit"].startswith("Nyquist")
    assert out["band"]["long_mm"] == 0.25
    assert out["form"] == "poly2" and out["filters"]["alpha"] == pytest.approx(math.sqrt(math.log(2) / math.pi))
    assert set(out["parameters"]) == set(UNITS)
    assert out["parameters"]["Sq"]["unit"] == "um" and out["parameters"]["Sq"]["U"] is None
    # a field shorter than the L-filter bounds the band
    t2 = texture(hf.height, d, l_filter_mm=5.0)
    assert t2.band["long_mm"] == pytest.approx(128 * d) and t2.band["long_limit"] == "field size"


def test_turned_plate_str_is_small():
    hf = textured_plate("turned", size=256, pixel_size=0.005, sq_um=2.0, seed=0)
    t = texture(hf.height, 0.005)
    # feed marks along y: the autocorrelation decays fast across them, never along them
    assert math.isnan(t.values["Str"]) and "not determined" in t.notes["Str"]
    assert 0 < t.values["Sal"] < 0.5 * 32 * 5


def test_white_noise_uncertainty_covers_and_corrects_the_bias():
    d = 0.005
    truth = _random_field((192, 192), 4.0, 0.001, seed=5)
    kw = {"s_filter_mm": 0.01, "l_filter_mm": 0.4}
    ref = texture(truth, d, **kw).values
    noisy = truth + np.random.default_rng(6).standard_normal(truth.shape) * 0.0003
    t = texture(noisy, d, height_u=0.0003, mc_samples=30, seed=1, **kw)
    u = t.uncertainty["parameters"]
    assert t.values["Sq"] > ref["Sq"]  # noise reads high
    assert abs(u["Sq"]["corrected"] - ref["Sq"]) < abs(t.values["Sq"] - ref["Sq"]) / 3
    for name in ("Sa", "Sq", "Sdq"):
        assert abs(t.values[name] - ref[name]) <= u[name]["U"], name
        assert abs(u[name]["corrected"] - ref[name]) <= u[name]["U_corrected"], name


def test_through_the_photometric_path():
    d = 0.005
    hf = textured_plate("shot_blasted", size=160, pixel_size=d, sq_um=2.0, tilt=(0.01, 0.0), seed=2)
    kw = {"s_filter_mm": 0.04, "l_filter_mm": 0.25}
    ref = texture(hf.height, d, **kw).values
    L = ring_lights(4, 40.0)
    sigma = 0.02
    st = solve(render(hf, L, noise=sigma, seed=3), L)
    z = integrate(st.p, st.q, "dct", pixel_size=d)
    vp, vq, _ = slope_noise_covariance(L, st.albedo, st.p, st.q, sigma)
    t = texture(z, d, integrator="dct", slope_u=(np.sqrt(vp), np.sqrt(vq)), mc_samples=20, seed=0, **kw)
    u = t.uncertainty["parameters"]
    for name in ("Sa", "Sq"):
        assert t.values[name] == pytest.approx(ref[name], rel=0.05)
        assert abs(u[name]["corrected"] - ref[name]) <= u[name]["U_corrected"]
    # without the integrator's correction the short wavelengths read low
    plain = texture(z, d, **kw).values
    assert plain["Sq"] < t.values["Sq"]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"height": np.zeros((4, 4))}, "at least 8 x 8"),
        ({"mask": np.ones((3, 3), bool)}, "mask: shape"),
        ({"s_filter_mm": 0.3, "l_filter_mm": 0.2}, "shorter than l_filter_mm"),
        ({"edge": "cut"}, "edge"),
        ({"form": "cubic"}, "form"),
        ({"integrator": "dct"}, "needs an S-filter"),
        ({"pixel_size": -1.0}, "pixel_size"),
        ({"height_u": -1.0}, "height_u"),
        ({"height_u": 0.001, "mc_samples": 1}, "mc_samples"),
        ({"height_u": np.ones((5, 5))}, "height_u: expected one value or a map"),
    ],
)
def test_bad_input(kwargs, message):
    args = {"height": _random_field((32, 32), 2.0, 0.001, 0), "pixel_size": 0.01}
    args.update(kwargs)
    with pytest.raises(InputError, match=message):
        texture(args.pop("height"), args.pop("pixel_size"), **args)


def test_a_rectangular_mask_is_the_cropped_field():
    hf = textured_plate("turned", size=(120, 160), pixel_size=0.002, sq_um=2.0, corr_mm=0.012, feed_mm=0.064, seed=3)
    z = hf.height * 1000
    mask = np.zeros(z.shape, bool)
    mask[20:100, 30:140] = True
    a, notes_a = parameters(np.where(mask, z, np.nan), 0.002)
    b, notes_b = parameters(z[20:100, 30:140], 0.002)
    for name in UNITS:
        if math.isnan(b[name]):
            assert math.isnan(a[name]) and name in notes_a, name
        else:
            assert a[name] == pytest.approx(b[name], rel=1e-6), name
