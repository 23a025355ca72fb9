"""``workbench surfaces render``: headless ray-cast pictures of meshes and patch models."""

from __future__ import annotations

import argparse
import time

import numpy as np

from workbench.commands.common import add_command, parse_vector, read_model, write_summary
from surfaces.validate import InputError


def picture(args: argparse.Namespace, geometry, *, colors=None) -> tuple[np.ndarray, dict]:
    """Render ``geometry`` as the parsed options ask; returns the RGB picture and summary numbers."""
    from surfaces.camera import Camera
    from surfaces.colormap import scalar_range
    from surfaces.distance import deviation
    from surfaces.mesh import tessellate
    from surfaces.render import parse_size, render

    mesh = tessellate(geometry, samples=args.samples) if hasattr(geometry, "control") else geometry
    verts = np.asarray(mesh.vertices)
    summary: dict = {
        "vertices": int(len(verts)),
        "triangles": int(len(mesh.triangles)),
        "size": list(parse_size(args.size)),
        "colour": args.colour,
    }
    scalars, label = None, ""
    if args.colour == "height":
        scalars, label = verts[:, 2], "height z"
    elif args.colour == "deviation":
        if not args.reference:
            raise InputError("--colour deviation: give the reference surface with --reference FILE")
        scalars = deviation(verts, read_model(args.reference))
        label = "deviation"
        summary.update(
            reference=str(args.reference),
            deviation_mean_abs=float(np.mean(np.abs(scalars))),
            deviation_rms=float(np.sqrt(np.mean(scalars**2))),
            deviation_max_abs=float(np.max(np.abs(scalars))),
        )
    if scalars is not None:
        lo, hi = scalar_range(scalars, args.vmin, args.vmax)
        if args.colour == "deviation" and args.vmin is None and args.vmax is None:
            # a symmetric range keeps zero deviation at the colour map's centre
            lo, hi = -max(abs(lo), abs(hi)), max(abs(lo), abs(hi))
        summary.update(scalar_min=lo, scalar_max=hi)
    else:
        lo = hi = None
    if args.eye or args.target:
        if not (args.eye and args.target):
            raise InputError("--eye/--target: give both for an explicit camera")
        cams = [
            Camera(
                parse_vector(args.eye, "--eye"),
                parse_vector(args.target, "--target"),
                parse_vector(args.up, "--up"),
                args.fov if args.projection == "perspective" else None,
                args.ortho_height
                or float(np.linalg.norm(verts.max(axis=0) - verts.min(axis=0))) * 1.05,
            )
        ]
        summary["views"] = ["camera"]
    else:
        cams = [v.strip() for v in args.views.split(",") if v.strip()]
        summary["views"] = cams
    cmap = args.cmap or ("coolwarm" if args.colour == "deviation" else "viridis")
    start = time.perf_counter()
    img = render(
        geometry if args.net else mesh,
        cams,
        args.size,
        projection=args.projection,
        fov_deg=args.fov,
        net=args.net,
        scalars=scalars,
        colors=colors,
        cmap=cmap,
        vmin=lo,
        vmax=hi,
        colorbar_label=label,
        shadows=args.shadows,
        antialias=args.antialias,
        samples=args.samples,
    )
    summary["seconds"] = round(time.perf_counter() - start, 4)
    return img, summary


def add_picture_options(p: argparse.ArgumentParser, *, default_views: str = "iso") -> None:
    """Options shared by ``surfaces render`` and ``view --png``."""
    p.add_argument("--views", default=default_views,
                   help="comma-separated standard views tiled in one picture: front, back, side, "
                   f"left, top, bottom, iso (default {default_views})")
    p.add_argument("--size", default="1024x768", help="picture size WIDTHxHEIGHT in pixels")
    p.add_argument("--colour", "--color", choices=("none", "height", "deviation"), default="none",
                   help="colour by vertex height (z) or by signed deviation from --reference")
    p.add_argument("--reference", help="reference mesh or patch file for --colour deviation")
    p.add_argument("--cmap", help="matplotlib colour map (default viridis; coolwarm for deviation)")
    p.add_argument("--vmin", type=float, help="value at the bottom of the colour bar")
    p.add_argument("--vmax", type=float, help="value at the top of the colour bar")
    p.add_argument("--net", action="store_true",
                   help="overlay the Bezier control net (patch .npz files only)")
    p.add_argument("--shadows", action="store_true", help="cast shadow rays towards the light")
    p.add_argument("--projection", choices=("orthographic", "perspective"), default="orthographic",
                   help="projection of the views")
    p.add_argument("--fov", type=float, default=30.0,
                   help="vertical field of view in degrees for --projection perspective")
    p.add_argument("--eye", help="explicit camera position 'x,y,z' (replaces --views)")
    p.add_argument("--target", help="explicit camera target 'x,y,z'")
    p.add_argument("--up", default="0,0,1", help="explicit camera up vector 'x,y,z' (default 0,0,1)")
    p.add_argument("--ortho-height", type=float,
                   help="window height in model units for an explicit orthographic camera")
    p.add_argument("--samples", type=int, default=8, help="tessellation points per patch edge")
    p.add_argument("--antialias", type=int, default=1,
                   help="supersampling factor (2 casts 4 rays per pixel)")


def run(args: argparse.Namespace) -> int:
    """Render FILE to ``--out`` and write the numbers to a JSON file beside it."""
    from surfaces.io import write_png

    geometry = read_model(args.file)
    img, summary = picture(args, geometry)
    out = write_png(args.out, img)
    summary = {"file": str(args.file), "out": str(out), **summary}
    json_path = write_summary(args.json or out.with_suffix(".json"), summary)
    extra = ""
    if "deviation_rms" in summary:
        extra = (f", deviation rms {summary['deviation_rms']:.4g}, "
                 f"max |d| {summary['deviation_max_abs']:.4g}")
    print(f"wrote {out} ({img.shape[1]}x{img.shape[0]}, {summary['triangles']} triangles, "
          f"{summary['seconds']:.2f} s{extra}); numbers in {json_path}")
    return 0


def register(subparsers) -> None:
    """Add ``render`` to the ``surfaces`` group (see :mod:`workbench.commands`)."""
    p = add_command(
        subparsers,
        "render",
        run,
        help="ray-cast a mesh or patch model to PNG (headless, no GPU)",
        description="Ray-cast a mesh (.ply/.obj/.stl) or patch model (.npz) with open3d's "
        "RaycastingScene: Lambert + Blinn-Phong shading, optional shadows, control net and "
        "colour maps with a colour bar.",
    )
    p.add_argument("file", help="mesh (.ply, .obj, .stl) or patch model (.npz)")
    p.add_argument("--out", required=True, help="output PNG")
    p.add_argument("--json", help="summary JSON (default: the PNG's name with .json)")
    add_picture_options(p)
