"""Physically based renders of inspection rigs with Mitsuba 3: glossy plates, LED discs, real lenses and sensors.

A renderer nobody on the project wrote (Mitsuba 3, ``pip install mitsuba``; its CPU
variant ``scalar_rgb``), driven in the conventions of
:mod:`datasets_synthetic.nearfield`: millimetres, x right, y up, z towards the
camera (:data:`datasets_synthetic.heightfields.CONVENTION`), the same
:class:`~datasets_synthetic.cameras.Camera` and
:class:`~datasets_synthetic.point_lights.PointLights`. Mitsuba is imported
inside the functions that need it, so ``import datasets_synthetic`` stays light.

The scene
---------
* The part: an :class:`~datasets_synthetic.heightfields.AnalyticSurface` (a plate
  with scratches and dents from :mod:`datasets_synthetic.heightfields`) sampled on
  a grid finer than the pixels (``mesh_step_px``) over the field of view plus a
  margin, written as a binary PLY mesh whose vertex normals are the surface's exact
  normals (Mitsuba interpolates them for shading).
* The material (:func:`material`): ``diffuse`` (the matte control), ``roughplastic``
  (a diffuse base under a dielectric GGX coat) or ``roughconductor`` (GGX metal).
* The LEDs: point emitters (isotropic, ``mu`` = 0) or small disc area emitters
  (``led_radius_mm`` > 0; a Lambertian disc, whose radiant intensity falls as the
  cosine off its axis: ``mu`` = 1). Either way light ``k`` delivers the irradiance
  ``e_k`` at the origin when it faces it (the point-light model of
  :mod:`datasets_synthetic.point_lights`): radiant intensity ``e_k |P_k|^2``.
* The camera: Mitsuba's ``orthographic`` or ``perspective`` sensor over the pixel
  grid of :mod:`datasets_synthetic.cameras` (pixel centres at whole pixel indices,
  box pixel filter: a pixel integrates its square footprint).
* The integrator: ``direct`` (direct light with cast shadows) or ``path`` (also
  interreflections).

A Lambertian surface of albedo ``rho`` under light ``k`` then has the radiance
``rho / pi * E_k(X) * max(0, n . l_k)``: the project's own model
(:func:`datasets_synthetic.point_lights.shading`) up to the factor ``rho / pi``.

The camera and sensor (:func:`camera_effects`, numpy and OpenCV, after Mitsuba)
---------------------------------------------------------------------------------
Lens first: OpenCV's distortion model (``k1, k2, p1, p2, k3``, resampled with
``cv2.remap``), vignetting (:func:`datasets_synthetic.cameras.vignetting_map`),
Gaussian blur; then the sensor: shot noise, read noise, clipping at full scale and
quantisation to ``bit_depth`` bits (12 by default).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from datasets_synthetic.cameras import Camera, SurfaceHits, analytic_surface, intersect, vignetting_map
from datasets_synthetic.heightfields import AnalyticSurface, HeightField
from datasets_synthetic.nearfield import NearFieldRender, write_near_field_folder
from datasets_synthetic.point_lights import PointLights, point_lights
from datasets_synthetic.render import grid_triangles
from surfaces.io import jsonable, write_json
from surfaces.validate import InputError, as_array, positive

#: The Mitsuba variant used (CPU, RGB; ``llvm_ad_rgb`` needs an LLVM this machine's is not).
VARIANT = "scalar_rgb"
MATERIALS = ("diffuse", "roughplastic", "roughconductor", "lambertian_ggx")
INTEGRATORS = ("direct", "path")
#: Default brightest clean value (full scale 1) when the exposure is chosen automatically.
PEAK = 0.9
#: Default albedo of the flat-field target.
FLAT_ALBEDO = 0.8


def _mitsuba():
    """Import Mitsuba and select :data:`VARIANT` (a clear error when it is missing)."""
    try:
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("datasets_synthetic.mitsuba_scenes needs Mitsuba 3: pip install mitsuba") from exc
    if mi.variant() != VARIANT:
        mi.set_variant(VARIANT)
    return mi


# ----------------------------------------------------------------------------- materials

@dataclass(frozen=True)
class Material:
    """A BSDF of the plate (see :func:`material`).

    Attributes
    ----------
    kind : {"diffuse", "roughplastic", "roughconductor", "lambertian_ggx"}
        Mitsuba plugin (``lambertian_ggx``: a ``blendbsdf`` of ``diffuse`` and a
        perfectly reflecting ``roughconductor``).
    albedo : float
        Diffuse reflectance (roughplastic: of the base under the coat; roughconductor:
        the specular reflectance scale).
    alpha : float
        GGX roughness (not for diffuse).
    specular : float
        roughplastic: the coat's ``specular_reflectance`` relative to ``albedo``;
        lambertian_ggx: the lobe's reflectance relative to ``albedo``.
    ior : float
        roughplastic: refractive index of the coat.
    conductor : str
        roughconductor: Mitsuba's material name (``"Al"``, ``"Cu"``, ``"none"`` for a
        perfect mirror, ...).
    """

    kind: str
    albedo: float = 0.8
    alpha: float = 0.3
    specular: float = 0.3
    ior: float = 1.5
    conductor: str = "Al"

    @property
    def coat_f0(self) -> float:
        """Normal-incidence Fresnel reflectance of a dielectric coat, ``((n - 1) / (n + 1))^2``."""
        return ((self.ior - 1.0) / (self.ior + 1.0)) ** 2

    def as_dict(self) -> dict:
        """The material as written in ``scene.json``."""
        out = {"kind": self.kind, "albedo": self.albedo}
        if self.kind == "roughplastic":
            out.update(alpha=self.alpha, specular=self.specular, ior=self.ior, distribution="ggx")
        elif self.kind == "lambertian_ggx":
            out.update(alpha=self.alpha, specular=self.specular, distribution="ggx")
        elif self.kind == "roughconductor":
            out.update(alpha=self.alpha, conductor=self.conductor, distribution="ggx")
        return out

    def bsdf(self) -> dict:
        """The Mitsuba BSDF dictionary."""
        grey = {"type": "rgb", "value": [self.albedo] * 3}
        if self.kind == "diffuse":
            return {"type": "diffuse", "reflectance": grey}
        if self.kind == "roughplastic":
            spec = self.specular * self.albedo
            return {"type": "roughplastic", "distribution": "ggx", "alpha": self.alpha, "int_ior": self.ior,
                    "ext_ior": 1.0, "diffuse_reflectance": grey, "nonlinear": False,
                    # a plain float: Mitsuba refuses RGB reflectances above 1 (specular > 1 / albedo)
                    "specular_reflectance": float(spec)}
        if self.kind == "lambertian_ggx":
            # (1 - t) diffuse(a) + t lobe(a) with t = w / (1 + w), a = albedo (1 + w): diffuse albedo, lobe w albedo
            t = self.specular / (1.0 + self.specular)
            a = self.albedo * (1.0 + self.specular)
            return {"type": "blendbsdf", "weight": t,
                    "diffuse": {"type": "diffuse", "reflectance": a},
                    "lobe": {"type": "roughconductor", "distribution": "ggx", "alpha": self.alpha, "material": "none",
                             "specular_reflectance": a}}
        return {"type": "roughconductor", "distribution": "ggx", "alpha": self.alpha, "material": self.conductor,
                "specular_reflectance": grey}


def material(kind: str = "diffuse", albedo: float = 0.8, alpha: float = 0.3, specular: float = 0.3,
             ior: float = 1.5, conductor: str = "Al") -> Material:
    """Check and assemble the plate's material.

    Parameters
    ----------
    kind : {"diffuse", "roughplastic", "roughconductor", "lambertian_ggx"}
        ``diffuse``: Lambertian (the matte control). ``roughplastic``: Lambertian base
        under a dielectric coat with a GGX microfacet lobe (the coat's Fresnel
        transmission also makes the base depart from Lambert's law). ``roughconductor``:
        a GGX metal (no diffuse part). ``lambertian_ggx``: a gloss lobe alone, the
        Lambertian albedo plus a GGX lobe without Fresnel falloff (Mitsuba's
        ``blendbsdf`` of ``diffuse`` and a perfectly reflecting ``roughconductor``).
    albedo : float
        Diffuse albedo in (0, 1] (roughconductor: scale of its reflectance).
    alpha : float
        GGX roughness (Mitsuba's ``alpha``, > 0).
    specular : float
        roughplastic only: the weight of the specular lobe relative to the diffuse one,
        Mitsuba's ``specular_reflectance = specular * albedo`` (>= 0). The coat's
        Fresnel term multiplies it: at normal incidence the lobe reflects
        ``F0 * specular * albedo`` with ``F0 = ((ior - 1) / (ior + 1))^2`` (0.04 at
        ior 1.5); ``specular`` = 1 / albedo is an ordinary plastic. lambertian_ggx: the
        lobe's reflectance relative to the diffuse albedo.
    ior : float
        roughplastic: the coat's refractive index (> 1).
    conductor : str
        roughconductor: Mitsuba's conductor name.

    Returns
    -------
    Material

    Examples
    --------
    >>> m = material("roughplastic", 0.8, alpha=0.3, specular=0.3)
    >>> m.bsdf()["specular_reflectance"], round(m.coat_f0, 3)
    (0.24, 0.04)
    """
    if kind not in MATERIALS:
        raise InputError(f"kind: expected one of {MATERIALS}, got {kind!r}")
    albedo = positive(albedo, "albedo")
    if albedo > 1:
        raise InputError(f"albedo: must lie in (0, 1], got {albedo}")
    alpha = positive(alpha, "alpha")
    specular = positive(specular, "specular", allow_zero=True)
    ior = positive(ior, "ior")
    if ior <= 1:
        raise InputError(f"ior: a coat's refractive index must exceed 1, got {ior}")
    return Material(kind, albedo, alpha, specular, ior, str(conductor))


# ----------------------------------------------------------------------------- the plate mesh

def plate_mesh(surface, x_range, y_range, step_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A triangle mesh of an analytic surface over a rectangle, with its exact vertex normals.

    Parameters
    ----------
    surface : AnalyticSurface or HeightField
        The scene.
    x_range, y_range : (float, float)
        Extent of the mesh in mm (x right, y up).
    step_mm : float
        Largest vertex spacing in mm (the grid divides each range evenly).

    Returns
    -------
    vertices : (V, 3) float32 array
        Grid points ``(x, y, z(x, y))`` in mm, row by row from the top (largest y).
    normals : (V, 3) float32 array
        Unit normals ``(-p, -q, 1) / |.|`` there.
    faces : (F, 3) uint32 array
        Triangles, counter-clockwise seen from +z (facing the camera).
    """
    s = analytic_surface(surface)
    step = positive(step_mm, "step_mm")
    (x0, x1), (y0, y1) = (as_array(r, name, shape=(2,)) for r, name in ((x_range, "x_range"), (y_range, "y_range")))
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"x_range, y_range: expected increasing ranges, got {x_range!r}, {y_range!r}")
    nx = int(np.ceil((x1 - x0) / step)) + 1
    ny = int(np.ceil((y1 - y0) / step)) + 1
    x, y = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y1, y0, ny))
    z, p, q, _ = s._evaluate(x, y)
    verts, faces = grid_triangles(np.stack([x, y, z], axis=-1))
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return verts, n.reshape(-1, 3).astype(np.float32), faces


