"""What a batch job is: its kind and the :class:`Job` record every other batch module passes around."""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from surfaces.validate import InputError

#: the job kinds, one per library pipeline
KINDS: tuple[str, ...] = ("photometric", "slices")
#: what a job id may be: one plain folder name (a letter or digit first, then letters, digits, ``. _ + -``),
#: so ``OUT/<id>`` is always a child of ``OUT`` (no ``.``, ``..``, separators, absolute paths, hidden names)
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,127}$")


@dataclass(frozen=True)
class Job:
    """One batch job: what to reconstruct and with which options.

    Attributes
    ----------
    id : str
        Unique, filesystem-safe name; the job's folder is ``OUT/<id>``.
    kind : str
        ``"photometric"`` or ``"slices"``.
    input : str or tuple of str
        Absolute path of the input (DiLiGenT-style folder, structure set, contour
        file or CT folder), or, for photometric jobs given as images + lights, the
        absolute paths of the images in light order.
    options : dict
        Keyword options for the pipeline (paths among them are absolute).
    roi : str or None
        Slices jobs on a structure set: the ROI name to reconstruct.

    Examples
    --------
    >>> Job("p7-Heart", "slices", "/data/p7/rtstruct.dcm", {"caps": "half"}, "Heart").describe()
    '/data/p7/rtstruct.dcm'
    >>> Job("t1", "photometric", ("/t/1.png", "/t/2.png", "/t/3.png")).describe()
    '/t/1.png;/t/2.png;/t/3.png'
    """

    id: str
    kind: str
    input: str | tuple[str, ...]
    options: dict[str, Any] = field(default_factory=dict)
    roi: str | None = None

    def describe(self) -> str:
        """Return the input as one line (images joined with ``;``) for tables and records."""
        return ";".join(self.input) if isinstance(self.input, tuple) else self.input


def check_kind(kind: str) -> str:
    """Return ``kind`` when it is one of :data:`KINDS`.

    Parameters
    ----------
    kind : str
        Job kind to check.

    Returns
    -------
    str
        ``kind`` unchanged.

    Raises
    ------
    ValueError
        When ``kind`` is not a known job kind.

    Examples
    --------
    >>> check_kind("slices")
    'slices'
    >>> check_kind("ct")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: kind: expected one of photometric, slices, got 'ct'
    """
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    return kind


def check_job_id(ident: Any, where: str = "id", reserved: Iterable[str] = ()) -> str:
    """Return ``ident`` when it is a safe job id: one plain folder name inside ``OUT``.

    The one id rule of every batch (``workbench batch``, ``workbench inspect run|watch``):
    :data:`ID_PATTERN` (a letter or digit first, then letters, digits, ``. _ + -``, at most
    128 characters), and none of the ``reserved`` names the output folder itself uses. So
    ``.``, ``..``, ``../x``, ``/abs``, ``a/b`` and hidden names are refused. Ids derived from
    file or folder names are made safe by :func:`workbench.batch.job_id` instead.

    Parameters
    ----------
    ident : str
        The id (a manifest's ``id`` column).
    where : str, optional
        Where it came from, for the message (e.g. ``"manifest m.csv row 3"``).
    reserved : iterable of str, optional
        Names the output folder uses (``failed``, ``results.csv``, ...).

    Returns
    -------
    str
        ``ident`` as text.

    Raises
    ------
    InputError
        When it is not a safe folder name.

    Examples
    --------
    >>> check_job_id("part-7")
    'part-7'
    >>> check_job_id("..", "row 1")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: row 1: id '..' is not a safe folder name (letters, digits, . _ + -, a letter or \
digit first, at most 128 characters)
    """
    text = str(ident)
    reserved = frozenset(reserved)
    if not ID_PATTERN.match(text) or text in reserved:
        also = f"; not {', '.join(sorted(reserved))}" if reserved else ""
        raise InputError(f"{where}: id {text!r} is not a safe folder name (letters, digits, . _ + -, a letter or "
                         f"digit first, at most 128 characters{also})")
    return text


def job_folder(out: str | os.PathLike, ident: str) -> Path:
    """Return ``OUT/<ident>``, checked to stay inside ``OUT`` (the only place a job writes or removes).

    Parameters
    ----------
    out : path
        Batch output folder.
    ident : str
        A job id (:func:`check_job_id`).

    Returns
    -------
    Path

    Raises
    ------
    InputError
        An unsafe id, or ``OUT/<ident>`` is a symbolic link (nothing is written or removed through a link).

    Examples
    --------
    >>> job_folder("/runs/out", "p1").as_posix()
    '/runs/out/p1'
    """
    folder = Path(out) / check_job_id(ident)
    if folder.is_symlink():
        raise InputError(f"job {ident}: {folder} is a symbolic link; a job folder must be a real folder inside "
                         f"{out} (remove the link)")
    return folder
