"""``workbench photometric reconstruct`` and ``calibrate``: images under known lights to a
measured surface, and the calibration of a near-field rig (LEDs, camera, flat field)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from photometric.options import BACKGROUNDS, LIGHT_MODELS, REFLECTANCES, SURFACES, PhotometricOptions
from surfaces.validate import InputError
from workbench.commands.camera_check import warn_camera_conflicts

#: the reconstruction's defaults: the options hold them (photometric.options), the parser shows them
DEFAULTS = PhotometricOptions()


def _numbers(text: str, name: str) -> float | list[float]:
    """One number, or comma-separated numbers (one per light)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"{name}: expected a number or comma-separated numbers, got {text!r}") from None
    return values[0] if len(values) == 1 else values


def _add_camera(p: argparse.ArgumentParser, pixel_help: str) -> None:
    p.add_argument("--camera", default=None, choices=("orthographic", "perspective"),
                   help="camera model (default: the rig's or the folder's scene.json, else orthographic): "
                   "orthographic = telecentric (--pixel-size), perspective = pinhole looking down from "
                   "--camera-height with --focal-length-px")
    p.add_argument("--pixel-size", type=float, default=None, metavar="MM", help=pixel_help)
    p.add_argument("--focal-length-px", default=None, metavar="F",
                   help="perspective: focal length in pixels, or FX,FY when the pixels are not square (OpenCV's "
                   "K[0,0], K[1,1])")
    p.add_argument("--camera-height", type=float, default=None, metavar="MM",
                   help="perspective: camera centre height above the reference plane z = 0, mm")
    p.add_argument("--distortion", default=None, metavar="K1,K2,P1,P2,K3",
                   help="perspective: lens distortion in OpenCV's model and order (fewer values: the rest 0); the "
                   "images are resampled to the distortion-free pinhole camera before anything is measured")
    p.add_argument("--principal-point-px", "--principal-point", dest="principal_point", default=None, metavar="CX,CY",
                   help="perspective: principal point (column, row) in pixels, 0-based: the top-left pixel's centre "
                   "is 0,0 (a MATLAB calibration's 1-based point minus 1); default the image centre")


def _add_rig_options(p: argparse.ArgumentParser) -> None:
    """The calibration options stored in the rig (shared by ``photometric calibrate`` and ``inspect calibrate``)."""
    p.add_argument("--flat-albedo", type=float, default=None, metavar="A",
                   help="albedo of the flat-field target (default 1)")
    p.add_argument("--led-mu", default=None, metavar="MU", help="LED lobe exponent(s) to store in the rig")
    p.add_argument("--intensities", default=None, metavar="I", help="LED intensities to store in the rig")
    p.add_argument("--window", type=int, default=None, metavar="PX",
                   help="half width of the highlight centroid window, pixels (default 4)")
    p.add_argument("--out", default="rig.json", help="rig file to write (default rig.json)")


def _focal(text: str | None):
    """``--focal-length-px``: F or FX,FY."""
    if text is None:
        return None
    f = _numbers(text, "--focal-length-px")
    if isinstance(f, list) and len(f) != 2:
        raise InputError(f"--focal-length-px: expected F or FX,FY, got {text!r}")
    return f


def _fx(text: str | None) -> float | None:
    """The x focal length of ``--focal-length-px`` (F or FX,FY), for comparing with a stated camera."""
    f = _focal(text)
    return f[0] if isinstance(f, list) else f


def _camera_options(args: argparse.Namespace) -> dict:
    pp = None
    if args.principal_point is not None:
        pp = _numbers(args.principal_point, "--principal-point-px")
        if not isinstance(pp, list) or len(pp) != 2:
            raise InputError(f"--principal-point-px: expected 'CX,CY', got {args.principal_point!r}")
    dist = None if getattr(args, "distortion", None) is None else _numbers(args.distortion, "--distortion")
    return {"camera": args.camera, "focal_length_px": _focal(args.focal_length_px),
            "camera_height_mm": args.camera_height, "principal_point_px": pp,
            **({} if dist is None else {"distortion": [dist] if isinstance(dist, float) else dist})}


#: what the uncertainty options add to ``photometric reconstruct``'s result folder
UNCERTAINTY_NOTE = ("Any of these options adds p_u.npy, q_u.npy, height_u.npy (standard uncertainties), "
                    "uncertainty.json (the budget of every defect figure) and uncertainty_k2 per defect in "
                    "defects.json; needs the pixel size.")


def add_uncertainty_options(p: argparse.ArgumentParser, note: str = UNCERTAINTY_NOTE,
                            method_help: str | None = None) -> None:
    """Add the GUM uncertainty options (one group) to a command's parser.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The command's parser (``photometric reconstruct``, ``inspect run|watch``).
    note : str
        The group's description: what the options add to the command's output.
    method_help : str, optional
        Help of ``--uncertainty`` (default: the choice of propagation).
    """
    g = p.add_argument_group("uncertainty (GUM, k = 2)", note)
    g.add_argument("--noise-sigma", type=float, default=None, metavar="S",
                   help="image noise, standard deviation in full-scale units 0-1 (default: estimated from the "
                   "residuals with 4 or more lights, none with a triad)")
    # "u" names a standard uncertainty, "tolerance" a limit; the older "-tolerance" flags stay as aliases
    g.add_argument("--light-u-deg", "--light-tolerance-deg", dest="light_tolerance_deg", type=float, default=None,
                   metavar="DEG",
                   help="standard uncertainty u of each light's direction, degrees (isotropic: each tangent axis)")
    g.add_argument("--light-position-u-mm", "--light-position-tolerance-mm", dest="light_position_tolerance_mm",
                   type=float, default=None, metavar="MM",
                   help="standard uncertainty u of each LED coordinate, mm (near-field rigs)")
    g.add_argument("--intensity-u", "--intensity-tolerance", dest="intensity_tolerance", type=float, default=None,
                   metavar="R", help="relative standard uncertainty u of each light's intensity")
    g.add_argument("--pixel-size-u", "--pixel-size-tolerance", dest="pixel_size_tolerance", type=float,
                   default=None, metavar="R", help="relative standard uncertainty u of the pixel size")
    g.add_argument("--uncertainty", default=None, choices=("linear", "montecarlo"),
                   help=method_help or "propagation: linear (default; closed form) or montecarlo (repeat the "
                   "fast solve with perturbed inputs)")
    g.add_argument("--mc-samples", type=int, default=None, metavar="N",
                   help="Monte Carlo repetitions (default 50)")


