"""Analytic height-field scenes with exact slopes and exact defect truth.

Every scene is a closed-form height ``z(x, y)`` in millimetres whose slopes
``p = dz/dx`` and ``q = dz/dy`` are differentiated by hand (never by finite
differences), so normals, defect depths, widths, lengths, areas and volumes are
known exactly. The image convention is stated once in :data:`CONVENTION`.

A scene is an :class:`AnalyticSurface`: a base plane plus closed-form features,
evaluated at ANY ``(x, y)`` in mm (so that a perspective ray can be intersected
with the true surface, :mod:`datasets_synthetic.cameras`). A :class:`HeightField`
is that surface sampled at the pixel centres of :data:`surfaces.grid.GRID_CONVENTION`;
it keeps the surface as ``surface``.

Defects (seed 002a: surface defects seen by a triad of images) are built on a
"capsule" distance: the distance ``d`` of a point to a segment of length
``length - width`` along the defect axis. A V-crack is ``z = -D (1 - 2 d / w)``,
a U-scratch ``z = -D (1 - (2 d / w)^2)`` (both for ``d < w / 2``), so their
footprint is a stadium of width ``w`` and overall length ``L`` with exact area
``(L - w) w + pi w^2 / 4``. A spherical dent is the cap of a sphere pressed
``D`` deep with rim diameter ``w``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photometric.normals import normals_from_slopes
from surfaces.grid import image_shape, pixel_axes, pixel_grid, xy_to_pixel
from surfaces.validate import as_array, InputError, positive

CONVENTION = (
    "Image convention (DiLiGenT): x to the right (column index), y up (row 0 is the TOP row, "
    "so y decreases as the row index grows), z towards the camera. Pixel (row, col) of an "
    "H x W image has its centre at x = (col - (W - 1) / 2) * pixel_size, "
    "y = ((H - 1) / 2 - row) * pixel_size, in mm. p = dz/dx, q = dz/dy (y up), unit normal "
    "n = (-p, -q, 1) / sqrt(1 + p^2 + q^2). Light directions are unit vectors from the surface "
    "towards the light in the same frame; a light's azimuth is measured from +x towards +y "
    "(counter-clockwise as seen by the camera), its slant from +z."
)

SCENES = ("plane", "tilted", "sphere", "crack", "scratch", "dent", "bumps", "vase", "plate",
          "inspection_scratch", "inspection_crack", "inspection_dent")

#: The inspection part's defect (issue 15: a flat 60 mm plate with one 0.10 mm deep scratch, or a
#: crack or dent instead): kind, depth, width and length in mm, centre (x, y) in mm, axis in degrees.
INSPECTION_DEFECTS = {
    "scratch": {"kind": "u_scratch", "depth_mm": 0.10, "width_mm": 0.5, "length_mm": 12.0,
                "center_mm": (3.0, -2.0), "axis_deg": 25.0},
    "crack": {"kind": "v_crack", "depth_mm": 0.10, "width_mm": 0.4, "length_mm": 10.0,
              "center_mm": (-4.0, 3.0), "axis_deg": -30.0},
    "dent": {"kind": "spherical_dent", "depth_mm": 0.10, "width_mm": 3.0, "length_mm": 3.0,
             "center_mm": (5.0, 4.0), "axis_deg": 0.0},
}


# ----------------------------------------------------------------------------- closed-form terms
# Each feature evaluates (z, p, q, inside) at arrays x, y (mm) and states the range of its z and a
# bound on its slope |grad z|; the ray intersection of datasets_synthetic.cameras brackets with them.


def _capsule(x, y, cx, cy, axis_deg, half_segment):
    """Distance to a segment and its gradient (the unit vector away from the nearest point)."""
    a = np.deg2rad(axis_deg)
    ux, uy = np.cos(a), np.sin(a)
    dx, dy = x - cx, y - cy
    s = np.clip(dx * ux + dy * uy, -half_segment, half_segment)
    rx, ry = dx - s * ux, dy - s * uy
    d = np.hypot(rx, ry)
    safe = np.where(d > 0, d, 1.0)
    return d, rx / safe, ry / safe


@dataclass(frozen=True)
class _Groove:
    """V-crack or U-scratch of depth D, width w and overall length L along ``axis_deg``."""

    kind: str
    depth: float
    width: float
    length: float
    cx: float
    cy: float
    axis_deg: float

    def evaluate(self, x, y):
        half_w = self.width / 2.0
        d, gx, gy = _capsule(x, y, self.cx, self.cy, self.axis_deg, (self.length - self.width) / 2.0)
        inside = d < half_w
        t = d / half_w
        if self.kind == "v_crack":
            z = np.where(inside, -self.depth * (1.0 - t), 0.0)
            dz_dd = np.where(inside, self.depth / half_w, 0.0)
        else:
            z = np.where(inside, -self.depth * (1.0 - t * t), 0.0)
            dz_dd = np.where(inside, 2.0 * self.depth * t / half_w, 0.0)
        return z, dz_dd * gx, dz_dd * gy, inside

    @property
    def bounds(self) -> tuple[float, float]:
        return -self.depth, 0.0

    @property
    def max_slope(self) -> float:
        # V: constant wall slope D / (w/2); U: steepest at the rim, 2 D / (w/2)
        return (1.0 if self.kind == "v_crack" else 2.0) * self.depth / (self.width / 2.0)


@dataclass(frozen=True)
class _Dent:
    """Spherical dent: a sphere of radius R pressed D deep, rim radius a."""

    depth: float
    rim: float
    radius: float
    cx: float
    cy: float

    def evaluate(self, x, y):
        dx, dy = x - self.cx, y - self.cy
        r2 = dx * dx + dy * dy
        inside = r2 < self.rim * self.rim
        root = np.sqrt(np.where(inside, self.radius * self.radius - r2, 1.0))
        z = np.where(inside, -(root - (self.radius - self.depth)), 0.0)
        return z, np.where(inside, dx / root, 0.0), np.where(inside, dy / root, 0.0), inside

    @property
    def bounds(self) -> tuple[float, float]:
        return -self.depth, 0.0

    @property
    def max_slope(self) -> float:
        return self.rim / (self.radius - self.depth)


@dataclass(frozen=True)
class _Cap:
    """Spherical cap of sphere radius R and height h on the base, rim radius a."""

    radius: float
    height: float
    rim: float
    cx: float
    cy: float

    def evaluate(self, x, y):
        dx, dy = x - self.cx, y - self.cy
        r2 = dx * dx + dy * dy
        inside = r2 < self.rim * self.rim
        root = np.sqrt(np.where(inside, self.radius * self.radius - r2, 1.0))
        z = np.where(inside, root - (self.radius - self.height), 0.0)
        return z, np.where(inside, -dx / root, 0.0), np.where(inside, -dy / root, 0.0), inside

    @property
    def bounds(self) -> tuple[float, float]:
        return 0.0, self.height

    @property
    def max_slope(self) -> float:
        below = self.radius - self.height
        return self.rim / below if below > 0 else np.inf


@dataclass(frozen=True)
class _Bump:
    """Gaussian bump ``A exp(-r^2 / (2 s^2))``."""

    amplitude: float
    sigma: float
    cx: float
    cy: float

    def evaluate(self, x, y):
        s2 = self.sigma * self.sigma
        g = self.amplitude * np.exp(-((x - self.cx) ** 2 + (y - self.cy) ** 2) / (2.0 * s2))
        return g, -(g * (x - self.cx) / s2), -(g * (y - self.cy) / s2), np.zeros(np.shape(g), bool)

    @property
    def bounds(self) -> tuple[float, float]:
        return min(0.0, self.amplitude), max(0.0, self.amplitude)

    @property
    def max_slope(self) -> float:
        return abs(self.amplitude) / self.sigma * np.exp(-0.5)


def _vase_profile(v):
    """Half-width f(v) of the classic vase outline and f'(v), v in [0, 1] bottom to top."""
    a = 6.0 * v + 1.0
    b = v - 1.0
    c = 3.0 * v - 2.0
    f = 0.15 - 0.1 * v * a**2 * b**2 * c**2
    df = -0.1 * (a**2 * b**2 * c**2 + v * (12.0 * a * b**2 * c**2 + 2.0 * a**2 * b * c**2
                                           + 6.0 * a**2 * b**2 * c))
    return f, df


