"""Synthetic scenes with exact ground truth: height fields, rendered image sets, CT phantoms.

Modules: :mod:`~datasets_synthetic.heightfields` (analytic height fields with exact
slopes and defect truth; the image convention :data:`~datasets_synthetic.heightfields.CONVENTION`),
:mod:`~datasets_synthetic.render` (Lambertian renders with cast shadows and noise, DiLiGenT
folders), :mod:`~datasets_synthetic.phantoms` (solids with exact volume and area, contour
stacks), :mod:`~datasets_synthetic.dicom` (CT series and RT Structure Set writers) and
:mod:`~datasets_synthetic.io` (atomic writers). Near-field inspection rigs (the shared
near-field format contract): :mod:`~datasets_synthetic.point_lights` (LED positions, axes,
lobes, falloff), :mod:`~datasets_synthetic.cameras` (orthographic and pinhole cameras, the
surface point each pixel sees), :mod:`~datasets_synthetic.nearfield` (part and flat-field
renders, near-field folders) and :mod:`~datasets_synthetic.spheres` (mirror-sphere
calibration images).
"""
