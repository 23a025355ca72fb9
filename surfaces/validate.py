"""One small validation helper used by every public function of the workbench.

Validate at the edge, trust inside: public functions call :func:`as_array` on
their array arguments, so bad input fails early with a ``ValueError`` that names
the argument and says what is wrong.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import numpy as np

__all__ = ["InputError", "as_array", "reading", "reads_file"]


class InputError(ValueError):
    """Bad input: an argument, option, file or record the user gave is wrong.

    Raised at the edges (readers, option and spec checks, argument validation)
    with a message that names the input and says what is wrong. The command line
    turns it into one line on stderr and exit code 2; any other exception is a
    defect and keeps its traceback. It is a ``ValueError``, so callers that catch
    ``ValueError`` still catch it.

    Examples
    --------
    >>> try:
    ...     as_array([1.0, float("nan")], "heights")
    ... except InputError as err:
    ...     print(type(err).__name__, isinstance(err, ValueError))
    InputError True
    """


@contextmanager
def reading(path: str | os.PathLike, what: str, also: tuple[type[BaseException], ...] = ()) -> Iterator[None]:
    """Report a foreign parser's complaint about a file's content as :class:`InputError` naming the file.

    The edge where a reader hands bytes to a library (``json``, ``numpy.loadtxt``,
    ``numpy.load``, pydicom, nibabel, OpenCV): their ``ValueError`` (a
    ``json.JSONDecodeError``, a ``UnicodeDecodeError``, numpy's "could not convert
    string to float") and the exception types in ``also`` mean the file is bad, so
    they become one ``InputError`` that names the file and what was expected. An
    ``InputError`` and every other exception pass unchanged.

    Parameters
    ----------
    path : path-like
        The file being read, named in the message.
    what : str
        What the file should be, e.g. ``"JSON file"``, ``"light table"``.
    also : tuple of exception types, optional
        More exception types that mean a damaged file for this reader (e.g.
        ``pydicom.errors.InvalidDicomError``, ``zipfile.BadZipFile``, ``EOFError``).

    Raises
    ------
    InputError
        ``"<path>: not a readable <what> (<the library's message>)"``.

    Examples
    --------
    >>> import json
    >>> try:
    ...     with reading("spec.json", "JSON file"):
    ...         json.loads("{not json")
    ... except InputError as err:
    ...     print(err)
    spec.json: not a readable JSON file (Expecting property name enclosed in double quotes: line 1 column 2 (char 1))
    """
    try:
        yield
    except InputError:
        raise
    except (ValueError, *also) as exc:
        detail = str(exc).strip().splitlines()
        detail = f" ({detail[0]})" if detail else f" ({type(exc).__name__})"
        raise InputError(f"{os.fspath(path)}: not a readable {what}{detail}") from exc


def reads_file(what: str, also: tuple[type[BaseException], ...] = ()) -> Callable[[Callable], Callable]:
    """Decorate a reader whose first argument is a file: its foreign errors become :class:`InputError`.

    The whole body of the reader runs inside :func:`reading` with the first
    argument as the path: a reader's job is to parse its file, so a
    ``ValueError`` raised while it runs (``json``, ``numpy``, ``float()`` on a
    field) says the file is bad.

    Parameters
    ----------
    what : str
        What the file should be (``"contour JSON file"``), named in the message.
    also : tuple of exception types, optional
        More exception types that mean a damaged file (see :func:`reading`).

    Returns
    -------
    callable
        The decorator.

    Examples
    --------
    >>> @reads_file("number file")
    ... def read_number(path):
    ...     return float("twelve")
    >>> try:
    ...     read_number("n.txt")
    ... except InputError as err:
    ...     print(err)
    n.txt: not a readable number file (could not convert string to float: 'twelve')
    """

    def decorate(func: Callable) -> Callable:
        @functools.wraps(func)
        def read(*args, **kwargs):
            path = args[0] if args else kwargs.get("path", "input")
            with reading(path, what, also):
                return func(*args, **kwargs)

        return read

    return decorate


def as_array(
    value,
    name: str,
    *,
    shape: Sequence[int | None] | None = None,
    ndim: int | Sequence[int] | None = None,
    dtype=np.float64,
    finite: bool = True,
    min_size: int | None = None,
) -> np.ndarray:
    """Convert ``value`` to an array and check it.

    Parameters
    ----------
    value : array_like
        The input.
    name : str
        Argument name used in error messages.
    shape : sequence of int or None, optional
        Required shape; ``None`` entries match any length. A leading ``...``
        is not supported: give the full shape.
    ndim : int or sequence of int, optional
        Allowed numbers of dimensions (checked when ``shape`` is not given).
    dtype : numpy dtype, optional
        Target dtype (default float64). ``None`` keeps the input dtype.
    finite : bool, optional
        Reject NaN and infinite values (default True; only for inexact dtypes).
    min_size : int, optional
        Minimum number of elements.

    Returns
    -------
    numpy.ndarray
        The converted array (a copy only when conversion needs one).

    Raises
    ------
    ValueError
        When the value cannot be converted, or its shape, size or values are wrong.
    """
    try:
        arr = np.asarray(value, dtype=dtype) if dtype is not None else np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: cannot be read as a numeric array ({exc})") from None
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise InputError(f"{name}: expected shape {want}, got {arr.shape}")
    elif ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if arr.ndim not in allowed:
            raise InputError(f"{name}: expected {' or '.join(map(str, allowed))} dimensions, got shape {arr.shape}")
    if min_size is not None and arr.size < min_size:
        raise InputError(f"{name}: needs at least {min_size} values, got {arr.size}")
    # method calls and the dtype's kind: numpy's wrappers cost more than the test on the small
    # arrays that most calls see
    if finite and arr.dtype.kind in "fc" and not np.isfinite(arr).all():
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise InputError(f"{name}: contains {bad} NaN or infinite value(s)")
    return arr


def positive(value: float, name: str, *, allow_zero: bool = False) -> float:
    """Check that a scalar is finite and positive (or non-negative).

    Parameters
    ----------
    value : float
        The scalar.
    name : str
        Argument name used in error messages.
    allow_zero : bool, optional
        Accept zero.

    Returns
    -------
    float
        ``value`` as a Python float.

    Raises
    ------
    ValueError
        When the value is not finite, negative, or zero while ``allow_zero`` is False.
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise InputError(f"{name}: must be a finite {kind} number, got {value!r}")
    return x


def drop_closing_repeat(points: np.ndarray, axis: int = 0) -> np.ndarray:
    """Data of a closed direction without a last row that repeats the first.

    A closed (periodic) direction is given without repeating its first point,
    row or column at the end; a repeated one (equal within ``1e-12`` of the
    largest coordinate, at least 1) is dropped here, so that both spellings work.

    Parameters
    ----------
    points : array
        Data points, the closed direction along ``axis``.
    axis : int
        The closed direction.

    Returns
    -------
    array
        ``points``, or a view without its last entry along ``axis``.

    Examples
    --------
    >>> drop_closing_repeat(np.array([[0.0, 0], [1, 0], [0, 1], [0, 0]])).shape
    (3, 2)
    """
    n = points.shape[axis]
    if n <= 2:
        return points
    first = np.take(points, [0], axis=axis)
    last = np.take(points, [n - 1], axis=axis)
    scale = max(float(np.max(np.abs(points))), 1.0)
    if np.max(np.abs(first - last)) <= 1e-12 * scale:
        return np.take(points, np.arange(n - 1), axis=axis)
    return points
