"""``workbench photometric texture``: ISO 25178-2 areal texture parameters of a measured height map.

Reads a ``photometric reconstruct`` result folder (``height.npy``, ``summary.json`` for
the pixel size, ``valid.npy``, and the uncertainty maps ``p_u.npy``/``q_u.npy`` or
``height_u.npy`` when written) or a bare ``height.npy``; applies the F-operator, the
ISO 16610-61 S- and L-filters and computes every parameter of
:mod:`photometric.texture` with its expanded uncertainty. Writes ``texture.json`` and
``texture.png`` (the S-L surface with a colour bar) to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from surfaces.validate import InputError
from workbench.commands.common import add_command, load_npy, write_summary


def register(subparsers) -> None:
    """Add the ``texture`` sub-command to the ``photometric`` group.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``photometric`` group's sub-parser collection.
    """
    p = add_command(
        subparsers,
        "texture",
        run,
        help="areal surface texture (ISO 25178-2: Sa, Sq, Sz, Sdr, Sal, Sk, Vmp, ...) of a height map, with U",
        description="Areal texture parameters (ISO 25178-2) of a measured height map: the F-operator removes "
        "the form (plane or second-degree polynomial), the Gaussian S- and L-filters of ISO 16610-61 (nesting "
        "indices in mm; normalised convolution at the edges of the field and of invalid pixels) select the "
        "wavelength band, and every height, hybrid, spatial, material-ratio and volume parameter is computed "
        "in micrometres with its expanded uncertainty (k = 2, Monte Carlo over the height's noise: the "
        "folder's p_u.npy/q_u.npy (integrated slope noise) or height_u.npy, or --height-u-mm). Writes "
        "texture.json (value, U, unit of every parameter; the band, filters and form) and texture.png.",
    )
    p.add_argument("source", metavar="HEIGHT_DIR|height.npy",
                   help="result folder of 'workbench photometric reconstruct' or a height map (.npy, (H, W), mm)")
    p.add_argument("--pixel-size", type=float, default=None, metavar="MM",
                   help="pixel size in mm (default: the folder's summary.json pixel_size_mm; required for a .npy)")
    p.add_argument("--s-filter-mm", type=float, default=None, metavar="X",
                   help="S-filter nesting index lambda_s, mm (default none: the band starts at two pixels)")
    p.add_argument("--l-filter-mm", type=float, default=None, metavar="Y",
                   help="L-filter nesting index lambda_c, mm (default none: the band ends at the field size)")
    p.add_argument("--form", default="plane", choices=("plane", "poly2", "none"),
                   help="F-operator: least-squares plane (default), second-degree polynomial, or none")
    p.add_argument("--edge", default=None, choices=("normalised", "drop"),
                   help="edge handling of the filters: normalised convolution, or also drop a band of 4 sigma of "
                   "the L-filter (about 0.75 lambda_c) along every edge (default: drop for heights integrated "
                   "from slopes, whose integrator leaves a boundary layer; normalised otherwise)")
    p.add_argument("--mask", default=None, metavar="M",
                   help="valid pixels (.npy of bool, (H, W); default the folder's valid.npy, else the finite heights)")
    p.add_argument("--integrator", default=None, choices=("dct", "lsq", "robust", "fc", "none"),
                   help="the slope integrator that made the heights: its transfer is divided out within the "
                   "S-filter (default: the folder's summary.json integrator; none for a .npy)")
    p.add_argument("--smr-c-um", type=float, default=0.0, metavar="C",
                   help="height c of Smr(c), um above the mean plane (default 0)")
    p.add_argument("--height-u-mm", type=float, default=None, metavar="U",
                   help="standard uncertainty of every height, mm, independent per pixel (overrides the folder's "
                   "uncertainty maps)")
    p.add_argument("--no-uncertainty", action="store_true", help="skip the Monte Carlo (U is null)")
    p.add_argument("--mc-samples", type=int, default=None, metavar="N",
                   help="Monte Carlo repetitions (default 50, at most 400)")
    p.add_argument("--seed", type=int, default=0, help="Monte Carlo seed (default 0)")
    p.add_argument("--out", default="texture_out", help="output folder (default texture_out)")


def _read(source: str, args: argparse.Namespace) -> tuple[np.ndarray, float, np.ndarray | None, dict, str, str]:
    """Height (mm), pixel size, mask, noise model keyword arguments, the pixel size's source, the integrator."""
    src = Path(source)
    noise: dict = {}
    mask = None
    integrator = args.integrator
    pixel, pixel_source = args.pixel_size, "--pixel-size"
    if src.is_dir():
        height = load_npy(src / "height.npy", "HEIGHT_DIR")
        summary = src / "summary.json"
        info = {}
        if summary.is_file():
            try:
                info = json.loads(summary.read_text())
            except (OSError, ValueError) as exc:
                raise InputError(f"HEIGHT_DIR: {summary} is not readable JSON ({exc})") from None
        if integrator is None and info.get("integrator") in ("dct", "lsq", "robust", "fc"):
            integrator = info["integrator"]
        if pixel is None:
            if not summary.is_file():
                raise InputError(f"--pixel-size: required, {src} has no summary.json")
            if "pixel_size_mm" not in info:
                raise InputError(f"--pixel-size: required, {summary} states no pixel_size_mm")
            if str(info.get("pixel_size_source", "")).startswith("default"):
                raise InputError(f"--pixel-size: required, {summary} has only the default pixel size (heights in "
                                 "pixel units, not mm)")
            pixel, pixel_source = float(info["pixel_size_mm"]), "summary.json"
        if (src / "valid.npy").is_file():
            mask = load_npy(src / "valid.npy", "HEIGHT_DIR valid.npy")
        if (src / "p_u.npy").is_file() and (src / "q_u.npy").is_file():
            noise = {"slope_u": (load_npy(src / "p_u.npy", "p_u.npy"), load_npy(src / "q_u.npy", "q_u.npy"))}
        elif (src / "height_u.npy").is_file():
            noise = {"height_u": load_npy(src / "height_u.npy", "height_u.npy")}
    elif src.suffix == ".npy" or src.is_file():
        height = load_npy(src, "height.npy")
        if pixel is None:
            raise InputError("--pixel-size: required with a .npy height map")
    else:
        raise FileNotFoundError(f"HEIGHT_DIR|height.npy: {src} does not exist")
    if height.ndim != 2:
        raise InputError(f"height: expected a 2-D map, got shape {height.shape}")
    if args.mask is not None:
        mask = load_npy(args.mask, "--mask")
    if mask is not None:
        if mask.shape != height.shape:
            raise InputError(f"--mask: shape {mask.shape} differs from the height's {height.shape}")
        mask = mask.astype(bool)
    for name, arr in noise.items():
        for a in (arr if isinstance(arr, tuple) else (arr,)):
            if a.shape != height.shape:
                raise InputError(f"{name}: shape {a.shape} differs from the height's {height.shape}")
    if args.height_u_mm is not None:
        if not args.height_u_mm >= 0:
            raise InputError(f"--height-u-mm: must be a non-negative standard uncertainty, got {args.height_u_mm}")
        noise = {"height_u": args.height_u_mm}
    if args.no_uncertainty:
        noise = {}
    if not (pixel is not None and math.isfinite(pixel) and pixel > 0):
        raise InputError(f"--pixel-size: must be a positive number of mm, got {pixel}")
    if integrator == "none":
        integrator = None
    if integrator is not None and args.s_filter_mm is None:
        integrator = None  # without an S-filter the integrator's transfer cannot be divided out (stated in the JSON)
    return np.asarray(height, dtype=np.float64), float(pixel), mask, noise, pixel_source, integrator


