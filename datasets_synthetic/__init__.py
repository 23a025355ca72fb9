"""Synthetic scenes with exact ground truth: height fields, rendered image sets, CT phantoms.

Package map
-----------
================  ===================================================================
``heightfields``  analytic height fields with exact slopes and defect truth (crack,
                  dent, scratch, bumps, sphere, vase, inspection plate)
``render``        Lambertian renders with cast shadows and noise, DiLiGenT-style folders
``phantoms``      CT phantoms with exact volume and area, cut into contour stacks
                  (a package: ``base``, ``scaled``, ``ring``, ``lobes``, ``cylinder``,
                  ``catalog``, ``write``)
``dicom``         CT series and RT Structure Set writers for the phantoms
``io``            output folders (files are written with :mod:`surfaces.io`)
================  ===================================================================

Importing the package loads numpy and :mod:`surfaces` helpers only (pydicom,
OpenCV, scipy and open3d are imported where they are used). A function named
like its module is called through it: ``datasets_synthetic.render.render``.

Examples
--------
>>> import datasets_synthetic as ds
>>> ring = ds.make_phantom("ring", major_mm=20.0, minor_mm=5.0)
>>> round(ring.volume_mm3 / ds.make_phantom("ring", major_mm=10.0, minor_mm=5.0).volume_mm3, 12)
2.0
"""

from __future__ import annotations

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
