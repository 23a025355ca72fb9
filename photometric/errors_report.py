"""The light-deviation accuracy study as a report: numbers, plots and Markdown.

:func:`analyse` runs the studies of :mod:`photometric.errors` for one set of
nominal lights and returns a dict (JSON-ready numbers plus a few arrays for the
plots); :func:`write_report` writes ``report.json``, ``report.md`` and the PNG
plots into a folder (atomically, file by file).
"""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from photometric import errors as E
from surfaces.io import atomic_write_bytes
from surfaces.validate import as_array, positive

MAP_AXES: tuple[tuple[tuple[int, str], tuple[int, str]], ...] = (
    ((0, "slant"), (1, "slant")),
    ((0, "slant"), (0, "azimuth")),
    ((0, "azimuth"), (1, "azimuth")),
)
RECOMMEND_TOLERANCES = (0.01, 0.02, 0.05, 0.1)
RECOMMEND_RANGES = (0.5, 1.0, 2.0)
RANGE_DEVIATIONS = (0.25, 0.5, 1.0, 2.0)


def _has(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        return False


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
        Run the crack study (needs ``datasets_synthetic`` and ``photometric.stereo``,
        ``.integrate``, ``.defects``; skipped with a note when they are missing).
    crack_size : int
        Image side of the crack study, pixels.
    progress : callable, optional
        Called with a short label before each stage (the command line's progress bar).

    Returns
    -------
    dict
        Report content; see the keys written by :func:`write_report`. Arrays used only
        for plotting are under ``"_arrays"`` (not written to JSON).
    """
    L = E._unit_lights(lights, "lights", nominal=True)
    dmax = positive(deviation_max, "deviation_max")
    D = positive(derivative_range, "derivative_range")
    eps = positive(tolerance, "tolerance")
    ps = positive(pixel_size, "pixel_size")
    sigma = positive(sigma_deg, "sigma_deg")
    if int(grid) < 5:
        raise ValueError(f"grid: need at least 5 points, got {grid}")
    grid = int(grid)
    step = progress or (lambda _label: None)
    N = L.shape[0]
    slant, azimuth = E.light_angles(L)
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
    lit = E._lit(L, p.ravel(), q.ravel())
    report["configuration"] = {
        "condition_number": E.condition_number(L),
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
            ex = E.exact_error(L, E.deviate_lights(L, dev), p, q)
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
            he = E.height_error(L, E.deviate_lights(L, dev), h, ps) if _has("photometric.integrate") else None
            if he is None:
                break
            cases.append({"lights": [k + 1], "deviation": "slant +1 deg",
                          **{key: val for key, val in he.items() if not isinstance(val, np.ndarray)}})
            if k == 0:
                arrays["surface_dh"] = he["dh"]
        report["surface_height_error"] = cases or {"skipped": "photometric.integrate is not available"}

    if crack:
        needed = ("datasets_synthetic.heightfields", "datasets_synthetic.render", "photometric.stereo",
                  "photometric.integrate", "photometric.defects")
        missing = [m for m in needed if not _has(m)]
        if missing:
            report["crack_study"] = {"skipped": "missing modules: " + ", ".join(missing)}
        else:
            step("crack study")
            devs = []
            for d in sorted({0.0, 1.0, 2.0, dmax}):
                dev = np.zeros((N, 2))
                dev[0, 0] = d
                devs.append(dev)
            cs = E.crack_study(L, np.stack(devs), size=crack_size, seed=seed)
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


# ----------------------------------------------------------------------------- writing


def _save_figure(fig, path: Path) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    atomic_write_bytes(path, buf.getvalue())


def _label(axis) -> str:
    k, kind = axis
    return f"{kind} deviation of light {k + 1} (deg)"


def _plot_maps(report: dict, out: Path, plt) -> list[str]:
    eps = report["inputs"]["tolerance"]
    names = []
    for i, m in enumerate(report["error_maps"]):
        dev = np.asarray(m["dev_deg"])
        # fixed margins: constrained layout doubles the drawing time of these four-panel maps
        fig, axes = plt.subplots(2, 2, figsize=(10.5, 8.5))
        fig.subplots_adjust(left=0.08, right=0.95, bottom=0.07, top=0.91, wspace=0.45, hspace=0.32)
        for ax, key, title in zip(
            axes.ravel(),
            ("max_dp", "max_dq", "mean_dp", "mean_dq"),
            ("max |dp|", "max |dq|", "mean |dp|", "mean |dq|"),
        ):
            z = np.asarray(m[key])
            half = 0.5 * (dev[1] - dev[0])
            mesh = ax.imshow(z, origin="lower", cmap="viridis", interpolation="nearest",
                             extent=(dev[0] - half, dev[-1] + half, dev[0] - half, dev[-1] + half))
            cb = fig.colorbar(mesh, ax=ax)
            cb.set_label(f"{title} (slope, dimensionless)")
            if z.max() > eps > z.min():
                cs = ax.contour(dev, dev, z, levels=[eps], colors="w", linewidths=1.2)
                ax.clabel(cs, fmt=f"eps={eps:g}", fontsize=7)
            ax.set_xlabel(_label(m["axis1"]))
            ax.set_ylabel(_label(m["axis2"]))
            ax.set_title(title)
            ax.set_aspect("equal")
        where = {"square": "|p|, |q| <= %g" % report["inputs"]["derivative_range"],
                 "surface": "the given surface", "crack": "the crack scene"}[m["derivatives"]]
        fig.suptitle(f"Derivative error over two light deviations, normals over {where}")
        (k1, a1), (k2, a2) = m["axis1"], m["axis2"]
        name = f"map_{i + 1}_{m['derivatives']}_L{k1 + 1}{a1}_L{k2 + 1}{a2}.png"
        _save_figure(fig, out / name)
        plt.close(fig)
        names.append(name)
    return names


def _plot_curves(report: dict, arrays: dict, out: Path, plt) -> str:
    c = arrays["curves"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0, 0.85, c["slopes"].size))
    for ax, key, name in zip(axes, ("dp", "dq"), ("dp", "dq")):
        for i, s in enumerate(c["slopes"]):
            g = s / np.sqrt(2.0)
            ax.plot(c["deviation_deg"], c[key][:, i], color=colours[i], label=f"p = q = {g:.3g} (exact)")
            ax.plot(c["deviation_deg"], c[f"{key}_first_order"][:, i], "--", color=colours[i], lw=1)
        eps = report["inputs"]["tolerance"]
        ax.axhline(eps, color="r", lw=0.8, ls=":")
        ax.axhline(-eps, color="r", lw=0.8, ls=":", label=f"+-eps = {eps:g}")
        ax.set_xlabel("slant deviation of light 1 (deg)")
        ax.set_ylabel(f"{name} (slope error, dimensionless)")
        ax.set_title(f"{name} against deviation (dashed: first order)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    name = "curves_light1_slant.png"
    _save_figure(fig, out / name)
    plt.close(fig)
    return name


def _plot_mc(report: dict, arrays: dict, out: Path, plt) -> list[str]:
    mc = arrays["mc"]
    pick = [0, 4]  # flat and the corner (D, D)
    fig, axes = plt.subplots(len(pick), 3, figsize=(14, 4 * len(pick)))
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.08, top=0.9, wspace=0.3, hspace=0.38)
    for row, i in zip(axes, pick):
        for ax, j, name in zip(row[:2], (0, 1), ("dp", "dq")):
            data = (mc.dp if j == 0 else mc.dq)[:, i]
            ax.hist(data, bins=80, density=True, alpha=0.6, label="Monte Carlo (exact model)")
            sd = np.sqrt(mc.predicted_covariance[i, j, j])
            x = np.linspace(data.min(), data.max(), 300)
            ax.plot(x, np.exp(-0.5 * (x / sd) ** 2) / (sd * np.sqrt(2 * np.pi)), "r",
                    label=f"first order N(0, {sd:.3g}^2)")
            ax.set_xlabel(f"{name} (slope error, dimensionless)")
            ax.set_ylabel("probability density (1/slope)")
            ax.set_title(f"{name} at p = {mc.p[i]:g}, q = {mc.q[i]:g}")
            ax.legend(fontsize=7)
        ax = row[2]
        ax.hist(mc.angle_deg[:, i], bins=80, density=True, alpha=0.6, label="Monte Carlo")
        ax.axvline(mc.angle_rms_deg[i], color="k", label=f"RMS {mc.angle_rms_deg[i]:.3g} deg")
        ax.axvline(mc.predicted_angle_rms_deg[i], color="r", ls="--",
                   label=f"first-order RMS {mc.predicted_angle_rms_deg[i]:.3g} deg")
        ax.set_xlabel("normal angle error (deg)")
        ax.set_ylabel("probability density (1/deg)")
        ax.set_title(f"normal error at p = {mc.p[i]:g}, q = {mc.q[i]:g}")
        ax.legend(fontsize=7)
    fig.suptitle(f"Random light deviations, sigma = {mc.sigma_deg:g} deg per light ({mc.dp.shape[0]} samples)")
    names = ["monte_carlo_histograms.png"]
    _save_figure(fig, out / names[0])
    plt.close(fig)

    ex = report["monte_carlo"]["exceedance"]
    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    ax.plot(ex["sigma_deg"], ex["probability_over_tolerance"], "o-")
    ax.set_xlabel("standard deviation of each light's deviation (deg)")
    ax.set_ylabel("P(max |dp|, |dq| over square > eps)")
    ax.set_title(f"Probability of exceeding eps = {report['inputs']['tolerance']:g} "
                 f"over |p|, |q| <= {report['inputs']['derivative_range']:g}")
    ax.grid(alpha=0.3)
    names.append("monte_carlo_exceedance.png")
    _save_figure(fig, out / names[1])
    plt.close(fig)
    return names


def _plot_condition(report: dict, arrays: dict, out: Path, plt) -> str:
    r = arrays["ring"]
    fig, ax = plt.subplots(figsize=(6.5, 4.2), constrained_layout=True)
    ax.semilogy(r["slant_deg"], r["condition_number"], label="condition number of L")
    ax.semilogy(r["slant_deg"], r["inverse_frobenius"], label="||L^-1||_F (noise gain)")
    ax.axvline(E.OPTIMAL_SLANT_DEG, color="k", ls="--", lw=0.8,
               label=f"tan(s) = sqrt(2): {E.OPTIMAL_SLANT_DEG:.2f} deg")
    for s in report["inputs"]["slant_deg"]:
        ax.axvline(s, color="r", ls=":", lw=0.8)
    ax.set_xlabel("common slant of three lights 120 deg apart (deg)")
    ax.set_ylabel("condition number / noise gain (dimensionless)")
    ax.set_title("Light configuration (red: the given lights' slants)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    name = "condition_vs_slant.png"
    _save_figure(fig, out / name)
    plt.close(fig)
    return name


def _plot_crack(report: dict, arrays: dict, out: Path, plt) -> str:
    cm = arrays["crack"]
    cases = report["crack_study"]["cases"]
    i = len(cases) - 1
    fig, axes = plt.subplots(1, 4, figsize=(17, 4.2), constrained_layout=True)
    # show the derivative the deviation spoils most
    c = "dq" if np.nanmax(np.abs(cm["dq_predicted"][i])) > np.nanmax(np.abs(cm["dp_predicted"][i])) else "dp"
    lim = max(float(np.nanmax(np.abs(cm[f"{k}_predicted"][i]))) for k in ("dp", "dq")) or 1.0
    for ax, key, title in zip(axes[:2], (f"{c}_measured", f"{c}_predicted"),
                              (f"{c} measured (render + solve)", f"{c} predicted (exact model)")):
        im = ax.imshow(cm[key][i], cmap="coolwarm", vmin=-lim, vmax=lim)
        fig.colorbar(im, ax=ax).set_label(f"{c} (slope error, dimensionless)")
        ax.set_title(title)
        ax.set_xlabel("column (pixel)")
        ax.set_ylabel("row (pixel)")
    ax = axes[2]
    for k, colour in (("dp", "C0"), ("dq", "C1")):
        ok = np.isfinite(cm[f"{k}_measured"][i])
        ax.plot(cm[f"{k}_predicted"][i][ok], cm[f"{k}_measured"][i][ok], ".", ms=2, alpha=0.5, color=colour,
                label=k)
    ax.plot([-lim, lim], [-lim, lim], "r", lw=0.8, label="measured = predicted")
    ax.set_xlabel("predicted error (slope, dimensionless)")
    ax.set_ylabel("measured error (slope, dimensionless)")
    ax.set_title("measured against predicted (lit pixels)")
    ax.legend(fontsize=7)
    ax = axes[3]
    dev = [c["deviations_deg"][0][0] for c in cases]
    ax.plot(dev, [c["depth_mm"] for c in cases], "o-", label="measured (plane fit)")
    if all(c["depth_mm_defects"] is not None for c in cases):
        ax.plot(dev, [c["depth_mm_defects"] for c in cases], "s--", label="measure_defects")
    ax.axhline(report["crack_study"]["true_depth_mm"], color="k", ls=":", label="true depth")
    ax.set_xlabel("slant deviation of light 1 (deg)")
    ax.set_ylabel("crack depth (mm)")
    ax.set_title("measured crack depth")
    ax.legend(fontsize=7)
    fig.suptitle(f"Crack study, light 1 slant off by {dev[i]:g} deg")
    name = "crack_study.png"
    _save_figure(fig, out / name)
    plt.close(fig)
    return name


def _plot_surface(report: dict, arrays: dict, out: Path, plt) -> str:
    fig, ax = plt.subplots(figsize=(6, 5), constrained_layout=True)
    im = ax.imshow(arrays["surface_dh"], cmap="coolwarm")
    fig.colorbar(im, ax=ax).set_label("height error (mm)")
    ax.set_xlabel("column (pixel)")
    ax.set_ylabel("row (pixel)")
    ax.set_title("Height error after integration, light 1 slant +1 deg")
    name = "surface_height_error.png"
    _save_figure(fig, out / name)
    plt.close(fig)
    return name


def _fmt(x, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, dict):
        s = _fmt(x.get("value"), digits)
        if x.get("saturated"):
            return f">= {s}" if (x.get("value") or 0) > 0 else "0 (a flat surface already exceeds eps)"
        return s
    return f"{x:.{digits}g}"


def _markdown(report: dict, pictures: dict[str, list[str]]) -> str:
    inp = report["inputs"]
    eps, D = inp["tolerance"], inp["derivative_range"]
    lines = [
        "# Accuracy of photometric stereo against deviated light directions",
        "",
        "Seed 002(a): the true lights `L'` make the images, the nominal lights `L` reconstruct them "
        "(`n_est ~ L^+ L' n`). Frame: " + report["convention"] + ".",
        "",
        "## Inputs",
        "",
        "| light | x | y | z | slant (deg) | azimuth (deg) |",
        "|---|---|---|---|---|---|",
    ]
    for k, (v, s, a) in enumerate(zip(inp["lights"], inp["slant_deg"], inp["azimuth_deg"])):
        lines.append(f"| {k + 1} | {v[0]:.4f} | {v[1]:.4f} | {v[2]:.4f} | {s:.2f} | {a:.2f} |")
    cfg = report["configuration"]
    lines += [
        "",
        f"Tolerance eps = {eps:g} on |dp| and |dq|; derivative range D = {D:g} (|p|, |q| <= D); "
        f"deviation maps over +-{inp['deviation_max_deg']:g} deg.",
        "",
        "## Recommended operating limits",
        "",
        "Largest angular deviation (any direction, degrees) that keeps |dp|, |dq| <= eps over "
        "|p|, |q| <= D: for one light alone (the strictest light), for any two lights off together, "
        "and for all lights off together (first-order estimate in brackets).",
        "",
        "| D | eps | one light (deg) | two lights (deg) | all lights (deg) |",
        "|---|---|---|---|---|",
    ]
    for r in report["recommendation_table"]:
        lines.append(
            f"| {r['derivative_range']:g} | {r['tolerance']:g} | {r['single_light_deg']:.3g} "
            f"({r['single_light_first_order_deg']:.3g}) | {r['pair_deg']:.3g} ({r['pair_first_order_deg']:.3g}) | "
            f"{r['all_lights_deg']:.3g} ({r['all_lights_first_order_deg']:.3g}) |"
        )
    lines += [
        "",
        f"### Per light and per pair (eps = {eps:g}, D = {D:g})",
        "",
        "| lights deviated | slant only (deg) | azimuth only (deg) | any direction (deg) |",
        "|---|---|---|---|",
    ]
    for r in report["tolerances"]:
        lines.append(
            f"| {', '.join(map(str, r['lights']))} | {_fmt(r['slant'])} | {_fmt(r['azimuth'])} | {_fmt(r['any'])} |"
        )
    lines += [
        "",
        f"### Necessary range of derivatives: largest D with |dp|, |dq| <= {eps:g}",
        "",
        "| deviation (deg) | one light | two lights | all lights |",
        "|---|---|---|---|",
    ]
    for r in report["derivative_range_limits"]:
        lines.append(
            f"| {r['deviation_deg']:g} | {_fmt(r.get('single_light'))} | {_fmt(r.get('pair'))} | "
            f"{_fmt(r.get('all_lights'))} |"
        )
    lines += ["", "## Error maps over two deviations", ""]
    for m, pic in zip(report["error_maps"], pictures["maps"]):
        lines.append(
            f"- {_label(m['axis1'])} against {_label(m['axis2'])}, normals over the {m['derivatives']}: "
            f"max |dp| {m['max_abs_dp']:.3g}, max |dq| {m['max_abs_dq']:.3g}, max angle "
            f"{m['max_angle_deg']:.3g} deg; {100 * m['fraction_within_tolerance']:.0f} % of the map within eps."
        )
        lines.append(f"\n![error map]({pic})\n")
    lines += ["## Error against deviation", "", f"![curves]({pictures['curves']})", ""]
    mc = report["monte_carlo"]
    lines += [
        "## Monte Carlo",
        "",
        f"Model: {mc['model']}; sigma = {mc['sigma_deg']:g} deg.",
        "",
        "| p | q | std dp (MC / 1st order) | std dq (MC / 1st order) | RMS angle deg (MC / 1st order) |",
        "|---|---|---|---|---|",
    ]
    for n in mc["normals"]:
        lines.append(
            f"| {n['p']:g} | {n['q']:g} | {n['std'][0]:.3g} / {n['std_first_order'][0]:.3g} | "
            f"{n['std'][1]:.3g} / {n['std_first_order'][1]:.3g} | "
            f"{n['angle_rms_deg']:.3g} / {n['angle_rms_first_order_deg']:.3g} |"
        )
    lines += ["", *(f"![Monte Carlo]({p})\n" for p in pictures["mc"])]
    lines += [
        "## Light configuration",
        "",
        f"Condition number of L: {cfg['condition_number']:.4g} (optimum 1 at slant {cfg['optimal_slant_deg']:.2f} deg "
        f"for three lights 120 deg apart); ||L^+||_F = {cfg['inverse_frobenius']:.4g}, so image noise "
        f"sigma_I = {cfg['noise_sigma_image']:g} gives a normal error of at most "
        f"{cfg['noise_sigma_normal_bound']:.3g} (albedo 1; RMS angle {cfg['noise_angle_rms_deg']['(0,0)']:.3g} deg "
        f"on a flat surface). {100 * cfg['shadowed_fraction_of_square']:.1f} % of the derivative square is in an "
        "attached shadow of some light (evaluated algebraically).",
        "",
        f"![condition number]({pictures['condition']})",
        "",
    ]
    if "surface_height_error" in report:
        lines += ["## The given surface", ""]
        she = report["surface_height_error"]
        if isinstance(she, list):
            for c in she:
                lines.append(
                    f"- light {c['lights'][0]} {c['deviation']}: max |dp| {c['max_abs_dp']:.3g}, "
                    f"max |dq| {c['max_abs_dq']:.3g}, RMS height error {c['rms_dh_mm']:.3g} mm, "
                    f"max {c['max_abs_dh_mm']:.3g} mm"
                )
        else:
            lines.append(f"- {she['skipped']}")
        if pictures.get("surface"):
            lines += ["", f"![height error]({pictures['surface']})"]
        lines.append("")
    cs = report.get("crack_study")
    if cs is not None:
        lines += ["## Crack study", ""]
        if "skipped" in cs:
            lines.append(f"Skipped: {cs['skipped']}.")
        else:
            lines += [
                f"Scene `{cs['scene']}` ({cs['size_px']} px, {cs['pixel_size_mm']:g} mm/px), true depth "
                f"{cs['true_depth_mm']:.4g} mm, rendered with light 1's slant off, reconstructed with the "
                f"nominal lights. With exact lights the reconstruction measures {cs['depth_nominal_mm']:.4g} mm "
                "(sampling and integration alone); the depth change is the effect of the deviation. "
                "Derivative errors on pixels lit by every light.",
                "",
                "| slant dev. (deg) | max abs dp measured / predicted / 1st order | max abs dq measured / predicted "
                "| worst measured-predicted | depth (mm) | depth change (mm) | error vs truth (mm) "
                "| measure_defects depth (mm) |",
                "|---|---|---|---|---|---|---|---|",
            ]
            for c in cs["cases"]:
                lines.append(
                    f"| {c['deviations_deg'][0][0]:g} | {c['max_abs_dp_measured']:.3g} / "
                    f"{c['max_abs_dp_predicted']:.3g} / {c['max_abs_dp_first_order']:.3g} | "
                    f"{c['max_abs_dq_measured']:.3g} / "
                    f"{c['max_abs_dq_predicted']:.3g} | {c['max_abs_diff_measured_predicted']:.2g} | "
                    f"{c['depth_mm']:.4g} | {c['depth_change_mm']:+.3g} | {c['depth_error_mm']:+.3g} | "
                    f"{_fmt(c['depth_mm_defects'], 4)} |"
                )
            lines += ["", f"![crack study]({pictures['crack']})", ""]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out_dir) -> dict[str, str]:
    """Write ``report.json``, ``report.md`` and the PNG plots of :func:`analyse`'s result.

    Parameters
    ----------
    report : dict
        The result of :func:`analyse`.
    out_dir : str or Path
        Output folder (created when missing).

    Returns
    -------
    dict
        File names written, keyed ``json``, ``markdown``, ``plots`` (list).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if "_arrays" not in report or "inputs" not in report:
        raise ValueError("report: expected the dict returned by photometric.errors_report.analyse")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {out} is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    arrays = report["_arrays"]
    pictures: dict = {
        "maps": _plot_maps(report, out, plt),
        "curves": _plot_curves(report, arrays, out, plt),
        "mc": _plot_mc(report, arrays, out, plt),
        "condition": _plot_condition(report, arrays, out, plt),
    }
    if "surface_dh" in arrays:
        pictures["surface"] = _plot_surface(report, arrays, out, plt)
    if "crack" in arrays:
        pictures["crack"] = _plot_crack(report, arrays, out, plt)
    public = {k: v for k, v in report.items() if k != "_arrays"}
    public["plots"] = [p for v in pictures.values() for p in (v if isinstance(v, list) else [v])]
    atomic_write_bytes(out / "report.json", json.dumps(public, indent=1).encode())
    atomic_write_bytes(out / "report.md", _markdown(report, pictures).encode())
    return {"json": "report.json", "markdown": "report.md", "plots": public["plots"]}
