"""The demo's run context: commands, progress steps, sections that could not run, the real-data folder."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest

from workbench.cli import build_parser
from workbench.demo.context import Context, shared_data_dir
from workbench.report import Report


def quick_context(out: Path) -> Context:
    """A --quick run's context writing to ``out``, without real data, with its own report."""
    return Context(out=out, quick=True, shared=out / "absent", report=Report("t", out))


def parses(command: str) -> bool:
    """True when every ``workbench ...`` part of ``command`` (joined by ``&&``) parses."""
    parser = build_parser()
    for part in command.split(" && "):
        words = shlex.split(part)
        if words[0] != "workbench":
            return False
        try:
            parser.parse_args(words[1:])
        except SystemExit:
            return False
    return True


def test_cmd_quotes_for_the_shell(tmp_path):
    ctx = Context(out=tmp_path, quick=True, shared=tmp_path, report=None)
    command = ctx.cmd("slices", "reconstruct", "a b/rtss.dcm", "--roi", "Lt Lung", "--out", "o")
    assert command == "workbench slices reconstruct 'a b/rtss.dcm' --roi 'Lt Lung' --out o"
    assert shlex.split(command)[1:] == ["slices", "reconstruct", "a b/rtss.dcm", "--roi", "Lt Lung",
                                        "--out", "o"]
    assert parses(command)


def test_parses_rejects_unknown_options_and_commands(capsys):
    assert parses("workbench surfaces render x.ply --out v.png && workbench demo --quick")
    assert not parses("workbench surfaces render x.ply --no-such-option")
    assert not parses("workbench no-such-group x")
    assert not parses("python -m workbench demo")


class _Bar:
    def __init__(self) -> None:
        self.n, self.text = 0, ""

    def set_postfix_str(self, text: str) -> None:
        self.text = text

    def update(self, k: int) -> None:
        self.n += k


def test_step_advances_the_bar(tmp_path):
    ctx = Context(out=tmp_path, quick=True, shared=tmp_path, report=None)
    ctx.step("no bar: nothing happens")
    ctx.bar = _Bar()
    ctx.step("x" * 50)
    ctx.step("second")
    assert (ctx.bar.n, ctx.bar.text) == (2, "second")
    ctx.step("y" * 50)
    assert ctx.bar.text == "y" * 40


def test_missing_is_recorded_and_reported(tmp_path):
    ctx = quick_context(tmp_path)
    ctx.missing("Real captures", "the folder is absent")
    assert ctx.unavailable == {"Real captures": "the folder is absent"}
    html = ctx.report.write().read_text()
    assert "Real captures: not available: the folder is absent" in html


def test_shared_data_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("WORKBENCH_SHARED_DATA", str(tmp_path))
    assert shared_data_dir() == tmp_path
    monkeypatch.delenv("WORKBENCH_SHARED_DATA")
    repo = Path(__file__).resolve().parents[3]
    assert shared_data_dir() == repo.parent / "shared" / "data"


def test_demo_package_api():
    import workbench.demo as demo

    assert sorted(demo.__all__) == ["Context", "run_demo", "shared_data_dir"]
    for name in demo.__all__:
        assert getattr(demo, name).__doc__, name


@pytest.mark.parametrize("words", [("demo", "--out", "o", "--quick"),
                                   ("synth", "phantom", "--pixel-size", "0.8", "--out", "k")])
def test_cmd_of_real_commands_parses(tmp_path, words):
    assert parses(Context(out=tmp_path, quick=True, shared=tmp_path, report=None).cmd(*words))