#: spec.json key -> the texture parameter it limits (upper limits, in the parameter's unit)
TEXTURE_LIMITS: dict[str, str] = {
    "max_Sa_um": "Sa", "max_Sq_um": "Sq", "max_Sz_um": "Sz", "max_Sp_um": "Sp", "max_Sv_um": "Sv",
    "max_Sdq": "Sdq", "max_Sdr_pct": "Sdr", "max_Sk_um": "Sk", "max_Spk_um": "Spk", "max_Svk_um": "Svk",
    "max_Vmp_ml_m2": "Vmp", "max_Vvv_ml_m2": "Vvv",
}


def judge_texture(texture_json: dict, limits: dict, rule: str) -> list[dict]:
    """Check texture parameters against spec limits with the inspection's decision rules.

    The value judged is the noise-bias ``corrected`` value with ``U_corrected`` when the
    texture has an uncertainty, else the value as measured (then only the ``simple``
    rule can decide).

    Parameters
    ----------
    texture_json : dict
        What ``texture.json`` holds (:meth:`photometric.texture.Texture.as_dict`).
    limits : dict
        Spec keys of :data:`TEXTURE_LIMITS` -> limit (other keys are ignored).
    rule : {"simple", "guard_band"}
        ISO 14253-1 decision rule (:func:`workbench.inspect.decide.decide_value`).

    Returns
    -------
    list of dict
        One check per limit: ``limit_key``, ``quantity``, ``value``, ``U``, ``limit``,
        ``unit``, ``verdict`` (``"pass"``, ``"uncertain"`` or ``"fail"``; a parameter that
        could not be determined is ``"uncertain"``).

    Examples
    --------
    >>> doc = {"parameters": {"Sa": {"value": 0.8, "U": 0.05, "unit": "um", "corrected": 0.79, "U_corrected": 0.02}}}
    >>> [c["verdict"] for c in judge_texture(doc, {"max_Sa_um": 0.8}, "guard_band")]
    ['uncertain']
    """
    from workbench.inspect.decide import decide_value

    checks = []
    for key, limit in limits.items():
        if key not in TEXTURE_LIMITS:
            continue
        name = TEXTURE_LIMITS[key]
        rec = texture_json["parameters"].get(name, {})
        if rec.get("corrected") is not None and rec.get("U_corrected") is not None:
            value, U = rec["corrected"], rec["U_corrected"]
        else:
            value, U = rec.get("value"), rec.get("U")
        if value is None:
            verdict = "uncertain"
        else:
            verdict = decide_value(value, U, limit, rule)
        checks.append({"limit_key": key, "quantity": name, "value": value, "U": U, "limit": float(limit),
                       "unit": rec.get("unit"), "verdict": verdict})
    return checks


