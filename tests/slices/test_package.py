"""The ``slices`` package: its public names load on first use and are the modules' own."""

from __future__ import annotations

import importlib

import pytest

import slices


@pytest.mark.parametrize("name", slices.__all__)
def test_every_public_name_resolves(name):
    value = getattr(slices, name)
    if name in slices._MODULES:
        assert value is importlib.import_module(f"slices.{name}")
    else:
        assert value is getattr(importlib.import_module(f"slices.{slices._NAMES[name]}"), name)


def test_unknown_name_and_dir():
    with pytest.raises(AttributeError, match="no attribute 'rays'"):
        slices.rays  # noqa: B018
    assert set(slices.__all__) <= set(dir(slices))
