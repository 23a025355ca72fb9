"""CT phantoms: solids with exactly known volume and surface area, cut into contour stacks.

Coordinates are patient millimetres; z runs along the slice normal. Every
cross-section is a union of closed curves that the phantom can evaluate
exactly, so sampled contours lie ON the true outline (before optional noise),
and the volume between any two planes is known:

- ``ellipsoid``: ``V = 4/3 pi a b c``, area by Legendre's elliptic-integral formula.
- ``kidney``: a bean outline with a deep concave hilum (rays from its centroid
  cross it three times, the fold case of seed 000), scaled by
  ``s(z) = sqrt(1 - (z/c)^2)``: ``V = A0 * 4c/3`` with ``A0 = pi A B`` exactly;
  the area by spectrally accurate quadrature (stated in ``area_accuracy_mm2``).
- ``ring``: a torus around the z axis (every section has a hole):
  ``V = 2 pi^2 R r^2``, ``S = 4 pi^2 R r``.
- ``lobes``: two overlapping spheres (sections split into two contours where the
  lobes branch): union volume and area by the spherical-cap (lens) formulas.
- ``tilted_cylinder``: a right circular cylinder whose axis leans in the x-z plane,
  flat caps (end sections are truncated ellipses): ``V = pi r^2 L``,
  ``S = 2 pi r (L + r)``, volume between planes in closed form.

Modules: ``base`` (:class:`Phantom`, :class:`DistancePhantom`, curve and surface
samplers), ``scaled`` (:class:`Ellipsoid`, :class:`Kidney`: one outline scaled
along z), ``ring``, ``lobes``, ``cylinder`` (one shape each), ``catalog``
(:func:`make_phantom` by name) and ``write`` (:func:`write_phantom`: files).
"""

from __future__ import annotations

from datasets_synthetic.phantoms.base import MIN_SECTION_FRACTION, DistancePhantom, Phantom
from datasets_synthetic.phantoms.catalog import SHAPES, make_phantom
from datasets_synthetic.phantoms.cylinder import TiltedCylinder
from datasets_synthetic.phantoms.lobes import Lobes
from datasets_synthetic.phantoms.ring import Ring
from datasets_synthetic.phantoms.scaled import Ellipsoid, Kidney, ScaledSection
from datasets_synthetic.phantoms.write import write_phantom

__all__ = [
    "MIN_SECTION_FRACTION",
    "SHAPES",
    "DistancePhantom",
    "Ellipsoid",
    "Kidney",
    "Lobes",
    "Phantom",
    "Ring",
    "ScaledSection",
    "TiltedCylinder",
    "make_phantom",
    "write_phantom",
]
