"""The files of the light-deviation accuracy study: ``report.json``, ``report.md`` and the plots."""

from __future__ import annotations

from pathlib import Path

from surfaces.io import atomic_write_text, write_json
from workbench.studies.errors_markdown import markdown
from workbench.studies.errors_plots import write_plots
from surfaces.validate import InputError

__all__ = ["write_report"]


def write_report(report: dict, out_dir) -> dict:
    """Write ``report.json``, ``report.md`` and the PNG plots of an accuracy study.

    Parameters
    ----------
    report : dict
        The result of :func:`workbench.studies.errors_analysis.analyse`.
    out_dir : str or Path
        Output folder (created when missing).

    Returns
    -------
    dict
        File names written, keyed ``json``, ``markdown``, ``plots`` (list); ``report.json``
        holds every number of ``report`` (not its ``"_arrays"``) and the ``plots`` list.
    """
    if "_arrays" not in report or "inputs" not in report:
        raise InputError("report: expected the dict returned by workbench.studies.errors_analysis.analyse")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {out} is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    pictures = write_plots(report, out)
    public = {k: v for k, v in report.items() if k != "_arrays"}
    public["plots"] = [p for v in pictures.values() for p in (v if isinstance(v, list) else [v])]
    write_json(out / "report.json", public, indent=1)
    atomic_write_text(out / "report.md", markdown(report, pictures))
    return {"json": "report.json", "markdown": "report.md", "plots": public["plots"]}