def _uncertainty_options(args: argparse.Namespace):
    """The tolerances of the command line, or None when no uncertainty option was given."""
    from photometric.uncertainty import Tolerances

    given = {
        "noise_sigma": args.noise_sigma,
        "light_tolerance_deg": args.light_tolerance_deg,
        "light_position_tolerance_mm": args.light_position_tolerance_mm,
        "intensity_tolerance": args.intensity_tolerance,
        "pixel_size_tolerance": args.pixel_size_tolerance,
        "method": args.uncertainty,
        "mc_samples": args.mc_samples,
    }
    if all(v is None for v in given.values()):
        return None
    names = {"noise_sigma": "--noise-sigma", "light_tolerance_deg": "--light-u-deg (--light-tolerance-deg)",
             "light_position_tolerance_mm": "--light-position-u-mm (--light-position-tolerance-mm)",
             "intensity_tolerance": "--intensity-u (--intensity-tolerance)",
             "pixel_size_tolerance": "--pixel-size-u (--pixel-size-tolerance)"}
    for key, flag in names.items():
        if given[key] is not None and not given[key] >= 0:
            raise InputError(f"{flag}: must be a non-negative standard uncertainty, got {given[key]}")
    if args.mc_samples is not None and args.mc_samples < 2:
        raise InputError(f"--mc-samples: need at least 2 Monte Carlo samples, got {args.mc_samples}")
    return Tolerances(**{k: v for k, v in given.items() if v is not None})


def _add_texture_options(p: argparse.ArgumentParser) -> None:
    """``--texture`` and its filters (the defaults of :data:`workbench.runs.texture.TEXTURE_DEFAULTS`)."""
    from workbench.runs.texture import FORMS, TEXTURE_DEFAULTS

    g = p.add_argument_group("areal texture (ISO 25178-2)",
                             "--texture adds texture.json (every parameter with U, k = 2, when an uncertainty option "
                             "is given) and texture.png (the S-L surface) to --out; needs the pixel size. The same "
                             "computation as 'workbench photometric texture OUT'.")
    g.add_argument("--texture", action="store_true", help="also measure the areal texture of the height")
    g.add_argument("--texture-s-filter-mm", type=float, default=TEXTURE_DEFAULTS["s_filter_mm"], metavar="X",
                   help="S-filter nesting index lambda_s, mm (default none: the band starts at two pixels)")
    g.add_argument("--texture-l-filter-mm", type=float, default=TEXTURE_DEFAULTS["l_filter_mm"], metavar="Y",
                   help="L-filter nesting index lambda_c, mm (default none: the band ends at the field size)")
    g.add_argument("--texture-form", default=TEXTURE_DEFAULTS["form"], choices=FORMS,
                   help=f"F-operator: least-squares plane or second-degree polynomial (default "
                   f"{TEXTURE_DEFAULTS['form']})")


def _texture_options(args: argparse.Namespace) -> dict | None:
    """The ``texture`` of :func:`workbench.runs.photometric.reconstruct_to_folder`, checked before any work."""
    from workbench.runs.texture import TEXTURE_DEFAULTS, texture_options

    given = {"s_filter_mm": args.texture_s_filter_mm, "l_filter_mm": args.texture_l_filter_mm,
             "form": args.texture_form}
    if not args.texture:
        changed = [f"--texture-{k.replace('_', '-')}" for k, v in given.items() if v != TEXTURE_DEFAULTS[k]]
        if changed:
            raise InputError(f"{changed[0]}: only applies with --texture")
        return None
    return texture_options(given, "--texture")


