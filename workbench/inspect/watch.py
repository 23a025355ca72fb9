"""Inspect part folders as they arrive in an inbox (``workbench inspect watch``).

Each poll lists the inbox's part folders (:func:`workbench.inspect.run.load_parts`). A part
is *ready* when it holds at least one image per light of the rig and its images (names,
sizes, modification times) have not changed for ``settle`` seconds: a camera still
writing its last image keeps the part waiting. Ready parts go through the batch driver
(:func:`workbench.inspect.run.run_inspection`), which skips parts finished or failed
before, so every part is inspected once, and a restarted watch goes on from the state
in ``OUT`` (no state of its own).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from workbench.batch import connect, plan
from workbench.inspect.part import IMAGE_SUFFIXES, check_options, load_rig
from workbench.inspect.run import InspectionRun, load_parts, make_jobs, run_inspection
from workbench.inspect.spec import load_spec
from surfaces.validate import InputError

__all__ = ["folder_signature", "ready_parts", "watch"]


def folder_signature(folder) -> tuple:
    """What changes while a part is being written: its image files' names, sizes and modification times.

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    tuple
        ``((name, size, mtime_ns), ...)`` of its image files, sorted by name.
    """
    entries = []
    for p in sorted(Path(folder).iterdir()):
        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES:
            st = p.stat()
            entries.append((p.name, st.st_size, st.st_mtime_ns))
    return tuple(entries)


def ready_parts(inbox, n_lights: int, seen: dict, settle: float, now: float | None = None) -> list:
    """The parts of an inbox whose images are complete and have settled.

    Parameters
    ----------
    inbox : str or Path
    n_lights : int
        Images a part needs at least (one per light of the rig).
    seen : dict
        Part id -> ``(signature, first time seen unchanged)``; updated in place between polls.
    settle : float
        Seconds a part's images must stay unchanged.
    now : float, optional
        The poll's time (:func:`time.monotonic`).

    Returns
    -------
    list of (str, Path)
        Ready parts, as :func:`workbench.inspect.run.load_parts` gives them.
    """
    now = time.monotonic() if now is None else now
    try:
        parts = load_parts(inbox)
    except ValueError:  # nothing has arrived yet
        return []
    ready = []
    for pid, folder in parts:
        sig = folder_signature(folder)
        old = seen.get(pid)
        if old is None or old[0] != sig:
            seen[pid] = (sig, now)
            continue
        if len(sig) >= n_lights and now - old[1] >= settle:
            ready.append((pid, folder))
    return ready


def watch(inbox, rig, spec, out, *, keep_arrays: bool = False, options: dict | None = None, client: Any = None,
          scheduler: str = "local", workers: int | None = None, interval: float = 2.0, settle: float = 2.0,
          timeout: float | None = None, on_run: Callable[[InspectionRun], None] | None = None,
          progress: Callable[[dict], None] | None = None, command: str = "workbench inspect watch") -> dict:
    """Poll an inbox and inspect each part once, until ``timeout`` (or forever).

    Parameters
    ----------
    inbox : str or Path
        The folder part folders arrive in.
    rig, spec : str or Path
        ``rig.json`` and ``spec.json`` (checked before the first poll).
    out : str or Path
        Output folder (as :func:`workbench.inspect.run.run_inspection`).
    keep_arrays, options
        As :func:`workbench.inspect.run.run_inspection`.
    client : distributed.Client, optional
        Use this client; else one is opened (``scheduler``, ``workers``) for the whole watch.
    interval : float
        Seconds between polls.
    settle : float
        Seconds a part's images must stay unchanged before it counts.
    timeout : float, optional
        Stop after this many seconds (at least one poll happens).
    on_run : callable, optional
        Called with the :class:`~workbench.inspect.run.InspectionRun` of each poll that ran parts.
    progress : callable, optional
        Called with each finished part's results.csv row.
    command : str
        The command line, for the report.

    Returns
    -------
    dict
        ``polls``, ``ran``, ``ok``, ``failed`` over the whole watch.
    """
    src = Path(inbox)
    if not src.is_dir():
        raise NotADirectoryError(f"INBOX: {src} is not a folder")
    if interval <= 0 or settle < 0 or (timeout is not None and timeout < 0):
        raise InputError("--interval must be positive, --settle and --timeout not negative")
    load_spec(spec)
    n_lights = len(load_rig(rig).lights)
    opts = check_options(dict(options or {}))
    totals = {"polls": 0, "ran": 0, "ok": 0, "failed": 0}
    seen: dict = {}
    start = time.monotonic()

    def loop(cl) -> None:
        while True:
            totals["polls"] += 1
            ready = ready_parts(src, n_lights, seen, settle)
            todo = plan(make_jobs(ready, rig, spec), Path(out).resolve()).to_run if ready else ()
            if todo:
                chosen = [(job.id, Path(job.input)) for job in todo]
                run = run_inspection(chosen, rig, spec, out, keep_arrays=keep_arrays, options=opts, client=cl,
                                     progress=progress, command=command)
                for key in ("ran", "ok", "failed"):
                    totals[key] += getattr(run.batch, key)
                if on_run is not None:
                    on_run(run)
            if timeout is not None and time.monotonic() - start + interval > timeout:
                return
            time.sleep(interval)

    if client is not None:
        loop(client)
    else:
        with connect(scheduler, workers) as own:
            loop(own)
    return totals
