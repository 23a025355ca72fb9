"""Tests of ``workbench view``: headless pictures with ``--png``, and the message without a display."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest

from surfaces.io import write_mesh
from tests.surfaces.test_boolean import box, icosphere
from workbench.cli import main
from workbench.commands.view import has_display


@pytest.fixture(scope="module")
def two_files(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("view")
    write_mesh(icosphere(1.0, (0, 0, 0), 2), tmp / "ball.ply")
    write_mesh(box((2.0, -0.5, -0.5), (3.0, 0.5, 0.5)), tmp / "box.obj")
    return tmp / "ball.ply", tmp / "box.obj"


def test_png_of_several_files_in_palette_colours(two_files, tmp_path, capsys):
    out = tmp_path / "scene.png"
    assert main(["view", *map(str, two_files), "--png", str(out), "--size", "80x40", "--views", "front"]) == 0
    img = cv2.imread(str(out))[..., ::-1]
    assert img.shape == (40, 80, 3)
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["files"] == [str(f) for f in two_files] and summary["out"] == str(out)
    # the sphere (left) is grey-blue, the box (right) orange: the right half is redder than the left
    left, right = img[:, :40].reshape(-1, 3).astype(float), img[:, 40:].reshape(-1, 3).astype(float)
    assert (right[:, 0] - right[:, 2]).max() > 40 > (left[:, 0] - left[:, 2]).max()
    assert f"wrote {out}" in capsys.readouterr().out


def test_colour_options_need_one_file(two_files, tmp_path, capsys):
    assert main(["view", *map(str, two_files), "--png", str(tmp_path / "x.png"), "--colour", "height"]) == 2
    assert "render one file at a time" in capsys.readouterr().err


def test_without_display_points_to_png(two_files, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert not has_display()
    assert main(["view", str(two_files[0])]) == 1
    assert "--png OUT.png" in capsys.readouterr().out
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    assert has_display()


@pytest.mark.parametrize("server", ["silent", "none"])
def test_unreachable_display_falls_back_to_png(two_files, monkeypatch, capsys, server):
    """DISPLAY set but hanging (a listener that never answers) or refusing: a note and a PNG, no hang."""
    import socket
    import time

    from workbench.commands import view

    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(view, "PROBE_TIMEOUT_S", 1.5)
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    port = listener.getsockname()[1]
    if server == "silent":
        listener.listen()
    else:
        listener.close()
    monkeypatch.setenv("DISPLAY", f"127.0.0.1:{port - 6000}")
    start = time.monotonic()
    try:
        assert main(["view", str(two_files[0])]) == 0
    finally:
        listener.close()
    assert time.monotonic() - start < 30
    png = f"{two_files[0].stem}_view.png"
    err = capsys.readouterr().err.splitlines()
    assert [line for line in err if "note" in line] == [
        f"workbench: note: display 127.0.0.1:{port - 6000} "
        + ("did not answer within 1.5 s" if server == "silent" else "cannot be opened")
        + f"; rendering {png} headless instead (--png)"]
    assert (Path.cwd() / png).is_file() and (Path.cwd() / png).with_suffix(".json").is_file()
