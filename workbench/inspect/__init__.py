"""Inspection runs (``workbench inspect``): calibrate a rig once, measure part after part, decide.

Modules: :mod:`~workbench.inspect.spec` (``spec.json``: limits in mm, region of interest,
exclusion zones, decision rule; checked before any work), :mod:`~workbench.inspect.decide`
(``simple`` and ISO 14253-1 ``guard_band`` verdicts per imperfection and per part),
:mod:`~workbench.inspect.overlay` (``overlay.png``), :mod:`~workbench.inspect.part` (one
part: images -> near-field reconstruction with the rig -> imperfections -> verdict ->
``result.json`` + ``overlay.png``), :mod:`~workbench.inspect.run` (many parts through
:mod:`workbench.batch`), :mod:`~workbench.inspect.watch` (an inbox poller) and
:mod:`~workbench.inspect.report` (``report.html``).
"""