def register(sub) -> None:
    """Add ``reconstruct`` and ``calibrate`` to the ``photometric`` group.

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
        "defects.json and summary.json to --out (with an uncertainty option also p_u.npy, q_u.npy, "
        "height_u.npy and uncertainty.json, GUM budgets with k = 2). Convention: x right, y up (row 0 at the top), "
        "z towards the camera; lights point from the surface to the light. Near-field rigs: with LED "
        "positions (--light-positions, --rig, or a folder's light_positions.txt) the point-light model "
        "(inverse-square falloff, LED lobe, optional flat field) is solved by alternating normals and "
        "depth; heights are z in mm in the rig frame (origin on the optical axis in the reference plane "
        "z = 0) with the median height of the valid pixels at --reference-height, and xy.npy holds x, y "
        "of each pixel's point. A solve that does not converge writes only summary.json "
        "(converged: false) and exits with code 2. Inputs that cannot give a result: values of "
        "8/16-bit images within 0.5/255 of full scale (saturated) or below 0.5/255 (black) are invalid in "
        "that image and a pixel with fewer than 3 valid images is invalid (summary.json invalid_fraction); "
        "a saturated or black image is left out with a "
        "warning (summary.json warnings), fewer than 3 usable images is an error; a light matrix with "
        "condition number above 10 is a warning, above 100 an error unless --force; lights with z < 0 are "
        "an error.",
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
    p.add_argument("--integrator", default=DEFAULTS.integrator, choices=("auto", "dct", "fc", "lsq", "robust"),
                   help="height integrator: dct (Simchony, free boundary; default), auto (dct on a full rectangle, "
                   "lsq when a mask cuts it), fc (Frankot-Chellappa, periodic), lsq (masked least squares, "
                   "multigrid CG), robust (lsq reweighted per edge: keeps depth jumps and silhouettes local)")
    _add_camera(p, "orthographic pixel size in mm (default: the folder's scene.json, else 1; required "
                "with point lights unless the rig or folder states the camera)")
    p.add_argument("--light-positions", default=None, metavar="P",
                   help="LED positions, one 'x y z' row in mm per image (rig frame: origin on the optical "
                   "axis in the reference plane, z towards the camera): the near-field model")
    p.add_argument("--led-mu", default=None, metavar="MU",
                   help="LED lobe exponent mu (cos^mu about the LED axis; 0 isotropic), one value or one "
                   "per light 'm1,m2,...' (default: the rig's or scene.json's, else unknown)")
    p.add_argument("--led-axes", default=None, metavar="FILE",
                   help="LED axes, one 'x y z' row per light in the rig frame (from the LED into the scene; default: "
                   "aimed at the origin, or the rig's); the lobe needs --led-mu (or the rig's)")
    p.add_argument("--flat-field", nargs="+", default=None, metavar="F",
                   help="flat-field images (flat matte target in the reference plane), one per light in "
                   "light order")
    p.add_argument("--flat-albedo", type=float, default=None, metavar="A",
                   help="albedo of the flat-field target (default: the folder's scene.json, else 1)")
    p.add_argument("--no-flat-field", action="store_true",
                   help="ignore the rig's gains and the folder's flat_*.png (modelled falloff and lobe only)")
    p.add_argument("--rig", default=None, metavar="RIG",
                   help="calibrated rig (rig.json of 'workbench photometric calibrate'): LED positions, "
                   "camera, flat-field gains")
    p.add_argument("--light-model", default=DEFAULTS.light_model, choices=LIGHT_MODELS,
                   help="auto (default): point lights when LED positions are known; directional: today's "
                   "far-field model even then")
    p.add_argument("--reflectance", default=DEFAULTS.reflectance, choices=REFLECTANCES,
                   help="near-field reflectance model (default: the rig's 'reflectance', else lambertian): "
                   "lambertian for matte parts; glossy refines the normals under a Lambertian albedo plus a GGX "
                   "lobe (dielectrics with a broad lobe; point lights, orthographic camera, 4 or more LEDs; needs "
                   "--gloss-alpha and --gloss-weight or a rig calibrated with them)")
    p.add_argument("--gloss-alpha", type=float, default=DEFAULTS.gloss_alpha, metavar="A",
                   help="glossy: GGX roughness of the material, 0 < A <= 1 (default: the rig's)")
    p.add_argument("--gloss-weight", type=float, default=DEFAULTS.gloss_weight, metavar="C",
                   help="glossy: lobe weight of the material, measured on a level reference part "
                   "(photometric.glossy.lobe_weight; default: the rig's)")
    p.add_argument("--reference-height", type=float, default=DEFAULTS.reference_height_mm, metavar="MM",
                   help=f"near-field anchor: median height of the valid pixels, mm (default "
                   f"{DEFAULTS.reference_height_mm:g}: the part lies "
                   "on the reference plane)")
    p.add_argument("--tolerance", type=float, default=None, metavar="MM",
                   help="near-field convergence: largest height change between passes, mm (default "
                   f"{DEFAULTS.tolerance_mm:g})")
    p.add_argument("--max-iterations", type=int, default=DEFAULTS.max_iterations, metavar="N",
                   help=f"near-field: most passes per resolution (default {DEFAULTS.max_iterations})")
    p.add_argument("--estimate-intensities", action="store_true",
                   help="near field without a flat field: estimate the relative LED intensities from the images "
                   "(semi-calibrated solve, LED 0's fixed; summary.json intensities). Without it and without "
                   "--intensities or a flat field, the solve assumes equal irradiance at the field centre")
    p.add_argument("--out", default="photometric_out", help="output folder (default photometric_out)")
    sel = p.add_mutually_exclusive_group()
    sel.add_argument("--triad", action="store_true",
                     help="use only the three images named in the folder's triad.txt")
    sel.add_argument("--select", nargs="+", default=None, metavar="NAME",
                     help="use only these image names of the folder (in this order)")
    p.add_argument("--outliers", action=argparse.BooleanOptionalAction, default=DEFAULTS.outliers,
                   help="shadow/highlight mode: drop dark or saturated observations and re-solve "
                   "(N >= 4); a triad marks such pixels invalid. Default: on with 6 or more images; "
                   "--no-outliers turns it off")
    p.add_argument("--dark", type=float, default=DEFAULTS.dark,
                   help=f"outlier mode: an observation below DARK x albedo is a shadow (default {DEFAULTS.dark:g})")
    p.add_argument("--saturation", type=float, default=DEFAULTS.saturation,
                   help="outlier mode: input values at or above this (full scale 1) are saturated "
                   f"(default {DEFAULTS.saturation:g})")
    p.add_argument("--highlight", type=float, default=None,
                   help="outlier mode: also drop observations brighter than the Lambertian "
                   "prediction by more than HIGHLIGHT x albedo (default off)")
    p.add_argument("--surface", default=DEFAULTS.surface, choices=SURFACES,
                   help="surface model: fit (bicubic patches fitted by least squares to the height and "
                   "the slopes of every pixel, smaller where they miss --surface-tolerance; default), "
                   "coons (Coons patches through every STEP-th height, tangents from single pixels) or none "
                   "(normals and height only: no surface model, no surface.ply; big captures)")
    p.add_argument("--max-patches", type=int, default=None, metavar="N",
                   help="fit: patch budget; the worst cells are refined first and the refinement stops at the "
                   "budget (summary.json surface_budget_reached). Default: one patch per 256 pixels (at least "
                   "16384) without --mask, none with a mask")
    p.add_argument("--surface-tolerance", type=float, default=None, metavar="MM",
                   help="fit: largest deviation of the surface from the integrated height, mm "
                   "(default 0.5 %% of the height range, or 0.01 px, or four times the height's noise at "
                   "half the largest patch, whichever is largest; where the noise sets it, cells whose normals "
                   "miss the measured ones by 1 deg more than the height's own are refined too)")
    p.add_argument("--force", action="store_true",
                   help="solve even when the light matrix's condition number is above 100 (nearly coplanar "
                   "lights; above 10 it is a warning; summary.json light_condition_number)")
    p.add_argument("--step", type=int, default=None,
                   help="pixels per surface patch: the largest fitted patch (a power of two) or the "
                   "coons grid step (default: about 64 patches across)")
    p.add_argument("--samples", type=int, default=None,
                   help="mesh subdivisions per (largest) patch side (default min(step, 8))")
    p.add_argument("--background", default=DEFAULTS.background, choices=BACKGROUNDS,
                   help=f"background removed before measuring defects (default {DEFAULTS.background})")
    _add_capture(p)
    p.add_argument("--no-distance-estimate", action="store_true",
                   help="with an imported calibration (--rig light.mat) and --camera-height: trust the height, do not "
                   "estimate it from the photometric residual")
    add_uncertainty_options(p)
    _add_texture_options(p)
    p.set_defaults(func=_reconstruct)

    r = sub.add_parser(
        "import-rig",
        help="rig.json from another tool's calibration: Quéau's light.mat + camera.mat, or its text (LUCES-style) form",
        description="Convert a near-field calibration in the camera frame of computer vision (x right, y down, "
        "z forward, origin at the camera centre, mm) into rig.json (the workbench's frame: origin on the optical "
        "axis in the reference plane, x right, y up, z towards the camera; principal point 0-based). CAL is "
        "light.mat (S positions, Dir axes, Phi intensities, mu lobes; camera.mat beside it with K, stored "
        "transposed, 1-based principal point), a folder holding both, or a folder of text tables "
        "(led_positions.txt or S.txt, led_directions.txt or Dir.txt, led_intensities.txt/light_intensities.txt "
        "or Phi.txt, led_mu.txt or mu.txt, K.txt). The files do not hold the working distance: give "
        "--camera-height, or --images (with --mask, --ambient) to estimate it from the photometric residual "
        "(printed and stored with its uncertainty; a given height far from the estimate is warned about).",
    )
    r.add_argument("calibration", metavar="CAL", help="light.mat, a folder with light.mat + camera.mat, or a "
                   "folder of text tables")
    r.add_argument("--camera-mat", default=None, metavar="FILE", help="camera.mat (default: beside light.mat)")
    r.add_argument("--k-origin", type=int, default=1, choices=(0, 1),
                   help="origin of the principal point in K (default 1: MATLAB's; 0 for a 0-based file)")
    r.add_argument("--camera-height", type=float, default=None, metavar="MM",
                   help="working distance: camera centre height above the reference plane, mm (default: estimated "
                   "from --images)")
    r.add_argument("--images", nargs="+", default=None, metavar="IMG",
                   help="the capture, one image per LED in the calibration's order: its size, and the working "
                   "distance estimate")
    r.add_argument("--image-size", default=None, metavar="H,W",
                   help="image size in pixels when no --images are given")
    r.add_argument("--mask", default=None, metavar="M", help="the part's mask for the working-distance estimate")
    _add_capture(r)
    r.add_argument("--led-axes", default=None, metavar="FILE",
                   help="LED axes 'x y z' per LED in the calibration's camera frame (replaces the file's Dir)")
    r.add_argument("--led-mu", default=None, metavar="MU", help="LED lobe exponent(s), replacing the file's mu")
    r.add_argument("--focal-length-px", default=None, metavar="F",
                   help="replaces the file's focal length: F or FX,FY (pixels)")
    r.add_argument("--principal-point-px", default=None, metavar="X,Y",
                   help="replaces the file's principal point: column,row in pixels, 0-based")
    r.add_argument("--out", default="rig.json", help="rig file to write (default rig.json)")
    r.set_defaults(func=_import_rig)

    c = sub.add_parser(
        "calibrate",
        help="near-field rig: LED positions from mirror spheres, flat-field gains, camera -> rig.json",
        description="Calibrate a near-field rig. Each --spheres folder holds one image per LED "
        "(filenames.txt, light order) of a mirror sphere and sphere.json ({'radius_mm': R, 'center_mm': "
        "[x, y, z]}; without it the sphere is found from its outline and taken to rest on z = 0). Each "
        "highlight gives a ray towards its LED (r = 2 (n.v) n - v); the LED is the least-squares nearest "
        "point of its rays from two or more folders (spheres at different places or heights). Flat-field "
        "images add per-light gain maps. Writes rig.json and, with a flat field, <name>_gains.npz beside "
        "it; prints each LED's position, residuals and uncertainty.",
    )
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("--spheres", nargs="+", default=None, metavar="DIR",
                     help="two or more mirror-sphere folders")
    src.add_argument("--light-positions", default=None, metavar="P",
                     help="known LED positions ('x y z' mm per light) instead of spheres (needs --flat-field)")
    _add_camera(c, "orthographic pixel size in mm (default: the sphere folders' scene.json)")
    c.add_argument("--flat-field", nargs="+", default=None, metavar="F",
                   help="flat-field images (flat matte target on z = 0), one per light in light order")
    _add_checkerboard(c)
    _add_rig_options(c)
    c.set_defaults(func=_calibrate)


def _add_checkerboard(c: argparse.ArgumentParser) -> None:
    """The camera from checkerboard views (shared by ``photometric calibrate`` and ``inspect calibrate``)."""
    c.add_argument("--checkerboard", nargs="+", default=None, metavar="IMG",
                   help="checkerboard views (3 or more, tilted differently; the first lying on the reference plane "
                   "unless --camera-height is given): the perspective camera with its lens distortion, calibrated "
                   "by OpenCV (fx, fy, principal point, k1,k2,p1,p2,k3) and its RMS reprojection error, into rig.json; "
                   "the sphere and flat-field images are undistorted with it")
    c.add_argument("--board", default=None, metavar="COLSxROWS", help="inner corners of the checkerboard, e.g. 9x6")
    c.add_argument("--square-mm", type=float, default=None, metavar="S", help="side of one checkerboard square, mm")


def _checkerboard_camera(args: argparse.Namespace):
    """The camera of ``--checkerboard`` (and its calibration record), or (None, None)."""
    if getattr(args, "checkerboard", None) is None:
        if getattr(args, "board", None) is not None or getattr(args, "square_mm", None) is not None:
            raise InputError("--board/--square-mm: only with --checkerboard")
        return None, None
    from photometric.camera import calibrate_checkerboard
    from photometric.io import read_images

    if args.board is None or args.square_mm is None:
        raise InputError("--checkerboard: needs --board COLSxROWS and --square-mm S")
    parts = args.board.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise InputError(f"--board: expected COLSxROWS inner corners (e.g. 9x6), got {args.board!r}")
    if any(getattr(args, k, None) is not None for k in ("pixel_size", "focal_length_px", "principal_point",
                                                         "distortion")) or args.camera == "orthographic":
        raise InputError("--checkerboard: calibrates the perspective camera itself (leave out --pixel-size, "
                         "--focal-length-px, --principal-point-px, --distortion)")
    images = read_images(list(args.checkerboard))
    return calibrate_checkerboard(list(images), (int(parts[0]), int(parts[1])), args.square_mm,
                                  camera_height_mm=args.camera_height)


def _calibrate(args: argparse.Namespace) -> int:
    from photometric.camera import make_camera
    from workbench.runs.photometric import calibrate_to_rig

    opts = _camera_options(args)
    folders = [*(args.spheres or []), *([Path(args.light_positions).parent] if args.light_positions else []),
               *(Path(f).parent for f in args.flat_field or [])]
    warn_camera_conflicts(dict.fromkeys(folders), pixel_size=args.pixel_size, camera=args.camera,
                          focal_length_px=_fx(args.focal_length_px), camera_height_mm=args.camera_height)
    if opts.pop("distortion", None) is not None:
        raise InputError("--distortion: give the lens through --checkerboard (the sphere and flat-field images are "
                         "then undistorted with it), or to reconstruct")
    camera, board = _checkerboard_camera(args)
    spheres, flats = args.spheres, args.flat_field
    if camera is not None and camera.distortion is not None:
        from dataclasses import replace

        from photometric.calibrate import read_sphere_set
        from photometric.camera import undistort_images
        from photometric.io import read_images

        if spheres is not None:
            spheres = [read_sphere_set(d, camera)[0] for d in spheres]
            spheres = [replace(s, images=undistort_images(camera, s.images)[0]) for s in spheres]
        if flats is not None:
            flats = undistort_images(camera, read_images(list(flats)))[0]
    if camera is None and any(v is not None for v in (*opts.values(), args.pixel_size)):
        model = opts["camera"] or ("perspective" if args.focal_length_px or args.camera_height else "orthographic")
        camera = make_camera(model, pixel_size_mm=args.pixel_size, focal_length_px=opts["focal_length_px"],
                             camera_height_mm=args.camera_height, principal_point_px=opts["principal_point_px"])
    rig = calibrate_to_rig(
        args.out,
        spheres=spheres,
        light_positions=args.light_positions,
        camera=camera,
        flat_field=flats,
        flat_albedo=args.flat_albedo,
        led_mu=None if args.led_mu is None else _numbers(args.led_mu, "--led-mu"),
        intensities=args.intensities,
        window_px=args.window,
    )
    cal = rig["calibration"]
    if board is not None:
        from surfaces.io import write_json

        cal = rig["calibration"] = {**cal, "camera_calibration": board}
        write_json(args.out, rig)
        print(f"camera from {board['views']} checkerboard views: RMS reprojection error "
              f"{board['rms_reprojection_px']:.3f} px, height {rig['camera']['camera_height_mm']:.2f} mm "
              f"({board['camera_height_source']}), distortion {rig['camera'].get('distortion')}")
    print(f"{len(rig['lights']['positions_mm'])} LEDs, {rig['camera']['model']} camera, "
          f"{rig['image_size'][0]} x {rig['image_size'][1]} px, flat field "
          f"{'yes' if rig['flat_field'] else 'no'} ({cal['method']})")
    for k, pos in enumerate(rig["lights"]["positions_mm"]):
        line = f"LED {k}: ({pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}) mm"
        if "residuals_mm" in cal:
            sd = cal["uncertainty_mm"][k]
            line += (f", ray residuals {', '.join(f'{r:.3f}' for r in cal['residuals_mm'][k])} mm, "
                     f"uncertainty ({sd[0]:.3f}, {sd[1]:.3f}, {sd[2]:.3f}) mm")
            if "sensitivity" in cal:
                sens = cal["sensitivity"][k]
                line += (f" (along the ray {sens['along_ray_mm']:.3f} mm, across {sens['across_ray_mm']:.3f} mm, "
                         f"rays {sens['ray_angle_deg']:.1f} deg apart)")
        print(line)
    if cal.get("birge_ratio") is not None:
        print(f"Birge ratio of the ray residuals {cal['birge_ratio']:.2f} ({cal['dof']} degrees of freedom, 99 % bound "
              f"{cal['birge_bound']:.2f}): uncertainties scaled by {cal['uncertainty_scale']:.2f}")
    for note in cal.get("advice", []):
        print(f"advice: {note}")
    print(f"wrote {args.out} (every number above is in it)")
    return 0


def _add_capture(p: argparse.ArgumentParser) -> None:
    """The capture's realities: a dark frame and Bayer mosaics."""
    from photometric.io import BAYER_PATTERNS

    p.add_argument("--ambient", nargs="+", default=None, metavar="IMG",
                   help="dark frame(s) (all LEDs off, same exposure) subtracted from the images, clipped at 0: one "
                   "for all images or one per image")
    p.add_argument("--bayer", default=None, choices=BAYER_PATTERNS,
                   help="the image files (and dark frames) are raw Bayer mosaics of this layout (top-left 2 x 2 "
                   "cell, row by row), demosaiced to RGB at full resolution (OpenCV bilinear) when read")


