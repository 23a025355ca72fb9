"""What a batch job is: its kind and the :class:`Job` record every other batch module passes around."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any
from surfaces.validate import InputError

#: the job kinds, one per library pipeline
KINDS: tuple[str, ...] = ("photometric", "slices")


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
