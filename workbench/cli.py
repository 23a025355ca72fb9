"""The ``workbench`` console script: one entry point, sub-commands per package.

Errors that come from bad input (:class:`surfaces.validate.InputError`, which
every reader and option check raises, and the file errors ``FileNotFoundError``,
``NotADirectoryError``, ``IsADirectoryError``, ``PermissionError`` and any other
``OSError`` that names a file) are printed as one line on stderr and the
process exits with code 2, without a traceback. Every other exception (a
``ValueError`` from inside numpy, an ``IndexError``, ...) is a bug and keeps its
traceback. Python warnings raised
while a command runs (a library's ``UserWarning``, SciPy's and NumPy's
``RuntimeWarning``) are printed as one line each, ``workbench: warning: ...``,
without their source line.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence

from surfaces.validate import InputError

# group name -> (help text, modules that register sub-commands into the group)
GROUPS: dict[str, tuple[str, tuple[str, ...]]] = {
    "surfaces": (
        "shared Bezier/Coons surface model: build, measure, export, render, sweep, boolean",
        (
            "workbench.commands.surfaces",
            "workbench.commands.kinematic",
            "workbench.commands.render",
            "workbench.commands.boolean",
        ),
    ),
    "photometric": (
        "photometric stereo: normals, height, defects, light-deviation error analysis",
        ("workbench.commands.photometric", "workbench.commands.errors", "workbench.commands.texture"),
    ),
    "slices": (
        "CT contour stacks and structure sets to one interpolating surface",
        ("workbench.commands.slices",),
    ),
    "synth": (
        "synthetic scenes with exact ground truth (image triads, CT phantoms)",
        ("workbench.commands.synth",),
    ),
    "batch": (
        "many photometric or slices jobs on a Dask cluster",
        ("workbench.commands.batch",),
    ),
    "inspect": (
        "inspection runs: calibrate a rig once, measure every part, pass or fail against a spec",
        ("workbench.commands.inspect",),
    ),
}
# modules that add top-level commands (``workbench view``, ``workbench demo``)
TOP_LEVEL: tuple[str, ...] = ("workbench.commands.view", "workbench.commands.demo")

#: the exceptions that mean bad input: one line on stderr and exit code 2 (an ``OSError`` only when it names a file)
INPUT_ERRORS = (InputError, FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError)


def is_input_error(exc: BaseException) -> bool:
    """Whether an exception reports bad input (one line, exit 2) rather than a bug (traceback).

    Parameters
    ----------
    exc : BaseException
        The exception a command raised.

    Returns
    -------
    bool
        True for :data:`INPUT_ERRORS` and for an ``OSError`` about a named file
        (``exc.filename`` set: a full disk, a file in use); False otherwise, a plain
        ``ValueError`` from numpy included.

    Examples
    --------
    >>> is_input_error(InputError("--grid: must be at least 2")), is_input_error(ValueError("shapes differ"))
    (True, False)
    >>> is_input_error(OSError(28, "No space left on device", "out/mesh.ply"))
    True
    """
    return isinstance(exc, INPUT_ERRORS) or (isinstance(exc, OSError) and exc.filename is not None)


class _Parser(argparse.ArgumentParser):
    """Argument parser whose usage errors are one line and exit code 2."""

    def error(self, message: str) -> None:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Build the full ``workbench`` argument parser.

    Parameters
    ----------
    only : str, optional
        A group of :data:`GROUPS` whose commands alone are registered (the other
        groups and the top-level commands keep their names and help, without
        sub-commands): :func:`main` parses one group's command line without
        importing every other command module. Default: every command.

    Returns
    -------
    argparse.ArgumentParser
        Parser with one sub-parser per group and per top-level command.

    Examples
    --------
    >>> args = build_parser().parse_args(["surfaces", "info", "part.npz"])
    >>> args.command, args.subcommand, args.file
    ('surfaces', 'info', 'part.npz')
    """
    parser = _Parser(
        prog="workbench",
        description="Surface-reconstruction workbench: photometric stereo and CT contour "
        "stacks converge on one Coons/Bezier surface model.",
    )
    parser.add_argument("--version", action=_Version, help="show program's version number and exit")
    top = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (help_text, modules) in GROUPS.items():
        group = top.add_parser(name, help=help_text, description=help_text)
        sub = group.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", parser_class=_Parser)
        group.set_defaults(func=_group_help(group))
        if only is not None and name != only:
            continue
        for module_name in modules:
            importlib.import_module(module_name).register(sub)
    if only is None:
        for module_name in TOP_LEVEL:
            importlib.import_module(module_name).register(top)
    return parser


def version() -> str:
    """The installed version of the workbench (``surface-workbench`` package metadata).

    Returns
    -------
    str
        E.g. ``"0.1.0"``; ``"unknown"`` when the package is not installed (run from a bare checkout).
    """
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("surface-workbench")
    except PackageNotFoundError:
        return "unknown"


class _Version(argparse.Action):
    """``--version`` as argparse prints it, the version looked up (importlib.metadata) only when asked for."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        formatter = parser._get_formatter()
        formatter.add_text(f"{parser.prog} {version()}")
        parser._print_message(formatter.format_help(), sys.stdout)
        parser.exit()


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    text = str(message).strip().splitlines()
    print(f"workbench: warning: {text[0] if text else category.__name__}", file=sys.stderr)


def _group_help(group: argparse.ArgumentParser):
    def show(_args: argparse.Namespace) -> int:
        group.print_help()
        return 2

    return show


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``workbench`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when omitted.

    Returns
    -------
    int
        Exit code: 0 on success, 2 on bad input or usage (one line on stderr,
        ``workbench: error: ...``), 130 when interrupted.

    Raises
    ------
    Exception
        Any exception that is not bad input (:func:`is_input_error`) propagates with its
        traceback: it is a bug to report, not a message for the user.

    Examples
    --------
    >>> main(["surfaces", "info", "no_such_part.npz"])  # stderr: workbench: error: no_such_part.npz: ...
    2
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    # a group's command line needs that group's modules only (the others cost a tenth of a second to import)
    parser = build_parser(argv[0] if argv and argv[0] in GROUPS else None)
    args = parser.parse_args(argv)
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            code = func(args)
    except (InputError, OSError) as exc:
        if not is_input_error(exc):
            raise
        message = str(exc) or exc.__class__.__name__
        print(f"workbench: error: {message.splitlines()[0] if message else ''}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("workbench: interrupted", file=sys.stderr)
        return 130
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
