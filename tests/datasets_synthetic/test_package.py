"""The ``datasets_synthetic`` package: its public names, and an import that stays light."""

from __future__ import annotations

import subprocess
import sys

import pytest

import datasets_synthetic


@pytest.mark.parametrize("name", datasets_synthetic.__all__)
def test_every_public_name_resolves(name):
    value = getattr(datasets_synthetic, name)
    if name == "InputError":  # bad input is one class across the packages
        from surfaces.validate import InputError

        assert value is InputError
        return
    module = getattr(value, "__module__", None)
    if module is not None:  # functions and classes: their home module's own
        assert module.startswith("datasets_synthetic.") and getattr(sys.modules[module], name) is value


def test_phantom_helpers_are_gone_and_import_stays_light():
    assert not hasattr(datasets_synthetic.phantoms, "polygon_area")
    code = ("import sys, datasets_synthetic; heavy = {'open3d', 'dask', 'matplotlib', 'manifold3d', 'pydicom',"
            " 'scipy', 'skimage'}; print(sorted(heavy & {m.split('.')[0] for m in sys.modules}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
