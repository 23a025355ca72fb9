"""``workbench inspect calibrate|run|watch``: calibrate a rig once, then measure and decide part after part.

Thin layer over :mod:`workbench.inspect`: ``calibrate`` is ``workbench photometric
calibrate`` with the inspection's option names; ``run`` checks the spec, the rig and the
options before any work, then runs the parts through :mod:`workbench.batch` with a
progress bar in parts per second; ``watch`` polls an inbox. Every number printed is also
in ``OUT/inspect_run.json``, ``OUT/results.csv`` and each part's ``result.json``.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys

from workbench.commands.common import add_command
from surfaces.validate import InputError

_RUN_EPILOG = (
    "Per part OUT/<part>/result.json (verdict pass|fail|uncertain, every imperfection with value and U, the rule "
    "that decided) and overlay.png; OUT/results.csv gets one row per part as it finishes, OUT/report.html and "
    "OUT/inspect_run.json are written at the end. A rerun skips finished parts and parts that failed before (a "
    "failed part whose images changed is measured again; --retry-failed measures every failed part again); a "
    "part that cannot be measured (a dark, saturated, wrong-size or mixed-bit-depth frame, a measurement out of its "
    "quality limits, ...) is recorded "
    "(OUT/failed/<part>.json, verdict not_measured) and the run goes on (exit code 1). The spec is read once "
    "per run; its sha256 is in every result.json and row (spec_sha256). Part ids: letters, digits, . _ + - "
    "(a letter or digit first); nothing is written outside OUT. "
    "spec.json keys: max_depth_mm, max_length_mm, max_width_mm, max_area_mm2, max_count, max_total_area_mm2, "
    "min_distance_mm, roi_mm, exclusion_zones_mm, decision_rule (simple | guard_band), name."
)


def register(sub) -> None:
    """Add ``calibrate``, ``run`` and ``watch`` to the ``inspect`` group.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The group's sub-parser collection.
    """
    from workbench.commands.photometric import _add_camera, _add_checkerboard, _add_rig_options

    c = add_command(
        sub, "calibrate", _calibrate,
        help="calibrate the inspection rig once: LED positions, flat-field gains, camera -> rig.json",
        description="Calibrate a near-field inspection rig (as 'workbench photometric calibrate'): LED positions "
        "from a file or from two or more mirror-sphere folders, flat-field gains from images of a flat matte "
        "target on the reference plane (one per light, in light order), and the camera. Writes rig.json and "
        "<name>_gains.npz beside it. Without a flat field, --intensity-images estimates the relative LED "
        "intensities from images of a matte part (semi-calibrated near-field solve) and stores them in rig.json.",
    )
    c.add_argument("--flat", dest="flat_field", nargs="+", default=None, metavar="F",
                   help="flat-field images (flat matte target on z = 0), one per light in light order (or "
                   "--intensity-images)")
    c.add_argument("--intensity-images", nargs="+", default=None, metavar="IMG",
                   help="without a flat field: images of a matte part (a flat target will do) under each LED, in "
                   "light order; the relative LED intensities are estimated from them (LED 0's = 1) and stored in "
                   "rig.json")
    src = c.add_mutually_exclusive_group(required=True)
    src.add_argument("--light-positions", default=None, metavar="P",
                     help="LED positions, one 'x y z' row in mm per light")
    src.add_argument("--spheres", nargs="+", default=None, metavar="DIR", help="two or more mirror-sphere folders")
    _add_camera(c, "orthographic (telecentric) pixel size in mm")
    _add_checkerboard(c)
    _add_rig_options(c)
    c.add_argument("--reference-part", default=None, metavar="DIR",
                   help="a clean reference part folder (one image per light): measured with the new rig, its "
                   "quality figures set the measurement-validity limits and its slopes the slope-bias reference "
                   "(rig.json 'quality'); without it the stated defaults apply. A reference that fails the "
                   "stated limits is refused")
    c.add_argument("--reflectance", default="lambertian", choices=("lambertian", "glossy"),
                   help="with --reference-part: the parts' reflectance model stored in rig.json; glossy measures "
                   "the lobe weight on the reference part (a level, flat part of the material) for --gloss-alpha")
    c.add_argument("--gloss-alpha", type=float, default=None, metavar="A",
                   help="glossy: GGX roughness of the parts' material (0 < A <= 1)")
    c.add_argument("--background", default=None, choices=("plane", "smooth"),
                   help="background model of the reference part's flatness (default: the options' default, plane)")

    r = add_command(
        sub, "run", _run,
        help="measure many parts and decide each against spec.json (pass, fail, uncertain)",
        description="Inspect every part of PARTS (a folder of part folders, each with one image per light in "
        "the rig's light order (filenames.txt, or the image names sorted), or a CSV / JSON-lines manifest with "
        "'input' and an optional 'id') with the calibrated rig, on a local Dask cluster or a running scheduler.",
        epilog=_RUN_EPILOG,
    )
    r.add_argument("parts", metavar="PARTS", help="folder of part folders, or a manifest")
    _add_common(r)
    r.add_argument("--retry-failed", action="store_true",
                   help="measure again the parts that failed before (a failed part whose images changed since is "
                   "measured again anyway)")

    w = add_command(
        sub, "watch", _watch,
        help="inspect new part folders as they arrive in an inbox",
        description="Poll INBOX for part folders; a part is inspected once all its images are there and have "
        "not changed for --settle seconds, and only once (finished and failed parts are known from OUT, so a "
        "restarted watch goes on where it stopped).",
        epilog=_RUN_EPILOG,
    )
    w.add_argument("inbox", metavar="INBOX", help="folder the part folders arrive in")
    _add_common(w)
    w.add_argument("--interval", type=float, default=2.0, metavar="S", help="seconds between polls (default 2)")
    w.add_argument("--settle", type=float, default=2.0, metavar="S",
                   help="a part's images must be unchanged this long before it counts (default 2 s)")
    w.add_argument("--timeout", type=float, default=None, metavar="S",
                   help="stop after this many seconds (default: run until interrupted)")
    w.add_argument("--retry-failed", action="store_true",
                   help="measure again, once, the parts that failed before this watch (a failed part whose images "
                   "change is measured again anyway)")


def _add_common(p: argparse.ArgumentParser) -> None:
    from workbench.commands.photometric import add_uncertainty_options

    p.add_argument("--rig", required=True, metavar="RIG", help="the calibrated rig (rig.json)")
    p.add_argument("--spec", required=True, metavar="SPEC", help="acceptance rules in mm (spec.json)")
    p.add_argument("--out", required=True, metavar="OUT", help="output folder (created when missing)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="worker processes of a local Dask cluster (default: number of CPUs)")
    where.add_argument("--scheduler", default="local", metavar="ADDRESS",
                       help="'local' (default) or a running scheduler tcp://HOST:8786")
    p.add_argument("--keep-arrays", action="store_true",
                   help="also write each part's arrays (npy), previews and surface.ply")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="reconstruction option for every part, e.g. background=smooth (repeatable)")
    add_uncertainty_options(
        p, note="Each imperfection's expanded uncertainty U (k = 2) goes into result.json; the guard_band "
        "rule needs it.",
        method_help="state each imperfection's expanded uncertainty U (k = 2) by this method; on by default "
        "(linear) when spec.json asks for guard_band or a tolerance is given")


_TOLERANCES = ("noise_sigma", "light_position_tolerance_mm", "light_tolerance_deg", "intensity_tolerance",
               "pixel_size_tolerance", "mc_samples")


def _options(args: argparse.Namespace) -> dict:
    """Reconstruction options: ``--option`` items and the uncertainty options."""
    from workbench.batch import coerce_value
    from workbench.inspect.spec import load_spec

    options = {}
    for item in args.option:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--option: expected KEY=VALUE, got {item!r}")
        options[key.strip()] = coerce_value(value.strip())
    tolerances = {k: getattr(args, k) for k in _TOLERANCES if getattr(args, k) is not None}
    for key, value in tolerances.items():
        flag = "--" + key.replace("_", "-")
        if key == "mc_samples":
            if value < 2:
                raise InputError(f"{flag}: need at least 2 Monte Carlo samples, got {value}")
        elif not math.isfinite(value) or value < 0:
            raise InputError(f"{flag}: must be a finite non-negative standard uncertainty, got {value}")
    wanted = args.uncertainty is not None or tolerances or load_spec(args.spec).decision_rule == "guard_band"
    if wanted:
        if "uncertainty" in options:
            raise InputError("--option uncertainty: give the uncertainty options instead (--uncertainty, "
                             "--noise-sigma, ...)")
        options["uncertainty"] = {**tolerances, "method": args.uncertainty or "linear"}
    return options


def _calibrate(args: argparse.Namespace) -> int:
    from workbench.commands.photometric import _calibrate as calibrate

    if args.intensity_images is not None:
        if args.flat_field is not None:
            raise InputError("--intensity-images: a flat field measures the LED power itself; give --flat or "
                             "--intensity-images, not both")
        if args.intensities is not None:
            raise InputError("--intensity-images: estimates the intensities; drop --intensities (or the images)")
        if args.reference_part is not None:
            raise InputError("--reference-part: measured with a flat-field rig (--flat), not with --intensity-images")
        return _calibrate_intensities(args)
    if args.flat_field is None:
        raise InputError("--flat: give the flat-field images, or --intensity-images to estimate the LED "
                         "intensities without a flat field")
    if args.reference_part is None:
        if args.reflectance != "lambertian" or args.gloss_alpha is not None:
            raise InputError("--reflectance/--gloss-alpha: the lobe weight is measured on a reference part "
                             "(--reference-part DIR)")
        return calibrate(args)
    if args.reflectance == "glossy" and args.gloss_alpha is None:
        raise InputError("--reflectance glossy: give the material's roughness (--gloss-alpha A)")
    import contextlib
    import copy
    import io
    import tempfile
    from dataclasses import replace
    from pathlib import Path

    from photometric.rig import read_rig
    from workbench.inspect.part import reference_quality, reference_reflectance
    from workbench.runs.photometric import write_rig

    if not Path(args.reference_part).is_dir():
        raise FileNotFoundError(f"--reference-part: folder {args.reference_part} does not exist")
    # calibrate into a scratch folder, measure the reference with that rig, then write rig.json once
    with tempfile.TemporaryDirectory(prefix="rig-") as tmp:
        scratch = copy.copy(args)
        scratch.out = str(Path(tmp) / "rig.json")
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            code = calibrate(scratch)
        print(printed.getvalue().replace(scratch.out, str(args.out)), end="")
        if code:
            return code
        rig = read_rig(scratch.out)
        options = {} if args.background is None else {"background": args.background}
        if args.reflectance == "glossy":
            rig = replace(rig, reflectance=reference_reflectance(args.reference_part, rig, args.gloss_alpha))
            print(f"reflectance glossy: alpha {rig.reflectance['alpha']:g}, lobe weight "
                  f"{rig.reflectance['weight']:.4g} (measured on the reference part)")
        quality = reference_quality(args.reference_part, rig, **options)
        write_rig(replace(rig, quality=quality), args.out)
    lim = quality["limits"]
    fig = quality["reference_figures"]
    print(f"reference part {args.reference_part}: background {1e3 * fig['background_rms_mm']:.3g} um RMS, invalid "
          f"{100 * fig['invalid_fraction']:.2g} %, mean slopes {quality['reference_slopes']}")
    print(f"quality limits -> {args.out}: background {1e3 * lim['background_rms_mm']:.3g} um, slope bias "
          f"{lim['slope_bias_mrad']:g} mrad, invalid {100 * lim['invalid_fraction']:.2g} %, Lambertian residual "
          f"{lim['lambertian_residual']:g}")
    return 0


def _calibrate_intensities(args: argparse.Namespace) -> int:
    """``inspect calibrate`` without a flat field: the rig's LEDs and camera, then the relative LED
    intensities estimated from images of a matte part (:func:`photometric.nearfield.solve_nearfield`
    with ``estimate_intensities``), stored in rig.json with the estimation's record."""
    from dataclasses import replace

    import numpy as np

    from photometric.calibrate import calibrate_rig
    from photometric.camera import make_camera
    from photometric.io import load_light_positions, read_images
    from photometric.leds import point_lights
    from photometric.nearfield import solve_nearfield
    from photometric.rig import Rig
    from workbench.commands.photometric import _camera_options, _numbers
    from workbench.runs.photometric import write_rig

    opts = _camera_options(args)
    camera = None
    if any(v is not None for v in (*opts.values(), args.pixel_size)):
        model = opts["camera"] or ("perspective" if args.focal_length_px or args.camera_height else "orthographic")
        # the parsed focal length (as photometric calibrate builds its camera)
        camera = make_camera(model, pixel_size_mm=args.pixel_size, focal_length_px=opts["focal_length_px"],
                             camera_height_mm=args.camera_height, principal_point_px=opts["principal_point_px"])
    images = read_images(list(args.intensity_images))
    mu = None if args.led_mu is None else _numbers(args.led_mu, "--led-mu")
    if args.spheres is not None:
        rig = calibrate_rig(spheres=args.spheres, camera=camera, led_mu=mu, window_px=args.window)
        if tuple(images.shape[1:3]) != tuple(rig.image_size):
            raise InputError(f"--intensity-images: {images.shape[1]} x {images.shape[2]} px, the sphere images "
                             f"{rig.image_size[0]} x {rig.image_size[1]} px")
    else:
        if camera is None:
            raise InputError("camera: give --camera with --pixel-size, or --focal-length-px and --camera-height")
        lights = point_lights(load_light_positions(args.light_positions), mu=mu)
        rig = Rig(lights, camera, (int(images.shape[1]), int(images.shape[2])),
                  calibration={"method": "known LED positions"})
    if images.shape[0] != len(rig.lights):
        raise InputError(f"--intensity-images: {images.shape[0]} image(s) for {len(rig.lights)} LEDs (one per LED)")
    res = solve_nearfield(images, rig.lights, rig.camera, estimate_intensities=True, residual=False)
    est = dict(res.intensities)
    rel = np.asarray(est["relative"], float)
    est.update(method="semi-calibrated near-field solve (Queau et al., JMIV 2018), LED 0's intensity fixed",
               images=[str(p) for p in args.intensity_images])
    rig = replace(rig, intensities=np.repeat(rel[:, None], 3, axis=1),
                  calibration={**rig.calibration, "intensities": est})
    content = write_rig(rig, args.out)
    print(f"{len(rig.lights)} LEDs, {content['camera']['model']} camera, {rig.image_size[0]} x {rig.image_size[1]} "
          f"px, no flat field ({rig.calibration['method']}); LED intensities estimated from "
          f"{images.shape[0]} images in {est['rounds']} round(s)")
    for k, pos in enumerate(rig.lights.positions):
        print(f"LED {k}: ({pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}) mm, intensity {rel[k]:.4f} "
              f"(radiant {est['radiant_relative'][k]:.4f})")
    print(f"wrote {args.out} (every number above is in it)")
    return 0