def _pair(text: str | None, flag: str, what: str):
    if text is None:
        return None
    v = _numbers(text, flag)
    if not isinstance(v, list) or len(v) != 2:
        raise InputError(f"{flag}: expected {what}, got {text!r}")
    return v


def _is_calibration(path) -> bool:
    """A calibration of another tool (light.mat, or a folder of them or of text tables), not rig.json."""
    from pathlib import Path

    p = Path(path)
    return p.suffix.lower() == ".mat" or p.is_dir()


def _capture(images, mask, ambient, bayer):
    """Grey-or-colour image stack (ambient subtracted) and mask, as the working-distance search needs them."""
    from photometric.io import read_ambient, read_images, read_mask

    imgs = read_images(list(images), bayer=bayer)
    if ambient:
        read_ambient(ambient, imgs, bayer)
    m = None if mask is None else read_mask(mask, imgs.shape[1:3])
    return imgs, m


def _imported(cal, *, camera_height, images, mask, ambient, bayer, image_size=None, axes=None, focal=None,
              pp=None, estimate=True):
    """Rig of an imported calibration at the given or estimated working distance, and the estimate (or None)."""
    from photometric.distance import estimate_camera_height, height_warning
    from photometric.importers import to_rig

    est, warning = None, None
    if images is None:
        if camera_height is None:
            raise InputError("--camera-height: the calibration does not hold the working distance; give it, or the "
                             "images (--images) to estimate it")
        size = image_size
        return to_rig(cal, camera_height, size, axes=axes, focal_length_px=focal, principal_point_px=pp), None, None
    imgs, m = _capture(images, mask, ambient, bayer)
    size = imgs.shape[1:3]
    start = camera_height if camera_height is not None else 2.5 * float(cal.positions_mm[:, 2].max())
    rig = to_rig(cal, start, size, axes=axes, focal_length_px=focal, principal_point_px=pp)
    if estimate or camera_height is None:
        est = estimate_camera_height(imgs, rig, mask=m)
        if camera_height is None:
            rig = to_rig(cal, est.camera_height_mm, size, axes=axes, focal_length_px=focal, principal_point_px=pp)
        else:
            warning = height_warning(camera_height, est)
        rig.calibration["working_distance"] = {**est.to_dict(), "source": "estimated" if camera_height is None
                                               else "given", "given_mm": camera_height}
    return rig, est, warning


