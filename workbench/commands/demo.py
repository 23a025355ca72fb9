"""``workbench demo``: the end-to-end demo and its HTML report."""

from __future__ import annotations

import argparse
import sys

from workbench.commands.common import add_command


def run(args: argparse.Namespace) -> int:
    """Run the demo, print a short summary (all numbers are in DIR/demo.json)."""
    from workbench.demo import run_demo

    if args.figures_only is not None:
        from workbench.demo.figures import redraw

        done = redraw(args.figures_only, shared=args.shared_data)
        print(f"redrew {len(done['redrawn'])} figures into {args.figures_only}/figures and {done['report']}")
        for name, reason in done["skipped"].items():
            print(f"workbench: warning: {name} not redrawn: {reason}", file=sys.stderr)
        return 0
    summary = run_demo(args.out, quick=args.quick, shared=args.shared_data, progress=True)
    print(f"report: {summary['report']} ({len(summary['figures'])} figures, "
          f"{summary['seconds']:.0f} s); numbers in {args.out}/demo.json")
    insp = summary.get("inspection", {})
    if "normal_error_mean_deg" in insp:
        print(f"inspection: normals {insp['normal_error_mean_deg']:.2f} deg mean error, height RMS "
              f"{insp['height_rms_error_mm'] * 1000:.1f} um")
    real = summary.get("real", {})
    if "triad_mean_error_deg" in real:
        print(f"bear: triad {real['triad_mean_error_deg']:.2f} deg (baseline 11.74), 14 images "
              f"{real['all14_mean_error_deg']:.2f} deg (baseline 9.60)")
    kidney = summary.get("ct", {}).get("kidney")
    if kidney:
        print(f"kidney: volume error {kidney['volume_error_percent']:+.2f} %, mean surface distance "
              f"{kidney['surface_distance_mean_mm']:.3f} mm")
    for roi in ("Heart", "Lt Lung"):
        if roi in summary.get("ct", {}):
            print(f"{roi}: {summary['ct'][roi]['volume_cc']:.2f} cc")
    for section, reason in summary["unavailable"].items():
        print(f"{section}: not available: {reason}")
    return 0


def register(subparsers) -> None:
    """Add the top-level ``demo`` command (see :mod:`workbench.commands`)."""
    p = add_command(
        subparsers,
        "demo",
        run,
        help="run the end-to-end demo and write DIR/report.html",
        description="Run every part of the workbench on synthetic scenes with exact truth and on "
        "the shared real data (when present), and write a self-contained HTML report with every "
        "figure, number and the command that reproduces it.",
    )
    p.add_argument("--out", default="demo_out", help="output folder (default demo_out)")
    p.add_argument("--quick", action="store_true",
                   help="reduced sizes (the CI smoke test; well under a minute)")
    p.add_argument("--figures-only", default=None, metavar="DIR",
                   help="redraw every figure of the demo folder DIR from the data saved beside the PNGs "
                   "(figures/<name>.json, .npz) and embed them in DIR/report.html again; runs no pipeline")
    p.add_argument("--shared-data", default=None,
                   help="real-data folder (default $WORKBENCH_SHARED_DATA or ../shared/data)")
