"""Analytic height-field scenes with exact slopes and exact defect truth.

Every scene is a closed-form height ``z(x, y)`` in millimetres whose slopes
``p = dz/dx`` and ``q = dz/dy`` are differentiated by hand (never by finite
differences), so normals, defect depths, widths, lengths, areas and volumes are
known exactly. The image convention is stated once in :data:`CONVENTION`.

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
from surfaces.grid import image_shape, pixel_grid, xy_to_pixel
from surfaces.validate import as_array, positive

CONVENTION = (
    "Image convention (DiLiGenT): x to the right (column index), y up (row 0 is the TOP row, "
    "so y decreases as the row index grows), z towards the camera. Pixel (row, col) of an "
    "H x W image has its centre at x = (col - (W - 1) / 2) * pixel_size, "
    "y = ((H - 1) / 2 - row) * pixel_size, in mm. p = dz/dx, q = dz/dy (y up), unit normal "
    "n = (-p, -q, 1) / sqrt(1 + p^2 + q^2). Light directions are unit vectors from the surface "
    "towards the light in the same frame; a light's azimuth is measured from +x towards +y "
    "(counter-clockwise as seen by the camera), its slant from +z."
)

SCENES = ("plane", "tilted", "sphere", "crack", "scratch", "dent", "bumps", "vase", "plate")


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

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the image grid."""
        return self.height.shape


def _make(height, p, q, mask, defects, pixel_size, name, params) -> HeightField:
    return HeightField(
        height=height,
        p=p,
        q=q,
        normals=normals_from_slopes(p, q),
        defect_mask=mask,
        defects=tuple(defects),
        pixel_size=float(pixel_size),
        name=name,
        params=params,
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


def _groove(kind, size, pixel_size, depth_mm, width_mm, length_mm, center_px, axis_deg):
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    depth = positive(depth_mm, "depth_mm")
    width = positive(width_mm, "width_mm")
    length = positive(length_mm, "length_mm")
    if length < width:
        raise ValueError(f"length_mm: must be at least width_mm ({width}), got {length}")
    x, y = pixel_grid((h, w), ps)
    cx, cy = _center_mm(center_px, (h, w), ps)
    half_w = width / 2.0
    d, gx, gy = _capsule(x, y, cx, cy, axis_deg, (length - width) / 2.0)
    inside = d < half_w
    t = d / half_w
    if kind == "v_crack":
        z = np.where(inside, -depth * (1.0 - t), 0.0)
        dz_dd = np.where(inside, depth / half_w, 0.0)
        section, end = depth * width / 2.0, np.pi * half_w**2 * depth / 3.0
    else:
        z = np.where(inside, -depth * (1.0 - t * t), 0.0)
        dz_dd = np.where(inside, 2.0 * depth * t / half_w, 0.0)
        section, end = 2.0 * depth * width / 3.0, np.pi * half_w**2 * depth / 2.0
    area = (length - width) * width + np.pi * half_w**2
    volume = section * (length - width) + end
    rec = _defect_record(kind, depth, width, length, area, volume, cx, cy, axis_deg, (h, w), ps)
    params = {"depth_mm": depth, "width_mm": width, "length_mm": length,
              "center_mm": [cx, cy], "axis_deg": float(axis_deg)}
    return z, dz_dd * gx, dz_dd * gy, inside, rec, params


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
    z, p, q, m, rec, prm = _groove("v_crack", size, pixel_size, depth_mm, width_mm, length_mm,
                                   center_px, axis_deg)
    return _make(z, p, q, m, [rec], pixel_size, "crack", prm)


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
    z, p, q, m, rec, prm = _groove("u_scratch", size, pixel_size, depth_mm, width_mm, length_mm,
                                   center_px, axis_deg)
    return _make(z, p, q, m, [rec], pixel_size, "scratch", prm)


def _dent(size, pixel_size, depth_mm, width_mm, center_px):
    h, w = image_shape(size)
    ps = positive(pixel_size, "pixel_size")
    depth = positive(depth_mm, "depth_mm")
    width = positive(width_mm, "width_mm")
    a = width / 2.0
    if depth >= a:
        raise ValueError(f"depth_mm: a spherical dent needs depth < width/2 ({a}), got {depth}")
    radius = (a * a + depth * depth) / (2.0 * depth)
    x, y = pixel_grid((h, w), ps)
    cx, cy = _center_mm(center_px, (h, w), ps)
    dx, dy = x - cx, y - cy
    r2 = dx * dx + dy * dy
    inside = r2 < a * a
    root = np.sqrt(np.where(inside, radius * radius - r2, 1.0))
    z = np.where(inside, -(root - (radius - depth)), 0.0)
    p = np.where(inside, dx / root, 0.0)
    q = np.where(inside, dy / root, 0.0)
    volume = np.pi * depth**2 * (3.0 * radius - depth) / 3.0
    rec = _defect_record("spherical_dent", depth, width, width, np.pi * a * a, volume, cx, cy, 0.0,
                         (h, w), ps)
    rec["sphere_radius_mm"] = float(radius)
    prm = {"depth_mm": depth, "width_mm": width, "center_mm": [cx, cy],
           "sphere_radius_mm": float(radius)}
    return z, p, q, inside, rec, prm


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
    z, p, q, m, rec, prm = _dent(size, pixel_size, depth_mm, width_mm, center_px)
    return _make(z, p, q, m, [rec], pixel_size, "dent", prm)


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
    positive(pixel_size, "pixel_size")
    zero = np.zeros((h, w))
    return _make(zero + float(z0), zero.copy(), zero.copy(), np.zeros((h, w), bool), [],
                 pixel_size, "plane", {"z0_mm": float(z0)})


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
    x, y = pixel_grid(size, pixel_size)
    sx, sy = float(slope_x), float(slope_y)
    if not (np.isfinite(sx) and np.isfinite(sy)):
        raise ValueError(f"slope_x, slope_y: must be finite, got {slope_x!r}, {slope_y!r}")
    return _make(sx * x + sy * y, np.full_like(x, sx), np.full_like(x, sy),
                 np.zeros(x.shape, bool), [], pixel_size, "tilted",
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
        Cap height h <= R; default 0.8 R (the rim slope stays finite, about 63 deg).
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
        raise ValueError(f"height_mm: must not exceed radius_mm ({radius}), got {cap}")
    rim = np.sqrt(2.0 * radius * cap - cap * cap)
    x, y = pixel_grid((h_px, w_px), ps)
    cx, cy = _center_mm(center_px, (h_px, w_px), ps)
    dx, dy = x - cx, y - cy
    r2 = dx * dx + dy * dy
    inside = r2 < rim * rim
    root = np.sqrt(np.where(inside, radius * radius - r2, 1.0))
    z = np.where(inside, root - (radius - cap), 0.0)
    p = np.where(inside, -dx / root, 0.0)
    q = np.where(inside, -dy / root, 0.0)
    prm = {"radius_mm": radius, "height_mm": cap, "rim_radius_mm": float(rim), "center_mm": [cx, cy]}
    return _make(z, p, q, inside, [], ps, "sphere", prm)


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
            raise ValueError(f"n_bumps: must be at least 1, got {n_bumps}")
        centers_px = np.column_stack([rng.uniform(0.15, 0.85, k) * (h - 1),
                                      rng.uniform(0.15, 0.85, k) * (w - 1)])
    centers = as_array(centers_px, "centers_px", shape=(None, 2))
    k = len(centers)
    amps = (as_array(amplitudes_mm, "amplitudes_mm", shape=(k,)) if amplitudes_mm is not None
            else rng.uniform(0.02, 0.08, k) * side)
    sig = (as_array(sigmas_mm, "sigmas_mm", shape=(k,)) if sigmas_mm is not None
           else rng.uniform(0.04, 0.09, k) * side)
    if np.any(sig <= 0):
        raise ValueError("sigmas_mm: every width must be positive")
    x, y = pixel_grid((h, w), ps)
    z = np.zeros((h, w))
    p = np.zeros((h, w))
    q = np.zeros((h, w))
    bumps = []
    for (row, col), a, s in zip(centers, amps, sig):
        cx, cy = _center_mm((row, col), (h, w), ps)
        g = a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2.0 * s * s))
        z += g
        p -= g * (x - cx) / (s * s)
        q -= g * (y - cy) / (s * s)
        bumps.append({"center_px": [float(row), float(col)], "center_mm": [cx, cy],
                      "amplitude_mm": float(a), "sigma_mm": float(s)})
    return _make(z, p, q, np.zeros((h, w), bool), [], ps, "bumps", {"bumps": bumps})