@dataclass(frozen=True)
class _Vase:
    """The vase relief of peak height H on a square of side S (see :func:`vase`)."""

    height: float
    side: float
    fmax: float
    dfmax: float

    def evaluate(self, x, y):
        u = x / self.side
        v = np.clip(y / self.side + 0.5, 0.0, 1.0)
        f, df = _vase_profile(v)
        g = (f * f - u * u) / self.fmax**2
        inside = (g > 0) & (y / self.side + 0.5 >= 0) & (y / self.side + 0.5 <= 1)
        gp = np.where(inside, g, 0.0)
        z = self.height * gp**1.5
        dz_dg = 1.5 * self.height * np.sqrt(gp)
        p = np.where(inside, dz_dg * (-2.0 * u) / self.fmax**2 / self.side, 0.0)
        q = np.where(inside, dz_dg * (2.0 * f * df) / self.fmax**2 / self.side, 0.0)
        return z, p, q, inside

    @property
    def bounds(self) -> tuple[float, float]:
        return 0.0, self.height

    @property
    def max_slope(self) -> float:
        # g <= 1, |u| <= f <= fmax and |f f'| <= fmax max|f'|, so |grad z| <= 3 H sqrt(1 + f'^2) / (fmax S)
        return 3.0 * self.height * np.sqrt(1.0 + self.dfmax**2) / (self.fmax * self.side)


