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

The names in ``__all__`` load their module on first use, so ``import
datasets_synthetic`` stays fast. A function named like its module is called
through it: ``datasets_synthetic.render.render``.

Examples
--------
>>> import datasets_synthetic as ds
>>> ring = ds.make_phantom("ring", major_mm=20.0, minor_mm=5.0)
>>> round(ring.volume_mm3 / ds.make_phantom("ring", major_mm=10.0, minor_mm=5.0).volume_mm3, 12)
2.0
"""

from __future__ import annotations

from importlib import import_module

_MODULES = ("dicom", "heightfields", "io", "phantoms", "render")

# public name -> the module that holds it
_NAMES = {
    "HeightField": "heightfields",
    "SCENES": "heightfields",
    "make_scene": "heightfields",
    "make_triad_folder": "render",
    "write_diligent_folder": "render",
    "Phantom": "phantoms",
    "SHAPES": "phantoms",
    "make_phantom": "phantoms",
    "write_phantom": "phantoms",
    "write_ct_series": "dicom",
    "write_rtstruct": "dicom",
}
__all__ = sorted({*_MODULES, *_NAMES})


def __getattr__(name: str):
    if name in _NAMES:
        value = getattr(import_module(f"datasets_synthetic.{_NAMES[name]}"), name)
    elif name in _MODULES:
        value = import_module(f"datasets_synthetic.{name}")
    else:
        raise AttributeError(f"module 'datasets_synthetic' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