def _print_estimate(est, given) -> None:
    if est is None:
        return
    print(f"working distance: {est.camera_height_mm:.1f} mm +- {2 * est.u_mm:.1f} mm (U, k = 2; curvature "
          f"u {est.u_curvature_mm:.2g} mm, spatial jackknife u {est.u_jackknife_mm:.2g} mm), photometric residual "
          f"{est.residual_rms:.4g} of full scale at {est.binning}x{est.binning} binning"
          + ("" if given is None else f"; using the given {given:g} mm"))


def _import_rig(args: argparse.Namespace) -> int:
    import sys

    from photometric.importers import read_calibration
    from photometric.importers import load_axes
    from workbench.runs.photometric import write_rig

    cal = read_calibration(args.calibration, args.camera_mat, k_origin=args.k_origin)
    size = _pair(args.image_size, "--image-size", "H,W")
    if args.images is None and size is None:
        raise InputError("--image-size: give the image size (H,W) or the images (--images)")
    axes = None if args.led_axes is None else load_axes(args.led_axes)
    if args.led_mu is not None:
        from dataclasses import replace

        import numpy as np

        mu = _numbers(args.led_mu, "--led-mu")
        cal = replace(cal, mu=np.broadcast_to(np.asarray(mu, float), (len(cal),)).copy())
    rig, est, warning = _imported(cal, camera_height=args.camera_height, images=args.images, mask=args.mask,
                                  ambient=args.ambient, bayer=args.bayer, image_size=size, axes=axes,
                                  focal=_focal(args.focal_length_px),
                                  pp=_pair(args.principal_point_px, "--principal-point-px", "X,Y (0-based)"))
    content = write_rig(rig, args.out)
    cam = content["camera"]
    print(f"{len(rig.lights)} LEDs from {cal.source.get('format')} calibration, perspective camera f "
          f"{cam['focal_length_px']:.2f}" + (f" x {cam['focal_length_y_px']:.2f}" if "focal_length_y_px" in cam else "")
          + f" px, principal point ({cam['principal_point_px'][0]:.2f}, {cam['principal_point_px'][1]:.2f}) px "
          f"(0-based), {rig.image_size[0]} x {rig.image_size[1]} px, camera height {cam['camera_height_mm']:.1f} mm")
    _print_estimate(est, args.camera_height)
    if warning:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"wrote {args.out}")
    return 0


