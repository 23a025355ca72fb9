"""spec.json: every limit checked before any work, one clear error per bad key."""

from __future__ import annotations

import json

import numpy as np
import pytest

from workbench.inspect.spec import SPEC_KEYS, TEXTURE_LIMITS, load_spec, parse_spec

SQUARE = [[-10, -10], [10, -10], [10, 10], [-10, 10]]


def test_full_spec_round_trips():
    doc = {"max_depth_mm": 0.1, "max_length_mm": 5, "max_width_mm": 0.5, "max_area_mm2": 2.0, "max_count": 3,
           "max_total_area_mm2": 4.0, "min_distance_mm": 2.0, "roi_mm": SQUARE,
           "exclusion_zones_mm": [[[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]]], "decision_rule": "guard_band",
           "name": "plate A", "min_width_mm": 0.4,
           "texture": {"s_filter_mm": 0.008, "l_filter_mm": 0.8, "form": "poly2"},
           **{k: 1.0 for k in TEXTURE_LIMITS}}
    spec = parse_spec(doc)
    assert set(doc) == set(SPEC_KEYS)
    assert spec.min_width_mm == 0.4 and parse_spec(spec.to_dict()).min_width_mm == 0.4
    assert spec.texture == doc["texture"] and spec.limits["max_Sa_um"] == 1.0
    assert spec.decision_rule == "guard_band" and spec.limits["max_count"] == 3
    assert isinstance(spec.limits["max_count"], int) and spec.limits["max_length_mm"] == 5.0
    np.testing.assert_array_equal(spec.roi, SQUARE)
    assert spec.exclusions[0].shape == (4, 2)  # the closing repeat is dropped
    again = parse_spec(spec.to_dict())
    assert again.limits == spec.limits and again.name == "plate A" and again.texture == spec.texture
    assert again.sha256 == spec.sha256


def test_texture_limits_and_filters():
    """A texture limit alone is a spec; the texture key's filters are checked before any work."""
    spec = parse_spec({"max_Sq_um": 2.0})
    assert spec.texture == {"s_filter_mm": None, "l_filter_mm": None, "form": "plane"}
    assert "texture" not in spec.to_dict()  # the defaults are not written back as if given
    assert parse_spec({"max_count": 0}).texture is None
    assert parse_spec({"max_count": 0, "texture": {"l_filter_mm": 0.8}}).texture["l_filter_mm"] == 0.8
    for doc, message in [({"max_Sa_um": -1}, "max_Sa_um: must not be negative"),
                         ({"max_Sa_um": 1, "texture": {"l_filter": 0.8}}, "texture: unknown key 'l_filter'"),
                         ({"max_Sa_um": 1, "texture": {"s_filter_mm": 0.8, "l_filter_mm": 0.08}}, "must be below"),
                         ({"max_Sa_um": 1, "texture": {"form": "poly3"}}, "texture form: expected one of"),
                         ({"max_Sa_um": 1, "texture": {"l_filter_mm": "0.8"}}, "l_filter_mm: expected a positive")]:
        with pytest.raises(ValueError, match=message):
            parse_spec(doc)


def test_default_rule_is_simple_and_zero_limits_are_allowed():
    spec = parse_spec({"max_depth_mm": 0, "max_count": 0})
    assert spec.decision_rule == "simple" and spec.roi is None and spec.exclusions == ()


@pytest.mark.parametrize("doc, message", [
    ({"max_depth": 0.1}, "unknown key 'max_depth'"),
    ({"max_depth_mm": -0.1}, "max_depth_mm: must not be negative"),
    ({"max_depth_mm": "0.1"}, "max_depth_mm: expected a finite number"),
    ({"max_depth_mm": True}, "max_depth_mm: expected a finite number"),
    ({"max_area_mm2": float("nan")}, "max_area_mm2: expected a finite number"),
    ({"max_count": 1.5}, "max_count: expected a whole number"),
    ({"max_depth_mm": 0.1, "decision_rule": "strict"}, "decision_rule: expected one of simple, guard_band"),
    ({"decision_rule": "simple"}, "no limit given"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [1, 1]]}, "roi_mm: a polygon needs at least 3 vertices"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [1, 1], [2, 2]]}, "roi_mm: the polygon has no area"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [2, 2], [2, 0], [0, 1]]}, "roi_mm: the polygon is self-intersecting"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [1, "a"], [1, 1]]}, "roi_mm: expected a list of [x, y]"),
    ({"max_depth_mm": 0.1, "roi_mm": [0, 1, 2]}, "roi_mm: expected a list of [x, y]"),
    ({"max_depth_mm": 0.1, "roi_mm": [[0, 0], [1, np.inf], [1, 1]]}, "roi_mm: vertices must be finite"),
    ({"max_depth_mm": 0.1, "exclusion_zones_mm": [SQUARE, [[0, 0]]]}, "exclusion_zones_mm[1]: a polygon needs"),
    ({"max_depth_mm": 0.1, "exclusion_zones_mm": 3}, "exclusion_zones_mm: expected a list of polygons"),
    ({"max_depth_mm": 0.1, "name": 3}, "name: expected text"),
    ([0.1], "expected a JSON object"),
])
def test_bad_spec_is_one_clear_error(doc, message):
    with pytest.raises(ValueError) as err:
        parse_spec(doc)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_load_spec_files(tmp_path):
    path = tmp_path / "spec.json"
    path.write_text(json.dumps({"max_depth_mm": 0.2}))
    assert load_spec(path).limits == {"max_depth_mm": 0.2}
    with pytest.raises(FileNotFoundError, match="--spec: file .* does not exist"):
        load_spec(tmp_path / "none.json")
    path.write_text("{max_depth_mm: 0.2")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_spec(path)
    path.write_text(json.dumps({"max_depth_mm": -1}))
    with pytest.raises(ValueError, match=r"spec spec.json max_depth_mm: must not be negative"):
        load_spec(path)
