"""``photometric reconstruct``'s defaults for real captures: --outliers on from 6 images, --no-outliers off."""

import json

import pytest

from workbench.cli import main


@pytest.mark.parametrize(("flag", "expected", "error"), [([], True, 7.736), (["--no-outliers"], False, 9.600),
                                                         (["--outliers"], True, 7.736)])
def test_bear_outlier_default_and_its_switch(shared_data, tmp_path, flag, expected, error):
    out = tmp_path / "bear"
    assert main(["photometric", "reconstruct", str(shared_data / "diligent_bear"), "--surface", "coons", *flag,
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outliers"] is expected
    assert summary["mean_angular_error_deg"] == pytest.approx(error, abs=0.0015)
