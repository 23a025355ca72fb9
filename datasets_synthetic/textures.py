"""Textured plates with exact slopes: turned, ground and shot-blasted surfaces (issue 36).

Each plate is a periodic, band-limited random or deterministic field synthesised in the
Fourier domain over the image grid: ``z = irfft2(Z)``. Its slopes are the exact
derivatives of the same trigonometric series (``p = irfft2(2 pi i f_x Z)``), never
finite differences, so a rendered plate's normals are exact at every pixel centre and
the texture parameters of the sampled height are known (compute them with
:func:`photometric.texture.texture` on ``hf.height`` with the same filters).

* ``"turned"``: feed marks of a round-nosed tool, a parabolic cusp profile of period
  ``feed_mm`` along x (its Fourier series truncated at four pixels per wavelength), with
  a little random roughness;
* ``"ground"``: an anisotropic Gaussian random field, long correlation along x (the
  grinding direction), short across;
* ``"shot_blasted"``: an isotropic Gaussian random field (Gaussian autocorrelation of
  length ``corr_mm``).

The RMS height of every plate is scaled to ``sq_um`` exactly (over the whole image).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft as sfft

from datasets_synthetic.heightfields import HeightField
from photometric.normals import normals_from_slopes
from surfaces.validate import InputError

KINDS = ("turned", "ground", "shot_blasted")


def _spectrum(kind: str, shape, ps: float, corr_mm: float, feed_mm: float, rng: np.random.Generator) -> np.ndarray:
    h, w = shape
    fy = sfft.fftfreq(h, d=ps)[:, None]
    fx = sfft.rfftfreq(w, d=ps)[None, :]
    white = sfft.rfft2(rng.standard_normal(shape))
    nyq = 0.25 / ps  # keep every component at four pixels per wavelength or longer
    if kind == "shot_blasted":
        amp = np.exp(-((math.pi * corr_mm) ** 2) * (fx**2 + fy**2) / 2.0)
    elif kind == "ground":
        amp = np.exp(-((math.pi * corr_mm) ** 2) * ((8.0 * fx) ** 2 + fy**2) / 2.0)
    else:
        # parabolic cusp of period feed along x: Fourier coefficients (-1)^k / k^2 of its harmonics
        amp = np.zeros((h, w // 2 + 1))
        spec = np.zeros((h, w // 2 + 1), dtype=complex)
        k_max = int(feed_mm * nyq)
        for k in range(1, k_max + 1):
            col = k * w * ps / feed_mm
            j = int(round(col))
            if abs(col - j) > 1e-6:
                raise InputError(f"feed_mm: the image width ({w} px x {ps} mm) must hold a whole number of feeds")
            spec[0, j] = (-1) ** k / k**2 * h * w / 2.0
        rough = np.exp(-((math.pi * corr_mm) ** 2) * (fx**2 + fy**2) / 2.0) * white
        rough *= (np.abs(fx) <= nyq) & (np.abs(fy) <= nyq)
        scale = np.sqrt(np.sum(np.abs(spec) ** 2) / max(np.sum(np.abs(rough) ** 2), 1e-300))
        return spec + 0.15 * scale * rough
    amp = amp * ((np.abs(fx) <= nyq) & (np.abs(fy) <= nyq))
    return amp * white


def textured_plate(
    kind: str = "shot_blasted",
    size=256,
    pixel_size: float = 0.005,
    sq_um: float = 2.0,
    corr_mm: float | None = None,
    feed_mm: float | None = None,
    tilt: tuple[float, float] = (0.0, 0.0),
    seed: int | np.random.Generator = 0,
) -> HeightField:
    """A flat plate with a machined or blasted texture, exact heights and slopes.

    Parameters
    ----------
    kind : {"turned", "ground", "shot_blasted"}
        Texture (see the module notes).
    size : int or (H, W)
        Image size, pixels.
    pixel_size : float
        Pixel size, mm.
    sq_um : float
        RMS height of the texture over the image, micrometres.
    corr_mm : float, optional
        Correlation length of the random part, mm (default 12 pixels).
    feed_mm : float, optional
        Turned plates: feed per revolution, mm (default 32 pixels; the image width must
        hold a whole number of feeds).
    tilt : (float, float)
        Slopes (dz/dx, dz/dy) of the plate's plane (a form for the F-operator to remove).
    seed : int or numpy.random.Generator
        Seed of the random field.

    Returns
    -------
    HeightField
        Heights in mm, exact slopes and normals; ``params`` holds the inputs.

    Examples
    --------
    >>> hf = textured_plate("ground", size=64, pixel_size=0.01, sq_um=1.5, seed=1)
    >>> hf.shape, round(float(hf.height.std()) * 1000, 6)
    ((64, 64), 1.5)
    """
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    h, w = (int(size), int(size)) if np.isscalar(size) else (int(size[0]), int(size[1]))
    if min(h, w) < 16:
        raise InputError(f"size: need at least 16 x 16 pixels, got {h} x {w}")
    ps = float(pixel_size)
    if not (math.isfinite(ps) and ps > 0):
        raise InputError(f"pixel_size: must be a positive number of mm, got {pixel_size!r}")
    if not (math.isfinite(sq_um) and sq_um > 0):
        raise InputError(f"sq_um: must be a positive number of um, got {sq_um!r}")
    corr = 12.0 * ps if corr_mm is None else float(corr_mm)
    feed = 32.0 * ps if feed_mm is None else float(feed_mm)
    if not (corr > 0 and feed > 0):
        raise InputError("corr_mm, feed_mm: must be positive")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    Z = _spectrum(kind, (h, w), ps, corr, feed, rng)
    Z[0, 0] = 0.0
    fy = sfft.fftfreq(h, d=ps)[:, None]
    fx = sfft.rfftfreq(w, d=ps)[None, :]
    z = sfft.irfft2(Z, s=(h, w))
    dz_dcol = sfft.irfft2(2j * math.pi * fx * Z, s=(h, w))
    dz_drow = sfft.irfft2(2j * math.pi * fy * Z, s=(h, w))
    scale = sq_um / 1000.0 / float(np.sqrt(np.mean(z * z)))
    # x grows with the column, y with decreasing row (y up)
    x = (np.arange(w) - (w - 1) / 2.0) * ps
    y = ((h - 1) / 2.0 - np.arange(h)) * ps
    height = scale * z + tilt[0] * x[None, :] + tilt[1] * y[:, None]
    p = scale * dz_dcol + tilt[0]
    q = -scale * dz_drow + tilt[1]
    return HeightField(
        height=height,
        p=p,
        q=q,
        normals=normals_from_slopes(p, q),
        defect_mask=np.zeros((h, w), bool),
        pixel_size=ps,
        name=f"textured_{kind}",
        params={"kind": kind, "size": [h, w], "pixel_size": ps, "sq_um": float(sq_um), "corr_mm": corr,
                "feed_mm": feed, "tilt": [float(t) for t in tilt]},
    )
