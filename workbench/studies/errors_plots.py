"""Plots of the light-deviation accuracy study (matplotlib, Agg), one PNG file each.

:func:`write_plots` draws the figures of a :func:`workbench.studies.errors_analysis.analyse`
result into a folder and returns their file names by kind.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from photometric.errors import OPTIMAL_SLANT_DEG
from surfaces.io import atomic_write_bytes

__all__ = ["axis_label", "write_plots"]


def _save_figure(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    atomic_write_bytes(path, buf.getvalue())


def axis_label(axis) -> str:
    """Axis title of a deviation: ``(light index, "slant" | "azimuth")`` -> text with units.

    Examples
    --------
    >>> axis_label((0, "slant"))
    'slant deviation of light 1 (deg)'
    """
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
            ax.set_xlabel(axis_label(m["axis1"]))
            ax.set_ylabel(axis_label(m["axis2"]))
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
    ax.axvline(OPTIMAL_SLANT_DEG, color="k", ls="--", lw=0.8,
               label=f"tan(s) = sqrt(2): {OPTIMAL_SLANT_DEG:.2f} deg")
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


def write_plots(report: dict, out_dir) -> dict:
    """Draw every figure of an accuracy study into ``out_dir``.

    Parameters
    ----------
    report : dict
        The result of :func:`workbench.studies.errors_analysis.analyse` (with ``"_arrays"``).
    out_dir : str or Path
        Existing output folder.

    Returns
    -------
    dict
        File names: ``maps`` (list), ``curves``, ``mc`` (list), ``condition`` and, when the
        study has them, ``surface`` and ``crack``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
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
    return pictures
