"""Inspect part folders as they arrive in an inbox (``workbench inspect watch``).

Each poll lists the inbox's part folders (:func:`workbench.inspect.run.scan_parts`: a folder
that cannot be a part, such as one named ``failed``, two whose ids collide (``a b`` and
``a_b``) or one that cannot be read, is reported once and skipped; the others go on). A part
is *ready* when it holds at least one image per light of the rig and its images (names,
sizes, modification times) have not changed for ``settle`` seconds: a camera still
writing its last image keeps the part waiting. Ready parts go through the batch driver
(:func:`workbench.inspect.run.run_inspection`), which skips parts finished or failed
before, so every part is inspected once, and a restarted watch goes on from the state
in ``OUT`` (no state of its own). A part that failed is measured again when its inputs
change (:func:`workbench.inspect.run.retry_changed`), and with ``retry_failed`` once more
at the start of the watch.

The spec is read once, at the start (its hash goes into every row). Results heal: a part
folder finished by a task whose watch was killed (a running scheduler finishes the task)
gets its results.csv row at the next start and at the end of the watch
(:func:`workbench.batch.heal`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from surfaces.validate import InputError
from workbench.batch import connect, heal, plan, prepare_out
from workbench.inspect.part import IMAGE_SUFFIXES, load_rig
from workbench.inspect.run import (
    InspectionRun,
    check_run_options,
    make_jobs,
    retry_changed,
    run_inspection,
    scan_parts,
)
from workbench.inspect.spec import check_spec_field, load_spec

__all__ = ["check_seconds", "folder_signature", "ready_parts", "watch"]


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


def ready_parts(inbox, n_lights: int, seen: dict, settle: float, now: float | None = None,
                problems: dict | None = None) -> list:
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
    problems : dict, optional
        Filled with ``folder name -> reason`` of the folders skipped
        (:func:`workbench.inspect.run.scan_parts`).

    Returns
    -------
    list of (str, Path)
        Ready parts, as :func:`workbench.inspect.run.load_parts` gives them.
    """
    now = time.monotonic() if now is None else now
    parts, skipped = scan_parts(inbox)
    if problems is not None:
        problems.update(skipped)
    ready = []
    for pid, folder in parts:
        try:
            sig = folder_signature(folder)
        except OSError as exc:  # removed or made unreadable between the listing and now
            if problems is not None:
                problems[folder.name] = f"cannot be read ({exc.strerror or exc})"
            continue
        old = seen.get(pid)
        if old is None or old[0] != sig:
            seen[pid] = (sig, now)
            continue
        if len(sig) >= n_lights and now - old[1] >= settle:
            ready.append((pid, folder))
    return ready


def check_seconds(value, name: str, *, positive: bool = False, optional: bool = False) -> float | None:
    """A duration option in seconds: finite, not negative (``positive``: > 0); None when ``optional``.

    Parameters
    ----------
    value : float or None
    name : str
        The option, for the message (``--timeout``).
    positive : bool, optional
    optional : bool, optional

    Returns
    -------
    float or None

    Examples
    --------
    >>> check_seconds(float("nan"), "--timeout")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: --timeout: expected a finite number of seconds >= 0, got nan
    """
    if value is None and optional:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number of seconds, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        raise InputError(f"{name}: expected a finite number of seconds {'> 0' if positive else '>= 0'}, got {value!r}")
    return v


