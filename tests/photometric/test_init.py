"""The public API of ``photometric``: every name in ``__all__`` resolves, loaded on first use."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import photometric


MODULES = ("lights", "normals", "io", "stereo", "integrate", "defects", "pipeline", "camera", "nearfield", "rig",
           "calibrate", "options", "leds")


@pytest.mark.parametrize("name", sorted(photometric.__all__))
def test_every_public_name_is_its_home_object(name):
    value = getattr(photometric, name)
    if name in ("errors", "integrate", "stages"):
        assert value is importlib.import_module(f"photometric.{name}")
        return
    homes = [m for m in MODULES if getattr(importlib.import_module(f"photometric.{m}"), name, None) is value]
    assert homes, f"{name} is not defined by any photometric module"


def test_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no_such_function"):
        photometric.no_such_function  # noqa: B018


def test_import_stays_light():
    """``import photometric`` loads no solver module (and so neither OpenCV nor scipy)."""
    code = (
        "import sys, photometric; "
        "heavy = [m for m in ('photometric.stereo', 'photometric.integrate', 'photometric.defects', "
        "'photometric.errors', 'cv2', 'scipy') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
    lazy = subprocess.run(
        [sys.executable, "-c",
         "import sys, photometric; photometric.solve; print('photometric.stereo' in sys.modules)"],
        capture_output=True, text=True, check=True,
    )
    assert lazy.stdout.strip() == "True"