def _progress_bar(total: int):
    from tqdm import tqdm

    bar = tqdm(total=total, unit="part", file=sys.stderr, dynamic_ncols=True)
    counts = {"pass": 0, "fail": 0, "uncertain": 0, "error": 0}

    def progress(row: dict) -> None:
        key = row.get("verdict") or "error" if row["status"] == "ok" else "error"
        counts[key] = counts.get(key, 0) + 1
        bar.set_postfix(refresh=False, **counts)
        bar.update(1)

    return bar, progress


def _print_run(run, out) -> None:
    b = run.batch
    v = run.verdicts
    print(f"ran {b.ran}: {v['pass']} pass, {v['fail']} fail, {v['uncertain']} uncertain, {b.failed} could not be "
          f"measured; {b.skipped} skipped; {b.wall_s:.1f} s, {run.parts_per_second:.2f} parts/s")
    for row in b.rows:
        if row["status"] == "failed":
            print(f"  not measured {row['id']}: {row['error']}")
    print(f"results: {out}/results.csv; report: {run.report}")


def _run(args: argparse.Namespace) -> int:

    from workbench.batch import plan, prepare_out
    from workbench.inspect.part import load_rig
    from workbench.inspect.run import check_run_options, load_parts, make_jobs, retry_rule, run_inspection
    from workbench.inspect.spec import check_spec_field, load_spec

    # every input and option is checked before any part runs or anything is written
    rig = load_rig(args.rig)
    spec = load_spec(args.spec)
    check_spec_field(spec, rig.image_size, rig.camera.nominal_pixel_mm())
    options = check_run_options(_options(args), rig)
    parts = load_parts(args.parts)
    out = prepare_out(args.out)  # created (or refused) before the progress bar: a bad --out is one line
    steps = plan(make_jobs(parts, args.rig, spec), out, retry=retry_rule(args.retry_failed, out))
    again = f" ({len(steps.retried)} of them failed before: measured again)" if steps.retried else ""
    print(f"{len(parts)} part(s): {len(steps.to_run)} to inspect{again}, {len(steps.complete)} finished before "
          f"(skipped), {len(steps.failed_before)} failed before (skipped"
          + ("; --retry-failed measures them again)" if steps.failed_before else ")"))
    bar, progress = _progress_bar(len(steps.to_run))
    with bar:
        run = run_inspection(parts, args.rig, args.spec, args.out, keep_arrays=args.keep_arrays, options=options,
                             scheduler=args.scheduler, workers=args.workers, progress=progress,
                             command="workbench " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
                             retry_failed=args.retry_failed)
    _print_run(run, args.out)
    return 1 if run.batch.failed else 0


