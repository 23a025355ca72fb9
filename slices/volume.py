"""A structure's whole volume from its contours' areas, and its uncertainty (GUM, k = 2).

:func:`whole_volume` integrates the section area ``A(z)`` of the whole structure
(outer contours minus holes, every body of a plane summed) over runs of
consecutive planes:

- between the planes, a cubic spline through the areas (not-a-knot: exact for
  the quadratic areas of spheres and ellipsoids); two planes: the parabola
  through them with a sphere's curvature (:data:`slices.caps.SPHERE_CURVATURE`);
- beyond each end plane, the trend cap (:func:`slices.caps.trend_cap_volume`):
  the area extrapolated from the last planes until it vanishes, or half a slab
  where it does not vanish within one spacing.

:func:`volume_uncertainty` gives its budget: slice sampling (the spline against
the trapezoid rule between the planes), the cap model (the trend against the
half-slab convention), the contour position (delineation, a systematic offset of
about half a pixel) and the pixel size (calibration), combined as independent
standard uncertainties and expanded with k = 2.
"""

from __future__ import annotations

import numpy as np

from slices.caps import SPHERE_CURVATURE, trend_cap_volume
from surfaces.validate import positive

__all__ = ["DELINEATION_PIXELS", "PIXEL_SIZE_REL", "SAMPLING_FACTOR", "CAP_FACTOR", "area_uncertainty",
           "plane_areas", "single_plane_range", "single_plane_volume", "whole_volume", "volume_uncertainty",
           "format_volume"]

#: Delineation: standard uncertainty of a contour's position, in pixels (a systematic offset of every contour,
#: normal: "about a pixel" at k = 2).
DELINEATION_PIXELS = 0.5

#: Pixel size: relative standard uncertainty of the in-plane scale (CT geometric QA: +-0.5 % at k = 2).
PIXEL_SIZE_REL = 0.0025

#: Slice sampling: standard uncertainty per mm^3 of |spline - trapezoid| between the planes (calibrated on
#: analytic solids, benchmarks/bench_ct_volume.py).
SAMPLING_FACTOR = 0.5

#: Cap model: standard uncertainty per mm^3 of |trend caps - half caps| (calibrated likewise).
CAP_FACTOR = 0.5

#: Planes farther apart than this many spacings start a new run (a gap in the structure).
GAP_SPACINGS = 1.5


