"""Cameras of an inspection rig and the surface points their pixels see.

The rig frame (shared near-field format contract): millimetres, origin on the
optical axis in the reference plane z = 0 (the nominal part surface), x right,
y up, z towards the camera (:data:`datasets_synthetic.heightfields.CONVENTION`).

* ``orthographic`` (telecentric): pixel (row, col) sees the vertical ray through
  ``x = (col - (W - 1) / 2) s``, ``y = ((H - 1) / 2 - row) s`` (``s`` the pixel
  size, :data:`surfaces.grid.GRID_CONVENTION`).
* ``perspective`` (pinhole): focal length ``f`` in pixels, principal point
  ``(cx, cy)`` (column, row; the image centre by default), centre
  ``C = (0, 0, camera_height_mm)`` looking down -z. Pixel (row, col) sees the ray
  ``C + t ((col - cx) / f, (cy - row) / f, -1)``, ``t > 0`` the depth below the
  camera; the reference plane is seen at ``camera_height_mm / f`` mm per pixel.

:func:`intersect` finds, for every pixel, the point of an
:class:`~datasets_synthetic.heightfields.AnalyticSurface` its ray meets first: a
bracketed, safeguarded Newton iteration on the closed-form height along all rays
at once (see its Notes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets_synthetic.heightfields import AnalyticSurface, HeightField
from photometric.normals import normals_from_slopes
from surfaces.grid import image_shape, pixel_grid, xy_to_pixel
from surfaces.validate import as_array, InputError, positive

CAMERA_MODELS = ("orthographic", "perspective")
VIGNETTING_MODELS = ("cos4", "radial")


@dataclass(frozen=True)
class Camera:
    """An orthographic or perspective camera (see the module docstring).

    Attributes
    ----------
    model : {"orthographic", "perspective"}
        Camera model.
    shape : (int, int)
        Image size ``(H, W)`` in pixels.
    pixel_size_mm : float or None
        Orthographic pixel size in mm.
    focal_length_px : float or None
        Perspective focal length in pixels.
    camera_height_mm : float or None
        Perspective camera centre's height above the reference plane, mm.
    principal_point_px : (float, float) or None
        Perspective principal point ``(cx, cy)``: column, row.
    """

    model: str
    shape: tuple[int, int]
    pixel_size_mm: float | None = None
    focal_length_px: float | None = None
    camera_height_mm: float | None = None
    principal_point_px: tuple[float, float] | None = None

    @property
    def reference_pixel_mm(self) -> float:
        """Size of a pixel on the reference plane z = 0, mm (at the principal point)."""
        if self.model == "orthographic":
            return float(self.pixel_size_mm)
        return float(self.camera_height_mm / self.focal_length_px)

    def as_dict(self) -> dict:
        """The camera as the format contract writes it in ``scene.json`` and ``rig.json``."""
        if self.model == "orthographic":
            return {"model": "orthographic", "pixel_size_mm": float(self.pixel_size_mm)}
        return {"model": "perspective", "focal_length_px": float(self.focal_length_px),
                "camera_height_mm": float(self.camera_height_mm),
                "principal_point_px": [float(v) for v in self.principal_point_px]}

    def rays(self, rows, cols) -> tuple[np.ndarray, np.ndarray]:
        """The rays through (fractional) pixel positions.

        Parameters
        ----------
        rows, cols : array_like
            Pixel positions (pixel centres at whole numbers), broadcast together.

        Returns
        -------
        origins : (..., 3) float64 array
            Perspective: the camera centre. Orthographic: the ray's point on z = 0 (the
            ray is the whole vertical line; callers take its first crossing from above).
        directions : (..., 3) float64 array
            Unit directions, pointing down into the scene.
        """
        r, c = np.broadcast_arrays(as_array(rows, "rows"), as_array(cols, "cols"))
        if self.model == "orthographic":
            x, y = _grid_xy(r, c, self.shape, self.pixel_size_mm)
            origins = np.stack([x, y, np.zeros_like(x)], axis=-1)
            directions = np.zeros(origins.shape)
            directions[..., 2] = -1.0
            return origins, directions
        dx, dy = self._slopes(r, c)
        d = np.stack([dx, dy, -np.ones_like(dx)], axis=-1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        origins = np.zeros(d.shape)
        origins[..., 2] = self.camera_height_mm
        return origins, d

    def _slopes(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Perspective ray slopes ``dx = (col - cx) / f``, ``dy = (cy - row) / f``."""
        cx, cy = self.principal_point_px
        f = self.focal_length_px
        return (cols - cx) / f, (cy - rows) / f


