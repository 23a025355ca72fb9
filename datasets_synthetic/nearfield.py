"""Near-field renders of inspection rigs: point lights, orthographic or perspective cameras, flat fields.

The forward model of the shared near-field format contract, written
independently of the solver in :mod:`photometric` (which it checks). For the
surface point ``X`` each pixel sees (:func:`datasets_synthetic.cameras.intersect`)::

    I_k(pixel) = s V(pixel) albedo(X) E_k(X) max(0, n(X) . l_k(X))

with the point-light irradiance ``E_k`` and light vector ``l_k`` of
:mod:`datasets_synthetic.point_lights`, the camera vignetting ``V``
(:func:`datasets_synthetic.cameras.vignetting_map`) and ONE exposure scale ``s``
for a set's part and flat-field images, so that their ratio is physical. The
flat-field target is the plane z = 0 with a uniform albedo, seen by the same
camera under the same lights, vignetting, exposure, noise and bit depth. Then
the sensor (:func:`datasets_synthetic.render.sensor`): shot noise, Gaussian noise
in full-scale units, clipping at 1 and quantisation.

Cast shadows (``shadows="cast"``) are found by open3d ray casting from every seen
point towards its own light POSITION over the triangle mesh of all seen points
(:func:`datasets_synthetic.render.grid_triangles`); nothing outside the field of
view casts a shadow.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import map_coordinates

from datasets_synthetic.cameras import Camera, SurfaceHits, analytic_surface, intersect, make_camera, vignetting_map
from datasets_synthetic.heightfields import CONVENTION, AnalyticSurface, make_scene
from datasets_synthetic.io import ensure_dir
from datasets_synthetic.point_lights import PointLights, rig_lights, shading
from datasets_synthetic.render import _albedo, _rgb_intensities, _write_folder, grid_triangles, sensor
from photometric.normals import angular_error_deg
from surfaces.grid import image_shape, xy_to_pixel
from surfaces.io import atomic_write_text, save_npy, write_png
from surfaces.validate import as_array, InputError, positive

NEAR_SHADOW_MODES = ("attached", "cast")
#: Default brightest clean value (full scale 1) when the exposure is chosen automatically.
PEAK = 0.9
#: Default albedo of the flat-field target.
FLAT_ALBEDO = 0.8


@dataclass(frozen=True)
class NearFieldRender:
    """A rendered near-field image set with its flat fields and truth.

    Attributes
    ----------
    images : (N, H, W) or (N, H, W, 3) float32 array
        Part images in [0, 1], one per light.
    flats : same shape as ``images``
        Flat-field target images, one per light, same exposure.
    hits : SurfaceHits
        The surface point, slopes and normal each pixel sees.
    camera : Camera
        The camera.
    lights : PointLights
        The lights the images were rendered with.
    exposure : float
        The scale ``s`` shared by part and flat images.
    exposure_auto : bool
        True when ``s`` was chosen as ``peak / (brightest clean value)``.
    vignetting : (H, W) float64 array
        ``V(pixel)``.
    albedo : float64 array, scalar, (H, W) or (H, W, 3)
        The part's albedo at the seen points.
    flat_albedo : float
        Albedo of the flat-field target.
    shadow_fraction : (N,) float64 array
        Fraction of pixels in cast shadow, per light (0 with attached shadows only).
    saturated_fraction : float
        Fraction of image values (part and flat) clipped at full scale.
    settings : dict
        The remaining options (shadows, vignetting spec, peak, noise, shot noise, bit depth).
    """

    images: np.ndarray
    flats: np.ndarray
    hits: SurfaceHits
    camera: Camera
    lights: PointLights
    exposure: float
    exposure_auto: bool
    vignetting: np.ndarray
    albedo: np.ndarray
    flat_albedo: float
    shadow_fraction: np.ndarray
    saturated_fraction: float
    settings: dict


def render_near_field(
    surface,
    camera: Camera,
    lights: PointLights,
    albedo=None,
    shadows: str = "attached",
    vignetting: dict | None = None,
    exposure: float | None = None,
    peak: float = PEAK,
    flat_albedo: float = FLAT_ALBEDO,
    noise: float = 0.0,
    shot_noise: float = 0.0,
    bit_depth: int | None = None,
    seed: int | np.random.Generator = 0,
    progress: bool = False,
) -> NearFieldRender:
    """Render a scene and its flat-field target under near point lights.

    Parameters
    ----------
    surface : AnalyticSurface or HeightField
        The scene (its closed form is intersected with every pixel's ray).
    camera : Camera
        :func:`~datasets_synthetic.cameras.orthographic_camera` or
        :func:`~datasets_synthetic.cameras.perspective_camera`.
    lights : PointLights
        The lights that make the images (the TRUE rig).
    albedo : float, (H, W) or (H, W, 3) array_like, optional
        Part albedo (1 by default). A map is painted on the part: its pixel (r, c)
        covers the reference-plane point of the grid ``surfaces.grid`` with the
        camera's reference pixel size, and is sampled bilinearly where the camera
        sees the part (for an orthographic camera: exactly the map).
    shadows : {"attached", "cast"}
        ``max(0, n . l)`` only, or also cast shadows towards each light position.
    vignetting : dict, optional
        :func:`~datasets_synthetic.cameras.vignetting_map` specification.
    exposure : float, optional
        Exposure scale ``s``; by default ``peak`` over the brightest clean value of
        the part and flat images, so nothing saturates.
    peak : float
        Brightest clean value for the automatic exposure, in (0, 1].
    flat_albedo : float
        Albedo of the flat-field target, in (0, 1].
    noise, shot_noise, bit_depth
        Sensor model (:func:`datasets_synthetic.render.sensor`): Gaussian standard
        deviation in full-scale units, shot-noise scale, None/8/16.
    seed : int or numpy.random.Generator
        Noise seed; the part images draw first (light order), then the flats.
    progress : bool
        Show a tqdm progress bar over the lights (command line only).

    Returns
    -------
    NearFieldRender

    Raises
    ------
    ValueError
        Bad options, a camera that does not see the part (see
        :func:`~datasets_synthetic.cameras.intersect`), or an image set without light.
    """
    from tqdm import tqdm

    if not isinstance(lights, PointLights):
        raise InputError(f"lights: expected PointLights, got {type(lights).__name__}")
    if shadows not in NEAR_SHADOW_MODES:
        raise InputError(f"shadows: expected one of {NEAR_SHADOW_MODES} for point lights, got {shadows!r}")
    if bit_depth not in (None, 8, 16):
        raise InputError(f"bit_depth: expected None, 8 or 16, got {bit_depth!r}")
    peak = positive(peak, "peak")
    if peak > 1:
        raise InputError(f"peak: must lie in (0, 1], got {peak}")
    flat_albedo = positive(flat_albedo, "flat_albedo")
    if flat_albedo > 1:
        raise InputError(f"flat_albedo: must lie in (0, 1], got {flat_albedo}")
    noise = positive(noise, "noise", allow_zero=True)
    shot_noise = positive(shot_noise, "shot_noise", allow_zero=True)
    scale = None if exposure is None else positive(exposure, "exposure")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    hits = intersect(surface, camera)
    flat_points = intersect(AnalyticSurface(), camera).points
    v = vignetting_map(camera, vignetting)
    rho = _albedo_at(albedo, camera, hits)
    h, w = camera.shape
    n = len(lights)
    rgb = lights.intensities.ndim == 2 or rho.ndim == 3
    casts = (_point_shadows(hits.points, lights.positions, camera.reference_pixel_mm, analytic_surface(surface))
             if shadows == "cast" else None)
    shape = (n, h, w, 3) if rgb else (n, h, w)
    clean = np.empty(shape, np.float32)
    clean_flat = np.empty(shape, np.float32)
    seen = tuple(np.ascontiguousarray(hits.points[..., i]) for i in range(3))
    facing = tuple(np.ascontiguousarray(hits.normals[..., i]) for i in range(3))
    flat = tuple(np.ascontiguousarray(flat_points[..., i]) for i in range(3))
    up = (np.zeros((h, w)), np.zeros((h, w)), np.ones((h, w)))
    for k in tqdm(range(n), desc="render", unit="light", disable=not progress):
        shade = shading(lights, k, seen, facing)
        shade *= v
        if casts is not None:
            shade *= ~casts[k]
        clean[k] = _colour(rho, lights.intensities[k], shade, rgb)
        shade = shading(lights, k, flat, up)
        shade *= v
        clean_flat[k] = _colour(np.asarray(flat_albedo), lights.intensities[k], shade, rgb)
    brightest = max(float(clean.max()), float(clean_flat.max()))
    if brightest <= 0:
        raise InputError("lights: no pixel of the part or the flat field is lit")
    auto = scale is None
    scale = peak / brightest if auto else scale
    images = np.empty(shape, np.float32)
    flats = np.empty(shape, np.float32)
    saturated = 0
    for source, target in ((clean, images), (clean_flat, flats)):
        for k in range(n):
            raw = sensor(scale * source[k].astype(np.float64), rng, noise, shot_noise, None, clip=False)
            saturated += int(np.count_nonzero(raw >= 1.0))
            target[k] = sensor(raw, rng, 0.0, 0.0, bit_depth, clip=True)
    settings = {"shadows": shadows, "vignetting": vignetting, "peak": peak, "noise": noise,
                "shot_noise": shot_noise, "bit_depth": bit_depth}
    return NearFieldRender(
        images=images, flats=flats, hits=hits, camera=camera, lights=lights, exposure=float(scale),
        exposure_auto=auto, vignetting=v, albedo=rho, flat_albedo=flat_albedo,
        shadow_fraction=np.zeros(n) if casts is None else casts.reshape(n, -1).mean(axis=1),
        saturated_fraction=saturated / (2.0 * images.size), settings=settings,
    )


def _colour(rho: np.ndarray, e, shade: np.ndarray, rgb: bool) -> np.ndarray:
    """``albedo * e_k * shade`` as grey (H, W) or RGB (H, W, 3)."""
    if not rgb:
        return rho * e * shade
    r = rho if rho.ndim == 3 else rho[..., None] if rho.ndim == 2 else rho
    return r * np.broadcast_to(e, (3,)) * shade[..., None]


def _albedo_at(albedo, camera: Camera, hits: SurfaceHits) -> np.ndarray:
    """The albedo at the seen points (a map is painted on the reference-plane grid)."""
    rho = np.asarray(1.0) if albedo is None else as_array(albedo, "albedo", ndim=(0, 2, 3))
    if np.any(rho < 0):
        raise InputError("albedo: must be non-negative")
    if rho.ndim == 0:
        return rho
    h, w = camera.shape
    if rho.shape not in ((h, w), (h, w, 3)):
        raise InputError(f"albedo: expected a scalar, ({h}, {w}) or ({h}, {w}, 3), got {rho.shape}")
    if camera.model == "orthographic":
        return rho
    row, col = xy_to_pixel(hits.points[..., 0], hits.points[..., 1], camera.shape, camera.reference_pixel_mm)
    coords = [row.ravel(), col.ravel()]
    channels = [rho] if rho.ndim == 2 else [rho[..., c] for c in range(3)]
    sampled = [map_coordinates(c, coords, order=1, mode="nearest", prefilter=False).reshape(h, w) for c in channels]
    return sampled[0] if rho.ndim == 2 else np.stack(sampled, axis=-1)


def _point_shadows(points: np.ndarray, positions: np.ndarray, pixel_mm: float, surface: AnalyticSurface) -> np.ndarray:
    """(N, H, W) True where the segment from a seen point to light k's position meets the seen surface.

    Only points that may be shadowed are ray cast: above its base plane the surface's
    relief never exceeds ``hi`` (:attr:`AnalyticSurface.relief_bounds`), so a point whose
    relief is ``hi`` and whose segment to the LED climbs away from the base plane stays
    above every occluder (on a flat plate with a scratch, only the scratch is cast). A
    climbing segment also reaches ``hi`` within a known distance, so the mesh covers only
    the pixels that far around those points.
    """
    import open3d as o3d

    h, w = points.shape[:2]
    flat = points.reshape(-1, 3)
    _, sx, sy = surface.plane
    hi = surface.relief_bounds[1]
    relief = flat[:, 2] - sx * flat[:, 0] - sy * flat[:, 1]
    low = relief < hi - 1e-12
    todo, reach = [], 0.0
    for position in positions:
        v = position - flat
        climb = v[:, 2] - sx * v[:, 0] - sy * v[:, 1]
        idx = np.flatnonzero(low | (climb <= 0))
        todo.append(idx)
        if idx.size:
            c = climb[idx]
            run = np.hypot(v[idx, 0], v[idx, 1])
            reach = np.inf if np.any(c <= 0) else max(reach, float(np.max((hi - relief[idx]) * run / c)))
    out = np.zeros((len(positions), h * w), bool)
    if not any(idx.size for idx in todo):
        return out.reshape(len(positions), h, w)
    every = np.concatenate(todo)
    rows, cols = every // w, every % w
    margin = h + w if not np.isfinite(reach) else int(np.ceil(1.1 * reach / pixel_mm)) + 2
    r0, r1 = max(int(rows.min()) - margin, 0), min(int(rows.max()) + margin, h - 1)
    c0, c1 = max(int(cols.min()) - margin, 0), min(int(cols.max()) + margin, w - 1)
    verts, tris = grid_triangles(points[r0:r1 + 1, c0:c1 + 1])
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
    start = 1e-3 * pixel_mm  # leave the vertex the ray starts from
    for k, (position, idx) in enumerate(zip(positions, todo)):
        if idx.size == 0:
            continue
        v = position - flat[idx]
        dist = np.linalg.norm(v, axis=1)
        d = v / dist[:, None]
        rays = np.concatenate([flat[idx] + start * d, d], axis=1).astype(np.float32)
        t_hit = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
        out[k, idx] = t_hit < dist - start
    return out.reshape(len(positions), h, w)


def write_near_field_folder(out_dir: str | os.PathLike, rendered: NearFieldRender, scene: dict,
                            nominal: PointLights | None = None) -> dict:
    """Write a near-field image set in the contract's folder layout.

    Files: the DiLiGenT layout of :func:`datasets_synthetic.render.write_diligent_folder`
    (``001.png ...`` 16-bit, ``filenames.txt``, ``light_directions.txt`` (unit
    directions from the origin to each NOMINAL LED), ``light_intensities.txt``,
    ``mask.png``, ``normal_gt.npy``, ``height_gt.npy``, ``scene.json``) plus
    ``light_positions.txt`` (nominal ``x y z`` in mm per image), ``flat_001.png ...``
    (16-bit flat-field images in light order) and ``xy_gt.npy`` ((H, W, 2) x, y in mm
    of the seen points). ``scene.json`` is written last.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    rendered : NearFieldRender
        The render.
    scene : dict
        Scene description for ``scene.json``; this function adds ``lights`` (the
        rendering rig), ``camera``, ``flat_field``, ``vignetting`` (when used),
        ``exposure``, ``exposure_auto``, ``peak``, ``saturated_fraction``,
        ``shadow_fraction`` and ``files``.
    nominal : PointLights, optional
        The lights a user believes in (text files); the rendering lights by default.

    Returns
    -------
    dict
        The content of ``scene.json``.
    """
    if not isinstance(rendered, NearFieldRender):
        raise InputError(f"rendered: expected a NearFieldRender, got {type(rendered).__name__}")
    nominal = rendered.lights if nominal is None else nominal
    n = len(rendered.lights)
    if not isinstance(nominal, PointLights) or len(nominal) != n:
        raise InputError(f"nominal: expected PointLights with {n} lights")
    out = ensure_dir(out_dir)
    flat_names = [f"flat_{k + 1:03d}.png" for k in range(n)]
    for name, img in zip(flat_names, rendered.flats):
        write_png(out / name, np.round(img.astype(np.float64) * 65535.0).astype(np.uint16))
    atomic_write_text(out / "light_positions.txt",
                      "".join(f"{a:.10f} {b:.10f} {c:.10f}\n" for a, b, c in nominal.positions))
    save_npy(out / "xy_gt.npy", rendered.hits.xy)
    content = dict(scene)
    content.update({
        "lights": rendered.lights.as_dict(),
        "camera": rendered.camera.as_dict(),
        "flat_field": {"files": flat_names, "albedo": rendered.flat_albedo},
        "exposure": rendered.exposure,
        "exposure_auto": rendered.exposure_auto,
        "peak": rendered.settings["peak"],
        "saturated_fraction": rendered.saturated_fraction,
        "shadows": rendered.settings["shadows"],
        "shadow_fraction": rendered.shadow_fraction,
        "noise": rendered.settings["noise"],
        "shot_noise": rendered.settings["shot_noise"],
        "bit_depth": rendered.settings["bit_depth"],
    })
    if rendered.settings["vignetting"] is not None:
        content["vignetting"] = rendered.settings["vignetting"]
    h, w = rendered.camera.shape
    written = _write_folder(out, rendered.images.astype(np.float64), nominal.directions,
                            _rgb_intensities(nominal.intensities, n), np.ones((h, w), bool),
                            rendered.hits.normals, rendered.hits.height, content,
                            extra_files={"light_positions": "light_positions.txt", "flat_field": flat_names,
                                         "xy_gt": "xy_gt.npy"})
    return written


def make_near_field_folder(
    out_dir: str | os.PathLike,
    scene: str = "plate",
    size=512,
    lights=3,
    slant: float = 45.0,
    light_distance: float = 150.0,
    led_mu=0.0,
    camera: str = "orthographic",
    pixel_size: float | None = None,
    focal_length_px: float | None = None,
    camera_height: float | None = None,
    noise: float = 0.003,
    shot_noise: float = 0.0,
    shadows: str = "cast",
    deviate=None,
    seed: int = 0,
    azimuth0: float = 90.0,
    intensities=None,
    albedo: float | str | None = "texture",
    bit_depth: int | None = 16,
    vignetting: dict | None = None,
    exposure: float | None = None,
    peak: float = PEAK,
    flat_albedo: float = FLAT_ALBEDO,
    progress: bool = False,
) -> dict:
    """Render a scene under near LEDs with its flat fields and write a near-field folder.

    Images are rendered with the TRUE LED positions (nominal ones moved on their
    sphere about the origin by ``deviate``); ``light_positions.txt`` and
    ``light_directions.txt`` hold the NOMINAL ones.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder.
    scene : str
        Scene name (:func:`datasets_synthetic.heightfields.make_scene`), built on the
        camera's reference-plane grid.
    size : int or (H, W)
        Image size in pixels.
    lights : int or (N, 3) array_like
        Number of LEDs on a ring (at ``slant``, ``azimuth0``, ``light_distance``), or
        their nominal positions in mm.
    slant : float
        Ring slant from +z, degrees (below 90).
    light_distance : float
        Ring LEDs' distance from the origin, mm.
    led_mu : float or (N,) array_like
        LED lobe exponents (0: isotropic); the LEDs are aimed at the origin.
    camera : {"orthographic", "perspective"}
        Camera model.
    pixel_size : float, optional
        Orthographic pixel size in mm (default 0.05); not for a perspective camera.
    focal_length_px, camera_height : float, optional
        Perspective focal length (pixels) and camera height (mm); both required.
    noise, shot_noise, bit_depth
        Sensor model (:func:`datasets_synthetic.render.sensor`).
    shadows : {"cast", "attached"}
        Shadow model (see :func:`render_near_field`).
    deviate : (N,) or (N, 2) array_like, optional
        Slant (and azimuth) deviations of the true LEDs, degrees.
    seed : int
        Seed of the scene, albedo texture and noise.
    azimuth0 : float
        Azimuth of the first ring LED, degrees.
    intensities : (N,) or (N, 3) array_like, optional
        LED intensities ``e_k``; ones by default.
    albedo : float, "texture" or None
        Constant albedo, or a smooth random texture in [0.55, 0.9] painted on the part.
    vignetting : dict, optional
        :func:`datasets_synthetic.cameras.vignetting_map` specification.
    exposure, peak, flat_albedo
        See :func:`render_near_field`.
    progress : bool
        Show a progress bar (command line only).

    Returns
    -------
    dict
        The content of ``scene.json`` (the keys of :func:`write_near_field_folder` and
        ``model`` "near-field", scene parameters, ``image_size``, ``pixel_size_mm`` (the
        reference-plane pixel), ``light_distance_mm``, ``lights_nominal`` (unit
        directions), ``light_positions_nominal_mm``, ``lights_true``, ``deviations_deg``,
        ``light_error_deg``, ``intensities``, ``albedo``, ``height_range_mm``, ``defects``
        (mm; the pixel values refer to the reference-plane grid) and ``scene_params``).
    """
    h, w = image_shape(size)
    cam = make_camera(camera, (h, w), pixel_size, focal_length_px, camera_height)
    nominal, true, dev = rig_lights(lights, slant, light_distance, azimuth0, led_mu, intensities, deviate)
    n = len(nominal)
    rho, albedo_desc = _albedo(albedo, (h, w), seed)
    hf = make_scene(scene, (h, w), cam.reference_pixel_mm, seed)
    rendered = render_near_field(hf, cam, true, rho, shadows, vignetting, exposure, peak, flat_albedo, noise,
                                 shot_noise, bit_depth, np.random.default_rng(seed), progress)
    height = rendered.hits.height
    content = {
        "model": "near-field",
        "scene": scene,
        "size": size if np.ndim(size) == 0 else [h, w],
        "image_size": [h, w],
        "pixel_size_mm": cam.reference_pixel_mm,
        "seed": int(seed),
        "convention": CONVENTION,
        "n_lights": n,
        "slant_deg": float(slant),
        "azimuth0_deg": float(azimuth0),
        "light_distance_mm": float(light_distance) if np.ndim(lights) == 0 else None,
        "lights_nominal": nominal.directions,
        "light_positions_nominal_mm": nominal.positions,
        "lights_true": true.directions,
        "deviations_deg": dev,
        "light_error_deg": angular_error_deg(true.directions, nominal.directions),
        "intensities": true.intensities,
        "albedo": albedo_desc,
        "cast_shadows": "open3d ray casting from each seen point to its light position over the mesh of the "
                        "seen points; nothing outside the field of view casts a shadow",
        "height_range_mm": [float(height.min()), float(height.max())],
        "defects": list(hf.defects),
        "defects_pixel_frame": "pixel values of the defects refer to the reference-plane grid (pixel_size_mm)",
        "scene_params": hf.params,
    }
    return write_near_field_folder(out_dir, rendered, content, nominal)
