"""``workbench surfaces render`` and ``workbench view`` on small meshes and patches.

Moved from tests/surfaces/test_render.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest


@pytest.fixture(scope="module")
def sphere():
    """Unit sphere at the origin as ``(vertices, triangles)``, about 20k triangles (as tests/surfaces' own)."""
    mesh = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=100)
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles)


def test_render_and_view_commands(tmp_path, sphere, capsys, monkeypatch):
    """``workbench surfaces render`` writes the PNG and its JSON; ``view`` without display says so."""
    import json

    import cv2

    from surfaces.io import write_mesh
    from surfaces.mesh import TriangleMesh
    from workbench.cli import main

    verts, tris = sphere
    write_mesh(TriangleMesh(verts, tris.astype(np.int64), None, None), tmp_path / "a.ply")
    write_mesh(TriangleMesh(1.02 * verts, tris.astype(np.int64), None, None), tmp_path / "b.ply")
    out = tmp_path / "v.png"
    code = main(["surfaces", "render", str(tmp_path / "a.ply"), "--out", str(out), "--views",
                 "front,top", "--size", "320x200", "--colour", "deviation", "--reference",
                 str(tmp_path / "b.ply")])
    assert code == 0
    img = cv2.imread(str(out))
    assert img.shape == (200, 320, 3) and img.std() > 10
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["views"] == ["front", "top"] and summary["triangles"] == len(tris)
    assert abs(summary["deviation_rms"] - 0.02) < 2e-3
    assert main(["surfaces", "render", str(tmp_path / "a.ply"), "--out", str(out),
                 "--colour", "deviation"]) == 2
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    capsys.readouterr()
    assert main(["view", str(tmp_path / "a.ply")]) == 1
    said = capsys.readouterr().out.strip().splitlines()
    assert len(said) == 1 and "--png" in said[0]
    assert main(["view", str(tmp_path / "a.ply"), str(tmp_path / "b.ply"), "--png",
                 str(tmp_path / "both.png"), "--size", "200x150"]) == 0
    assert cv2.imread(str(tmp_path / "both.png")).shape == (150, 200, 3)


def test_view_command_opens_window_with_display(tmp_path, monkeypatch):
    """With DISPLAY set, ``workbench view`` hands meshes and control nets to open3d's viewer."""
    import open3d.visualization as vis

    from surfaces.bezier import BezierPatches
    from surfaces.io import save_patches
    from workbench.cli import main

    u = np.linspace(0.0, 3.0, 4)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1)
    ctrl = np.concatenate([grid, 0.2 * np.sin(grid[..., :1] + grid[..., 1:])], axis=-1)
    save_patches(BezierPatches(ctrl[None, None]), tmp_path / "p.npz")
    shown = []
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr("workbench.commands.view.probe_display", lambda: None)  # a display that answers
    monkeypatch.setattr(vis, "draw_geometries", lambda geoms, **kw: shown.extend(geoms))
    assert main(["view", str(tmp_path / "p.npz"), "--net"]) == 0
    kinds = sorted(type(g).__name__ for g in shown)
    assert kinds == ["LineSet", "TriangleMesh"]
    mesh = next(g for g in shown if type(g).__name__ == "TriangleMesh")
    assert mesh.has_vertex_normals() and mesh.has_vertex_colors()
