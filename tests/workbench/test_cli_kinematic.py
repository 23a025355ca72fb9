"""Command-line tests of ``workbench surfaces sweep`` and ``workbench surfaces helix``."""

from __future__ import annotations

import json
import math

import numpy as np

import pytest

from surfaces.io import load_patches, read_mesh
from workbench.cli import main


def _write(path, obj):
    path.write_text(json.dumps(obj))
    return str(path)


def test_sweep_cylinder_summary_matches_closed_form(tmp_path, capsys):
    g = _write(tmp_path / "g.json", {"type": "circle", "radius": 0.5})
    d = _write(tmp_path / "d.json", {"type": "line", "start": [0, 0, 0], "end": [0, 0, 2]})
    out = tmp_path / "cyl.ply"
    code = main(["surfaces", "sweep", "--generatrix", g, "--directrix", d, "--samples-v", "6",
                 "--mesh-samples", "3", "--out", str(out)])
    assert code == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["area"] == pytest.approx(2 * math.pi * 0.5 * 2, rel=1e-5)
    assert summary["volume"] == pytest.approx(math.pi * 0.25 * 2, rel=1e-5)
    assert summary["frame"] == "rmf" and summary["closed_u"] and not summary["closed_v"]
    mesh = read_mesh(out)
    assert mesh.n_triangles == summary["n_triangles"]
    shape = (summary["patch_rows"], summary["patch_cols"])
    assert load_patches(out.with_suffix(".npz")).shape == shape
    printed = capsys.readouterr().out
    assert f"area {summary['area']:.6g}" in printed and f"volume {summary['volume']:.6g}" in printed


def test_sweep_with_bspline_directrix_scale_twist(tmp_path):
    g = _write(tmp_path / "g.json", {"points": [[0.3, 0], [0, 0.2], [-0.3, 0], [0, -0.2]],
                                     "closed": True})
    d = _write(tmp_path / "d.json", {"points": [[0, 0, 0], [1, 0, 0.5], [2, 1, 1], [3, 1, 2]]})
    summary_path = tmp_path / "custom.json"
    code = main(["surfaces", "sweep", "--generatrix", g, "--directrix", d, "--frame", "fixed",
                 "--scale", "1", "0.5", "--twist", "90", "--samples-u", "16", "--samples-v", "16",
                 "--mesh-samples", "2", "--out", str(tmp_path / "s.obj"),
                 "--summary", str(summary_path)])
    assert code == 0
    summary = json.loads(summary_path.read_text())
    assert summary["scale"] == [1.0, 0.5] and summary["twist_deg"] == 90.0
    assert summary["volume"] > 0 and summary["area"] > 0
    assert (tmp_path / "s.obj").is_file()


@pytest.mark.parametrize("profile", ["circle", "thread"])
def test_helix_profiles(tmp_path, profile):
    out = tmp_path / f"{profile}.ply"
    code = main(["surfaces", "helix", "--radius", "2", "--pitch", "1", "--turns", "1.5",
                 "--profile", profile, "--samples-u", "16", "--mesh-samples", "2",
                 "--out", str(out)])
    assert code == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    if profile == "circle":
        assert summary["area"] == pytest.approx(summary["closed_form_area"], rel=1e-3)
        assert summary["volume"] == pytest.approx(summary["closed_form_volume"], rel=1e-3)
    else:
        assert summary["volume"] is None and summary["area"] > 0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["surfaces", "helix", "--radius", "2", "--pitch", "0.2", "--turns", "1",
          "--wire-radius", "0.3", "--out", "{tmp}/x.ply"], "overlap"),
        (["surfaces", "helix", "--radius", "2", "--pitch", "1", "--turns", "1",
          "--out", "{tmp}/x.xyz"], "unsupported mesh format"),
        (["surfaces", "sweep", "--generatrix", "{tmp}/missing.json", "--directrix",
          "{tmp}/missing.json", "--out", "{tmp}/x.ply"], "does not exist"),
    ],
)
def test_bad_input_exits_2(tmp_path, capsys, argv, message):
    code = main([a.format(tmp=tmp_path) for a in argv])
    assert code == 2
    assert message in capsys.readouterr().err


def test_frenet_on_line_is_a_clear_error(tmp_path, capsys):
    g = _write(tmp_path / "g.json", {"type": "circle", "radius": 0.5})
    d = _write(tmp_path / "d.json", {"type": "line", "start": [0, 0, 0], "end": [0, 0, 2]})
    code = main(["surfaces", "sweep", "--generatrix", g, "--directrix", d, "--frame", "frenet",
                 "--out", str(tmp_path / "x.ply")])
    assert code == 2
    assert "Frenet frame is undefined" in capsys.readouterr().err