def plane_areas(contours) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The structure's section area and outline length on each plane (outer contours minus holes).

    Parameters
    ----------
    contours : sequence of slices.io.Contour

    Returns
    -------
    z : numpy.ndarray, shape (P,)
        Planes (mm), increasing.
    area : numpy.ndarray, shape (P,)
        Net area (mm^2).
    perimeter : numpy.ndarray, shape (P,)
        Summed outline length (mm), holes included.
    """
    from slices.chaining import Outlines

    table = Outlines.of(list(contours))
    sign = np.where(table.hole, -1.0, 1.0)
    n = len(table.planes)
    area = np.bincount(table.plane_of, sign * np.abs(table.area), minlength=n)
    perimeter = np.bincount(table.plane_of, table.perimeter, minlength=n)
    return np.asarray(table.planes, float), area, perimeter


def _runs(z: np.ndarray, d: float) -> list[slice]:
    breaks = np.flatnonzero(np.diff(z) > GAP_SPACINGS * d) + 1
    edges = [0, *breaks.tolist(), len(z)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]


def _between(z: np.ndarray, a: np.ndarray) -> tuple[float, float]:
    """(model, trapezoid) volume between the first and last plane of one run."""
    if len(z) < 2:
        return 0.0, 0.0
    trap = float(np.sum((a[1:] + a[:-1]) / 2 * np.diff(z)))
    if len(z) == 2:
        h = float(z[1] - z[0])
        return trap - SPHERE_CURVATURE * h**3 / 12.0, trap  # the parabola with a sphere's curvature
    from scipy.interpolate import CubicSpline

    return float(CubicSpline(z, a).integrate(z[0], z[-1])), trap


def single_plane_volume(area: float, spacing: float) -> float:
    """Volume of a structure seen on one plane only: a sphere through its outline, or the slab.

    A sphere whose section on the plane has the contour's area, ``R^2 = A / pi + c^2``,
    its centre ``c`` from the plane uniform in ``[0, c_max]``: the nearer of half a
    spacing and the offset beyond which it would reach the next plane
    (``R < d - c``). Where no sphere fits (``A / pi >= d^2``: a flat structure),
    the slab ``A d`` as planning systems count it.

    Parameters
    ----------
    area : float
        Section area (mm^2).
    spacing : float
        Plane spacing (mm).

    Returns
    -------
    float
        mm^3.

    Examples
    --------
    >>> round(single_plane_volume(100.0, 3.0), 6)  # too wide for a sphere between the planes: the slab
    300.0
    """
    a, d = abs(float(area)), positive(spacing, "spacing")
    c_max = min(d / 2, (d * d - a / np.pi) / (2 * d))
    if c_max <= 0:
        return a * d
    c = (np.arange(64) + 0.5) / 64 * c_max
    return float(np.mean(4.0 / 3.0 * np.pi * (a / np.pi + c * c) ** 1.5))


def single_plane_range(area: float, spacing: float) -> tuple[float, float]:
    """The volumes of the spheres one outline fits (mm^3): cut at its equator, and nearest a pole.

    The sphere's centre from the plane runs from 0 (the outline is its equator) to
    ``c_max`` of :func:`single_plane_volume` (beyond, it would reach the next plane);
    the slab ``A d`` for both where no sphere fits.

    Parameters
    ----------
    area : float
        Section area (mm^2).
    spacing : float
        Plane spacing (mm).

    Returns
    -------
    (float, float)
        Smallest and largest volume.

    Examples
    --------
    >>> lo, hi = single_plane_range(np.pi, 3.0)  # a 2 mm outline at 3 mm spacing: a 1 mm sphere, or more
    >>> round(lo / np.pi, 6), hi > lo
    (1.333333, True)
    """
    a, d = abs(float(area)), positive(spacing, "spacing")
    c_max = min(d / 2, (d * d - a / np.pi) / (2 * d))
    if c_max <= 0:
        return a * d, a * d
    return 4.0 / 3.0 * np.pi * (a / np.pi) ** 1.5, 4.0 / 3.0 * np.pi * (a / np.pi + c_max * c_max) ** 1.5


def _short_run_note(z: np.ndarray, a: np.ndarray, d: float) -> str:
    """The note of a run of one or two planes: what the contours cannot tell, and what the volume assumes."""
    if len(z) == 1:
        lo, hi = single_plane_range(a[0], d)
        if lo == hi:
            return (f"plane z = {z[0]:.6g} mm alone: too wide for a sphere between the planes, counted as the slab "
                    f"of one spacing ({lo:.4g} mm^3)")
        return (f"plane z = {z[0]:.6g} mm alone: one outline fits a sphere cut anywhere between its equator and "
                f"near a pole ({lo:.4g} to {hi:.4g} mm^3 for this outline); the volume is the expectation over a "
                "uniform cut position, and its U covers the spread")
    return (f"planes z = {z[0]:.6g} and {z[-1]:.6g} mm alone: the shape between and beyond them is taken from a "
            "sphere's curvature (two areas cannot give a trend); each end's position within one spacing is in U")


def whole_volume(contours, spacing: float | None = None) -> dict:
    """The whole structure's volume from its section areas (see the module text).

    Parameters
    ----------
    contours : sequence of slices.io.Contour
    spacing : float, optional
        Plane spacing (mm); default the median step (1 mm for one plane).

    Returns
    -------
    dict
        ``volume_mm3`` (between the planes plus the trend caps), ``between_mm3``,
        ``caps_mm3`` (the trend caps), ``trapezoid_mm3`` (the trapezoid rule
        between the planes), ``half_caps_mm3`` (half slabs at every end),
        ``n_runs`` (runs of consecutive planes), ``spacing_mm`` and ``rule``.

    Examples
    --------
    A sphere of radius 10 mm cut every 3 mm from z = -8.5 (exact circles' areas): the whole volume.

    >>> from slices.io import Contour
    >>> t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    >>> cs = [Contour(z, np.sqrt(100 - z * z) * np.column_stack([np.cos(t), np.sin(t)]))
    ...       for z in np.arange(-8.5, 10, 3.0)]
    >>> round(whole_volume(cs)["volume_mm3"] / (4 / 3 * np.pi * 1000), 4)
    1.0
    """
    z, a, _ = plane_areas(contours)
    d = float(spacing) if spacing is not None else (float(np.median(np.diff(z))) if len(z) > 1 else 1.0)
    d = positive(d, "spacing")
    between = trap = caps = half = 0.0
    runs = _runs(z, d)
    short, notes = [], []
    for run in runs:
        zr, ar = z[run], a[run]
        if len(zr) <= 2:
            short.append((float(abs(ar[0])), float(abs(ar[-1]))))
            notes.append(_short_run_note(zr, ar, d))
        m, t = _between(zr, ar)
        between += m
        trap += t
        caps += single_plane_volume(ar[0], d) if len(zr) == 1 else \
            trend_cap_volume(ar[:3], d) + trend_cap_volume(ar[::-1][:3], d)
        half += (abs(ar[0]) + abs(ar[-1])) * d / 2
    return {"volume_mm3": between + caps, "between_mm3": between, "caps_mm3": caps, "trapezoid_mm3": trap,
            "half_caps_mm3": half, "n_runs": len(runs), "spacing_mm": d, "short_run_end_areas_mm2": short,
            "notes": notes,
            "rule": "section areas (outer contours minus holes) integrated with a cubic spline between the planes "
                    "(two planes: a parabola with a sphere's curvature), caps from the areas' trend beyond each "
                    "end plane (half a slab where the trend does not close within one spacing)"}


def volume_uncertainty(contours, spacing: float | None = None, pixel_mm: float = 1.0) -> dict:
    """The whole volume's uncertainty budget (GUM: standard uncertainties in quadrature, k = 2).

    Parameters
    ----------
    contours : sequence of slices.io.Contour
    spacing : float, optional
        Plane spacing (mm).
    pixel_mm : float
        In-plane pixel size of the image the contours were drawn on (mm; 1 mm when unknown).

    Returns
    -------
    dict
        ``volume_mm3`` (:func:`whole_volume`), ``u_mm3`` (combined standard
        uncertainty), ``k`` (2), ``U_mm3`` (expanded), ``budget`` (each
        component's ``u_mm3`` and ``basis``), and the area's ``area_rel_u`` is not
        given here (see :func:`slices.summary.summarize`).
    """
    w = whole_volume(contours, spacing)
    z, a, perim = plane_areas(contours)
    d = w["spacing_mm"]
    px = positive(pixel_mm, "pixel_mm")
    # outward offset delta of every contour: dV/d(delta) = sum of perimeters x spacing (Steiner, slab count)
    dv_ddelta = float(np.sum(perim) * d)
    budget = {
        "slice_sampling": {
            "u_mm3": SAMPLING_FACTOR * abs(w["between_mm3"] - w["trapezoid_mm3"]),
            "basis": f"{SAMPLING_FACTOR:g} x |spline - trapezoid rule| between the planes"},
        "cap_model": {
            "u_mm3": float(np.sqrt((CAP_FACTOR * abs(w["caps_mm3"] - w["half_caps_mm3"])) ** 2
                                   + sum((a0 * a0 + a1 * a1) * d * d / 12.0
                                         for a0, a1 in w["short_run_end_areas_mm2"]))),
            "basis": f"{CAP_FACTOR:g} x |trend caps - half caps| (the conventions' spread beyond the end planes); "
                     "runs of one or two planes (caps from a prior): each end anywhere within one spacing "
                     "(end area x spacing / sqrt(12))"},
        "contour_position": {
            "u_mm3": dv_ddelta * DELINEATION_PIXELS * px,
            "basis": f"every contour offset by u = {DELINEATION_PIXELS:.3g} pixel ({DELINEATION_PIXELS * px:.3g} mm; "
                     "about a pixel at k = 2): perimeters x spacing x offset"},
        "pixel_size": {
            "u_mm3": 2.0 * PIXEL_SIZE_REL * abs(w["volume_mm3"]),
            "basis": f"in-plane scale u = {PIXEL_SIZE_REL * 100:.2f} % (+-0.5 % at k = 2), volume ~ scale^2"},
    }
    u = float(np.sqrt(sum(c["u_mm3"] ** 2 for c in budget.values())))
    return {"volume_mm3": w["volume_mm3"], "u_mm3": u, "k": 2, "U_mm3": 2.0 * u, "budget": budget,
            "pixel_mm": px, "model": w}


def area_uncertainty(contours, area_mm2: float, spacing: float | None = None, pixel_mm: float = 1.0) -> dict:
    """The surface area's uncertainty budget (GUM, k = 2), the same four causes as the volume's.

    Parameters
    ----------
    contours : sequence of slices.io.Contour
    area_mm2 : float
        The area measured (the written surface's).
    spacing : float, optional
        Plane spacing (mm).
    pixel_mm : float
        In-plane pixel size (mm).

    Returns
    -------
    dict
        ``area_mm2``, ``u_mm2``, ``k`` (2), ``U_mm2`` and ``budget`` (each component's
        ``u_mm2`` and ``basis``): slice sampling (0.5 x the area's difference from the
        stack of prisms, perimeters x spacing plus the end faces), cap model (0.5 x the
        walls of half a slab at every end of a run), contour position (an offset of
        0.5 pixel: each outline's length grows by 2 pi per outer contour and shrinks by
        2 pi per hole, the end faces by their perimeters) and pixel size (the area
        scales as the in-plane scale to a power between 1 and 2: 1.5).
    """
    from slices.chaining import Outlines

    table = Outlines.of(list(contours))
    sign = np.where(table.hole, -1.0, 1.0)
    n = len(table.planes)
    z = np.asarray(table.planes, float)
    d = float(spacing) if spacing is not None else (float(np.median(np.diff(z))) if n > 1 else 1.0)
    d = positive(d, "spacing")
    area_net = np.bincount(table.plane_of, sign * np.abs(table.area), minlength=n)
    perim = np.bincount(table.plane_of, table.perimeter, minlength=n)
    turning = np.bincount(table.plane_of, sign, minlength=n)
    runs = _runs(z, d)
    prisms = float(np.sum(perim) * d)
    ends_perim = sum(perim[r][0] + perim[r][-1] for r in runs)
    prisms += sum(abs(area_net[r][0]) + abs(area_net[r][-1]) for r in runs)
    px = positive(pixel_mm, "pixel_mm")
    ds_ddelta = float(np.sum(2 * np.pi * turning) * d + ends_perim)
    budget = {
        "slice_sampling": {"u_mm2": SAMPLING_FACTOR * abs(float(area_mm2) - prisms),
                           "basis": f"{SAMPLING_FACTOR:g} x |area - stack of prisms (perimeters x spacing + end "
                                    "faces)|"},
        "cap_model": {"u_mm2": CAP_FACTOR * ends_perim * d / 2,
                      "basis": f"{CAP_FACTOR:g} x the walls of half a slab at every end (the conventions' spread)"},
        "contour_position": {"u_mm2": abs(ds_ddelta) * DELINEATION_PIXELS * px,
                             "basis": f"every contour offset by {DELINEATION_PIXELS:g} pixel: 2 pi x spacing per outer "
                                      "contour (minus per hole) plus the end faces' perimeters, x offset"},
        "pixel_size": {"u_mm2": 1.5 * PIXEL_SIZE_REL * abs(float(area_mm2)),
                       "basis": f"in-plane scale u = {PIXEL_SIZE_REL * 100:.2f} %, area ~ scale^1.5"},
    }
    u = float(np.sqrt(sum(c["u_mm2"] ** 2 for c in budget.values())))
    return {"area_mm2": float(area_mm2), "u_mm2": u, "k": 2, "U_mm2": 2.0 * u, "budget": budget, "pixel_mm": px}


def format_volume(volume_mm3: float, U_mm3: float) -> str:
    """``volume = 12.34 +- 0.56 cc (k = 2)``, as the photometric figures are printed.

    Parameters
    ----------
    volume_mm3, U_mm3 : float
        Volume and its expanded uncertainty (mm^3).

    Returns
    -------
    str

    Examples
    --------
    >>> format_volume(12340.0, 560.0)
    'volume = 12.34 +- 0.56 cc (k = 2)'
    >>> format_volume(105.6, 9.1)
    'volume = 0.1056 +- 0.0091 cc (k = 2)'
    """
    v, u = volume_mm3 / 1000.0, U_mm3 / 1000.0
    digits = max(2, 1 - int(np.floor(np.log10(u))) if u > 0 else 2)
    return f"volume = {v:.{digits}f} +- {u:.{digits}f} cc (k = 2)"
