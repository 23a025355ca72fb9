"""Lambertian photometric stereo: lights, normals and albedo, height, defects.

Modules (imported on demand to keep ``import photometric`` light):
``lights`` (convention, reading, validation, mirror-sphere calibration), ``io``
(images and DiLiGenT-style folders), ``stereo`` (normals and albedo), ``integrate``
(height from gradients, height field to Bezier patches), ``defects`` (crack/dent
measures), ``pipeline`` (files in, files out).
"""
