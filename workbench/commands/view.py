"""``workbench view``: an open3d window when there is a display, else a pointer to ``--png``.

A display that is set but does not answer (``DISPLAY=:99`` with no X server, a
dead SSH tunnel) would make the window hang forever: it is probed first, in a
subprocess with a time limit, and the scene is rendered headless to a PNG
instead (``<first file>_view.png`` in the current folder), with a one-line note.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np

from workbench.commands.common import add_command, read_model, write_summary
from workbench.commands.render import add_picture_options, picture
from surfaces.validate import InputError

PALETTE = np.array([[0.72, 0.76, 0.82], [0.90, 0.60, 0.35], [0.45, 0.70, 0.45],
                    [0.80, 0.45, 0.55], [0.55, 0.55, 0.85]])


def has_display() -> bool:
    """True when an X11 or Wayland display is available (``DISPLAY`` / ``WAYLAND_DISPLAY`` set)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


#: seconds a display gets to answer
PROBE_TIMEOUT_S = 3.0

# opens and closes the X display named by DISPLAY through Xlib; exit 0 when it answers
_X11_PROBE = """
import ctypes, ctypes.util, sys
name = ctypes.util.find_library("X11")
if name is None:
    sys.exit(3)
x11 = ctypes.CDLL(name)
x11.XOpenDisplay.restype = ctypes.c_void_p
x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
display = x11.XOpenDisplay(None)
if not display:
    sys.exit(1)
x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
x11.XCloseDisplay(display)
"""


def probe_display(timeout: float | None = None) -> str | None:
    """Check that the display in ``DISPLAY`` / ``WAYLAND_DISPLAY`` answers, within ``timeout`` seconds.

    Parameters
    ----------
    timeout : float, optional
        Seconds to wait for the display (default :data:`PROBE_TIMEOUT_S`).

    Returns
    -------
    str or None
        None when the display answers, else why not (one phrase for the note).
    """
    timeout = PROBE_TIMEOUT_S if timeout is None else timeout
    wayland = os.environ.get("WAYLAND_DISPLAY")
    if wayland:
        path = Path(wayland) if os.path.isabs(wayland) else Path(os.environ.get("XDG_RUNTIME_DIR", "/tmp")) / wayland
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(timeout)
            try:
                sock.connect(str(path))
                return None
            except OSError as exc:
                return f"Wayland display {wayland} does not answer ({exc.strerror or exc})"
    display = os.environ.get("DISPLAY", "")
    try:
        probe = subprocess.run([sys.executable, "-c", _X11_PROBE], timeout=timeout,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return f"display {display} did not answer within {timeout:g} s"
    if probe.returncode == 3:  # no Xlib to ask: let open3d try
        return None
    return None if probe.returncode == 0 else f"display {display} cannot be opened"


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
    if not args.png and has_display():
        reason = probe_display()
        if reason is not None:
            args.png = f"{Path(args.files[0]).stem}_view.png"
            print(f"workbench: note: {reason}; rendering {args.png} headless instead (--png)", file=sys.stderr)
    if args.png:
        from surfaces.io import write_png

        if len(models) == 1:
            img, summary = picture(args, models[0])
        else:
            if args.net or args.colour != "none":
                raise InputError("--net/--colour: render one file at a time to use them")
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
