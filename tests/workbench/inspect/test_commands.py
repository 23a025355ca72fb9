"""``workbench inspect calibrate|run|watch`` on the command line."""

from __future__ import annotations

import csv
import json
import shutil

import pytest

from workbench.cli import main


def _error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("workbench: error: ")
    return err[0]


def test_calibrate_writes_the_rig(small_lot, tmp_path, capsys):
    rig = tmp_path / "cal" / "rig.json"
    args = ["inspect", "calibrate", "--flat", *small_lot["flats"], "--light-positions",
            str(small_lot["root"] / "rig" / "light_positions.txt"), "--pixel-size",
            str(small_lot["truth"]["pixel_size_mm"]), "--flat-albedo", "0.8", "--out", str(rig)]
    assert main(args) == 0
    doc = json.loads(rig.read_text())
    assert doc["format"] == "workbench-rig" and doc["image_size"] == [224, 224]
    assert doc["flat_field"]["gains"] == "rig_gains.npz" and "LED 3" in capsys.readouterr().out
    assert doc == json.loads(small_lot["rig"].read_text())  # the same rig as the library call


def test_calibrate_needs_the_flat_field(small_lot, tmp_path, capsys):
    args = ["inspect", "calibrate", "--light-positions", str(small_lot["root"] / "rig" / "light_positions.txt"),
            "--pixel-size", "0.1", "--out", str(tmp_path / "rig.json")]
    assert main(args) == 2
    line = _error_line(capsys)
    assert "--flat" in line and "--intensity-images" in line and not (tmp_path / "rig.json").exists()


def test_run_on_a_cluster(small_lot, tmp_path, cluster, capsys):
    out = tmp_path / "out"
    args = ["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(small_lot["spec"]),
            str(small_lot["parts"]), "--out", str(out), "--scheduler", cluster]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "4 part(s): 4 to inspect" in text and "parts/s" in text and "report:" in text
    with open(out / "results.csv", newline="") as fh:
        rows = {row["id"]: row for row in csv.DictReader(fh)}
    assert rows["scratch_over"]["verdict"] == "fail" and rows["clean"]["verdict"] == "pass"
    assert all(row["status"] == "ok" for row in rows.values()) and (out / "report.html").is_file()
    assert main(args) == 0
    assert "0 to inspect, 4 finished before (skipped)" in capsys.readouterr().out


@pytest.mark.parametrize("spec, message", [
    ({"max_depth_mm": 0.1, "colour": "red"}, "unknown key 'colour'"),
    ({"max_depth_mm": -0.1}, "max_depth_mm: must not be negative"),
    ({"max_depth_mm": 0.1, "decision_rule": "lenient"}, "decision_rule: expected one of simple, guard_band"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [1, 0]]}, "roi_mm: a polygon needs at least 3 vertices"),
])
def test_bad_spec_exits_2_before_any_work(small_lot, tmp_path, capsys, spec, message):
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(spec))
    out = tmp_path / "out"
    args = ["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(path), str(small_lot["parts"]),
            "--out", str(out)]
    assert main(args) == 2
    assert message in _error_line(capsys) and not out.exists()


def test_bad_options_exit_2(small_lot, tmp_path, capsys):
    base = ["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(small_lot["spec"]),
            str(small_lot["parts"]), "--out", str(tmp_path / "out")]
    assert main([*base, "--option", "speed=2"]) == 2
    assert "--option speed: not an option" in _error_line(capsys)
    assert main([*base, "--option", "novalue"]) == 2
    assert "--option: expected KEY=VALUE" in _error_line(capsys)
    assert main([*base[:-3], str(tmp_path / "no_parts"), "--out", str(tmp_path / "out")]) == 2
    assert "PARTS" in _error_line(capsys) and not (tmp_path / "out").exists()


def test_guard_band_states_the_uncertainty(small_lot, tmp_path, cluster, capsys):
    """guard_band turns the stated uncertainty on: every decided value carries its U (k = 2)."""
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.1, "decision_rule": "guard_band"}))
    parts = tmp_path / "parts"
    shutil.copytree(small_lot["parts"] / "scratch_over", parts / "p1")
    out = tmp_path / "out"
    assert main(["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(spec), str(parts), "--out",
                 str(out), "--scheduler", cluster, "--light-position-tolerance-mm", "0.2"]) == 0
    doc = json.loads((out / "p1" / "result.json").read_text())
    check = doc["imperfections"][0]["checks"][0]
    assert check["rule"] == "guard_band" and check["U"] > 0 and check["verdict"] == "fail"
    assert check["value"] - check["U"] > 0.1 and doc["max_depth_U_mm"] == check["U"]
    assert doc["measurement"]["uncertainty"]["method"] == "linear"
    with open(out / "results.csv", newline="") as fh:
        row = next(csv.DictReader(fh))
    # results.csv: U to two significant digits, the depth to the same decimal (issue 37); result.json keeps them full
    decimals = len(row["max_depth_U_mm"].split(".")[1])
    assert float(row["max_depth_U_mm"]) == pytest.approx(check["U"], rel=0.06) and 10 <= check["U"] * 10**decimals < 100
    assert row["max_depth_mm"] == f"{doc['max_depth_mm']:.{decimals}f}"
    capsys.readouterr()
    assert main(["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(spec), str(parts), "--out",
                 str(tmp_path / "o2"), "--option", "uncertainty=linear"]) == 2
    assert "give the uncertainty options instead" in _error_line(capsys)


def test_watch_with_a_timeout(small_lot, tmp_path, cluster, capsys):
    inbox = tmp_path / "inbox"
    shutil.copytree(small_lot["parts"] / "dent_under", inbox / "p1")
    out = tmp_path / "out"
    args = ["inspect", "watch", "--rig", str(small_lot["rig"]), "--spec", str(small_lot["spec"]), str(inbox),
            "--out", str(out), "--scheduler", cluster, "--interval", "0.3", "--settle", "0", "--timeout", "3"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "watch ended: 1 part(s) inspected" in text
    assert json.loads((out / "p1" / "result.json").read_text())["verdict"] == "pass"
