"""``workbench surfaces coons|info|convert``: the shared surface model from the command line.

``coons`` checks the grid's shape from the file header and estimates the memory
and the size of the files it will write before it loads anything; above
``--max-memory`` (default half of this machine's memory) it refuses in one line.
``coons`` and ``info`` warn when a closed surface is oriented inward (negative
volume) and say how to flip it.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

from workbench.commands.common import (
    add_command,
    format_size,
    load_npy,
    machine_memory,
    mesh_out,
    npy_shape,
    parse_size,
    read_model,
    write_summary,
)
from surfaces.validate import InputError

#: peak memory of ``surfaces coons`` per mesh vertex and per patch, bytes (measured on 64^2 to 512^2
#: grids at 8 samples: tessellation, the mesh checks and the summary dominate)
BYTES_PER_VERTEX = 600
BYTES_PER_PATCH = 2048
#: above these, ``coons`` says what it is about to need before it starts
NOTE_MEMORY = 2**30
NOTE_OUTPUT = 100 * 2**20
#: what the numbers of ``info`` and ``coons`` are measured in (files carry no unit)
UNITS = {"length": "as the input file (workbench writes mm)", "area": "length^2", "volume": "length^3"}


def register(sub) -> None:
    """Add ``coons``, ``info`` and ``convert`` to the ``surfaces`` group (see :mod:`workbench.commands`)."""
    p = add_command(
        sub,
        "coons",
        _coons,
        help="bicubic Coons patches through a grid of points (.npy (R, C, 3)), as Bezier patches and a mesh",
        description="Build bicubic Coons patches through every point of a grid (seed 001), convert them "
        "to Bezier form, tessellate and measure them. Writes the mesh, the patches (.npz) and a JSON summary.",
    )
    p.add_argument("grid", help="grid of points, .npy of shape (R, C, 3); axis 0 is u, axis 1 is v")
    p.add_argument("--pu", help="tangents along u per grid step, .npy (R, C, 3) (default: finite differences)")
    p.add_argument("--pv", help="tangents along v per grid step, .npy (R, C, 3) (default: finite differences)")
    p.add_argument("--twist", default="zero", help="zero, fd (finite differences) or a .npy (R, C, 3) file")
    p.add_argument("--closed-u", action="store_true", help="the u direction closes on itself")
    p.add_argument("--closed-v", action="store_true", help="the v direction closes on itself")
    p.add_argument("--uniform", action="store_true", help="uniform instead of chord-length tangent scaling")
    p.add_argument("--samples", type=int, default=8, help="subdivisions per patch side in the mesh (default 8)")
    p.add_argument("--out", required=True, help="mesh file to write (.ply, .obj or .stl)")
    p.add_argument("--max-memory", default=None, metavar="SIZE",
                   help="refuse grids whose estimated peak memory exceeds SIZE (e.g. 8G, 512M; "
                   "default half of this machine's memory); lower --samples to need less")

    p = add_command(
        sub,
        "info",
        _info,
        help="measure a patch file (.npz) or mesh (.ply/.obj/.stl): size, area, volume, watertightness",
        description="Print a JSON summary of a patch model or mesh. Patch models are measured by "
        "quadrature over the patches, meshes over their triangles.",
    )
    p.add_argument("file", help="patches .npz (from `workbench surfaces coons` or `slices`) or a mesh file")
    p.add_argument("--json", dest="json_out", help="also write the summary to this JSON file")

    p = add_command(
        sub,
        "convert",
        _convert,
        help="convert between mesh formats, or tessellate a patch file into a mesh",
        description="Read a mesh (.ply/.obj/.stl) or patches (.npz) and write a mesh in the format of --out.",
    )
    p.add_argument("file", help="input mesh or patches .npz")
    p.add_argument("--out", required=True, help="output mesh (.ply, .obj or .stl)")
    p.add_argument("--samples", type=int, default=8, help="subdivisions per patch side for patch input")


def _mesh_summary(mesh) -> dict:
    return {
        "n_vertices": mesh.n_vertices,
        "n_triangles": mesh.n_triangles,
        "watertight": mesh.is_watertight(),
        "oriented": mesh.is_oriented(),
        "mesh_area": mesh.surface_area(),
        "mesh_volume": mesh.signed_volume() if mesh.is_watertight() else None,
    }


def _patch_summary(patches) -> dict:
    import warnings

    from surfaces.measure import InwardOrientationWarning, area, volume

    a, err = area(patches, return_error=True)
    closed = patches.closed_u and patches.closed_v
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InwardOrientationWarning)  # the command warns once, with how to flip it
        signed = volume(patches)
    return {
        "n_patches": patches.n_patches,
        "patch_rows": patches.shape[0],
        "patch_cols": patches.shape[1],
        "closed_u": patches.closed_u,
        "closed_v": patches.closed_v,
        "area": a,
        "area_error_estimate": err,
        # the divergence theorem gives the enclosed volume for closed surfaces;
        # for an open one the flux is still reported, under another name
        "volume" if closed else "flux_volume_open_surface": signed,
    }


def coons_needs(shape: tuple[int, ...], samples: int, closed_u: bool, closed_v: bool, suffix: str) -> dict:
    """Estimate what ``surfaces coons`` needs for a grid, before it loads it.

    Parameters
    ----------
    shape : tuple of int
        Grid shape ``(R, C, 3)``.
    samples : int
        Subdivisions per patch side.
    closed_u, closed_v : bool
        Closure flags (a closed direction has one patch more and no extra vertex row).
    suffix : str
        Mesh format of ``--out`` (".ply", ".obj" or ".stl").

    Returns
    -------
    dict
        ``patches``, ``vertices``, ``triangles``, ``memory_bytes`` (peak, estimated from
        :data:`BYTES_PER_VERTEX` and :data:`BYTES_PER_PATCH`) and ``output_bytes`` (the
        mesh, exact for PLY and STL, plus the ``.npz`` of the patches).

    Examples
    --------
    >>> needs = coons_needs((512, 512, 3), 8, False, False, ".ply")
    >>> needs["vertices"], needs["triangles"], round(needs["memory_bytes"] / 2**30, 1)
    (16719921, 33423488, 9.8)
    """
    rows, cols = shape[0], shape[1]
    pr = max(rows if closed_u else rows - 1, 0)
    pc = max(cols if closed_v else cols - 1, 0)
    n = max(int(samples), 1)
    vertices = (pr * n + (not closed_u)) * (pc * n + (not closed_v)) if pr and pc else 0
    triangles = 2 * pr * pc * n * n
    mesh = {".ply": 300 + 24 * vertices + 13 * triangles, ".stl": 84 + 50 * triangles}.get(
        suffix.lower(), 60 * vertices + 30 * triangles)
    return {
        "patches": pr * pc,
        "vertices": vertices,
        "triangles": triangles,
        "memory_bytes": BYTES_PER_VERTEX * vertices + BYTES_PER_PATCH * pr * pc,
        "output_bytes": mesh + 384 * pr * pc,
    }


def _check_coons_inputs(args: argparse.Namespace) -> dict:
    """Shapes, samples, the output name and the memory estimate, before anything is loaded."""
    shape = npy_shape(args.grid, "grid")
    if len(shape) != 3 or shape[-1] != 3:
        raise InputError(f"grid: expected shape (R, C, 3), got {shape}")
    given = [(args.pu, "--pu"), (args.pv, "--pv")]
    if args.twist not in ("zero", "fd"):
        given.append((args.twist, "--twist"))
    for path, name in given:
        if path and npy_shape(path, name) != shape:
            raise InputError(f"{name}: expected the grid's shape {shape}, got {npy_shape(path, name)}")
    if args.samples < 1:
        raise InputError(f"--samples: need at least 1 subdivision per patch side, got {args.samples}")
    out = mesh_out(args.out)
    needs = coons_needs(shape, args.samples, args.closed_u, args.closed_v, out.suffix)
    limit = parse_size(args.max_memory, "--max-memory") if args.max_memory else machine_memory() // 2
    if limit and needs["memory_bytes"] > limit:
        raise InputError(
            f"grid: {shape[0]} x {shape[1]} points at --samples {args.samples} need about "
            f"{format_size(needs['memory_bytes'])} of memory ({needs['triangles']:,} triangles), more than "
            f"--max-memory {format_size(limit)}; lower --samples, split the grid or raise --max-memory")
    if needs["memory_bytes"] > NOTE_MEMORY or needs["output_bytes"] > NOTE_OUTPUT:
        print(f"workbench: note: {needs['patches']:,} patches, {needs['triangles']:,} triangles: about "
              f"{format_size(needs['memory_bytes'])} of memory and {format_size(needs['output_bytes'])} of "
              "files", file=sys.stderr)
    return needs


def _orientation(summary: dict, fix: str) -> str | None:
    """Record a closed surface's orientation in ``summary``; the warning text when it points inward."""
    volume = summary.get("volume")
    if volume is None:
        volume = summary.get("mesh_volume")
    summary["orientation"] = None if volume is None else ("inward" if volume < 0 else "outward")
    if summary["orientation"] != "inward":
        return None
    return f"the surface is oriented inward (volume {volume:.6g} < 0, normals point inside); {fix}"