@dataclass(frozen=True)
class AnalyticSurface:
    """A closed-form height field ``z(x, y) = z0 + sx x + sy y + sum of features`` in mm.

    Attributes
    ----------
    plane : (float, float, float)
        Base plane ``(z0, sx, sy)``: height at the origin (mm) and slopes dz/dx, dz/dy.
    features : tuple
        Closed-form features (grooves, dents, caps, bumps, vase) added to the plane.
    """

    plane: tuple[float, float, float] = (0.0, 0.0, 0.0)
    features: tuple = ()

    def evaluate(self, x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Height, exact slopes and feature footprint at any points.

        Parameters
        ----------
        x, y : array_like
            Coordinates in mm (x right, y up); broadcast against each other.

        Returns
        -------
        z, p, q : float64 arrays
            Height (mm) and slopes ``dz/dx``, ``dz/dy`` at the points.
        inside : bool array
            True inside a feature's footprint (a defect, the cap, the vase's support).

        Examples
        --------
        >>> s = make_scene("tilted", 8, 0.1).surface
        >>> [round(float(v), 12) for v in s.evaluate(2.0, -1.0)[:3]]
        [0.15, 0.1, 0.05]
        """
        x, y = np.broadcast_arrays(as_array(x, "x"), as_array(y, "y"))
        return self._evaluate(x, y)

    def _evaluate(self, x: np.ndarray, y: np.ndarray):
        """:meth:`evaluate` on checked float64 arrays of one shape."""
        z0, sx, sy = self.plane
        z = z0 + sx * x + sy * y
        p = np.full(x.shape, sx)
        q = np.full(x.shape, sy)
        inside = np.zeros(x.shape, bool)
        for feature in self.features:
            dz, dp, dq, m = feature.evaluate(x, y)
            z = z + dz
            p = p + dp
            q = q + dq
            inside |= m
        return z, p, q, inside

    @property
    def relief_bounds(self) -> tuple[float, float]:
        """Lowest and highest value of ``z - (sx x + sy y)`` anywhere (mm): z0 plus the features' ranges."""
        lo = self.plane[0] + sum(f.bounds[0] for f in self.features)
        hi = self.plane[0] + sum(f.bounds[1] for f in self.features)
        return float(lo), float(hi)

    @property
    def relief_max_slope(self) -> float:
        """An upper bound of ``|grad (z - sx x - sy y)|`` anywhere (the features' slope bounds, summed)."""
        return float(sum(f.max_slope for f in self.features))


