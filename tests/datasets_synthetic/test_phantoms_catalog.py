"""Phantoms by name."""

from __future__ import annotations

import pytest

from datasets_synthetic.phantoms import SHAPES, make_phantom
from datasets_synthetic.phantoms.catalog import _CLASSES


def test_every_shape_by_name():
    assert SHAPES == ("ellipsoid", "kidney", "ring", "lobes", "tilted_cylinder")
    for shape in SHAPES:
        ph = make_phantom(shape)
        assert ph.name == shape and type(ph) is _CLASSES[shape]
    assert make_phantom("ring", major_mm=30.0).R == 30.0


@pytest.mark.parametrize(("shape", "params", "message"), [
    ("cube", {}, "shape: unknown phantom 'cube'"),
    ("ellipsoid", {"radius": 3.0}, "params: .*radius"),
    ("kidney", {"bend_radius_mm": 5.0, "thickness_mm": 8.0}, "bend_radius_mm"),
])
def test_bad_names_and_parameters(shape, params, message):
    with pytest.raises(ValueError, match=message):
        make_phantom(shape, **params)
