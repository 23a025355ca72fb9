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
from pathlib import Path

from workbench.commands.common import add_command
# the run helpers live in workbench.runs.texture (one home); these names stay importable from here
from workbench.runs.texture import (  # noqa: F401
    NO_U_REASON,
    TEXTURE_LIMITS,
    format_parameter,
    judge_texture,
    measure_texture,
    read_height_source,
    texture_of_result,
    write_texture,
)


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
        print("  " + ", ".join(f"{name} {format_parameter(pars[name])}" for name in group))
    print(f"wrote {out / 'texture.json'} (every parameter, value, U (k = 2), unit) and {out / 'texture.png'}")
    return 0


def _measure_and_write(args: argparse.Namespace) -> dict:
    """Read, measure, write ``texture.json`` and ``texture.png``; return the JSON document."""
    height, pixel, mask, noise, pixel_source, integrator = read_height_source(
        args.source, pixel_size=args.pixel_size, mask=args.mask, integrator=args.integrator,
        height_u_mm=args.height_u_mm, s_filter_mm=args.s_filter_mm, no_uncertainty=args.no_uncertainty)
    tex, doc = measure_texture(height, pixel, mask, noise=noise, integrator=integrator, s_filter_mm=args.s_filter_mm,
                               l_filter_mm=args.l_filter_mm, form=args.form, edge=args.edge, smr_c_um=args.smr_c_um,
                               mc_samples=args.mc_samples, seed=args.seed,
                               no_uncertainty_reason="--no-uncertainty" if args.no_uncertainty else NO_U_REASON)
    doc["source"] = str(args.source)
    doc["pixel_size_source"] = pixel_source
    write_texture(tex, doc, args.out)
    return doc
