"""Helpers shared by the benchmark scripts (run from this folder or through run_all.py).

Every script times its peer in the same run with :func:`best_of` and writes
its result page ``results/<name>.md`` with :func:`write_results`: a title,
then paragraphs, headings and :class:`Table` s in order. ``run_all.py``
gathers the pages into ``benchmarks/README.md``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from surfaces.io import atomic_write_text

RESULTS = Path(__file__).resolve().parent / "results"


def best_of(fn, repeat: int = 3):
    """Call ``fn`` ``repeat`` times; return the shortest wall time (s) and the last result."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


@dataclass(frozen=True)
class Table:
    """A Markdown table of a result page.

    Attributes
    ----------
    headers : sequence of str
        Column titles.
    rows : sequence of sequences
        Cells, one sequence per row, as many as ``headers``; numbers should be
        formatted by the caller (``f"{t:.3f}"``), anything else is shown with ``str``.
    align : str
        One letter per column, ``l`` (left) or ``r`` (right); empty: no alignment marks.

    Examples
    --------
    >>> print(Table(["task", "time (s)"], [["solve", "0.169"], ["a | b", 2]], "lr").markdown())
    | task | time (s) |
    |---|---:|
    | solve | 0.169 |
    | a \\| b | 2 |
    """

    headers: Sequence[str]
    rows: Sequence[Sequence[object]]
    align: str = ""

    def markdown(self) -> str:
        """Return the table as Markdown lines (no trailing newline)."""
        n = len(self.headers)
        if n == 0:
            raise ValueError("headers: a table needs at least one column")
        if self.align and (len(self.align) != n or set(self.align) - {"l", "r"}):
            raise ValueError(f"align: expected {n} letters l or r, got {self.align!r}")
        for i, row in enumerate(self.rows):
            if len(row) != n:
                raise ValueError(f"rows[{i}]: expected {n} cells, got {len(row)}")
        marks = "|".join("---:" if a == "r" else "---" for a in self.align or "l" * n)
        lines = [_row(self.headers), f"|{marks}|", *(_row(row) for row in self.rows)]
        return "\n".join(lines)


def _row(cells: Sequence[object]) -> str:
    texts = (str(c).replace("|", "\\|") for c in cells)
    return "|" + "|".join(f" {t} " if t else " " for t in texts) + "|"


def results_markdown(title: str, parts: Sequence[str | Table]) -> str:
    """Assemble a result page: ``# title``, then each part, separated by blank lines.

    Parameters
    ----------
    title : str
        The page title (a level-1 heading; ``run_all.py`` demotes it in the README).
    parts : sequence of str or Table
        Paragraphs, notes, headings (``"## ..."``) and tables, in order.

    Returns
    -------
    str
        The page, ending in one newline.

    Examples
    --------
    >>> print(results_markdown("Speed", ["Best of 3.", Table(["n", "s"], [[1, "0.5"]]), "## Notes", "None."]))
    # Speed
    <BLANKLINE>
    Best of 3.
    <BLANKLINE>
    | n | s |
    |---|---|
    | 1 | 0.5 |
    <BLANKLINE>
    ## Notes
    <BLANKLINE>
    None.
    <BLANKLINE>
    """
    blocks = [f"# {title}"] + [p.markdown() if isinstance(p, Table) else p.strip("\n") for p in parts]
    return "\n\n".join(blocks) + "\n"


def write_results(name: str, title: str, parts: Sequence[str | Table], folder: Path = RESULTS) -> str:
    """Write a benchmark's result page ``<folder>/<name>.md`` atomically (see :func:`results_markdown`).

    Parameters
    ----------
    name : str
        The benchmark's name (``bench_<name>.py``).
    title : str
        The page title.
    parts : sequence of str or Table
        Paragraphs, notes, headings and tables, in order.
    folder : Path
        Where result pages go (default ``benchmarks/results``); created when missing.

    Returns
    -------
    str
        The page written.
    """
    text = results_markdown(title, parts)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / f"{name}.md", text)
    return text