def _rig_option(args: argparse.Namespace):
    """``--rig`` as ``reconstruct`` gets it: rig.json (moved to ``--camera-height`` when only that is given), or an
    imported calibration (light.mat) at the given or estimated working distance; the camera options left."""
    from photometric.importers import read_calibration
    from photometric.rig import at_camera_height, read_rig

    opts = _camera_options(args)
    if args.rig is None:
        return None, opts, None, None
    if _is_calibration(args.rig):
        if args.images is None:
            raise InputError("--rig: an imported calibration (light.mat or a calibration folder) needs --images")
        if args.camera not in (None, "perspective"):
            raise InputError("--camera: an imported calibration is a perspective camera")
        cal = read_calibration(args.rig)
        rig, est, warning = _imported(cal, camera_height=args.camera_height, images=args.images, mask=args.mask,
                                      ambient=args.ambient, bayer=args.bayer, focal=opts["focal_length_px"],
                                      pp=opts["principal_point_px"], estimate=not args.no_distance_estimate)
        return rig, {**dict.fromkeys(opts), "distortion": opts.get("distortion")}, est, warning
    if args.camera_height is not None and all(opts[k] is None for k in ("camera", "focal_length_px",
                                                                         "principal_point_px")):
        return (at_camera_height(read_rig(args.rig), args.camera_height),
                {**dict.fromkeys(opts), "distortion": opts.get("distortion")}, None, None)
    return args.rig, opts, None, None


