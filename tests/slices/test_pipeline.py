"""``slices.pipeline.reconstruct``: an input file in, a solid, its figures and summary out, nothing written."""

from __future__ import annotations

import os

import numpy as np
import pytest

from slices.options import ReadOptions, SurfaceOptions
from slices.pipeline import UNION_LIMIT, SlicesReconstruction, reconstruct
from slices.structure import reconstruct_contours
from surfaces.io import write_json
from slices.io import Contour
from tests.slices._stacks import branching_stack, half_disc, phantom_stack


def _file(path, contours):
    return write_json(path, {"units": "mm", "contours": [{"z": c.z, "points": c.points} for c in contours]})


@pytest.fixture(scope="module")
def ellipsoid(tmp_path_factory):
    _, conts, truth = phantom_stack("ellipsoid", a=12.0, b=9.0, c=10.0, n_points=40, spacing=2.0)
    return _file(tmp_path_factory.mktemp("in") / "ellipsoid.json", conts), conts, truth


def test_reconstruct_returns_everything_and_writes_nothing(ellipsoid):
    path, conts, truth = ellipsoid
    before = sorted(os.listdir(path.parent))
    result = reconstruct(path, n_rays=32, samples=2)
    assert sorted(os.listdir(path.parent)) == before
    assert isinstance(result, SlicesReconstruction)
    rec = result.reconstruction
    assert result.patches == [b.patches for b in rec.bodies] and len(result.patches) == 1
    assert result.mesh.is_watertight() and not result.union  # one body: nothing to unite
    assert result.display_mesh.n_triangles == result.mesh.n_triangles
    s = result.summary
    # default caps "trend": volume_mm3 is the whole structure's (area trend), the surface's volume beside it
    assert s["surface_volume_mm3"] == rec.volume_mm3 and s["volume_ml"] == s["volume_mm3"] / 1000
    assert s["volume_source"] == "area trend" and s["volume_caps"].startswith("caps trend: whole structure")
    # the whole ellipsoid, to its 40-point polygons' area (0.4 % under the ellipses')
    assert abs(s["volume_mm3"] / truth["volume_mm3"] - 1) < 8e-3
    assert s["volume_by_caps_mm3"]["flat"] < s["volume_mm3"] < s["volume_by_caps_mm3"]["half"] + 1e-9 * s["volume_mm3"]
    # mostly the contours' position (0.5 mm standard, 1 mm pixels assumed) over the ~1000 mm^2 side surface
    budget = s["volume_uncertainty"]["budget"]
    assert budget["contour_position"]["u_mm3"] == pytest.approx(0.5 * rec.sensitivity_mm3 / 0.5, rel=0.1)
    assert 0.1 * s["volume_mm3"] < s["volume_U_mm3"] < 0.3 * s["volume_mm3"] and s["volume_k"] == 2
    assert (s["rays"], s["caps"], s["method"], s["ray_start"], s["source"]) == (32, "trend", "blending", "auto", "json")
    assert s["n_slices"] == truth["n_planes"] and s["n_contours"] == len(conts)
    assert s["reference_bspline"] == result.reference and s["reference_bspline"]["smooth_mm"] > 0
    assert s["time_s"] >= s["surface_time_s"] > 0


def test_same_figures_as_the_contours_in_memory(ellipsoid):
    path, conts, _ = ellipsoid
    options = SurfaceOptions(caps="half", lattice_factor=2.5, correspondence="arc", samples=2)
    result = reconstruct(path, options=options, reference=False)
    rec = reconstruct_contours(conts, options=options)
    assert result.summary["volume_mm3"] == rec.volume_mm3 and result.summary["area_mm2"] == rec.area_mm2
    assert result.reconstruction.options == options and result.reference is None
    assert "reference_bspline" not in result.summary


def test_start_angle_in_radians_reported_in_degrees(ellipsoid):
    path, _, _ = ellipsoid
    s = reconstruct(path, start_angle=np.radians(2.5), samples=1, reference=False).summary
    assert s["ray_start"] == pytest.approx(2.5) and s["bodies"][0]["ray_start_deg"] == pytest.approx(2.5)


def test_union_modes(tmp_path):
    path = _file(tmp_path / "fork.json", branching_stack())
    united = reconstruct(path, surface_path="coons", samples=2, reference=False)
    assert united.union and united.summary["mesh_union"] and united.summary["n_bodies"] == 3
    apart = reconstruct(path, surface_path="coons", union="no", samples=2, reference=False)
    assert not apart.union and apart.mesh.n_triangles == apart.reconstruction.mesh.n_triangles
    assert any("concatenated, not united" in n for n in apart.summary["notes"])
    assert reconstruct(path, surface_path="coons", union=True, samples=2, reference=False).union
    assert UNION_LIMIT > united.mesh.n_triangles
    with pytest.raises(ValueError, match="union"):
        reconstruct(path, surface_path="coons", union="maybe")


def test_bad_options_fail_before_reading(tmp_path):
    missing = tmp_path / "missing.json"
    with pytest.raises(ValueError, match=r"unknown \['rays'\]"):
        reconstruct(missing, rays=32)
    with pytest.raises(ValueError, match="caps"):
        reconstruct(missing, caps="none", minus=["Heart"])
    with pytest.raises(ValueError, match="n_rays"):
        reconstruct(missing, n_rays=2)
    with pytest.raises(FileNotFoundError):
        reconstruct(missing)


