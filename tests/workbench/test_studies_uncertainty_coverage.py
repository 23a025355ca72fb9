"""The coverage study of ``workbench.studies.uncertainty`` on rendered trials.

Moved from tests/photometric/test_uncertainty.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_coverage_of_fifty_rendered_trials():
    """The fast version of the benchmark's coverage study (200 trials there, 93-97 %)."""
    from workbench.studies.uncertainty import coverage_study

    out = coverage_study(50, "linear", seed=11)
    assert out["missed"] == 0
    for fig in ("max_depth_mm", "mean_width_mm", "length_mm", "height"):
        assert 0.84 <= out[fig]["coverage"] <= 1.0, (fig, out[fig])
    assert out["max_depth_mm"]["mean_U"] < 0.4 * 0.05
