"""The state every demo section shares: output folder, size switch, real-data folder, report, numbers."""

from __future__ import annotations

import os
import shlex
from dataclasses import dataclass, field
from pathlib import Path

from workbench.report import Report


def shared_data_dir() -> Path:
    """The real-data folder: ``$WORKBENCH_SHARED_DATA`` or ``../shared/data`` beside the repository.

    Returns
    -------
    pathlib.Path
        The folder (it may not exist; the sections that need it say so in the report).
    """
    env = os.environ.get("WORKBENCH_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "data"


@dataclass
class Context:
    """State shared by the demo sections.

    Attributes
    ----------
    out : pathlib.Path
        Output folder of the run.
    quick : bool
        Reduced sizes (the smoke test).
    shared : pathlib.Path
        Real-data folder.
    report : workbench.report.Report
        The HTML report being assembled.
    numbers : dict
        Every number of the run, by section (``demo.json``).
    unavailable : dict
        Section -> reason, for sections whose real data is absent.
    bar : tqdm progress bar or None
        Advanced by :meth:`step`.

    Examples
    --------
    >>> ctx = Context(out=Path("o"), quick=True, shared=Path("s"), report=None)
    >>> ctx.cmd("slices", "reconstruct", "rtss.dcm", "--roi", "Lt Lung")
    "workbench slices reconstruct rtss.dcm --roi 'Lt Lung'"
    """

    out: Path
    quick: bool
    shared: Path
    report: Report
    numbers: dict = field(default_factory=dict)
    unavailable: dict = field(default_factory=dict)
    bar: object = None

    def step(self, text: str) -> None:
        """Advance the progress bar by one step, showing ``text``."""
        if self.bar is not None:
            self.bar.set_postfix_str(text[:40])
            self.bar.update(1)

    def cmd(self, *words: str) -> str:
        """The shell command ``workbench <words>`` that reproduces a figure's data.

        Parameters
        ----------
        *words : str
            Sub-command, arguments and options; quoted for the shell where needed.

        Returns
        -------
        str
        """
        return "workbench " + shlex.join(words)

    def missing(self, what: str, reason: str) -> None:
        """Record that the section ``what`` could not run for ``reason`` (real data absent).

        Parameters
        ----------
        what : str
            Section name, the key in ``demo.json``'s ``unavailable``.
        reason : str
            Why, as shown in the report.
        """
        self.unavailable[what] = reason
        self.report.note(f"{what}: not available: {reason}")
