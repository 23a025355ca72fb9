"""Output folders of the synthetic-data writers."""

from __future__ import annotations

import pytest

from datasets_synthetic.io import ensure_dir


def test_ensure_dir_creates_parents_and_keeps_existing(tmp_path):
    out = ensure_dir(tmp_path / "a" / "b")
    assert out.is_dir() and out == tmp_path / "a" / "b"
    (out / "keep.txt").write_text("x")
    assert ensure_dir(str(out)) == out and (out / "keep.txt").read_text() == "x"


def test_ensure_dir_refuses_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="folder: .* exists and is not a folder"):
        ensure_dir(tmp_path / "f", name="folder")
