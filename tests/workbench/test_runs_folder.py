"""Tests of :mod:`workbench.runs.folder`: a result folder appears whole or not at all."""

from __future__ import annotations

import json
import os
import socket

import pytest

from workbench.runs import folder
from workbench.runs.folder import COMPLETE_MARKER, FolderBusy, check_out_folder, hold_lock, result_folder

DEAD_PID = 2**22 + 12345


def _fill(tmp, **files):
    for name, text in files.items():
        (tmp / name).write_text(text)


def test_new_folder_appears_whole_with_its_marker(tmp_path):
    out = tmp_path / "a" / "b" / "res"
    with result_folder(out) as tmp:
        assert tmp.parent == out.parent and tmp.name.startswith(".res.tmp-")
        assert not out.exists() and (out.parent / ".res.lock").is_file()
        _fill(tmp, x="1")
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE_MARKER, "x"]
    assert json.loads((out / COMPLETE_MARKER).read_text())["pid"] == os.getpid()
    assert sorted(p.name for p in out.parent.iterdir()) == ["res"]


@pytest.mark.parametrize("exchange", [True, False])
def test_previous_result_stays_until_the_swap(tmp_path, monkeypatch, exchange):
    if not exchange:  # the two-rename path of systems without renameat2
        monkeypatch.setattr(folder, "_exchange", lambda a, b: False)
    out = tmp_path / "res"
    with result_folder(out, owned=["x", "y"]) as tmp:
        _fill(tmp, x="old", y="old")
    with result_folder(out, owned=["x", "y"]) as tmp:
        _fill(tmp, x="new")
        assert (out / "x").read_text() == "old" and (out / "y").is_file()
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE_MARKER, "x"]
    assert (out / "x").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


@pytest.mark.parametrize("error", [ValueError("bad input"), KeyboardInterrupt()])
def test_failure_leaves_the_previous_result_and_nothing_else(tmp_path, error):
    out = tmp_path / "res"
    with result_folder(out) as tmp:
        _fill(tmp, x="old")
    with pytest.raises(type(error)):
        with result_folder(out) as tmp:
            _fill(tmp, x="new", y="new")
            raise error
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE_MARKER, "x"] and (out / "x").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_failed_first_run_leaves_no_folder_and_no_parents(tmp_path):
    with pytest.raises(ValueError):
        with result_folder(tmp_path / "new" / "deeper" / "res"):
            raise ValueError("bad input")
    assert list(tmp_path.iterdir()) == []


def test_out_that_is_a_file_or_holds_other_data_is_refused(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="--out: .*f exists and is not a folder"):
        check_out_folder(tmp_path / "f", "--out")
    data = tmp_path / "data"
    data.mkdir()
    (data / "scan.png").write_text("x")
    with pytest.raises(ValueError, match="not a result of this command \\(scan.png\\)"):
        with result_folder(data, owned=["summary.json"]):
            pass
    assert (data / "scan.png").is_file() and sorted(p.name for p in tmp_path.iterdir()) == ["data", "f"]
    (data / "scan.png").unlink()
    (data / "summary.json").write_text("{}")  # an older result without marker is ours to replace
    assert check_out_folder(data, owned=["summary.json"]) == data


def test_second_writer_is_refused(tmp_path):
    out = tmp_path / "res"
    with result_folder(out) as tmp:
        with pytest.raises(FolderBusy, match=f"{out} is being written by another run \\(pid {os.getpid()}"):
            with result_folder(out):
                pass
        _fill(tmp, x="1")
    assert (out / "x").read_text() == "1"


def test_leftovers_of_a_killed_writer_are_cleaned(tmp_path):
    out = tmp_path / "res"
    (tmp_path / ".res.lock").write_text(json.dumps({"pid": DEAD_PID, "host": socket.gethostname()}))
    (tmp_path / ".res.tmp-1-abc").mkdir()
    (tmp_path / ".res.tmp-1-abc" / "half").write_text("x")
    moved = tmp_path / ".res.old-abc"  # a killed two-rename swap had moved the result aside
    moved.mkdir()
    (moved / COMPLETE_MARKER).write_text("{}")
    with result_folder(out) as tmp:
        assert (out / COMPLETE_MARKER).is_file()  # put back before the new run starts
        _fill(tmp, x="1")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_lock_of_a_live_process_on_another_host_is_respected(tmp_path):
    lock = tmp_path / "l.lock"
    lock.write_text(json.dumps({"pid": DEAD_PID, "host": "elsewhere"}))
    with pytest.raises(FolderBusy, match="busy \\(pid .* on elsewhere\\); wait for it, or delete"):
        with hold_lock(lock, "busy"):
            pass
    assert lock.exists()
