"""One inspected part: its images, the near-field solve with the rig, the verdict, its files.

:func:`inspect_part` reads one part folder (one image per light, in the rig's light order),
measures it with the calibrated rig (point lights, camera, flat-field gains), decides the
imperfections against the spec (:func:`workbench.inspect.decide.judge`) and writes, each
file atomically:

``result.json``
    verdict, decision rule, the checks that decided, every imperfection with each value
    and its U (k = 2), the part checks, the spec and the measurement's key figures.
``overlay.png``
    :func:`workbench.inspect.overlay.overlay_image`.

The measurement composes the library's stages (:mod:`photometric.stages`) with the same
:class:`photometric.options.PhotometricOptions` as :func:`photometric.pipeline.reconstruct`:
read, solve (near field with the rig's strengths prepared once per process,
:func:`photometric.nearfield.nearfield_setup`), integrate, measure and, when asked, the
uncertainty, which needs the height and the defects; no surface model and no mesh, which
nothing of ``result.json`` uses. With ``keep_arrays``, or with an option only the pipeline
takes (``surface``, ``step``, ...), the part runs through :func:`photometric.pipeline.reconstruct`
instead, and ``keep_arrays`` writes its heavy files
(:func:`workbench.runs.photometric.write_result`: npy arrays, PNG previews,
``surface.ply``, ``defects.json``, ``summary.json``). The part folder itself appears
complete or not at all when the part runs through :func:`workbench.batch.execute_job`
(``workbench inspect run``).
"""

from __future__ import annotations

import functools
import inspect as _inspect
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photometric.rig import Rig, read_rig
from surfaces.io import write_json, write_png
from workbench.inspect.decide import judge
from workbench.inspect.overlay import overlay_image, overlay_text
from workbench.inspect.spec import Spec, load_spec
from surfaces.validate import InputError

__all__ = ["IMAGE_SUFFIXES", "RESULT_FORMAT", "RESERVED_OPTIONS", "DIRECT_OPTIONS", "check_options", "part_images",
           "load_rig", "inspect_part", "reference_quality", "reference_reflectance"]

#: image files a part folder may hold (one per light)
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".npy")
#: ``format`` of result.json
RESULT_FORMAT = "workbench-inspection"
#: reconstruct options the inspection sets itself (the rig gives lights and camera)
RESERVED_OPTIONS = ("source", "rig", "lights", "light_positions", "mask", "progress", "select", "options", "out")
#: reconstruct options the inspection's own composition of the stages takes (any other option, or
#: ``keep_arrays``, runs :func:`photometric.pipeline.reconstruct`)
DIRECT_OPTIONS = ("integrator", "background", "outliers", "dark", "saturation", "highlight", "reference_height_mm",
                  "tolerance_mm", "max_iterations", "force", "uncertainty", "reflectance", "gloss_alpha",
                  "gloss_weight")
# what result.json reports of a measurement's summary (photometric.stages.summarize)
_SUMMARY_KEYS = ("pixel_size_mm", "light_model", "camera", "converged", "iterations", "n_defects", "invalid_fraction",
                 "size", "uncertainty", "timings_s", "quality", "reflectance")
# files of a captured or rendered folder that are not part images
_NOT_IMAGES = ("mask.png",)


def check_options(options: dict) -> dict:
    """Check reconstruction options (``--option KEY=VALUE``) against the pipeline before any work.

    Parameters
    ----------
    options : dict
        Keyword options of :func:`photometric.pipeline.reconstruct` (``integrator``,
        ``background``, ``tolerance_mm``, the uncertainty options, ...).

    Returns
    -------
    dict
        ``options`` unchanged.

    Raises
    ------
    InputError
        An option the pipeline does not take, one the inspection sets itself, or a value
        :class:`photometric.options.PhotometricOptions` refuses.
    """
    from photometric.options import split_keywords
    from photometric.pipeline import reconstruct

    known = set(_inspect.signature(reconstruct).parameters) - set(RESERVED_OPTIONS)
    for key in options:
        if key in RESERVED_OPTIONS:
            raise InputError(f"--option {key}: set by the inspection itself (the rig and the part folder)")
        if key not in known:
            raise InputError(f"--option {key}: not an option of photometric reconstruct (known: "
                             f"{', '.join(sorted(known))})")
    split_keywords(options)  # the values too: PhotometricOptions checks them once, before any part
    return options