def _grid_xy(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int], ps: float):
    """x, y in mm of fractional pixel positions (the inverse of :func:`surfaces.grid.xy_to_pixel`)."""
    h, w = shape
    return (cols - (w - 1) / 2.0) * ps, ((h - 1) / 2.0 - rows) * ps


def orthographic_camera(size, pixel_size_mm: float) -> Camera:
    """A telecentric camera on the pixel grid of :mod:`surfaces.grid`.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    pixel_size_mm : float
        Pixel size in mm (> 0).

    Returns
    -------
    Camera

    Examples
    --------
    >>> orthographic_camera(4, 0.05).as_dict()
    {'model': 'orthographic', 'pixel_size_mm': 0.05}
    """
    return Camera("orthographic", image_shape(size), pixel_size_mm=positive(pixel_size_mm, "pixel_size_mm"))


def perspective_camera(size, focal_length_px: float, camera_height_mm: float, principal_point_px=None) -> Camera:
    """A pinhole camera at ``(0, 0, camera_height_mm)`` looking down -z.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    focal_length_px : float
        Focal length in pixels (> 0).
    camera_height_mm : float
        Height of the camera centre above the reference plane z = 0, mm (> 0).
    principal_point_px : (cx, cy), optional
        Principal point, column and row; ``((W - 1) / 2, (H - 1) / 2)`` by default.

    Returns
    -------
    Camera

    Examples
    --------
    >>> cam = perspective_camera((480, 640), 2400.0, 300.0)
    >>> cam.principal_point_px, cam.reference_pixel_mm
    ((319.5, 239.5), 0.125)
    """
    h, w = image_shape(size)
    f = positive(focal_length_px, "focal_length_px")
    height = positive(camera_height_mm, "camera_height_mm")
    if principal_point_px is None:
        pp = ((w - 1) / 2.0, (h - 1) / 2.0)
    else:
        pp = tuple(float(v) for v in as_array(principal_point_px, "principal_point_px", shape=(2,)))
    return Camera("perspective", (h, w), focal_length_px=f, camera_height_mm=height, principal_point_px=pp)


def make_camera(model: str, size, pixel_size_mm: float | None = None, focal_length_px: float | None = None,
                camera_height_mm: float | None = None) -> Camera:
    """A camera from the options of a command or a folder maker (clear errors for a missing or foreign one).

    Parameters
    ----------
    model : {"orthographic", "perspective"}
        Camera model.
    size : int or (H, W)
        Image size in pixels.
    pixel_size_mm : float, optional
        Orthographic pixel size in mm (default 0.05); not for a perspective camera.
    focal_length_px, camera_height_mm : float, optional
        Perspective focal length (pixels) and camera height (mm); both required for it.

    Returns
    -------
    Camera

    Examples
    --------
    >>> make_camera("perspective", 64, focal_length_px=640.0, camera_height_mm=200.0).reference_pixel_mm
    0.3125
    """
    if model == "orthographic":
        if focal_length_px is not None or camera_height_mm is not None:
            raise InputError("camera: focal_length_px and camera_height belong to a perspective camera")
        return orthographic_camera(size, 0.05 if pixel_size_mm is None else pixel_size_mm)
    if model == "perspective":
        if focal_length_px is None or camera_height_mm is None:
            raise InputError("camera: a perspective camera needs focal_length_px and camera_height")
        if pixel_size_mm is not None:
            raise InputError("pixel_size: a perspective camera's scale is camera_height / focal_length_px; "
                             "give no pixel size")
        return perspective_camera(size, focal_length_px, camera_height_mm)
    raise InputError(f"camera: expected 'orthographic' or 'perspective', got {model!r}")


