"""Propagation: :func:`propagate` composes slopes, heights and defect figures into the
budget (linear), or repeats the fast solve with perturbed inputs (Monte Carlo)."""

from __future__ import annotations

import math
import time

import numpy as np

from photometric.nearfield import _upsample
from photometric.options import BACKGROUND
from photometric.uncertainty.budget import (
    _H_POWER,
    COVERAGE_FACTOR,
    FIGURES,
    Tolerances,
    UncertaintyResult,
    _budget,
    _entry,
)
from photometric.uncertainty.defects import (
    _Background,
    _bias_term,
    _blur_widening,
    _depth_grid,
    _every_phase_half_width,
    _figures,
    _grown,
    _noise_functionals,
    _points,
    _quantisation,
    _quantisation_term,
    _sampler,
    _section_exponent,
    _systematic,
    _volume_edge,
)
from photometric.uncertainty.heights import _bin, _integrate_field, _mode_variance, _squared_basis_sum
from photometric.uncertainty.slopes import (
    PointLightModel,
    _far_systematic,
    _point_fields,
    _slope_maps,
    _tangents,
    estimate_noise_sigma,
)
from surfaces.threads import one_blas_thread
from surfaces.validate import InputError, as_array, positive

#: Largest image on which the systematic fields are integrated pixel by pixel; larger
#: images integrate them on blocks of r x r pixels (the fields are smooth at that scale).
_SYSTEMATIC_PIXELS = 1 << 18


#: Blocks across the narrowest defect at least, when the fields are integrated on blocks.
_RESOLVE = 8


def _stage_times(t0: float, marks: dict) -> dict:
    """Seconds of each stage between the marks, and the total."""
    out, last = {}, t0
    for name, t in marks.items():
        out[name] = round(t - last, 4)
        last = t
    out["defects"] = round(time.perf_counter() - last, 4)
    out["total"] = round(time.perf_counter() - t0, 4)
    return out


def _median(values: np.ndarray, where: np.ndarray) -> float:
    """Median over ``where`` (of at most ~250 000 evenly spread pixels: a summary figure)."""
    step = max(1, int(math.sqrt(values.size / 250_000)))
    v = values[::step, ::step][where[::step, ::step]]
    return float(np.median(v)) if v.size else 0.0