def _add_to_summary(out, summary: dict, rig, est, warning) -> dict:
    """summary.json with the imported rig's source and the working distance (the CLI composed them)."""
    from pathlib import Path

    from surfaces.io import write_json

    cal = getattr(rig, "calibration", {}) or {}
    summary = dict(summary)
    summary["rig_source"] = {k: cal[k] for k in ("method", "source", "conversion", "camera_height_mm_moved_from")
                             if k in cal}
    if est is not None:
        summary["working_distance"] = cal.get("working_distance", est.to_dict())
    if warning:
        summary["warnings"] = [*summary.get("warnings", []), warning]
    write_json(Path(out) / "summary.json", summary)
    return summary


def _pm(value: float, expanded: float | None) -> str:
    """``0.100 ± 0.006 mm (k = 2)``."""
    from photometric.uncertainty import format_value

    return format_value(value, expanded, "mm")


def _height_rmse_line(summary: dict, args: argparse.Namespace, unit: str) -> str:
    """The height RMSE against the truth with its convention, and again with the best plane removed.

    The pipeline's ``height_rmse_mm`` removes the means only, so a tilt of the whole
    field (what a deviated light gives) is part of it. The plane-removed figure and the
    plane's tilt are added to ``summary.json`` (``height_rmse_plane_removed_mm``,
    ``height_error_tilt_deg``) beside it.
    """
    from pathlib import Path

    import numpy as np

    from surfaces.io import write_json

    out = Path(args.out)
    truth = None if args.folder is None else Path(args.folder) / "height_gt.npy"
    text = (f"height RMSE vs height_gt: {summary['height_rmse_mm']:.4g} {unit} with the means removed "
            "(a tilt of the whole field, e.g. from a deviated light, is included)")
    if truth is None or not truth.is_file() or not (out / "height.npy").is_file():
        return text
    height, valid, gt = np.load(out / "height.npy"), np.load(out / "valid.npy"), np.load(truth, allow_pickle=False)
    v = valid & np.isfinite(height)
    if gt.shape != height.shape or v.sum() < 3:
        return text
    rows, cols = np.nonzero(v)
    diff = height[v] - gt[v]
    design = np.column_stack([cols, rows, np.ones_like(cols)]).astype(np.float64)
    coef, *_ = np.linalg.lstsq(design, diff, rcond=None)
    rmse_plane = float(np.sqrt(np.mean((diff - design @ coef) ** 2)))
    pixel = float(summary.get("pixel_size_mm") or 1.0)
    tilt = float(np.degrees(np.arctan(np.hypot(coef[0], coef[1]) / pixel)))
    summary.update(height_rmse_plane_removed_mm=rmse_plane, height_error_tilt_deg=tilt)
    write_json(out / "summary.json", summary)
    scene = Path(args.folder) / "scene.json"
    cause = ""
    if scene.is_file():
        dev = np.abs(np.asarray(json.loads(scene.read_text()).get("deviations_deg") or [0.0], float))
        if dev.size and dev.max() > 0:
            cause = f"; the scene's true lights deviate from the nominal ones by up to {dev.max():g} deg"
    return (f"{text}; {rmse_plane:.4g} {unit} with the best plane removed (the error's plane tilts "
            f"{tilt:.3g} deg{cause})")