def part_images(folder, n_lights: int) -> list[Path]:
    """The images of one part folder, in light order.

    The folder's ``filenames.txt`` (one name per line) gives the order when present;
    otherwise every image file (:data:`IMAGE_SUFFIXES`, ``mask.png`` and ``flat_*`` aside)
    sorted by name.

    Parameters
    ----------
    folder : str or Path
    n_lights : int
        Lights of the rig: the folder must hold exactly one image per light.

    Returns
    -------
    list of Path

    Raises
    ------
    FileNotFoundError
        The folder, or an image named in ``filenames.txt``, does not exist.
    ValueError
        Fewer or more images than lights (the message names the missing or extra count).
    """
    root = Path(folder)
    if not root.is_dir():
        raise FileNotFoundError(f"part {root}: no such folder")
    listing = root / "filenames.txt"
    if listing.is_file():
        names = [line.strip() for line in listing.read_text().splitlines() if line.strip()]
        paths = [root / n for n in names]
        missing = [p.name for p in paths if not p.is_file()]
        if missing:
            raise FileNotFoundError(f"part {root.name}: image {missing[0]} named in filenames.txt does not exist")
    else:
        paths = sorted(p for p in root.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                       and p.name not in _NOT_IMAGES and not p.name.startswith("flat_"))
    if len(paths) != n_lights:
        what = "missing" if len(paths) < n_lights else "extra"
        raise InputError(f"part {root.name}: {len(paths)} image(s) for {n_lights} lights of the rig "
                         f"({abs(len(paths) - n_lights)} {what}; one image per light, in light order)")
    return paths


@functools.lru_cache(maxsize=4)
def _cached_rig(path: str, mtime_ns: int) -> Rig:
    return read_rig(path)


def load_rig(rig) -> Rig:
    """Read ``rig.json`` once per process (its gains are large): cached by path and modification time.

    Parameters
    ----------
    rig : str, Path or photometric.rig.Rig

    Returns
    -------
    photometric.rig.Rig
    """
    if isinstance(rig, Rig):
        return rig
    p = Path(rig).resolve()
    if not p.is_file():
        raise FileNotFoundError(f"--rig: file {p} does not exist")
    return _cached_rig(str(p), os.stat(p).st_mtime_ns)


@functools.lru_cache(maxsize=4)
def _cached_spec(path: str, mtime_ns: int) -> Spec:
    return load_spec(path)


def _spec(spec) -> Spec:
    if isinstance(spec, Spec):
        return spec
    p = Path(spec).resolve()
    if not p.is_file():
        raise FileNotFoundError(f"--spec: file {p} does not exist")
    return _cached_spec(str(p), os.stat(p).st_mtime_ns)


# (rig, its near-field set-up) of the rigs this process measured with, newest last
_SETUPS: list = []


def _setup(rig: Rig):
    """The rig's near-field strengths, once per process and rig (a 5 MP flat field takes about 2 s)."""
    from photometric.nearfield import nearfield_setup

    for known, setup in _SETUPS:
        if known is rig:
            return setup
    setup = nearfield_setup(rig.lights, rig.camera, rig.image_size, rig.gains)
    _SETUPS[:] = _SETUPS[-1:] + [(rig, setup)]
    return setup


