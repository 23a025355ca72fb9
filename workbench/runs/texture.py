"""Areal texture (ISO 25178-2) of a measured height, written beside it: one home for the texture's run helpers.

:mod:`photometric.texture` computes; this module reads a height (a ``photometric
reconstruct`` result folder or a bare ``height.npy``), chooses the edge handling, writes
``texture.json`` and ``texture.png`` (:data:`TEXTURE_FILES`) and judges the parameters
against spec limits (:data:`TEXTURE_LIMITS`, :func:`judge_texture`). The command
``workbench photometric texture``, ``photometric reconstruct --texture``
(:func:`workbench.runs.photometric.reconstruct_to_folder`) and the inspection
(:func:`workbench.inspect.part.inspect_part`) all call these.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from surfaces.validate import InputError

__all__ = ["TEXTURE_FILES", "TEXTURE_LIMITS", "TEXTURE_DEFAULTS", "FORMS", "texture_options", "read_height_source",
           "default_edge", "measure_texture", "write_texture", "texture_of_result", "format_parameter",
           "judged_value", "judge_texture"]

#: files ``texture.json`` and ``texture.png`` (the S-L surface with a colour bar)
TEXTURE_FILES = ("texture.json", "texture.png")
#: F-operators a run or a spec may name (``none`` only on the ``photometric texture`` command)
FORMS = ("plane", "poly2")
#: defaults of ``photometric reconstruct --texture`` and of a spec's ``texture`` key: no S-filter (the band
#: starts at two pixels), no L-filter (it ends at the field size), the least-squares plane removed
TEXTURE_DEFAULTS: dict = {"s_filter_mm": None, "l_filter_mm": None, "form": "plane"}

#: spec.json key -> the texture parameter it limits (upper limits, in the parameter's unit)
TEXTURE_LIMITS: dict[str, str] = {
    "max_Sa_um": "Sa", "max_Sq_um": "Sq", "max_Sz_um": "Sz", "max_Sp_um": "Sp", "max_Sv_um": "Sv",
    "max_Sdq": "Sdq", "max_Sdr_pct": "Sdr", "max_Sk_um": "Sk", "max_Spk_um": "Spk", "max_Svk_um": "Svk",
    "max_Vmp_ml_m2": "Vmp", "max_Vvv_ml_m2": "Vvv",
}


def texture_options(doc=None, where: str = "texture") -> dict:
    """Check the filters and form of a texture run (a spec's ``texture`` key, ``--texture-*`` options).

    Parameters
    ----------
    doc : dict, optional
        Any of ``s_filter_mm``, ``l_filter_mm`` (positive mm or None) and ``form``
        (:data:`FORMS`); missing keys take :data:`TEXTURE_DEFAULTS`.
    where : str
        Name of the input, for messages.

    Returns
    -------
    dict
        ``{"s_filter_mm", "l_filter_mm", "form"}``.

    Raises
    ------
    InputError
        An unknown key, a filter that is not a positive number, ``s_filter_mm >= l_filter_mm``,
        or an unknown form.

    Examples
    --------
    >>> texture_options({"l_filter_mm": 0.8})
    {'s_filter_mm': None, 'l_filter_mm': 0.8, 'form': 'plane'}
    """
    doc = {} if doc is None else doc
    if not isinstance(doc, dict):
        raise InputError(f"{where}: expected an object with s_filter_mm, l_filter_mm, form; got {doc!r}")
    unknown = [k for k in doc if k not in TEXTURE_DEFAULTS]
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(TEXTURE_DEFAULTS)})")
    out = {**TEXTURE_DEFAULTS, **doc}
    for key in ("s_filter_mm", "l_filter_mm"):
        v = out[key]
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise InputError(f"{where} {key}: expected a positive number of mm, got {v!r}")
        out[key] = float(v)
    if out["s_filter_mm"] is not None and out["l_filter_mm"] is not None and out["s_filter_mm"] >= out["l_filter_mm"]:
        raise InputError(f"{where}: s_filter_mm ({out['s_filter_mm']:g}) must be below l_filter_mm "
                         f"({out['l_filter_mm']:g})")
    if out["form"] not in FORMS:
        raise InputError(f"{where} form: expected one of {', '.join(FORMS)}, got {out['form']!r}")
    return out


def read_height_source(source, *, pixel_size: float | None = None, mask=None, integrator: str | None = None,
                       height_u_mm: float | None = None, s_filter_mm: float | None = None,
                       no_uncertainty: bool = False) -> tuple[np.ndarray, float, np.ndarray | None, dict, str, str]:
    """Read a height to measure the texture of: a result folder or a bare ``height.npy``.

    Parameters
    ----------
    source : path-like
        A ``photometric reconstruct`` result folder (``height.npy``, ``summary.json`` for the
        pixel size and the integrator, ``valid.npy``, ``p_u.npy``/``q_u.npy`` or
        ``height_u.npy``) or a height map ``.npy`` ((H, W), mm).
    pixel_size : float, optional
        Pixel size, mm (default: the folder's ``summary.json``; required for a ``.npy``).
    mask : path-like, optional
        Valid pixels (``.npy`` of bool, (H, W)); default the folder's ``valid.npy``.
    integrator : str, optional
        The slope integrator that made the heights (default: the folder's); ``"none"``: none.
    height_u_mm : float, optional
        Standard uncertainty of every height, mm (overrides the folder's maps).
    s_filter_mm : float, optional
        The S-filter: without it the integrator's transfer cannot be divided out, so the
        integrator returned is None.
    no_uncertainty : bool
        Give no noise model.

    Returns
    -------
    height : numpy.ndarray, (H, W) float64, mm
    pixel : float, mm
    mask : numpy.ndarray of bool or None
    noise : dict
        Keyword arguments of :func:`photometric.texture.texture` (``height_u`` or ``slope_u``; empty: none).
    pixel_source : str
        ``"--pixel-size"`` or ``"summary.json"``.
    integrator : str or None

    Raises
    ------
    FileNotFoundError, InputError
        A missing source, a missing or default pixel size, shapes that differ.
    """
    from workbench.commands.common import load_npy

    src = Path(source)
    noise: dict = {}
    valid = None
    pixel, pixel_source = pixel_size, "--pixel-size"
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
            valid = load_npy(src / "valid.npy", "HEIGHT_DIR valid.npy")
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
    if mask is not None:
        valid = load_npy(mask, "--mask")
    if valid is not None:
        if valid.shape != height.shape:
            raise InputError(f"--mask: shape {valid.shape} differs from the height's {height.shape}")
        valid = valid.astype(bool)
    for name, arr in noise.items():
        for a in (arr if isinstance(arr, tuple) else (arr,)):
            if a.shape != height.shape:
                raise InputError(f"{name}: shape {a.shape} differs from the height's {height.shape}")
    if height_u_mm is not None:
        if not height_u_mm >= 0:
            raise InputError(f"--height-u-mm: must be a non-negative standard uncertainty, got {height_u_mm}")
        noise = {"height_u": height_u_mm}
    if no_uncertainty:
        noise = {}
    if not (pixel is not None and math.isfinite(pixel) and pixel > 0):
        raise InputError(f"--pixel-size: must be a positive number of mm, got {pixel}")
    if integrator == "none":
        integrator = None
    if integrator is not None and s_filter_mm is None:
        integrator = None  # without an S-filter the integrator's transfer cannot be divided out (stated in the JSON)
    return np.asarray(height, dtype=np.float64), float(pixel), valid, noise, pixel_source, integrator


def default_edge(integrator: str | None, l_filter_mm: float | None, pixel_size: float, shape) -> str:
    """The filters' edge handling when none is asked for.

    Heights integrated from slopes (``dct``, ``lsq``, ``robust``) carry the integrator's
    boundary layer: with an L-filter, a band of 4 sigma of it is left out along every edge
    (``"drop"``) when at least 32 pixels remain across; otherwise ``"normalised"``.

    Parameters
    ----------
    integrator : str or None
    l_filter_mm : float or None
    pixel_size : float
        mm.
    shape : (H, W)

    Returns
    -------
    {"normalised", "drop"}
    """
    from photometric.texture import gaussian_sigma_px

    if integrator in ("dct", "lsq", "robust") and l_filter_mm:
        band = math.ceil(4.0 * gaussian_sigma_px(l_filter_mm, pixel_size))
        if min(shape) - 2 * band >= 32:
            return "drop"
    return "normalised"


def measure_texture(height, pixel_size: float, mask=None, *, noise: dict | None = None, integrator: str | None = None,
                    s_filter_mm: float | None = None, l_filter_mm: float | None = None, form: str = "plane",
                    edge: str | None = None, smr_c_um: float = 0.0, mc_samples: int | None = None,
                    seed: int = 0, no_uncertainty_reason: str | None = None):
    """The texture of a height and the document ``texture.json`` holds.

    Parameters
    ----------
    height : (H, W) array_like
        Heights, mm (NaN: not measured).
    pixel_size : float
        mm.
    mask : (H, W) array_like of bool, optional
        Valid pixels.
    noise : dict, optional
        ``height_u`` (mm) or ``slope_u`` (``(p_u, q_u)``) of :func:`photometric.texture.texture`;
        none: U is not measured.
    integrator : str, optional
        The slope integrator that made the heights (its transfer is divided out within the S-filter).
    s_filter_mm, l_filter_mm, form, smr_c_um, seed
        As :func:`photometric.texture.texture`.
    edge : {"normalised", "drop"}, optional
        Default :func:`default_edge`.
    mc_samples : int, optional
        Monte Carlo repetitions (default :data:`photometric.texture.DEFAULT_MC_SAMPLES`).
    no_uncertainty_reason : str, optional
        Why there is no noise model, stated in the document's ``uncertainty`` when ``noise`` is empty.

    Returns
    -------
    tex : photometric.texture.Texture
    doc : dict
        :meth:`photometric.texture.Texture.as_dict`, with ``uncertainty`` saying ``not measured``
        and why when there was no noise model.
    """
    from photometric.texture import DEFAULT_MC_SAMPLES, texture

    noise = noise or {}
    z = np.asarray(height)
    if edge is None:
        edge = default_edge(integrator if s_filter_mm is not None else None, l_filter_mm, pixel_size, z.shape)
    if s_filter_mm is None:
        integrator = None
    tex = texture(z, pixel_size, mask, s_filter_mm=s_filter_mm, l_filter_mm=l_filter_mm, form=form, edge=edge,
                  smr_c_um=smr_c_um, integrator=integrator, mc_samples=mc_samples or DEFAULT_MC_SAMPLES, seed=seed,
                  **noise)
    doc = tex.as_dict()
    if not noise:
        doc["uncertainty"] = {"method": "not measured", "reason": no_uncertainty_reason or "no noise model given"}
    return tex, doc


def write_texture(tex, doc: dict, out) -> list[str]:
    """Write ``texture.json`` (``doc``) and ``texture.png`` (the S-L surface with a colour bar) into ``out``.

    Parameters
    ----------
    tex : photometric.texture.Texture
    doc : dict
        What ``texture.json`` holds.
    out : path-like
        Folder (created when missing).

    Returns
    -------
    list of str
        :data:`TEXTURE_FILES`.
    """
    from surfaces.io import write_json, write_png
    from workbench.images import scalar_image

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    write_json(folder / "texture.json", doc)
    step = max(1, int(math.ceil(max(tex.surface.shape) / 1000)))  # at most about 1000 pixels across
    img = scalar_image(tex.surface[::step, ::step], tex.area[::step, ::step], cmap="viridis", percentile=99.9,
                       label="S-L surface, um")
    write_png(folder / "texture.png", img)
    return list(TEXTURE_FILES)


#: why a folder's texture has no U
NO_U_REASON = ("no uncertainty map in the input (run 'photometric reconstruct' with an uncertainty option, e.g. "
               "--uncertainty linear, for p_u.npy and q_u.npy) and no --height-u-mm")


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
        What ``texture.json`` holds (with ``source`` and ``pixel_size_source``).
    """
    height, pixel, mask, noise, pixel_source, integrator = read_height_source(folder, s_filter_mm=s_filter_mm)
    tex, doc = measure_texture(height, pixel, mask, noise=noise, integrator=integrator, s_filter_mm=s_filter_mm,
                               l_filter_mm=l_filter_mm, form=form, edge=edge, mc_samples=mc_samples, seed=seed,
                               no_uncertainty_reason=NO_U_REASON)
    doc["source"] = str(folder)
    doc["pixel_size_source"] = pixel_source
    write_texture(tex, doc, folder if out is None else out)
    return doc


def format_parameter(rec: dict) -> str:
    """One parameter of ``texture.json`` as text: the value to the decimal of U's second significant digit.

    Parameters
    ----------
    rec : dict
        ``{"value", "U", "unit"}`` (``U`` may be missing or None: 4 significant digits).

    Returns
    -------
    str

    Examples
    --------
    >>> format_parameter({"value": 0.81234, "U": 0.1234, "unit": "um"})
    '0.81 +- 0.12 um'
    >>> format_parameter({"value": 0.4567891, "U": None, "unit": "1"})
    '0.4568'
    """
    from workbench.batch.results import round_to_u

    if rec.get("value") is None:
        return "not determined"
    value, U = round_to_u(rec["value"], rec.get("U"))
    text = value if U is None else f"{value} +- {U}"
    return text + ("" if rec.get("unit") in (None, "1") else f" {rec['unit']}")


def judged_value(rec: dict) -> tuple[float | None, float | None]:
    """The value a texture parameter is judged by, and its U (k = 2).

    The noise-bias ``corrected`` value with ``U_corrected`` when the texture has an
    uncertainty, else the value as measured with its ``U`` (None without a noise model).

    Parameters
    ----------
    rec : dict
        One parameter of ``texture.json``.

    Returns
    -------
    (float or None, float or None)

    Examples
    --------
    >>> judged_value({"value": 0.8, "U": 0.05, "corrected": 0.79, "U_corrected": 0.02})
    (0.79, 0.02)
    >>> judged_value({"value": 0.8, "U": None})
    (0.8, None)
    """
    if rec.get("corrected") is not None and rec.get("U_corrected") is not None:
        return rec["corrected"], rec["U_corrected"]
    return rec.get("value"), rec.get("U")


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
        ``limit_kind`` (``"max"``), ``unit``, ``rule``, ``verdict`` (``"pass"``,
        ``"uncertain"`` or ``"fail"``; a parameter that could not be determined is
        ``"uncertain"``).

    Raises
    ------
    InputError
        ``guard_band`` and a determined parameter without U (measure with an uncertainty, or
        use the ``simple`` rule).

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
        value, U = judged_value(rec)
        if value is None:
            verdict = "uncertain"
        else:
            if rule == "guard_band" and U is None:
                raise InputError(f"guard_band: texture {name} has no expanded uncertainty U (inspect with an "
                                 "uncertainty option, or use decision_rule 'simple')")
            verdict = decide_value(value, U, limit, rule)
        checks.append({"limit_key": key, "quantity": name, "value": value, "U": U, "limit": float(limit),
                       "limit_kind": "max", "unit": rec.get("unit"), "rule": rule, "verdict": verdict})
    return checks
