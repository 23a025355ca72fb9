"""Camera models of the photometric rig: orthographic (telecentric) and perspective (pinhole).

Rig frame (the near-field contract): millimetres, origin on the optical axis in the
reference plane ``z = 0`` (the nominal part surface), x right, y up, z towards the
camera (:data:`photometric.lights.CONVENTION`). Pixel ``(row, col)`` of an ``H x W``
image sees the ray through its centre:

* ``orthographic`` (telecentric; ``pixel_size_mm`` ``h``): the vertical ray through
  ``x = (col - (W - 1) / 2) h``, ``y = ((H - 1) / 2 - row) h``, the project's pixel grid
  (:data:`surfaces.grid.GRID_CONVENTION`).
* ``perspective`` (pinhole; focal length ``f`` in pixels, principal point ``(cx, cy)``
  (column, row; **0-based**: the centre of the top-left pixel is ``(0, 0)``), by default
  ``((W - 1) / 2, (H - 1) / 2)``, camera centre ``C = (0, 0, H_c)`` with ``H_c`` =
  ``camera_height_mm``, looking down ``-z``): the ray from ``C`` along
  ``(u / f, v / f, -1)`` with the pixel offsets ``u = col - cx`` and
  ``v = (cy - row) f / f_y``. The surface point at depth ``w = H_c - z`` below the camera
  is ``X = (u w / f, v w / f, z)``; the reference plane is seen at ``H_c / f`` mm per
  pixel at the principal point. ``f`` is the focal length along the rows (``fx``,
  OpenCV's ``K[0, 0]``); a camera whose pixels are not square also has ``f_y``
  (``K[1, 1]``, ``focal_length_y_px``; default ``f``): :func:`pixel_offsets` scales the
  row offsets by ``f / f_y``, so every formula below keeps one ``f``, and
  :func:`gradient_field`'s row derivative is per row of pixels.

A surface seen by every pixel is one depth per pixel: ``height.npy`` holds ``z`` (mm) of
the point each pixel sees and ``xy.npy`` its ``x, y`` (:func:`surface_xy`). Normals come
from photometric stereo; :func:`gradient_field` turns them into the field that the
normal integrators of :mod:`photometric.integrate` integrate (``z`` itself for the
orthographic camera, ``log w`` for the perspective one) and :func:`depth_from_field`
turns the integral back into ``z``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from surfaces.grid import image_shape
from surfaces.validate import as_array, InputError, positive

__all__ = [
    "MODELS",
    "Orthographic",
    "Perspective",
    "make_camera",
    "camera_from_dict",
    "pixel_offsets",
    "surface_xy",
    "plane_points",
    "pixel_rays",
    "gradient_field",
    "depth_from_field",
    "footprint_area",
    "intrinsic_matrix",
    "undistort_images",
    "calibrate_checkerboard",
]

#: Camera model names (``--camera``; ``"model"`` in ``scene.json`` and ``rig.json``).
MODELS = ("orthographic", "perspective")


@dataclass(frozen=True)
class Orthographic:
    """A telecentric camera: every pixel sees a vertical ray.

    Attributes
    ----------
    pixel_size_mm : float
        Pixel pitch on the part, mm (> 0).
    """

    pixel_size_mm: float

    model = "orthographic"

    def to_dict(self, shape=None) -> dict:
        """The ``camera`` entry of ``scene.json``/``rig.json`` (``shape`` is not needed)."""
        return {"model": self.model, "pixel_size_mm": float(self.pixel_size_mm)}

    def nominal_pixel_mm(self) -> float:
        """Pixel size on the reference plane, mm."""
        return float(self.pixel_size_mm)


@dataclass(frozen=True)
class Perspective:
    """A pinhole camera looking down ``-z`` from ``(0, 0, camera_height_mm)``.

    Attributes
    ----------
    focal_length_px : float
        Focal length ``f`` in pixels (> 0).
    camera_height_mm : float
        Height ``H_c`` of the camera centre above the reference plane, mm (> 0).
    principal_point_px : tuple of float or None
        ``(cx, cy)`` (column, row) in pixels, 0-based (the top-left pixel's centre is
        ``(0, 0)``; a MATLAB calibration's is ``(1, 1)``: subtract 1); ``None``: the image
        centre ``((W - 1) / 2, (H - 1) / 2)``.
    focal_length_y_px : float or None
        Focal length along the columns ``f_y`` in pixels (OpenCV's ``K[1, 1]``) when it
        differs from ``focal_length_px`` (``K[0, 0]``); ``None``: square pixels.
    distortion : tuple of float or None
        OpenCV's lens distortion ``(k1, k2, p1, p2, k3)`` of this camera's images; the read
        stage resamples them to the distortion-free pinhole camera of the same ``K``
        (:func:`undistort_images`), so every formula here stays a pinhole's. None: none.
    """

    focal_length_px: float
    camera_height_mm: float
    principal_point_px: tuple[float, float] | None = None
    focal_length_y_px: float | None = None
    distortion: tuple[float, ...] | None = None

    model = "perspective"

    @property
    def fy(self) -> float:
        """Focal length along the columns, pixels (``focal_length_px`` for square pixels)."""
        return float(self.focal_length_px if self.focal_length_y_px is None else self.focal_length_y_px)

    @property
    def aspect(self) -> float:
        """``f / f_y``: the factor :func:`pixel_offsets` applies to the row offsets (1 for square pixels)."""
        return float(self.focal_length_px) / self.fy

    def centre(self, shape) -> tuple[float, float]:
        """``(cx, cy)`` for an image of ``shape`` (H, W)."""
        if self.principal_point_px is not None:
            return float(self.principal_point_px[0]), float(self.principal_point_px[1])
        h, w = image_shape(shape, "shape")
        return (w - 1) / 2.0, (h - 1) / 2.0

    def to_dict(self, shape=None) -> dict:
        """The ``camera`` entry of ``scene.json``/``rig.json``; the principal point is
        written out when ``shape`` (H, W) is given or it was set."""
        out = {"model": self.model, "focal_length_px": float(self.focal_length_px),
               "camera_height_mm": float(self.camera_height_mm)}
        if self.principal_point_px is not None or shape is not None:
            out["principal_point_px"] = list(self.centre(shape))
        if self.focal_length_y_px is not None:
            out["focal_length_y_px"] = float(self.focal_length_y_px)
        if self.distortion is not None:
            out["distortion"] = [float(c) for c in self.distortion]
        return out

    def nominal_pixel_mm(self) -> float:
        """Pixel size on the reference plane at the principal point, ``H_c / f`` mm."""
        return float(self.camera_height_mm) / float(self.focal_length_px)


Camera = Orthographic | Perspective


def make_camera(
    model: str = "orthographic",
    *,
    pixel_size_mm: float | None = None,
    focal_length_px: float | None = None,
    camera_height_mm: float | None = None,
    principal_point_px=None,
    focal_length_y_px: float | None = None,
    distortion=None,
) -> Camera:
    """Build and check a camera from the user's options.

    Parameters
    ----------
    model : {"orthographic", "perspective"}
        Camera model.
    pixel_size_mm : float, optional
        Orthographic pixel size, mm (required for ``"orthographic"``).
    focal_length_px : float or (float, float), optional
        Perspective focal length in pixels, or ``(fx, fy)`` for pixels that are not square
        (OpenCV's ``K[0, 0]``, ``K[1, 1]``); required for ``"perspective"``.
    camera_height_mm : float, optional
        Camera height above the reference plane, mm; required for ``"perspective"``.
    principal_point_px : (cx, cy), optional
        Perspective principal point (column, row), 0-based; default the image centre.
    focal_length_y_px : float, optional
        ``fy`` when ``focal_length_px`` is one number (default: square pixels).
    distortion : sequence of float, optional
        Perspective lens distortion, OpenCV's ``(k1, k2, p1, p2, k3)`` (fewer: the rest 0).

    Returns
    -------
    Orthographic or Perspective

    Raises
    ------
    ValueError
        Unknown model, a missing or non-positive value, options of the other model.

    Examples
    --------
    >>> make_camera("perspective", focal_length_px=2400, camera_height_mm=300).nominal_pixel_mm()
    0.125
    >>> make_camera("perspective", focal_length_px=(3043, 3026), camera_height_mm=200).to_dict()["focal_length_y_px"]
    3026.0
    >>> make_camera("perspective", focal_length_px=2400)
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: camera: a perspective camera needs --focal-length-px and --camera-height ...
    """
    if model not in MODELS:
        raise InputError(f"camera: expected one of {MODELS}, got {model!r}")
    if model == "orthographic":
        if any(v is not None for v in (focal_length_px, camera_height_mm, principal_point_px, focal_length_y_px,
                                       distortion)):
            raise InputError("camera: --focal-length-px, --camera-height and a principal point need "
                             "--camera perspective")
        if pixel_size_mm is None:
            raise InputError("camera: an orthographic camera with point lights needs --pixel-size (mm)")
        return Orthographic(positive(pixel_size_mm, "pixel_size"))
    missing = [n for n, v in (("focal-length-px", focal_length_px), ("camera-height", camera_height_mm))
               if v is None]
    if missing:
        raise InputError("camera: a perspective camera needs --focal-length-px and --camera-height "
                         f"(missing: {', '.join(missing)})")
    if pixel_size_mm is not None:
        raise InputError("camera: --pixel-size is for the orthographic camera; a perspective camera "
                         "takes --focal-length-px and --camera-height")
    pp = None
    if principal_point_px is not None:
        pp = tuple(float(c) for c in as_array(principal_point_px, "principal_point_px", shape=(2,)))
    if np.ndim(focal_length_px) == 1:
        pair = as_array(focal_length_px, "focal_length_px", shape=(2,))
        if focal_length_y_px is not None:
            raise InputError("focal_length_px: give (fx, fy) or focal_length_y_px, not both")
        focal_length_px, focal_length_y_px = float(pair[0]), float(pair[1])
    fy = None if focal_length_y_px is None else positive(focal_length_y_px, "focal_length_y_px")
    dist = None
    if distortion is not None:
        d = as_array(distortion, "distortion", ndim=1)
        if not 1 <= d.size <= 5:
            raise InputError(f"distortion: expected k1[,k2[,p1[,p2[,k3]]]] (OpenCV's order), got {d.size} values")
        dist = tuple(float(c) for c in np.concatenate([d, np.zeros(5 - d.size)]))
        dist = None if not any(dist) else dist
    return Perspective(positive(focal_length_px, "focal_length_px"),
                       positive(camera_height_mm, "camera_height_mm"), pp, fy, dist)


def camera_from_dict(entry, name: str = "camera") -> Camera:
    """The camera of a ``scene.json`` or ``rig.json`` ``camera`` entry.

    Parameters
    ----------
    entry : dict
        ``{"model": "orthographic", "pixel_size_mm": h}`` or ``{"model": "perspective",
        "focal_length_px": f, "camera_height_mm": H, "principal_point_px": [cx, cy]}``
        (principal point optional).
    name : str, optional
        Where the entry came from, for messages.

    Returns
    -------
    Orthographic or Perspective
    """
    if not isinstance(entry, dict) or "model" not in entry:
        raise InputError(f"{name}: expected an object with a 'model' ({' or '.join(MODELS)})")
    try:
        return make_camera(
            entry["model"],
            pixel_size_mm=entry.get("pixel_size_mm") if entry["model"] == "orthographic" else None,
            focal_length_px=entry.get("focal_length_px") if entry["model"] == "perspective" else None,
            camera_height_mm=entry.get("camera_height_mm") if entry["model"] == "perspective" else None,
            principal_point_px=entry.get("principal_point_px") if entry["model"] == "perspective" else None,
            focal_length_y_px=entry.get("focal_length_y_px") if entry["model"] == "perspective" else None,
            distortion=entry.get("distortion") if entry["model"] == "perspective" else None,
        )
    except ValueError as exc:
        raise InputError(f"{name}: {exc}") from None


def pixel_offsets(camera: Camera, shape) -> tuple[np.ndarray, np.ndarray]:
    """Per-column and per-row offsets of the pixel centres from the optical axis.

    Parameters
    ----------
    camera : Orthographic or Perspective
    shape : (H, W)
        Image size.

    Returns
    -------
    u : numpy.ndarray, shape (W,), float64
        ``col - cx`` (right); for the orthographic camera multiplied by the pixel size
        (mm, so ``u`` is ``x``).
    v : numpy.ndarray, shape (H,), float64
        ``(cy - row) f / f_y`` (up; ``cy - row`` for square pixels); orthographic: ``y`` in mm.
    """
    h, w = image_shape(shape, "shape")
    if isinstance(camera, Orthographic):
        ps = camera.pixel_size_mm
        return (np.arange(w) - (w - 1) / 2.0) * ps, ((h - 1) / 2.0 - np.arange(h)) * ps
    cx, cy = camera.centre((h, w))
    v = cy - np.arange(h, dtype=np.float64)
    return np.arange(w) - cx, v if camera.focal_length_y_px is None else v * camera.aspect


def surface_xy(camera: Camera, z) -> np.ndarray:
    """``x, y`` (mm) of the surface point each pixel sees, given its height ``z``.

    Parameters
    ----------
    camera : Orthographic or Perspective
    z : array_like, shape (H, W)
        Height of the seen point above the reference plane, mm (NaN stays NaN in
        perspective ``xy``).

    Returns
    -------
    numpy.ndarray, shape (H, W, 2), float64
        Orthographic: the pixel grid (independent of ``z``); perspective:
        ``(u w / f, v w / f)`` with ``w = H_c - z``.

    Examples
    --------
    >>> cam = make_camera("perspective", focal_length_px=100.0, camera_height_mm=200.0)
    >>> surface_xy(cam, np.zeros((2, 3)))[0].tolist()  # 2 mm per pixel on z = 0
    [[-2.0, 1.0], [0.0, 1.0], [2.0, 1.0]]
    """
    zz = as_array(z, "z", ndim=2, finite=False)
    u, v = pixel_offsets(camera, zz.shape)
    if isinstance(camera, Orthographic):
        row = np.stack([u, np.zeros_like(u)], axis=1)  # (W, 2): x, then y added per row
        out = np.broadcast_to(row, zz.shape + (2,)).copy()
        out[..., 1] = v[:, None]
        return out
    scale = (camera.camera_height_mm - zz) * (1.0 / camera.focal_length_px)
    return np.stack([u[None, :] * scale, v[:, None] * scale], axis=2)


def plane_points(camera: Camera, shape, z0: float = 0.0) -> np.ndarray:
    """Points where each pixel's ray meets the horizontal plane ``z = z0`` (mm).

    Parameters
    ----------
    camera : Orthographic or Perspective
    shape : (H, W)
    z0 : float, optional
        Plane height, mm (below a perspective camera).

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), float64
    """
    h, w = image_shape(shape, "shape")
    if isinstance(camera, Perspective) and z0 >= camera.camera_height_mm:
        raise InputError(f"z0: the plane z = {z0} mm is not below the camera ({camera.camera_height_mm} mm)")
    z = np.full((h, w), float(z0))
    return np.concatenate([surface_xy(camera, z), z[..., None]], axis=2)


def pixel_rays(camera: Camera, shape, rows, cols) -> tuple[np.ndarray, np.ndarray]:
    """Rays through fractional pixel positions (sub-pixel highlight centroids).

    Parameters
    ----------
    camera : Orthographic or Perspective
    shape : (H, W)
        Image size (for the default principal point and the orthographic grid).
    rows, cols : array_like, shape (K,)
        Fractional pixel indices (pixel centres at integers).

    Returns
    -------
    origins : numpy.ndarray, shape (K, 3), float64
        Orthographic: the point of the ray on the plane ``z = 0``; perspective: the
        camera centre.
    directions : numpy.ndarray, shape (K, 3), float64
        Unit directions into the scene (``d_z < 0``).
    """
    h, w = image_shape(shape, "shape")
    r = as_array(rows, "rows", ndim=1)
    c = as_array(cols, "cols", shape=r.shape)
    if isinstance(camera, Orthographic):
        ps = camera.pixel_size_mm
        origins = np.stack([(c - (w - 1) / 2.0) * ps, ((h - 1) / 2.0 - r) * ps, np.zeros_like(r)], axis=1)
        return origins, np.tile([0.0, 0.0, -1.0], (r.size, 1))
    cx, cy = camera.centre((h, w))
    d = np.stack([(c - cx) / camera.focal_length_px, (cy - r) / camera.fy, -np.ones_like(r)], axis=1)
    origins = np.tile([0.0, 0.0, camera.camera_height_mm], (r.size, 1))
    return origins, d / np.linalg.norm(d, axis=1, keepdims=True)


def gradient_field(camera: Camera, normals) -> tuple[np.ndarray, np.ndarray, float]:
    """The gradient that the normal integrators integrate, from unit normals.

    Parameters
    ----------
    camera : Orthographic or Perspective
    normals : array_like, shape (H, W, 3)
        Unit normals facing the camera (``n_z > 0``).

    Returns
    -------
    p, q : numpy.ndarray, shape (H, W), float32
        Orthographic: ``p = dz/dx = -n_x / n_z``, ``q = dz/dy = -n_y / n_z``.
        Perspective: the derivatives of the log-depth ``l = log w`` (``w = H_c - z``)
        per pixel along ``u`` (right) and ``v`` (up): with ``a = n_x / n_z``,
        ``b = n_y / n_z``, ``l_u = a / (f - u a - v b)``, ``l_v = b / (f - u a - v b)``.
        They follow from ``n ~ (f l_u, f l_v, 1 + u l_u + v l_v)``, the cross product of
        the derivatives of ``X = (u w / f, v w / f, H_c - w)`` along ``u`` and ``v``.
    spacing : float
        The ``pixel_size`` to integrate with: the orthographic pixel size (mm), or 1
        (offsets in pixels) for the perspective camera.

    Notes
    -----
    Where ``n_z <= 0`` or ``f - u a - v b <= 0`` the surface is seen edge-on or from
    behind; ``p, q`` are 0 there (such pixels are not valid normals).

    Examples
    --------
    A plane rising 0.1 mm per mm to the right, seen at the principal point by a camera
    300 mm above it: ``l_u = -0.1 / f``.

    >>> cam = make_camera("perspective", focal_length_px=1000.0, camera_height_mm=300.0)
    >>> n = np.array([-0.1, 0.0, 1.0]) / np.sqrt(1.01)
    >>> p, q, spacing = gradient_field(cam, np.broadcast_to(n, (3, 3, 3)))
    >>> round(float(p[1, 1]) * 1000.0, 6), float(q[1, 1]), spacing
    (-0.1, 0.0, 1.0)
    """
    n = as_array(normals, "normals", dtype=np.float32, finite=False)
    if n.ndim != 3 or n.shape[2] != 3:
        raise InputError(f"normals: expected shape (H, W, 3), got {n.shape}")
    u, v = pixel_offsets(camera, n.shape[:2])
    return _gradient(camera, n[..., 0], n[..., 1], n[..., 2], u, v)


def _gradient(camera: Camera, nx, ny, nz, u, v) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`gradient_field` from normal planes (h, w) and the offsets ``u`` (w,), ``v`` (h,) of
    the grid (a coarse grid's block centres, in full-resolution pixels).

    float32 throughout, written into the two output planes in place (no float64 or extra
    full-size temporaries): this runs on every pass of the near-field alternation.
    """
    f32 = np.float32
    shape = np.shape(nz)
    p = np.empty(shape, f32)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        facing = nz > 0
        # a masked division is about three times slower than a plain one: only when some pixel faces away
        every = bool(facing.all())
        if isinstance(camera, Orthographic):
            q = np.divide(f32(-1.0), nz, dtype=f32) if every else \
                np.divide(f32(-1.0), nz, out=np.zeros(shape, f32), where=facing)
            np.multiply(nx, q, out=p)
            np.multiply(ny, q, out=q)
        else:
            q = np.empty(shape, f32)
            inv = np.divide(f32(1.0), nz, dtype=f32) if every else \
                np.divide(f32(1.0), nz, out=np.zeros(shape, f32), where=facing)
            np.multiply(nx, inv, out=p)  # a = n_x / n_z
            np.multiply(ny, inv, out=q)  # b = n_y / n_z
            f = f32(camera.focal_length_px)
            # den = f - u a - v b, then 1 / den (0 where not ahead), into inv (no longer needed)
            den = np.multiply(p, u.astype(f32)[None, :], out=inv)
            np.subtract(f, den, out=den)
            den -= q * v.astype(f32)[:, None]
            ok = den > f32(1e-6) * f
            np.divide(f32(1.0), den, out=den, where=ok)
            den[~ok] = 0.0
            p *= den
            q *= den
            if camera.focal_length_y_px is not None:  # per row of pixels, not per f-scaled row offset
                q *= f32(camera.aspect)
        # a grazing normal (n_z a denormal) overflows: no slope there. A float64 sum of float32 values
        # cannot overflow, so it is finite exactly when every value is (one pass, no temporary)
        for g in (p, q):
            if not np.isfinite(g.sum(dtype=np.float64)):
                g[~np.isfinite(g)] = 0.0
    return p, q, _spacing(camera)


def _spacing(camera: Camera) -> float:
    return camera.pixel_size_mm if isinstance(camera, Orthographic) else 1.0


def depth_from_field(camera: Camera, field, *, valid=None, reference_height_mm: float = 0.0,
                     sample_step: int = 1, dtype=np.float64) -> tuple[np.ndarray, float]:
    """Height ``z`` from an integrated field, anchored to the reference height.

    The integral of :func:`gradient_field` is known up to a constant (an offset of
    ``z``, or a scale of the perspective depth ``w = exp(l)``), which the normals do not
    determine. The anchoring rule: the **median height of the valid pixels is**
    ``reference_height_mm`` (0: the part's surface lies, robustly, on the reference
    plane; a dent or scratch does not move the median).

    Parameters
    ----------
    camera : Orthographic or Perspective
    field : array_like, shape (H, W)
        Orthographic: ``z`` up to a constant (mm); perspective: ``log w`` up to a
        constant. NaN outside the integration domain (kept NaN).
    valid : array_like, shape (H, W), optional
        Pixels whose median is anchored (default: the finite ones).
    reference_height_mm : float, optional
        Median height of the valid pixels, mm (below a perspective camera).
    sample_step : int, optional
        Take the median over every ``sample_step``-th row and column (speed on large
        images; 1 = all pixels).
    dtype : {float64, float32}, optional
        dtype of ``z``, computed in float64 and rounded. float32 (orthographic camera)
        rounds each height by at most ``2**-24 |z|`` (6e-9 mm at 0.1 mm) and halves the
        memory traffic of the arrays that follow it; a perspective ``z = H_c - w`` loses more
        (``2**-24 H_c``, 1.8e-5 mm at 300 mm), so there float64 is the sensible choice.

    Returns
    -------
    z : numpy.ndarray, shape (H, W), ``dtype``
        Height of the point each pixel sees, mm.
    constant : float
        The constant added to ``field`` (orthographic, mm) or to ``log w``
        (perspective).
    """
    fld = as_array(field, "field", ndim=2, finite=False,
                   dtype=None if np.issubdtype(np.asarray(field).dtype, np.floating) else np.float64)
    s = max(1, int(sample_step))
    # finiteness and validity on the sampled pixels only; the median in float64 (as of a float64 field)
    sub = fld[::s, ::s]
    use = np.isfinite(sub)
    if valid is not None:
        ok = as_array(valid, "valid", shape=fld.shape, dtype=bool)
        use &= ok[::s, ::s]
    sample = sub[use]
    if sample.size == 0 and s > 1:
        use = np.isfinite(fld) if valid is None else np.isfinite(fld) & ok
        sample = fld[use]
    if sample.size == 0:
        raise InputError("field: no valid pixel to anchor the height")
    med = float(np.median(sample.astype(np.float64, copy=False)))
    if np.dtype(dtype) not in (np.float64, np.float32):
        raise InputError(f"dtype: expected float64 or float32, got {np.dtype(dtype)}")
    # z in float64 straight from a float32 field: no float64 copy of the field first
    if isinstance(camera, Orthographic):
        c = float(reference_height_mm) - med
        if np.dtype(dtype) == np.float32 and fld.dtype == np.float32:
            # the sum of a float32 and a float64 rounded once to float32, without a float64 array
            z = np.empty(fld.shape, np.float32)
            return np.add(fld, np.float64(c), dtype=np.float64, casting="same_kind", out=z), c
        return np.add(fld, c, dtype=np.float64).astype(dtype, copy=False), c
    depth = camera.camera_height_mm - float(reference_height_mm)
    if depth <= 0:
        raise InputError(f"reference_height_mm: {reference_height_mm} mm is not below the camera")
    # exp is monotone, so the median of w = exp(l + c) is exp(median(l) + c)
    c = float(np.log(depth)) - med
    w = np.exp(np.add(fld, c, dtype=np.float64))
    return np.subtract(camera.camera_height_mm, w, out=w).astype(dtype, copy=False), c


def footprint_area(camera: Camera, z, p=None, q=None) -> np.ndarray | float:
    """Area of each pixel's footprint projected on the ``x, y`` plane, mm^2.

    Parameters
    ----------
    camera : Orthographic or Perspective
    z : array_like, shape (H, W)
        Height of the seen point, mm.
    p, q : array_like, shape (H, W), optional
        Perspective: the log-depth derivatives ``l_u``, ``l_v`` of
        :func:`gradient_field` (per pixel); omitted, the surface is taken as locally
        parallel to the image plane.

    Returns
    -------
    float or numpy.ndarray, shape (H, W)
        Orthographic: ``h^2``. Perspective: ``|det d(x, y)/d(u, v)| = (w / f)^2
        (1 + u l_u + v l_v)`` with ``w = H_c - z`` (the derivative of
        ``(u w / f, v w / f)``).
    """
    if isinstance(camera, Orthographic):
        return camera.pixel_size_mm**2
    zz = as_array(z, "z", ndim=2, finite=False)
    w = camera.camera_height_mm - zz
    scale = w * w / (camera.focal_length_px * camera.fy)
    if p is None or q is None:
        return scale
    u, v = pixel_offsets(camera, zz.shape)
    v = v / camera.aspect  # cy - row: q is per row of pixels
    lu = as_array(p, "p", shape=zz.shape, finite=False)
    lv = as_array(q, "q", shape=zz.shape, finite=False)
    return scale * np.abs(1.0 + u[None, :] * lu + v[:, None] * lv)


def intrinsic_matrix(camera: Perspective, shape) -> np.ndarray:
    """OpenCV's intrinsic matrix ``K`` of a perspective camera (0-based principal point).

    Parameters
    ----------
    camera : Perspective
    shape : (H, W)
        Image size (for the default principal point).

    Returns
    -------
    numpy.ndarray, shape (3, 3), float64
        ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``.
    """
    cx, cy = camera.centre(shape)
    return np.array([[camera.focal_length_px, 0.0, cx], [0.0, camera.fy, cy], [0.0, 0.0, 1.0]])


def undistort_images(camera: Camera, images, mask=None):
    """Resample images through a distorting lens to the distortion-free pinhole camera of the same ``K``.

    Each output pixel looks up where its pinhole ray lands in the distorted image
    (``cv2.initUndistortRectifyMap`` with OpenCV's distortion model, bilinear
    interpolation); a pixel whose ray falls outside the distorted image is 0 and leaves
    the mask.

    Parameters
    ----------
    camera : Orthographic or Perspective
        Without ``distortion`` the images come back as they are.
    images : numpy.ndarray, shape (N, H, W) or (N, H, W, 3), float32
    mask : numpy.ndarray, shape (H, W), bool, optional

    Returns
    -------
    images : numpy.ndarray
        The resampled stack (a new array when resampled).
    mask : numpy.ndarray or None
        The mask resampled (nearest) and cut to the pixels seen; None when none was given
        and nothing was cut.
    """
    import cv2

    if not isinstance(camera, Perspective) or camera.distortion is None:
        return images, mask
    h, w = images.shape[1:3]
    K = intrinsic_matrix(camera, (h, w))
    map_x, map_y = cv2.initUndistortRectifyMap(K, np.asarray(camera.distortion), None, K, (w, h), cv2.CV_32FC1)
    out = np.empty_like(images)
    for k in range(images.shape[0]):
        out[k] = cv2.remap(images[k], map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    seen = (map_x >= 0) & (map_x <= w - 1) & (map_y >= 0) & (map_y <= h - 1)
    if mask is not None:
        m = cv2.remap(np.asarray(mask, np.uint8), map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                      borderValue=0) > 0
        return out, m & seen
    return out, (None if seen.all() else seen)


def calibrate_checkerboard(images, board, square_mm: float, *, camera_height_mm: float | None = None):
    """A perspective camera with lens distortion from checkerboard images (OpenCV's calibration).

    The inner corners are found (``cv2.findChessboardCorners``, refined with
    ``cv2.cornerSubPix``) and ``cv2.calibrateCamera`` fits ``fx``, ``fy``, the principal point
    and ``(k1, k2, p1, p2, k3)``. The camera height above the reference plane is
    ``camera_height_mm`` when given, else the distance of the camera centre from the board
    of the **first** image (the board lying on the reference plane).

    Parameters
    ----------
    images : sequence of numpy.ndarray, each (H, W) or (H, W, 3)
        Views of the board (one size), values in [0, 1] or integers; at least 3 views for
        a stable fit.
    board : (int, int)
        Inner corners per row and per column ``(COLS, ROWS)`` (``--board COLSxROWS``).
    square_mm : float
        Side of one square, mm.
    camera_height_mm : float, optional

    Returns
    -------
    camera : Perspective
    info : dict
        ``rms_reprojection_px`` (OpenCV's RMS over every corner), ``views`` (images whose
        corners were found), ``board``, ``square_mm``, ``camera_height_source``.

    Raises
    ------
    InputError
        No corners in some image, fewer than 3 usable views, a bad board or square size.
    """
    import cv2

    cols, rows = (int(board[0]), int(board[1]))
    if cols < 2 or rows < 2:
        raise InputError(f"board: expected at least 2 x 2 inner corners, got {cols} x {rows}")
    sq = positive(square_mm, "square_mm")
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * sq
    found, shape = [], None
    for k, img in enumerate(images):
        a = np.asarray(img)
        grey = a.mean(axis=2) if a.ndim == 3 else a
        if shape is None:
            shape = grey.shape
        elif grey.shape != shape:
            raise InputError(f"checkerboard: image {k} is {grey.shape}, image 0 is {shape}")
        g8 = np.clip(grey * (255.0 if grey.dtype.kind == "f" else 255.0 / np.iinfo(grey.dtype).max), 0, 255)
        g8 = g8.astype(np.uint8)
        ok, corners = cv2.findChessboardCorners(g8, (cols, rows), cv2.CALIB_CB_ADAPTIVE_THRESH
                                                | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not ok:
            raise InputError(f"checkerboard: image {k}: no {cols} x {rows} inner corners found")
        corners = cv2.cornerSubPix(g8, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4))
        found.append(corners)
    if len(found) < 3:
        raise InputError(f"checkerboard: {len(found)} view(s); give at least 3 (tilted differently)")
    h, w = shape
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(found), found, (w, h), None, None)
    source = "option"
    if camera_height_mm is None:
        R, _ = cv2.Rodrigues(rvecs[0])
        centre = -R.T @ tvecs[0].ravel()  # the camera centre in the first board's frame
        camera_height_mm, source = float(abs(centre[2])), "first checkerboard view (board on the reference plane)"
    cam = make_camera("perspective", focal_length_px=(float(K[0, 0]), float(K[1, 1])),
                      camera_height_mm=camera_height_mm, principal_point_px=(float(K[0, 2]), float(K[1, 2])),
                      distortion=np.asarray(dist).ravel()[:5])
    info = {"method": "checkerboard (cv2.findChessboardCorners + cv2.calibrateCamera)",
            "rms_reprojection_px": float(rms), "views": len(found), "board": [cols, rows], "square_mm": sq,
            "camera_height_source": source}
    return cam, info