def texture_of_result(folder, out=None, *, s_filter_mm: float | None, l_filter_mm: float | None,
                      form: str = "plane", edge: str | None = None, mc_samples: int | None = None,
                      seed: int = 0) -> dict:
    """The hook of ``photometric reconstruct --texture``: texture of a result folder, written beside it.

    Parameters
    ----------
    folder : path-like
        A ``photometric reconstruct`` result folder (or its staging folder before the swap).
    out : path-like, optional
        Where ``texture.json`` and ``texture.png`` go (default: ``folder``).
    s_filter_mm, l_filter_mm, form, edge, mc_samples, seed
        As the options of ``workbench photometric texture``.

    Returns
    -------
    dict
        What ``texture.json`` holds.
    """
    args = argparse.Namespace(source=str(folder), pixel_size=None, s_filter_mm=s_filter_mm, l_filter_mm=l_filter_mm,
                              form=form, edge=edge, mask=None, integrator=None, smr_c_um=0.0, height_u_mm=None,
                              no_uncertainty=False, mc_samples=mc_samples, seed=seed,
                              out=str(folder if out is None else out))
    return _measure_and_write(args)


def _picture(tex, path: Path) -> None:
    """The S-L surface with a colour bar, at most about 1000 pixels across."""
    from surfaces.io import write_png
    from workbench.images import scalar_image

    step = max(1, int(math.ceil(max(tex.surface.shape) / 1000)))
    img = scalar_image(tex.surface[::step, ::step], tex.area[::step, ::step], cmap="viridis", percentile=99.9,
                       label="S-L surface, um")
    write_png(path, img)


def _pm(rec: dict) -> str:
    if rec["value"] is None:
        return "not determined"
    text = f"{rec['value']:.4g}"
    if rec.get("U") is not None:
        text += f" +- {rec['U']:.2g}"
    return text + ("" if rec["unit"] == "1" else f" {rec['unit']}")


def run(args: argparse.Namespace) -> int:
    """Compute the texture and write ``texture.json`` and ``texture.png`` (the ``texture`` sub-command).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed options (see :func:`register`).

    Returns
    -------
    int
        Exit code 0.
    """
    summary = _measure_and_write(args)
    out = Path(args.out)
    band = summary["band"]
    print(f"band {band['short_mm'] * 1000:.4g} um ({band['short_limit']}) to {band['long_mm']:.4g} mm "
          f"({band['long_limit']}), form {summary['form']}, {summary['evaluation_area_px']} pixels")
    pars = summary["parameters"]
    for group in (("Sa", "Sq", "Sz", "Ssk", "Sku"), ("Sdq", "Sdr", "Sal", "Str"), ("Sk", "Spk", "Svk", "Vmp", "Vvv")):
        print("  " + ", ".join(f"{name} {_pm(pars[name])}" for name in group))
    print(f"wrote {out / 'texture.json'} (every parameter, value, U (k = 2), unit) and {out / 'texture.png'}")
    return 0


def _measure_and_write(args: argparse.Namespace) -> dict:
    """Read, measure, write ``texture.json`` and ``texture.png``; return the JSON document."""
    from photometric.texture import DEFAULT_MC_SAMPLES, gaussian_sigma_px, texture

    height, pixel, mask, noise, pixel_source, integrator = _read(args.source, args)
    edge = args.edge
    if edge is None:
        # integrated heights carry the integrator's boundary layer: leave it out when the field allows
        edge = "normalised"
        if integrator in ("dct", "lsq", "robust") and args.l_filter_mm:
            band = math.ceil(4.0 * gaussian_sigma_px(args.l_filter_mm, pixel))
            edge = "drop" if min(height.shape) - 2 * band >= 32 else "normalised"
    tex = texture(height, pixel, mask, s_filter_mm=args.s_filter_mm, l_filter_mm=args.l_filter_mm, form=args.form,
                  edge=edge, smr_c_um=args.smr_c_um, integrator=integrator,
                  mc_samples=args.mc_samples or DEFAULT_MC_SAMPLES, seed=args.seed, **noise)
    out = Path(args.out)
    summary = tex.as_dict()
    summary["source"] = str(args.source)
    summary["pixel_size_source"] = pixel_source
    if not noise:
        reason = ("no uncertainty map in the input (run 'photometric reconstruct' with an uncertainty option, e.g. "
                  "--uncertainty linear, for p_u.npy and q_u.npy) and no --height-u-mm"
                  if not args.no_uncertainty else "--no-uncertainty")
        summary["uncertainty"] = {"method": "not measured", "reason": reason}
    write_summary(out / "texture.json", summary)
    _picture(tex, out / "texture.png")
    return summary
