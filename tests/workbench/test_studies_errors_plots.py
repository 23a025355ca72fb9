"""workbench.studies.errors_plots: the figures of the accuracy study."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from photometric.lights import ring_lights
from workbench.studies.errors_analysis import analyse
from workbench.studies.errors_plots import axis_label, write_plots


@pytest.fixture(scope="module")
def report():
    return analyse(ring_lights(3, 45.0), deviation_max=2.0, grid=7, samples=200, crack=False)


@pytest.mark.slow
def test_every_figure_is_a_png(report, tmp_path):
    pictures = write_plots(report, tmp_path)
    assert set(pictures) == {"maps", "curves", "mc", "condition"}
    names = pictures["maps"] + [pictures["curves"], *pictures["mc"], pictures["condition"]]
    assert len(pictures["maps"]) == len(report["error_maps"]) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)
    for name in names:
        img = cv2.imread(str(tmp_path / name))
        assert img is not None and img.shape[0] > 200 and img.std() > 10  # drawn, not blank
    assert pictures["maps"][0] == "map_1_square_L1slant_L2slant.png"


@pytest.mark.slow
def test_surface_and_crack_figures_when_present(tmp_path):
    rows, cols = np.mgrid[0:16, 0:16]
    rep = analyse(ring_lights(3, 45.0), deviation_max=2.0, grid=7, samples=200, crack_size=40,
                  surface=0.05 * np.sin(rows / 3.0) * np.cos(cols / 4.0), pixel_size=0.1)
    pictures = write_plots(rep, tmp_path)
    assert pictures["surface"] == "surface_height_error.png" and pictures["crack"] == "crack_study.png"
    assert (tmp_path / "crack_study.png").stat().st_size > 1000


def test_axis_label():
    assert axis_label((2, "azimuth")) == "azimuth deviation of light 3 (deg)"