#: how to flip an inward surface, per input
FLIP_GRID = "flip it by reversing the grid's rows (grid[::-1]) or swapping its axes (grid.transpose(1, 0, 2))"
FLIP_MESH = "flip it by reversing every triangle's vertex order (e.g. triangles[:, ::-1])"


def _coons(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from surfaces.coons import from_grid
    from surfaces.io import save_patches, write_mesh
    from surfaces.mesh import tessellate

    t0 = time.perf_counter()
    _check_coons_inputs(args)
    # delay: no bar at all before an error in the first half second
    with tqdm(total=5, desc="coons", unit="stage", leave=False, delay=0.5) as bar:
        bar.set_postfix_str("read", refresh=False)
        grid = load_npy(args.grid, "grid")
        pu = load_npy(args.pu, "--pu") if args.pu else None
        pv = load_npy(args.pv, "--pv") if args.pv else None
        twist = args.twist if args.twist in ("zero", "fd") else load_npy(args.twist, "--twist")
        out = mesh_out(args.out)
        bar.set_postfix_str("patches", refresh=False)
        bar.update()
        patches = from_grid(
            grid, pu, pv, twist, closed_u=args.closed_u, closed_v=args.closed_v, chord_length=not args.uniform
        )
        del grid, pu, pv, twist
        bar.set_postfix_str("tessellate", refresh=False)
        bar.update()
        mesh = tessellate(patches, args.samples)
        bar.set_postfix_str("measure", refresh=False)
        bar.update()
        summary = {"input": str(args.grid), "units": UNITS, **_patch_summary(patches), **_mesh_summary(mesh)}
        summary["time_s"] = time.perf_counter() - t0
        bar.set_postfix_str("write", refresh=False)
        bar.update()
        write_mesh(mesh, out)
        save_patches(patches, out.with_suffix(".npz"))
        inward = _orientation(summary, FLIP_GRID)
        write_summary(out.with_suffix(".json"), summary)
        bar.update()
    if inward:
        warnings.warn(inward, UserWarning, stacklevel=1)
    print(
        f"{patches.n_patches} patches, {mesh.n_triangles} triangles, area {summary['area']:.6g}"
        f"{', watertight' if summary['watertight'] else ''}; wrote {out}, {out.with_suffix('.npz')}, "
        f"{out.with_suffix('.json')}"
    )
    return 0


def _info(args: argparse.Namespace) -> int:
    from surfaces.bezier import BezierPatches
    from surfaces.mesh import tessellate

    obj = read_model(args.file)
    if isinstance(obj, BezierPatches):
        summary = {"file": args.file, "units": UNITS, **_patch_summary(obj), **_mesh_summary(tessellate(obj, 8))}
    else:
        summary = {"file": args.file, "units": UNITS, **_mesh_summary(obj)}
    inward = _orientation(summary, FLIP_GRID if isinstance(obj, BezierPatches) else FLIP_MESH)
    if inward:
        warnings.warn(inward, UserWarning, stacklevel=1)
    if args.json_out:
        write_summary(args.json_out, summary)
    print(json.dumps(summary, indent=2))
    return 0


def _convert(args: argparse.Namespace) -> int:
    from surfaces.io import write_mesh

    obj = read_model(args.file)
    path = write_mesh(obj, args.out, samples=args.samples)
    print(f"wrote {path}")
    return 0