def watch(inbox, rig, spec, out, *, keep_arrays: bool = False, options: dict | None = None, client: Any = None,
          scheduler: str = "local", workers: int | None = None, interval: float = 2.0, settle: float = 2.0,
          timeout: float | None = None, on_run: Callable[[InspectionRun], None] | None = None,
          progress: Callable[[dict], None] | None = None, command: str = "workbench inspect watch",
          retry_failed: bool = False, on_skip: Callable[[str, str], None] | None = None) -> dict:
    """Poll an inbox and inspect each part once, until ``timeout`` (or forever).

    Parameters
    ----------
    inbox : str or Path
        The folder part folders arrive in.
    rig, spec : str or Path
        ``rig.json`` and ``spec.json`` (checked before the first poll; the spec is read once
        and frozen for the whole watch).
    out : str or Path
        Output folder (as :func:`workbench.inspect.run.run_inspection`).
    keep_arrays, options
        As :func:`workbench.inspect.run.run_inspection`.
    client : distributed.Client, optional
        Use this client; else one is opened (``scheduler``, ``workers``) for the whole watch.
    interval : float
        Seconds between polls (finite, > 0).
    settle : float
        Seconds a part's images must stay unchanged before it counts (finite, >= 0).
    timeout : float, optional
        Stop after this many seconds of watching (finite, >= 0; counted once the cluster is up; at
        least one poll happens).
    on_run : callable, optional
        Called with the :class:`~workbench.inspect.run.InspectionRun` of each poll that ran parts.
    progress : callable, optional
        Called with each finished part's results.csv row.
    command : str
        The command line, for the report.
    retry_failed : bool, optional
        Measure again, once, every part that failed before this watch started (a part whose
        inputs changed since it failed is measured again anyway).
    on_skip : callable, optional
        Called once with ``(folder name, reason)`` of each inbox folder that cannot be a part.

    Returns
    -------
    dict
        ``polls``, ``ran``, ``ok``, ``failed`` over the whole watch, ``healed`` (rows given
        back to finished parts) and ``skipped_folders`` (folder name -> reason).
    """
    src = Path(inbox)
    if not src.is_dir():
        raise NotADirectoryError(f"INBOX: {src} is not a folder")
    interval = check_seconds(interval, "--interval", positive=True)
    settle = check_seconds(settle, "--settle")
    timeout = check_seconds(timeout, "--timeout", optional=True)
    frozen = load_spec(spec)
    rig_obj = load_rig(rig)
    check_spec_field(frozen, rig_obj.image_size, rig_obj.camera.nominal_pixel_mm())
    n_lights = len(rig_obj.lights)
    opts = check_run_options(options, rig_obj)
    out = prepare_out(out)
    totals: dict = {"polls": 0, "ran": 0, "ok": 0, "failed": 0, "healed": 0, "skipped_folders": {}}
    seen: dict = {}
    changed = retry_changed(out)
    retried: set = set()

    def retry(job) -> bool:
        if retry_failed and job.id not in retried:
            retried.add(job.id)
            return True
        return changed(job)

    def heal_all() -> None:
        parts, _ = scan_parts(src)
        if parts:
            totals["healed"] += heal(make_jobs(parts, rig, frozen), out)

    def loop(cl) -> None:
        start = time.monotonic()  # the cluster is up: the timeout counts the watching
        while True:
            totals["polls"] += 1
            problems: dict = {}
            ready = ready_parts(src, n_lights, seen, settle, problems=problems)
            for name, reason in problems.items():
                if totals["skipped_folders"].get(name) != reason:
                    totals["skipped_folders"][name] = reason
                    if on_skip is not None:
                        on_skip(name, reason)
            todo = plan(make_jobs(ready, rig, frozen), out, retry=retry).to_run if ready else ()
            if todo:
                chosen = [(job.id, Path(job.input)) for job in todo]
                run = run_inspection(chosen, rig, frozen, out, keep_arrays=keep_arrays, options=opts, client=cl,
                                     progress=progress, command=command, retry_failed=lambda job: True)
                for key in ("ran", "ok", "failed"):
                    totals[key] += getattr(run.batch, key)
                if on_run is not None:
                    on_run(run)
            if timeout is not None and time.monotonic() - start + interval > timeout:
                return
            time.sleep(interval)

    heal_all()  # parts a killed watch's scheduler finished have their folder, not their row
    if client is not None:
        loop(client)
    else:
        with connect(scheduler, workers) as own:
            loop(own)
    heal_all()
    return totals