@dataclass(frozen=True)
class _Measured:
    """What the verdict, the overlay and result.json need of one part's measurement."""

    albedo: np.ndarray
    mask: np.ndarray
    valid: np.ndarray
    defects: list
    pixel_size_mm: float
    summary: dict  # the pipeline summary's keys that result.json reports, and timings_s
    result: object = None  # the full PhotometricReconstruction (pipeline path only)
    height: np.ndarray | None = None  # mm, NaN where not measured (the overlay's shaded panel)
    labels: np.ndarray | None = None  # id + 1 on each defect's pixels (the overlay's outlines)
    slope_u: tuple | None = None  # (p_u, q_u) standard uncertainties of the slopes (the texture's noise model)
    integrator: str = "dct"  # the integrator that made the height (the texture divides out its transfer)


def _measure_direct(paths: list, mask_path, rig: Rig, options: dict, threads: int | None) -> _Measured:
    """Read, solve, integrate, measure (and, when asked, the uncertainty of) one part: the library's stages.

    The same stages and options as :func:`photometric.pipeline.reconstruct` with ``rig`` (its
    near-field path), without the surface model and the mesh, which nothing of ``result.json`` uses.
    """
    from photometric import stages
    from photometric.options import photometric_options

    opts = photometric_options(**options)
    t_all = time.perf_counter()
    inp = stages.read([str(p) for p in paths], opts, rig=rig, mask=None if mask_path is None else str(mask_path))
    # nothing of result.json uses the fit residual: the solve skips it unless the noise is estimated from it
    sol = stages.solve(inp, opts, residual=opts.uncertainty is not None, threads=threads,
                       setup=_setup(rig) if rig.gains is not None else None)
    height = stages.integrate(inp, sol, opts)
    found = stages.measure(inp, sol, height, opts, labels=True)  # the overlay draws the outlines
    timings = {"read": inp.seconds, "screen": sol.timings_s["screen"],
               "nearfield": sol.timings_s["total"] - sol.timings_s["screen"], "solve": sol.timings_s["solve"],
               "integrate": sol.timings_s["integrate"], "defects": found.seconds}
    defects, unc = found.defects, None
    if opts.uncertainty is not None:
        t0 = time.perf_counter()
        unc = stages.uncertainty(inp, sol, height, found, opts)
        timings["uncertainty"] = time.perf_counter() - t0
        defects = _with_u(defects, unc)
    timings["total"] = time.perf_counter() - t_all
    s = stages.summarize(inp, sol, height, found, opts, unc=unc, timings=timings)
    summary = {k: s.get(k) for k in _SUMMARY_KEYS}
    summary["flat_field"] = s.get("flat_field") is not None
    return _Measured(sol.fit.albedo, sol.data.mask, sol.fit.valid, defects, inp.pixel_size_mm, summary,
                     height=height.height, labels=found.labels,
                     slope_u=None if unc is None else (unc.p_u, unc.q_u), integrator=opts.integrator)


def _with_u(defects: list, unc) -> list:
    """The defects with the expanded uncertainties (k = 2) of their figures."""
    stated = {d["id"]: d["uncertainty_k2"] for d in unc.defects}
    return [{**d, "uncertainty_k2": stated.get(d["id"])} for d in defects]


