"""Tests of :mod:`workbench.report` (cell formatting, sections, figure records, the written page).

The report's round trip through an HTML parser and its refusals of missing
values are tested with the demo in ``test_demo.py``.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from workbench.report import Report, _format_cell


@pytest.mark.parametrize(
    ("cell", "text", "numeric"),
    [
        (3, "3", True),
        (np.int32(-7), "-7", True),
        (0.028812, "0.02881", True),
        (1234.5678, "1235", True),
        (123456.0, "123456", True),
        (2.5, "2.5", True),
        (0.0, "0", True),
        (1e-5, "1e-05", True),
        (3e13, "3e+13", True),
        (np.float32(0.125), "0.125", True),
        (True, "yes", False),
        (np.bool_(False), "no", False),
        ("a < b", "a &lt; b", False),
        ("`workbench demo --quick`", "<code>workbench demo --quick</code>", False),
        ("``", "``", False),
    ],
)
def test_format_cell(cell, text, numeric):
    assert _format_cell(cell, 4, "here") == (text, numeric)


def test_sections_notes_and_figure_records(tmp_path):
    rep = Report("Title & more", tmp_path / "rep")
    rep.section("CT: breast structure set", "first <section>")
    rep.note("not available: no ../shared/data")
    picture = np.zeros((6, 8, 3), np.uint8)
    picture[:, :4] = 200
    path = rep.figure(picture, "half-grey", "a grey left half", "workbench view x.ply --png y.png")
    assert path == tmp_path / "rep" / "figures" / "half-grey.png" and path.is_file()
    rep.section("Figures")
    rep.figure(picture[..., 0], "grey_2", "one channel", "workbench demo --out o")
    assert rep.figure_index() == [
        ["Figure 1", "figures/half-grey.png", "a grey left half", "workbench view x.ply --png y.png"],
        ["Figure 2", "figures/grey_2.png", "one channel", "workbench demo --out o"],
    ]
    assert [f.section for f in rep.figures] == ["CT: breast structure set", "Figures"]
    page = rep.write("index.html", meta="2 cores").read_text()
    assert page.startswith("<!DOCTYPE html>") and "<title>Title &amp; more</title>" in page
    assert '<h2 id="ct-breast-structure-set">' in page and "first &lt;section&gt;" in page
    assert '<div class="note">not available: no ../shared/data</div>' in page
    assert '<p class="meta">2 cores</p>' in page
    assert len(re.findall(r'<img src="data:image/png;base64,', page)) == 2
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == ["figures", "index.html"]


def test_table_caption_digits_and_headers(tmp_path):
    rep = Report("t", tmp_path)
    rep.table(["x (mm)"], [[np.pi]], caption="pi <approx>", digits=6)
    html = rep.parts[-1]
    assert "<caption>pi &lt;approx&gt;</caption>" in html and '<td class="num">3.14159</td>' in html
    with pytest.raises(ValueError, match="headers: a table needs at least one column"):
        rep.table([], [])


def test_figure_must_encode(tmp_path):
    rep = Report("t", tmp_path)
    with pytest.raises(ValueError):
        rep.figure(np.zeros((4, 4, 3), np.float64), "f", "c", "cmd")
    assert rep.figures == []


def test_table_decimals_per_column(tmp_path):
    """A column of one resolution: fixed decimals, not significant digits (0.00 beside 9.60, never -0.00)."""
    rep = Report("t", tmp_path)
    rep.table(["set", "mean (deg)", "difference (deg)"], [["all 14", 9.5998315, -0.0001685]], decimals={1: 2, 2: 2})
    page = rep.write().read_text()
    assert '<td class="num">9.60</td><td class="num">0.00</td>' in page
    assert "0.0001685" not in page
