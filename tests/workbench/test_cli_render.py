"""Tests of ``workbench surfaces render``: the picture, its JSON numbers and bad options."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from surfaces.io import save_patches, write_mesh
from surfaces.mesh import TriangleMesh, tessellate
from tests.surfaces.test_boolean import icosphere
from workbench.cli import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from surfaces.coons import from_grid

    tmp = tmp_path_factory.mktemp("render")
    u, v = np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5), indexing="ij")
    patches = from_grid(np.stack([u, v, 0.3 * (u**2 - v**2)], axis=-1))
    save_patches(patches, tmp / "saddle.npz")
    mesh = tessellate(patches, 4)
    write_mesh(mesh, tmp / "saddle.ply")
    write_mesh(TriangleMesh(mesh.vertices + [0.0, 0.0, 0.1], mesh.triangles), tmp / "raised.ply")
    write_mesh(icosphere(1.0, (0, 0, 0), 2), tmp / "ball.stl")
    return tmp


def _picture(path):
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None and img.dtype == np.uint8
    return img


def test_render_views_and_numbers(files, tmp_path, capsys):
    out = tmp_path / "v.png"
    argv = ["surfaces", "render", str(files / "ball.stl"), "--out", str(out), "--views", "front,top",
            "--size", "64x48", "--colour", "height"]
    assert main(argv) == 0
    img = _picture(out)
    assert img.shape[2] == 3 and img.std() > 5
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["views"] == ["front", "top"] and summary["size"] == [64, 48] and summary["colour"] == "height"
    assert summary["file"] == str(files / "ball.stl") and summary["out"] == str(out)
    assert (summary["scalar_min"], summary["scalar_max"]) == pytest.approx((-1.0, 1.0), abs=0.05)
    printed = capsys.readouterr().out
    assert f"wrote {out}" in printed and f"{summary['triangles']} triangles" in printed


@pytest.mark.parametrize(("reference", "largest"), [("saddle.ply", 0.0), ("raised.ply", 0.1)])
def test_render_deviation_from_a_reference(files, tmp_path, reference, largest):
    out = tmp_path / "d.png"
    json_path = tmp_path / "numbers" / "d.json"  # --json into a folder that does not exist yet
    argv = ["surfaces", "render", str(files / "saddle.npz"), "--out", str(out), "--size", "48x48",
            "--samples", "4", "--colour", "deviation", "--reference", str(files / reference),
            "--json", str(json_path)]
    assert main(argv) == 0
    summary = json.loads(json_path.read_text())
    assert summary["reference"] == str(files / reference)
    # the PLY stores float32 coordinates; the raised copy lies 0.1 above along z, less along the normal
    assert summary["deviation_max_abs"] == pytest.approx(largest, abs=1e-6 if largest == 0 else 0.02)
    assert summary["scalar_min"] == -summary["scalar_max"]  # symmetric: zero at the colour map's centre


def test_render_explicit_camera_and_net(files, tmp_path):
    out = tmp_path / "c.png"
    argv = ["surfaces", "render", str(files / "saddle.npz"), "--out", str(out), "--size", "40x30", "--net",
            "--eye", "3,3,3", "--target", "0,0,0", "--projection", "perspective"]
    assert main(argv) == 0
    assert _picture(out).shape[:2] == (30, 40)
    assert json.loads(out.with_suffix(".json").read_text())["views"] == ["camera"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--colour", "deviation"], "--reference"),
        (["--eye", "1,1,1"], "--eye/--target: give both"),
        (["--eye", "1,1", "--target", "0,0,0"], "--eye: expected three finite numbers"),
        (["--size", "big"], "size: expected WIDTHxHEIGHT"),
    ],
)
def test_render_bad_options_exit_2(files, tmp_path, capsys, extra, message):
    out = tmp_path / "x.png"
    assert main(["surfaces", "render", str(files / "ball.stl"), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and not out.exists()


def test_render_missing_file(tmp_path, capsys):
    assert main(["surfaces", "render", str(tmp_path / "no.npz"), "--out", str(tmp_path / "x.png")]) == 2
    assert "no.npz: no such patch file" in capsys.readouterr().err
