"""``workbench view``: an open3d window when there is a display, else a pointer to ``--png``."""

from __future__ import annotations

import argparse
import os

import numpy as np

from workbench.commands.common import add_command, read_model, write_summary
from workbench.commands.render import add_picture_options, picture

PALETTE = np.array([[0.72, 0.76, 0.82], [0.90, 0.60, 0.35], [0.45, 0.70, 0.45],
                    [0.80, 0.45, 0.55], [0.55, 0.55, 0.85]])


def has_display() -> bool:
    """True when an X11 or Wayland display is available (``DISPLAY`` / ``WAYLAND_DISPLAY`` set)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _merged(models, samples: int):
    """One mesh of all models, each file in its own palette colour (vertex colours)."""
    from surfaces.mesh import TriangleMesh, merge_meshes, tessellate

    meshes, colors = [], []
    for k, model in enumerate(models):
        mesh = tessellate(model, samples=samples) if hasattr(model, "control") else model
        meshes.append(TriangleMesh(mesh.vertices, mesh.triangles, mesh.vertex_normals, None))
        colors.append(np.broadcast_to(PALETTE[k % len(PALETTE)], mesh.vertices.shape))
    return merge_meshes(meshes), np.concatenate(colors)


def run(args: argparse.Namespace) -> int:
    """Show the files, or render them to ``--png``."""
    models = [read_model(f) for f in args.files]
    if args.png:
        from surfaces.io import write_png

        if len(models) == 1:
            img, summary = picture(args, models[0])
        else:
            if args.net or args.colour != "none":
                raise ValueError("--net/--colour: render one file at a time to use them")
            mesh, colors = _merged(models, args.samples)
            img, summary = picture(args, mesh, colors=colors)
        out = write_png(args.png, img)
        json_path = write_summary(out.with_suffix(".json"),
                                  {"files": [str(f) for f in args.files], "out": str(out), **summary})
        print(f"wrote {out} ({img.shape[1]}x{img.shape[0]}, {summary['triangles']} triangles); "
              f"numbers in {json_path}")
        return 0
    if not has_display():
        print("workbench view: no display (DISPLAY/WAYLAND_DISPLAY unset); "
              "use --png OUT.png to render the picture headless")
        return 1
    import open3d as o3d

    from surfaces.convert import control_net_lineset, to_open3d

    shown = []
    for k, model in enumerate(models):
        mesh = to_open3d(model, samples=args.samples)
        if not mesh.has_vertex_colors():
            mesh.paint_uniform_color(PALETTE[k % len(PALETTE)])
        shown.append(mesh)
        if args.net and hasattr(model, "control"):
            shown.append(control_net_lineset(model))
    o3d.visualization.draw_geometries(shown, window_name="workbench view", mesh_show_back_face=True)
    return 0


def register(subparsers) -> None:
    """Add the top-level ``view`` command (see :mod:`workbench.commands`)."""
    p = add_command(
        subparsers,
        "view",
        run,
        help="show meshes / patch models in an open3d window (or --png without a display)",
        description="Open an open3d window with the given meshes (.ply/.obj/.stl) and patch "
        "models (.npz). Without a display, --png renders the same scene headless by ray casting.",
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="mesh or patch files to show together")
    p.add_argument("--png", help="render headless to this PNG instead of opening a window")
    add_picture_options(p)
