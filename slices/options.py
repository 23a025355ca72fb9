"""The options of a reconstruction, each default held once.

:class:`SurfaceOptions` says how contours become a surface (rays, lattice,
method, caps, tessellation), :class:`ReadOptions` how an input file becomes
contours. Their fields are the package's defaults; public functions take
either an options object or the same names as keywords
(:func:`surface_options`, :func:`split_options`). Angles are radians here;
the command line converts its degrees once, at the edge.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from surfaces.validate import as_array, InputError, positive


def _choice(value, name: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise InputError(f"{name}: must be one of {allowed}, got {value!r}")


def _whole(value, name: str, least: int, what: str) -> int:
    x = positive(value, name)
    if x != int(x) or x < least:
        raise InputError(f"{name}: need a whole number of at least {least} {what}, got {value!r}")
    return int(x)


@dataclass(frozen=True)
class SurfaceOptions:
    """How the contours of a structure become one surface (seed 000, sections II-III).

    Attributes
    ----------
    method : {"blending", "coons", "bspline"}
        Side surface (:func:`slices.surface.side_surface`).
    n_rays : int
        Rays per contour (seed 000, eq. 1), at least 3.
    caps : {"none", "flat", "half", "dome", "trend"}
        End caps (:mod:`slices.caps`); default ``"trend"``, the structure beyond its end
        planes from the contours' area trend.
    lattice_factor : float
        Lattice values per point of a body's largest contour (``M = lattice_factor * max n``,
        :func:`slices.surface.lattice_size`), at least 1.
    lattice_mode : {"balanced", "uniform", "adaptive", "union"}
        Common ``u`` lattice (:func:`slices.surface.slice_curves`).
    correspondence : {"seed", "arc", "aligned"}
        ``u`` that links the slices (:func:`slices.surface.slice_curves`).
    start_angle : float or None
        Direction of ray 0 in radians from +x for every body; None: each body's
        own (:func:`slices.control_points.choose_start_angle`).
    samples : int or None
        Tessellation subdivisions per patch side; None gives each body edges of
        about :data:`slices.body.EDGE_MM` around and across the slices
        (:func:`slices.body.mesh_samples`).
    monotone : bool
        Limit the blend across the slices to be monotone and shape-preserving
        (:func:`surfaces.blending.limit_monotone`) on the first surface tried.
        Default False: the seed's blend is kept where its mesh does not fold
        (the limit flattens every extremum across the slices, and doubles the
        distance to a smooth true surface), and a body whose mesh folds is
        rebuilt with the limit anyway (:data:`slices.body.FALLBACKS`).
    unfold : bool
        Check every body's mesh for self-intersecting faces and rebuild folded
        bodies (:func:`slices.body.build_body`).
    surface_path : {"auto", "coons", "implicit"}
        ``auto``: the seed's patches for a single chain of contours (one contour per plane,
        no hole, one body), the implicit surface (:mod:`slices.implicit`) for branching,
        multi-body and holed structures, and for a chain whose patches' mesh folds (with
        ``unfold``); ``coons`` forces the patches (with their fallback surfaces and
        stepped slabs, :func:`slices.body.build_stepped`), ``implicit`` the implicit surface.

    Examples
    --------
    >>> SurfaceOptions(caps="half").n_rays
    64
    >>> SurfaceOptions(n_rays=2)
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: n_rays: need a whole number of at least 3 rays (seed 000, eq. 1), got 2
    """

    method: str = "blending"
    n_rays: int = 64
    caps: str = "trend"
    lattice_factor: float = 2.0
    lattice_mode: str = "balanced"
    correspondence: str = "seed"
    start_angle: float | None = None
    samples: int | None = None
    monotone: bool = False
    unfold: bool = True
    surface_path: str = "auto"

    def __post_init__(self) -> None:
        # the modules that use the names hold them (imported here: they import these defaults)
        from slices.caps import CAP_KINDS
        from slices.surface import CORRESPONDENCES, LATTICE_MODES, METHODS

        _choice(self.method, "method", tuple(METHODS))
        _choice(self.caps, "caps", CAP_KINDS)
        _choice(self.lattice_mode, "lattice_mode", LATTICE_MODES)
        _choice(self.correspondence, "correspondence", CORRESPONDENCES)
        _choice(self.surface_path, "surface_path", SURFACE_PATHS)
        n_rays = _whole(self.n_rays, "n_rays", 3, "rays (seed 000, eq. 1)")
        factor = positive(self.lattice_factor, "lattice_factor")
        if factor < 1:
            raise InputError(f"lattice_factor: must be at least 1, got {self.lattice_factor!r}")
        if self.start_angle is not None:
            object.__setattr__(self, "start_angle", float(as_array(self.start_angle, "start_angle", shape=())))
        if self.samples is not None:
            object.__setattr__(self, "samples", _whole(self.samples, "samples", 1, "subdivision per patch side"))
        for flag in ("monotone", "unfold"):
            if not isinstance(getattr(self, flag), bool | np.bool_):
                raise InputError(f"{flag}: must be True or False, got {getattr(self, flag)!r}")
            object.__setattr__(self, flag, bool(getattr(self, flag)))
        object.__setattr__(self, "n_rays", n_rays)
        object.__setattr__(self, "lattice_factor", factor)

@dataclass(frozen=True)
class ReadOptions:
    """How an input becomes contours (see :func:`slices.io.load`).

    Attributes
    ----------
    hu_min, hu_max : float or None
        Intensity (HU) window of CT series and grey image stacks.
    spacing : str or (float, float, float) or None
        ``z, y, x`` voxel spacing of mask stacks in mm.
    resample : bool
        Unequal slice spacing: resample CT series and image stacks onto uniform
        slices, or blend contour inputs at their true positions, instead of failing.
    slice_thickness : float or None
        Slab thickness (mm) of a structure drawn on a single plane (``--slice-thickness``);
        None: the structure set's ``ContourSlabThickness``, else the SliceThickness of
        the CT images beside it (:func:`slices.structure.read_roi`).
    """

    hu_min: float | None = None
    hu_max: float | None = None
    spacing: str | tuple | None = None
    resample: bool = False
    slice_thickness: float | None = None


#: Values of :attr:`SurfaceOptions.surface_path`.
SURFACE_PATHS = ("auto", "coons", "implicit")


def _names(cls) -> set[str]:
    return {f.name for f in fields(cls)}


def surface_options(options: SurfaceOptions | None = None, **keywords) -> SurfaceOptions:
    """Options object from an optional base and keyword overrides.

    Parameters
    ----------
    options : SurfaceOptions, optional
        Base options (the defaults when omitted).
    **keywords
        Fields of :class:`SurfaceOptions` to override.

    Returns
    -------
    SurfaceOptions

    Raises
    ------
    ValueError
        Unknown names, or values the options do not accept.

    Examples
    --------
    >>> opts = surface_options(caps="dome", n_rays=32)
    >>> opts.caps, opts.n_rays, opts.method
    ('dome', 32, 'blending')
    """
    unknown = set(keywords) - _names(SurfaceOptions)
    if unknown:
        raise InputError(f"options: unknown {sorted(unknown)}")
    base = SurfaceOptions() if options is None else options
    return replace(base, **keywords) if keywords else base


def split_options(keywords: dict, reading: ReadOptions | None = None,
                  options: SurfaceOptions | None = None) -> tuple[ReadOptions, SurfaceOptions]:
    """Sort keyword options into reading and surface options.

    Parameters
    ----------
    keywords : dict
        Fields of :class:`ReadOptions` and :class:`SurfaceOptions`.
    reading : ReadOptions, optional
        Base reading options.
    options : SurfaceOptions, optional
        Base surface options.

    Returns
    -------
    (ReadOptions, SurfaceOptions)

    Raises
    ------
    ValueError
        A name that is neither (the message lists them).

    Examples
    --------
    >>> read, surf = split_options({"hu_min": -500, "caps": "half"})
    >>> read.hu_min, surf.caps
    (-500, 'half')
    """
    read_names = _names(ReadOptions)
    unknown = set(keywords) - read_names - _names(SurfaceOptions)
    if unknown:
        raise InputError(f"options: unknown {sorted(unknown)}")
    read_kw = {k: v for k, v in keywords.items() if k in read_names}
    base = ReadOptions() if reading is None else reading
    surf = surface_options(options, **{k: v for k, v in keywords.items() if k not in read_names})
    return (replace(base, **read_kw) if read_kw else base), surf
