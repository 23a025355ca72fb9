"""Uncertainty of photometric measurements: the budget of a result folder (values as
``0.100 ± 0.006 mm (k = 2)`` and one budget chart) and the coverage study that checks the
stated intervals against rendered trials with known truth.

:func:`uncertainty_budget` reads what ``workbench photometric reconstruct`` wrote with an
uncertainty option (``defects.json``, ``uncertainty.json``) and draws the chart;
:func:`coverage_study` renders scratches under lights that deviate at random by the stated
tolerance, reconstructs with the nominal lights and counts how often the stated 95 %
intervals hold the truth. Both compose ``datasets_synthetic``, ``photometric`` and
matplotlib, so they live here.
"""

from __future__ import annotations

import io
import json
import math
import time
from pathlib import Path

import numpy as np

from photometric.uncertainty import COVERAGE_FACTOR, FIGURES, SOURCES, Tolerances, format_value
from surfaces.io import atomic_write_bytes
from surfaces.validate import InputError, positive, reading

__all__ = ["FIGURE_LABELS", "TARGET_COVERAGE", "uncertainty_budget", "draw_budget", "coverage_interval",
           "coverage_study"]

#: Row labels and units of the defect figures.
FIGURE_LABELS = {
    "max_depth_mm": ("max depth", "mm"),
    "mean_width_mm": ("mean width", "mm"),
    "length_mm": ("length", "mm"),
    "area_mm2": ("area", "mm²"),
    "volume_mm3": ("volume", "mm³"),
}
#: The band the stated 95 % intervals' coverage must reach (issue 17).
TARGET_COVERAGE = (0.93, 0.97)
_COLOURS = {
    "image_noise": "#4c72b0", "light_direction": "#dd8452", "light_position": "#937860",
    "light_intensity": "#55a868", "montecarlo": "#8172b3", "pixel_size": "#c44e52",
    "discretisation": "#8c8c8c", "method_bias": "#da8bc3",
}


def _read_json(path: Path) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"result_dir: {path.name} not found in {path.parent} (run 'workbench photometric "
                                "reconstruct' with an uncertainty option, e.g. --light-tolerance-deg)")
    with reading(path, "JSON file"):
        return json.loads(path.read_text())


