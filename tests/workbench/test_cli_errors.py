"""Tests of ``workbench photometric errors`` (the light-deviation accuracy report)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from photometric import errors as E
from photometric.lights import ring_lights
from workbench.cli import main

FAST = ["--grid", "9", "--samples", "400", "--deviation-max", "3"]
KEYS = {
    "inputs", "configuration", "sensitivity_per_deg", "first_order_relative_difference_at_2deg",
    "error_maps", "error_curves", "tolerances", "derivative_range_limits", "recommendation_table",
    "monte_carlo", "plots", "convention", "crack_study", "surface_height_error",
}


@pytest.fixture(scope="module")
def lights_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("lights") / "lights.txt"
    np.savetxt(path, ring_lights(3, 45.0), fmt="%.6f")
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory, lights_file):
    """One run of the command on a small grid, with a surface and the crack study.

    Most of its time (about 5 of 7 s on a free core) goes into drawing the 13 plots;
    the options are already the smallest that still give every part of the report.
    """
    tmp = tmp_path_factory.mktemp("errors")
    rows, cols = np.mgrid[0:24, 0:30]
    np.save(tmp / "h.npy", 0.2 * np.exp(-((rows - 12) ** 2 + (cols - 15) ** 2) / 40.0))
    out = tmp / "out"
    argv = ["photometric", "errors", "--lights", str(lights_file), "--tolerance", "0.05",
            "--derivative-range", "1.0", "--surface", str(tmp / "h.npy"), "--pixel-size", "0.1",
            "--crack-size", "64", "--out", str(out), *FAST]
    code = main(argv)
    return code, out


@pytest.mark.slow
def test_exit_code_and_files(run):
    code, out = run
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert KEYS <= set(report)
    assert "_arrays" not in report
    md = (out / "report.md").read_text()
    assert "| D | eps |" in md
    assert len(report["plots"]) >= 7
    for name in report["plots"]:
        assert name.endswith(".png")
        assert (out / name).is_file() and (out / name).stat().st_size > 1000
        assert f"({name})" in md


@pytest.mark.slow
def test_numbers_match_the_library(run):
    _, out = run
    report = json.loads((out / "report.json").read_text())
    assert len(report["tolerances"]) == 7  # 3 single lights, 3 pairs, all three
    direct = E.max_deviation(ring_lights(3, 45.0), 0.05, 1.0, (0,), "any", n_grid=9)
    row = report["tolerances"][0]
    assert row["lights"] == [1]
    assert row["any"]["value"] == pytest.approx(direct.value, rel=1e-6)
    assert row["any"]["error"] == pytest.approx(0.05, rel=1e-6)
    assert report["configuration"]["condition_number"] == pytest.approx(np.sqrt(2.0), rel=1e-4)
    assert max(report["first_order_relative_difference_at_2deg"].values()) < 0.05


@pytest.mark.slow
def test_surface_parts(run):
    _, out = run
    report = json.loads((out / "report.json").read_text())
    expect = {"square", "surface", "crack"}
    assert {m["derivatives"] for m in report["error_maps"]} == expect
    assert report["inputs"]["surface"]["pixel_size_mm"] == 0.1
    she = report["surface_height_error"]
    assert len(she) == 3 and all(c["rms_dh_mm"] > 0 for c in she)


@pytest.mark.slow
def test_crack_study(run):
    _, out = run
    cs = json.loads((out / "report.json").read_text())["crack_study"]
    assert cs["cases"][0]["max_abs_dp_measured"] < 1e-3  # no deviation: only float32 rounding
    assert cs["cases"][0]["depth_change_mm"] == pytest.approx(0.0, abs=1e-9)
    for c in cs["cases"][1:]:
        assert c["max_abs_dq_measured"] > 1e-3
        assert c["max_abs_diff_measured_predicted"] < 1e-4
    assert (out / "crack_study.png").is_file()


@pytest.mark.parametrize(
    "content, extra, message",
    [
        ("0 0 1\n0 0 1\n0 0 1\n", [], "coplanar"),
        ("0 0 1\n1 0 0\n", [], "3"),
        (None, ["--tolerance", "-1"], "tolerance"),
        (None, ["--surface", "missing.npy"], "surface"),
        (None, ["--grid", "2"], "grid"),
    ],
)
def test_bad_input_exits_2(tmp_path, lights_file, capsys, content, extra, message):
    path = lights_file
    if content is not None:
        path = tmp_path / "bad.txt"
        path.write_text(content)
    code = main(["photometric", "errors", "--lights", str(path), "--no-crack", "--out", str(tmp_path / "o"),
                 *FAST, *extra])
    assert code == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("content, message", [
    (np.zeros(5), "expected a 2-D height field"),
    (np.zeros((1, 5)), "expected a 2-D height field"),
    (b"not numpy", "not a readable .npy file"),
])
def test_bad_surface_file(tmp_path, lights_file, capsys, content, message):
    path = tmp_path / "h.npy"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        np.save(path, content)
    code = main(["photometric", "errors", "--lights", str(lights_file), "--surface", str(path),
                 "--no-crack", "--out", str(tmp_path / "o"), *FAST])
    assert code == 2
    err = capsys.readouterr().err
    assert "--surface" in err and message in err


def test_missing_lights_file(tmp_path, capsys):
    assert main(["photometric", "errors", "--lights", str(tmp_path / "nope.txt")]) == 2
    assert "nope.txt" in capsys.readouterr().err
