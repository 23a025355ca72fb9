"""Tests of ``benchmarks/common.py`` (the one result-page writer) and that every benchmark script imports.

The benchmarks themselves are not run here (they take minutes); ``make bench`` runs them.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
SCRIPTS = sorted(p.name for p in BENCH.glob("bench_*.py"))


@pytest.fixture()
def common(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    monkeypatch.delitem(sys.modules, "common", raising=False)
    import common

    return common


def test_table_markdown(common):
    table = common.Table(["mesh", "time (s)", "note"], [["sphere", "0.251", ""], ["a|b", 3, "ok"]], align="lrl")
    assert table.markdown().splitlines() == [
        "| mesh | time (s) | note |",
        "|---|---:|---|",
        "| sphere | 0.251 | |",
        "| a\\|b | 3 | ok |",
    ]
    assert common.Table(["x"], []).markdown() == "| x |\n|---|"


@pytest.mark.parametrize(
    ("headers", "rows", "align", "message"),
    [
        ([], [], "", "at least one column"),
        (["a", "b"], [["1"]], "", r"rows\[0\]: expected 2 cells, got 1"),
        (["a", "b"], [], "l", "align: expected 2 letters"),
        (["a"], [], "c", "align: expected 1 letters"),
    ],
)
def test_table_rejects(common, headers, rows, align, message):
    with pytest.raises(ValueError, match=message):
        common.Table(headers, rows, align).markdown()


def test_write_results(common, tmp_path):
    parts = ["Best of 3 on 2 cores.", common.Table(["n", "s"], [[1, "0.5"]], "rr"), "## Notes\n", "Done."]
    text = common.write_results("demo", "A benchmark", parts, folder=tmp_path / "results")
    assert text == (
        "# A benchmark\n\nBest of 3 on 2 cores.\n\n| n | s |\n|---:|---:|\n| 1 | 0.5 |\n\n## Notes\n\nDone.\n"
    )
    assert (tmp_path / "results" / "demo.md").read_text() == text
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["demo.md"]


def test_best_of(common):
    calls = []
    best, last = common.best_of(lambda: calls.append(1) or len(calls), repeat=4)
    assert last == 4 and best >= 0.0 and len(calls) == 4


def test_run_all_nests_result_titles(common, monkeypatch):
    spec = importlib.util.spec_from_file_location("bench_run_all", BENCH / "run_all.py")
    run_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_all)
    assert run_all._nest("# Title\n\ntext\n## Part") == "## Title\n\ntext\n### Part"
    assert run_all._nest("## Already nested") == "## Already nested"
    assert run_all._names(["batch", "surfaces"]) == ["surfaces", "batch"]
    with pytest.raises(SystemExit, match="no benchmark named nope"):
        run_all._names(["nope"])


@pytest.mark.parametrize("script", SCRIPTS)
def test_script_imports(common, script):
    spec = importlib.util.spec_from_file_location(f"bench_script_{Path(script).stem}", BENCH / script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert callable(module.main) and module.__doc__