@dataclass(frozen=True)
class HeightField:
    """An analytic height field sampled at pixel centres.

    Attributes
    ----------
    height : (H, W) float64 array
        Height z in mm (see :data:`CONVENTION`).
    p, q : (H, W) float64 arrays
        Exact slopes dz/dx and dz/dy (dimensionless, y up).
    normals : (H, W, 3) float64 array
        Unit normals ``(-p, -q, 1) / sqrt(1 + p^2 + q^2)``.
    defect_mask : (H, W) bool array
        Pixel centres that lie inside a defect's footprint.
    defects : tuple of dict
        True defect parameters (see :func:`v_crack` for the keys).
    pixel_size : float
        Pixel size in mm.
    name : str
        Scene name.
    params : dict
        Parameters that produced the scene (JSON-serialisable).
    surface : AnalyticSurface or None
        The closed-form surface that was sampled (evaluate it at any (x, y)).
    """

    height: np.ndarray
    p: np.ndarray
    q: np.ndarray
    normals: np.ndarray
    defect_mask: np.ndarray
    defects: tuple[dict, ...] = ()
    pixel_size: float = 1.0
    name: str = ""
    params: dict = field(default_factory=dict)
    surface: AnalyticSurface | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the image grid."""
        return self.height.shape


def _sample(surface: AnalyticSurface, size, pixel_size, defects, name, params) -> HeightField:
    """The surface at the pixel centres of an image grid."""
    x, y = pixel_grid(size, pixel_size)
    z, p, q, mask = surface._evaluate(x, y)
    return HeightField(
        height=z,
        p=p,
        q=q,
        normals=normals_from_slopes(p, q),
        defect_mask=mask,
        defects=tuple(defects),
        pixel_size=float(pixel_size),
        name=name,
        params=params,
        surface=surface,
    )


def _center_mm(center_px, size, pixel_size) -> tuple[float, float]:
    h, w = image_shape(size)
    if center_px is None:
        return 0.0, 0.0
    c = as_array(center_px, "center_px", shape=(2,))
    return (c[1] - (w - 1) / 2.0) * pixel_size, ((h - 1) / 2.0 - c[0]) * pixel_size


def _defect_record(kind, depth, width, length, area, volume, cx, cy, axis_deg, size, ps) -> dict:
    row, col = xy_to_pixel(cx, cy, size, ps)
    return {
        "kind": kind,
        "depth_mm": float(depth),
        "width_mm": float(width),
        "length_mm": float(length),
        "area_mm2": float(area),
        "volume_mm3": float(volume),
        "depth_px": float(depth / ps),
        "width_px": float(width / ps),
        "length_px": float(length / ps),
        "area_px": float(area / ps**2),
        "center_px": [float(row), float(col)],
        "center_mm": [float(cx), float(cy)],
        "axis_deg": float(axis_deg),
    }


def _groove_mm(kind, size, ps, depth_mm, width_mm, length_mm, cx, cy, axis_deg):
    """A groove feature centred at (cx, cy) mm, its defect record and parameters."""
    depth = positive(depth_mm, "depth_mm")
    width = positive(width_mm, "width_mm")
    length = positive(length_mm, "length_mm")
    if length < width:
        raise InputError(f"length_mm: must be at least width_mm ({width}), got {length}")
    half_w = width / 2.0
    if kind == "v_crack":
        section, end = depth * width / 2.0, np.pi * half_w**2 * depth / 3.0
    else:
        section, end = 2.0 * depth * width / 3.0, np.pi * half_w**2 * depth / 2.0
    area = (length - width) * width + np.pi * half_w**2
    volume = section * (length - width) + end
    rec = _defect_record(kind, depth, width, length, area, volume, cx, cy, axis_deg, size, ps)
    params = {"depth_mm": depth, "width_mm": width, "length_mm": length,
              "center_mm": [cx, cy], "axis_deg": float(axis_deg)}
    return _Groove(kind, depth, width, length, cx, cy, float(axis_deg)), rec, params


def _groove(kind, size, pixel_size, depth_mm, width_mm, length_mm, center_px, axis_deg):
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    cx, cy = _center_mm(center_px, (h, w), ps)
    return _groove_mm(kind, (h, w), ps, depth_mm, width_mm, length_mm, cx, cy, axis_deg)


def v_crack(
    size=256,
    pixel_size: float = 0.05,
    depth_mm: float = 0.2,
    width_mm: float = 0.6,
    length_mm: float = 6.0,
    center_px=None,
    axis_deg: float = 0.0,
) -> HeightField:
    """A V-shaped crack on a flat plate (seed 002a: the test image of a crack).

    ``z = -D (1 - 2 d / w)`` for ``d < w / 2``, ``d`` the distance to the crack's
    central segment (length ``L - w``), so the ends are half cones.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    depth_mm, width_mm, length_mm : float
        Depth D, width w and overall length L (L >= w) in mm.
    center_px : (row, col), optional
        Crack centre in (fractional) pixels; the image centre by default.
    axis_deg : float
        Direction of the crack's length, from +x towards +y (y up), degrees.

    Returns
    -------
    HeightField
        ``defects[0]`` holds ``kind, depth_mm, width_mm, length_mm, area_mm2,
        volume_mm3`` (exact: ``(L - w) D w / 2 + pi w^2 D / 12``), the same in px,
        ``center_px`` (row, col), ``center_mm`` (x, y) and ``axis_deg``.
    """
    h, w = image_shape(size)
    term, rec, prm = _groove("v_crack", (h, w), pixel_size, depth_mm, width_mm, length_mm, center_px, axis_deg)
    return _sample(AnalyticSurface(features=(term,)), (h, w), pixel_size, [rec], "crack", prm)


def u_scratch(
    size=256,
    pixel_size: float = 0.05,
    depth_mm: float = 0.05,
    width_mm: float = 0.4,
    length_mm: float = 5.0,
    center_px=None,
    axis_deg: float = 0.0,
) -> HeightField:
    """A U-shaped (parabolic) scratch: ``z = -D (1 - (2 d / w)^2)`` for ``d < w / 2``.

    Parameters and returns as :func:`v_crack`; the exact volume is
    ``(L - w) 2 D w / 3 + pi w^2 D / 8``.
    """
    h, w = image_shape(size)
    term, rec, prm = _groove("u_scratch", (h, w), pixel_size, depth_mm, width_mm, length_mm, center_px, axis_deg)
    return _sample(AnalyticSurface(features=(term,)), (h, w), pixel_size, [rec], "scratch", prm)


def _dent_mm(size, ps, depth_mm, width_mm, cx, cy):
    """A spherical-dent feature centred at (cx, cy) mm, its defect record and parameters."""
    depth = positive(depth_mm, "depth_mm")
    width = positive(width_mm, "width_mm")
    a = width / 2.0
    if depth >= a:
        raise InputError(f"depth_mm: a spherical dent needs depth < width/2 ({a}), got {depth}")
    radius = (a * a + depth * depth) / (2.0 * depth)
    volume = np.pi * depth**2 * (3.0 * radius - depth) / 3.0
    rec = _defect_record("spherical_dent", depth, width, width, np.pi * a * a, volume, cx, cy, 0.0, size, ps)
    rec["sphere_radius_mm"] = float(radius)
    prm = {"depth_mm": depth, "width_mm": width, "center_mm": [cx, cy],
           "sphere_radius_mm": float(radius)}
    return _Dent(depth, a, radius, cx, cy), rec, prm


def _dent(size, pixel_size, depth_mm, width_mm, center_px):
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    cx, cy = _center_mm(center_px, (h, w), ps)
    return _dent_mm((h, w), ps, depth_mm, width_mm, cx, cy)


def spherical_dent(
    size=256, pixel_size: float = 0.05, depth_mm: float = 0.1, width_mm: float = 2.0,
    center_px=None,
) -> HeightField:
    """A spherical dent: a sphere cap of rim diameter w pressed D deep into a flat plate.

    ``z = -(sqrt(R^2 - r^2) - (R - D))`` for ``r < w / 2`` with
    ``R = ((w/2)^2 + D^2) / (2 D)``; exact volume ``pi D^2 (3 R - D) / 3``.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    depth_mm, width_mm : float
        Depth D and rim diameter w in mm (D < w / 2).
    center_px : (row, col), optional
        Centre in pixels; the image centre by default.

    Returns
    -------
    HeightField
        One defect record (see :func:`v_crack`), ``length_mm == width_mm``.
    """
    h, w = image_shape(size)
    term, rec, prm = _dent((h, w), pixel_size, depth_mm, width_mm, center_px)
    return _sample(AnalyticSurface(features=(term,)), (h, w), pixel_size, [rec], "dent", prm)


def plane(size=256, pixel_size: float = 0.05, z0: float = 0.0) -> HeightField:
    """A flat plane ``z = z0`` (mm), normals (0, 0, 1).

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    z0 : float
        Height in mm.

    Returns
    -------
    HeightField
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    z0 = float(z0)
    if not np.isfinite(z0):
        raise InputError(f"z0: must be finite, got {z0!r}")
    return _sample(AnalyticSurface(plane=(z0, 0.0, 0.0)), (h, w), ps, [], "plane", {"z0_mm": z0})


