"""The demo's driver: runs every section into one report and writes ``report.html`` and ``demo.json``."""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

from tqdm import tqdm

from surfaces.io import write_json
from workbench.demo.accuracy import section_accuracy
from workbench.demo.breast import section_breast
from workbench.demo.context import Context, shared_data_dir
from workbench.demo.ct import section_ct
from workbench.demo.inspection import section_inspection
from workbench.demo.real import section_real
from workbench.report import Report

SECTIONS = (section_inspection, section_accuracy, section_real, section_ct, section_breast)
STEPS = 13  # ctx.step calls in a full run (one fewer with --quick: no Lt Lung)

INTRO = (
    "Everything on this page was computed by one run of the demo on the machine named below "
    "(no precomputed results): synthetic scenes with exact ground truth, the shared real data "
    "(DiLiGenT bear, a breast RT structure set) when present, the photometric-stereo and CT "
    "pipelines, and the one Bezier surface model both converge on. Pictures are ray-cast "
    "headless with open3d's RaycastingScene. Every command below runs from this report's folder "
    "(paths are relative to it; \"$WORKBENCH_SHARED_DATA\" is the real-data folder, ../shared/data beside "
    "the repository by default), and `workbench demo --figures-only .` redraws every figure from the data "
    "saved beside it in figures/ (figures/<name>.json and .npz)."
)


def finish_report(ctx: Context, seconds: float) -> Path:
    """Add the figure index (and the sections that could not run) and write ``report.html``.

    Parameters
    ----------
    ctx : Context
        The run, after its sections.
    seconds : float
        Run time so far, shown under the title.

    Returns
    -------
    pathlib.Path
        The HTML file.
    """
    report = ctx.report
    report.section("5. Figures and the commands that reproduce them",
                   "Each figure's data comes from the command shown; the pictures themselves are "
                   "drawn by the demo from the data saved in figures/ (workbench demo --figures-only "
                   "redraws them).")
    report.table(["figure", "file", "what it shows", "command"],
                 [[f, file, cap, f"`{cmd}`"] for f, file, cap, cmd in report.figure_index()])
    if ctx.unavailable:
        report.table(["section", "reason"], [[k, v] for k, v in ctx.unavailable.items()],
                     caption="Sections that could not run.")
    meta = (f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {platform.node()}, "
            f"{os.cpu_count()} CPU(s), Python {platform.python_version()}; "
            f"{'quick' if ctx.quick else 'full'} run, {seconds:.0f} s")
    return report.write("report.html", meta=meta)


def run_demo(out_dir: str | os.PathLike = "demo_out", quick: bool = False,
             shared: str | os.PathLike | None = None, progress: bool = False) -> dict:
    """Run every demo section and write ``report.html``, ``demo.json`` and the figures.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created).
    quick : bool
        Reduced sizes (the CI smoke test): 128-pixel plate, coarser grids, Heart only.
    shared : path-like, optional
        Real-data folder; :func:`~workbench.demo.context.shared_data_dir` when omitted.
    progress : bool
        Show a tqdm progress bar (command line).

    Returns
    -------
    dict
        The ``demo.json`` content: ``report``, ``seconds``, ``quick``, ``shared_data``,
        ``unavailable`` (section -> reason, when real data is absent), ``figures``
        (file, caption, command) and every number under its section name.
    """
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    report = Report("Surface-reconstruction workbench: demo report", out)
    ctx = Context(out=out, quick=bool(quick),
                  shared=Path(shared) if shared is not None else shared_data_dir(), report=report)
    report.paragraph(INTRO)
    with tqdm(total=STEPS - int(bool(quick)), desc="demo", unit="step", disable=not progress) as bar:
        ctx.bar = bar
        for section in SECTIONS:
            section(ctx)
        bar.update(max(0, bar.total - bar.n))
    path = finish_report(ctx, time.perf_counter() - t0)
    summary = {
        "report": str(path),
        "seconds": time.perf_counter() - t0,
        "quick": bool(quick),
        "shared_data": str(ctx.shared),
        "unavailable": ctx.unavailable,
        "figures": [{"file": f.file, "caption": f.caption, "command": f.command}
                    for f in report.figures],
        **ctx.numbers,
    }
    write_json(out / "demo.json", summary)
    return summary
