"""Result folders that appear whole or not at all: a lock, a temporary twin, a marker, one swap.

:func:`result_folder` is the one mechanism behind every command that writes a
folder of results (``photometric reconstruct``, ``slices reconstruct``; ``workbench
batch`` uses :func:`hold_lock` and :data:`COMPLETE_MARKER` for its jobs):

1. ``--out`` is checked (not a file; empty, a finished result, or only the files
   the command writes) and locked: ``.<name>.lock`` beside it holds the writer's
   pid and host; a second writer is refused with a :class:`FolderBusy` error
   (a ``ValueError``), a lock of a dead process on this host is taken over.
2. Temporary folders of dead writers (``.<name>.tmp-*``, ``.<name>.old-*``) are
   removed; a previous result that a killed writer had moved aside is put back.
3. The caller fills ``.<name>.tmp-<pid>-<random>``; on success the marker
   ``_COMPLETE`` is written last and the folder is swapped in whole (one
   ``renameat2(RENAME_EXCHANGE)`` on Linux, else two renames), so ``--out`` holds
   the previous complete result until the swap and the new one after it.
4. On any exception, Ctrl-C included, the temporary folder is removed and
   ``--out`` is left as it was; after SIGKILL the next writer cleans up (step 2).

Parent folders that the lock needed are removed again when the run fails, so a
failed run leaves nothing behind.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import json
import os
import shutil
import socket
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from surfaces.validate import InputError

__all__ = ["COMPLETE_MARKER", "FolderBusy", "check_out_folder", "hold_lock", "is_complete", "result_folder"]

#: written last into a finished result folder (a batch job's marker also carries its row)
COMPLETE_MARKER = "_COMPLETE"


class FolderBusy(InputError):
    """Another live process holds the lock of a result folder (bad input: the folder given is in use; exit 2)."""


def check_out_folder(out: str | os.PathLike, name: str = "out_dir", owned: Iterable[str] | None = None) -> Path:
    """Check that a result folder may be (re)written, before any work is done.

    Parameters
    ----------
    out : path-like
        The result folder (need not exist).
    name : str
        The argument or option it came from, for messages.
    owned : iterable of str, optional
        Names the writer puts into the folder. An existing folder is accepted when
        it is empty, holds :data:`COMPLETE_MARKER`, or holds only these names (an
        older result); anything else is somebody's data and is refused, since
        the swap replaces the whole folder. ``None`` accepts any existing folder.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    NotADirectoryError
        When ``out`` is an existing file.
    ValueError
        When ``out`` holds files the writer did not write.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"{name}: {out} exists and is not a folder")
    if out.is_dir() and owned is not None and not (out / COMPLETE_MARKER).exists():
        foreign = sorted(p.name for p in out.iterdir() if p.name not in set(owned) | {COMPLETE_MARKER})
        if foreign:
            raise InputError(
                f"{name}: {out} holds files that are not a result of this command ({', '.join(foreign[:3])}"
                f"{', ...' if len(foreign) > 3 else ''}); give a new or empty folder")
    return out


def is_complete(folder: str | os.PathLike) -> bool:
    """Return whether ``folder`` holds the :data:`COMPLETE_MARKER` (a finished result).

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    bool
    """
    return (Path(folder) / COMPLETE_MARKER).is_file()


@contextmanager
def hold_lock(path: str | os.PathLike, busy: str) -> Iterator[None]:
    """Hold an exclusive lock file for the duration of the block.

    The file is created exclusively and holds ``{"pid", "host", "started_utc"}``.
    A lock of a process on this host that is no longer alive is taken over.

    Parameters
    ----------
    path : path-like
        The lock file; its folder must exist.
    busy : str
        Start of the refusal message; `` (pid P on HOST)`` and the way out are appended.

    Raises
    ------
    FolderBusy
        When a live process holds the lock.
    """
    path = Path(path)
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started_utc": _now_utc()}
    fd = _create_exclusive(path)
    if fd is None:
        try:
            holder = json.loads(path.read_text())
        except (ValueError, OSError):
            holder = {}
        if holder.get("host") == me["host"] and not _pid_alive(int(holder.get("pid", -1))):
            path.unlink(missing_ok=True)  # that run died; take over
            fd = _create_exclusive(path)
        if fd is None:
            raise FolderBusy(
                f"{busy} (pid {holder.get('pid')} on {holder.get('host')}); wait for it, or delete {path} "
                "if that run is dead")
    with os.fdopen(fd, "w") as fh:
        json.dump(me, fh)
    try:
        yield
    finally:
        path.unlink(missing_ok=True)


