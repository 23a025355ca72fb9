"""Tests of :mod:`workbench.cli`: the groups, usage errors, bad input as one line and exit code 2."""

from __future__ import annotations

import importlib

import pytest

from workbench.cli import GROUPS, TOP_LEVEL, build_parser, main


def test_every_command_module_registers():
    parser = build_parser()
    top = next(a for a in parser._actions if a.dest == "command")
    assert set(top.choices) == {*GROUPS, "view", "demo"}
    for name, (_help, modules) in GROUPS.items():
        group = top.choices[name]
        sub = next(a for a in group._actions if a.dest == "subcommand")
        assert sub.choices, name
        for command in sub.choices.values():
            assert callable(command.get_default("func")), command.prog
        for module_name in modules:
            assert callable(importlib.import_module(module_name).register)
    for module_name in TOP_LEVEL:
        assert callable(importlib.import_module(module_name).register)


def test_no_command_and_group_without_command_show_help(capsys):
    assert main([]) == 2
    assert "usage: workbench" in capsys.readouterr().out
    assert main(["synth"]) == 2
    out = capsys.readouterr().out
    assert "usage: workbench synth" in out and "triad" in out and "phantom" in out


@pytest.mark.parametrize(
    "argv",
    [["no-such-group"], ["surfaces", "no-such-command"], ["surfaces", "info"], ["surfaces", "coons", "g.npy"]],
)
def test_usage_errors_are_one_line_and_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("workbench") and ": error: " in err[-1]


def test_input_errors_are_one_line_and_exit_2(tmp_path, capsys):
    assert main(["surfaces", "info", str(tmp_path / "none.ply")]) == 2
    err = capsys.readouterr().err
    assert err == f"workbench: error: {tmp_path / 'none.ply'}: no such mesh file\n"


def test_interrupt_exits_130(monkeypatch, capsys):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr("workbench.commands.demo.run", interrupted)
    assert main(["demo"]) == 130
    assert capsys.readouterr().err == "workbench: interrupted\n"


def test_other_errors_are_not_hidden(monkeypatch):
    """A bug is not bad input: it keeps its traceback."""

    def broken(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr("workbench.commands.demo.run", broken)
    with pytest.raises(ZeroDivisionError):
        main(["demo"])


def test_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == f"workbench {version('surface-workbench')}\n"


def test_warnings_are_one_line_each(monkeypatch, capsys):
    """A library warning or a numpy RuntimeWarning: one line each, no source line, the command goes on."""
    import warnings

    import numpy as np

    def noisy(args):
        warnings.warn("the grid is oriented inward\nsecond line", UserWarning, stacklevel=1)
        np.float64(1.0) / np.float64(0.0)
        print("done")
        return 0

    monkeypatch.setattr("workbench.commands.demo.run", noisy)
    assert main(["demo"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ("workbench: warning: the grid is oriented inward\n"
                            "workbench: warning: divide by zero encountered in scalar divide\n")
    assert captured.out == "done\n"
