"""``workbench slices reconstruct`` and ``workbench slices rois``: contour stacks to one surface."""

from __future__ import annotations

import argparse

from workbench.commands.common import add_command, write_summary
from surfaces.validate import InputError


def register(sub) -> None:
    """Add ``reconstruct`` and ``rois`` to the ``slices`` group.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The group's sub-parser collection.
    """
    from slices.body import MESH_BUDGET
    from slices.caps import CAP_KINDS
    from slices.options import SurfaceOptions as defaults
    from slices.pipeline import UNION_LIMIT
    from slices.surface import CORRESPONDENCES, METHODS

    p = add_command(
        sub,
        "reconstruct",
        _reconstruct,
        help="planar contours (RTSTRUCT, CT series, mask stack, contour JSON) to one "
        "interpolating surface with volume and area",
        description="Seed 000: the seed's control-point parameters per contour (rays from the "
        "centroid, fold handling), a closed parabolic-blending curve per slice and parabolic "
        "blending across slices into one grid of bicubic Bezier patches through every control "
        "point. Several contours per plane are chained into bodies by overlap; holes are "
        "subtracted. Writes surface.ply, surface.stl, patches.npz, summary.json and render.png.",
    )
    p.add_argument("input", metavar="INPUT",
                   help="RTSTRUCT .dcm, CT series folder, mask stack (.npy, multi-page .tif, "
                   "folder of PNGs), NIfTI label or mask volume (.nii, .nii.gz) or contour .json")
    p.add_argument("--roi", default=None, metavar="NAME",
                   help="ROI name (case-insensitive) or number of an RT structure set")
    p.add_argument("--roi-number", type=int, default=None, metavar="N",
                   help="ROI number of an RT structure set (to pick one of several ROIs with the same name)")
    p.add_argument("--slice-thickness", type=float, default=None, metavar="MM",
                   help="slab thickness of a structure drawn on a single plane (default: the structure set's "
                   "ContourSlabThickness, else the SliceThickness of the CT images beside it)")
    p.add_argument("--label", default=None, metavar="N",
                   help="NIfTI input: the voxel value of the structure (default: every non-zero voxel); "
                   "with --minus/--plus, those name labels too")
    p.add_argument("--method", default=defaults.method, choices=tuple(METHODS),
                   help="side surface: blending (seed 000 parabolic blending), coons "
                   "(seed 001 Coons patches over the lattice nodes), bspline (interpolating "
                   f"cubic B-spline over the lattice nodes); default {defaults.method}")
    p.add_argument("--surface-path", default=defaults.surface_path, choices=("auto", "coons", "implicit"),
                   help="auto (default): the seed's patches for a single chain of contours, an implicit surface "
                   "(blended signed distances, marching cubes) for branching, multi-body and holed structures and "
                   "for chains whose patches fold; coons or implicit force one")
    p.add_argument("--rays", type=int, default=defaults.n_rays,
                   help=f"rays from each contour's centroid (seed 000 eq. 1, N1 >= 3; default {defaults.n_rays})")
    p.add_argument("--caps", default=defaults.caps, choices=CAP_KINDS,
                   help="end caps: trend (the structure beyond its end planes from the contours' area trend; "
                   "volume_mm3 is then the whole structure's, with its uncertainty), none (open surface), flat (in "
                   "the end contour planes), half (half a slice beyond, as planning systems count), dome (smooth "
                   "closure); "
                   f"default {defaults.caps}")
    p.add_argument("--out", default="slices_out", help="output folder (default slices_out)")
    p.add_argument("--hu-min", type=float, default=None,
                   help="CT series / grey stacks: lower HU (intensity) of the object window")
    p.add_argument("--hu-max", type=float, default=None,
                   help="CT series / grey stacks: upper HU (intensity) of the object window")
    p.add_argument("--spacing", default=None, metavar="Z,Y,X",
                   help="mask stacks: voxel spacing in mm, e.g. 2.5,0.8,0.8")
    p.add_argument("--resample", action="store_true",
                   help="unequal slice spacing: resample a CT series / image stack onto uniform "
                   "slices, or blend contour inputs (RTSTRUCT, JSON) with non-uniform parabolas "
                   "at the true slice positions, instead of failing")
    p.add_argument("--lattice", type=float, default=defaults.lattice_factor,
                   help="common u lattice values per point of the largest contour "
                   f"(default {defaults.lattice_factor:g})")
    p.add_argument("--correspondence", default=defaults.correspondence, choices=CORRESPONDENCES,
                   help="u that links the slices: seed (eqs. 1-5: rays, turning points, chord "
                   "length) or arc (normalised arc length from the first ray); "
                   f"default {defaults.correspondence}")
    p.add_argument("--ray-start", default="auto", metavar="DEG|auto",
                   help="direction of ray 0 in degrees from +x, common to all slices of a body; auto "
                   "(default) rotates the rays (within one ray spacing) so that support points do not "
                   "jump across folds from slice to slice")
    p.add_argument("--union", default="auto", choices=("auto", "yes", "no"),
                   help="several bodies: write one solid (manifold3d union of the bodies minus "
                   f"the holes) or their meshes side by side; auto (default) unites up to {UNION_LIMIT // 1000}k "
                   "triangles")
    p.add_argument("--minus", action="append", default=[], metavar="NAME",
                   help="structure sets: subtract this ROI (reconstructed with the same options) from "
                   "--roi; repeatable. The written surface and volume_mm3 are the composed solid's")
    p.add_argument("--plus", action="append", default=[], metavar="NAME",
                   help="structure sets: add (unite) this ROI to --roi before any --minus; repeatable")
    p.add_argument("--repair", action="store_true",
                   help="repair the written solid (weld, orient, fill small holes); with --minus/--plus, each "
                   "mesh before the set operations; what was repaired goes into summary.json")
    p.add_argument("--samples", type=int, default=defaults.samples, metavar="N",
                   help="tessellation subdivisions per patch side (default: adapted so that the mesh "
                   f"has about {MESH_BUDGET:,} vertices)")
    p.add_argument("--no-render", action="store_true", help="skip render.png")
    p.add_argument("--reference", action="store_true",
                   help="also compare with the smoothing B-spline reference (seed 000, ref. [5]; adds its time)")
    p.add_argument("--export-mask", default=None, metavar="OUT.nii.gz",
                   help="also write the structure as a NIfTI mask (RAS affine) on a planning grid: the contours "
                   "rasterised (even-odd) on the planes that hold them, interpolated between; by default on the "
                   "grid of the CT series found beside an RT Structure Set, else on planes through the contour planes")
    p.add_argument("--mask-spacing", default=None, metavar="X,Y,Z",
                   help="voxel size of --export-mask in mm (default 1,1 and the slice spacing)")
    p.add_argument("--reference-image", default=None, metavar="CT_DIR|NIfTI",
                   help="--export-mask on the grid of this CT series folder or NIfTI image (same physical points)")
    p.add_argument("--mask-origin", default=None, metavar="X,Y,Z",
                   help="--export-mask: centre of voxel (0,0,0) in patient mm (DICOM LPS)")
    p.add_argument("--mask-size", default=None, metavar="NX,NY,NZ",
                   help="--export-mask: voxels along x, y, z")

    r = add_command(sub, "rois", _rois, help="list the ROIs of an RT structure set (or the labels of a NIfTI volume)",
                    description="List ROI numbers, names, contour and plane counts; for a NIfTI label volume, "
                    "its labels with voxel and plane counts.")
    r.add_argument("file", metavar="FILE", help="RTSTRUCT .dcm, or NIfTI .nii/.nii.gz")
    r.add_argument("--json", default=None, metavar="OUT",
                   help="also write the table to this JSON file")