def _measure_pipeline(paths: list, mask_path, rig: Rig, options: dict, keep_arrays: bool) -> _Measured:
    """One part through :func:`photometric.pipeline.reconstruct` (the uncertainty, a surface, the arrays)."""
    from photometric.pipeline import reconstruct

    if not keep_arrays:
        # The surface model and mesh are only written with the arrays: a coarse Coons grid is enough.
        # The adaptive least-squares fit refines to its tolerance whatever the start step (over 3 min
        # on a 5 MP part) and nothing of it reaches result.json.
        options = {"surface": "coons", "step": max(2, -(-max(rig.image_size) // 8)), "samples": 1, **options}
    res = reconstruct([str(p) for p in paths], rig=rig, mask=None if mask_path is None else str(mask_path),
                      **options)
    s = res.summary
    defects = res.defects if res.uncertainty is None else _with_u(res.defects, res.uncertainty)
    summary = {k: s.get(k) for k in _SUMMARY_KEYS}
    summary["flat_field"] = s.get("flat_field") is not None
    unc = res.uncertainty
    return _Measured(res.albedo, res.mask, res.valid, defects, float(s["pixel_size_mm"]), summary, res,
                     height=res.height, labels=_labels_of(res, rig),
                     slope_u=None if unc is None else (unc.p_u, unc.q_u), integrator=str(s.get("integrator", "dct")))


def _labels_of(res, rig: Rig) -> np.ndarray | None:
    """The defects' label image of a pipeline result, for the overlay's outlines (the same segmentation again:
    the pipeline keeps only the records); None when it does not give the same defects."""
    from photometric.defects import measure_defects

    h = float(res.summary["pixel_size_mm"])
    found, labels = measure_defects(res.height, h, res.valid, background=res.background, p=res.p, q=res.q,
                                    xy=None if rig.camera.model == "orthographic" else res.xy, return_labels=True)
    return labels if [d["id"] for d in found] == [d["id"] for d in res.defects] else None


def _frames(paths: list, mask_path, rig: Rig):
    """Check the part's frames (:func:`photometric.frames.read_frames`); raise naming every bad one."""
    from photometric.frames import read_frames
    from photometric.io import read_mask

    mask = None if mask_path is None else read_mask(mask_path)
    frames = read_frames(paths, expected_shape=rig.image_size, mask=mask)
    if not frames.ok:
        raise InputError(f"part {Path(paths[0]).parent.name} not measured: {'; '.join(frames.reasons)}")
    return frames


def _rig_position_u(options: dict, rig: Rig) -> tuple[dict, str | None]:
    """The uncertainty options with the rig's LED position u when the user gave none (issue 33: the
    calibration's own u, :func:`photometric.rig.position_u_mm`, instead of 0); the source said."""
    from photometric.rig import position_u_mm

    unc = options.get("uncertainty")
    if not isinstance(unc, dict):
        return options, None
    if {"light_position_tolerance_mm", "light_position_u_mm"} & set(unc):
        return options, "option"
    u = position_u_mm(rig)
    if u is None:
        return options, None
    return {**options, "uncertainty": {**unc, "light_position_tolerance_mm": u}}, "rig"


def _texture(m: _Measured, spec: Spec) -> tuple:
    """The part's areal texture (:func:`workbench.runs.texture.measure_texture`) with the spec's filters:
    ``(Texture, texture.json document)``, or ``(None, None)`` when the spec asks for none."""
    if spec.texture is None:
        return None, None
    from workbench.runs.texture import measure_texture

    noise = {} if m.slope_u is None else {"slope_u": m.slope_u}
    return measure_texture(m.height, m.pixel_size_mm, m.valid & np.isfinite(m.height), noise=noise,
                           integrator=m.integrator, **spec.texture,
                           no_uncertainty_reason="the part was measured without an uncertainty option")


def _texture_record(doc: dict, checks: list) -> dict:
    """result.json's ``texture``: standard, filters, form, band, every parameter (value, U, unit) and the checks."""
    from workbench.runs.texture import judged_value

    params = {}
    for name, rec in doc["parameters"].items():
        value, U = judged_value(rec)
        params[name] = {"value": value, "U": U, "unit": rec["unit"], "as_measured": rec["value"]}
    return {"standard": doc["standard"], "form": doc["form"], "filters": doc["filters"], "band": doc["band"],
            "evaluation_area_px": doc["evaluation_area_px"], "uncertainty": doc["uncertainty"],
            "parameters": params, "checks": checks,
            "note": "value: the noise-bias corrected value with its U (k = 2) when the texture has an uncertainty, "
                    "else the value as measured (as_measured); every figure of texture.json"}


def _texture_figures(record: dict | None, checks: list) -> dict:
    """The texture's results.csv figures: Sa, Sq, Sz (um) with U, and the texture checks' verdict."""
    from workbench.batch.results import TEXTURE_COLUMNS
    from workbench.inspect.decide import VERDICTS

    if record is None:
        return {}
    out: dict = {}
    if checks:
        out["texture_verdict"] = max((c["verdict"] for c in checks), key=VERDICTS.index)
    for name in TEXTURE_COLUMNS:
        rec = record["parameters"][name]
        if rec["value"] is not None:
            out[f"{name}_um"] = float(rec["value"])
            if rec["U"] is not None:
                out[f"{name}_U_um"] = float(rec["U"])
    return out


#: the quality figure a part's own texture makes large: its background flatness (the flatness limit
#: assumes a smooth part; a spec that measures the texture states that the part is not smooth)
TEXTURE_EXEMPT = ("background_rms_mm",)


def _quality_gate(report: dict | None, part: str, texture: bool = False) -> None:
    """Refuse a measurement that fails a quality limit (:func:`photometric.stages.quality`): the part is
    ``not_measured`` with the reasons (it never passes on a result that cannot be trusted). With
    ``texture`` (the spec measures the part's texture) the background flatness is not a limit: the
    texture itself is in it; it is recorded in ``report["not_applied"]`` with the reason."""
    if report is None:
        raise InputError(f"part {part} not measured: its quality figures could not be computed")
    failed = report["failed"]
    if texture:
        exempt = [f for f in failed if f.get("figure") in TEXTURE_EXEMPT]
        failed = [f for f in failed if f.get("figure") not in TEXTURE_EXEMPT]
        if exempt:
            report["not_applied"] = [{**f, "why": "the spec measures the part's texture, which the background "
                                      "flatness holds"} for f in exempt]
            report["failed"], report["trusted"] = failed, not failed
    if not report["trusted"]:
        reasons = "; ".join(f["reason"] for f in failed)
        raise InputError(f"part {part} not measured: the measurement fails its quality limits "
                         f"({report['limits_source']} limits): {reasons}")


def _quality_figures(report: dict) -> dict:
    """The quality figures of a results.csv row (:data:`workbench.batch.FIGURES` ``inspect``)."""
    fig = report["figures"]
    bias = fig.get("slope_bias_mrad")
    return {"background_rms_mm": fig.get("background_rms_mm"),
            "slope_bias_mrad": None if bias is None else bias[2]}


def _summary_figures(decision) -> dict:
    """The part's key figures (the results.csv row of :data:`workbench.batch.FIGURES` ``inspect``)."""
    counted = [r for r in decision.imperfections if r["region"] == "inspected"]
    deepest = max(counted, key=lambda r: r["values"]["max_depth_mm"]["value"], default=None)
    return {
        "verdict": decision.verdict,
        "n_imperfections": len(counted),
        "n_fail": sum(r["verdict"] == "fail" for r in counted),
        "n_uncertain": sum(r["verdict"] == "uncertain" for r in counted),
        "max_depth_mm": deepest["values"]["max_depth_mm"]["value"] if deepest else 0.0,
        "max_depth_U_mm": deepest["values"]["max_depth_mm"]["U"] if deepest else None,
        "total_area_mm2": float(sum(r["values"]["area_mm2"]["value"] for r in counted)),
    }


def inspect_part(folder, out_dir, rig, spec, *, keep_arrays: bool = False, part_id: str | None = None,
                 threads: int | None = None, **options) -> dict:
    """Inspect one part and write ``result.json`` and ``overlay.png`` into ``out_dir``.

    Parameters
    ----------
    folder : str or Path
        The part folder (:func:`part_images`; a ``mask.png`` beside the images is used).
    out_dir : str or Path
        Output folder (created when missing).
    rig : str, Path or photometric.rig.Rig
        The calibrated rig (``rig.json``).
    spec : str, Path or Spec
        The acceptance specification (``spec.json``).
    keep_arrays : bool, optional
        Also write the reconstruction's arrays, previews and mesh.
    part_id : str, optional
        Name of the part in ``result.json`` (default: the folder's name).
    threads : int, optional
        Threads of the near-field solve (default: its own, the CPU count up to 4); a batch
        worker sharing the machine with others runs 1.
    **options
        More keyword options of :func:`photometric.pipeline.reconstruct` (checked by
        :func:`check_options`); those of :data:`DIRECT_OPTIONS` keep the inspection's own
        composition of the stages, any other runs the pipeline.

    Returns
    -------
    dict
        The part's key figures (``verdict``, ``n_imperfections``, ``n_fail``,
        ``n_uncertain``, ``max_depth_mm``, ``max_depth_U_mm``, ``total_area_mm2``,
        ``invalid_fraction``, the quality figures ``background_rms_mm`` and ``slope_bias_mrad``)
        and ``timings_s`` (wall seconds of ``reconstruct`` (the
        measurement), ``decide``, ``overlay``, ``arrays`` (with ``keep_arrays``), the
        measurement's ``stages``, ``total``, and ``cpu``: the process's CPU seconds over the part).

    Raises
    ------
    FileNotFoundError, ValueError
        A missing or extra image, an image of another size than the rig's, a spec the
        measurement cannot decide (``guard_band`` without U), a measurement that fails a
        quality limit (:func:`photometric.stages.quality`; limits from ``rig.json`` or the
        stated defaults), ...: nothing is written and the part is ``not_measured``.
    """
    t_all, cpu_all = time.perf_counter(), time.process_time()
    check_options(options)
    rig_obj = load_rig(rig)
    options, u_source = _rig_position_u(options, rig_obj)
    spec_obj = _spec(spec)
    root = Path(folder)
    paths = part_images(root, len(rig_obj.lights))
    mask = root / "mask.png"
    mask = mask if mask.is_file() else None
    frames = _frames(paths, mask, rig_obj)  # a dark, saturated, wrong-size or mixed-depth frame: not measured
    t0 = time.perf_counter()
    if keep_arrays or set(options) - set(DIRECT_OPTIONS):
        m = _measure_pipeline(paths, mask, rig_obj, options, keep_arrays)
    else:
        m = _measure_direct(paths, mask, rig_obj, options, threads)
    t_measure = time.perf_counter() - t0
    if u_source is not None and isinstance(m.summary.get("uncertainty"), dict):
        m.summary["uncertainty"] = {**m.summary["uncertainty"], "light_position_u_source": u_source}
    # a measurement out of its limits: not measured
    _quality_gate(m.summary.get("quality"), part_id or root.name, texture=spec_obj.texture is not None)
    pixel = m.pixel_size_mm
    t0 = time.perf_counter()
    tex, tex_doc = _texture(m, spec_obj)
    t_texture = time.perf_counter() - t0
    t0 = time.perf_counter()
    decision = judge(m.defects, spec_obj, m.valid.shape, pixel, texture=tex_doc)
    t_decide = time.perf_counter() - t0

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    write_png(out / "overlay.png", overlay_image(m.albedo, m.mask, decision, spec_obj, pixel, height=m.height,
                                                 labels=m.labels))
    t_overlay = time.perf_counter() - t0
    files = ["overlay.png", "result.json"]
    texture_record = None
    if tex is not None:
        from workbench.runs.texture import write_texture

        files += write_texture(tex, tex_doc, out)
        texture_record = _texture_record(tex_doc, decision.texture_checks)
    t0 = time.perf_counter()
    if keep_arrays:
        from workbench.runs.photometric import write_result

        files += write_result(m.result, out)["files"]
    t_arrays = time.perf_counter() - t0
    figures = _summary_figures(decision)
    s = m.summary
    figures["invalid_fraction"] = s["invalid_fraction"]
    figures.update(_texture_figures(texture_record, decision.texture_checks))
    figures.update(_quality_figures(s["quality"]))
    timings = {"reconstruct": round(t_measure, 4), "decide": round(t_decide, 4), "overlay": round(t_overlay, 4)}
    if tex is not None:
        timings["texture"] = round(t_texture, 4)
    if keep_arrays:
        timings["arrays"] = round(t_arrays, 4)
    timings["stages"] = s["timings_s"]
    result = {
        "format": RESULT_FORMAT,
        "version": 1,
        "part": part_id or root.name,
        "input": [str(p) for p in paths],
        "verdict": decision.verdict,
        "decision_rule": decision.rule,
        "decided_by": decision.decided_by,
        "units": "mm",
        "coverage_factor": 2,
        "imperfections": decision.imperfections,
        "part_checks": decision.part_checks,
        "overlay_text": overlay_text(decision),
        **({"texture": texture_record} if texture_record is not None else {}),
        **{k: v for k, v in figures.items() if k != "verdict"},
        "spec": spec_obj.to_dict(),
        "spec_sha256": spec_obj.sha256,
        "frames": frames.to_dict()["frames"],
        "quality": s["quality"],
        "measurement": {
            "pixel_size_mm": pixel,
            "light_model": s.get("light_model"),
            "camera": s.get("camera"),
            "converged": s.get("converged"),
            "iterations": s.get("iterations"),
            "flat_field": s.get("flat_field"),
            "n_defects": s.get("n_defects"),
            "invalid_fraction": s.get("invalid_fraction"),
            "image_size": [s["size"]["height"], s["size"]["width"]],
            "uncertainty": s.get("uncertainty"),
            "quality_trusted": s["quality"]["trusted"],
            "reflectance": s.get("reflectance"),
        },
        "files": sorted(set(files)),
    }
    timings["total"] = round(time.perf_counter() - t_all, 4)
    # CPU of this process (all its threads) while the part ran: on a shared machine wall time is not the cost
    timings["cpu"] = round(time.process_time() - cpu_all, 4)
    result["timings_s"] = timings
    write_json(out / "result.json", result)
    return {**figures, "timings_s": timings}


def reference_quality(folder, rig, **options) -> dict:
    """Measure a reference part on the rig and set the quality limits from it (``rig.json`` ``quality``).

    The part (a clean part of the kind to be inspected, :func:`part_images`' layout) is
    measured as :func:`inspect_part` measures (the library's stages), judged against the
    stated :class:`photometric.quality.QualityLimits` defaults (a reference that fails them
    cannot vouch for anything: refused), and its figures widened into limits by
    :func:`photometric.quality.reference_limits`; its mean background slopes become the
    reference of the slope bias.

    Parameters
    ----------
    folder : str or Path
        The reference part folder.
    rig : str, Path or photometric.rig.Rig
        The calibrated rig (its own ``quality`` entry is ignored).
    **options
        Reconstruction options of :data:`DIRECT_OPTIONS` (``background``, ``outliers``, ...).

    Returns
    -------
    dict
        The ``quality`` entry of ``rig.json``: ``limits``, ``reference_slopes`` ``[p, q]``,
        ``reference_part``, ``reference_figures``, ``rule``.

    Raises
    ------
    FileNotFoundError, ValueError
        A missing folder, bad frames, an option outside :data:`DIRECT_OPTIONS`, or a
        reference whose measurement fails the stated limits (the reasons named).
    """
    from dataclasses import replace

    from photometric import stages
    from photometric.options import photometric_options
    from photometric.quality import REFERENCE_FACTOR, QualityFigures, QualityLimits, reference_limits

    other = sorted(set(options) - set(DIRECT_OPTIONS) - {"uncertainty"})
    if other:
        raise InputError(f"--reference-part: option {other[0]} is not one the inspection's measurement takes")
    check_options(options)
    rig_obj = replace(load_rig(rig), quality=None)
    root = Path(folder)
    paths = part_images(root, len(rig_obj.lights))
    mask = root / "mask.png"
    mask = mask if mask.is_file() else None
    _frames(paths, mask, rig_obj)
    opts = photometric_options(**{k: v for k, v in options.items() if k != "uncertainty"})
    inp = stages.read([str(p) for p in paths], opts, rig=rig_obj, mask=None if mask is None else str(mask))
    sol = stages.solve(inp, opts, residual=False)
    height = stages.integrate(inp, sol, opts)
    found = stages.measure(inp, sol, height, opts, labels=False)
    report = stages.quality(inp, sol, height, found, opts, limits=QualityLimits())
    if not report["trusted"]:
        raise InputError(f"--reference-part {root}: its own measurement fails the stated quality limits, so it "
                         f"cannot set them: {'; '.join(f['reason'] for f in report['failed'])}")
    fig = report["figures"]

    def num(v):
        return float("nan") if v is None else float(v)

    figures = QualityFigures(num(fig["background_rms_mm"]), fig["background_model"],
                             tuple(num(v) for v in fig["lambertian_residual"]), None, num(fig["invalid_fraction"]))
    limits = reference_limits(figures)
    return {"limits": limits.as_dict(), "reference_slopes": report["mean_slopes"], "reference_part": str(root),
            "reference_figures": fig, "background": opts.background,
            "rule": f"{REFERENCE_FACTOR:g} x the reference's figures, within the stated defaults and floors "
                    "(photometric.quality.reference_limits)"}


def reference_reflectance(folder, rig, alpha: float) -> dict:
    """The glossy reflectance of a material, measured on a level reference part (``rig.json`` ``reflectance``).

    The reference is a flat part of the material lying level on the reference plane
    (``z = 0``, normals ``(0, 0, 1)``): :func:`photometric.glossy.lobe_weight` of its
    images with the solver's own light vectors there (flat-field strengths included,
    :func:`photometric.stages.glossy_light_vectors`).

    Parameters
    ----------
    folder : str or Path
        The reference part folder.
    rig : str, Path or photometric.rig.Rig
    alpha : float
        GGX roughness of the material (0 < alpha <= 1), from its datasheet or a fit.

    Returns
    -------
    dict
        ``{"model": "glossy", "alpha": alpha, "weight": c, "reference_part": folder}``.

    Raises
    ------
    ValueError
        Fewer than 4 lights, a perspective camera, or no pixel to measure ``c`` on.
    """
    from dataclasses import replace

    from photometric import stages
    from photometric.camera import plane_points
    from photometric.glossy import lobe_weight
    from photometric.options import photometric_options

    opts = photometric_options(gloss_alpha=alpha)
    rig_obj = replace(load_rig(rig), quality=None, reflectance=None)
    if rig_obj.camera.model != "orthographic" or len(rig_obj.lights) < 4:
        raise InputError("--reflectance glossy: the glossy model needs an orthographic camera and 4 or more LEDs")
    root = Path(folder)
    paths = part_images(root, len(rig_obj.lights))
    mask = root / "mask.png"
    mask = mask if mask.is_file() else None
    _frames(paths, mask, rig_obj)
    inp = stages.read([str(p) for p in paths], opts, rig=rig_obj, mask=None if mask is None else str(mask))
    shape = inp.data.images.shape[1:3]
    grey, S = stages.glossy_light_vectors(inp.data, inp.setup, plane_points(rig_obj.camera, shape))
    normals = np.zeros(shape + (3,))
    normals[..., 2] = 1.0
    c = lobe_weight(grey, S, normals, (0.0, 0.0, 1.0), opts.gloss_alpha, inp.data.mask)
    if not np.isfinite(c) or c < 0:
        raise InputError(f"--reference-part {root}: no lobe weight could be measured on it (got {c})")
    return {"model": "glossy", "alpha": float(opts.gloss_alpha), "weight": float(c), "reference_part": str(root)}