def project(camera: Camera, points) -> tuple[np.ndarray, np.ndarray]:
    """Fractional pixel positions where the camera sees points of the rig frame.

    Parameters
    ----------
    camera : Camera
        The camera.
    points : (..., 3) array_like
        Points in mm; for a perspective camera below its centre (z < camera height).

    Returns
    -------
    row, col : float64 arrays, shape (...)
        Pixel positions (centres at whole numbers).
    """
    pts = as_array(points, "points")
    if pts.ndim < 1 or pts.shape[-1] != 3:
        raise InputError(f"points: expected shape (..., 3), got {pts.shape}")
    if camera.model == "orthographic":
        return xy_to_pixel(pts[..., 0], pts[..., 1], camera.shape, camera.pixel_size_mm)
    depth = camera.camera_height_mm - pts[..., 2]
    if np.any(depth <= 0):
        raise InputError(f"points: {int(np.sum(depth <= 0))} point(s) at or above the camera centre "
                         f"(z >= {camera.camera_height_mm} mm)")
    cx, cy = camera.principal_point_px
    f = camera.focal_length_px
    return cy - f * pts[..., 1] / depth, cx + f * pts[..., 0] / depth


def view_directions(camera: Camera, points) -> np.ndarray:
    """Unit vectors from points towards the camera (the viewing direction ``v``).

    Parameters
    ----------
    camera : Camera
        The camera.
    points : (..., 3) array_like
        Points in mm.

    Returns
    -------
    (..., 3) float64 array
        ``(0, 0, 1)`` for an orthographic camera, ``(C - X) / |C - X|`` for a perspective one.
    """
    pts = as_array(points, "points")
    if camera.model == "orthographic":
        v = np.zeros(pts.shape)
        v[..., 2] = 1.0
        return v
    v = -pts
    v[..., 2] += camera.camera_height_mm
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class SurfaceHits:
    """The surface point each pixel sees.

    Attributes
    ----------
    points : (H, W, 3) float64 array
        ``(x, y, z)`` in mm of the point on the surface (z is the surface's exact height at x, y).
    p, q : (H, W) float64 arrays
        Exact slopes there.
    normals : (H, W, 3) float64 array
        Unit normals ``(-p, -q, 1) / |.|``.
    inside : (H, W) bool array
        Points inside a feature's footprint (a defect, the cap, ...).
    """

    points: np.ndarray
    p: np.ndarray
    q: np.ndarray
    normals: np.ndarray
    inside: np.ndarray

    @property
    def height(self) -> np.ndarray:
        """(H, W) z in mm (``height_gt.npy``)."""
        return self.points[..., 2]

    @property
    def xy(self) -> np.ndarray:
        """(H, W, 2) x, y in mm (``xy_gt.npy``)."""
        return self.points[..., :2]


#: Newton iterations (each over the rays not yet converged) before :func:`intersect` gives up.
MAX_ITERATIONS = 100
#: Samples along a ray's bracket that find its first crossing where the surface may be crossed twice.
MARCH_SAMPLES = 64


