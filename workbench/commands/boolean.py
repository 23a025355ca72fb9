"""``workbench surfaces boolean``: union, intersection or difference of two closed meshes.

Writes the result mesh (``--out C.ply``, format by suffix: .ply, .obj, .stl)
and, next to it, a JSON summary with the volumes (``C.json``); optionally the
intersection curve as polylines (``--curves``) and a Loop-subdivision
smoothing of the result (``--smooth N``).

An empty result (disjoint solids, a difference that removes everything) is a
valid answer: the mesh file is still written, with no triangles, atomically over
any older file at ``--out`` (so no stale mesh survives), the JSON says
``"empty": true`` and stderr says so in one line; the exit code is 0.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from workbench.commands.common import add_command, mesh_out, read_model, write_summary
from surfaces.validate import InputError

#: what the summary's numbers are measured in (mesh files carry no unit)
UNITS = {"length": "as the input files (workbench writes mm)", "area": "length^2", "volume": "length^3"}


def register(subparsers) -> None:
    """Add ``boolean`` to the ``surfaces`` group (see :mod:`workbench.commands`)."""
    from surfaces.boolean import OPS
    from surfaces.smooth import FILTERS

    p = add_command(
        subparsers,
        "boolean",
        run,
        help="union / intersection / difference of two closed meshes (manifold3d)",
        description="Set operation on two solids bounded by closed, outward oriented triangle "
        "meshes (PLY/OBJ/STL). Writes the result mesh and a JSON summary with the volumes "
        "(same name as --out, suffix .json). Lengths are those of the input files (workbench "
        "writes mm), volumes their cube. An empty result writes a mesh with no triangles over "
        "--out and says so on stderr.",
    )
    p.add_argument("a", type=Path, help="first closed solid A: mesh (.ply, .obj, .stl) or patch file (.npz)")
    p.add_argument("b", type=Path, help="second closed solid B: mesh (.ply, .obj, .stl) or patch file (.npz)")
    p.add_argument("--op", choices=OPS, required=True, help="operation; difference is A minus B")
    p.add_argument("--out", type=Path, required=True, help="result mesh (.ply, .obj or .stl)")
    p.add_argument(
        "--repair",
        action="store_true",
        help="weld, drop degenerate/duplicate triangles, orient and fill small holes in the "
        "inputs instead of refusing them (what was repaired goes into the JSON)",
    )
    p.add_argument(
        "--smooth",
        type=int,
        default=0,
        metavar="N",
        help="Loop subdivision steps applied to the result (each x4 triangles; default 0)",
    )
    p.add_argument(
        "--filter",
        choices=FILTERS,
        default="taubin",
        help="filter after subdivision when --smooth > 0 (default taubin)",
    )
    p.add_argument(
        "--filter-iterations",
        type=int,
        default=10,
        help="filter steps after subdivision (default 10)",
    )
    p.add_argument(
        "--curves",
        type=Path,
        default=None,
        help="also write the intersection curve polylines to this JSON file",
    )


def run(args: argparse.Namespace) -> int:
    """Run the set operation and write the mesh, the summary and optionally the curves.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of ``workbench surfaces boolean``.

    Returns
    -------
    int
        0 on success.
    """
    from surfaces.boolean import boolean
    from surfaces.io import write_mesh
    from surfaces.smooth import loop_smooth

    mesh_out(args.out)
    if args.smooth < 0 or args.filter_iterations < 0:
        raise InputError("--smooth, --filter-iterations: must be >= 0")
    a = read_model(args.a)
    b = read_model(args.b)
    result = boolean(a, b, args.op, repair=args.repair, names=(str(args.a), str(args.b)))
    mesh = result.mesh
    summary = {"a": str(args.a), "b": str(args.b), "out": str(args.out), "units": UNITS, **result.summary()}
    if args.smooth > 0 and len(mesh.triangles):
        mesh = loop_smooth(mesh, args.smooth, filter=args.filter, filter_iterations=args.filter_iterations)
        summary["smooth"] = {
            "iterations": args.smooth,
            "filter": args.filter,
            "filter_iterations": args.filter_iterations,
            "volume_smoothed": mesh.signed_volume(),
            "n_triangles": len(mesh.triangles),
        }
    json_path = args.out.with_suffix(".json")
    summary["empty"] = len(mesh.triangles) == 0
    # an empty result is a valid answer (disjoint solids); it still replaces an older mesh at --out
    write_mesh(mesh, args.out)
    if args.curves is not None:
        write_summary(
            args.curves,
            {
                "units": "as the input meshes",
                "curves": [
                    {"closed": closed, "points": np.asarray(c).tolist()}
                    for c, closed in zip(result.curves, result.curves_closed)
                ],
            },
        )
        summary["curves_file"] = str(args.curves)
    summary["summary_file"] = str(json_path)
    write_summary(json_path, summary)
    if summary["empty"]:
        print(f"workbench: warning: the {args.op} is empty; {args.out} holds a mesh with no triangles",
              file=sys.stderr)
    print(
        f"{args.op}: volume A {result.volume_a:.6g}, B {result.volume_b:.6g}, "
        f"result {result.volume:.6g} (length units^3 of the inputs); {summary['n_triangles']} triangles, "
        f"watertight {summary['watertight']}, {summary['n_curves']} intersection curve(s)"
    )
    if "smooth" in summary:
        print(
            f"smoothed ({args.smooth} Loop step(s), {args.filter}): volume {summary['smooth']['volume_smoothed']:.6g}"
        )
    print(f"wrote {args.out} and {json_path}")
    return 0
