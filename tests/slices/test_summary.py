"""The summary of a reconstruction: body table, chaining sentence, the figures of ``summary.json``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slices.io import Contour, ContourStack
from slices.structure import reconstruct_contours
from slices.summary import body_table, chaining_text, summarize
from tests.slices._stacks import branching_stack, circle


@pytest.fixture(scope="module")
def fork():
    conts = branching_stack() + [Contour(10.0, circle(40, 0, 5))]
    return ContourStack(conts, "json", "fork", ["read from memory"]), reconstruct_contours(
        conts, caps="flat", samples=1, start_angle=0.1, surface_path="coons")


def test_body_table(fork):
    _, rec = fork
    rows = body_table(rec)
    assert len(rows) == len(rec.bodies) == 4
    first = rows[0]
    assert (first["kind"], first["start"], first["stop"], first["n_slices"]) == ("outer", "end", "branch", 2)
    assert first["volume_mm3"] == rec.bodies[0].volume_mm3
    assert first["ray_start_deg"] == pytest.approx(np.degrees(0.1))
    single = next(r for r in rows if r["n_slices"] == 1)
    assert single["caps"] == ["half", "half"] and single["z_min_mm"] == 10.0 and single["volume_mm3"] > 0
    assert first["caps"] == ["flat", "half"] and first["subtracted"] is False


def test_chaining_text(fork):
    _, rec = fork
    assert chaining_text(rec) == (
        "4 bodies chained by overlap of contours on neighbouring planes: 4 outer, 0 holes (volume "
        "subtracted); 1 chain split at a branching or merging contour; 1 single-contour body given "
        "half caps (no thickness with caps flat)")


def test_summarize(fork):
    stack, rec = fork
    mesh, united = rec.solid_mesh()
    s = summarize("fork.json", stack, rec, mesh, united, None, {"max_control_point_deviation_mm": 0.5},
                  {"surface_time_s": 1.0})
    assert (s["input"], s["source"], s["roi"], s["rays"], s["ray_start"]) == ("fork.json", "json", "fork", 64,
                                                                           pytest.approx(np.degrees(0.1)))
    assert s["n_slices"] == 5 and s["n_contours"] == 7 and s["n_bodies"] == 4 and s["n_outer_bodies"] == 4
    assert s["volume_source"] == "patches" and s["mesh_union"] and s["surface_time_s"] == 1.0
    # united: the solid's area, without the caps the branches share; the bodies' sum kept beside it
    assert s["area_source"] == "united solid" and s["area_mm2"] == mesh.surface_area()
    assert s["bodies_area_mm2"] == rec.area_mm2 > s["area_mm2"]
    assert s["n_patches"] == sum(b.patches.n_patches for b in rec.bodies)
    assert s["notes"] == ["read from memory"] and s["reference_bspline"]["max_control_point_deviation_mm"] == 0.5
    json.dumps(s)  # plain Python throughout
    comp = {"result_volume_mm3": 12.0, "area_mm2": 30.0, "operation": "'fork' - 'x'"}
    c = summarize("fork.json", stack, rec, mesh, united, comp, None, {})
    assert (c["volume_mm3"], c["volume_ml"], c["area_mm2"]) == (12.0, 0.012, 30.0)
    assert c["area_source"] == "composition" and c["bodies_area_mm2"] == rec.area_mm2
    assert c["volume_source"] == "composition" and c["composition"] is comp and "reference_bspline" not in c
    assert "'fork' - 'x'" in c["notes"][-1] and stack.notes == ["read from memory"]
