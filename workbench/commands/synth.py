"""``workbench synth triad|phantom``: synthetic scenes with exact ground truth."""

from __future__ import annotations

import argparse

import numpy as np

from workbench.commands.common import add_command


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
    p.add_argument("--size", type=int, default=512, help="image side in pixels (default 512)")
    p.add_argument("--pixel-size", type=float, default=0.05, help="pixel size in mm (default 0.05)")
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
    p.add_argument("--out", required=True, help="output folder")

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


def _parse_deviate(text: str | None, n: int) -> np.ndarray:
    if text is None:
        return np.zeros((n, 2))
    items = [s.strip() for s in text.split(",") if s.strip()]
    if len(items) != n:
        raise ValueError(f"--deviate: expected {n} values (one per light), got {len(items)} in {text!r}")
    rows = []
    for item in items:
        parts = item.split(":")
        if len(parts) > 2:
            raise ValueError(f"--deviate: {item!r} is neither SLANT nor SLANT:AZIMUTH")
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            raise ValueError(f"--deviate: {item!r} is not a number") from None
        rows.append(vals + [0.0] * (2 - len(vals)))
    return np.array(rows)


def _parse_specular(text: str | None) -> dict | None:
    if text is None:
        return None
    try:
        ks, shininess = (float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--specular: expected KS,SHININESS, got {text!r}") from None
    return {"ks": ks, "shininess": shininess}


def _triad(args: argparse.Namespace) -> int:
    from datasets_synthetic.render import make_triad_folder

    if args.lights < 1:
        raise ValueError(f"--lights: expected at least 1, got {args.lights}")
    albedo = args.albedo
    if albedo != "texture":
        try:
            albedo = float(albedo)
        except ValueError:
            raise ValueError(f"--albedo: expected 'texture' or a number, got {args.albedo!r}") from None
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
