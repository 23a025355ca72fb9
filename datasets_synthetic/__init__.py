"""Synthetic scenes with exact ground truth: height fields, rendered image sets, CT phantoms.

Package map
-----------
================  ============================================================"""

from __future__ import annotations

from surfaces import __version__ as __version__  # the distribution's version, one home

from datasets_synthetic.dicom import write_ct_series, write_rtstruct
from datasets_synthetic.heightfields import SCENES, HeightField, make_scene
from datasets_synthetic.phantoms import SHAPES, Phantom, make_phantom, write_phantom
from datasets_synthetic.render import make_triad_folder, write_diligent_folder

__all__ = [
    "SCENES",
    "SHAPES",
    "HeightField",
    "Phantom",
    "make_phantom",
    "make_scene",
    "make_triad_folder",
    "write_ct_series",
    "write_diligent_folder",
    "write_phantom",
    "write_rtstruct",
]