def test_coil_spring_with_caps_is_a_closed_solid_of_the_closed_form_volume(tmp_path, capsys):
    """Tube theorem: V = pi a^2 L for the wire; the capped mesh is watertight and encloses it."""
    out = tmp_path / "spring.ply"
    assert main(["surfaces", "helix", "--radius", "2", "--pitch", "1", "--turns", "2", "--wire-radius", "0.2",
                 "--samples-u", "24", "--mesh-samples", "4", "--caps", "--out", str(out)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["caps"] == "flat" and summary["watertight"]
    assert summary["mesh_volume"] == pytest.approx(summary["closed_form_volume"], rel=5e-3)
    assert summary["cap_area"] == pytest.approx(2 * np.pi * 0.2**2, rel=5e-3)
    mesh = read_mesh(out)
    assert mesh.is_watertight() and mesh.is_oriented()
    assert mesh.signed_volume() == pytest.approx(summary["mesh_volume"], rel=1e-4)
    assert "closed by flat caps" in capsys.readouterr().out
    # without --caps the tube stays open
    assert main(["surfaces", "helix", "--radius", "2", "--pitch", "1", "--turns", "2", "--wire-radius", "0.2",
                 "--samples-u", "24", "--mesh-samples", "4", "--out", str(out)]) == 0
    assert not json.loads(out.with_suffix(".json").read_text())["watertight"]


def test_sweep_with_caps_is_a_closed_cylinder(tmp_path):
    g = _write(tmp_path / "g.json", {"type": "circle", "radius": 0.5})
    d = _write(tmp_path / "d.json", {"type": "line", "start": [0, 0, 0], "end": [0, 0, 2]})
    out = tmp_path / "c.stl"
    assert main(["surfaces", "sweep", "--generatrix", g, "--directrix", d, "--caps", "--out", str(out)]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["watertight"] and summary["mesh_volume"] == pytest.approx(np.pi * 0.25 * 2, rel=5e-3)


def test_caps_on_an_open_cross_section_is_a_clear_error(tmp_path, capsys):
    """An open generatrix of a sweep is refused (the thread's own profile is closed, see below)."""
    g = _write(tmp_path / "g.json", {"type": "line", "start": [0.2, 0.0], "end": [0.5, 0.0]})
    d = _write(tmp_path / "d.json", {"type": "line", "start": [0, 0, 0], "end": [0, 0, 2]})
    out = tmp_path / "t.ply"
    assert main(["surfaces", "sweep", "--generatrix", g, "--directrix", d, "--caps", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--caps: flat caps close a tube" in err and "cross-section (generatrix) is open" in err
    assert not out.exists()


@pytest.mark.parametrize("radius, pitch, turns, depth", [(2.0, 1.0, 1.0, None), (5.0, 2.0, 3.0, 0.8)])
def test_thread_with_caps_is_its_ridge_closed_along_the_root(tmp_path, capsys, radius, pitch, turns, depth):
    """The open thread profile is closed along its root chord; the capped ridge has the closed-form volume
    ``pi n P ((r0 + h/2)^2 + h^2/8 - r0^2)`` (screw motion keeps volume: 2 pi n times integral r dr dz)."""
    out = tmp_path / "t.ply"
    argv = ["surfaces", "helix", "--radius", str(radius), "--pitch", str(pitch), "--turns", str(turns),
            "--profile", "thread", "--caps", "--out", str(out)]
    assert main(argv + (["--depth", str(depth)] if depth else [])) == 0
    assert "closed along its root chord" in capsys.readouterr().out
    summary = json.loads(out.with_suffix(".json").read_text())
    h = depth if depth else 0.3 * pitch
    r0 = radius - h
    exact = np.pi * turns * pitch * ((r0 + h / 2) ** 2 + h * h / 8 - r0**2)
    assert summary["closed_form_volume"] == pytest.approx(exact, rel=1e-12)
    assert summary["caps"] == "flat" and summary["watertight"] and "root chord" in summary["profile_closed"]
    assert summary["mesh_volume"] == pytest.approx(exact, rel=5e-3)
    # the caps are the closed profile's area, integral (r - r0) dz = P h / 2, at each end
    assert summary["cap_area"] == pytest.approx(2 * pitch * h / 2, rel=1e-2)
    mesh = read_mesh(out)
    assert mesh.is_watertight() and mesh.is_oriented()
