"""``workbench surfaces sweep|helix``: kinematic surfaces (seed 004) into the shared model.

Both commands build the kinematic surface, interpolate a sampled grid with a bicubic
B-spline surface (seed 003), convert it exactly to Bezier patches, tessellate and
measure it, and write: the mesh (``--out``), the patches (same name, ``.npz``) and a
JSON summary (same name, ``.json``; or ``--summary``) holding every printed number.
``--caps`` closes the two open ends of a tube (a closed cross-section: a pipe, a coil
spring) with flat caps in the mesh (:func:`surfaces.kinematic.cap_ends`), so the mesh is
a watertight solid with a volume.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from workbench.commands.common import add_command, mesh_out, write_summary
from surfaces.validate import InputError


def register(sub) -> None:
    """Add ``sweep`` and ``helix`` to the ``surfaces`` group (see :mod:`workbench.commands`)."""
    p = add_command(
        sub,
        "sweep",
        _sweep,
        help="kinematic surface: a generatrix curve swept along a directrix curve (JSON curves)",
        description="Sweep a generatrix (cross-section in the directrix's normal plane, "
        "2D (a, b) -> a N + b B, or 3D local) along a directrix with a fixed, Frenet or "
        "rotation-minimising frame and optional scale and twist laws (seed 004). Curve files: "
        '{"points": [[x, y, z], ...], "degree": 3, "closed": false, "method": "chord"} '
        '(interpolated B-spline), {"type": "bspline", "control": [...], "knots": [...], '
        '"degree": 3}, '
        '{"type": "line", "start": [...], "end": [...]}, {"type": "circle", "radius": r, '
        '"center": [0, 0]}, {"type": "helix", "radius": r, "pitch": p, "turns": n}.',
    )
    p.add_argument("--generatrix", required=True, help="generatrix curve, JSON file (local frame)")
    p.add_argument("--directrix", required=True, help="directrix curve, JSON file (model frame)")
    p.add_argument("--frame", choices=("fixed", "frenet", "rmf"), default="rmf",
                   help="moving frame along the directrix (default rmf: rotation-minimising)")
    p.add_argument("--scale", type=float, nargs="+", metavar="S",
                   help="scale law: one value (constant) or START END (linear along the directrix)")
    p.add_argument("--twist", type=float, default=0.0,
                   help="total twist in degrees, reached linearly along the directrix (default 0)")
    p.add_argument("--up", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="direction of the first normal N at the start (fixed and rmf frames)")
    _common(p, samples_u=32, samples_v=64)

    p = add_command(
        sub,
        "helix",
        _helix,
        help="helical surfaces: coil spring (circle profile) or screw thread (thread profile)",
        description="Helical kinematic surfaces about the z axis. --profile circle: a wire of "
        "radius --wire-radius swept along the helix (coil spring, rotation-minimising frame). "
        "--profile thread: a round thread profile of depth --depth swept helically with the "
        "same pitch (screw thread; --radius is the major radius).",
    )
    p.add_argument("--radius", type=float, required=True,
                   help="helix radius (circle) or major thread radius (thread), model units")
    p.add_argument("--pitch", type=float, required=True, help="rise per turn (> 0)")
    p.add_argument("--turns", type=float, required=True, help="number of turns (> 0)")
    p.add_argument("--profile", choices=("circle", "thread"), default="circle",
                   help="circle: coil spring; thread: screw thread (default circle)")
    p.add_argument("--wire-radius", type=float,
                   help="wire radius of the coil (default: min(radius, pitch) / 5)")
    p.add_argument("--depth", type=float, help="thread depth (default: 0.3 * pitch)")
    _common(p, samples_u=24, samples_v=None)


def _common(p: argparse.ArgumentParser, samples_u: int, samples_v: int | None) -> None:
    p.add_argument("--samples-u", type=int, default=samples_u,
                   help=f"grid samples along the generatrix (default {samples_u})")
    p.add_argument("--samples-v", type=int, default=samples_v,
                   help="grid samples along the motion (default "
                   + (f"{samples_v})" if samples_v else "24 per turn)"))
    p.add_argument("--mesh-samples", type=int, default=4,
                   help="subdivisions per patch side in the written mesh (default 4)")
    p.add_argument("--out", required=True, help="mesh file to write (.ply, .obj or .stl)")
    p.add_argument("--summary", help="JSON summary path (default: --out with suffix .json)")
    p.add_argument("--caps", action="store_true",
                   help="close the tube's two open ends with flat caps in the mesh, making a watertight "
                   "solid (needs a closed cross-section: a closed generatrix, the coil spring)")


def _sweep(args: argparse.Namespace) -> int:
    from surfaces import kinematic
    from surfaces.curves import load_curve

    out = mesh_out(args.out)
    generatrix = load_curve(args.generatrix)
    directrix = load_curve(args.directrix)
    scale = None
    if args.scale:
        if len(args.scale) > 2:
            raise InputError(f"--scale: give one value or START END, got {len(args.scale)} values")
        scale = args.scale[0] if len(args.scale) == 1 else tuple(args.scale)
    surface = kinematic.sweep(
        generatrix, directrix, frame=args.frame, scale=scale, twist=math.radians(args.twist),
        up=args.up,
    )
    info = {
        "command": "sweep",
        "generatrix": str(args.generatrix),
        "directrix": str(args.directrix),
        "frame": args.frame,
        "scale": args.scale,
        "twist_deg": args.twist,
    }
    return _finish(surface, args, out, info, args.samples_v)


def _helix(args: argparse.Namespace) -> int:
    from surfaces import kinematic

    out = mesh_out(args.out)
    info = {"command": "helix", "profile": args.profile, "radius": args.radius,
            "pitch": args.pitch, "turns": args.turns}
    if args.profile == "circle":
        wire = args.wire_radius
        if wire is None:
            wire = min(args.radius, args.pitch) / 5
        surface = kinematic.coil_spring(args.radius, args.pitch, args.turns, wire)
        length = args.turns * math.hypot(2 * math.pi * args.radius, args.pitch)
        info.update(
            wire_radius=wire,
            centreline_length=length,
            # tube theorem: exact for a circular section normal to a non-overlapping path
            closed_form_area=2 * math.pi * wire * length,
            closed_form_volume=math.pi * wire * wire * length,
        )
    else:
        depth = args.depth if args.depth is not None else 0.3 * args.pitch
        # the thread's profile is open: with --caps it is closed along its root chord (the ridge's section)
        surface = kinematic.screw_thread(args.radius, args.pitch, args.turns, depth, closed=args.caps)
        info.update(depth=depth)
        if args.caps:
            r0 = args.radius - depth
            info.update(profile_closed="along the root chord (r = major radius - depth): the solid is the "
                        "thread's ridge, without the core cylinder",
                        closed_form_volume=math.pi * args.turns * args.pitch
                        * ((r0 + depth / 2) ** 2 + depth**2 / 8 - r0**2))
    samples_v = args.samples_v or max(8, int(math.ceil(24 * args.turns)))
    return _finish(surface, args, out, info, samples_v)


def _finish(surface, args: argparse.Namespace, out: Path, info: dict, samples_v: int) -> int:
    from surfaces.io import save_patches, write_mesh
    from surfaces.measure import area_and_volume
    from surfaces.mesh import tessellate

    from surfaces.kinematic import cap_ends

    if args.caps and (not surface.closed_u or surface.closed_v):
        raise InputError("--caps: flat caps close a tube with a closed cross-section and two open ends; "
                         + ("this cross-section (generatrix) is open" if not surface.closed_u
                            else "this surface closes on itself"))
    t0 = time.perf_counter()
    patches = surface.to_bezier(args.samples_u, samples_v)
    mesh = tessellate(patches, args.mesh_samples)
    caps = {}
    if args.caps:
        mesh, cap_area = cap_ends(mesh)
        caps = {"caps": "flat", "cap_area": cap_area, "mesh_volume": abs(mesh.signed_volume())}
    summary = {
        **info,
        "samples": [int(args.samples_u), int(samples_v)],
        "patch_rows": patches.shape[0],
        "patch_cols": patches.shape[1],
        "closed_u": patches.closed_u,
        "closed_v": patches.closed_v,
        **area_and_volume(patches),
        "n_vertices": mesh.n_vertices,
        "n_triangles": mesh.n_triangles,
        "watertight": mesh.is_watertight(),
        **caps,
    }
    summary["time_s"] = time.perf_counter() - t0
    write_mesh(mesh, out)
    npz = save_patches(patches, out.with_suffix(".npz"))
    json_path = Path(args.summary) if args.summary else out.with_suffix(".json")
    summary.update(out=str(out), patches_file=str(npz), summary_file=str(json_path))
    write_summary(json_path, summary)
    volume = summary["volume"]
    print(
        f"{patches.shape[0]}x{patches.shape[1]} patches, {mesh.n_triangles} triangles, "
        f"area {summary['area']:.6g}, volume "
        + (f"{volume:.6g}" if volume is not None else "n/a (open surface)")
        + (f", closed by flat caps (mesh volume {caps['mesh_volume']:.6g})" if caps else "")
        + ("; the open thread profile was closed along its root chord (the ridge alone)"
           if "profile_closed" in summary else "")
        + f"; wrote {out}, {npz}, {json_path}"
    )
    return 0
