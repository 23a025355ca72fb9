"""Tests of the ``workbench`` package itself: its public API, a light import, ``python -m workbench``."""

from __future__ import annotations

import subprocess
import sys

import workbench


def test_public_api_names_exist():
    assert sorted(workbench.__all__) == sorted(set(workbench.__all__))
    for name in workbench.__all__:
        assert getattr(workbench, name).__doc__, name


def test_import_is_light():
    """Importing workbench must not start dask, open3d or matplotlib (heavy optional parts)."""
    code = (
        "import sys, workbench, workbench.batch, workbench.commands.common; "
        "print(sorted(m for m in ('dask', 'distributed', 'open3d', 'matplotlib') if m in sys.modules))"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]"


def test_python_dash_m():
    run = subprocess.run([sys.executable, "-m", "workbench", "synth", "--help"], capture_output=True, text=True)
    assert run.returncode == 0 and "triad" in run.stdout
    run = subprocess.run([sys.executable, "-m", "workbench", "synth", "triad", "--size", "x"],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "Traceback" not in run.stderr


def test_every_package_has_the_distribution_version():
    from importlib.metadata import version

    import datasets_synthetic
    import photometric
    import slices
    import surfaces

    expected = version("surface-workbench")
    for package in (photometric, slices, surfaces, datasets_synthetic, workbench):
        assert package.__version__ == expected, package.__name__
