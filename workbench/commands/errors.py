"""``workbench photometric errors``: accuracy of the triad against deviated light directions.

Seed 002(a): how much deviations of the light directions spoil the reconstructed
derivatives, and which deviations keep ``|dp|, |dq|`` within a tolerance over a
range of derivatives. Writes ``report.json``, ``report.md`` and PNG plots.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from workbench.commands.common import add_command, load_npy
from surfaces.validate import InputError


def register(subparsers) -> None:
    """Add the ``errors`` sub-command to the ``photometric`` group.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``photometric`` group's sub-parser collection.
    """
    p = add_command(
        subparsers,
        "errors",
        run,
        help="error of p, q, normals and height against deviated light directions; tolerances",
        description="Accuracy study of photometric stereo when the real light directions deviate "
        "from the nominal ones (seed 002(a)): error maps over two deviations, first-order "
        "sensitivity, Monte Carlo, operating limits of the deviations and of the derivative range, "
        "light conditioning, and a rendered crack study.",
    )
    p.add_argument("--lights", required=True,
                   help="nominal light directions: text file with one 'x y z' row per light "
                        "(DiLiGenT light_directions.txt) or 'slant azimuth' in degrees, .npy or .json "
                        "(photometric.io.load_lights)")
    p.add_argument("--deviation-max", type=float, default=5.0,
                   help="half-width of the deviation grids of the error maps and curves, degrees (default 5)")
    p.add_argument("--derivative-range", type=float, default=1.0,
                   help="derivative range D: the error is taken over |p|, |q| <= D (default 1.0)")
    p.add_argument("--tolerance", type=float, default=0.05,
                   help="required accuracy eps of p and q (absolute, default 0.05)")
    p.add_argument("--surface", default=None,
                   help="optional height field (.npy, (H, W), mm; row 0 is the top of the image) for "
                        "error maps over its slopes and the height error after integration")
    p.add_argument("--pixel-size", type=float, default=1.0,
                   help="pixel pitch of --surface, mm (default 1.0)")
    p.add_argument("--grid", type=int, default=41,
                   help="grid points per axis of the deviation maps and derivative square (default 41)")
    p.add_argument("--sigma", type=float, default=1.0,
                   help="RMS angle of each light's random deviation in the Monte Carlo study (isotropic "
                        "Gaussian in the light's tangent plane), degrees (default 1)")
    p.add_argument("--samples", type=int, default=20000,
                   help="Monte Carlo samples (default 20000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (Monte Carlo, crack scene; default 0)")
    p.add_argument("--no-crack", action="store_true",
                   help="skip the rendered crack study")
    p.add_argument("--crack-size", type=int, default=128,
                   help="image side of the crack study, pixels (default 128)")
    p.add_argument("--out", default="photometric_errors",
                   help="output folder (default ./photometric_errors)")


def _read_surface(path: str) -> np.ndarray:
    """The ``--surface`` height field: a 2-D ``.npy`` array of at least 2 x 2 pixels."""
    h = load_npy(path, "--surface")
    if h.ndim != 2 or min(h.shape) < 2:
        raise InputError(f"--surface: expected a 2-D height field, got shape {h.shape}")
    return np.asarray(h, dtype=float)


def run(args: argparse.Namespace) -> int:
    """Run the study and write the report (the ``errors`` sub-command).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options (see :func:`register`).

    Returns
    -------
    int
        Exit code 0.
    """
    from tqdm import tqdm

    from photometric.io import load_lights
    from workbench.studies.errors_analysis import analyse
    from workbench.studies.errors_report import write_report

    lights = load_lights(args.lights)
    if args.samples < 100:
        raise InputError(f"--samples: need at least 100 samples, got {args.samples}")
    if args.crack_size < 32:
        raise InputError(f"--crack-size: need at least 32 pixels, got {args.crack_size}")
    surface = _read_surface(args.surface) if args.surface else None
    stages = 6 + (surface is not None) + (not args.no_crack)  # the steps analyse() reports
    # delay: no bar at all before an error in the first half second
    with tqdm(total=stages, desc="errors", unit="stage", leave=False, delay=0.5) as bar:
        def progress(label: str) -> None:
            bar.set_postfix_str(label, refresh=False)  # update() draws it, after the delay
            bar.update(1)

        report = analyse(
            lights,
            deviation_max=args.deviation_max,
            derivative_range=args.derivative_range,
            tolerance=args.tolerance,
            surface=surface,
            pixel_size=args.pixel_size,
            grid=args.grid,
            sigma_deg=args.sigma,
            samples=args.samples,
            seed=args.seed,
            crack=not args.no_crack,
            crack_size=args.crack_size,
            progress=progress,
        )
        files = write_report(report, args.out)
    _summary(report, Path(args.out), files)
    return 0


def _summary(report: dict, out: Path, files: dict) -> None:
    inp = report["inputs"]
    eps, D = inp["tolerance"], inp["derivative_range"]
    print(f"lights: {len(inp['lights'])}, condition number {report['configuration']['condition_number']:.4g}")
    print(f"allowed deviation for |dp|, |dq| <= {eps:g} over |p|, |q| <= {D:g} (any direction, deg):")
    for row in report["tolerances"]:
        t = row["any"]
        more = " (or more)" if t["saturated"] else ""
        print(f"  lights {','.join(map(str, row['lights']))}: {t['value']:.4g}{more}")
    for row in report["derivative_range_limits"]:
        t = row["single_light"]
        print(f"  one light off by {row['deviation_deg']:g} deg: largest D {t['value']:.4g}")
    cs = report.get("crack_study", {})
    for c in cs.get("cases", []):
        print(f"  crack, light 1 slant {c['deviations_deg'][0][0]:g} deg: max |dp| measured "
              f"{c['max_abs_dp_measured']:.3g} / predicted {c['max_abs_dp_predicted']:.3g}, "
              f"depth {c['depth_mm']:.4g} mm (true {cs['true_depth_mm']:.4g}; "
              f"{c['depth_change_mm']:+.2g} mm from the deviation)")
    if "depth_nominal_mm" in cs:
        print(f"  crack depth with exact lights {cs['depth_nominal_mm']:.4g} mm against the true "
              f"{cs['true_depth_mm']:.4g}: not the lights, the integration of a V only a few pixels wide rounds "
              "its floor; that bias is in every row, the change from it is the deviation's effect")
    print(f"wrote {out / files['json']}, {out / files['markdown']} and {len(files['plots'])} plots")
