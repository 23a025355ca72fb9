"""The HTML report writer and a reduced-size (--quick) smoke run of the whole demo.

Each demo module has its own tests in ``tests/workbench/demo/``.
"""

from __future__ import annotations

import base64
import html
import json
import math
import re
import time
from html.parser import HTMLParser
from pathlib import Path

import cv2
import numpy as np
import pytest

from workbench.report import Report

from .demo.test_context import parses


class _Collector(HTMLParser):
    """Image sources, links, and the text of every table cell."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.links: list[str] = []
        self.cells: list[str] = []
        self.headers: list[str] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        elif tag == "a":
            self.links.append(attrs.get("href", ""))
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            (self.cells if tag == "td" else self.headers).append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _decode(data: bytes):
    import cv2

    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)


def check_report(path: Path) -> _Collector:
    """Every image decodes, every linked file exists and decodes, every cell has a value."""
    parsed = _Collector()
    parsed.feed(path.read_text(encoding="utf-8"))
    assert parsed.images, "the report has no images"
    for src in parsed.images:
        if src.startswith("data:image/png;base64,"):
            img = _decode(base64.b64decode(src.split(",", 1)[1]))
        else:
            assert not src.startswith(("http:", "https:")), f"external image {src}"
            img = _decode((path.parent / src).read_bytes())
        assert img is not None and img.size > 0 and img.std() > 0, f"blank or broken image {src[:60]}"
    for href in parsed.links:
        if href.startswith("#"):
            continue
        assert not href.startswith(("http:", "https:")), f"the report needs the network: {href}"
        target = path.parent / href
        assert target.is_file(), f"link to a missing file {href}"
        if target.suffix == ".png":
            assert _decode(target.read_bytes()) is not None
    for cell in parsed.cells:
        assert cell and cell.lower() not in ("none", "nan", "null"), f"empty table cell {cell!r}"
    return parsed


def _picture(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random((20, 30, 3)) * 255).astype(np.uint8)


def test_report_roundtrip(tmp_path):
    rep = Report("t", tmp_path)
    rep.section("One", "intro <b>escaped</b>")
    rep.figure(_picture(0), "first", "a caption & more", "workbench demo --quick")
    rep.table(["a", "b", "c"], [[1, 2.5, "x"], [np.int64(3), np.float32(0.125), True]])
    rep.note("not available: reason")
    rep.section("Two")
    rep.figure(_picture(1), "second", "another", "workbench view x.ply --png y.png")
    rep.table(["figure", "file", "caption", "command"],
              [[a, b, c, f"`{d}`"] for a, b, c, d in rep.figure_index()])
    path = rep.write(meta="now")
    parsed = check_report(path)
    assert len(parsed.images) == 2
    assert "<b>escaped</b>" not in path.read_text()
    assert (tmp_path / "figures" / "first.png").is_file()
    assert parsed.cells[:3] == ["1", "2.5", "x"]
    assert "workbench view x.ply --png y.png" in parsed.cells
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures", "report.html"]


@pytest.mark.parametrize("cell", [None, "", "  ", float("nan"), math.inf])
def test_report_rejects_missing_values(tmp_path, cell):
    rep = Report("t", tmp_path)
    with pytest.raises(ValueError, match="rows\\[0\\]\\[1\\]"):
        rep.table(["a", "b"], [[1, cell]])


def test_report_rejects_bad_figures(tmp_path):
    rep = Report("t", tmp_path)
    rep.figure(_picture(0), "a", "c", "cmd")
    with pytest.raises(ValueError, match="already"):
        rep.figure(_picture(0), "a", "c", "cmd")
    with pytest.raises(ValueError, match="name"):
        rep.figure(_picture(0), "../x", "c", "cmd")
    with pytest.raises(ValueError, match="command"):
        rep.figure(_picture(0), "b", "c", " ")
    with pytest.raises(ValueError, match="cells"):
        rep.table(["a", "b"], [[1]])


@pytest.fixture(scope="module")
def quick_demo(tmp_path_factory):
    """One --quick run of ``workbench demo`` through the command line."""
    from workbench.cli import main

    out = tmp_path_factory.mktemp("demo")
    start = time.perf_counter()
    code = main(["demo", "--out", str(out), "--quick"])
    return out, code, time.perf_counter() - start


REAL_DATA_SECTIONS = {"Real captures", "CT: breast structure set"}


@pytest.mark.slow
def test_quick_demo_report(quick_demo):
    """The report is complete and self-contained; only real-data sections may be missing."""
    from workbench.demo import shared_data_dir

    out, code, seconds = quick_demo
    assert code == 0
    summary = json.loads((out / "demo.json").read_text())
    # only sections whose real data is absent may be missing; any error fails the run
    missing = set(summary["unavailable"])
    assert missing == (set() if shared_data_dir().is_dir() else REAL_DATA_SECTIONS)
    parsed = check_report(out / "report.html")
    assert len(parsed.images) == len(summary["figures"]) >= (9 if missing else 15)
    from workbench.report import REPORT_WIDTH_PX

    for fig in summary["figures"]:
        assert (out / fig["file"]).is_file() and parses(fig["command"]), fig["command"]
        # shown at its own size in the report: colour-bar and tile labels keep their 11 px
        assert cv2.imread(str(out / fig["file"])).shape[1] <= REPORT_WIDTH_PX, fig["file"]
    # the figure index (section 5) lists every figure with its command
    for fig in summary["figures"]:
        assert fig["command"] in parsed.cells
    insp = summary["inspection"]
    assert insp["normal_error_mean_deg"] < 2.0
    assert insp["height_rms_error_mm"] < 0.1 * insp["height_range_true_mm"]
    assert {d["kind"] for d in insp["defects"]} == {"v_crack", "spherical_dent", "u_scratch"}
    for d in insp["defects"]:
        assert d["depth_measured_mm"] == pytest.approx(d["depth_true_mm"], rel=0.35)
    assert summary["accuracy"]["recommendation"]
    for case in summary["accuracy"]["crack_study"]["cases"]:
        assert case["max_abs_diff_measured_predicted"] < 1e-3
    kidney = summary["ct"]["kidney"]
    assert abs(kidney["volume_error_percent"]) < 5.0
    assert kidney["surface_distance_mean_mm"] < 1.0
    assert seconds < 180


@pytest.mark.slow
def test_quick_demo_real_data(quick_demo, shared_data):
    """With ../shared: the bear baselines are reproduced and the Heart volume is in range."""
    out, code, _ = quick_demo
    summary = json.loads((out / "demo.json").read_text())
    real = summary["real"]
    # plain least squares reproduces the published subset baselines (11.74 / 9.60 deg)
    assert real["triad_mean_error_deg"] == pytest.approx(11.74, abs=0.3)
    assert real["all14_mean_error_deg"] == pytest.approx(9.60, abs=0.3)
    assert summary["ct"]["Heart"]["volume_cc"] == pytest.approx(437.46, rel=0.05)


@pytest.mark.slow
def test_quick_demo_report_is_portable_and_redrawable(quick_demo, tmp_path):
    """No absolute path in report.html; --figures-only redraws every figure from the saved data, unchanged."""
    import shutil

    from workbench.cli import main
    from workbench.demo.figures import DRAWERS

    out, code, _ = quick_demo
    assert code == 0
    page = (out / "report.html").read_text()
    text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", page)
    for absolute in {str(out), str(out.resolve()), str(Path.home()), "/tmp/", "/work/"}:
        assert absolute not in text, absolute
    summary = json.loads((out / "demo.json").read_text())
    names = [Path(f["file"]).stem for f in summary["figures"]]
    for name in names:
        spec = json.loads((out / "figures" / f"{name}.json").read_text())
        assert spec["draw"] in DRAWERS and spec["command"] in html.unescape(text)
    # a copy of the folder elsewhere: its figures are redrawn from the copy's own data
    copy = tmp_path / "moved"
    shutil.copytree(out, copy)
    before = {n: cv2.imread(str(copy / "figures" / f"{n}.png")) for n in names}
    for n in names:
        (copy / "figures" / f"{n}.png").unlink()
    assert main(["demo", "--figures-only", str(copy)]) == 0
    for n in names:
        after = cv2.imread(str(copy / "figures" / f"{n}.png"))
        assert after is not None and after.shape == before[n].shape, n
        assert np.abs(after.astype(int) - before[n].astype(int)).mean() < 0.5, n
    assert (copy / "report.html").read_text().count("data:image/png;base64,") == len(names)
