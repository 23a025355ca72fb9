"""workbench.studies.uncertainty: the budget of a result folder and its chart."""

import cv2
import pytest

from datasets_synthetic.render import make_triad_folder
from workbench.runs.photometric import reconstruct_to_folder
from workbench.studies.uncertainty import coverage_interval, coverage_study, uncertainty_budget


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    base = tmp_path_factory.mktemp("budget")
    make_triad_folder(base / "in", scene="scratch", size=96, noise=0.002, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.05, seed=3)
    reconstruct_to_folder(base / "in", base / "out", uncertainty={"noise_sigma": 0.002, "light_tolerance_deg": 0.5})
    return base / "out"


def test_budget_values_and_chart(result, tmp_path):
    out = uncertainty_budget(result, tmp_path / "budget.png")
    first = out["defects"][0]
    assert first["text"]["max_depth_mm"].endswith("mm (k = 2)") and " ± " in first["text"]["max_depth_mm"]
    assert first["expanded_uncertainty"]["max_depth_mm"] > 0
    assert out["method"] == "linear" and out["tolerances"]["light_tolerance_deg"] == 0.5
    picture = cv2.imread(out["chart"])
    assert picture is not None and picture.shape[0] > 200 and picture.shape[1] > 600
    assert set(out["budget"]) == {"max_depth_mm", "mean_width_mm", "length_mm", "area_mm2", "volume_mm3"}


def test_budget_without_a_chart_and_bad_input(result, tmp_path):
    assert uncertainty_budget(result)["chart"] is None
    with pytest.raises(ValueError, match="defect"):
        uncertainty_budget(result, tmp_path / "b.png", defect=99)
    with pytest.raises(FileNotFoundError, match="defects.json not found"):
        uncertainty_budget(tmp_path)


def test_coverage_study_reports_every_figure():
    out = coverage_study(2, "linear", size=96, pixels_per_trial=5, seed=1, length_mm=3.0)
    assert out["trials"] == 2 and out["missed"] == 0
    for key in ("max_depth_mm", "mean_width_mm", "length_mm", "area_mm2", "volume_mm3", "height"):
        assert 0.0 <= out[key]["coverage"] <= 1.0 and out[key]["mean_U"] > 0
    assert out["height"]["samples"] == 10
    with pytest.raises(ValueError, match="n_trials"):
        coverage_study(0)


def test_coverage_interval_is_the_wilson_interval():
    # closed forms: 0 of n gives [0, z^2 / (n + z^2)]; p = 1/2 is symmetric about 1/2
    z2 = 1.959963984540054**2
    assert coverage_interval(0, 10) == pytest.approx((0.0, z2 / (10 + z2)))
    low, high = coverage_interval(100, 200)
    assert low + high == pytest.approx(1.0)
    # 200 trials at 95 %: the band the 93-97 % target is judged against
    assert coverage_interval(190, 200) == pytest.approx((0.9104, 0.9726), abs=5e-4)
    assert coverage_interval(50, 50)[1] == 1.0
    with pytest.raises(ValueError, match="hits"):
        coverage_interval(11, 10)
    with pytest.raises(ValueError, match="confidence"):
        coverage_interval(1, 10, confidence=1.0)


def test_coverage_study_states_the_interval_of_each_figure():
    out = coverage_study(3, "linear", size=96, pixels_per_trial=4, seed=2, length_mm=3.0)
    for key in ("max_depth_mm", "length_mm", "height"):
        low, high = out[key]["coverage_interval"]
        assert 0.0 <= low <= out[key]["coverage"] <= high <= 1.0
        # three trials cannot rule out the 93-97 % target
        assert out[key]["missed_target"] is False
