"""Command line, end-to-end demo, reports and batch runs of the surface-reconstruction workbench.

What users call from Python: :func:`main` (the ``workbench`` console script)
and :func:`build_parser`; :class:`Report` (the self-contained HTML report);
the batch API (:func:`load_jobs`, :func:`plan`, :func:`run_batch`,
:func:`write_report`, :class:`Job`). Importing :mod:`workbench` stays light:
dask, open3d and matplotlib are imported only where they are used.
"""

from workbench.batch import BatchReport, Job, Plan, load_jobs, plan, run_batch, write_report
from workbench.cli import build_parser, main
from workbench.report import Report
from surfaces.validate import InputError  # bad input; the same class in every package

__all__ = [
    "BatchReport",
    "InputError",
    "Job",
    "Plan",
    "Report",
    "build_parser",
    "load_jobs",
    "main",
    "plan",
    "run_batch",
    "write_report",
]


def __getattr__(name: str):
    if name == "__version__":  # the distribution's version, read on first use (one home: surfaces)
        import surfaces

        return surfaces.__version__
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
