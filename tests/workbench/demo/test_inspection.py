"""Demo section 1 (synthetic plate): defect matching, and the section on a 128-pixel plate."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.demo.inspection import defect_numbers, match_defects, section_inspection

from .test_context import parses, quick_context

TRUTH = [
    {"kind": "v_crack", "center_px": [20, 30], "depth_mm": 0.1, "width_mm": 0.4, "length_mm": 6.0,
     "area_mm2": 2.4},
    {"kind": "spherical_dent", "center_px": [80, 90], "depth_mm": 0.2, "width_mm": 3.0,
     "length_mm": 3.0, "area_mm2": 7.0},
]


def _region(row, col, depth=0.09):
    return {"center_px": [row, col], "max_depth_mm": depth, "max_width_mm": 0.5, "length_mm": 5.5,
            "area_mm2": 2.0}


def test_match_defects_takes_the_nearest_region_within_half_the_extent():
    found = [_region(82, 90, 0.19), _region(21, 33), _region(25, 30, 0.05)]
    matched = match_defects(found, TRUTH, pixel_size=0.2)
    assert [m["kind"] for m in matched] == ["v_crack", "spherical_dent"]
    assert matched[0]["measured"] is found[1]      # 3.2 px = 0.63 mm away; the other is 5 px
    assert matched[1]["measured"] is found[0]
    # the dent's half-extent is 1.5 mm = 7.5 px: a region 8 px away is not it
    assert match_defects([_region(80, 98)], TRUTH[1:], 0.2)[0]["measured"] is None
    assert match_defects([_region(80, 97)], TRUTH[1:], 0.2)[0]["measured"] is not None
    assert [m["measured"] for m in match_defects([], TRUTH, 0.2)] == [None, None]


def test_defect_numbers_pairs_true_and_measured_values():
    rows = defect_numbers(match_defects([_region(21, 33)], TRUTH, 0.2))
    assert list(rows[0]) == ["kind", "depth_true_mm", "depth_measured_mm", "width_true_mm",
                             "width_measured_mm", "length_true_mm", "length_measured_mm",
                             "area_true_mm2", "area_measured_mm2"]
    assert rows[0]["depth_true_mm"] == 0.1 and rows[0]["depth_measured_mm"] == 0.09
    assert rows[0]["width_measured_mm"] == 0.5 and rows[0]["area_measured_mm2"] == 2.0
    assert rows[1]["kind"] == "spherical_dent" and rows[1]["area_true_mm2"] == 7.0
    assert all(rows[1][k] is None for k in rows[1] if "_measured_" in k)


@pytest.fixture(scope="module")
def quick_inspection(tmp_path_factory):
    ctx = quick_context(tmp_path_factory.mktemp("inspection"))
    section_inspection(ctx)
    return ctx


def test_section_on_a_small_plate(quick_inspection):
    ctx = quick_inspection
    nums = ctx.numbers["inspection"]
    assert (nums["size_px"], nums["pixel_size_mm"]) == (128, 0.2)
    assert nums["normal_error_mean_deg"] < 2.0
    assert nums["height_rms_error_mm"] < 0.1 * nums["height_range_true_mm"]
    assert nums["bezier_patches"] > 0 and nums["mesh_triangles"] > 0
    assert {d["kind"] for d in nums["defects"]} == {"v_crack", "spherical_dent", "u_scratch"}
    assert all(d["depth_measured_mm"] is not None for d in nums["defects"])
    names = [f.file for f in ctx.report.figures]
    assert names == [f"figures/inspection-{n}.png" for n in
                     ("truth", "images", "normals", "height", "bezier", "deviation", "crack-profile", "budget")]
    assert all(parses(f.command) for f in ctx.report.figures)
    assert (ctx.out / "inspection" / "reconstruction" / "defects.json").is_file()
    assert not ctx.unavailable


def test_truth_picture_is_on_the_same_grid_as_the_reconstruction(quick_inspection):
    """The true height mesh and the pipeline's surface.ply lie on the same centred grid.

    The fitted surface is trimmed along the mask's outline, half a pixel beyond the outer
    pixel centres where the true height mesh ends (at most half a pixel).
    """
    from surfaces.io import read_mesh
    from workbench.demo.meshes import heightfield_mesh

    ctx = quick_inspection
    truth = heightfield_mesh(np.load(ctx.out / "inspection" / "triad" / "height_gt.npy"), 0.2)
    recon = read_mesh(ctx.out / "inspection" / "reconstruction" / "surface.ply")
    half = 0.5 * 0.2
    lo, hi = truth.vertices[:, :2].min(0), truth.vertices[:, :2].max(0)
    assert np.all((recon.vertices[:, :2].min(0) >= lo - half - 1e-9) & (recon.vertices[:, :2].min(0) <= lo))
    assert np.all((recon.vertices[:, :2].max(0) <= hi + half + 1e-9) & (recon.vertices[:, :2].max(0) >= hi))


def test_section_states_each_defect_with_its_expanded_uncertainty(quick_inspection):
    """The defect figures read ``value ± U unit (k = 2)``, U from the reconstruction's budget,
    and the budget chart is a real picture."""
    import json
    import re

    from workbench.studies.uncertainty import FIGURE_LABELS

    ctx = quick_inspection
    recon = ctx.out / "inspection" / "reconstruction"
    assert (recon / "uncertainty.json").is_file() and (recon / "height_u.npy").is_file()
    rows = ctx.numbers["inspection"]["uncertainty"]
    assert {r["kind"] for r in rows} == {"v_crack", "spherical_dent", "u_scratch"}
    found = {d["id"]: d for d in json.loads((recon / "defects.json").read_text())["defects"]}
    pattern = re.compile(r"^(\d+\.\d+) ± (\d+\.\d+) (mm|mm²|mm³) \(k = 2\)$")
    for r in rows:
        for fig, (_, unit) in FIGURE_LABELS.items():
            m = pattern.match(r["text"][fig])
            assert m, r["text"][fig]
            assert m.group(3) == unit
            value, U = float(m.group(1)), float(m.group(2))
            k2 = found[r["id"]]["uncertainty_k2"][fig]
            assert abs(value - found[r["id"]][fig]) <= 10 ** -len(m.group(1).split(".")[1])
            assert 0 < U and abs(U - k2) <= 0.5 * 10 ** -len(m.group(2).split(".")[1]) + 1e-12
    # the depth of each found defect is stated tighter than the depth itself (not padded)
    assert all(found[r["id"]]["uncertainty_k2"]["max_depth_mm"] < found[r["id"]]["max_depth_mm"] for r in rows)
    chart = next(f for f in ctx.report.figures if f.file.endswith("inspection-budget.png"))
    from PIL import Image

    picture = np.asarray(Image.open(ctx.out / chart.file).convert("RGB"))
    assert picture.shape[0] > 150 and picture.shape[1] > 400
    assert len(np.unique(picture.reshape(-1, 3), axis=0)) > 8  # bars in several colours, not a blank
