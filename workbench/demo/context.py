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
    >>> print(ctx.cmd("slices", "reconstruct", str(Path("s/rt ss.dcm").resolve()),
    ...               "--out", str(Path("o/ct").resolve())))
    workbench slices reconstruct "$WORKBENCH_SHARED_DATA"/'rt ss.dcm' --out ct
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
        """The shell command ``workbench <words>`` that reproduces a figure's data, run from the report's folder.

        Paths inside :attr:`out` are written relative to it, paths inside :attr:`shared`
        as ``"$WORKBENCH_SHARED_DATA"/<path>``, so that the report holds no absolute path
        and its commands work wherever the folder is copied.

        Parameters
        ----------
        *words : str
            Sub-command, arguments and options; quoted for the shell where needed.

        Returns
        -------
        str
        """
        return "workbench " + " ".join(self.shell_word(w) for w in words)

    def shell_word(self, word: str) -> str:
        """One word of a command, quoted for the shell, with a path made portable (see :meth:`cmd`)."""
        if os.path.isabs(word):
            path = Path(word)
            for base, prefix in ((self.out, None), (self.shared, '"$WORKBENCH_SHARED_DATA"')):
                try:
                    rel = path.resolve().relative_to(Path(base).resolve())
                except ValueError:
                    continue
                if prefix is None:
                    return shlex.quote(rel.as_posix() or ".")
                return prefix + ("/" + shlex.quote(rel.as_posix()) if rel.parts else "")
        return shlex.quote(word)

    def rel(self, path: str | os.PathLike) -> str:
        """A path of the run as the figure data stores it: relative to :attr:`out`, or ``shared:<path>``."""
        from workbench.demo.figures import SHARED

        p = Path(path).resolve()
        try:
            return p.relative_to(Path(self.out).resolve()).as_posix()
        except ValueError:
            return SHARED + p.relative_to(Path(self.shared).resolve()).as_posix()

    def figure(self, name: str, draw, caption: str, command: str, params: dict | None = None,
               arrays: dict | None = None) -> None:
        """Save a figure's data beside its PNG, draw it from that data and add it to the report.

        Parameters
        ----------
        name : str
            Figure name (``figures/<name>.png``).
        draw : callable
            A drawer of :mod:`workbench.demo.figures` (``draw(source, **params, **arrays)``).
        caption, command : str
            What the figure shows and the command that reproduces its data.
        params : dict, optional
            JSON keyword arguments of the drawer (paths via :meth:`rel`).
        arrays : dict, optional
            Array keyword arguments of the drawer.
        """
        from workbench.demo import figures

        figures.save(self.out, name, draw, caption, command, params, arrays)
        picture = figures.draw(figures.Source(Path(self.out), Path(self.shared)), name)
        self.report.figure(picture, name, caption, command)

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
