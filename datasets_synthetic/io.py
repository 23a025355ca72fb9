"""File helpers of the synthetic-data writers.

Every file is written under a temporary name in its destination folder and
moved into place with :func:`os.replace`, so a reader never sees half a file.
"""

from __future__ import annotations

import os
from pathlib import Path


from surfaces.io import atomic_write_bytes, atomic_write_text, save_npy, write_json

__all__ = ["atomic_write_bytes", "atomic_write_text", "write_json", "save_npy", "ensure_dir"]


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
