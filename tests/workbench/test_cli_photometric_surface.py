"""``workbench photometric reconstruct``: the integrator and surface options reach the library and summary.json.

Moved from tests/photometric/test_integrate.py and test_surface_step.py: the library's tests do not
run the workbench.
"""

from __future__ import annotations

import json

import pytest

from datasets_synthetic.render import make_triad_folder
from workbench.cli import main


@pytest.fixture(scope="module")
def crack_folder(tmp_path_factory):
    """The crack scene of tests/photometric/test_surface_step.py."""
    out = tmp_path_factory.mktemp("crack")
    make_triad_folder(out, scene="crack", size=256, noise=0.0, shadows="none", deviate=None,
                      albedo=0.8, bit_depth=None, pixel_size=0.05, seed=0)
    return out


def test_robust_integrator_from_the_command_line(tmp_path):
    """``--integrator robust`` reaches the integrator and is stated in summary.json."""

    folder = tmp_path / "plate"
    make_triad_folder(folder, scene="plate", size=48, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    for integrator in ("lsq", "robust"):
        assert main(["photometric", "reconstruct", str(folder), "--integrator", integrator, "--surface", "coons",
                     "--out", str(tmp_path / integrator)]) == 0
    lsq, robust = (json.loads((tmp_path / i / "summary.json").read_text()) for i in ("lsq", "robust"))
    assert robust["integrator"] == "robust"
    assert robust["height_rmse_mm"] < 1.05 * lsq["height_rmse_mm"] + 1e-6


def test_cli_surface_options(crack_folder, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["photometric", "reconstruct", str(crack_folder), "--surface-tolerance", "0.01",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["surface"] == "fit" and summary["surface_tolerance_mm"] == 0.01
    assert summary["surface_max_dev_mm"] <= 0.02
    text = capsys.readouterr().out
    assert f"{summary['n_patches']} patches (fit" in text
    assert main(["photometric", "reconstruct", str(crack_folder), "--surface", "coons", "--step", "8",
                 "--out", str(tmp_path / "c")]) == 0
    coons = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert coons["surface"] == "coons" and coons["n_patches"] == 32 * 32 and coons["patches"] == [32, 32]
    assert main(["photometric", "reconstruct", str(crack_folder), "--surface-tolerance", "0",
                 "--out", str(tmp_path / "bad")]) == 2
    assert "surface_tolerance" in capsys.readouterr().err