# many small products (3 x 3 solves, dot products over a model window): one BLAS thread
@one_blas_thread()
def propagate(
    *,
    lights,
    intensities,
    albedo,
    p,
    q,
    valid,
    height,
    defects: list,
    labels,
    pixel_size: float,
    tolerances: Tolerances,
    integrator: str = "dct",
    background: str = BACKGROUND,
    residual=None,
    channels: int = 1,
    images=None,
    pixel_size_given: bool = True,
    resolve=None,
    point: PointLightModel | None = None,
    draw=None,
) -> UncertaintyResult:
    """Uncertainty of the slopes, heights and defect figures of a far-field reconstruction.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal unit lights of the solve.
    intensities : array_like, shape (N,) or (N, 3)
        Light intensities.
    albedo : array_like, shape (H, W) or (H, W, 3)
        Albedo of the solve.
    p, q : array_like, shape (H, W)
        Slopes.
    valid : array_like, shape (H, W), bool
        Solved pixels.
    height : array_like, shape (H, W)
        Height, mm (NaN outside ``valid``).
    defects : list of dict
        :func:`photometric.defects.measure_defects` records.
    labels : array_like, shape (H, W), int
        Their label image (``return_labels=True``).
    pixel_size : float
        Pixel size, mm.
    tolerances : Tolerances
        Sources and method.
    integrator : {"dct", "fc", "lsq"}
        The integrator of the reconstruction (the systematic fields go through it).
    background : {"plane", "smooth", "none"}
        The defects' background.
    residual : array_like, shape (H, W), optional
        RMS residual of the solve (noise estimate with N >= 4 when ``noise_sigma`` is None).
    channels : int
        Colour channels of the images.
    images : array_like, shape (N, H, W[, 3]), optional
        The images (Monte Carlo adds noise to them).
    pixel_size_given : bool
        False when the pixel size is the default 1 unit per pixel: an error (the
        uncertainties are stated in mm).
    resolve : callable, optional
        Monte Carlo: ``resolve(images, lights, intensities) -> (p, q, valid, height,
        defects)`` re-runs the fast solve (the pipeline passes its own).
    point : PointLightModel, optional
        Point lights (near-field rig, orthographic or perspective camera: ``point.xy`` holds
        the points the pixels see, the slope fields are integrated on the pixel grid with
        ``pixel_size``, the reference-plane pixel): the LED position Jacobian
        replaces the direction sensitivities; ``lights`` are then their directions.
    draw : callable, optional
        Monte Carlo: ``draw(rng) -> lights`` for ``resolve`` (default: the directions
        deviated by ``light_tolerance_deg``).

    Returns
    -------
    UncertaintyResult
    """
    tol = tolerances
    t0 = time.perf_counter()
    h = positive(pixel_size, "pixel_size")
    if not pixel_size_given:
        raise InputError("pixel_size: uncertainties are stated in mm and need the pixel size (--pixel-size or the "
                         "folder's scene.json); without it the heights are in pixel units")
    L = as_array(lights, "lights", ndim=2)
    n = L.shape[0]
    E = np.ones(n) if intensities is None else np.asarray(intensities, float)
    pp = as_array(p, "p", ndim=2, dtype=np.float32, finite=False)
    qq = as_array(q, "q", shape=pp.shape, dtype=np.float32, finite=False)
    ok = as_array(valid, "valid", shape=pp.shape, dtype=bool)
    z = as_array(height, "height", shape=pp.shape, finite=False)
    lab = as_array(labels, "labels", shape=pp.shape, dtype=np.int64)
    shape = pp.shape

    sigma, sigma_source = tol.noise_sigma, "option"
    if sigma is None:
        if n >= 4 and residual is not None:
            sigma, sigma_source = estimate_noise_sigma(residual, ok, n, E), "estimated from the residuals"
        else:
            sigma, sigma_source = 0.0, "not given (a triad has no residual to estimate it from)"

    point_fields = []
    if point is None:
        if tol.light_position_tolerance_mm > 0:
            raise InputError("light_position_tolerance_mm: applies to point lights (LED positions); distant lights "
                             "are directions (use light_tolerance_deg)")
        p_u, q_u, mean_vp, mean_vq = _slope_maps(L, E, albedo, pp, qq, ok, sigma, tol, channels)
    else:
        if tol.light_tolerance_deg > 0:
            raise InputError("light_tolerance_deg: point lights (LED positions) take light_position_tolerance_mm")
        point_fields, p_u, q_u, mean_vp, mean_vq = _point_fields(point, albedo, pp, qq, ok, z, sigma, tol,
                                                                 channels)

    near = ok & np.isfinite(z)
    grown = _grown(lab, defects, 3)
    deg = 1 if background in ("plane", "none") else 3
    bg = _Background(near & ~grown, deg, shape) if defects else None
    figs = _figures(lab, defects, z, bg) if defects else []

    marks = {"setup": time.perf_counter()}
    # systematic parameters: one slope field each, integrated once (on blocks of r x r
    # pixels for large images: the fields are linear in 1, p, q, p^2, pq, q^2, whose block
    # means give the fields' block means exactly)
    dterms = [{"max_depth_mm": {}, "volume_mm3": {}} for _ in defects]
    sys_var = np.zeros(shape, np.float32)
    r = max(1, int(math.ceil(math.sqrt(pp.size / _SYSTEMATIC_PIXELS))))
    if defects:
        # the blocks must resolve the narrowest defect (at least _RESOLVE blocks across)
        r = min(r, max(1, int(min(d["mean_width_mm"] for d in defects) / h // _RESOLVE)))
    if min(shape) < 8 * r:
        r = 1
    coarse_T: dict = {}
    okf = ok.astype(np.float32)
    ok_c = (_bin(okf, r) if r > 1 else okf) > 0
    if tol.method != "linear":
        fields = iter(())
    elif point is None:
        fields = _far_systematic(L, tol, pp, qq, okf, r)
    else:
        fields = ((src, u, _bin(dp, r) if r > 1 else dp, _bin(dq, r) if r > 1 else dq)
                  for src, _name, u, dp, dq in point_fields)
    var_c = np.zeros(ok_c.shape, np.float32)
    if figs:
        rows, cols, parts = _points(bg, figs)
        idx, wts = _sampler(rows, cols, r, ok_c.shape)
        n_bg = bg.rows.size
    for source, u, dp, dq in fields:
        zj = _integrate_field(dp, dq, integrator, ok_c, h * r)
        var_c += (zj * np.float32(u)) ** 2
        if figs:
            # constants cancel in depth and volume against the fitted background
            values = np.einsum("nk,nk->n", zj.ravel()[idx], wts)
            coef = bg.gram_inv @ (bg.A.T @ values[:n_bg])
            for i, fig in enumerate(figs):
                c_depth, c_vol = _systematic(fig, values, parts[i], coef, h)
                for figname, c in (("max_depth_mm", c_depth), ("volume_mm3", c_vol)):
                    acc = dterms[i][figname].setdefault(source, [0.0, u])
                    acc[0] += c * c
    sys_var = _upsample(var_c, r, shape) if r > 1 else var_c
    marks["systematic"] = time.perf_counter()

    T = _mode_variance(shape, mean_vp, mean_vq, h) if sigma > 0 else None
    height_var = sys_var
    if T is not None:
        height_var = height_var + _squared_basis_sum(_squared_basis_sum(T, 0), 1).astype(np.float32)
    if tol.pixel_size_tolerance > 0:
        zc = np.where(near, z - (z[near].mean() if near.any() else 0.0), 0.0)
        height_var = height_var + ((tol.pixel_size_tolerance * zc) ** 2).astype(np.float32)
    height_u = np.sqrt(np.maximum(height_var, 0.0))
    height_u[~near] = np.nan

    marks["maps"] = time.perf_counter()
    rng = np.random.default_rng(tol.seed)
    coef0 = bg.coef(z) if figs else None

    mc = None
    if tol.method == "montecarlo":
        if resolve is None or images is None:
            raise InputError("method: 'montecarlo' needs the images and the solver (use the pipeline)")
        mc = _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng, draw)
        p_u, q_u, height_u = mc["p_u"], mc["q_u"], mc["height_u"]

    out_defects = []
    for i, (rec, fig) in enumerate(zip(defects, figs)):
        terms: dict = {f: {} for f in FIGURES}
        if mc is None:
            for figname in ("max_depth_mm", "volume_mm3"):
                for source, (c2, u) in dterms[i][figname].items():
                    terms[figname][source] = _entry(u, math.sqrt(c2))
            if sigma > 0:
                vd, vv = _noise_functionals(fig, bg, h, r, T, mean_vp, mean_vq, coarse_T)
                terms["max_depth_mm"]["image_noise"] = _entry(sigma, math.sqrt(vd) / sigma)
                terms["volume_mm3"]["image_noise"] = _entry(sigma, math.sqrt(vv) / sigma)
        else:
            for figname, spread in mc["defects"][i].items():
                terms[figname]["montecarlo"] = _entry(spread, 1.0)
        if tol.pixel_size_tolerance > 0:
            for figname in FIGURES:
                terms[figname]["pixel_size"] = _entry(tol.pixel_size_tolerance, _H_POWER[figname] * rec[figname])
        # blur widens the slope footprint by a known amount (a bias of width and length, and
        # of the area by the perimeter's band): stated with the pixel grid's errors, whose
        # model then rasterises the narrower, true outline
        grow = _blur_widening(rec, h, tol.blur_px, _section_exponent(rec), tol.pixel_area) * h
        shift = {"mean_width_mm": grow, "length_mm": grow,
                 "area_mm2": grow * (rec["length_mm"] + rec["mean_width_mm"] - 2.0 * grow)}
        for figname, errors in _quantisation(rec, h, rng, grow).items():
            # the outline's errors are bounded and flat-topped, not normal: U holds at the
            # largest of them (the defect's place on the grid is fixed, not random) with the
            # Gaussian of the other terms, stated as the discretisation's effective uncertainty
            others = math.sqrt(sum(e["contribution"] ** 2 for e in terms[figname].values()))
            terms[figname]["discretisation"] = _entry(_quantisation_term(errors + shift[figname], others), 1.0)
        # the deepest pixel's grid error on the defect's model: its spread, and its mean
        # (a bias that depends on the axis) stated as the uncorrected bias that, with every
        # other term, a k = 2 interval must still cover (GUM F.2.4.5)
        # The phase of the defect on the grid is fixed, not random: the interval must hold at
        # the placement of the largest error, not on average over placements
        bias, spread, grid_errors = _depth_grid(rec, h, integrator, rng, tol.blur_px, tol.pixel_area)
        rest = math.sqrt(sum(e["contribution"] ** 2 for e in terms["max_depth_mm"].values()))
        others = math.sqrt(rest**2 + spread**2)
        U_grid = _every_phase_half_width(grid_errors, rest)
        terms["max_depth_mm"]["discretisation"] = _entry(spread, 1.0)
        terms["max_depth_mm"]["method_bias"] = _entry(
            max(_bias_term(others, bias), math.sqrt(max(0.25 * U_grid**2 - others**2, 0.0))), 1.0)
        terms["volume_mm3"]["discretisation"] = _entry(_volume_edge(z, fig, bg, coef0, h), 1.0)
        budget, expanded = _budget(rec, terms)
        out_defects.append({"id": rec["id"], "uncertainty_k2": expanded, "budget": budget})

    summary = {
        "method": tol.method,
        "tolerances": tol.to_dict(),
        "noise_sigma": float(sigma),
        "noise_sigma_source": sigma_source,
        "coverage_factor": COVERAGE_FACTOR,
        "pixel_size_mm": h,
        "median_p_u": _median(p_u, ok),
        "median_q_u": _median(q_u, ok),
        "median_height_u_mm": _median(height_u, near),
        "timings_s": _stage_times(t0, marks),
    }
    if mc is not None:
        summary["mc_samples"] = int(tol.mc_samples)
        summary["mc_missing"] = mc["missing"]
    return UncertaintyResult(p_u=p_u, q_u=q_u, height_u=height_u, defects=out_defects, summary=summary)


def perturbed_lights(L: np.ndarray, u_rad: float, rng: np.random.Generator) -> np.ndarray:
    """Lights moved by independent random tangent deviations of standard uncertainty ``u_rad`` per axis.

    One Monte Carlo draw of the light-direction uncertainty: each light moves along
    its slant and azimuth tangents by normal deviates, then is normalised again.

    Parameters
    ----------
    L : numpy.ndarray, shape (N, 3)
        Unit light directions.
    u_rad : float
        Standard uncertainty of each tangent component (radians).
    rng : numpy.random.Generator
        Source of the deviates.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        The moved unit directions.

    Examples
    --------
    >>> L = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    >>> moved = perturbed_lights(L, 0.01, np.random.default_rng(0))
    >>> bool(np.allclose(np.linalg.norm(moved, axis=1), 1.0)), bool(np.degrees(np.arccos((moved * L).sum(1))).max() < 3)
    (True, True)
    """
    e_s, e_a = _tangents(L)
    d = rng.normal(0.0, u_rad, (L.shape[0], 2))
    moved = L + d[:, :1] * e_s + d[:, 1:] * e_a
    return moved / np.linalg.norm(moved, axis=1, keepdims=True)


def _match(defects: list, found: list) -> list:
    """For each nominal defect the found defect of its kind nearest to its centre, when that
    lies within half the nominal defect's bounding box (at least 3 pixels); else None."""
    out = []
    for rec in defects:
        r0, c0, r1, c1 = rec["bbox_px"]
        reach = max(3.0, 0.5 * max(r1 - r0, c1 - c0))
        dist = [math.dist(rec["center_px"], f["center_px"]) if f["kind"] == rec["kind"] else np.inf for f in found]
        best = int(np.argmin(dist)) if dist else -1
        out.append(found[best] if best >= 0 and dist[best] <= reach else None)
    return out


def _monte_carlo(images, L, E, sigma, tol, resolve, defects, shape, h, rng, draw=None) -> dict:
    """Repeat the fast solve with perturbed inputs; spreads of slopes, heights and figures."""
    imgs = np.asarray(images, np.float32)
    n = tol.mc_samples
    s1 = {k: np.zeros(shape) for k in ("p", "q", "z")}
    s2 = {k: np.zeros(shape) for k in ("p", "q", "z")}
    count = np.zeros(shape)
    values = [{f: [] for f in FIGURES} for _ in defects]
    missing = 0
    u_dir = math.radians(tol.light_tolerance_deg)
    for _ in range(n):
        Lm = draw(rng) if draw is not None else perturbed_lights(L, u_dir, rng) if u_dir > 0 else L
        Em = E * (1.0 + tol.intensity_tolerance * rng.standard_normal(E.shape[0]).reshape(
            (-1,) + (1,) * (E.ndim - 1))) if tol.intensity_tolerance > 0 else E
        im = imgs + rng.normal(0.0, sigma, imgs.shape).astype(np.float32) if sigma > 0 else imgs
        scale = 1.0 + tol.pixel_size_tolerance * rng.standard_normal() if tol.pixel_size_tolerance > 0 else 1.0
        p, q, ok, z, found = resolve(im, Lm, Em)
        zz = np.where(ok & np.isfinite(z), z, 0.0) * scale
        for key, arr in (("p", p), ("q", q), ("z", zz)):
            a = np.where(ok, arr, 0.0)
            s1[key] += a
            s2[key] += a * a
        count += ok
        for i, m in enumerate(_match(defects, found)):
            if m is None:
                missing += 1
                continue
            for f in FIGURES:
                values[i][f].append(m[f] * scale ** _H_POWER[f])
    c = np.maximum(count, 2)

    def spread(key):
        mean = s1[key] / c
        return np.sqrt(np.maximum(s2[key] / c - mean * mean, 0.0) * c / (c - 1))

    good = count >= 2
    return {
        "p_u": np.where(good, spread("p"), 0.0).astype(np.float32),
        "q_u": np.where(good, spread("q"), 0.0).astype(np.float32),
        "height_u": np.where(good, spread("z"), np.nan).astype(np.float32),
        "defects": [{f: float(np.std(v[f], ddof=1)) if len(v[f]) > 1 else float("inf") for f in FIGURES}
                    for v in values],
        "missing": missing,
    }
