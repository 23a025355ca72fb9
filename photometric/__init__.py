"""Lambertian photometric stereo: lights, normals and albedo, height, defects, error analysis.

Modules: ``lights`` (the convention, slant and azimuth, validation of distant lights),
``leds`` (near-field point lights: the LED model), ``camera`` (orthographic and
perspective cameras of a near-field rig), ``normals`` (normals from slopes, the angular
error), ``io`` (images, light files and DiLiGenT-style folders), ``stereo`` (normals and albedo under
distant lights), ``nearfield`` (point lights: the alternation of normals and depth),
``rig`` (flat-field gains, ``rig.json``), ``calibrate`` (LED positions from mirror
spheres, distant directions from one), ``integrate`` (height from gradients, height field to Bezier patches),
``defects`` (crack/dent measures), ``options`` (:class:`~photometric.options.PhotometricOptions`,
every default once), ``stages`` (read, solve, integrate, surface, measure, uncertainty: each
public with a typed result), ``pipeline`` (their composition: input to measured surface, no
files) and the package ``errors`` (accuracy against deviated lights).

The names users call are importable from here (``photometric.solve``); each is loaded
with its module on first use, so ``import photometric`` stays light. The integrator is
``photometric.integrate.integrate`` (``photometric.integrate`` is its module).
"""

from __future__ import annotations

import importlib

from surfaces.validate import InputError  # bad input; the same class in every package

_HOMES = {
    "lights": (
        "CONVENTION", "validate_lights", "condition_number", "lights_from_angles", "light_angles",
        "ring_lights", "tangent_basis", "deviate_lights", "rotate_lights", "as_intensities",
    ),
    "leds": ("PointLights", "point_lights", "light_field"),
    "camera": ("Orthographic", "Perspective", "make_camera"),
    "nearfield": ("NearFieldResult", "NotConvergedError", "solve_nearfield"),
    "rig": ("Rig", "flat_field_gains", "read_rig"),
    "calibrate": ("calibrate_positions", "calibrate_rig", "calibrate_mirror_sphere"),
    "normals": ("normals_from_slopes", "angular_error_deg"),
    "io": ("PhotometricData", "read_folder", "read_image", "read_images", "read_mask", "load_lights",
           "load_intensities", "load_light_positions"),
    "stereo": ("StereoResult", "solve"),
    "integrate": ("height_to_patches",),
    "defects": ("fit_background", "measure_defects"),
    "pipeline": ("PhotometricReconstruction", "reconstruct"),
    "options": ("PhotometricOptions",),
}
_MODULE_OF = {name: module for module, names in _HOMES.items() for name in names}

__all__ = [*_MODULE_OF, "errors", "integrate", "stages", "InputError"]


def __getattr__(name: str):
    if name == "__version__":  # the distribution's version, read on first use (one home: surfaces)
        import surfaces

        return surfaces.__version__
    if name in _HOMES or name in ("errors", "stages"):
        return importlib.import_module(f"photometric.{name}")
    if name not in _MODULE_OF:
        raise AttributeError(f"module 'photometric' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"photometric.{_MODULE_OF[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