def _reconstruct(args: argparse.Namespace) -> int:
    import json

    from tqdm import tqdm

    from workbench.runs.photometric import reconstruct_to_folder

    if (args.folder is None) == (args.images is None):
        raise InputError("input: give either a folder DIR or --images (with --lights), not both")
    if args.images is not None and args.lights is None and args.light_positions is None and args.rig is None:
        raise InputError("--lights: required with --images (or --light-positions, or --rig)")
    if args.no_flat_field and args.flat_field is not None:
        raise InputError("--no-flat-field: cannot be combined with --flat-field")
    if args.rig is not None and (args.light_positions is not None or args.lights is not None):
        given = "--light-positions" if args.light_positions is not None else "--lights"
        raise InputError(f"--rig: the rig gives the LED positions; drop {given} (or --rig)")
    if args.images is not None and (args.triad or args.select):
        raise InputError("--triad/--select: only apply to a folder input")
    select = "triad" if args.triad else args.select
    warn_camera_conflicts([] if args.folder is None else [args.folder], rig=args.rig, pixel_size=args.pixel_size,
                          camera=args.camera, focal_length_px=_fx(args.focal_length_px),
                          camera_height_mm=args.camera_height)
    tolerances = _uncertainty_options(args)
    rig, camera_opts, est, warning = _rig_option(args)
    texture = _texture_options(args)
    stages = ["read", "normals", "height", "surface", "defects", *(["uncertainty"] if tolerances else []), "write"]
    # delay: no bar at all before an error in the first half second
    with tqdm(total=len(stages), desc="photometric", unit="stage", leave=False, delay=0.5) as bar:
        def progress(stage: str) -> None:
            bar.set_postfix_str(stage, refresh=False)  # update() draws it, after the delay
            if bar.n or stage != stages[0]:
                bar.update(1)

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
            max_patches=args.max_patches,
            background=args.background,
            light_positions=args.light_positions,
            led_mu=None if args.led_mu is None else _numbers(args.led_mu, "--led-mu"),
            led_axes=args.led_axes,
            flat_field=False if args.no_flat_field else args.flat_field,
            flat_albedo=args.flat_albedo,
            rig=rig,
            ambient=args.ambient,
            bayer=args.bayer,
            light_model=args.light_model,
            reflectance=args.reflectance,
            gloss_alpha=args.gloss_alpha,
            gloss_weight=args.gloss_weight,
            reference_height_mm=args.reference_height,
            tolerance_mm=DEFAULTS.tolerance_mm if args.tolerance is None else args.tolerance,
            max_iterations=args.max_iterations,
            estimate_intensities=args.estimate_intensities,
            uncertainty=tolerances,
            force=args.force,
            progress=progress,
            texture=texture,
            **camera_opts,
        )
        bar.update(bar.total - bar.n)
    if est is not None or not isinstance(rig, (str, type(None))):
        summary = _add_to_summary(args.out, summary, rig, est, warning)
    size = summary["size"]
    print(
        f"{size['images']} images of {size['width']} x {size['height']} px, "
        f"light condition number {summary['light_condition_number']:.3f}, "
        f"invalid {100 * summary['invalid_fraction']:.2f} % of the mask"
    )
    if summary.get("light_model") == "point" or summary.get("camera", {}).get("model") == "perspective":
        print(f"{summary['light_model']} lights, {summary['camera']['model']} camera: "
              f"{summary['iterations']} pass(es), final height change "
              + ("-" if summary["final_depth_change_mm"] is None else f"{summary['final_depth_change_mm']:.2g} mm")
              + f" (tolerance {summary['tolerance_mm']:g} mm)")
        led = summary.get("intensities") or {}
        if led.get("source") == "estimated":
            print("estimated LED intensities (LED 0 = 1): "
                  + ", ".join(f"{v / led['relative'][0]:.4f}" for v in led["relative"])
                  + f" ({led['rounds']} round(s))")
    if "mean_angular_error_deg" in summary:
        print(f"mean angular error vs normal_gt: {summary['mean_angular_error_deg']:.3f} deg")
    # Without a pixel size the heights are in pixel units, not mm.
    unit = "px" if summary["pixel_size_source"].startswith("default") else "mm"
    if "height_rmse_mm" in summary:
        print(_height_rmse_line(summary, args, unit))
    surface = ("no surface model (--surface none)" if summary["surface"] == "none" else
               f"{summary['n_patches']} patches ({summary['surface']}, surface within "
               f"{summary['surface_max_dev_mm']:.3g} {unit} of the height), {summary['mesh']['triangles']} triangles")
    print(f"height range {summary['height_range_mm']:.4g} {unit} ({summary['integrator']}), {surface}, "
          f"{summary['n_defects']} defect(s)")
    if "uncertainty" in summary:
        unc = summary["uncertainty"]
        print(f"uncertainty ({unc['method']}, k = 2): noise sigma {unc['noise_sigma']:.3g} "
              f"({unc['noise_sigma_source']}), median u(height) {unc['median_height_u_mm']:.3g} {unit}")
        with open(f"{args.out}/defects.json") as fh:
            for rec in json.load(fh)["defects"][:5]:
                k2 = rec.get("uncertainty_k2", {})
                print(f"  defect {rec['id']} ({rec['kind']}): "
                      f"depth {_pm(rec['max_depth_mm'], k2.get('max_depth_mm'))}, "
                      f"width {_pm(rec['mean_width_mm'], k2.get('mean_width_mm'))}, "
                      f"length {_pm(rec['length_mm'], k2.get('length_mm'))}")
    _print_estimate(est, args.camera_height)
    if warning:
        import sys

        print(f"warning: {warning}", file=sys.stderr)
    if "texture" in summary:
        from workbench.runs.texture import format_parameter

        tex = summary["texture"]
        band = tex["band"]
        print(f"texture (ISO 25178-2, band {band['short_mm'] * 1000:.4g} um to {band['long_mm']:.4g} mm, form "
              f"{tex['filters']['form']}): " + ", ".join(f"{n} {format_parameter(tex[n])}" for n in ("Sa", "Sq", "Sz"))
              + f"; every parameter in {args.out}/texture.json")
    print(f"total {summary['timings_s']['total']:.2f} s; wrote {args.out} (summary.json holds every number above)")
    return 0