def _watch(args: argparse.Namespace) -> int:
    from workbench.inspect.watch import check_seconds, watch

    check_seconds(args.interval, "--interval", positive=True)
    check_seconds(args.settle, "--settle")
    check_seconds(args.timeout, "--timeout", optional=True)
    options = _options(args)
    print(f"watching {args.inbox} every {args.interval:g} s (a part counts after {args.settle:g} s unchanged)"
          + (f" for {args.timeout:g} s" if args.timeout is not None else "; Ctrl-C to stop"))

    def each(run) -> None:
        _print_run(run, args.out)

    def skipped(name: str, reason: str) -> None:
        print(f"workbench: warning: INBOX folder {name!r} skipped: {reason}", file=sys.stderr)

    total = watch(args.inbox, args.rig, args.spec, args.out, keep_arrays=args.keep_arrays, options=options,
                  scheduler=args.scheduler, workers=args.workers, interval=args.interval, settle=args.settle,
                  timeout=args.timeout, on_run=each, retry_failed=args.retry_failed, on_skip=skipped,
                  command="workbench " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    healed = f"; {total['healed']} result row(s) restored" if total["healed"] else ""
    print(f"watch ended: {total['ran']} part(s) inspected, {total['failed']} could not be measured, "
          f"{len(total['skipped_folders'])} folder(s) skipped{healed}")
    return 1 if total["failed"] or total["skipped_folders"] else 0
