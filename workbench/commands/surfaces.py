"""``workbench surfaces coons|info|convert``: the shared surface model from the command line."""

from __future__ import annotations

import argparse
import json
import time

from workbench.commands.common import add_command, load_npy, mesh_out, read_model, write_summary


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
    from surfaces.measure import area, volume

    a, err = area(patches, return_error=True)
    closed = patches.closed_u and patches.closed_v
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
        "volume" if closed else "flux_volume_open_surface": volume(patches),
    }


def _coons(args: argparse.Namespace) -> int:
    from surfaces.coons import from_grid
    from surfaces.io import save_patches, write_mesh
    from surfaces.mesh import tessellate

    t0 = time.perf_counter()
    grid = load_npy(args.grid, "grid")
    pu = load_npy(args.pu, "--pu") if args.pu else None
    pv = load_npy(args.pv, "--pv") if args.pv else None
    twist = args.twist if args.twist in ("zero", "fd") else load_npy(args.twist, "--twist")
    out = mesh_out(args.out)
    patches = from_grid(
        grid, pu, pv, twist, closed_u=args.closed_u, closed_v=args.closed_v, chord_length=not args.uniform
    )
    mesh = tessellate(patches, args.samples)
    summary = {"input": str(args.grid), **_patch_summary(patches), **_mesh_summary(mesh)}
    summary["time_s"] = time.perf_counter() - t0
    write_mesh(mesh, out)
    save_patches(patches, out.with_suffix(".npz"))
    write_summary(out.with_suffix(".json"), summary)
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
        summary = {"file": args.file, **_patch_summary(obj), **_mesh_summary(tessellate(obj, 8))}
    else:
        summary = {"file": args.file, **_mesh_summary(obj)}
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