def write_ply(path: str | os.PathLike, vertices, normals, faces) -> Path:
    """Write a binary little-endian PLY mesh with vertex normals (what Mitsuba's ``ply`` plugin reads).

    Parameters
    ----------
    path : str or path-like
        File to write.
    vertices, normals : (V, 3) array_like
        Positions (mm) and unit normals.
    faces : (F, 3) array_like of int
        Triangle vertex indices.

    Returns
    -------
    Path
        The file written.
    """
    v = as_array(vertices, "vertices", shape=(None, 3)).astype("<f4")
    n = as_array(normals, "normals", shape=(len(v), 3)).astype("<f4")
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or f.size and (f.min() < 0 or f.max() >= len(v)):
        raise InputError(f"faces: expected (F, 3) indices into {len(v)} vertices")
    vert = np.empty(len(v), dtype=[(c, "<f4") for c in ("x", "y", "z", "nx", "ny", "nz")])
    for i, c in enumerate(("x", "y", "z")):
        vert[c] = v[:, i]
        vert["n" + c] = n[:, i]
    tri = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    tri["n"] = 3
    tri["i"] = f
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(v)}\n" + "".join(f"property float {c}\n" for c in vert.dtype.names)
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    out = Path(path)
    with open(out, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(vert.tobytes())
        fh.write(tri.tobytes())
    return out


# ----------------------------------------------------------------------------- sensor, lights, scene

def _sensor(mi, camera: Camera, spp: int) -> dict:
    """Mitsuba's sensor seeing the pixel grid of ``camera`` (box filter: a pixel averages its footprint)."""
    T = mi.ScalarTransform4f
    h, w = camera.shape
    film = {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"}
    sampler = {"type": "independent", "sample_count": int(spp)}
    if camera.model == "orthographic":
        # Mitsuba's orthographic sensor sees x in [-1, 1] (and y in [-H/W, H/W]) of its local frame
        half = w * camera.pixel_size_mm / 2.0
        to_world = T().look_at(origin=[0, 0, 1e4], target=[0, 0, 0], up=[0, 1, 0]) @ T().scale([half, half, 1.0])
        return {"type": "orthographic", "to_world": to_world, "near_clip": 1.0, "far_clip": 2e4, "film": film,
                "sampler": sampler}
    cx, cy = camera.principal_point_px
    if abs(cx - (w - 1) / 2.0) > 1e-9 or abs(cy - (h - 1) / 2.0) > 1e-9:
        raise InputError("camera: the Mitsuba harness renders perspective cameras with the principal point at the "
                         "image centre only")
    fov = float(np.degrees(2.0 * np.arctan(w / (2.0 * camera.focal_length_px))))
    to_world = T().look_at(origin=[0, 0, camera.camera_height_mm], target=[0, 0, 0], up=[0, 1, 0])
    return {"type": "perspective", "fov": fov, "fov_axis": "x", "to_world": to_world, "near_clip": 1.0,
            "far_clip": 1e5, "film": film, "sampler": sampler}


def _emitter(mi, lights: PointLights, k: int, radius_mm: float) -> dict:
    """Light ``k`` as a point emitter or a Lambertian disc facing its axis, on-axis intensity ``e_k |P_k|^2``."""
    e = float(np.mean(lights.intensities[k]))
    power = e * lights.d0[k] ** 2
    if radius_mm <= 0:
        return {"type": "point", "position": lights.positions[k].tolist(),
                "intensity": {"type": "rgb", "value": [power] * 3}}
    T = mi.ScalarTransform4f
    pos = lights.positions[k]
    axis = lights.axes[k]
    up = [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [0.0, 1.0, 0.0]
    to_world = T().look_at(origin=pos.tolist(), target=(pos + axis).tolist(), up=up) @ T().scale(radius_mm)
    radiance = power / (np.pi * radius_mm**2)
    return {"type": "disk", "to_world": to_world,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}},
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}}