def intersect(surface, camera: Camera, tol_mm: float = 1e-9) -> SurfaceHits:
    """The first point of an analytic surface on every pixel's ray.

    Parameters
    ----------
    surface : AnalyticSurface or HeightField
        The scene (a height field's ``surface``).
    camera : Camera
        The camera.
    tol_mm : float
        Convergence tolerance of the depth along the ray, mm (default 1e-9).

    Returns
    -------
    SurfaceHits
        For an orthographic camera exactly the height field at the pixel centres.

    Raises
    ------
    ValueError
        A camera not above the part, rays that never meet the (tilted) base plane, or
        rays that do not converge.

    Notes
    -----
    Along the perspective ray ``X(t) = (t dx, t dy, H - t)`` the surface
    ``z = z0 + sx x + sy y + r(x, y)`` with relief ``r`` in ``[lo, hi]`` (the scene's
    :attr:`~datasets_synthetic.heightfields.AnalyticSurface.relief_bounds`) is met
    where ``g(t) = H - t k - r(t dx, t dy) = 0``, ``k = 1 + sx dx + sy dy``; the
    root lies in ``[(H - hi) / k, (H - lo) / k]``, where ``g`` changes sign. When
    ``|(dx, dy)| m < k`` (``m`` the relief's slope bound) ``g`` is strictly
    decreasing and the root unique; otherwise the ray is sampled at
    :data:`MARCH_SAMPLES` points of its bracket and the first sign change kept (the
    first hit from the camera). Newton steps on the exact slope, ``g' = -1 - dx p - dy q``,
    fall back to bisection whenever they leave the bracket, all rays at once.
    """
    surface = analytic_surface(surface)
    if not isinstance(camera, Camera):
        raise InputError(f"camera: expected a Camera, got {type(camera).__name__}")
    tol = positive(tol_mm, "tol_mm")
    if camera.model == "orthographic":
        x, y = pixel_grid(camera.shape, camera.pixel_size_mm)
        z, p, q, inside = surface._evaluate(x, y)
        return _hits(x, y, z, p, q, inside)
    h, w = camera.shape
    rows = np.arange(h, dtype=np.float64)[:, None]
    cols = np.arange(w, dtype=np.float64)[None, :]
    dx, dy = (np.broadcast_to(a, (h, w)).ravel() for a in camera._slopes(rows, cols))
    t = _depths(surface, camera.camera_height_mm, dx, dy, tol)
    x, y = t * dx, t * dy
    z, p, q, inside = surface._evaluate(x, y)
    return _hits(*(a.reshape(h, w) for a in (x, y, z, p, q, inside)))


def analytic_surface(surface) -> AnalyticSurface:
    """The closed-form surface of a scene.

    Parameters
    ----------
    surface : AnalyticSurface or HeightField
        A scene, or a height field that carries its analytic ``surface``.

    Returns
    -------
    AnalyticSurface

    Raises
    ------
    ValueError
        Anything else, or a height field without an analytic surface.
    """
    if isinstance(surface, HeightField):
        if surface.surface is None:
            raise InputError("surface: this HeightField carries no analytic surface")
        surface = surface.surface
    if not isinstance(surface, AnalyticSurface):
        raise InputError(f"surface: expected an AnalyticSurface or HeightField, got {type(surface).__name__}")
    return surface


def _hits(x, y, z, p, q, inside) -> SurfaceHits:
    return SurfaceHits(np.stack([x, y, z], axis=-1), p, q, normals_from_slopes(p, q), inside)


def _depths(surface: AnalyticSurface, height: float, dx: np.ndarray, dy: np.ndarray, tol: float) -> np.ndarray:
    """Depths ``t`` of the first surface crossing of the rays ``(t dx, t dy, height - t)``."""
    z0, sx, sy = surface.plane
    lo, hi = surface.relief_bounds
    k = 1.0 + sx * dx + sy * dy
    if np.any(k <= 0):
        raise InputError(f"camera: {int(np.sum(k <= 0))} ray(s) run parallel to or away from the scene's "
                         f"tilted base plane (slopes {sx}, {sy}) and never meet it")
    if height <= hi:
        raise InputError(f"camera_height_mm: the camera ({height} mm) must be above the part, whose relief "
                         f"reaches z = {hi} mm")
    a = (height - hi) / k
    b = (height - lo) / k

    def g(i, t):
        z, p, q, _ = surface._evaluate(t * dx[i], t * dy[i])
        return height - t - z, -1.0 - dx[i] * p - dy[i] * q

    # a ray may cross the relief more than once only where its obliquity times the slope bound reaches k
    unsure = np.flatnonzero(np.hypot(dx, dy) * surface.relief_max_slope >= k)
    if unsure.size:
        start, stop = a[unsure], b[unsure]
        prev = start.copy()
        todo = np.arange(unsure.size)
        for j in range(1, MARCH_SAMPLES + 1):
            tj = start[todo] + (stop[todo] - start[todo]) * (j / MARCH_SAMPLES)
            crossed = g(unsure[todo], tj)[0] <= 0
            a[unsure[todo[crossed]]] = prev[todo[crossed]]
            b[unsure[todo[crossed]]] = tj[crossed]
            prev[todo] = tj
            todo = todo[~crossed]
            if todo.size == 0:
                break
    # most rays of a flat part meet the base plane where the relief is z0: start there
    t = np.clip((height - z0) / k, a, b)
    active = np.arange(t.size)
    for _ in range(MAX_ITERATIONS):
        ti = t[active]
        gi, slope = g(active, ti)
        ai = np.where(gi > 0, ti, a[active])
        bi = np.where(gi < 0, ti, b[active])
        step = ti - gi / np.where(slope < 0, slope, -1.0)
        bisect = (slope >= 0) | ~(step > ai) | ~(step < bi)
        new = np.where(bisect, 0.5 * (ai + bi), step)
        done = (gi == 0) | (np.abs(new - ti) <= tol) | (bi - ai <= tol)
        t[active] = np.where(gi == 0, ti, new)
        a[active], b[active] = ai, bi
        active = active[~done]
        if active.size == 0:
            return t
    raise InputError(f"camera: {active.size} ray(s) did not converge to a surface point in {MAX_ITERATIONS} "
                     "iterations")