def _reconstruct(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from slices.summary import count_noun as count
    from workbench.runs.slices import reconstruct_to_folder

    bars = []  # opened at the first finished body: no empty bar before an error or after a run without bodies

    def progress(done: int, total: int) -> None:
        if not bars:
            bars.append(tqdm(total=total, initial=done, desc="bodies", unit="body", leave=False))  # never 0/N
        bars[0].total = total
        bars[0].n = done
        bars[0].refresh()

    try:
        summary = reconstruct_to_folder(
            args.input, args.out, roi=_roi_or_label(args), method=args.method, rays=args.rays, caps=args.caps,
            hu_min=args.hu_min, hu_max=args.hu_max, spacing=args.spacing, resample=args.resample,
            lattice=args.lattice, render=not args.no_render, samples=args.samples, progress=progress,
            correspondence=args.correspondence, union=args.union, minus=args.minus, plus=args.plus,
            repair=args.repair, ray_start=args.ray_start, reference=args.reference, export_mask=args.export_mask,
            mask_spacing=args.mask_spacing, reference_image=args.reference_image, mask_origin=args.mask_origin,
            mask_size=args.mask_size, slice_thickness=args.slice_thickness, surface_path=args.surface_path,
        )
    finally:
        for bar in bars:
            bar.close()
    ref = summary.get("reference_bspline", {})
    for r in summary.get("contour_repairs", []):
        change = "n/a" if r["area_change_pct"] is None else f"{r['area_change_pct']:+.4f} %"
        print(f"repaired contour {r['contour']} at z={r['z_mm']:.2f} mm: {r['parts']} part(s), {r['holes']} hole(s), "
              f"area {r['area_before_mm2']:.2f} -> {r['area_after_mm2']:.2f} mm^2 ({change})")
    print(f"{summary['roi']}: {summary['n_contours']} contours on {summary['n_slices']} planes, "
          f"{count(summary['n_bodies'], 'body', 'bodies')} ({summary['chaining']})")
    made = (f"{summary['n_patches']} patches" if summary.get("surface_path", "coons") == "coons" else
            f"implicit surface ({summary['mesh_triangles']} triangles)")
    print(f"volume {summary['volume_mm3']:.1f} mm^3 = {summary['volume_ml']:.3f} ml "
          f"(slab {summary['slab_volume_mm3'] / 1000:.3f} ml, end planes half), area {summary['area_mm2']:.1f} mm^2, "
          f"{made}")
    print(f"  {summary['volume_caps']}")
    if summary.get("volume_U_mm3") is not None:
        from slices.volume import format_volume

        print(f"  {format_volume(summary['volume_mm3'], summary['volume_U_mm3'])} (budget in summary.json "
              "volume_uncertainty)")
    dev_ref = ref.get("max_control_point_deviation_mm")
    print(f"max control-point deviation {summary['max_control_point_deviation_mm']:.2e} mm"
          + (f" (smoothing B-spline reference: {dev_ref:.3f} mm)" if dev_ref is not None else ""))
    comp = summary.get("composition")
    if comp is not None:
        parts = ", ".join(f"{e['roi']} {e['volume_ml']:.3f} ml" for e in [comp["base"], *comp["plus"], *comp["minus"]])
        print(f"composition {comp['operation']}: {comp['result_volume_ml']:.3f} ml "
              f"(removed {comp['removed_volume_ml']:.3f} ml, added {comp['added_volume_ml']:.3f} ml; "
              f"ROIs {parts}), watertight {comp['watertight']}")
    print(f"wrote {args.out}/surface.ply, surface.stl, patches.npz, summary.json"
          + ("" if args.no_render else ", render.png") + f" in {summary['time_s']:.2f} s")
    return 0


def _roi_or_label(args: argparse.Namespace):
    """``--label`` for NIfTI input, ``--roi`` for the others (the library takes either as ``roi``)."""
    from slices.io import is_nifti

    if args.roi_number is not None:
        if args.roi is not None or args.label is not None:
            raise InputError("--roi-number: give either --roi NAME or --roi-number N (or --label), not both")
        return int(args.roi_number)
    if args.label is None:
        return args.roi
    if not is_nifti(args.input):
        raise InputError(f"--label: only for NIfTI input (.nii, .nii.gz), not {args.input!r}; use --roi")
    if args.roi is not None:
        raise InputError("--label and --roi: give one (--label for NIfTI volumes)")
    return args.label


def _rois(args: argparse.Namespace) -> int:
    from slices.io import is_nifti, list_rois, nifti_labels

    if is_nifti(args.file):
        labels = nifti_labels(args.file)
        if args.json:
            write_summary(args.json, labels)
        print(f"{'label':>8} {'voxels':>10} {'planes':>6}")
        for r in labels:
            print(f"{r['label']:>8} {r['n_voxels']:>10} {r['n_planes']:>6}")
        return 0
    rois = list_rois(args.file)
    if args.json:
        write_summary(args.json, rois)
    print(f"{'number':>6}  {'name':<24} {'contours':>8} {'planes':>6} {'max points':>10}")
    for r in rois:
        print(f"{r['number']:>6}  {r['name']:<24} {r['n_contours']:>8} {r['n_planes']:>6} "
              f"{r['max_points']:>10}")
    return 0