def tilted_plane(
    size=256, pixel_size: float = 0.05, slope_x: float = 0.1, slope_y: float = 0.05
) -> HeightField:
    """A tilted plane ``z = slope_x x + slope_y y`` (x right, y up, mm).

    A positive ``slope_x`` rises to the right, so its normals have negative x.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    slope_x, slope_y : float
        p and q (dimensionless).

    Returns
    -------
    HeightField
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    sx, sy = float(slope_x), float(slope_y)
    if not (np.isfinite(sx) and np.isfinite(sy)):
        raise InputError(f"slope_x, slope_y: must be finite, got {slope_x!r}, {slope_y!r}")
    return _sample(AnalyticSurface(plane=(0.0, sx, sy)), (h, w), ps, [], "tilted",
                   {"slope_x": sx, "slope_y": sy})


def sphere_cap(
    size=256, pixel_size: float = 0.05, radius_mm: float | None = None,
    height_mm: float | None = None, center_px=None,
) -> HeightField:
    """A spherical cap on a flat base: ``z = sqrt(R^2 - r^2) - (R - h)`` for ``r < a``.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    radius_mm : float, optional
        Sphere radius R; default 0.45 of the smaller image side.
    height_mm : float, optional
        Cap height h <= R; default 0.8 R (the rim slope stays finite, about 78 deg).
    center_px : (row, col), optional
        Cap centre in pixels; the image centre by default.

    Returns
    -------
    HeightField
        ``params`` holds R, h and the rim radius ``a = sqrt(2 R h - h^2)``;
        ``defect_mask`` marks the cap's footprint (no defect records).
    """
    h_px, w_px = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    radius = positive(radius_mm, "radius_mm") if radius_mm is not None else 0.45 * min(h_px, w_px) * ps
    cap = positive(height_mm, "height_mm") if height_mm is not None else 0.8 * radius
    if cap > radius:
        raise InputError(f"height_mm: must not exceed radius_mm ({radius}), got {cap}")
    rim = np.sqrt(2.0 * radius * cap - cap * cap)
    cx, cy = _center_mm(center_px, (h_px, w_px), ps)
    prm = {"radius_mm": radius, "height_mm": cap, "rim_radius_mm": float(rim), "center_mm": [cx, cy]}
    surface = AnalyticSurface(features=(_Cap(radius, cap, float(rim), cx, cy),))
    return _sample(surface, (h_px, w_px), ps, [], "sphere", prm)


def gaussian_bumps(
    size=256, pixel_size: float = 0.05, centers_px=None, amplitudes_mm=None, sigmas_mm=None,
    n_bumps: int = 5, seed: int = 0,
) -> HeightField:
    """A sum of Gaussian bumps ``z = sum_k A_k exp(-|x - c_k|^2 / (2 s_k^2))``.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    centers_px : (K, 2) array_like, optional
        Bump centres (row, col) in pixels; random (from ``seed``) when omitted.
    amplitudes_mm : (K,) array_like, optional
        Heights A_k in mm (negative for pits); random when omitted.
    sigmas_mm : (K,) array_like, optional
        Widths s_k in mm; random when omitted.
    n_bumps : int
        Number of random bumps when ``centers_px`` is omitted.
    seed : int
        Seed of the random bumps.

    Returns
    -------
    HeightField
        ``params["bumps"]`` lists the bumps; no defect records.
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    rng = np.random.default_rng(seed)
    side = min(h, w) * ps
    if centers_px is None:
        k = int(n_bumps)
        if k < 1:
            raise InputError(f"n_bumps: must be at least 1, got {n_bumps}")
        centers_px = np.column_stack([rng.uniform(0.15, 0.85, k) * (h - 1),
                                      rng.uniform(0.15, 0.85, k) * (w - 1)])
    centers = as_array(centers_px, "centers_px", shape=(None, 2))
    k = len(centers)
    amps = (as_array(amplitudes_mm, "amplitudes_mm", shape=(k,)) if amplitudes_mm is not None
            else rng.uniform(0.02, 0.08, k) * side)
    sig = (as_array(sigmas_mm, "sigmas_mm", shape=(k,)) if sigmas_mm is not None
           else rng.uniform(0.04, 0.09, k) * side)
    if np.any(sig <= 0):
        raise InputError("sigmas_mm: every width must be positive")
    terms, bumps = [], []
    for (row, col), a, s in zip(centers, amps, sig):
        cx, cy = _center_mm((row, col), (h, w), ps)
        terms.append(_Bump(float(a), float(s), float(cx), float(cy)))
        bumps.append({"center_px": [float(row), float(col)], "center_mm": [cx, cy],
                      "amplitude_mm": float(a), "sigma_mm": float(s)})
    return _sample(AnalyticSurface(features=tuple(terms)), (h, w), ps, [], "bumps", {"bumps": bumps})


