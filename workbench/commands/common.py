"""Helpers every sub-command module shares: adding a command, reading inputs, checking and writing outputs.

Each helper raises an :class:`~surfaces.validate.InputError` or a
``FileNotFoundError`` that names the option or file and what is wrong;
:func:`workbench.cli.main` prints it as one line and exits with code 2 (any
other exception is a bug and keeps its traceback).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from surfaces.io import MESH_FORMATS, load_patches, read_mesh, write_json
from surfaces.validate import InputError

#: file suffix of a patch model (:func:`surfaces.io.save_patches`); every other model file is a mesh
PATCH_SUFFIX = ".npz"


def add_command(
    sub: argparse._SubParsersAction,
    name: str,
    func: Callable[[argparse.Namespace], int | None],
    help: str,
    description: str | None = None,
    **kwargs,
) -> argparse.ArgumentParser:
    """Add one sub-command to a group and make ``func`` its action.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The group's sub-parser collection (what ``register`` receives).
    name : str
        Command name, e.g. ``"coons"``.
    func : callable
        ``func(args) -> exit code or None``, run by :func:`workbench.cli.main`.
    help : str
        One line for the group's command list.
    description : str, optional
        Text of the command's own ``--help`` (default: ``help``).
    **kwargs
        More :meth:`argparse._SubParsersAction.add_parser` arguments (``epilog``, ...).

    Returns
    -------
    argparse.ArgumentParser
        The command's parser, to add its options to.

    Examples
    --------
    >>> import argparse
    >>> sub = argparse.ArgumentParser(prog="workbench").add_subparsers()
    >>> p = add_command(sub, "hello", lambda args: print(f"hello {args.who}"), help="greet")
    >>> _ = p.add_argument("who")
    >>> args = p.parse_args(["world"])
    >>> args.func(args)
    hello world
    """
    parser = sub.add_parser(name, help=help, description=description or help, **kwargs)
    parser.set_defaults(func=func)
    return parser


def read_model(path: str | os.PathLike):
    """Read a patch model (``.npz``) or a triangle mesh (``.ply``, ``.obj``, ``.stl``).

    Parameters
    ----------
    path : path-like
        Input file; its suffix says which.

    Returns
    -------
    BezierPatches or TriangleMesh
        The model as stored.

    Raises
    ------
    FileNotFoundError
        When the file does not exist (the message names it).
    InputError
        On an unsupported suffix or an unreadable file.
    """
    p = Path(path)
    if p.suffix.lower() == PATCH_SUFFIX:
        return load_patches(p)
    return read_mesh(p)


def load_npy(path: str | os.PathLike, name: str) -> np.ndarray:
    """Load a ``.npy`` array given on the command line (no pickles).

    Parameters
    ----------
    path : path-like
        The file.
    name : str
        The argument or option it came from (``"grid"``, ``"--pu"``), for messages.

    Returns
    -------
    numpy.ndarray
        The array as stored.

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    InputError
        When it is not a readable ``.npy`` file.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: {p} does not exist")
    try:
        return np.load(p, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise InputError(f"{name}: {p} is not a readable .npy file ({exc})") from None


def npy_shape(path: str | os.PathLike, name: str) -> tuple[int, ...]:
    """Shape of a ``.npy`` array given on the command line, read from its header (no data loaded).

    Parameters
    ----------
    path : path-like
        The file.
    name : str
        The argument or option it came from, for messages.

    Returns
    -------
    tuple of int

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    InputError
        When it is not a readable ``.npy`` file of numbers.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: {p} does not exist")
    try:
        array = np.load(p, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise InputError(f"{name}: {p} is not a readable .npy file ({exc})") from None
    if not isinstance(array, np.ndarray) or not np.issubdtype(array.dtype, np.number):
        raise InputError(f"{name}: {p} does not hold an array of numbers")
    return tuple(array.shape)


#: ``--max-memory`` suffixes
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def machine_memory() -> int:
    """Physical memory of this machine in bytes (0 when the system does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 0


def parse_size(text: str, name: str) -> int:
    """Parse a memory size such as ``"8G"``, ``"512M"``, ``"1.5GB"`` or ``"100000"`` (bytes).

    Parameters
    ----------
    text : str
        A positive number with an optional binary suffix K, M, G or T (``B`` allowed after it).
    name : str
        The option it came from, for messages.

    Returns
    -------
    int
        Bytes.

    Raises
    ------
    InputError
        When ``text`` is not a positive size.

    Examples
    --------
    >>> parse_size("2G", "--max-memory"), parse_size("512mb", "--max-memory")
    (2147483648, 536870912)
    >>> parse_size("lots", "--max-memory")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: --max-memory: expected a size such as 8G or 512M, got 'lots'
    """
    clean = text.strip().upper().removesuffix("B").replace("I", "")
    unit = clean[-1:] if clean[-1:] in _UNITS and clean[-1:] else ""
    try:
        value = float(clean[: len(clean) - len(unit)]) * _UNITS[unit]
    except ValueError:
        value = float("nan")
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{name}: expected a size such as 8G or 512M, got {text!r}")
    return int(value)


def format_size(n_bytes: float) -> str:
    """Bytes as a short text with a binary unit.

    Examples
    --------
    >>> format_size(10.3 * 2**30), format_size(836e6), format_size(512)
    ('10.3 GB', '797 MB', '512 B')
    """
    for unit, factor in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if n_bytes >= factor:
            value = n_bytes / factor
            return f"{value:.3g} {unit}" if value < 100 else f"{value:.0f} {unit}"
    return f"{int(n_bytes)} B"


def mesh_out(path: str | os.PathLike, name: str = "--out") -> Path:
    """Check an output mesh name before any work is done: a known format, in an existing folder.

    Parameters
    ----------
    path : path-like
        Mesh file to write later (:data:`surfaces.io.MESH_FORMATS`).
    name : str
        The option it came from, for messages.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        On a suffix that is not a mesh format.
    FileNotFoundError
        When the folder does not exist.

    Examples
    --------
    >>> mesh_out("surface.ply")
    PosixPath('surface.ply')
    >>> mesh_out("surface.vtk")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: --out: unsupported mesh format '.vtk'; use .ply, .obj or .stl
    """
    out = Path(path)
    if out.suffix.lower() not in MESH_FORMATS:
        formats = ", ".join(MESH_FORMATS[:-1]) + f" or {MESH_FORMATS[-1]}"
        raise InputError(f"{name}: unsupported mesh format {out.suffix!r}; use {formats}")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{name}: folder {out.parent} does not exist")
    return out


def parse_vector(text: str, name: str) -> np.ndarray:
    """Parse ``"x,y,z"`` into a point or direction.

    Parameters
    ----------
    text : str
        Three comma-separated finite numbers.
    name : str
        The option it came from, for messages.

    Returns
    -------
    (3,) float64 array

    Raises
    ------
    InputError
        When ``text`` is not three finite numbers.

    Examples
    --------
    >>> parse_vector("0, 0.5,-2", "--eye")
    array([ 0. ,  0.5, -2. ])
    >>> parse_vector("1,2", "--up")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: --up: expected three finite numbers 'x,y,z', got '1,2'
    """
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"{name}: expected three numbers 'x,y,z', got {text!r}") from None
    if len(values) != 3 or not np.all(np.isfinite(values)):
        raise InputError(f"{name}: expected three finite numbers 'x,y,z', got {text!r}")
    return np.asarray(values)


def write_summary(path: str | os.PathLike, summary: dict) -> Path:
    """Write a command's summary as indented JSON, atomically, creating its folder.

    Parameters
    ----------
    path : path-like
        The ``.json`` file.
    summary : dict
        Every number the command prints, and more (numpy values allowed).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return write_json(out, summary)
