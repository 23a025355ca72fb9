"""A rendered production lot (issue 18): clean parts pass, parts clearly over the depth limit fail."""

from __future__ import annotations

import json

import pytest

from photometric.camera import make_camera
from workbench.inspect.lot import LotPart, lot_plan, render_lot
from workbench.inspect.run import run_inspection
from workbench.runs.photometric import calibrate_to_rig

LIMIT = 0.10


def test_lot_plan_mixes_parts_around_the_limit():
    plan = lot_plan(40, LIMIT, seed=3)
    assert plan == lot_plan(40, LIMIT, seed=3) and len({p.id for p in plan}) == 40
    factors = sorted(p.depth_mm / LIMIT for p in plan)
    assert sum(f == 0 for f in factors) == 12 and sum(0.3 <= f <= 0.6 for f in factors) == 10
    assert sum(0.93 <= f <= 1.07 for f in factors) == 8 and sum(f >= 1.5 for f in factors) == 10
    assert {p.defect for p in plan if p.depth_mm > 0} == {"scratch", "crack", "dent"}
    assert all(p.defect is None for p in plan if p.depth_mm == 0)
    assert all(0.85 <= p.albedo_scale <= 1.1 for p in plan)
    with pytest.raises(ValueError, match="n_parts"):
        lot_plan(3)


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=":0") as c:
        yield c


def test_rendered_lot_verdicts_against_truth(tmp_path, client):
    plan = lot_plan(12, LIMIT, seed=1)
    truth = render_lot(tmp_path / "lot", plan, size=224, field_mm=20.0, noise=0.003)
    flats = sorted(str(p) for p in (tmp_path / "lot" / "rig").glob("flat_*.png"))
    rig = tmp_path / "rig.json"
    calibrate_to_rig(rig, light_positions=tmp_path / "lot" / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": LIMIT, "decision_rule": "simple"}))
    run = run_inspection(tmp_path / "lot" / "parts", rig, spec, tmp_path / "out", client=client)
    assert run.batch.ok == 12
    for part in truth["parts"]:
        result = json.loads((tmp_path / "out" / part["id"] / "result.json").read_text())
        measured = result["max_depth_mm"]
        if part["defect"] is None:
            assert result["verdict"] == "pass" and result["n_imperfections"] == 0, part
        else:
            # the deepest imperfection is the rendered defect, within 15 % of its depth
            assert measured == pytest.approx(part["depth_mm"], rel=0.15), part
        if part["depth_mm"] >= 1.5 * LIMIT:
            assert result["verdict"] == "fail", part
        elif part["depth_mm"] <= 0.6 * LIMIT:
            assert result["verdict"] == "pass", part


def test_rendered_lot_under_guard_band(tmp_path, client):
    """ISO 14253-1 on a rendered lot: clean parts pass, parts over the limit by more than 2U fail, parts under it
    by more than 2U pass, and scratches at the limit are uncertain."""
    plan = lot_plan(12, LIMIT, seed=2) + [LotPart("at_limit", "scratch", LIMIT, 1.0, 901),
                                          LotPart("just_under", "scratch", 0.99 * LIMIT, 0.9, 902)]
    truth = render_lot(tmp_path / "lot", plan, size=224, field_mm=20.0, noise=0.003)
    flats = sorted(str(p) for p in (tmp_path / "lot" / "rig").glob("flat_*.png"))
    rig = tmp_path / "rig.json"
    calibrate_to_rig(rig, light_positions=tmp_path / "lot" / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"max_depth_mm": LIMIT, "decision_rule": "guard_band"}))
    run = run_inspection(tmp_path / "lot" / "parts", rig, spec, tmp_path / "out", client=client,
                         options={"uncertainty": {"method": "linear", "light_position_tolerance_mm": 0.2}})
    assert run.batch.ok == len(plan)
    decided = {"clean": 0, "over": 0, "under": 0}
    for part in truth["parts"]:
        result = json.loads((tmp_path / "out" / part["id"] / "result.json").read_text())
        assert result["decision_rule"] == "guard_band"
        if part["defect"] is None:
            assert result["verdict"] == "pass", part
            decided["clean"] += 1
            continue
        U = result["max_depth_U_mm"]
        assert U is not None and 0 < U < 0.4 * part["depth_mm"], (part, U)
        if part["depth_mm"] - LIMIT > 2 * U:
            assert result["verdict"] == "fail", (part, result["max_depth_mm"], U)
            decided["over"] += 1
        elif LIMIT - part["depth_mm"] > 2 * U:
            assert result["verdict"] == "pass", (part, result["max_depth_mm"], U)
            decided["under"] += 1
        if part["id"] in ("at_limit", "just_under"):
            assert result["verdict"] == "uncertain", (part, result["max_depth_mm"], U)
    assert decided["clean"] >= 3 and decided["over"] >= 2 and decided["under"] >= 2
