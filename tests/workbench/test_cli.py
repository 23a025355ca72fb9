"""Tests of :mod:`workbench.cli`: the groups, usage errors, bad input as one line and exit code 2."""

from __future__ import annotations

import importlib

import pytest

from surfaces.validate import InputError
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


def test_a_plain_value_error_keeps_its_traceback(monkeypatch):
    """numpy's own ValueError (a bug: shapes that do not broadcast) is not bad input: no exit 2, it propagates."""
    import numpy as np

    def buggy(args):
        return np.ones(3) + np.ones(4)

    monkeypatch.setattr("workbench.commands.demo.run", buggy)
    with pytest.raises(ValueError, match="could not be broadcast") as raised:
        main(["demo"])
    assert not isinstance(raised.value, InputError)


def test_the_console_script_prints_a_bug_with_its_traceback(tmp_path):
    """Through the real entry point: a ValueError from numpy gives a traceback and exit 1, bad input one line and 2."""
    import os
    import subprocess
    import sys

    script = (
        "import sys, numpy as np, workbench.commands.demo as d\n"
        "d.run = lambda args: np.ones(3) + np.ones(4)\n"
        "from workbench.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    bug = subprocess.run([sys.executable, "-c", script, "demo"], capture_output=True, text=True, env=env,
                         cwd=tmp_path, timeout=120)
    assert bug.returncode == 1
    assert "Traceback (most recent call last)" in bug.stderr
    assert "ValueError: operands could not be broadcast" in bug.stderr
    assert "workbench: error" not in bug.stderr
    bad = subprocess.run([sys.executable, "-c", script, "surfaces", "info", "none.ply"], capture_output=True,
                         text=True, env=env, cwd=tmp_path, timeout=120)
    assert bad.returncode == 2
    assert bad.stderr == "workbench: error: none.ply: no such mesh file\n"


@pytest.mark.parametrize(
    ("error", "code"),
    [
        (InputError("--grid: must be at least 2"), 2),
        (FileNotFoundError("part.ply: no such mesh file"), 2),
        (PermissionError(13, "Permission denied", "out/report.json"), 2),
        (OSError(28, "No space left on device", "out/mesh.ply"), 2),
        (OSError("a socket went away"), None),
        (ValueError("a bug"), None),
        (KeyError("a bug"), None),
    ],
)
def test_only_input_and_file_errors_are_exit_2(monkeypatch, capsys, error, code):
    def failing(args):
        raise error

    monkeypatch.setattr("workbench.commands.demo.run", failing)
    if code is None:
        with pytest.raises(type(error)):
            main(["demo"])
    else:
        assert main(["demo"]) == code
        err = capsys.readouterr().err
        assert err.startswith("workbench: error: ") and err.count("\n") == 1


def test_every_package_exports_the_same_input_error():
    import datasets_synthetic
    import photometric
    import slices
    import surfaces
    import workbench

    for package in (surfaces, photometric, slices, datasets_synthetic, workbench):
        assert package.InputError is InputError, package.__name__
        assert "InputError" in package.__all__, package.__name__


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
