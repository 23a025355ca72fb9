"""photometric.pipeline: the light model is chosen from the input, and the far-field path is unchanged.

A DiLiGenT folder has no LED positions, so it is solved far-field exactly as before issue 15
(the published figures of the bear); a folder with ``light_positions.txt`` is solved near-field,
and ``light_model="directional"`` forces today's model on the same images.
"""

import pytest

from datasets_synthetic.nearfield import make_near_field_folder
from datasets_synthetic.truth import height_errors, read_truth
from photometric.pipeline import reconstruct


@pytest.mark.parametrize(
    "select,outliers,expected",
    [("triad", False, 11.735), (None, False, 9.600), (None, True, 7.736)],
    ids=["triad", "all14", "outliers"],
)
def test_diligent_bear_far_field_figures_unchanged(shared_data, select, outliers, expected):
    res = reconstruct(shared_data / "diligent_bear", select=select, outliers=outliers)
    s = res.summary
    assert s["light_model"] == "directional"
    assert s["camera"]["model"] == "orthographic"
    assert "iterations" not in s and "light_positions_mm" not in s
    assert res.xy is None
    assert s["mean_angular_error_deg"] == pytest.approx(expected, abs=0.0015)


def _errors(res, folder) -> dict:
    """Height (and point) errors against the folder's ground truth (compared outside the library)."""
    return height_errors(res.height, res.valid, read_truth(folder), xy=res.xy, anchored=res.xy is not None)


@pytest.fixture(scope="module")
def near_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("near_scratch")
    make_near_field_folder(out, "inspection_scratch", 256, lights=3, light_distance=150.0, led_mu=1.0,
                           pixel_size=60.0 / 256, shadows="attached", seed=2)
    return out


def test_folder_with_light_positions_is_solved_near_field(near_folder):
    near = reconstruct(near_folder, flat_field=False)
    s = {**near.summary, **_errors(near, near_folder)}
    assert s["light_model"] == "point" and s["converged"] is True
    assert s["camera"] == {"model": "orthographic", "pixel_size_mm": pytest.approx(60.0 / 256)}
    assert s["final_depth_change_mm"] < s["tolerance_mm"]
    assert s["iterations"] == len(s["iteration_history"]) >= 2
    assert s["anchor"]["reference_height_mm"] == 0.0
    assert s["height_rmse_mm"] < 0.01 and abs(s["height_bias_mm"]) < 0.01
    far = reconstruct(near_folder, light_model="directional")
    assert far.summary["light_model"] == "directional"
    assert _errors(far, near_folder)["height_rmse_mm"] > 50 * s["height_rmse_mm"]


def test_folder_flat_fields_are_used_by_default(near_folder):
    res = reconstruct(near_folder, led_mu=0.0)  # a wrong lobe: the flat field measures the real one
    s = {**res.summary, **_errors(res, near_folder)}
    assert s["flat_field"]["source"] == "folder"
    assert s["flat_field"]["albedo"] == pytest.approx(0.8)
    res = reconstruct(near_folder, led_mu=0.0, flat_field=False)
    wrong = {**res.summary, **_errors(res, near_folder)}
    assert wrong["flat_field"] is None
    assert s["height_rmse_mm"] < wrong["height_rmse_mm"] / 3