@contextmanager
def result_folder(
    out: str | os.PathLike, *, name: str = "out_dir", owned: Iterable[str] | None = None
) -> Iterator[Path]:
    """Yield an empty temporary folder beside ``out``; swap it in whole as ``out`` on success.

    Parameters
    ----------
    out : path-like
        The result folder. Missing parent folders are created (and removed again
        when the block fails).
    name : str
        The argument or option ``out`` came from, for messages.
    owned : iterable of str, optional
        Names the writer puts into the folder (see :func:`check_out_folder`).

    Yields
    ------
    pathlib.Path
        The temporary folder to fill. :data:`COMPLETE_MARKER` is added after the block.

    Raises
    ------
    NotADirectoryError, ValueError
        From :func:`check_out_folder`.
    FolderBusy
        When another live process writes ``out``.

    Examples
    --------
    >>> import tempfile
    >>> base = Path(tempfile.mkdtemp())
    >>> with result_folder(base / "res") as tmp:
    ...     _ = (tmp / "a.txt").write_text("1")
    >>> sorted(p.name for p in (base / "res").iterdir()), sorted(p.name for p in base.iterdir())
    (['_COMPLETE', 'a.txt'], ['res'])
    """
    out = check_out_folder(Path(out).absolute(), name, owned)
    created = _make_parents(out.parent)
    try:
        with hold_lock(out.parent / f".{out.name}.lock", f"{name}: {out} is being written by another run"):
            _clean_leftovers(out)
            tmp = out.parent / f".{out.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
            tmp.mkdir()
            try:
                yield tmp
                marker = {"pid": os.getpid(), "host": socket.gethostname(), "finished_utc": _now_utc()}
                (tmp / COMPLETE_MARKER).write_text(json.dumps(marker) + "\n")
                _swap_in(tmp, out)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        for folder in created:
            try:
                folder.rmdir()
            except OSError:
                break
        raise


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; return the created ones, deepest first."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for path in reversed(missing):
        try:
            path.mkdir()
        except FileExistsError:
            pass
    return missing


def _clean_leftovers(out: Path) -> None:
    """Remove what dead writers of ``out`` left; put back a result they had moved aside (we hold the lock)."""
    parent = out.parent
    for old in sorted(parent.glob(f".{out.name}.old-*")):
        if not out.exists() and is_complete(old):
            os.rename(old, out)
        else:
            shutil.rmtree(old, ignore_errors=True)
    for tmp in parent.glob(f".{out.name}.tmp-*"):
        shutil.rmtree(tmp, ignore_errors=True)


def _swap_in(tmp: Path, out: Path) -> None:
    """Make ``tmp`` be ``out``: exchanged in one step when the system allows, else out aside, tmp in."""
    if not out.exists():
        os.rename(tmp, out)
        return
    if _exchange(tmp, out):
        shutil.rmtree(tmp, ignore_errors=True)  # now the previous result
        return
    old = out.parent / f".{out.name}.old-{uuid.uuid4().hex[:8]}"
    os.rename(out, old)
    os.rename(tmp, out)
    shutil.rmtree(old, ignore_errors=True)


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically with Linux ``renameat2(RENAME_EXCHANGE)``; False where unsupported."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    return renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0


def _create_exclusive(path: Path) -> int | None:
    try:
        return os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    except FileExistsError:
        return None


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _now_utc() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")
