"""Output folders of the synthetic-data writers.

The files themselves are written with :mod:`surfaces.io` (atomic: a temporary
name in the destination folder, then :func:`os.replace`).
"""

from __future__ import annotations

import os
from pathlib import Path


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

    Raises
    ------
    NotADirectoryError
        When ``path`` is an existing file.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(f"{name}: {path} exists and is not a folder")
    path.mkdir(parents=True, exist_ok=True)
    return path
