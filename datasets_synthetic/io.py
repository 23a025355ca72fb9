"""Atomic file writers shared by the synthetic-data writers.

Every file is written under a temporary name in its destination folder and
moved into place with :func:`os.replace`, so a reader never sees half a file.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, then rename).

    Parameters
    ----------
    path : str or path-like
        Destination file; its folder must exist.
    data : bytes
        File content.

    Returns
    -------
    pathlib.Path
        The destination path.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"path: folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        # mkstemp creates owner-only files; data files are meant to be shared
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def write_json(path: str | os.PathLike, content: dict) -> Path:
    """Write ``content`` as indented JSON atomically; numpy scalars and arrays become lists.

    Parameters
    ----------
    path : str or path-like
        Destination file.
    content : dict
        JSON-serialisable content (numpy values allowed).

    Returns
    -------
    pathlib.Path
    """
    return atomic_write_text(path, json.dumps(_jsonable(content), indent=2) + "\n")


def save_npy(path: str | os.PathLike, array: np.ndarray) -> Path:
    """Save one array as ``.npy`` atomically.

    Parameters
    ----------
    path : str or path-like
        Destination file (``.npy``).
    array : numpy.ndarray
        The array, saved with its dtype.

    Returns
    -------
    pathlib.Path
    """
    import io

    buf = io.BytesIO()
    np.save(buf, np.asarray(array), allow_pickle=False)
    return atomic_write_bytes(path, buf.getvalue())


def ensure_dir(path: str | os.PathLike, name: str = "out_dir") -> Path:
    """Create a folder (and parents) when missing; refuse an existing file of that name.

    Parameters
    ----------
    path : str or path-like
        The folder.
    name : str
        Argument name used in error messages.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(f"{name}: {path} exists and is not a folder")
    path.mkdir(parents=True, exist_ok=True)
    return path
