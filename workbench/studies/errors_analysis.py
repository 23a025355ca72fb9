"""The light-deviation accuracy study of one set of nominal lights, as one dict.

:func:`analyse` runs the studies of :mod:`photometric.errors` (configuration,
sensitivity, error maps and curves, tolerances, Monte Carlo, a given surface) and the
rendered crack study of :mod:`workbench.studies.crack`, and returns JSON-ready numbers
plus, under ``"_arrays"``, the arrays the plots need. :func:`workbench.studies.errors_report.write_report`
writes it; ``workbench photometric errors`` is the command line.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from photometric import errors as E
from photometric.lights import condition_number, deviate_lights, light_angles, validate_lights
from surfaces.validate import as_array, InputError, positive
from workbench.studies.crack import crack_study

__all__ = ["MAP_AXES", "RECOMMEND_TOLERANCES", "RECOMMEND_RANGES", "RANGE_DEVIATIONS", "analyse"]

MAP_AXES: tuple[tuple[tuple[int, str], tuple[int, str]], ...] = (
    ((0, "slant"), (1, "slant")),
    ((0, "slant"), (0, "azimuth")),
    ((0, "azimuth"), (1, "azimuth")),
)
RECOMMEND_TOLERANCES = (0.01, 0.02, 0.05, 0.1)
RECOMMEND_RANGES = (0.5, 1.0, 2.0)
RANGE_DEVIATIONS = (0.25, 0.5, 1.0, 2.0)


def _f(x) -> float | None:
    """A JSON-safe float (None for inf/NaN)."""
    x = float(x)
    return x if np.isfinite(x) else None


def _tol(t: E.Tolerance) -> dict:
    return {"value": _f(t.value), "error": _f(t.error), "first_order": _f(t.first_order), "saturated": t.saturated}


def analyse(
    lights,
    deviation_max: float = 5.0,
    derivative_range: float = 1.0,
    tolerance: float = 0.05,
    surface=None,
    pixel_size: float = 1.0,
    grid: int = 41,
    sigma_deg: float = 1.0,
    samples: int = 20000,
    seed: int = 0,
    crack: bool = True,
    crack_size: int = 128,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Run the whole light-deviation study for one set of nominal lights.

    Parameters
    ----------
    lights : array_like, (N, 3)
        Nominal unit lights (N >= 3; maps and pairs use lights 0, 1, 2).
    deviation_max : float
        Half-width of the deviation grids of the error maps and curves, degrees.
    derivative_range : float
        ``D``: the derivative square ``|p|, |q| <= D``.
    tolerance : float
        ``eps``: allowed absolute error of ``p`` and ``q``.
    surface : array_like, (H, W), optional
        A height field (mm) whose slopes are used for extra maps and the height error.
    pixel_size : float
        Pixel pitch of ``surface``, mm.
    grid : int
        Grid points per axis of the deviation maps and of the derivative square.
    sigma_deg : float
        Standard deviation of the Monte Carlo light deviations, degrees.
    samples : int
        Monte Carlo samples.
    seed : int
        Randomness of the Monte Carlo study and of the crack scene.
    crack : bool
        Run the rendered crack study (:func:`workbench.studies.crack.crack_study`).
    crack_size : int
        Image side of the crack study, pixels.
    progress : callable, optional
        Called with a short label before each stage (the command line's progress bar).

    Returns
    -------
    dict
        Report content: ``convention``, ``inputs``, ``configuration``,
        ``sensitivity_per_deg``, ``first_order_relative_difference_at_2deg``,
        ``error_maps``, ``error_curves``, ``tolerances``, ``derivative_range_limits``,
        ``recommendation_table``, ``monte_carlo`` and, when asked for,
        ``surface_height_error`` and ``crack_study``. Arrays used only for plotting are
        under ``"_arrays"`` (not written to JSON).
    """
    L = validate_lights(lights)
    dmax = positive(deviation_max, "deviation_max")
    D = positive(derivative_range, "derivative_range")
    eps = positive(tolerance, "tolerance")
    ps = positive(pixel_size, "pixel_size")
    sigma = positive(sigma_deg, "sigma_deg")
    if int(grid) < 5:
        raise InputError(f"grid: need at least 5 points, got {grid}")
    grid = int(grid)
    step = progress or (lambda _label: None)
    N = L.shape[0]
    slant, azimuth = light_angles(L)
    p, q = E.derivative_square(D, grid)
    # the worst case sits on the square's boundary, which a 21 x 21 grid includes
    tol_grid = min(grid, 21)
    arrays: dict = {}
    report: dict = {
        "convention": "DiLiGenT frame: x right (columns), y up (rows reversed), z towards the camera; "
        "p = dz/dx, q = dz/dy; light l = (sin s cos a, sin s sin a, cos s); "
        "true lights make the images, nominal lights reconstruct them: n_est ~ L^+ L' n",
        "inputs": {
            "lights": L.tolist(),
            "slant_deg": slant.tolist(),
            "azimuth_deg": azimuth.tolist(),
            "deviation_max_deg": dmax,
            "derivative_range": D,
            "tolerance": eps,
            "grid": grid,
            "sigma_deg": sigma,
            "samples": int(samples),
            "seed": int(seed),
            "surface": None if surface is None else {"shape": list(np.shape(surface)), "pixel_size_mm": ps},
        },
    }

    step("configuration")
    slants = np.linspace(5.0, 85.0, 161)
    ring = E.ring_conditioning(slants)
    noise = E.noise_propagation(L, 0.01, 1.0, [0.0, D, D], [0.0, 0.0, D])
    lit = E.lit_normals(L, p, q)
    report["configuration"] = {
        "condition_number": condition_number(L),
        "singular_values": np.linalg.svd(L, compute_uv=False).tolist(),
        "inverse_frobenius": float(np.linalg.norm(np.linalg.pinv(L))),
        "optimal_slant_deg": E.OPTIMAL_SLANT_DEG,
        "ring_condition_at_optimum": float(E.ring_conditioning([E.OPTIMAL_SLANT_DEG])["condition_number"][0]),
        "noise_sigma_image": 0.01,
        "noise_sigma_normal_bound": noise["sigma_normal_bound"],
        "noise_angle_rms_deg": {"(0,0)": float(noise["angle_rms_deg"][0]), "(D,0)": float(noise["angle_rms_deg"][1]),
                                "(D,D)": float(noise["angle_rms_deg"][2])},
        "noise_std_pq_at_(D,D)": np.sqrt(np.diag(noise["covariance_pq"][2])).tolist(),
        "shadowed_fraction_of_square": float(1.0 - lit.mean()),
    }
    arrays["ring"] = ring

    step("sensitivity")
    J = np.radians(1.0) * np.abs(E.sensitivity(L, p, q))  # per degree
    sens = {}
    check = {}
    for k in range(N):
        for j, name in enumerate(("slant", "azimuth")):
            sens[f"light{k + 1}_{name}"] = {"max_dp_per_deg": float(J[..., 0, k, j].max()),
                                            "max_dq_per_deg": float(J[..., 1, k, j].max())}
            dev = np.zeros((N, 2))
            dev[k, j] = 2.0
            ex = E.exact_error(L, deviate_lights(L, dev), p, q)
            fp, fq = E.first_order_error(L, dev, p, q)
            rel = [float(np.abs(a - b).max() / np.abs(a).max()) if np.abs(a).max() > 1e-12 else 0.0
                   for a, b in ((ex.dp, fp), (ex.dq, fq))]
            check[f"light{k + 1}_{name}"] = max(rel)
    report["sensitivity_per_deg"] = sens
    report["first_order_relative_difference_at_2deg"] = check

    step("error maps")
    maps = []
    surface_pq = None
    if surface is not None:
        sp, sq = E.surface_derivatives(surface, ps)
        stride = max(1, int(np.ceil(np.sqrt(sp.size / 20000.0))))
        surface_pq = (sp[::stride, ::stride], sq[::stride, ::stride])
    sets = [("square", (p, q))] + ([("surface", surface_pq)] if surface_pq is not None else [])
    for set_name, (sp_, sq_) in sets:
        for a1, a2 in MAP_AXES:
            if max(a1[0], a2[0]) >= N:
                continue
            maps.append(_map_entry(E.error_map(L, sp_, sq_, a1, a2, dmax, grid), set_name, eps))
    report["error_maps"] = maps

    step("curves")
    slopes = np.array([0.0, 0.5, 1.0, 2.0]) * D * np.sqrt(2.0)  # p = q = 0, D/2, D, 2D
    # gradients at 45 deg so that both p and q vary with the slope
    curves = E.error_curves(L, slopes, 0, "slant", dmax, 2 * grid - 1, slope_direction_deg=45.0)
    report["error_curves"] = {
        "light": 1,
        "angle": "slant",
        "slope_direction_deg": 45.0,
        "slopes": slopes.tolist(),
        "max_abs_dp": np.abs(curves["dp"]).max(axis=0).tolist(),
        "max_abs_dq": np.abs(curves["dq"]).max(axis=0).tolist(),
    }
    arrays["curves"] = curves

    step("tolerances")
    tol_rows = []
    groups = [(k,) for k in range(N)] + (list(_pairs(N)) + [tuple(range(N))] if N <= 4 else [tuple(range(N))])
    for moved in groups:
        row = {"lights": [k + 1 for k in moved]}
        for mode in ("slant", "azimuth", "any"):
            row[mode] = _tol(E.max_deviation(L, eps, D, moved, mode, n_grid=tol_grid))
        tol_rows.append(row)
    report["tolerances"] = tol_rows
    range_rows = []
    for delta in sorted(set(RANGE_DEVIATIONS) | {dmax}):
        row = {"deviation_deg": float(delta)}
        for key, sets_ in (("single_light", [(k,) for k in range(N)]),
                           ("pair", list(_pairs(N)) if N <= 4 else []),
                           ("all_lights", [tuple(range(N))])):
            if not sets_:
                continue
            res = [E.max_derivative_range(L, eps, delta, s, "any", n_grid=tol_grid) for s in sets_]
            worst = min(res, key=lambda r: r.value)
            row[key] = _tol(worst)
        range_rows.append(row)
    report["derivative_range_limits"] = range_rows
    report["recommendation_table"] = E.recommendation_table(
        L, tuple(sorted(set(RECOMMEND_TOLERANCES) | {eps})), tuple(sorted(set(RECOMMEND_RANGES) | {D})),
        n_grid=21,
    ) if N <= 4 else []

    step("Monte Carlo")
    test_p = np.array([0.0, 0.5 * D, D, 0.0, D, -D])
    test_q = np.array([0.0, 0.0, 0.0, D, D, 0.5 * D])
    mc = E.monte_carlo(L, sigma, test_p, test_q, int(samples), seed)
    sigmas = np.linspace(0.0, 2.0 * E.max_deviation(L, eps, D, (0,), "any", n_grid=21).value, 9)
    exceed = E.exceedance_probability(L, sigmas, eps, D, n_samples=min(int(samples), 1000), n_grid=15, seed=seed)
    report["monte_carlo"] = {
        "sigma_deg": sigma,
        "model": "each light turned towards a uniformly random tangent direction by a Rayleigh-distributed "
                 "angle of RMS sigma (isotropic Gaussian tangent deviation, N(0, sigma^2 / 2) per axis)",
        "normals": [
            {
                "p": float(test_p[i]),
                "q": float(test_q[i]),
                "mean": mc.mean[i].tolist(),
                "std": np.sqrt(np.diag(mc.covariance[i])).tolist(),
                "std_first_order": np.sqrt(np.diag(mc.predicted_covariance[i])).tolist(),
                "correlation": float(mc.covariance[i, 0, 1] / np.sqrt(mc.covariance[i, 0, 0] * mc.covariance[i, 1, 1])),
                "correlation_first_order": float(
                    mc.predicted_covariance[i, 0, 1]
                    / np.sqrt(mc.predicted_covariance[i, 0, 0] * mc.predicted_covariance[i, 1, 1])
                ),
                "angle_rms_deg": float(mc.angle_rms_deg[i]),
                "angle_rms_first_order_deg": float(mc.predicted_angle_rms_deg[i]),
                "p95_abs_dp": float(np.quantile(np.abs(mc.dp[:, i]), 0.95)),
                "p95_abs_dq": float(np.quantile(np.abs(mc.dq[:, i]), 0.95)),
            }
            for i in range(test_p.size)
        ],
        "exceedance": {"sigma_deg": sigmas.tolist(), "probability_over_tolerance": exceed.tolist(),
                       "samples": min(int(samples), 1000)},
    }
    arrays["mc"] = mc

    if surface is not None:
        step("surface height error")
        h = as_array(surface, "surface", ndim=2)
        cases = []
        for k in range(N):
            dev = np.zeros((N, 2))
            dev[k, 0] = 1.0
            he = E.height_error(L, deviate_lights(L, dev), h, ps)
            cases.append({"lights": [k + 1], "deviation": "slant +1 deg",
                          **{key: val for key, val in he.items() if not isinstance(val, np.ndarray)}})
            if k == 0:
                arrays["surface_dh"] = he["dh"]
        report["surface_height_error"] = cases

    if crack:
        step("crack study")
        devs = []
        for d in sorted({0.0, 1.0, 2.0, dmax}):
            dev = np.zeros((N, 2))
            dev[0, 0] = d
            devs.append(dev)
        cs = crack_study(L, np.stack(devs), size=crack_size, seed=seed)
        arrays["crack"] = cs.pop("maps")
        # the paper's error map over the crack's own derivatives
        m = E.error_map(L, arrays["crack"]["p_true"], arrays["crack"]["q_true"], (0, "slant"), (1, "slant"),
                        dmax, grid)
        cs["error_map_max_abs_dp"] = float(m.max_dp.max())
        cs["error_map_max_abs_dq"] = float(m.max_dq.max())
        report["error_maps"].append(_map_entry(m, "crack", eps))
        report["crack_study"] = cs
    report["_arrays"] = arrays
    return report


def _map_entry(m: E.ErrorMap, derivatives: str, eps: float) -> dict:
    return {
        "derivatives": derivatives,
        "axis1": list(m.axis1),
        "axis2": list(m.axis2),
        "n_normals": m.n_normals,
        "max_abs_dp": float(m.max_dp.max()),
        "max_abs_dq": float(m.max_dq.max()),
        "max_angle_deg": float(m.max_angle_deg.max()),
        "fraction_within_tolerance": float(np.mean(np.maximum(m.max_dp, m.max_dq) <= eps)),
        "dev_deg": m.dev1_deg.tolist(),
        "max_dp": m.max_dp.tolist(),
        "max_dq": m.max_dq.tolist(),
        "mean_dp": m.mean_dp.tolist(),
        "mean_dq": m.mean_dq.tolist(),
    }


def _pairs(n: int):
    return [(i, j) for i in range(n) for j in range(i + 1, n)]
