"""The shared surface model: bicubic Bezier patches and everything built on them.

Every way into the workbench ends in one :class:`BezierPatches` model (control
points ``(rows, cols, 4, 4, 3)`` plus closure flags); tessellation, area,
volume, files and pictures are written once on it.

Package map
-----------
==================  ==================================================================
the model           ``bezier`` (:class:`BezierPatches`, evaluation, normals, control net)
ways in             ``coons`` (grids, seed 001), ``blending`` (parabolic blending, seed
                    000), ``bspline`` and ``knots`` (interpolation, seed 003),
                    ``kinematic``, ``curves`` and ``frames`` (sweeps, seed 004)
measures            ``measure`` (area and volume by quadrature), ``distance``
                    (signed deviation from a reference surface)
meshes              ``mesh`` (:class:`TriangleMesh`, tessellation, welding, signed
                    volume), ``topology`` (edges, shells, chains), ``intersect``
                    (self-intersecting faces), ``folds`` (the fold certificate of layered
                    meshes), ``voxelize`` (a solid onto a voxel grid)
solids              ``boolean`` (set operations, seed 002b), ``repair`` (checks and
                    repair of solid boundaries), ``smooth`` (Loop subdivision)
files               ``io`` (meshes, patch files, PNG, JSON; atomic writes)
pictures            ``render`` (headless ray casting), ``camera``, ``colormap``,
                    ``convert`` (open3d geometry for windows)
conventions         ``grid`` (the pixel grid), ``validate`` (argument checks),
                    ``vectors`` (cross, dot, unit)
==================  ==================================================================

The modules and the names in ``__all__`` load on first use, so ``import
surfaces`` stays fast; scipy, open3d, OpenCV and manifold3d are imported inside
the functions that need them. Functions named like their module are called
through it: ``surfaces.boolean.boolean``, ``surfaces.render.render``.

Examples
--------
>>> import numpy as np
>>> import surfaces
>>> x, y = np.meshgrid([0.0, 1.0], [0.0, 1.0], indexing="ij")
>>> square = surfaces.coons.from_grid(np.stack([x, y, np.zeros_like(x)], axis=-1))
>>> surfaces.area(square), surfaces.tessellate(square, samples=2).n_triangles
(1.0, 8)
"""

from __future__ import annotations

from importlib import import_module

_MODULES = (
    "bezier",
    "blending",
    "boolean",
    "bspline",
    "camera",
    "colormap",
    "convert",
    "coons",
    "curves",
    "distance",
    "folds",
    "frames",
    "grid",
    "intersect",
    "io",
    "kinematic",
    "knots",
    "measure",
    "mesh",
    "render",
    "repair",
    "smooth",
    "topology",
    "validate",
    "vectors",
    "voxelize",
)

# public name -> the module that holds it
_NAMES = {
    "BezierPatches": "bezier",
    "TriangleMesh": "mesh",
    "as_mesh": "mesh",
    "tessellate": "mesh",
    "signed_volume": "mesh",
    "area": "measure",
    "volume": "measure",
    "integrals": "measure",
    "area_and_volume": "measure",
    "BSplineCurve": "bspline",
    "BSplineSurface": "bspline",
    "interpolate_curve": "bspline",
    "interpolate_surface": "bspline",
    "KinematicSurface": "kinematic",
    "sweep": "kinematic",
    "revolve": "kinematic",
    "pipe": "kinematic",
    "load_curve": "curves",
    "BooleanResult": "boolean",
    "union": "boolean",
    "intersection": "boolean",
    "difference": "boolean",
    "compose": "boolean",
    "check_solid": "repair",
    "repair_mesh": "repair",
    "loop_smooth": "smooth",
    "read_mesh": "io",
    "write_mesh": "io",
    "load_patches": "io",
    "save_patches": "io",
    "write_png": "io",
    "write_json": "io",
    "render_view": "render",
    "Camera": "camera",
    "fit_camera": "camera",
    "apply_colormap": "colormap",
    "to_open3d": "convert",
    "deviation": "distance",
    "InputError": "validate",
}
__all__ = sorted({*_MODULES, *_NAMES})


def _distribution_version() -> str:
    """The ``surface-workbench`` distribution's version, every package's ``__version__`` (read on first use:
    importing importlib.metadata costs about 20 ms)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("surface-workbench")
    except PackageNotFoundError:  # a source tree on the path, not installed
        return "0+unknown"


def __getattr__(name: str):
    if name == "__version__":
        value = _distribution_version()
    elif name in _NAMES:
        value = getattr(import_module(f"surfaces.{_NAMES[name]}"), name)
    elif name in _MODULES:
        value = import_module(f"surfaces.{name}")
    else:
        raise AttributeError(f"module 'surfaces' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
