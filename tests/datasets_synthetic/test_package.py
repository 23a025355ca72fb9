"""The ``datasets_synthetic`` package: its public names load on first use and are the modules' own."""

from __future__ import annotations

import importlib

import pytest

import datasets_synthetic


@pytest.mark.parametrize("name", datasets_synthetic.__all__)
def test_every_public_name_resolves(name):
    value = getattr(datasets_synthetic, name)
    if name in datasets_synthetic._MODULES:
        assert value is importlib.import_module(f"datasets_synthetic.{name}")
    else:
        module = importlib.import_module(f"datasets_synthetic.{datasets_synthetic._NAMES[name]}")
        assert value is getattr(module, name)


def test_unknown_name():
    with pytest.raises(AttributeError, match="no attribute 'polygon_area'"):
        datasets_synthetic.polygon_area  # noqa: B018
    assert set(datasets_synthetic.__all__) <= set(dir(datasets_synthetic))