def draw_budget(budget: dict, title: str = ""):
    """The budget chart of one defect: per figure, each source's share of the combined variance.

    Parameters
    ----------
    budget : dict
        One defect's ``budget`` of ``uncertainty.json`` (figure -> sources, combined, ...).
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        Stacked horizontal bars (one per figure, 0-100 % of ``u_c^2``), each labelled with
        its value and expanded uncertainty.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = [f for f in FIGURES if f in budget]
    fig, ax = plt.subplots(figsize=(9.0, 0.65 * len(figs) + 1.9))
    fig.subplots_adjust(left=0.14, right=0.62, top=0.86, bottom=0.2)
    used = []
    for row, name in enumerate(figs):
        entry = budget[name]
        total = sum(s["contribution"] ** 2 for s in entry["sources"].values())
        left = 0.0
        for source in SOURCES:
            s = entry["sources"].get(source)
            if s is None or total <= 0:
                continue
            share = 100.0 * s["contribution"] ** 2 / total
            ax.barh(row, share, left=left, color=_COLOURS[source], edgecolor="white",
                    label=source.replace("_", " ") if source not in used else None)
            if source not in used:
                used.append(source)
            left += share
        label, unit = FIGURE_LABELS[name]
        ax.text(103.0, row, format_value(entry["value"], entry["expanded_uncertainty"], unit),
                va="center", fontsize=9)
    ax.set_yticks(range(len(figs)), [FIGURE_LABELS[f][0] for f in figs])
    ax.invert_yaxis()
    ax.set_xlim(0, 100)
    ax.set_xlabel("share of the combined variance u_c² (%)")
    ax.set_title(title or f"Uncertainty budget (GUM, k = {COVERAGE_FACTOR:g})", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=min(4, max(len(used), 1)), fontsize=8,
              frameon=False)
    return fig


def uncertainty_budget(result_dir, out=None, *, defect: int = 0) -> dict:
    """Values with their expanded uncertainty and the budget chart of a reconstruction folder.

    Parameters
    ----------
    result_dir : str or Path
        Folder written by ``workbench photometric reconstruct`` with an uncertainty option
        (``defects.json`` with ``uncertainty_k2``, ``uncertainty.json``).
    out : str or Path, optional
        PNG file for the budget chart of defect ``defect`` (not drawn when None).
    defect : int
        Defect id whose budget is drawn (0: the deepest).

    Returns
    -------
    dict
        ``defects``: per defect ``id``, ``kind``, ``values`` (figure -> value, mm),
        ``expanded_uncertainty`` (figure -> U, k = 2), ``text`` (figure ->
        ``"0.100 ± 0.006 mm (k = 2)"``); ``method``, ``noise_sigma``, ``tolerances``;
        ``chart``: the PNG path (or None); ``budget``: the drawn defect's budget.
    """
    folder = Path(result_dir)
    defects = _read_json(folder / "defects.json")["defects"]
    unc = _read_json(folder / "uncertainty.json")
    budgets = {d["id"]: d["budget"] for d in unc["defects"]}
    rows = []
    for rec in defects:
        k2 = rec.get("uncertainty_k2", {})
        rows.append({
            "id": rec["id"], "kind": rec["kind"],
            "values": {f: rec[f] for f in FIGURES},
            "expanded_uncertainty": {f: k2.get(f) for f in FIGURES},
            "text": {f: format_value(rec[f], k2.get(f), FIGURE_LABELS[f][1]) for f in FIGURES},
        })
    chart = None
    if out is not None:
        if defect not in budgets:
            raise InputError(f"defect: no defect with id {defect} (ids {sorted(budgets)})")
        import matplotlib.pyplot as plt

        kind = next(r["kind"] for r in rows if r["id"] == defect)
        fig = draw_budget(budgets[defect], f"Uncertainty budget of defect {defect} ({kind}), {unc['method']}, "
                          f"k = {COVERAGE_FACTOR:g}")
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        plt.close(fig)
        chart = Path(out)
        atomic_write_bytes(chart, buf.getvalue())
        chart = str(chart)
    return {"defects": rows, "method": unc["method"], "noise_sigma": unc["noise_sigma"],
            "tolerances": unc["tolerances"], "chart": chart, "budget": budgets.get(defect)}


def _trial(rng: np.random.Generator, opts: dict, method: str, mc_samples: int) -> dict | None:
    """One rendered scratch under randomly deviated lights, reconstructed with the nominal ones."""
    from datasets_synthetic.heightfields import u_scratch
    from datasets_synthetic.render import render
    from photometric.leds import light_field, point_lights
    from photometric.lights import ring_lights
    from photometric.pipeline import reconstruct
    from photometric.uncertainty.propagation import perturbed_lights

    size, h = opts["size"], opts["pixel_size"]
    L = ring_lights(opts["n_lights"], opts["slant_deg"])
    centre = (0.5 * (size - 1) + rng.uniform(-4, 4), 0.5 * (size - 1) + rng.uniform(-4, 4))
    hf = u_scratch(size, h, depth_mm=opts["depth_mm"], width_mm=opts["width_mm"], length_mm=opts["length_mm"],
                   center_px=centre, axis_deg=rng.uniform(-90.0, 90.0))
    if opts["rig"] == "near":
        from surfaces.grid import pixel_grid

        nominal = opts["light_distance_mm"] * L
        true = point_lights(nominal + rng.normal(0.0, opts["light_position_tolerance_mm"], nominal.shape),
                            point_lights(nominal).axes)
        x, y = pixel_grid(hf.shape, h)
        X = np.stack([x, y, hf.height], axis=-1)
        shading = np.einsum("khwc,hwc->khw", light_field(true, X), hf.normals)
        images = (opts["albedo"] * np.clip(shading, 0.0, None)
                  + rng.normal(0.0, opts["noise"], shading.shape)).astype(np.float32)
        inputs = {"light_positions": nominal}
        tol = Tolerances(noise_sigma=opts["noise"], light_position_tolerance_mm=opts["light_position_tolerance_mm"],
                         method=method, mc_samples=mc_samples, seed=int(rng.integers(1 << 31)))
    else:
        true_lights = perturbed_lights(L, math.radians(opts["light_tolerance_deg"]), rng)
        images = render(hf, true_lights, albedo=opts["albedo"], noise=opts["noise"], seed=rng)
        inputs = {"lights": L}
        tol = Tolerances(noise_sigma=opts["noise"], light_tolerance_deg=opts["light_tolerance_deg"], method=method,
                         mc_samples=mc_samples, seed=int(rng.integers(1 << 31)))
    t0 = time.perf_counter()
    res = reconstruct(images, pixel_size=h, uncertainty=tol, **inputs)
    seconds = time.perf_counter() - t0
    if not res.defects:
        return None
    rec, k2 = res.defects[0], res.uncertainty.defects[0]["uncertainty_k2"]
    truth = hf.defects[0]
    out = {"seconds": seconds, "uncertainty_seconds": res.summary["timings_s"]["uncertainty"]}
    for fig, key in (("max_depth_mm", "depth_mm"), ("mean_width_mm", "width_mm"), ("length_mm", "length_mm"),
                     ("area_mm2", "area_mm2"), ("volume_mm3", "volume_mm3")):
        out[fig] = (rec[fig] - truth[key], k2[fig])
    ok = res.valid & np.isfinite(res.height)
    truth_z = hf.height - hf.height[ok].mean()
    rows, cols = np.nonzero(ok)
    pick = rng.choice(rows.size, size=min(opts["pixels_per_trial"], rows.size), replace=False)
    r, c = rows[pick], cols[pick]
    out["height"] = (res.height[r, c] - truth_z[r, c], COVERAGE_FACTOR * res.uncertainty.height_u[r, c])
    return out


def coverage_interval(hits: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Confidence interval of a coverage estimated from ``hits`` of ``n`` independent trials.

    The Wilson score interval of a binomial proportion (Wilson 1927; scipy's
    ``binomtest(...).proportion_ci(method="wilson")``): it stays inside [0, 1] and keeps
    its coverage near 0 and 1, where the normal approximation does not. 190 of 200 trials
    (95 %) give about [91.0, 97.3] %.

    Parameters
    ----------
    hits : int
        Trials whose interval held the truth.
    n : int
        Independent trials (>= 1).
    confidence : float
        Confidence level of the interval, in (0, 1).

    Returns
    -------
    (low, high) : tuple of float
        Bounds of the coverage, fractions.
    """
    from scipy.stats import binomtest

    n = int(n)
    if n < 1:
        raise InputError(f"n: need at least 1 trial, got {n}")
    if not 0 <= hits <= n:
        raise InputError(f"hits: must lie in [0, n = {n}], got {hits}")
    if not 0.0 < confidence < 1.0:
        raise InputError(f"confidence: must lie in (0, 1), got {confidence}")
    ci = binomtest(int(hits), n).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def coverage_study(
    n_trials: int = 200,
    method: str = "linear",
    *,
    size: int = 160,
    pixel_size: float = 0.05,
    n_lights: int = 3,
    slant_deg: float = 45.0,
    light_tolerance_deg: float = 0.5,
    noise: float = 0.002,
    depth_mm: float = 0.05,
    width_mm: float = 0.4,
    length_mm: float = 5.0,
    albedo: float = 0.8,
    pixels_per_trial: int = 20,
    mc_samples: int = 30,
    seed: int = 0,
    rig: str = "far",
    light_distance_mm: float = 150.0,
    light_position_tolerance_mm: float = 0.5,
) -> dict:
    """Coverage of the stated 95 % intervals over independent rendered trials.

    Each trial renders a U-scratch (random sub-pixel centre and axis) with the TRUE lights,
    each deviated from the nominal ring by independent tangent errors of standard deviation
    ``light_tolerance_deg`` per axis, plus Gaussian noise ``noise``; it is reconstructed
    with the nominal lights and those tolerances stated, and the intervals
    ``value ± U`` (k = 2) are checked against the true depth, width, length, area, volume
    and the true height (zero mean over the valid pixels) at ``pixels_per_trial`` random
    pixels.

    Parameters
    ----------
    n_trials : int
        Independent trials (the issue asks for at least 200 in the benchmark).
    method : {"linear", "montecarlo"}
        Propagation of the reconstruction.
    size, pixel_size :
        Image side (px) and pixel size (mm).
    n_lights, slant_deg :
        Nominal ring of lights.
    light_tolerance_deg, noise :
        The stated (and simulated) standard uncertainties.
    depth_mm, width_mm, length_mm, albedo :
        The scratch and the plate's albedo.
    pixels_per_trial : int
        Random pixels per trial for the height coverage.
    mc_samples : int
        Monte Carlo repetitions (``method="montecarlo"``).
    seed : int
        Seed of the trials.
    rig : {"far", "near"}
        ``far``: distant lights deviated in direction; ``near``: LEDs at
        ``light_distance_mm`` on the same ring (point lights, inverse-square falloff,
        orthographic camera) whose TRUE positions deviate by ``light_position_tolerance_mm``
        per coordinate (rendered with :func:`photometric.leds.light_field`).
    light_distance_mm, light_position_tolerance_mm :
        The near-field rig.

    Returns
    -------
    dict
        Per figure (``max_depth_mm``, ``mean_width_mm``, ``length_mm``, ``area_mm2``,
        ``volume_mm3``, ``height``): ``coverage`` (fraction of intervals holding the
        truth), ``coverage_interval`` (its 95 % Wilson interval over the trials, the
        independent units; :func:`coverage_interval`), ``missed_target`` (True only when
        that interval lies wholly outside :data:`TARGET_COVERAGE`), ``mean_U``,
        ``error_mean``, ``error_sd``, ``error_rms``; ``trials``,
        ``missed`` (trials without a detected defect), ``seconds`` (whole study),
        ``seconds_per_trial`` and ``uncertainty_seconds_per_trial``, and the options.
    """
    n = int(n_trials)
    if n < 1:
        raise InputError(f"n_trials: need at least 1 trial, got {n_trials}")
    if rig not in ("far", "near"):
        raise InputError(f"rig: expected 'far' or 'near', got {rig!r}")
    for value, name in ((light_tolerance_deg, "light_tolerance_deg"), (noise, "noise"),
                        (light_position_tolerance_mm, "light_position_tolerance_mm")):
        positive(value, name, allow_zero=True)
    opts = {"size": int(size), "pixel_size": float(pixel_size), "n_lights": int(n_lights),
            "slant_deg": float(slant_deg), "light_tolerance_deg": float(light_tolerance_deg), "noise": float(noise),
            "depth_mm": float(depth_mm), "width_mm": float(width_mm), "length_mm": float(length_mm),
            "albedo": float(albedo), "pixels_per_trial": int(pixels_per_trial), "rig": rig,
            "light_distance_mm": float(light_distance_mm),
            "light_position_tolerance_mm": float(light_position_tolerance_mm)}
    t0 = time.perf_counter()
    trials = []
    for rng in (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(n)):
        trials.append(_trial(rng, opts, method, mc_samples))
    done = [t for t in trials if t is not None]
    out: dict = {"method": method, "trials": n, "missed": n - len(done), "options": opts,
                 "seconds": time.perf_counter() - t0}
    for key in (*FIGURES, "height"):
        err = np.concatenate([np.atleast_1d(t[key][0]) for t in done]) if done else np.zeros(0)
        U = np.concatenate([np.atleast_1d(t[key][1]) for t in done]) if done else np.zeros(0)
        held = np.abs(err) <= U
        # the pixels of one trial share its lights and integration: independent are the trials
        hits = round(float(held.mean()) * len(done)) if err.size else 0
        low, high = coverage_interval(hits, len(done)) if done else (float("nan"), float("nan"))
        out[key] = {
            "coverage": float(held.mean()) if err.size else float("nan"),
            "coverage_interval": [low, high],
            "missed_target": bool(high < TARGET_COVERAGE[0] or low > TARGET_COVERAGE[1]),
            "mean_U": float(U.mean()) if U.size else float("nan"),
            "error_mean": float(err.mean()) if err.size else float("nan"),
            "error_sd": float(err.std(ddof=1)) if err.size > 1 else float("nan"),
            "error_rms": float(np.sqrt(np.mean(err**2))) if err.size else float("nan"),
            "samples": int(err.size),
        }
    out["seconds_per_trial"] = float(np.mean([t["seconds"] for t in done])) if done else float("nan")
    out["uncertainty_seconds_per_trial"] = (float(np.mean([t["uncertainty_seconds"] for t in done]))
                                            if done else float("nan"))
    return out
