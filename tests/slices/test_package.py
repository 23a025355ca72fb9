"""The ``slices`` package: its public names, and an import that stays light."""

from __future__ import annotations

import subprocess
import sys

import pytest

import slices


@pytest.mark.parametrize("name", slices.__all__)
def test_every_public_name_is_the_modules_own(name):
    value = getattr(slices, name)
    if name == "InputError":  # bad input is one class across the packages
        from surfaces.validate import InputError

        assert value is InputError
        return
    assert value.__module__.startswith("slices.") and value.__module__ != "slices"
    assert getattr(sys.modules[value.__module__], name) is value


def test_import_loads_no_heavy_optional_library():
    code = ("import sys, slices; heavy = {'open3d', 'dask', 'matplotlib', 'manifold3d', 'pydicom', 'scipy', 'cv2',"
            " 'skimage'}; print(sorted(heavy & {m.split('.')[0] for m in sys.modules}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
