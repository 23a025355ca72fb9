"""``workbench photometric reconstruct``: images under known lights to a measured surface."""

from __future__ import annotations

import argparse


def register(sub) -> None:
    """Add ``reconstruct`` to the ``photometric`` group.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The group's sub-parser collection.
    """
    p = sub.add_parser(
        "reconstruct",
        help="photometric stereo: normals, albedo, height, surface mesh and defect measures",
        description="Lambertian photometric stereo (seed 002a) from a DiLiGenT-style folder "
        "(filenames.txt, light_directions.txt, [light_intensities.txt], [mask.png], "
        "[normal_gt.npy]) or from --images with --lights. Writes normals.npy, albedo.npy, p.npy, "
        "q.npy, valid.npy, height.npy, normals.png, albedo.png, height.png, surface.ply, "
        "defects.json and summary.json to --out. Convention: x right, y up (row 0 at the top), "
        "z towards the camera; lights point from the surface to the light.",
    )
    p.add_argument("folder", nargs="?", default=None, metavar="DIR",
                   help="DiLiGenT-style folder (omit when giving --images)")
    p.add_argument("--images", nargs="+", default=None, metavar="IMG",
                   help="image files (PNG/TIFF 8/16 bit or .npy), one per light, in light order")
    p.add_argument("--lights", default=None, metavar="L",
                   help="light directions: text 'x y z' (or 'slant azimuth' deg, azimuth also called "
                   "tilt) per row, .npy (N, 3) or .json; required with --images, overrides the folder's")
    p.add_argument("--intensities", default=None, metavar="I",
                   help="light intensities: one value or 'r g b' per row (text, .npy or .json)")
    p.add_argument("--mask", default=None, metavar="M", help="object mask image (non-zero inside)")
    p.add_argument("--integrator", default="dct", choices=("dct", "fc", "lsq"),
                   help="height integrator: dct (Simchony, free boundary; default), fc "
                   "(Frankot-Chellappa, periodic), lsq (masked least squares, multigrid CG)")
    p.add_argument("--pixel-size", type=float, default=None, metavar="MM",
                   help="pixel size in mm (default: the folder's scene.json, else 1)")
    p.add_argument("--out", default="photometric_out", help="output folder (default photometric_out)")
    sel = p.add_mutually_exclusive_group()
    sel.add_argument("--triad", action="store_true",
                     help="use only the three images named in the folder's triad.txt")
    sel.add_argument("--select", nargs="+", default=None, metavar="NAME",
                     help="use only these image names of the folder (in this order)")
    p.add_argument("--outliers", action="store_true",
                   help="shadow/highlight mode: drop dark or saturated observations and re-solve "
                   "(N >= 4); a triad marks such pixels invalid")
    p.add_argument("--dark", type=float, default=0.1,
                   help="outlier mode: an observation below DARK x albedo is a shadow (default 0.1)")
    p.add_argument("--saturation", type=float, default=0.99,
                   help="outlier mode: input values at or above this (full scale 1) are saturated "
                   "(default 0.99)")
    p.add_argument("--highlight", type=float, default=None,
                   help="outlier mode: also drop observations brighter than the Lambertian "
                   "prediction by more than HIGHLIGHT x albedo (default off)")
    p.add_argument("--surface", default="fit", choices=("fit", "coons"),
                   help="surface model: fit (bicubic patches fitted by least squares to the height and "
                   "the slopes of every pixel, smaller where they miss --surface-tolerance; default) or "
                   "coons (Coons patches through every STEP-th height, tangents from single pixels)")
    p.add_argument("--surface-tolerance", type=float, default=None, metavar="MM",
                   help="fit: largest deviation of the surface from the integrated height, mm "
                   "(default 0.5 %% of the height range)")
    p.add_argument("--step", type=int, default=None,
                   help="pixels per surface patch: the largest fitted patch (a power of two) or the "
                   "coons grid step (default: about 64 patches across)")
    p.add_argument("--samples", type=int, default=None,
                   help="mesh subdivisions per (largest) patch side (default min(step, 8))")
    p.add_argument("--background", default="plane", choices=("plane", "smooth"),
                   help="background removed before measuring defects (default plane)")
    p.set_defaults(func=_reconstruct)


def _reconstruct(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from workbench.runs.photometric import reconstruct_to_folder

    if (args.folder is None) == (args.images is None):
        raise ValueError("input: give either a folder DIR or --images (with --lights), not both")
    if args.images is not None and args.lights is None:
        raise ValueError("--lights: required with --images")
    if args.images is not None and (args.triad or args.select):
        raise ValueError("--triad/--select: only apply to a folder input")
    select = "triad" if args.triad else args.select
    stages = ["read", "normals", "height", "surface", "defects", "write"]
    with tqdm(total=len(stages), desc="photometric", unit="stage", leave=False) as bar:
        def progress(stage: str) -> None:
            if bar.n or stage != stages[0]:
                bar.update(1)
            bar.set_postfix_str(stage)

        summary = reconstruct_to_folder(
            args.folder if args.folder is not None else args.images,
            args.out,
            lights=args.lights,
            intensities=args.intensities,
            mask=args.mask,
            select=select,
            integrator=args.integrator,
            pixel_size=args.pixel_size,
            outliers=args.outliers,
            dark=args.dark,
            saturation=args.saturation,
            highlight=args.highlight,
            step=args.step,
            samples=args.samples,
            surface=args.surface,
            surface_tolerance=args.surface_tolerance,
            background=args.background,
            progress=progress,
        )
        bar.update(bar.total - bar.n)
    size = summary["size"]
    print(
        f"{size['images']} images of {size['width']} x {size['height']} px, "
        f"light condition number {summary['light_condition_number']:.3f}, "
        f"invalid {100 * summary['invalid_fraction']:.2f} % of the mask"
    )
    if "mean_angular_error_deg" in summary:
        print(f"mean angular error vs normal_gt: {summary['mean_angular_error_deg']:.3f} deg")
    # Without a pixel size the heights are in pixel units, not mm.
    unit = "px" if summary["pixel_size_source"].startswith("default") else "mm"
    if "height_rmse_mm" in summary:
        print(f"height RMSE vs height_gt: {summary['height_rmse_mm']:.4g} {unit}")
    print(
        f"height range {summary['height_range_mm']:.4g} {unit} ({summary['integrator']}), "
        f"{summary['n_patches']} patches ({summary['surface']}, surface within "
        f"{summary['surface_max_dev_mm']:.3g} {unit} of the height), "
        f"{summary['mesh']['triangles']} triangles, {summary['n_defects']} defect(s)"
    )
    print(f"total {summary['timings_s']['total']:.2f} s; wrote {args.out} (summary.json holds every number above)")
    return 0
