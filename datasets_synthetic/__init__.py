"""Synthetic scenes with exact ground truth: height fields, rendered image sets, CT phantoms.

Package map
-----------
================  ============================================================"""

from __future__ import annotations

from datasets_synthetic.dicom import write_ct_series, write_rtstruct
from datasets_synthetic.heightfields import SCENES, HeightField, make_scene
from datasets_synthetic.phantoms import SHAPES, Phantom, make_phantom, write_phantom
from datasets_synthetic.render import make_triad_folder, write_diligent_folder
from surfaces.validate import InputError  # bad input; the same class in every package

__all__ = [
    "SCENES",
    "SHAPES",
    "HeightField",
    "InputError",
    "Phantom",
    "make_phantom",
    "make_scene",
    "make_triad_folder",
    "write_ct_series",
    "write_diligent_folder",
    "write_phantom",
    "write_rtstruct",
]


def __getattr__(name: str):
    if name == "__version__":  # the distribution's version, read on first use (one home: surfaces)
        import surfaces

        return surfaces.__version__
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