def test_reading_options_reach_the_reader(tmp_path):
    z, y, x = np.indices((8, 30, 30))
    ball = ((z - 3.5) * 2.0) ** 2 + ((y - 14.5) * 0.5) ** 2 + ((x - 14.5) * 0.5) ** 2 <= 6.0**2
    path = tmp_path / "ball.npy"
    np.save(path, ball)
    with pytest.raises(ValueError, match="spacing"):
        reconstruct(path)
    result = reconstruct(path, reading=ReadOptions(spacing="2,0.5,0.5"), samples=1, reference=False)
    assert result.summary["source"] == "mask" and result.summary["spacing_mm"] == 2.0
    assert result.summary["volume_mm3"] == pytest.approx(4 / 3 * np.pi * 6.0**3, rel=0.15)


def test_the_solid_is_checked_once_and_the_summary_reports_it(ellipsoid, monkeypatch):
    """Watertight and oriented are checked once on the solid; the summary holds those answers."""
    from surfaces.mesh import TriangleMesh

    calls = []
    for name in ("is_watertight", "is_oriented"):
        real = getattr(TriangleMesh, name)
        monkeypatch.setattr(TriangleMesh, name, lambda self, _r=real, _n=name: calls.append(_n) or _r(self))
    path, _, _ = ellipsoid
    result = reconstruct(path, n_rays=32, samples=2, caps="half", reference=False)
    assert calls.count("is_watertight") == 1 and calls.count("is_oriented") == 1
    monkeypatch.undo()
    assert result.summary["mesh_watertight"] is result.mesh.is_watertight() is True
    assert result.summary["mesh_oriented"] is result.mesh.is_oriented() is True


@pytest.mark.parametrize("caps", ["flat", "half"])
def test_united_area_is_the_outer_surface_of_touching_bodies(tmp_path, caps):
    """Two half discs on one plane, sharing the wall x = 0: two bodies that touch, one cylinder united.

    With a 4 mm slab the united solid is a cylinder of radius 10 mm and height 4 mm, area
    ``2 pi r h + 2 pi r^2``; the bodies' sum also counts the shared wall (2r x h) on both sides.
    """
    r, h = 10.0, 4.0
    path = _file(tmp_path / "halves.json", [Contour(0.0, half_disc(1, r)), Contour(0.0, half_disc(-1, r))])
    result = reconstruct(path, surface_path="coons", caps=caps, spacing=h, reference=False)
    s = result.summary
    assert result.union and s["n_bodies"] == 2 and s["area_source"] == "united solid"
    cylinder = 2 * np.pi * r * h + 2 * np.pi * r**2
    assert s["area_mm2"] == result.mesh.surface_area() == pytest.approx(cylinder, rel=1e-3)
    assert s["bodies_area_mm2"] == result.reconstruction.area_mm2
    assert s["bodies_area_mm2"] == pytest.approx(cylinder + 2 * 2 * r * h, rel=3e-3)
    assert result.mesh.is_watertight() and result.mesh.is_oriented()
    # side by side, the bodies' own area stays the figure
    apart = reconstruct(path, surface_path="coons", caps=caps, spacing=h, union="no", reference=False).summary
    assert apart["area_source"] == "patches" and apart["area_mm2"] == apart["bodies_area_mm2"]


def test_reading_is_timed_apart_from_the_surface(ellipsoid, monkeypatch):
    """``surface_time_s`` starts with the contours in memory; reading is ``read_time_s``."""
    import time

    from slices import structure

    real = structure.load

    def slow_load(*args, **kwargs):
        time.sleep(0.2)
        return real(*args, **kwargs)

    monkeypatch.setattr(structure, "load", slow_load)
    path, _, _ = ellipsoid
    s = reconstruct(path, n_rays=32, samples=1, reference=False).summary
    assert s["read_time_s"] >= 0.2 and s["surface_time_s"] < s["time_s"] - 0.2
    assert s["union_time_s"] >= 0 and s["time_s"] >= s["read_time_s"] + s["surface_time_s"] + s["union_time_s"]


def test_the_stage_clocks_time_no_imports(ellipsoid):
    """In a fresh process the surface and union stages import nothing: their libraries are loaded before
    the clocks start (``surface_time_s`` of an ordinary organ is ~10 ms; SciPy's first import ~0.2 s)."""
    import ast
    import subprocess
    import sys
    from pathlib import Path

    path, _, _ = ellipsoid
    script = (
        "import sys\n"
        "import slices.pipeline as p\n"
        "seen = {}\n"
        "def spy(name, real):\n"
        "    def run(*a, **k):\n"
        "        before = set(sys.modules)\n"
        "        out = real(*a, **k)\n"
        "        seen[name] = sorted(set(sys.modules) - before)\n"
        "        return out\n"
        "    return run\n"
        "p.reconstruct_contours = spy('surface', p.reconstruct_contours)\n"
        "p.Reconstruction.solid_mesh = spy('union', p.Reconstruction.solid_mesh)\n"
        f"p.reconstruct({str(path)!r}, n_rays=32, reference=False, union='yes')\n"
        "print(seen)\n"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", script], cwd=root, capture_output=True, text=True, check=True)
    seen = ast.literal_eval(out.stdout.strip().splitlines()[-1])
    assert seen == {"surface": [], "union": []}


def test_notes_count_in_words(ellipsoid):
    """Issue 37: the notes say "1 curve point" / "N curve points", never "point(s)" or "body(ies)"."""
    path, _, _ = ellipsoid
    notes = reconstruct(path, n_rays=32, samples=2, monotone=True).summary["notes"]
    limited = [n for n in notes if n.startswith("the blend across slices was limited")]
    assert limited and " curve points where" in limited[0]
    assert not any("(s)" in n or "(ies)" in n for n in notes)
