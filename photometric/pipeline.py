"""Photometric stereo end to end: images and lights in, a measured surface out (no files).

:func:`reconstruct` composes the stages of :mod:`photometric.stages` (read, solve,
integrate, surface, measure and, when asked, uncertainty) with one
:class:`photometric.options.PhotometricOptions` and returns everything as one
:class:`PhotometricReconstruction`; it writes nothing. The command line, the demo and batch
jobs write the result files with ``workbench.runs.photometric.reconstruct_to_folder``.
Ground truth other than the folder's normals (``height_gt.npy``, ``xy_gt.npy`` of
synthetic scenes) is compared outside the library (:mod:`datasets_synthetic.truth`).
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np

from photometric import stages
from photometric.options import LIGHT_MODELS, READ_KEYWORDS, SURFACES, PhotometricOptions, split_keywords
from photometric.stages import TARGET_PATCHES
from photometric.uncertainty import UncertaintyResult
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh

__all__ = ["SURFACES", "TARGET_PATCHES", "LIGHT_MODELS", "PhotometricReconstruction", "reconstruct"]


@dataclass(frozen=True)
class PhotometricReconstruction:
    """Everything :func:`reconstruct` computes.

    Attributes
    ----------
    normals : numpy.ndarray or None, shape (H, W, 3), float32
        Unit normals (:attr:`photometric.stereo.StereoResult.normals`); None when
        :func:`reconstruct` passed them to its ``out`` arrays.
    albedo : numpy.ndarray or None, shape (H, W) or (H, W, 3), float32
        Albedo; None like ``normals``.
    p, q : numpy.ndarray, shape (H, W), float32
        Slopes ``dz/dx``, ``dz/dy`` (y up); zero where not valid.
    valid : numpy.ndarray, shape (H, W), bool
        Pixels with a trustworthy normal.
    mask : numpy.ndarray, shape (H, W), bool
        The object mask of the input.
    height : numpy.ndarray, shape (H, W), float32 (far field) or float64 (near field)
        Height in mm (NaN outside the valid pixels); near-field: ``z`` of the point each
        pixel sees, in the rig frame.
    patches : surfaces.bezier.BezierPatches
        The bicubic surface: patches of mixed sizes fitted to the height and slopes
        (:class:`surfaces.mixed.MixedPatches` from :func:`surfaces.fit.fit_height`,
        ``surface="fit"``) or the Coons grid through the height
        (:func:`photometric.integrate.height_to_patches`, ``surface="coons"``).
    mesh : surfaces.mesh.TriangleMesh
        The tessellated surface, trimmed to the fitted pixels along their sub-pixel outline
        (fit) or to the mask by triangle centroids (coons); coordinates in mm on the
        centred pixel grid of :data:`surfaces.grid.GRID_CONVENTION`.
    defects : list of dict
        Defect measures (:func:`photometric.defects.measure_defects`).
    background : str
        Background removed before measuring the defects.
    summary : dict
        Input, sizes, options, ``light_model`` ("directional" or "point") and ``camera``,
        light condition number, invalid fraction, timings (s) of the stages ``read``,
        ``solve``, ``integrate``, ``surface``, ``defects``, mesh size, the surface method
        with ``surface_tolerance_mm`` and ``surface_patch_sizes_px`` (fit),
        ``surface_max_dev_mm`` and ``surface_rms_dev_mm`` (largest and RMS
        ``|surface - height|`` over the fitted (fit) or valid (coons) pixels), ``n_patches``
        and ``patches`` (the patch grid's shape; ``[n_patches, 1]`` for the fit's flat list
        of patches), number of defects and, with the folder's ``normal_gt``,
        ``mean_angular_error_deg`` and ``median_angular_error_deg`` (over the mask).
        Near-field and perspective solves add ``light_positions_mm``, ``led_mu``,
        ``flat_field``, ``iterations``, ``final_depth_change_mm``, ``converged``,
        ``tolerance_mm``, ``anchor`` and ``iteration_history``. JSON-ready
        (:func:`photometric.stages.summarize`).
    xy : numpy.ndarray or None, shape (H, W, 2), float64
        ``x, y`` (mm) of the point each pixel sees (near-field and perspective solves;
        None on the far-field orthographic path, whose points are the pixel grid).
    uncertainty : photometric.uncertainty.UncertaintyResult or None
        Per-pixel ``p_u``, ``q_u``, ``height_u`` and the defects' budgets, when
        ``uncertainty`` was given.
    """

    normals: np.ndarray | None
    albedo: np.ndarray | None
    p: np.ndarray
    q: np.ndarray
    valid: np.ndarray
    mask: np.ndarray
    height: np.ndarray
    patches: BezierPatches
    mesh: TriangleMesh
    defects: list
    background: str
    summary: dict
    xy: np.ndarray | None = None
    uncertainty: UncertaintyResult | None = None




def reconstruct(source, options: PhotometricOptions | None = None, *, progress: Callable[[str], None] | None = None,
                out: Callable[[str, tuple[int, ...], np.dtype], object] | None = None,
                **keywords) -> PhotometricReconstruction:
    """Run photometric stereo end to end and return every result (writes nothing).

    Parameters
    ----------
    source : str, Path, sequence of paths, array_like or PhotometricData
        A DiLiGenT-style folder, image files or an ``(N, H, W[, 3])`` array (:func:`photometric.stages.read`).
    options : PhotometricOptions, optional
        Base options (the defaults when omitted); keywords override its fields.
    progress : callable, optional
        Called with each stage's name as it starts: ``read``, ``normals``, ``height``,
        ``surface``, ``defects`` and ``uncertainty`` when asked (the command line's progress bar).
    out : callable, optional
        Where the normals and albedo go instead of the result (bounded memory;
        :func:`photometric.stages.solve`); the result's ``normals`` and ``albedo`` are then None.
    **keywords
        The input's (:data:`photometric.options.READ_KEYWORDS`: ``lights``, ``mask``, ``rig``, ...
        of :func:`photometric.stages.read`) and fields of :class:`photometric.options.PhotometricOptions`.

    Returns
    -------
    PhotometricReconstruction
        Arrays, surface, mesh, defects and the summary (:func:`photometric.stages.summarize`).
    """
    read_kw, opts = split_keywords(keywords, options)
    say = progress or (lambda _stage: None)
    t_all = time.perf_counter()
    say("read")
    inp = stages.read(source, opts, **read_kw)
    say("normals")
    sol = stages.solve(inp, opts, out=out)
    inp = replace(inp, data=sol.data)  # a streamed solve has dropped the image stack: let it go
    say("height")
    height = stages.integrate(inp, sol, opts)
    say("surface")
    surf = stages.surface(inp, sol, height, opts)
    say("defects")
    found = stages.measure(inp, sol, height, opts)
    timings = {"read": inp.seconds, "solve": sol.timings_s["solve"], "integrate": height.seconds,
               "surface": surf.seconds, "defects": found.seconds}
    unc = None
    if opts.uncertainty is not None:
        say("uncertainty")
        t0 = time.perf_counter()
        unc = stages.uncertainty(inp, sol, height, found, opts)
        timings["uncertainty"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    summary = stages.summarize(inp, sol, height, found, opts, surf=surf, unc=unc, timings=timings)
    fit, streamed = sol.fit, out is not None
    return PhotometricReconstruction(
        normals=None if streamed else fit.normals, albedo=None if streamed else fit.albedo, p=fit.p, q=fit.q,
        valid=fit.valid, mask=sol.data.mask, height=height.height, patches=surf.patches, mesh=surf.mesh,
        defects=found.defects, background=found.background, summary=summary,
        xy=None if inp.setup is None else fit.xy, uncertainty=unc)


def _signature() -> inspect.Signature:
    """Every keyword by name (batch manifests and ``--option`` checks read them from here)."""
    P = inspect.Parameter
    defaults = PhotometricOptions()
    params = [P("source", P.POSITIONAL_OR_KEYWORD), P("options", P.POSITIONAL_OR_KEYWORD, default=None)]
    params += [P(name, P.KEYWORD_ONLY, default=None) for name in READ_KEYWORDS]
    params += [P(f.name, P.KEYWORD_ONLY, default=getattr(defaults, f.name)) for f in fields(PhotometricOptions)]
    params += [P("progress", P.KEYWORD_ONLY, default=None), P("out", P.KEYWORD_ONLY, default=None)]
    return inspect.Signature(params, return_annotation=PhotometricReconstruction)


reconstruct.__signature__ = _signature()
