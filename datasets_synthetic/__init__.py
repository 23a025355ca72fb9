"""Synthetic scenes with exact ground truth: height fields, rendered image sets, CT phantoms.

Modules: :mod:`~datasets_synthetic.heightfields` (analytic height fields with exact
slopes and defect truth; the image convention :data:`~datasets_synthetic.heightfields.CONVENTION`),
:mod:`~datasets_synthetic.render` (Lambertian renders with cast shadows and noise, DiLiGenT
folders), :mod:`~datasets_synthetic.phantoms` (solids with exact volume and area, contour
stacks), :mod:`~datasets_synthetic.dicom` (CT series and RT Structure Set writers) and
:mod:`~datasets_synthetic.io` (atomic writers).
"""
