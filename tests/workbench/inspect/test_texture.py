"""Issue 36 in the inspection: texture limits in spec.json, decided like imperfections, recorded per part.

The part is a cosine ripple z = A cos(2 pi x / lambda) rendered under the lot's near-field rig:
its closed forms (ISO 25178-2 over whole periods, plane removed) are Sq = A / sqrt 2 and Sa = 2 A / pi.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

import numpy as np
import pytest

from workbench.batch.results import FIGURES, result_row
from workbench.batch.jobs import Job
from workbench.inspect.decide import judge
from workbench.inspect.part import inspect_part
from workbench.inspect.spec import parse_spec

A_MM = 0.01  # ripple amplitude
PERIOD_MM = 2.0  # ten whole periods over the 20 mm field
SA_UM = 2 * A_MM / np.pi * 1000
SQ_UM = A_MM / np.sqrt(2) * 1000


@dataclass(frozen=True)
class Ripple:
    """A closed-form feature of :class:`datasets_synthetic.heightfields.AnalyticSurface`: A cos(2 pi x / lambda)."""

    amplitude: float
    period: float

    def evaluate(self, x, y):
        w = 2 * np.pi / self.period
        return (self.amplitude * np.cos(w * x), -self.amplitude * w * np.sin(w * x), np.zeros_like(x),
                np.zeros(np.shape(x), bool))

    @property
    def bounds(self):
        return (-self.amplitude, self.amplitude)

    @property
    def max_slope(self):
        return 2 * np.pi * self.amplitude / self.period


@pytest.fixture(scope="module")
def ripple_part(small_lot, tmp_path_factory):
    from datasets_synthetic.cameras import orthographic_camera
    from datasets_synthetic.heightfields import AnalyticSurface
    from datasets_synthetic.nearfield import render_near_field
    from datasets_synthetic.point_lights import ring_point_lights
    from surfaces.io import write_png

    truth = small_lot["truth"]
    h, w = truth["image_size"]
    cam = orthographic_camera((h, w), truth["pixel_size_mm"])
    lights = ring_point_lights(4, 40.0, 200.0)  # render_lot's ring
    assert np.allclose(lights.positions, truth["light_positions_mm"])
    images = render_near_field(AnalyticSurface(features=(Ripple(A_MM, PERIOD_MM),)), cam, lights, 0.8,
                               exposure=truth["exposure"], flat_albedo=truth["flat_albedo"], noise=truth["noise"],
                               bit_depth=16, seed=21).images
    folder = tmp_path_factory.mktemp("ripple") / "ripple"
    names = [f"{k + 1:03d}.png" for k in range(len(images))]
    for name, img in zip(names, images):
        write_png(folder / name, np.round(np.clip(img, 0, 1) * 65535).astype(np.uint16))
    (folder / "filenames.txt").write_text("\n".join(names) + "\n")
    return folder


def test_texture_limit_fails_a_rough_part(small_lot, ripple_part, tmp_path):
    spec = parse_spec({"max_depth_mm": 0.1, "max_Sa_um": 0.5 * SA_UM, "max_Sq_um": 2 * SQ_UM,
                       "texture": {"form": "plane"}})
    fig = inspect_part(ripple_part, tmp_path, small_lot["rig"], spec)
    result = json.loads((tmp_path / "result.json").read_text())
    assert fig["verdict"] == "fail" and result["decided_by"] == ["texture Sa"]
    assert fig["texture_verdict"] == "fail"
    # the closed forms of the ripple, through the whole photometric path
    assert fig["Sa_um"] == pytest.approx(SA_UM, rel=0.02) and fig["Sq_um"] == pytest.approx(SQ_UM, rel=0.02)
    tex = result["texture"]
    assert tex["form"] == "plane" and tex["parameters"]["Sa"]["value"] == fig["Sa_um"]
    assert tex["parameters"]["Sa"]["U"] is None and tex["uncertainty"]["method"] == "not measured"
    checks = {c["quantity"]: c for c in tex["checks"]}
    assert checks["Sa"]["verdict"] == "fail" and checks["Sq"]["verdict"] == "pass"
    assert checks["Sa"]["limit"] == pytest.approx(0.5 * SA_UM) and checks["Sa"]["unit"] == "um"
    assert {"texture.json", "texture.png"} <= set(result["files"]) and (tmp_path / "texture.png").is_file()
    assert result["spec"]["texture"]["form"] == "plane" and result["timings_s"]["texture"] > 0
    # guard_band refuses a texture without U, as it does imperfection figures
    with pytest.raises(ValueError, match="guard_band: texture Sa has no expanded uncertainty"):
        inspect_part(ripple_part, tmp_path / "g", small_lot["rig"],
                     parse_spec({"max_Sa_um": SA_UM, "decision_rule": "guard_band"}))
    # the results.csv row: the texture columns, to the precision of their U or fixed decimals
    assert {"texture_verdict", "Sa_um", "Sa_U_um", "Sq_um", "Sz_um"} <= set(FIGURES["inspect"])
    row = result_row(Job("ripple", "inspect", str(ripple_part)), "ok", "", 1.0, fig)
    assert row["Sa_um"] == f"{fig['Sa_um']:.3f}" and row["texture_verdict"] == "fail" and row["Sa_U_um"] == ""


def test_texture_with_u_under_guard_band(small_lot, ripple_part, tmp_path):
    spec = parse_spec({"max_Sa_um": 1.2 * SA_UM, "decision_rule": "guard_band"})
    fig = inspect_part(ripple_part, tmp_path, small_lot["rig"], spec, uncertainty={"method": "linear"})
    assert fig["verdict"] == "pass" and fig["Sa_U_um"] > 0
    doc = json.loads((tmp_path / "texture.json").read_text())
    sa = doc["parameters"]["Sa"]
    assert (fig["Sa_um"], fig["Sa_U_um"]) == (sa["corrected"], sa["U_corrected"])
    assert fig["Sa_um"] == pytest.approx(SA_UM, rel=0.02)
    v, U = fig["Sa_um"], fig["Sa_U_um"]
    # within U of the limit: uncertain under guard_band, a pass under the simple rule; beyond U: fail
    for limit, rule, verdict in [(v + 0.5 * U, "guard_band", "uncertain"), (v + 0.5 * U, "simple", "pass"),
                                 (v - 1.5 * U, "guard_band", "fail"), (v + 1.5 * U, "guard_band", "pass")]:
        d = judge([], parse_spec({"max_Sa_um": limit, "decision_rule": rule}), (8, 8), 0.1, texture=doc)
        assert d.verdict == verdict and d.texture_checks[0]["verdict"] == verdict
    assert judge([], parse_spec({"max_Sa_um": v + 0.5 * U, "decision_rule": "guard_band"}), (8, 8), 0.1,
                 texture=doc).decided_by == ["texture Sa"]
    with pytest.raises(ValueError, match="texture was not measured"):
        judge([], parse_spec({"max_Sa_um": 1.0}), (8, 8), 0.1)


def test_lot_report_shows_the_texture(small_lot, ripple_part, tmp_path):
    from workbench.batch import key_figures
    from workbench.batch.results import write_results
    from workbench.inspect.report import write_inspection_report

    spec = parse_spec({"max_depth_mm": 0.1, "max_Sa_um": 0.5 * SA_UM, "texture": {"form": "poly2"}})
    fig = inspect_part(ripple_part, tmp_path / "ripple", small_lot["rig"], spec)
    row = result_row(Job("ripple", "inspect", str(ripple_part)), "ok", "", 1.0, key_figures("inspect", fig))
    write_results(tmp_path / "results.csv", [row])
    page = write_inspection_report(tmp_path, "workbench inspect run ...").read_text()
    assert "Areal texture (ISO 25178-2)" in page and "Form removed: poly2" in page and "max_Sa_um = " in page
    assert f"{fig['Sa_um']:.4g} um" in page and "<th>Sa (um)</th>" in page
    assert not re.search(r"\d\.\d{7,}", page)
