"""CT contour stacks and RT structure sets to one interpolating surface (seed 000).

Package map
-----------
==================  ==================================================================
reading             ``io`` (RTSTRUCT, CT series, mask stacks, contour JSON: ``load``,
                    ``list_rois``; :class:`Contour`, :class:`ContourStack`)
one contour         ``control_points`` (checks and orientation, the seed's parameters:
                    rays, support and turning points, chord length; eqs. 1-5)
one body            ``surface`` (slice curves on a common lattice, side surfaces:
                    blending, Coons, B-spline), ``caps`` (none, flat, half, dome),
                    ``body`` (surface, volume, area and mesh of one chain of contours)
a structure         ``chaining`` (holes, bodies by overlap, the slab volume),
                    ``structure`` (all bodies, the united solid), ``compose`` (set
                    operations of ROIs), ``reference`` (the smoothing B-spline comparison)
end to end          ``pipeline`` (an input in, a :class:`SlicesReconstruction` out),
                    ``summary`` (its figures), ``options`` (every default, once)
==================  ==================================================================

The library computes and returns; it writes no files (``workbench.runs.slices``
writes a result folder). Lengths are mm, angles radians. The modules and the
names in ``__all__`` load on first use, so ``import slices`` stays fast.

Examples
--------
>>> import slices
>>> square = slices.clean_contour([[0, 0], [0, 3], [3, 3], [3, 0]])
>>> slices.signed_area(square)
9.0
"""

from __future__ import annotations

from importlib import import_module

_MODULES = (
    "body",
    "caps",
    "chaining",
    "compose",
    "control_points",
    "io",
    "options",
    "pipeline",
    "reference",
    "structure",
    "summary",
    "surface",
)

# public name -> the module that holds it
_NAMES = {
    "Contour": "io",
    "ContourStack": "io",
    "load": "io",
    "list_rois": "io",
    "read_rtstruct": "io",
    "clean_contour": "control_points",
    "signed_area": "control_points",
    "parameterize": "control_points",
    "ContourParameters": "control_points",
    "slice_curves": "surface",
    "side_surface": "surface",
    "Body": "chaining",
    "chain": "chaining",
    "slab_volume": "chaining",
    "BodySurface": "body",
    "build_body": "body",
    "Reconstruction": "structure",
    "reconstruct_contours": "structure",
    "reconstruct_roi": "structure",
    "compose_rois": "compose",
    "SlicesReconstruction": "pipeline",
    "reconstruct": "pipeline",
    "SurfaceOptions": "options",
    "ReadOptions": "options",
}
__all__ = sorted({*_MODULES, *_NAMES})


def __getattr__(name: str):
    if name in _NAMES:
        value = getattr(import_module(f"slices.{_NAMES[name]}"), name)
    elif name in _MODULES:
        value = import_module(f"slices.{name}")
    else:
        raise AttributeError(f"module 'slices' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
