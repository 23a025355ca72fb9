"""CT contour stacks and RT structure sets to one interpolating surface (seed 000).

Package map
-----------
==================  ==================================================================
reading             ``io`` (RTSTRUCT, CT series, mask stacks, contour JSON: ``load``,
                    ``list_rois``; :class:`Contour`, :class:`ContourStack`)
one contour         ``control_points`` (checks and orientation, the seed's parameters:
                    rays, support and turning points, chord length; eqs. 1-5)
one body            ``surface`` (slice curves on a common lattice, side surfaces:
                    blending, Coons, B-spline), ``caps`` (trend, none, flat, half, dome),
                    ``body`` (surface, volume, area and mesh of one chain of contours)
a structure         ``chaining`` (holes, bodies by overlap, the slab volume),
                    ``structure`` (all bodies, the united solid), ``compose`` (set
                    operations of ROIs), ``reference`` (the smoothing B-spline comparison)
end to end          ``pipeline`` (an input in, a :class:`SlicesReconstruction` out),
                    ``summary`` (its figures), ``options`` (every default, once)
volume and masks    ``volume`` (the whole structure's volume from its areas, and the
                    volume's and area's uncertainty, k = 2), ``mask`` (the contours as
                    a voxel mask on a planning grid: the CT's, an image's, explicit)
==================  ==================================================================

The library computes and returns; it writes no files (``workbench.runs.slices``
writes a result folder). Lengths are mm, angles radians. Importing the package
loads numpy and the shared surface model only; scipy, OpenCV, scikit-image,
pydicom and manifold3d are imported inside the functions that need them.

Examples
--------
>>> import slices
>>> square = slices.clean_contour([[0, 0], [0, 3], [3, 3], [3, 0]])
>>> slices.signed_area(square)
9.0
"""

from __future__ import annotations

from slices.body import BodySurface, build_body
from slices.chaining import Body, chain, slab_volume
from slices.compose import compose_rois
from slices.control_points import ContourParameters, parameterize
from slices.polygons import clean_contour, signed_area
from slices.io import Contour, ContourStack, list_rois, load, read_rtstruct
from slices.options import ReadOptions, SurfaceOptions
from slices.pipeline import SlicesReconstruction, reconstruct
from slices.structure import Reconstruction, reconstruct_contours, reconstruct_roi
from slices.surface import side_surface, slice_curves
from surfaces.validate import InputError  # bad input; the same class in every package

__all__ = [
    "Body",
    "BodySurface",
    "Contour",
    "InputError",
    "ContourParameters",
    "ContourStack",
    "ReadOptions",
    "Reconstruction",
    "SlicesReconstruction",
    "SurfaceOptions",
    "build_body",
    "chain",
    "clean_contour",
    "compose_rois",
    "list_rois",
    "load",
    "parameterize",
    "read_rtstruct",
    "reconstruct",
    "reconstruct_contours",
    "reconstruct_roi",
    "side_surface",
    "signed_area",
    "slab_volume",
    "slice_curves",
]


def __getattr__(name: str):
    if name == "__version__":  # the distribution's version, read on first use (one home: surfaces)
        import surfaces

        return surfaces.__version__
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
