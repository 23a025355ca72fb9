"""A spec's narrowest imperfection against the rig's pixels.

Moved from tests/photometric/test_uncertainty_resolution.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from photometric.resolution import ResolutionWarning, check_resolution, require_resolution


def test_spec_meets_the_rig():
    from workbench.inspect.spec import check_spec_field, parse_spec

    """spec.json's min_width_mm is checked where the spec meets the rig's pixel: refused below two
    pixels (one line naming the key), a warning where it reads shallow, silent where resolved."""
    spec = parse_spec({"max_depth_mm": 0.08, "min_width_mm": 0.035})
    with pytest.raises(ValueError, match="spec min_width_mm: .* 0.35 px across .* not resolved"):
        check_spec_field(spec, (100, 100), 0.1)
    with pytest.warns(ResolutionWarning, match="reads up to"):
        check_spec_field(parse_spec({"max_depth_mm": 0.08, "min_width_mm": 0.3}), (100, 100), 0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_spec_field(parse_spec({"max_depth_mm": 0.08, "min_width_mm": 1.0}), (100, 100), 0.05)
        check_spec_field(parse_spec({"max_depth_mm": 0.08}), (100, 100), 1.0)  # not stated: not checked
    with pytest.raises(ValueError, match="min_width_mm: must be positive"):
        parse_spec({"max_depth_mm": 0.08, "min_width_mm": 0})
    assert require_resolution(1.0, 0.05).status == "ok"
    assert np.isfinite(check_resolution(0.3, 0.05).depth_shortfall)