def vase(size=256, pixel_size: float = 0.05, height_mm: float | None = None) -> HeightField:
    """A smooth vase-shaped relief (C1 everywhere, zero slope on its outline).

    With normalised coordinates ``u = x / S`` in [-1/2, 1/2] and ``v = y / S + 1/2``
    in [0, 1] (S the smaller image side in mm), the classic vase outline
    ``f(v) = 0.15 - 0.1 v (6v + 1)^2 (v - 1)^2 (3v - 2)^2`` bounds the relief
    ``z = H ((f^2 - u^2) / f_max^2)^(3/2)`` for ``|u| < f(v)`` and 0 outside.
    Slopes by the chain rule (exact).

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    height_mm : float, optional
        Peak height H; default 0.15 S.

    Returns
    -------
    HeightField
        ``defect_mask`` marks the vase's support ``|u| < f(v)``; no defect records.
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    side = min(h, w) * ps
    top = positive(height_mm, "height_mm") if height_mm is not None else 0.15 * side
    f, df = _vase_profile(np.linspace(0.0, 1.0, 20001))
    # f' is a polynomial sampled densely; 1 % on its largest value keeps the slope bound an upper bound
    term = _Vase(top, side, float(np.max(f)), 1.01 * float(np.max(np.abs(df))))
    return _sample(AnalyticSurface(features=(term,)), (h, w), ps, [], "vase", {"height_mm": top, "side_mm": side})


def inspection_plate(
    size=512, pixel_size: float = 0.05, seed: int = 0, tilt: tuple[float, float] = (0.0, 0.0),
    jitter: bool = True,
) -> HeightField:
    """A flat inspection plate with a V-crack, a spherical dent and a U-scratch.

    Defect sizes are fixed fractions of the plate side ``S = size * pixel_size``
    (at 512 px and 0.05 mm: crack 10.2 x 0.77 mm, 0.23 mm deep; dent 3.1 mm
    across, 0.26 mm deep; scratch 7.7 x 0.51 mm, 0.077 mm deep), so the scene
    looks the same at any resolution. Their places (crack upper left, dent right,
    scratch at the bottom) and axes are jittered slightly by ``seed``; the
    footprints never overlap. Wall slopes stay below 0.6 (31 deg).

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels (at least 32).
    pixel_size : float
        Pixel size in mm.
    seed : int
        Seed of the placement jitter.
    tilt : (float, float)
        Slopes (p, q) of the plate itself, added to the whole scene.
    jitter : bool
        Jitter places and axes (default True); False gives the nominal layout.

    Returns
    -------
    HeightField
        Three defect records: crack, dent, scratch (in this order); depths are
        measured from the (tilted) plate.
    """
    h, w = image_shape(size)
    if min(h, w) < 32:
        raise InputError(f"size: the inspection plate needs at least 32 pixels, got {size!r}")
    ps = positive(pixel_size, "pixel_size")
    tilt = as_array(tilt, "tilt", shape=(2,))
    rng = np.random.default_rng(seed)
    s = min(h, w) * ps
    j = (lambda n: rng.uniform(-1.0, 1.0, n)) if jitter else (lambda n: np.zeros(n))
    jc, jd, js = j(3), j(2), j(3)
    crack = _groove("v_crack", (h, w), ps, 0.009 * s, 0.03 * s, 0.40 * s,
                    ((0.32 + 0.03 * jc[0]) * (h - 1), (0.36 + 0.03 * jc[1]) * (w - 1)),
                    30.0 + 8.0 * jc[2])
    dent = _dent((h, w), ps, 0.01 * s, 0.12 * s,
                 ((0.40 + 0.03 * jd[0]) * (h - 1), (0.78 + 0.03 * jd[1]) * (w - 1)))
    scratch = _groove("u_scratch", (h, w), ps, 0.003 * s, 0.02 * s, 0.30 * s,
                      ((0.80 + 0.02 * js[0]) * (h - 1), (0.50 + 0.03 * js[1]) * (w - 1)),
                      -15.0 + 8.0 * js[2])
    surface = AnalyticSurface(plane=(0.0, float(tilt[0]), float(tilt[1])),
                              features=(crack[0], dent[0], scratch[0]))
    prm = {"seed": int(seed), "tilt": [float(tilt[0]), float(tilt[1])], "side_mm": s,
           "jitter": bool(jitter)}
    return _sample(surface, (h, w), ps, [crack[1], dent[1], scratch[1]], "plate", prm)


def _footprint_box(term) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) in mm of a groove's or dent's footprint."""
    if isinstance(term, _Dent):
        return term.cx - term.rim, term.cx + term.rim, term.cy - term.rim, term.cy + term.rim
    a = np.deg2rad(term.axis_deg)
    half = (term.length - term.width) / 2.0
    ex, ey = abs(half * np.cos(a)) + term.width / 2.0, abs(half * np.sin(a)) + term.width / 2.0
    return term.cx - ex, term.cx + ex, term.cy - ey, term.cy + ey


