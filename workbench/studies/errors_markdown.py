"""The Markdown text of the light-deviation accuracy study (``report.md``)."""

from __future__ import annotations

from workbench.studies.errors_plots import axis_label

__all__ = ["markdown"]


def _fmt(x, digits: int = 3) -> str:
    if x is None:
        return "-"
    if isinstance(x, dict):
        s = _fmt(x.get("value"), digits)
        if x.get("saturated"):
            return f">= {s}" if (x.get("value") or 0) > 0 else "0 (a flat surface already exceeds eps)"
        return s
    return f"{x:.{digits}g}"


def markdown(report: dict, pictures: dict) -> str:
    """Markdown report of an accuracy study, with its figures linked.

    Parameters
    ----------
    report : dict
        The result of :func:`workbench.studies.errors_analysis.analyse`.
    pictures : dict
        File names of the figures by kind (:func:`workbench.studies.errors_plots.write_plots`).

    Returns
    -------
    str
        The text of ``report.md``.
    """
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
            f"- {axis_label(m['axis1'])} against {axis_label(m['axis2'])}, normals over the {m['derivatives']}: "
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
        for c in report["surface_height_error"]:
            lines.append(
                f"- light {c['lights'][0]} {c['deviation']}: max |dp| {c['max_abs_dp']:.3g}, "
                f"max |dq| {c['max_abs_dq']:.3g}, RMS height error {c['rms_dh_mm']:.3g} mm, "
                f"max {c['max_abs_dh_mm']:.3g} mm"
            )
        if pictures.get("surface"):
            lines += ["", f"![height error]({pictures['surface']})"]
        lines.append("")
    cs = report.get("crack_study")
    if cs is not None:
        lines += [
            "## Crack study",
            "",
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