def vignetting_map(camera: Camera, spec: dict | None) -> np.ndarray:
    """Per-pixel camera vignetting ``V(pixel)``, the same for every light.

    Parameters
    ----------
    camera : Camera
        The camera.
    spec : dict or None
        ``None`` (no vignetting: ones), ``{"model": "cos4"}`` (perspective only:
        ``cos^4`` of the angle between the pixel's ray and the optical axis,
        ``cos = f / sqrt(f^2 + (col - cx)^2 + (row - cy)^2)``), or
        ``{"model": "radial", "coefficients": [k1, k2, ...]}``:
        ``V = 1 + k1 rho^2 + k2 rho^4 + ...`` with ``rho`` the distance from the
        principal point (orthographic: the image centre) over the half diagonal
        ``sqrt(((W - 1) / 2)^2 + ((H - 1) / 2)^2)``.

    Returns
    -------
    (H, W) float64 array
        Positive factors, 1 on the axis.

    Examples
    --------
    >>> v = vignetting_map(perspective_camera((3, 3), 1.0, 100.0), {"model": "cos4"})
    >>> float(v[1, 1]), round(float(v[0, 1]), 6)
    (1.0, 0.25)
    """
    h, w = camera.shape
    if spec is None:
        return np.ones((h, w))
    if not isinstance(spec, dict) or spec.get("model") not in VIGNETTING_MODELS:
        raise InputError(f"vignetting: expected None or a dict with 'model' in {VIGNETTING_MODELS}, got {spec!r}")
    cx, cy = camera.principal_point_px if camera.model == "perspective" else ((w - 1) / 2.0, (h - 1) / 2.0)
    rows = np.arange(h, dtype=np.float64)[:, None]
    cols = np.arange(w, dtype=np.float64)[None, :]
    r2 = (cols - cx) ** 2 + (rows - cy) ** 2
    if spec["model"] == "cos4":
        unknown = set(spec) - {"model"}
        if unknown:
            raise InputError(f"vignetting: unknown keys {sorted(unknown)} for the cos4 model")
        if camera.model != "perspective":
            raise InputError("vignetting: cos4 needs a perspective camera (a telecentric lens has no off-axis "
                             "angle); use the radial model")
        f2 = camera.focal_length_px**2
        return (f2 / (f2 + r2)) ** 2
    unknown = set(spec) - {"model", "coefficients"}
    if unknown:
        raise InputError(f"vignetting: unknown keys {sorted(unknown)} for the radial model")
    k = as_array(spec.get("coefficients", []), "vignetting['coefficients']", ndim=1)
    rho2 = r2 / (((w - 1) / 2.0) ** 2 + ((h - 1) / 2.0) ** 2)
    v = 1.0 + sum(kk * rho2 ** (i + 1) for i, kk in enumerate(k))
    if np.any(v <= 0):
        raise InputError(f"vignetting: coefficients {k.tolist()} make the factor non-positive ({float(v.min()):.4g})")
    return np.broadcast_to(v, (h, w)).copy()