def inspection_part(
    size=2048,
    pixel_size: float = 60.0 / 2048,
    defect: str = "scratch",
    depth_mm: float | None = None,
    width_mm: float | None = None,
    length_mm: float | None = None,
    center_mm=None,
    axis_deg: float | None = None,
    tilt: tuple[float, float] = (0.0, 0.0),
) -> HeightField:
    """The inspection part of issue 15: a flat plate with ONE defect of known size in mm.

    Unlike :func:`inspection_plate`, the defect does not scale with the image: the
    nominal part is a 60 mm plate (the default 2048 px at 60/2048 mm) with a
    0.10 mm deep U-scratch 12 mm long and 0.5 mm wide at (3, -2) mm, axis 25 deg
    (:data:`INSPECTION_DEFECTS` holds the crack and dent variants). Any field that
    contains the defect works.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm (for a perspective camera: its scale on the reference plane).
    defect : {"scratch", "crack", "dent"}
        U-scratch, V-crack or spherical dent.
    depth_mm, width_mm, length_mm : float, optional
        Defect size in mm (defaults in :data:`INSPECTION_DEFECTS`; a dent's length is its width).
    center_mm : (x, y), optional
        Defect centre in mm (x right, y up from the optical axis).
    axis_deg : float, optional
        Direction of a groove's length from +x towards +y, degrees.
    tilt : (float, float)
        Slopes (p, q) of the plate itself.

    Returns
    -------
    HeightField
        One defect record (keys as :func:`v_crack`, in mm and in pixels of this grid).

    Raises
    ------
    ValueError
        An unknown defect, bad sizes, or a field that does not contain the defect.
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    if defect not in INSPECTION_DEFECTS:
        raise InputError(f"defect: expected one of {', '.join(INSPECTION_DEFECTS)}, got {defect!r}")
    spec = INSPECTION_DEFECTS[defect]
    depth = spec["depth_mm"] if depth_mm is None else depth_mm
    width = spec["width_mm"] if width_mm is None else width_mm
    length = spec["length_mm"] if length_mm is None else length_mm
    cx, cy = (float(v) for v in (spec["center_mm"] if center_mm is None
                                 else as_array(center_mm, "center_mm", shape=(2,))))
    axis = float(spec["axis_deg"] if axis_deg is None else axis_deg)
    tilt = as_array(tilt, "tilt", shape=(2,))
    if defect == "dent":
        term, rec, prm = _dent_mm((h, w), ps, depth, width, cx, cy)
    else:
        term, rec, prm = _groove_mm(spec["kind"], (h, w), ps, depth, width, length, cx, cy, axis)
    x0, x1, y0, y1 = _footprint_box(term)
    xs, ys = pixel_axes((h, w), ps)
    if x0 < xs[0] or x1 > xs[-1] or y0 < ys[-1] or y1 > ys[0]:
        raise InputError(
            f"size, pixel_size: the field x in [{xs[0]:.3f}, {xs[-1]:.3f}] mm, y in [{ys[-1]:.3f}, {ys[0]:.3f}] mm "
            f"does not contain the {defect} (x in [{x0:.3f}, {x1:.3f}], y in [{y0:.3f}, {y1:.3f}] mm); "
            "use a larger field (the nominal part is a 60 mm plate)")
    prm = {"defect": defect, **prm, "tilt": [float(tilt[0]), float(tilt[1])], "plate_mm": 60.0}
    surface = AnalyticSurface(plane=(0.0, float(tilt[0]), float(tilt[1])), features=(term,))
    return _sample(surface, (h, w), ps, [rec], f"inspection_{defect}", prm)


def make_scene(name: str, size: int = 256, pixel_size: float = 0.05, seed: int = 0) -> HeightField:
    """Build a named scene with default parameters scaled to the image.

    Parameters
    ----------
    name : str
        One of :data:`SCENES`: ``"plane", "tilted", "sphere", "crack", "scratch", "dent",
        "bumps", "vase", "plate"`` (sized relative to the image) or ``"inspection_scratch",
        "inspection_crack", "inspection_dent"`` (:func:`inspection_part`, defect sizes in mm).
    size : int or (H, W)
        Image size in pixels.
    pixel_size : float
        Pixel size in mm.
    seed : int
        Seed for scenes with random parts (bumps, plate jitter); others ignore it.

    Returns
    -------
    HeightField
        Its ``surface`` evaluates the same scene at any (x, y).
    """
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    s = min(h, w) * ps
    if name == "plane":
        return plane((h, w), ps)
    if name == "tilted":
        return tilted_plane((h, w), ps, 0.1, 0.05)
    if name == "sphere":
        return sphere_cap((h, w), ps)
    if name == "crack":
        return v_crack((h, w), ps, 0.009 * s, 0.03 * s, 0.5 * s, axis_deg=30.0)
    if name == "scratch":
        return u_scratch((h, w), ps, 0.003 * s, 0.02 * s, 0.5 * s, axis_deg=-15.0)
    if name == "dent":
        return spherical_dent((h, w), ps, 0.02 * s, 0.25 * s)
    if name == "bumps":
        return gaussian_bumps((h, w), ps, seed=seed)
    if name == "vase":
        return vase((h, w), ps)
    if name == "plate":
        return inspection_plate((h, w), ps, seed=seed)
    if name.startswith("inspection_") and name[len("inspection_"):] in INSPECTION_DEFECTS:
        return inspection_part((h, w), ps, defect=name[len("inspection_"):])
    raise InputError(f"name: unknown scene {name!r}; expected one of {', '.join(SCENES)}")
