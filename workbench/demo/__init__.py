"""The end-to-end demo: every package on data it makes (or the shared real data), one HTML report.

:func:`run_demo` computes everything in the run (no precomputed results) and
writes ``out_dir/report.html`` (self-contained: figures embedded as data URIs),
the figures as PNG files in ``out_dir/figures/``, every number in
``out_dir/demo.json`` and the intermediate data (triad folder, phantom,
surfaces) in sub-folders. One module per section, each a function of the
shared :class:`~workbench.demo.context.Context`:

1. :mod:`~workbench.demo.inspection`: a synthetic plate with a crack, a dent
   and a scratch, rendered under three lights; photometric stereo, height by
   integration, the Bezier surface through it, and the defects measured
   against their truth.
2. :mod:`~workbench.demo.accuracy`: derivative-error maps against light
   deviations and the recommended deviation tolerances for that light set
   (seed 002a).
3. :mod:`~workbench.demo.real`: DiLiGenT bear (``../shared/data/diligent_bear``),
   triad and all 14 images, normal maps and angular error beside the baseline
   figures.
4. :mod:`~workbench.demo.ct`: a folding kidney phantom reconstructed from
   contours (volume, surface distance); :mod:`~workbench.demo.breast`: the
   breast structure set's Heart and Lt Lung beside their reference volumes.
5. A table of every figure and the command that reproduces it
   (:mod:`~workbench.demo.run`, which also runs the sections in order).

:mod:`~workbench.demo.meshes` holds the geometry only the demo draws (the true
height field, contour lines). Every figure is drawn by a registered drawer from
data saved beside its PNG (:mod:`~workbench.demo.figures`: ``figures/<name>.json``
and ``.npz``), so ``workbench demo --figures-only DIR`` redraws them all; the
report's commands are relative to its folder. A section whose real data is absent is reported
as "not available: <reason>" and listed under ``unavailable`` in the returned
summary; any error propagates.
"""

from workbench.demo.context import Context, shared_data_dir
from workbench.demo.run import run_demo

__all__ = ["Context", "run_demo", "shared_data_dir"]
