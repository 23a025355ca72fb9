"""Seed 002(a)'s crack test image: rendered with deviated lights, reconstructed with the nominal ones.

The study composes the synthetic scene and renderer (:mod:`datasets_synthetic`), the
solver, integrator and defect measures (:mod:`photometric`) and the exact and
first-order error model (:mod:`photometric.errors`), so it lives here in ``workbench``
and not in a library package.
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.heightfields import make_scene
from datasets_synthetic.render import render
from photometric.defects import measure_defects
from photometric.errors import exact_error, first_order_error, lit_normals
from photometric.integrate import integrate
from photometric.lights import deviate_lights, validate_lights
from photometric.stereo import solve
from surfaces.validate import as_array, InputError, positive

__all__ = ["crack_study", "plane_depth"]


def plane_depth(height, defect_mask) -> float:
    """Depth of a defect below the least-squares plane of the sound surface.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height field (mm).
    defect_mask : array_like of bool, shape (H, W)
        The defect's pixels; the plane is fitted to all the others.

    Returns
    -------
    float
        ``max(plane - height)`` over the defect (mm).

    Examples
    --------
    >>> z = np.add.outer(np.arange(5.0), np.arange(6.0)) * 0.1  # a tilted plane
    >>> mask = np.zeros(z.shape, bool); mask[2, 3] = True
    >>> z[2, 3] -= 0.25
    >>> round(plane_depth(z, mask), 12)
    0.25
    """
    h = as_array(height, "height", ndim=2)
    m = as_array(defect_mask, "defect_mask", shape=h.shape, dtype=bool)
    sound = ~m
    if not m.any() or sound.sum() < 3:
        raise InputError("defect_mask: needs a defect pixel and at least 3 sound pixels")
    rows, cols = np.indices(h.shape)
    A = np.stack([cols[sound], rows[sound], np.ones(int(sound.sum()))], axis=1).astype(float)
    coef, *_ = np.linalg.lstsq(A, h[sound], rcond=None)
    plane = coef[0] * cols + coef[1] * rows + coef[2]
    return float(np.max((plane - h)[m]))


def crack_study(
    lights,
    deviations_deg,
    size: int = 128,
    pixel_size: float = 0.05,
    scene: str = "crack",
    seed: int = 0,
) -> dict:
    """Render a crack with deviated lights, reconstruct with the nominal ones, compare.

    Seed 002(a)'s test image of a crack: the scene ``datasets_synthetic.heightfields.
    make_scene(scene)`` is rendered (attached shadows, no noise) with the true lights
    ``deviate_lights(lights, d)`` for each ``d``, solved by ``photometric.stereo.solve``
    with the nominal lights, and integrated (``photometric.integrate.integrate``, DCT).
    The measured derivative error ``p_rec - p_true`` is set beside the exact prediction
    (:func:`photometric.errors.exact_error`) and the first-order one, on pixels lit by
    every light; the crack depth is measured below the least-squares plane of the sound
    surface (:func:`plane_depth`) and by ``photometric.defects.measure_defects``.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights.
    deviations_deg : array_like, shape (M, N, 2)
        ``[d_slant, d_azimuth]`` per light for each of the M cases, degrees.
    size : int
        Image side, pixels.
    pixel_size : float
        Pixel pitch, mm.
    scene : str
        Scene name for ``make_scene`` ("crack" or "plate").
    seed : int
        Scene seed.

    Returns
    -------
    dict
        ``true_depth_mm``, ``depth_nominal_mm`` (measured with undeviated lights: the
        discretisation and integration error alone), ``pixel_size_mm``, ``scene``,
        ``size_px``, ``lit_fraction``; ``cases``: one dict per deviation with
        ``deviations_deg``, ``max_abs_dp_measured``, ``max_abs_dp_predicted``,
        ``max_abs_dp_first_order`` (and ``dq``), ``rms_dp_measured``, ``rms_dp_predicted``,
        ``max_abs_diff_measured_predicted``, ``depth_mm`` (plane method),
        ``depth_mm_defects`` (``measure_defects``' deepest ``max_depth_mm`` or None),
        ``depth_error_mm`` (against the truth), ``depth_change_mm`` (against
        ``depth_nominal_mm``: the effect of the deviation); and arrays for plotting under
        ``maps``: ``p_true``, ``q_true`` (H, W), ``dp_measured``, ``dp_predicted``,
        ``dq_measured``, ``dq_predicted`` (M, H, W) and ``lit`` (H, W) bool.
    """
    L = validate_lights(lights)
    dev = as_array(deviations_deg, "deviations_deg")
    if dev.ndim != 3 or dev.shape[1:] != (L.shape[0], 2):
        raise InputError(f"deviations_deg: expected shape (M, {L.shape[0]}, 2), got {dev.shape}")
    ps = positive(pixel_size, "pixel_size")
    hf = make_scene(scene, int(size), ps, int(seed))
    mask = np.asarray(hf.defect_mask, bool)
    if not hf.defects or not mask.any():
        raise InputError(f"scene: {scene!r} has no defect to measure")
    true_lights = deviate_lights(L, dev)
    lit = lit_normals(L, hf.p, hf.q)
    for Lt in true_lights:
        lit &= lit_normals(Lt, hf.p, hf.q)
    base = solve(render(hf, L, shadows="attached"), L)
    depth_nominal = plane_depth(
        integrate(base.p.astype(float), base.q.astype(float), method="dct", pixel_size=ps), mask
    )
    cases = []
    maps = {k: [] for k in ("dp_measured", "dp_predicted", "dq_measured", "dq_predicted")}
    for d, Lt in zip(dev, true_lights):
        res = solve(render(hf, Lt, shadows="attached"), L)
        ok = lit & np.asarray(res.valid, bool)
        dp_m, dq_m = res.p.astype(float) - hf.p, res.q.astype(float) - hf.q
        ex = exact_error(L, Lt, hf.p, hf.q)
        fp, fq = first_order_error(L, d, hf.p, hf.q)
        height = integrate(res.p.astype(float), res.q.astype(float), method="dct", pixel_size=ps)
        found = measure_defects(height, ps)
        depths = [float(f["max_depth_mm"]) for f in found if "max_depth_mm" in f]
        depth = plane_depth(height, mask)
        cases.append({
            "deviations_deg": d.tolist(),
            "max_abs_dp_measured": float(np.abs(dp_m[ok]).max()),
            "max_abs_dp_predicted": float(np.abs(ex.dp[ok]).max()),
            "max_abs_dp_first_order": float(np.abs(fp[ok]).max()),
            "max_abs_dq_measured": float(np.abs(dq_m[ok]).max()),
            "max_abs_dq_predicted": float(np.abs(ex.dq[ok]).max()),
            "max_abs_dq_first_order": float(np.abs(fq[ok]).max()),
            "rms_dp_measured": float(np.sqrt(np.mean(dp_m[ok] ** 2))),
            "rms_dp_predicted": float(np.sqrt(np.mean(ex.dp[ok] ** 2))),
            "max_abs_diff_measured_predicted": float(
                max(np.abs(dp_m - ex.dp)[ok].max(), np.abs(dq_m - ex.dq)[ok].max())
            ),
            "depth_mm": depth,
            "depth_mm_defects": max(depths) if depths else None,
            "depth_error_mm": depth - float(hf.defects[0]["depth_mm"]),
            "depth_change_mm": depth - depth_nominal,
        })
        maps["dp_measured"].append(np.where(ok, dp_m, np.nan))
        maps["dq_measured"].append(np.where(ok, dq_m, np.nan))
        maps["dp_predicted"].append(ex.dp)
        maps["dq_predicted"].append(ex.dq)
    return {
        "scene": scene,
        "size_px": int(size),
        "pixel_size_mm": ps,
        "true_depth_mm": float(hf.defects[0]["depth_mm"]),
        "depth_nominal_mm": depth_nominal,
        "lit_fraction": float(lit.mean()),
        "cases": cases,
        "maps": {"p_true": hf.p, "q_true": hf.q, "lit": lit, **{k: np.stack(v) for k, v in maps.items()}},
    }