def _integrator(kind: str, max_depth: int) -> dict:
    if kind == "direct":
        return {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1}
    return {"type": "path", "max_depth": int(max_depth)}


def _mesh_extent(surface: AnalyticSurface, camera: Camera, margin_mm: float) -> tuple[tuple, tuple]:
    """x and y ranges (mm) that hold every point the camera sees, plus ``margin_mm``."""
    h, w = camera.shape
    if camera.model == "orthographic":
        hx, hy = w * camera.pixel_size_mm / 2.0, h * camera.pixel_size_mm / 2.0
    else:
        lo, _ = surface.relief_bounds
        z0, sx, sy = surface.plane
        # the lowest point any ray may reach bounds the footprint of the cone of view
        depth = camera.camera_height_mm - min(lo, z0) + (abs(sx) + abs(sy)) * camera.camera_height_mm
        hx = depth * (w / 2.0) / camera.focal_length_px
        hy = depth * (h / 2.0) / camera.focal_length_px
    return (-hx - margin_mm, hx + margin_mm), (-hy - margin_mm, hy + margin_mm)


# ----------------------------------------------------------------------------- camera effects

def distort_image(image, camera_matrix, distortion) -> np.ndarray:
    """Resample an ideal image as a lens with OpenCV's distortion model records it.

    The distorted image at pixel ``u_d`` shows the ideal image at ``u``, where
    ``u_d = K distort(K^-1 u)`` (OpenCV's ``k1, k2, p1, p2, k3`` model): every output
    pixel is undistorted (``cv2.undistortPoints``, 50 iterations) and the ideal image sampled
    there (``cv2.remap``, bilinear; outside the image: the nearest edge value).

    Parameters
    ----------
    image : (H, W) or (N, H, W) array_like
        Ideal image(s).
    camera_matrix : (3, 3) array_like
        ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` in pixels (0-based principal point).
    distortion : (5,) array_like
        ``k1, k2, p1, p2, k3``.

    Returns
    -------
    float32 array, the shape of ``image``
    """
    import cv2

    img = as_array(image, "image", ndim=(2, 3)).astype(np.float32)
    K = as_array(camera_matrix, "camera_matrix", shape=(3, 3))
    d = as_array(distortion, "distortion", shape=(5,))
    h, w = img.shape[-2:]
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
    pts = np.stack([cols.ravel(), rows.ravel()], axis=-1)[:, None, :]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    und = cv2.undistortPoints(pts, K, d, R=None, P=K, criteria=crit).reshape(h, w, 2).astype(np.float32)
    stack = img[None] if img.ndim == 2 else img
    out = np.stack([cv2.remap(s, und[..., 0], und[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
                    for s in stack])
    return out[0] if img.ndim == 2 else out


def lens_matrix(camera: Camera, focal_length_px: float | None = None) -> np.ndarray:
    """The pixel matrix ``K`` in which a lens distortion of ``camera`` is stated.

    Parameters
    ----------
    camera : Camera
        Perspective: its focal length and principal point. Orthographic (a telecentric
        lens has no focal length in pixels): ``focal_length_px`` or, by default, the
        image width, so that the normalised radius is 0.5 at mid-edge of a square image.
    focal_length_px : float, optional
        Overrides the focal length.

    Returns
    -------
    (3, 3) float64 array
    """
    h, w = camera.shape
    if camera.model == "perspective":
        f = camera.focal_length_px if focal_length_px is None else positive(focal_length_px, "focal_length_px")
        cx, cy = camera.principal_point_px
    else:
        f = float(w) if focal_length_px is None else positive(focal_length_px, "focal_length_px")
        cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def camera_effects(images, camera: Camera, rng: int | np.random.Generator = 0, distortion=None,
                   vignetting: dict | None = None, blur_px: float = 0.0, shot_noise: float = 0.0,
                   read_noise: float = 0.0, bit_depth: int | None = 12) -> np.ndarray:
    """What a real lens and sensor make of ideal images (in full-scale units, 1 = the sensor's largest value).

    In this order: lens distortion (:func:`distort_image`), vignetting
    (:func:`datasets_synthetic.cameras.vignetting_map`), Gaussian blur of standard
    deviation ``blur_px`` (``cv2.GaussianBlur``), shot noise ``g Poisson(I / g)``,
    Gaussian read noise, clipping to [0, 1] and quantisation to ``2^bit_depth - 1``
    levels.

    Parameters
    ----------
    images : (H, W) or (N, H, W) array_like
        Ideal images in full-scale units.
    camera : Camera
        The camera (its shape, and the pixel matrix of the distortion, :func:`lens_matrix`).
    rng : int or numpy.random.Generator
        Noise source.
    distortion : dict, optional
        ``{"k1", "k2", "p1", "p2", "k3"}`` (missing keys are 0) and optionally
        ``"focal_length_px"`` for an orthographic camera.
    vignetting : dict, optional
        :func:`~datasets_synthetic.cameras.vignetting_map` specification.
    blur_px : float
        Gaussian blur standard deviation in pixels (0: none).
    shot_noise : float
        Shot-noise scale ``g`` in full-scale units (a full well of ``1 / g`` electrons).
    read_noise : float
        Standard deviation of the read noise, full-scale units.
    bit_depth : int or None
        Quantisation (e.g. 12); None keeps floats (still clipped at 1).

    Returns
    -------
    float32 array, the shape of ``images``
        Values in [0, 1] (multiples of ``1 / (2^bit_depth - 1)`` when quantised).
    """
    import cv2

    img = as_array(images, "images", ndim=(2, 3)).astype(np.float64)
    if img.shape[-2:] != tuple(camera.shape):
        raise InputError(f"images: expected images of the camera's shape {camera.shape}, got {img.shape[-2:]}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    blur_px = positive(blur_px, "blur_px", allow_zero=True)
    shot_noise = positive(shot_noise, "shot_noise", allow_zero=True)
    read_noise = positive(read_noise, "read_noise", allow_zero=True)
    if bit_depth is not None and not (isinstance(bit_depth, (int, np.integer)) and 1 <= bit_depth <= 16):
        raise InputError(f"bit_depth: expected None or an integer in 1..16, got {bit_depth!r}")
    if distortion is not None:
        unknown = set(distortion) - {"k1", "k2", "p1", "p2", "k3", "focal_length_px"}
        if unknown:
            raise InputError(f"distortion: unknown keys {sorted(unknown)}")
        coef = [float(distortion.get(k, 0.0)) for k in ("k1", "k2", "p1", "p2", "k3")]
        img = distort_image(img, lens_matrix(camera, distortion.get("focal_length_px")), coef).astype(np.float64)
    img = img * vignetting_map(camera, vignetting)
    if blur_px > 0:
        stack = img[None] if img.ndim == 2 else img
        img = np.stack([cv2.GaussianBlur(s, (0, 0), blur_px, borderType=cv2.BORDER_REFLECT) for s in stack])
        img = img.reshape(np.shape(images))
    if shot_noise > 0:
        img = shot_noise * rng.poisson(np.maximum(img, 0.0) / shot_noise)
    if read_noise > 0:
        img = img + rng.normal(0.0, read_noise, img.shape)
    img = np.clip(img, 0.0, 1.0)
    if bit_depth is not None:
        full = 2.0**bit_depth - 1.0
        img = np.round(img * full) / full
    return img.astype(np.float32)


# ----------------------------------------------------------------------------- rendering

@dataclass(frozen=True)
class MitsubaRender:
    """A Mitsuba render of a plate under N LEDs, its flat fields and the truth.

    Attributes
    ----------
    images : (N, H, W) float32 array
        Part images in full-scale units [0, 1] after :func:`camera_effects`.
    flats : (N, H, W) float32 array or None
        Flat-field images (a diffuse plane z = 0 of ``flat_albedo``), same exposure and effects.
    radiance : (N, H, W) float32 array
        Mitsuba's part radiance before exposure and effects (grey: the mean of R, G, B).
    hits : SurfaceHits
        The exact surface point, slopes and normal each (ideal, undistorted) pixel sees.
    camera : Camera
        The camera.
    lights : PointLights
        The true lights (``mu`` = 1 for disc LEDs, 0 for points).
    material : Material
        The plate's BSDF.
    defects : tuple of dict
        The scene's defect truth (mm; :mod:`datasets_synthetic.heightfields` records).
    exposure : float
        Scale from radiance to full-scale units, shared by part and flat images.
    saturated_fraction : float
        Fraction of part and flat values at full scale after the effects.
    settings : dict
        Everything else that made the render (JSON-ready).
    """

    images: np.ndarray
    flats: np.ndarray | None
    radiance: np.ndarray
    hits: SurfaceHits
    camera: Camera
    lights: PointLights
    material: Material
    defects: tuple = ()
    exposure: float = 1.0
    saturated_fraction: float = 0.0
    settings: dict = field(default_factory=dict)


def render_mitsuba(
    surface,
    camera: Camera,
    lights: PointLights,
    bsdf: Material | None = None,
    led_radius_mm: float = 0.0,
    integrator: str = "direct",
    spp: int = 16,
    max_depth: int = 4,
    flats: bool = True,
    flat_albedo: float = FLAT_ALBEDO,
    mesh_step_px: float = 0.5,
    margin_mm: float | None = None,
    exposure: float | None = None,
    peak: float = PEAK,
    effects: dict | None = None,
    seed: int = 0,
    mesh_dir: str | os.PathLike | None = None,
) -> MitsubaRender:
    """Render a plate under each LED in turn with Mitsuba 3 (see the module docstring).

    Parameters
    ----------
    surface : AnalyticSurface or HeightField
        The plate (e.g. :func:`datasets_synthetic.heightfields.inspection_part`).
    camera : Camera
        Orthographic or perspective (principal point at the image centre).
    lights : PointLights
        LED positions and intensities ``e_k`` (irradiance at the origin when facing it);
        their axes aim the discs. ``mu`` must be 0 for point LEDs and is 1 for discs
        (a Lambertian emitter), whatever it holds.
    bsdf : Material, optional
        The plate's material; diffuse with albedo 0.8 by default.
    led_radius_mm : float
        0: point emitters; > 0: disc emitters of that radius.
    integrator : {"direct", "path"}
        Direct light with shadows, or path tracing (interreflections, ``max_depth``).
    spp : int
        Samples per pixel.
    max_depth : int
        Path length of the ``path`` integrator.
    flats : bool
        Also render the flat-field target (a diffuse plane z = 0 of ``flat_albedo``).
    flat_albedo : float
        Albedo of the flat-field target.
    mesh_step_px : float
        Mesh vertex spacing in reference-plane pixels (0.5: four vertices per pixel).
    margin_mm : float, optional
        The mesh reaches this far beyond the field of view (default: 4 pixels); the
        part outside casts shadows and reflects light too.
    exposure : float, optional
        Scale from radiance to full scale; by default ``peak`` over the brightest
        radiance of the part and flat images.
    peak : float
        Brightest value of the automatic exposure, in (0, 1].
    effects : dict, optional
        Keyword arguments of :func:`camera_effects` (``distortion``, ``vignetting``,
        ``blur_px``, ``shot_noise``, ``read_noise``, ``bit_depth``); by default no lens
        effect, no noise and float images.
    seed : int
        Seed of Mitsuba's samplers and of the sensor noise.
    mesh_dir : str or path-like, optional
        Where to write ``plate.ply`` (kept); a temporary folder by default.

    Returns
    -------
    MitsubaRender

    Raises
    ------
    InputError
        Bad options, LEDs with a lobe the emitter cannot make, or a scene without light.
    """
    mi = _mitsuba()
    if not isinstance(lights, PointLights):
        raise InputError(f"lights: expected PointLights, got {type(lights).__name__}")
    if not isinstance(camera, Camera):
        raise InputError(f"camera: expected a Camera, got {type(camera).__name__}")
    bsdf = material() if bsdf is None else bsdf
    if not isinstance(bsdf, Material):
        raise InputError(f"bsdf: expected a Material (datasets_synthetic.mitsuba_scenes.material), got "
                         f"{type(bsdf).__name__}")
    if integrator not in INTEGRATORS:
        raise InputError(f"integrator: expected one of {INTEGRATORS}, got {integrator!r}")
    radius = positive(led_radius_mm, "led_radius_mm", allow_zero=True)
    if radius == 0 and np.any(lights.mu != 0):
        raise InputError(f"lights: point emitters are isotropic (mu = 0), got mu = {lights.mu.tolist()}; use disc "
                         "LEDs (led_radius_mm > 0) for a cosine lobe")
    spp = int(positive(spp, "spp"))
    peak = positive(peak, "peak")
    if peak > 1:
        raise InputError(f"peak: must lie in (0, 1], got {peak}")
    flat_albedo = positive(flat_albedo, "flat_albedo")
    step = positive(mesh_step_px, "mesh_step_px") * camera.reference_pixel_mm
    margin = 4.0 * camera.reference_pixel_mm if margin_mm is None else positive(margin_mm, "margin_mm",
                                                                                 allow_zero=True)
    s = analytic_surface(surface)
    true_lights = point_lights(lights.positions, lights.axes, 1.0 if radius > 0 else 0.0, lights.intensities)
    hits = intersect(s, camera)
    xr, yr = _mesh_extent(s, camera, margin)
    verts, normals, faces = plate_mesh(s, xr, yr, step)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp if mesh_dir is None else mesh_dir)
        folder.mkdir(parents=True, exist_ok=True)
        ply = write_ply(folder / "plate.ply", verts, normals, faces)
        plate = mi.load_dict({"type": "ply", "filename": str(ply), "face_normals": False, "bsdf": bsdf.bsdf()})
    flat = None
    if flats:
        T = mi.ScalarTransform4f
        flat = mi.load_dict({"type": "rectangle", "to_world": T().scale([xr[1] - xr[0], yr[1] - yr[0], 1.0]),
                             "bsdf": material("diffuse", flat_albedo).bsdf()})
    sensor = _sensor(mi, camera, spp)
    n = len(true_lights)
    h, w = camera.shape

    def shoot(shape, k: int, salt: int) -> np.ndarray:
        scene = mi.load_dict({"type": "scene", "integrator": _integrator(integrator, max_depth), "sensor": sensor,
                              "shape": shape, "light": _emitter(mi, true_lights, k, radius)})
        return np.asarray(mi.render(scene, seed=int(seed) * 7919 + 2 * k + salt), dtype=np.float64).mean(axis=-1)

    radiance = np.stack([shoot(plate, k, 0) for k in range(n)])
    flat_radiance = np.stack([shoot(flat, k, 1) for k in range(n)]) if flats else None
    brightest = max(float(radiance.max()), float(flat_radiance.max()) if flats else 0.0)
    if brightest <= 0:
        raise InputError("lights: no pixel of the part or the flat field is lit")
    scale = peak / brightest if exposure is None else positive(exposure, "exposure")
    fx = dict(bit_depth=None) if effects is None else dict(effects)
    rng = np.random.default_rng(seed)
    images = camera_effects(scale * radiance, camera, rng, **fx)
    flat_images = camera_effects(scale * flat_radiance, camera, rng, **fx) if flats else None
    clipped = int(np.count_nonzero(images >= 1.0))
    total = images.size
    if flats:
        clipped += int(np.count_nonzero(flat_images >= 1.0))
        total += flat_images.size
    settings = {
        "renderer": f"Mitsuba {mi.__version__} ({VARIANT})", "integrator": integrator, "spp": spp,
        "max_depth": int(max_depth) if integrator == "path" else None, "led_radius_mm": radius,
        "led_model": "Lambertian disc area emitter (mu = 1)" if radius > 0 else "isotropic point emitter (mu = 0)",
        "material": bsdf.as_dict(), "mesh_step_mm": step, "mesh_extent_mm": [list(xr), list(yr)],
        "flat_albedo": flat_albedo, "exposure_auto": exposure is None, "peak": peak,
        "effects": jsonable(fx), "seed": int(seed),
    }
    defects = tuple(surface.defects) if isinstance(surface, HeightField) else ()
    return MitsubaRender(images=images, flats=flat_images, radiance=radiance.astype(np.float32), hits=hits,
                         camera=camera, lights=true_lights, material=bsdf, defects=defects, exposure=float(scale),
                         saturated_fraction=clipped / total, settings=settings)


def write_mitsuba_folder(out_dir: str | os.PathLike, rendered: MitsubaRender, scene: dict | None = None,
                         nominal: PointLights | None = None) -> dict:
    """Write a Mitsuba render in the near-field folder layout of :mod:`datasets_synthetic.nearfield`.

    The folder reads like any near-field capture (``workbench photometric reconstruct``):
    16-bit PNGs of the part and flat-field images, ``light_positions.txt`` (the
    ``nominal`` LEDs, the true ones by default), the truth (``height_gt.npy``,
    ``normal_gt.npy``, ``xy_gt.npy``) and ``scene.json`` with ``renderer`` (the
    render's settings) and ``defects``.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    rendered : MitsubaRender
        The render (with flat fields).
    scene : dict, optional
        Extra ``scene.json`` content.
    nominal : PointLights, optional
        The LEDs a user believes in.

    Returns
    -------
    dict
        The content of ``scene.json``.
    """
    if not isinstance(rendered, MitsubaRender):
        raise InputError(f"rendered: expected a MitsubaRender, got {type(rendered).__name__}")
    if rendered.flats is None:
        raise InputError("rendered: the near-field folder needs flat-field images (render with flats=True)")
    n = len(rendered.lights)
    fx = rendered.settings.get("effects", {})
    as_near = NearFieldRender(
        images=rendered.images, flats=rendered.flats, hits=rendered.hits, camera=rendered.camera,
        lights=rendered.lights, exposure=rendered.exposure, exposure_auto=rendered.settings["exposure_auto"],
        vignetting=vignetting_map(rendered.camera, fx.get("vignetting")), albedo=np.asarray(rendered.material.albedo),
        flat_albedo=rendered.settings["flat_albedo"], shadow_fraction=np.full(n, np.nan),
        saturated_fraction=rendered.saturated_fraction,
        settings={"shadows": "cast (Mitsuba)", "vignetting": fx.get("vignetting"), "peak": rendered.settings["peak"],
                  "noise": fx.get("read_noise", 0.0), "shot_noise": fx.get("shot_noise", 0.0),
                  "bit_depth": fx.get("bit_depth")},
    )
    content = {"model": "near-field", "renderer": rendered.settings, "image_size": list(rendered.camera.shape),
               "pixel_size_mm": rendered.camera.reference_pixel_mm, "n_lights": n,
               "defects": list(rendered.defects), "albedo": rendered.material.albedo}
    content.update(scene or {})
    written = write_near_field_folder(out_dir, as_near, content, nominal)
    # Mitsuba does not report which samples were shadowed: say so rather than write NaN (not JSON)
    written["shadow_fraction"] = None
    write_json(Path(out_dir) / "scene.json", written)
    return written
