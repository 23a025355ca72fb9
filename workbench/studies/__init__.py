"""Studies that compose scenes, rendering, solving and measuring, and the files they write.

``errors_analysis`` (the light-deviation accuracy study as numbers), ``errors_plots``
(its figures), ``errors_markdown`` (its text), ``errors_report`` (its files) and
``crack`` (seed 002(a)'s rendered crack test). They sit in ``workbench`` because they
use ``datasets_synthetic`` and matplotlib, which the library packages never import.
"""
