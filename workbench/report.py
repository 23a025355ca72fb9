"""A small HTML report writer: sections, figures, tables; one self-contained file that opens offline.

Figures are written as PNG files into ``<out_dir>/figures/`` (the artefacts)
and embedded in the HTML as base64 ``data:`` URIs, so ``report.html`` works
on its own (mailed, copied, opened without a network) and the PNGs stay
available beside it. Every figure carries the command that reproduces it;
:meth:`Report.figure_index` lists them all for the report's last section.
"""

from __future__ import annotations

import base64
import html
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from surfaces.validate import InputError

#: widest picture the report shows at its own size (the page's 1200 px column less its padding): wider
#: ones are scaled down by the browser, and their colour-bar labels with them
REPORT_WIDTH_PX = 1160

CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; margin: 2em auto;
       max-width: 1200px; color: #222; line-height: 1.45; padding: 0 1em; }
h1 { border-bottom: 2px solid #345; padding-bottom: .2em; }
h2 { margin-top: 2em; border-bottom: 1px solid #aab; color: #234; }
figure { display: inline-block; margin: .6em 1em .6em 0; vertical-align: top; max-width: 100%; }
figure img { max-width: 100%; border: 1px solid #ccd; }
figcaption { font-size: .9em; color: #444; max-width: 640px; }
figcaption code, td code { font-size: .85em; background: #f3f3f6; padding: 0 .25em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .92em; }
th, td { border: 1px solid #bbc; padding: .25em .6em; text-align: left; vertical-align: top; }
th { background: #eef0f5; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.note { background: #fff4e0; border-left: 4px solid #e90; padding: .5em .8em; margin: .8em 0; }
.meta { color: #666; font-size: .9em; }
"""


@dataclass
class FigureRecord:
    """One figure of the report: its id, file (relative to the report), caption and command."""

    number: int
    file: str
    caption: str
    command: str
    section: str


@dataclass
class Report:
    """An HTML report assembled in order, then written with :meth:`write`.

    Parameters
    ----------
    title : str
        Page title.
    out_dir : path-like
        Folder of ``report.html``; figures go to ``out_dir/figures``.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     report = Report("Inspection plate", folder)
    ...     report.section("Defects", "Measured depths against the scene's truth.")
    ...     report.table(["defect", "depth (mm)", "found"], [["crack", 0.028812, True], ["dent", 0.05, False]])
    ...     page = report.write(meta="run of today").read_text()
    >>> page.count("<tr>"), '<td class="num">0.02881</td><td>yes</td>' in page
    (3, True)
    """

    title: str
    out_dir: Path
    parts: list[str] = field(default_factory=list)
    figures: list[FigureRecord] = field(default_factory=list)
    _section: str = ""

    def __post_init__(self) -> None:
        self.out_dir = Path(self.out_dir)
        (self.out_dir / "figures").mkdir(parents=True, exist_ok=True)

    def section(self, title: str, intro: str = "") -> None:
        """Start a section (``<h2>``) with an optional introductory paragraph."""
        self._section = title
        anchor = re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-")
        self.parts.append(f'<h2 id="{anchor}">{html.escape(title)}</h2>')
        if intro:
            self.paragraph(intro)

    def paragraph(self, text: str) -> None:
        """Add a paragraph of plain text (escaped)."""
        self.parts.append(f"<p>{html.escape(text)}</p>")

    def note(self, text: str) -> None:
        """Add a highlighted note, e.g. ``not available: <reason>``."""
        self.parts.append(f'<div class="note">{html.escape(text)}</div>')

    def figure(self, image: np.ndarray, name: str, caption: str, command: str) -> Path:
        """Write a picture to ``figures/<name>.png`` and embed it.

        Parameters
        ----------
        image : (H, W, 3) or (H, W) uint8
            RGB picture.
        name : str
            File stem (letters, digits, ``-`` and ``_``).
        caption : str
            What the picture shows (units included).
        command : str
            The command line that reproduces it.

        Returns
        -------
        pathlib.Path
            The PNG written.
        """
        import cv2

        from surfaces.io import write_png

        if not re.fullmatch(r"[A-Za-z0-9_\-]+", name):
            raise InputError(f"name: use letters, digits, '-' and '_' only, got {name!r}")
        if any(rec.file == f"figures/{name}.png" for rec in self.figures):
            raise InputError(f"name: figure {name!r} already exists in this report")
        if not command.strip():
            raise InputError(f"command: figure {name!r} needs the command that reproduces it")
        path = write_png(self.out_dir / "figures" / f"{name}.png", np.asarray(image))
        data = path.read_bytes()
        if cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) is None:
            raise InputError(f"image: figure {name!r} did not encode as PNG")
        number = len(self.figures) + 1
        rel = f"figures/{name}.png"
        self.figures.append(FigureRecord(number, rel, caption, command, self._section))
        uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
        self.parts.append(
            f'<figure id="fig-{number}"><img src="{uri}" alt="{html.escape(caption, quote=True)}">'
            f"<figcaption><b>Figure {number}.</b> {html.escape(caption)} "
            f'(<a href="{rel}">{html.escape(rel)}</a>)<br><code>{html.escape(command)}</code>'
            "</figcaption></figure>"
        )
        return path

    def table(self, headers: list[str], rows: list[list], caption: str = "", digits: int = 4,
              decimals: dict[int, int] | None = None) -> None:
        """Add a table; every cell must have a value.

        Parameters
        ----------
        headers : list of str
            Column titles.
        rows : list of lists
            Cells: str, int or float (floats shown with ``digits`` significant
            digits). ``None``, empty strings and non-finite numbers are
            rejected: write why a value is missing instead.
        caption : str
            Shown above the table.
        digits : int
            Significant digits of floats.
        decimals : dict, optional
            Column index -> fixed decimals for the floats of that column: a column of
            figures with one resolution (degrees to 0.01 beside a baseline given so) reads
            ``0.00``, not ``-0.0001685`` beside ``9.6``.
        """
        if not headers:
            raise InputError("headers: a table needs at least one column")
        cells_html = []
        for r, row in enumerate(rows):
            if len(row) != len(headers):
                raise InputError(f"rows[{r}]: expected {len(headers)} cells, got {len(row)}")
            tds = []
            for c, cell in enumerate(row):
                text, numeric = _format_cell(cell, digits, f"rows[{r}][{c}] ({headers[c]})",
                                             (decimals or {}).get(c))
                cls = ' class="num"' if numeric else ""
                tds.append(f"<td{cls}>{text}</td>")
            cells_html.append("<tr>" + "".join(tds) + "</tr>")
        head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
        cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
        self.parts.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{''.join(cells_html)}"
                          "</tbody></table>")

    def figure_index(self) -> list[list[str]]:
        """Rows ``[figure, file, caption, command]`` for every figure so far."""
        return [[f"Figure {f.number}", f.file, f.caption, f.command] for f in self.figures]

    def write(self, name: str = "report.html", meta: str = "") -> Path:
        """Write the report atomically.

        Parameters
        ----------
        name : str
            File name inside ``out_dir``.
        meta : str
            A line under the title (date, machine, run time).

        Returns
        -------
        pathlib.Path
            The HTML file.
        """
        body = "\n".join(self.parts)
        meta_html = f'<p class="meta">{html.escape(meta)}</p>' if meta else ""
        page = (
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(self.title)}</title><style>{CSS}</style></head><body>"
            f"<h1>{html.escape(self.title)}</h1>{meta_html}\n{body}\n</body></html>\n"
        )
        from surfaces.io import atomic_write_text

        out = atomic_write_text(self.out_dir / name, page)
        return out


def _format_cell(cell, digits: int, where: str, decimals: int | None = None) -> tuple[str, bool]:
    """HTML text of a table cell and whether it is numeric; ValueError for a missing value."""
    if cell is None:
        raise InputError(f"{where}: empty cell (None); say why the value is missing instead")
    if isinstance(cell, (bool, np.bool_)):
        return ("yes" if cell else "no"), False
    if isinstance(cell, (int, np.integer)):
        return str(int(cell)), True
    if isinstance(cell, (float, np.floating)):
        if not math.isfinite(float(cell)):
            raise InputError(f"{where}: non-finite number {cell!r}")
        x = float(cell)
        if decimals is not None:
            text = f"{x:.{int(decimals)}f}"
            return (f"{0.0:.{int(decimals)}f}" if float(text) == 0 else text), True  # no "-0.00"
        if x == 0 or not 1e-3 <= abs(x) < 1e12:
            return f"{x:.{digits}g}", True
        # fixed-point with ``digits`` significant digits (never fewer than all integer digits)
        decimals = max(0, digits - 1 - math.floor(math.log10(abs(x))))
        text = f"{x:.{decimals}f}"
        return (text.rstrip("0").rstrip(".") if "." in text else text), True
    text = str(cell)
    if not text.strip():
        raise InputError(f"{where}: empty cell; say why the value is missing instead")
    if text.startswith("`") and text.endswith("`") and len(text) > 2:
        return f"<code>{html.escape(text[1:-1])}</code>", False
    return html.escape(text), False