def _vase_profile(v):
    """Half-width f(v) of the classic vase outline and f'(v), v in [0, 1] bottom to top."""
    a = 6.0 * v + 1.0
    b = v - 1.0
    c = 3.0 * v - 2.0
    f = 0.15 - 0.1 * v * a**2 * b**2 * c**2
    df = -0.1 * (a**2 * b**2 * c**2 + v * (12.0 * a * b**2 * c**2 + 2.0 * a**2 * b * c**2
                                           + 6.0 * a**2 * b**2 * c))
    return f, df


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
    x, y = pixel_grid((h, w), ps)
    u = x / side
    v = np.clip(y / side + 0.5, 0.0, 1.0)
    f, df = _vase_profile(v)
    fmax = float(np.max(_vase_profile(np.linspace(0.0, 1.0, 20001))[0]))
    g = (f * f - u * u) / fmax**2
    inside = (g > 0) & (y / side + 0.5 >= 0) & (y / side + 0.5 <= 1)
    gp = np.where(inside, g, 0.0)
    z = top * gp**1.5
    dz_dg = 1.5 * top * np.sqrt(gp)
    p = np.where(inside, dz_dg * (-2.0 * u) / fmax**2 / side, 0.0)
    q = np.where(inside, dz_dg * (2.0 * f * df) / fmax**2 / side, 0.0)
    return _make(z, p, q, inside, [], ps, "vase", {"height_mm": top, "side_mm": side})


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
        raise ValueError(f"size: the inspection plate needs at least 32 pixels, got {size!r}")
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
    x, y = pixel_grid((h, w), ps)
    z = tilt[0] * x + tilt[1] * y
    p = np.full((h, w), tilt[0])
    q = np.full((h, w), tilt[1])
    mask = np.zeros((h, w), bool)
    recs = []
    for dz, dp, dq, m, rec, _ in (crack, dent, scratch):
        z = z + dz
        p = p + dp
        q = q + dq
        mask |= m
        recs.append(rec)
    prm = {"seed": int(seed), "tilt": [float(tilt[0]), float(tilt[1])], "side_mm": s,
           "jitter": bool(jitter)}
    return _make(z, p, q, mask, recs, ps, "plate", prm)


def make_scene(name: str, size: int = 256, pixel_size: float = 0.05, seed: int = 0) -> HeightField:
    """Build a named scene with default parameters scaled to the image.

    Parameters
    ----------
    name : str
        One of ``"plane", "tilted", "sphere", "crack", "scratch", "dent", "bumps",
        "vase", "plate"``.
    size : int
        Image side in pixels.
    pixel_size : float
        Pixel size in mm.
    seed : int
        Seed for scenes with random parts (bumps, plate jitter); others ignore it.

    Returns
    -------
    HeightField
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
    raise ValueError(f"name: unknown scene {name!r}; expected one of {', '.join(SCENES)}")
