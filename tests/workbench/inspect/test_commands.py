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
    with pytest.raises(SystemExit) as stop:
        main(args)
    assert stop.value.code == 2
    assert "required: --flat" in capsys.readouterr().err and not (tmp_path / "rig.json").exists()


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


def test_guard_band_asks_for_the_uncertainty(small_lot, tmp_path, cluster, capsys):
    """guard_band turns the stated uncertainty on; a part whose U cannot be stated is recorded, not decided."""
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": 0.1, "decision_rule": "guard_band"}))
    parts = tmp_path / "parts"
    shutil.copytree(small_lot["parts"] / "scratch_over", parts / "p1")
    out = tmp_path / "out"
    code = main(["inspect", "run", "--rig", str(small_lot["rig"]), "--spec", str(spec), str(parts), "--out", str(out),
                 "--scheduler", cluster])
    result = out / "p1" / "result.json"
    if code == 0:
        doc = json.loads(result.read_text())
        checks = doc["imperfections"][0]["checks"]
        assert checks[0]["rule"] == "guard_band" and checks[0]["U"] > 0
        assert doc["measurement"]["uncertainty"]["method"] == "linear"
    else:
        # the measurement cannot state U for this rig: the part is recorded with the reason, never decided
        assert code == 1 and not result.exists()
        record = json.loads((out / "failed" / "p1.json").read_text())
        assert "uncertainty" in record["error"] and record["options"]["uncertainty"] == {"method": "linear"}


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
