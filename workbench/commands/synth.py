"""``workbench synth triad|spheres|phantom``: synthetic scenes with exact ground truth.

``triad`` renders far-field image sets (distant lights, as before) or, with
``--light-distance``, near-field sets (point LEDs, orthographic or perspective
camera, flat-field images) in the folder layout of the near-field format
contract; ``spheres`` renders mirror-sphere calibration sets.
"""

from __future__ import annotations

import argparse

import numpy as np

from workbench.commands.common import add_command, parse_vector
from surfaces.validate import InputError


def register(sub) -> None:
    """Add ``triad`` and ``phantom`` to the ``synth`` group (see :mod:`workbench.commands`)."""
    from datasets_synthetic.heightfields import SCENES
    from datasets_synthetic.phantoms import SHAPES

    p = add_command(
        sub,
        "triad",
        _triad,
        help="render a height-field scene under N (deviated) lights as a DiLiGenT-layout folder",
        description="Render an analytic height field (exact normals, heights and defect truth) with "
        "Lambertian shading, shadows and noise. Images use the TRUE lights (nominal lights deviated by "
        "--deviate); light_directions.txt records the NOMINAL ones. Writes 001.png..., filenames.txt, "
        "light_directions.txt, light_intensities.txt, mask.png, normal_gt.npy, height_gt.npy, scene.json.",
    )
    p.add_argument("--scene", default="plate", choices=SCENES, help="scene name (default plate)")
    p.add_argument("--size", type=_size, default=512,
                   help="image side in pixels, or HxW (near field only; default 512)")
    p.add_argument("--pixel-size", type=float, default=None,
                   help="pixel size in mm (default 0.05; near field: the orthographic pixel size)")
    p.add_argument("--lights", type=int, default=3, help="number of lights on a ring (default 3)")
    p.add_argument("--slant", type=float, default=45.0, help="light slant from the view axis, deg (default 45)")
    p.add_argument("--azimuth0", type=float, default=90.0,
                   help="azimuth of the first light from +x towards +y (up), deg (default 90)")
    p.add_argument("--noise", type=float, default=0.005,
                   help="Gaussian noise standard deviation, full scale 1 (default 0.005)")
    p.add_argument("--shot-noise", type=float, default=0.0,
                   help="shot-noise scale g: signal g*Poisson(I/g) (default 0: off)")
    p.add_argument("--shadows", default="cast", choices=("cast", "attached", "none"),
                   help="shadow model (default cast)")
    p.add_argument("--deviate", default=None,
                   help="per-light deviation of the true from the nominal light, deg: comma-separated slant "
                   "values, or slant:azimuth pairs, one per light (e.g. 2,0,0 or 2:0,0:1,0:0; default none)")
    p.add_argument("--bit-depth", type=int, default=16, choices=(8, 16),
                   help="quantisation before writing 16-bit PNGs (default 16)")
    p.add_argument("--albedo", default="texture",
                   help="'texture' (smooth random albedo in [0.55, 0.9], default) or a constant")
    p.add_argument("--specular", default=None,
                   help="add a Blinn-Phong term: KS,SHININESS (e.g. 0.3,40; default none)")
    p.add_argument("--seed", type=int, default=0, help="random seed of scene, albedo and noise (default 0)")
    near = p.add_argument_group(
        "near field", "with --light-distance: point LEDs on the ring (slant, azimuth0) at that distance from the "
        "origin, inverse-square falloff and an LED lobe; writes the near-field folder of the format contract "
        "(adds light_positions.txt, flat_001.png ..., xy_gt.npy and the lights, camera and flat field in "
        "scene.json)")
    near.add_argument("--light-distance", type=float, default=None,
                      help="distance of every LED from the origin, mm (switches to the near-field model)")
    _add_near_options(near)
    p.add_argument("--out", required=True, help="output folder")

    p = add_command(
        sub,
        "spheres",
        _spheres,
        help="render mirror-sphere calibration images (one folder per sphere placement) under near LEDs",
        description="Render a polished sphere at each --centers placement under N point LEDs: per light one "
        "image with the LED's specular highlight (the LED a small emitting disc; the highlight traced on its own "
        "fine grid and blurred by a Gaussian lens PSF, so its centroid is sub-pixel exact) and a weak diffuse term. "
        "Writes OUT/sphere_01, OUT/sphere_02, ... (001.png..., "
        "filenames.txt, sphere.json with radius_mm and center_mm) and OUT/scene.json with the true rig.",
    )
    p.add_argument("--light-distance", type=float, required=True, help="distance of every LED from the origin, mm")
    p.add_argument("--lights", type=int, default=3, help="number of LEDs on a ring (default 3)")
    p.add_argument("--slant", type=float, default=45.0, help="LED slant from the view axis, deg (default 45)")
    p.add_argument("--azimuth0", type=float, default=90.0,
                   help="azimuth of the first LED from +x towards +y (up), deg (default 90)")
    p.add_argument("--centers", nargs="+", action="extend", required=True, metavar="X,Y,Z",
                   help="sphere centres in mm, one per placement (a sphere resting on the plane has Z = radius); "
                   "repeatable; write a centre with a negative X as --centers=-12,8,10")
    p.add_argument("--radius", type=float, default=10.0, help="sphere radius, mm (default 10)")
    p.add_argument("--led-radius", type=float, default=1.0, help="radius of each LED's emitting disc, mm (default 1)")
    p.add_argument("--supersample", type=int, default=4,
                   help="rays per pixel side for the sphere's diffuse image (default 4; the highlight is traced on "
                   "its own fine grid)")
    p.add_argument("--psf-sigma", type=float, default=1.0,
                   help="Gaussian lens blur of the highlight, pixels (default 1; 0: none)")
    p.add_argument("--background", type=float, default=0.0,
                   help="albedo of the matte reference plane around the sphere (default 0: black)")
    p.add_argument("--deviate", default=None,
                   help="per-LED deviation of the true from the nominal position on its sphere about the origin, "
                   "deg, as for triad (default none)")
    p.add_argument("--noise", type=float, default=0.0,
                   help="Gaussian noise standard deviation, full scale 1 (default 0)")
    p.add_argument("--bit-depth", type=int, default=16, choices=(8, 16),
                   help="quantisation before writing 16-bit PNGs (default 16)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    _add_camera_options(p, default_size="512")
    p.add_argument("--led-mu", default="0", help="LED lobe exponent(s) mu >= 0, one or one per LED (default 0)")
    p.add_argument("--out", required=True, help="output folder (one subfolder per placement)")

    p = add_command(
        sub,
        "phantom",
        _phantom,
        help="CT phantom with exact volume/area: contours JSON, DICOM CT series or RT Structure Set",
        description="Cut an analytic solid into planar contours (unequal point counts, optional noise) and "
        "write contours.json, truth.json (exact volume_mm3, volume_between_end_planes_mm3, area_mm2, ...) "
        "and surface_points.npy; --format dicom adds a CT series in ct/, rtstruct adds rtstruct.dcm too.",
    )
    p.add_argument("--shape", default="kidney", choices=SHAPES, help="phantom shape (default kidney)")
    p.add_argument("--spacing", type=float, default=2.5, help="slice spacing in mm (default 2.5)")
    p.add_argument("--pixel-size", "--pixel", dest="pixel_size", type=float, default=0.8,
                   help="CT pixel size in mm (default 0.8; --pixel is accepted too)")
    p.add_argument("--format", dest="fmt", default="json", choices=("json", "dicom", "rtstruct"),
                   help="json: contours only; dicom: + CT series; rtstruct: + CT series and RT Structure Set")
    p.add_argument("--points", type=int, default=64,
                   help="points on the longest contour; others get proportionally fewer (default 64)")
    p.add_argument("--noise", type=float, default=0.0, help="contour noise standard deviation, mm (default 0)")
    p.add_argument("--offset", type=float, default=0.0,
                   help="shift of the slice grid from the phantom's centre plane, mm (default 0)")
    p.add_argument("--surface-points", type=int, default=20000,
                   help="size of the true-surface sample surface_points.npy (default 20000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="output folder")


def _size(text: str):
    """``N`` (an int) or ``HxW`` (a tuple of ints) from ``--size``."""
    parts = text.lower().replace(",", "x").split("x")
    try:
        values = [int(v) for v in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or HxW pixels, got {text!r}") from None
    if len(values) not in (1, 2) or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected N or HxW positive pixel counts, got {text!r}")
    return values[0] if len(values) == 1 else tuple(values)


def _add_camera_options(p, default_size: str | None = None) -> None:
    """The camera and field options of the near-field commands."""
    if default_size is not None:
        p.add_argument("--size", type=_size, default=int(default_size),
                       help=f"image side in pixels, or HxW (default {default_size})")
        p.add_argument("--pixel-size", type=float, default=None,
                       help="orthographic pixel size in mm (default 0.05, or --field over the width)")
    p.add_argument("--camera", default="orthographic", choices=("orthographic", "perspective"),
                   help="orthographic (telecentric, --pixel-size) or perspective (pinhole, --focal-length-px and "
                   "--camera-height; default orthographic)")
    p.add_argument("--focal-length-px", type=float, default=None, help="perspective focal length, pixels")
    p.add_argument("--camera-height", type=float, default=None,
                   help="perspective camera centre's height above the reference plane z = 0, mm")
    p.add_argument("--field", type=float, default=None,
                   help="width of the field of view on the reference plane, mm (instead of --pixel-size, or of "
                   "--focal-length-px for a perspective camera: f = width * camera height / field)")
    p.add_argument("--vignetting", default=None,
                   help="camera vignetting: cos4 (perspective) or radial:K1[,K2...] (V = 1 + K1 rho^2 + ...; "
                   "default none)")


def _add_near_options(p) -> None:
    """The light, camera and flat-field options of ``triad --light-distance``."""
    p.add_argument("--led-mu", default=None,
                   help="LED lobe exponent(s) mu >= 0 about each LED's axis (aimed at the origin), one or one per "
                   "LED (default 0: isotropic)")
    p.add_argument("--intensities", default=None,
                   help="LED intensities e_k, comma-separated, one per LED (default all 1)")
    _add_camera_options(p)
    p.add_argument("--flat-albedo", type=float, default=None,
                   help="albedo of the flat-field target in the reference plane (default 0.8)")
    p.add_argument("--exposure", type=float, default=None,
                   help="exposure scale shared by part and flat images (default: the brightest clean value "
                   "becomes --peak, so nothing saturates)")
    p.add_argument("--peak", type=float, default=None,
                   help="brightest clean value of the automatic exposure, full scale 1 (default 0.9)")


def _floats(text: str | None, option: str, n: int | None = None) -> np.ndarray | None:
    """Comma-separated numbers of an option (one, or ``n`` of them when given)."""
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in str(text).split(",") if v.strip()])
    except ValueError:
        raise InputError(f"{option}: expected comma-separated numbers, got {text!r}") from None
    if values.size == 0 or (n is not None and values.size not in (1, n)):
        raise InputError(f"{option}: expected one value or {n} (one per light), got {text!r}")
    return values


def _vignetting(text: str | None) -> dict | None:
    """``--vignetting`` as a :func:`datasets_synthetic.cameras.vignetting_map` specification."""
    if text is None:
        return None
    if text == "cos4":
        return {"model": "cos4"}
    if text.startswith("radial:"):
        return {"model": "radial", "coefficients": _floats(text[len("radial:"):], "--vignetting").tolist()}
    raise InputError(f"--vignetting: expected cos4 or radial:K1[,K2...], got {text!r}")


def _camera_settings(args: argparse.Namespace) -> dict:
    """Pixel size / focal length / camera height from the camera options, with one-line errors."""
    h, w = (args.size, args.size) if isinstance(args.size, int) else args.size
    pixel_size, focal, height = args.pixel_size, args.focal_length_px, args.camera_height
    if args.camera == "orthographic":
        if focal is not None or height is not None:
            raise InputError("--focal-length-px, --camera-height: only for --camera perspective")
        if args.field is not None:
            if pixel_size is not None:
                raise InputError("--field, --pixel-size: give one of them")
            pixel_size = _positive(args.field, "--field") / w
        return {"pixel_size": 0.05 if pixel_size is None else _positive(pixel_size, "--pixel-size"),
                "focal_length_px": None, "camera_height": None}
    if pixel_size is not None:
        raise InputError("--pixel-size: a perspective camera's scale is --camera-height / --focal-length-px")
    if height is None:
        raise InputError("--camera-height: a perspective camera needs its height above the reference plane (mm)")
    _positive(height, "--camera-height")
    if args.field is not None:
        if focal is not None:
            raise InputError("--field, --focal-length-px: give one of them")
        focal = w * height / _positive(args.field, "--field")
    if focal is None:
        raise InputError("--focal-length-px: a perspective camera needs a focal length (or --field)")
    return {"pixel_size": None, "focal_length_px": _positive(focal, "--focal-length-px"), "camera_height": height}


def _positive(value: float, option: str) -> float:
    if not value > 0:
        raise InputError(f"{option}: must be positive, got {value}")
    return float(value)


def _check_ring(args: argparse.Namespace) -> None:
    """One-line errors for LEDs that would not be above the reference plane."""
    if args.light_distance <= 0:
        raise InputError(f"--light-distance: must be positive (mm from the origin), got {args.light_distance}")
    if not 0.0 <= args.slant < 90.0:
        raise InputError(f"--slant: an LED at slant {args.slant} deg is not above the reference plane z = 0; "
                         "expected [0, 90)")
    if args.lights < 1:
        raise InputError(f"--lights: expected at least 1, got {args.lights}")


def _parse_deviate(text: str | None, n: int) -> np.ndarray:
    if text is None:
        return np.zeros((n, 2))
    items = [s.strip() for s in text.split(",") if s.strip()]
    if len(items) != n:
        raise InputError(f"--deviate: expected {n} values (one per light), got {len(items)} in {text!r}")
    rows = []
    for item in items:
        parts = item.split(":")
        if len(parts) > 2:
            raise InputError(f"--deviate: {item!r} is neither SLANT nor SLANT:AZIMUTH")
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            raise InputError(f"--deviate: {item!r} is not a number") from None
        rows.append(vals + [0.0] * (2 - len(vals)))
    return np.array(rows)


def _parse_specular(text: str | None) -> dict | None:
    if text is None:
        return None
    try:
        ks, shininess = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--specular: expected KS,SHININESS, got {text!r}") from None
    return {"ks": ks, "shininess": shininess}


NEAR_ONLY = ("led_mu", "intensities", "focal_length_px", "camera_height", "field", "vignetting", "flat_albedo",
             "exposure", "peak")


def _triad(args: argparse.Namespace) -> int:
    from datasets_synthetic.render import make_triad_folder

    if args.lights < 1:
        raise InputError(f"--lights: expected at least 1, got {args.lights}")
    albedo = args.albedo
    if albedo != "texture":
        try:
            albedo = float(albedo)
        except ValueError:
            raise InputError(f"--albedo: expected 'texture' or a number, got {args.albedo!r}") from None
    if args.light_distance is not None:
        return _near_triad(args, albedo)
    given = [name for name in NEAR_ONLY if getattr(args, name) is not None]
    if given or args.camera != "orthographic":
        names = ", ".join("--" + n.replace("_", "-") for n in given) or "--camera perspective"
        raise InputError(f"{names}: near-field options; give --light-distance MM too")
    if not isinstance(args.size, int):
        raise InputError(f"--size: HxW images need --light-distance (far-field sets are square), got {args.size}")
    args.pixel_size = 0.05 if args.pixel_size is None else args.pixel_size
    scene = make_triad_folder(
        args.out, scene=args.scene, size=args.size, lights=args.lights, slant=args.slant,
        noise=args.noise, shadows=args.shadows, deviate=_parse_deviate(args.deviate, args.lights),
        seed=args.seed, pixel_size=args.pixel_size, azimuth0=args.azimuth0, albedo=albedo,
        shot_noise=args.shot_noise, bit_depth=args.bit_depth, specular=_parse_specular(args.specular),
        progress=True,
    )
    print(f"scene {scene['scene']}: {scene['size']} x {scene['size']} px, "
          f"{scene['pixel_size_mm']} mm/px, {scene['n_lights']} lights at slant {scene['slant_deg']} deg")
    for k, (err, frac) in enumerate(zip(scene["light_error_deg"], scene["shadow_fraction"])):
        print(f"  light {k + 1}: true vs nominal {float(err):.3f} deg, cast shadow {100 * frac:.2f} %")
    for d in scene["defects"]:
        print(f"  {d['kind']}: depth {d['depth_mm']:.4f} mm, width {d['width_mm']:.4f} mm, "
              f"length {d['length_mm']:.4f} mm, area {d['area_mm2']:.4f} mm^2")
    print(f"wrote {args.out} (scene.json holds every number above)")
    return 0


def _near_triad(args: argparse.Namespace, albedo) -> int:
    from datasets_synthetic.nearfield import FLAT_ALBEDO, PEAK, make_near_field_folder

    _check_ring(args)
    if args.specular is not None:
        raise InputError("--specular: the near-field renderer is Lambertian; drop --specular or --light-distance")
    cam = _camera_settings(args)
    mu = _floats(args.led_mu, "--led-mu", args.lights)
    intensities = _floats(args.intensities, "--intensities", args.lights)
    scene = make_near_field_folder(
        args.out, scene=args.scene, size=args.size, lights=args.lights, slant=args.slant,
        light_distance=args.light_distance, led_mu=0.0 if mu is None else mu, camera=args.camera,
        pixel_size=cam["pixel_size"], focal_length_px=cam["focal_length_px"], camera_height=cam["camera_height"],
        noise=args.noise, shot_noise=args.shot_noise, shadows=args.shadows,
        deviate=_parse_deviate(args.deviate, args.lights), seed=args.seed, azimuth0=args.azimuth0,
        intensities=None if intensities is None else np.broadcast_to(intensities, (args.lights,)),
        albedo=albedo, bit_depth=args.bit_depth, vignetting=_vignetting(args.vignetting), exposure=args.exposure,
        peak=PEAK if args.peak is None else args.peak,
        flat_albedo=FLAT_ALBEDO if args.flat_albedo is None else args.flat_albedo, progress=True,
    )
    h, w = scene["image_size"]
    camera = scene["camera"]
    view = (f"orthographic, {camera['pixel_size_mm']} mm/px" if camera["model"] == "orthographic" else
            f"perspective, f {camera['focal_length_px']:g} px at {camera['camera_height_mm']:g} mm "
            f"({scene['pixel_size_mm']:.5g} mm/px on z = 0)")
    print(f"scene {scene['scene']}: {h} x {w} px, {view}; {scene['n_lights']} LEDs at slant "
          f"{scene['slant_deg']} deg, {scene['light_distance_mm']} mm from the origin")
    for k, (pos, err, frac) in enumerate(zip(scene["lights"]["positions_mm"], scene["light_error_deg"],
                                             scene["shadow_fraction"])):
        print(f"  LED {k + 1}: at ({pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}) mm, true vs nominal "
              f"{float(err):.3f} deg, cast shadow {100 * frac:.2f} %")
    print(f"  exposure {scene['exposure']:.6g} ({'automatic' if scene['exposure_auto'] else 'given'}), "
          f"saturated {100 * scene['saturated_fraction']:.3f} %, flat field albedo {scene['flat_field']['albedo']}")
    for d in scene["defects"]:
        print(f"  {d['kind']}: depth {d['depth_mm']:.4f} mm, width {d['width_mm']:.4f} mm, "
              f"length {d['length_mm']:.4f} mm, area {d['area_mm2']:.4f} mm^2")
    print(f"wrote {args.out} (scene.json holds every number above)")
    return 0


def _spheres(args: argparse.Namespace) -> int:
    from datasets_synthetic.spheres import make_sphere_folders

    _check_ring(args)
    cam = _camera_settings(args)
    centers = [parse_vector(c, "--centers") for c in args.centers]
    mu = _floats(args.led_mu, "--led-mu", args.lights)
    scene = make_sphere_folders(
        args.out, centers, args.radius, size=args.size, lights=args.lights, slant=args.slant,
        light_distance=args.light_distance, azimuth0=args.azimuth0, led_mu=mu, camera=args.camera,
        pixel_size=cam["pixel_size"], focal_length_px=cam["focal_length_px"], camera_height=cam["camera_height"],
        led_radius=args.led_radius, supersample=args.supersample, psf_sigma_px=args.psf_sigma,
        background=args.background, deviate=_parse_deviate(args.deviate, args.lights),
        vignetting=_vignetting(args.vignetting), noise=args.noise, bit_depth=args.bit_depth, seed=args.seed,
    )
    print(f"{len(scene['spheres'])} sphere placement(s), radius {scene['radius_mm']} mm, {scene['n_lights']} LEDs "
          f"(disc radius {scene['led_radius_mm']} mm)")
    for sphere in scene["spheres"]:
        where = ", ".join(f"({r:.2f}, {c:.2f})" for r, c in sphere["highlights_px"])
        print(f"  {sphere['folder']}: centre {sphere['center_mm']} mm, highlights at (row, col) {where}")
    print(f"wrote {args.out} (scene.json holds the true LED positions)")
    return 0


def _phantom(args: argparse.Namespace) -> int:
    from datasets_synthetic.phantoms import make_phantom, write_phantom

    phantom = make_phantom(args.shape)
    truth = write_phantom(args.out, phantom, args.spacing, args.pixel_size, fmt=args.fmt,
                          n_points=args.points, noise_mm=args.noise, seed=args.seed,
                          offset_mm=args.offset, n_surface=args.surface_points, progress=True)
    print(f"phantom {truth['shape']}: volume {truth['volume_mm3']:.3f} mm^3, "
          f"area {truth['area_mm2']:.3f} mm^2")
    print(f"  {truth['n_contours']} contours on {truth['n_planes']} planes, z "
          f"{truth['z_first_contour_mm']:.3f} .. {truth['z_last_contour_mm']:.3f} mm; volume between "
          f"end planes {truth['volume_between_end_planes_mm3']:.3f} mm^3")
    if "ct" in truth:
        ct = truth["ct"]
        print(f"  CT series: {ct['n_slices']} slices of {ct['rows']} x {ct['columns']} px")
    print(f"wrote {args.out} (truth.json holds every number above)")
    return 0
