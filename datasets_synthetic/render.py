"""Lambertian image sets of analytic height fields, with shadows, noise and wrong lights.

The image model (seed 002a) is ``I_k = albedo * e_k * max(0, n . l_k)`` for light
``k`` of intensity ``e_k`` and unit direction ``l_k`` (from the surface towards the
light, :data:`datasets_synthetic.heightfields.CONVENTION`), optionally plus a
Blinn-Phong term ``k_s e_k max(0, n . h_k)^s`` with ``h_k = (l_k + v) / |l_k + v|``.
Cast shadows come from an exact horizon test on the height field (see
:func:`cast_shadow_mask`). Light geometry (rings of lights, slant and azimuth,
deviations, validation) is :mod:`photometric.lights`; this module is the forward model.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets_synthetic.heightfields import CONVENTION, HeightField, make_scene
from datasets_synthetic.io import ensure_dir
from photometric.lights import deviate_lights, light_angles, ring_lights, validate_lights
from photometric.normals import angular_error_deg
from surfaces.grid import image_shape, pixel_grid
from surfaces.io import atomic_write_text, save_npy, write_json, write_png
from surfaces.validate import as_array, InputError, positive

SHADOW_MODES = ("attached", "cast", "none")
#: Marching step of the cast-shadow test, pixels.
SHADOW_STEP = 0.25


def _direction(vector, name: str) -> np.ndarray:
    """One unit direction (3,) checked by the light validator."""
    return validate_lights(as_array(vector, name, shape=(3,))[None], name, min_lights=1)[0]


def cast_shadow_mask(
    height, light, pixel_size: float, step: float = SHADOW_STEP, method: str = "auto"
) -> np.ndarray:
    """Pixels whose view of a distant light is blocked by the height field itself.

    Horizon test: pixel ``x0`` (height ``z0``) is in cast shadow when some point at
    image-plane distance ``t > 0`` towards the light rises above the light ray,
    ``z(x0 + t d) > z0 + t tan(e)``, with ``d`` the light's image-plane direction and
    ``e`` its elevation. The ray is marched in steps of ``step`` pixels for all
    undecided pixels at once (``scipy.ndimage.map_coordinates``, bilinear, i.e. exact
    for the bilinear height-field surface up to the step); a pixel drops out once it
    is shadowed, its ray has risen above the highest point, or the ray has left the
    image (nothing outside the image casts a shadow).

    ``method="raycast"`` instead casts one ray per pixel centre towards the light
    with open3d's ``RaycastingScene`` (Embree) over the height-field triangle mesh
    (two triangles per cell), exact for that mesh up to float32 and a start offset
    of 1e-3 pixel. The two agree on all but a few pixels per thousand at shadow
    boundaries; "auto" marches short reaches (up to 64 steps) and ray-casts long ones,
    where it is about ten times faster.

    Parameters
    ----------
    height : (H, W) array_like
        Height in mm.
    light : (3,) array_like
        Unit light direction (x right, y up, z towards the camera).
    pixel_size : float
        Pixel size in mm.
    step : float
        Marching step in pixels (default 0.25).
    method : {"auto", "march", "raycast"}
        Horizon marching, open3d ray casting, or the faster of the two for this reach.

    Returns
    -------
    (H, W) bool array
        True where the pixel is in cast shadow. A light at or below the horizon
        (``l_z <= 0``) shadows every pixel.
    """
    z = as_array(height, "height", ndim=2)
    lz = _direction(light, "light")
    ps = positive(pixel_size, "pixel_size")
    step = positive(step, "step")
    if method not in ("auto", "march", "raycast"):
        raise InputError(f"method: expected 'auto', 'march' or 'raycast', got {method!r}")
    return _shadow(z, lz, ps, step, method)


def _shadow(z: np.ndarray, lz: np.ndarray, ps: float, step: float, method: str = "auto") -> np.ndarray:
    """:func:`cast_shadow_mask` on checked input (float64 heights, a unit light)."""
    h, w = z.shape
    if lz[2] <= 0:
        return np.ones((h, w), bool)
    lxy = float(np.hypot(lz[0], lz[1]))
    zrange = float(z.max() - z.min())
    if lxy < 1e-12 or zrange == 0.0:
        return np.zeros((h, w), bool)
    rise = ps * lz[2] / lxy  # ray height gained per pixel travelled towards the light
    reach = min(zrange / rise, float(np.hypot(h, w)))
    if method == "raycast" or (method == "auto" and reach / step > 64):
        return _raycast_shadow(z, lz, ps)
    from scipy.ndimage import map_coordinates

    drow, dcol = -lz[1] / lxy, lz[0] / lxy
    flat = z.ravel()
    zmax = float(z.max())
    tol = 1e-9 * (1.0 + zrange)
    shadow = np.zeros(h * w, bool)
    # march only the pixels still undecided: not yet shadowed, ray still below the highest
    # point, sample still inside the image (the image is convex, so it never comes back)
    active = np.arange(h * w)
    rows0 = (active // w).astype(np.float64)
    cols0 = (active % w).astype(np.float64)
    for t in np.arange(step, reach + step, step):
        r = rows0 + t * drow
        c = cols0 + t * dcol
        keep = ((flat[active] + t * rise < zmax) & (r >= 0) & (r <= h - 1) & (c >= 0) & (c <= w - 1))
        active, r, c = active[keep], r[keep], c[keep]
        rows0, cols0 = rows0[keep], cols0[keep]
        if active.size == 0:
            break
        zt = map_coordinates(z, [r, c], order=1, mode="nearest", prefilter=False)
        hit = zt - t * rise > flat[active] + tol
        shadow[active[hit]] = True
        active, rows0, cols0 = active[~hit], rows0[~hit], cols0[~hit]
    return shadow.reshape(h, w)


def grid_triangles(points) -> tuple[np.ndarray, np.ndarray]:
    """A triangle mesh through a grid of surface points, two triangles per grid cell.

    Parameters
    ----------
    points : (H, W, 3) array_like
        Surface points in mm, one per pixel (the height field at the pixel centres,
        or the points a perspective camera sees).

    Returns
    -------
    vertices : (H * W, 3) float32 array
        The points, row by row (open3d ray casting works in float32).
    triangles : (2 (H - 1) (W - 1), 3) uint32 array
        Vertex indices; cell (r, c) gives (r, c), (r + 1, c), (r, c + 1) and
        (r, c + 1), (r + 1, c), (r + 1, c + 1).
    """
    pts = as_array(points, "points", shape=(None, None, 3))
    h, w = pts.shape[:2]
    verts = pts.reshape(-1, 3).astype(np.float32)
    idx = np.arange(h * w).reshape(h, w)[:-1, :-1].ravel()
    tris = np.concatenate([np.column_stack([idx, idx + w, idx + 1]),
                           np.column_stack([idx + 1, idx + w, idx + w + 1])]).astype(np.uint32)
    return verts, tris


def _raycast_shadow(z: np.ndarray, light: np.ndarray, ps: float) -> np.ndarray:
    """Cast shadows by open3d ray casting over the height-field mesh (see cast_shadow_mask)."""
    import open3d as o3d

    h, w = z.shape
    x, y = pixel_grid(z.shape, ps)
    verts, tris = grid_triangles(np.stack([x, y, z], axis=-1))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(verts), o3d.core.Tensor(tris))
    direction = light.astype(np.float32)
    origins = verts + np.float32(1e-3 * ps) * direction
    rays = np.column_stack([origins, np.broadcast_to(direction, origins.shape)])
    t_hit = scene.cast_rays(o3d.core.Tensor(np.ascontiguousarray(rays)))["t_hit"].numpy()
    return np.isfinite(t_hit).reshape(h, w)


def texture_albedo(size, low: float = 0.55, high: float = 0.9, scale_px: float = 12.0,
                   seed: int = 0) -> np.ndarray:
    """A smooth random albedo map (Gaussian-filtered noise rescaled to [low, high]).

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    low, high : float
        Albedo range, 0 < low < high <= 1.
    scale_px : float
        Correlation length in pixels.
    seed : int
        Random seed.

    Returns
    -------
    (H, W) float64 array.
    """
    from scipy.ndimage import gaussian_filter

    h, w = image_shape(size)
    if not (0.0 < low < high <= 1.0):
        raise InputError(f"low, high: need 0 < low < high <= 1, got {low}, {high}")
    g = gaussian_filter(np.random.default_rng(seed).standard_normal((h, w)),
                        positive(scale_px, "scale_px"), mode="wrap")
    g = (g - g.min()) / max(float(np.ptp(g)), 1e-300)
    return low + (high - low) * g


def render(
    hf: HeightField,
    lights,
    intensities=None,
    albedo=None,
    shadows: str = "attached",
    specular: dict | None = None,
    noise: float = 0.0,
    shot_noise: float = 0.0,
    bit_depth: int | None = None,
    seed: int | np.random.Generator = 0,
    shadow_step: float = SHADOW_STEP,
    cast_masks=None,
) -> np.ndarray:
    """Render Lambertian images ``I_k = albedo * e_k * max(0, n . l_k)`` (seed 002a).

    Parameters
    ----------
    hf : HeightField
        The scene (normals, height and pixel size are used).
    lights : (N, 3) array_like
        Unit light directions actually used for rendering (the true lights).
    intensities : (N,) or (N, 3) array_like, optional
        Light intensities ``e_k`` (grey or RGB); ones by default.
    albedo : float, (H, W) or (H, W, 3) array_like, optional
        Albedo (1.0 by default).
    shadows : {"attached", "cast", "none"}
        "attached" clamps ``n . l`` at zero; "cast" also zeroes the diffuse and
        specular terms where :func:`cast_shadow_mask` finds the light blocked;
        "none" keeps the raw linear model ``albedo e n . l`` (negative values are kept,
        no clipping, unless ``bit_depth`` is given).
    specular : dict, optional
        Blinn-Phong term ``{"ks": 0.5, "shininess": 20.0, "view": (0, 0, 1)}``
        (any subset); added where ``n . l > 0``, not multiplied by the albedo.
    noise : float
        Standard deviation of additive Gaussian noise (full scale 1).
    shot_noise : float
        Shot-noise scale g: the signal becomes ``g * Poisson(I / g)`` (mean I,
        variance ``g I``); 0 disables it.
    bit_depth : {None, 8, 16}
        Quantise to ``round(I (2^b - 1)) / (2^b - 1)``.
    seed : int or numpy.random.Generator
        Noise seed.
    shadow_step : float
        Marching step of the cast-shadow test, pixels.
    cast_masks : (N, H, W) array_like of bool, optional
        Precomputed :func:`cast_shadow_mask` results for these lights (reused with
        ``shadows="cast"`` instead of recomputing them).

    Returns
    -------
    images : (N, H, W) or (N, H, W, 3) float32 array
        In [0, 1] (saturated at 1) except for ``shadows="none"`` without quantisation;
        RGB when ``intensities`` is (N, 3) or ``albedo`` is (H, W, 3).
    """
    L = validate_lights(lights, min_lights=1)
    opts = _options(hf, len(L), intensities, albedo, shadows, specular, noise, shot_noise, bit_depth)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    h, w = hf.shape
    if cast_masks is not None:
        cast_masks = as_array(cast_masks, "cast_masks", shape=(len(L), h, w), dtype=bool)
    out = np.empty((len(L), h, w, 3) if opts.rgb else (len(L), h, w), np.float32)
    for k in range(len(L)):
        cast = None if cast_masks is None else cast_masks[k]
        out[k] = _image(hf, L[k], opts.e[k], opts, rng, cast, shadow_step)
    return out


@dataclass(frozen=True)
class _Options:
    """Checked rendering options (see :func:`render`)."""

    e: np.ndarray
    rho: np.ndarray
    shadows: str
    spec: tuple | None
    noise: float
    shot_noise: float
    bit_depth: int | None

    @property
    def rgb(self) -> bool:
        return self.e.ndim == 2 or self.rho.ndim == 3


def _options(hf, n_lights, intensities, albedo, shadows, specular, noise, shot_noise, bit_depth) -> _Options:
    """The options of :func:`render` for ``n_lights`` lights, checked once."""
    if not isinstance(hf, HeightField):
        raise InputError(f"hf: expected a HeightField, got {type(hf).__name__}")
    if shadows not in SHADOW_MODES:
        raise InputError(f"shadows: expected one of {SHADOW_MODES}, got {shadows!r}")
    if bit_depth not in (None, 8, 16):
        raise InputError(f"bit_depth: expected None, 8 or 16, got {bit_depth!r}")
    h, w = hf.shape
    e = np.ones(n_lights) if intensities is None else as_array(intensities, "intensities", ndim=(1, 2))
    if e.shape not in ((n_lights,), (n_lights, 3)) or np.any(e < 0):
        raise InputError(f"intensities: expected non-negative ({n_lights},) or ({n_lights}, 3), "
                         f"got shape {e.shape}")
    rho = np.asarray(1.0) if albedo is None else as_array(albedo, "albedo", ndim=(0, 2, 3))
    if rho.ndim and rho.shape not in ((h, w), (h, w, 3)):
        raise InputError(f"albedo: expected a scalar, ({h}, {w}) or ({h}, {w}, 3), got {rho.shape}")
    if np.any(rho < 0):
        raise InputError("albedo: must be non-negative")
    spec = None
    if specular is not None:
        unknown = set(specular) - {"ks", "shininess", "view"}
        if unknown:
            raise InputError(f"specular: unknown keys {sorted(unknown)}")
        view = _direction(specular.get("view", (0.0, 0.0, 1.0)), "specular['view']")
        spec = (positive(specular.get("ks", 0.5), "specular['ks']", allow_zero=True),
                positive(specular.get("shininess", 20.0), "specular['shininess']"), view)
    return _Options(e, rho, shadows, spec, positive(noise, "noise", allow_zero=True),
                    positive(shot_noise, "shot_noise", allow_zero=True), bit_depth)


def _image(hf: HeightField, light: np.ndarray, ek, opts: _Options, rng: np.random.Generator,
           cast: np.ndarray | None, shadow_step: float) -> np.ndarray:
    """One image under the unit ``light`` of intensity ``ek`` (the loop body of :func:`render`)."""
    h, w = hf.shape
    n = hf.normals
    ndotl = n @ light
    diffuse = ndotl if opts.shadows == "none" else np.maximum(ndotl, 0.0)
    highlight = np.zeros((h, w))
    if opts.spec is not None:
        ks, shininess, view = opts.spec
        half = light + view
        half /= np.linalg.norm(half)
        highlight = ks * np.maximum(n @ half, 0.0) ** shininess * (ndotl > 0)
    if opts.shadows == "cast":
        lit = ~(cast if cast is not None else _shadow(hf.height, light, hf.pixel_size, shadow_step))
        diffuse = diffuse * lit
        highlight = highlight * lit
    rho = opts.rho
    if opts.rgb:
        e3 = np.broadcast_to(ek, (3,)) if opts.e.ndim == 2 else np.full(3, ek)
        r = rho if rho.ndim == 3 else np.broadcast_to(rho[..., None], (h, w, 3)) if rho.ndim else rho
        img = r * e3 * diffuse[..., None] + e3 * highlight[..., None]
    else:
        img = rho * ek * diffuse + ek * highlight
    return sensor(img, rng, opts.noise, opts.shot_noise, opts.bit_depth,
                  clip=opts.shadows != "none" or opts.bit_depth is not None)


def sensor(img, rng: np.random.Generator, noise: float = 0.0, shot_noise: float = 0.0,
           bit_depth: int | None = None, clip: bool = True) -> np.ndarray:
    """What the sensor makes of a clean image: shot noise, Gaussian noise, clipping, quantisation.

    Parameters
    ----------
    img : array_like
        Clean image in full-scale units (1 = the largest value the sensor records).
    rng : numpy.random.Generator
        Noise source (drawn from in this order: Poisson, then Gaussian).
    noise : float
        Standard deviation of additive Gaussian noise, full-scale units.
    shot_noise : float
        Shot-noise scale g: the signal becomes ``g * Poisson(I / g)`` (mean I, variance
        ``g I``); 0 disables it.
    bit_depth : {None, 8, 16}
        Quantise to ``round(I (2^b - 1)) / (2^b - 1)``.
    clip : bool
        Clip to [0, 1] (always done when quantising).

    Returns
    -------
    float64 array (same shape)
    """
    if shot_noise > 0:
        img = shot_noise * rng.poisson(np.maximum(img, 0.0) / shot_noise)
    if noise > 0:
        img = img + rng.normal(0.0, noise, np.shape(img))
    if clip or bit_depth is not None:
        img = np.clip(img, 0.0, 1.0)
    if bit_depth is not None:
        full = 2.0**bit_depth - 1.0
        img = np.round(img * full) / full
    return img


def write_diligent_folder(
    out_dir: str | os.PathLike,
    images,
    lights_nominal,
    intensities,
    mask,
    normal_gt,
    height_gt,
    scene: dict,
) -> dict:
    """Write an image set in the DiLiGenT layout (plus exact ground truth).

    Files: ``filenames.txt``, ``light_directions.txt`` (one "x y z" row per image, the
    NOMINAL lights), ``light_intensities.txt`` (one "r g b" row per image),
    16-bit PNGs ``001.png``, ``002.png``, ..., ``mask.png`` (8-bit, 255 inside),
    ``normal_gt.npy`` (H, W, 3) float64, ``height_gt.npy`` (H, W) float64 in mm, and
    ``scene.json``. Every file is written atomically.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    images : (N, H, W) or (N, H, W, 3) array_like
        Images in [0, 1]; stored as ``round(65535 I)``.
    lights_nominal : (N, 3) array_like
        Unit light directions written to ``light_directions.txt``.
    intensities : (N,) or (N, 3) array_like
        Light intensities (a grey value is repeated in r, g, b).
    mask : (H, W) array_like of bool
        Object mask.
    normal_gt : (H, W, 3) array_like
        True unit normals.
    height_gt : (H, W) array_like
        True heights in mm.
    scene : dict
        Content of ``scene.json`` (JSON-serialisable; numpy values allowed).

    Returns
    -------
    dict
        ``scene`` with ``"files"`` added (file names relative to ``out_dir``).
    """
    out = ensure_dir(out_dir)
    imgs = as_array(images, "images", ndim=(3, 4), dtype=np.float64)
    n, h, w = imgs.shape[:3]
    if imgs.ndim == 4 and imgs.shape[3] != 3:
        raise InputError(f"images: colour images need 3 channels, got shape {imgs.shape}")
    if imgs.min() < 0 or imgs.max() > 1:
        raise InputError(f"images: values must lie in [0, 1], got [{imgs.min()}, {imgs.max()}]")
    lights = validate_lights(lights_nominal, "lights_nominal", min_lights=1)
    if len(lights) != n:
        raise InputError(f"lights_nominal: {len(lights)} rows for {n} images")
    e = _rgb_intensities(intensities, n)
    m = as_array(mask, "mask", shape=(h, w), dtype=bool)
    ngt = as_array(normal_gt, "normal_gt", shape=(h, w, 3))
    hgt = as_array(height_gt, "height_gt", shape=(h, w))
    return _write_folder(out, imgs, lights, e, m, ngt, hgt, scene)


def _rgb_intensities(intensities, n: int) -> np.ndarray:
    """Intensities (n,) or (n, 3) as (n, 3): a grey value is repeated in r, g, b."""
    e = as_array(intensities, "intensities", ndim=(1, 2))
    if e.ndim == 1:
        e = np.repeat(e[:, None], 3, axis=1)
    if e.shape != (n, 3):
        raise InputError(f"intensities: expected ({n},) or ({n}, 3), got {e.shape}")
    return e


def _write_folder(out: Path, imgs: np.ndarray, lights: np.ndarray, e: np.ndarray, m: np.ndarray,
                  ngt: np.ndarray, hgt: np.ndarray, scene: dict, extra_files: dict | None = None) -> dict:
    """The files of :func:`write_diligent_folder` from checked arrays (images float64 in [0, 1]).

    ``extra_files`` names files the caller wrote already (listed under ``files`` in scene.json,
    which is written last).
    """
    n = imgs.shape[0]
    names = [f"{k + 1:03d}.png" for k in range(n)]
    for name, img in zip(names, imgs):
        write_png(out / name, np.round(img * 65535.0).astype(np.uint16))
    write_png(out / "mask.png", m.astype(np.uint8) * 255)
    atomic_write_text(out / "filenames.txt", "".join(f"{s}\n" for s in names))
    atomic_write_text(out / "light_directions.txt",
                      "".join(f"{a:.10f} {b:.10f} {c:.10f}\n" for a, b, c in lights))
    atomic_write_text(out / "light_intensities.txt",
                      "".join(f"{a:.10f} {b:.10f} {c:.10f}\n" for a, b, c in e))
    save_npy(out / "normal_gt.npy", ngt)
    save_npy(out / "height_gt.npy", hgt)
    content = dict(scene)
    content["files"] = {"images": names, "lights": "light_directions.txt",
                        "intensities": "light_intensities.txt", "mask": "mask.png",
                        "normal_gt": "normal_gt.npy", "height_gt": "height_gt.npy", **(extra_files or {})}
    write_json(out / "scene.json", content)
    return content


def make_triad_folder(
    out_dir: str | os.PathLike,
    scene: str = "plate",
    size: int = 512,
    lights=3,
    slant: float = 45.0,
    noise: float = 0.005,
    shadows: str = "cast",
    deviate=(2.0, 0.0, 0.0),
    seed: int = 0,
    pixel_size: float = 0.05,
    azimuth0: float = 90.0,
    intensities=None,
    albedo: float | str | None = "texture",
    shot_noise: float = 0.0,
    bit_depth: int | None = 16,
    specular: dict | None = None,
    progress: bool = False,
) -> dict:
    """Render a scene under (deliberately deviated) lights and write it as a DiLiGenT folder.

    The images are rendered with the TRUE lights, ``deviate_lights(nominal, deviate)``;
    ``light_directions.txt`` holds the NOMINAL lights, as a user who believes the
    nominal set-up would have them (the error analysis of seed 002a).

    Parameters
    ----------
    out_dir : str or path-like
        Output folder.
    scene : str
        Scene name for :func:`datasets_synthetic.heightfields.make_scene`.
    size : int
        Image side in pixels.
    lights : int or (N, 3) array_like
        Number of ring lights (:func:`photometric.lights.ring_lights` at ``slant``/``azimuth0``) or the
        nominal unit directions themselves.
    slant : float
        Slant of the ring lights, degrees.
    noise : float
        Gaussian noise standard deviation (full scale 1).
    shadows : {"cast", "attached", "none"}
        Shadow model (see :func:`render`).
    deviate : (N,) or (N, 2) array_like or None
        Slant (and azimuth) deviations of the true lights from the nominal ones, degrees.
    seed : int
        Seed of the scene, albedo texture and noise.
    pixel_size : float
        Pixel size in mm.
    azimuth0 : float
        Azimuth of the first ring light, degrees.
    intensities : (N,) or (N, 3) array_like, optional
        Light intensities; ones by default.
    albedo : float, "texture" or None
        Constant albedo, or a smooth random texture in [0.55, 0.9] (default).
    shot_noise : float
        Shot-noise scale (see :func:`render`).
    bit_depth : {None, 8, 16}
        Quantisation before writing (PNGs are always 16-bit files).
    specular : dict, optional
        Blinn-Phong parameters (see :func:`render`).
    progress : bool
        Show a tqdm progress bar over the lights (command line only).

    Returns
    -------
    dict
        The content of ``scene.json``: scene parameters, ``convention``,
        ``lights_nominal``, ``lights_true``, ``deviations_deg`` ([slant, azimuth]
        per light), ``light_error_deg`` (angle true vs nominal), ``intensities``,
        ``shadow_fraction`` per image, ``defects`` and ``files``.
    """
    from tqdm import tqdm

    size = int(size)
    hf = make_scene(scene, size, pixel_size, seed)
    if np.ndim(lights) == 0:
        nominal = ring_lights(int(lights), slant, azimuth0)
    else:
        nominal = validate_lights(lights, min_lights=1)
    n = len(nominal)
    dev = _deviations(deviate, n)
    true = deviate_lights(nominal, dev)
    rho, albedo_desc = _albedo(albedo, size, seed)
    opts = _options(hf, n, intensities, rho, shadows, specular, noise, shot_noise, bit_depth)
    e = opts.e
    rng = np.random.default_rng(seed)
    images, shadow_fraction = [], []
    for k in tqdm(range(n), desc="render", unit="image", disable=not progress):
        cast = (_shadow(hf.height, true[k], hf.pixel_size, SHADOW_STEP) if shadows == "cast"
                else np.zeros(hf.shape, bool))
        img = _image(hf, true[k], e[k], opts, rng, cast, SHADOW_STEP).astype(np.float32)
        images.append(np.clip(img, 0.0, 1.0))
        shadow_fraction.append(float(np.mean(cast)))
    slant_nom, az_nom = light_angles(nominal)
    content = {
        "scene": scene,
        "size": size,
        "pixel_size_mm": float(pixel_size),
        "seed": int(seed),
        "convention": CONVENTION,
        "n_lights": n,
        "slant_deg": float(slant),
        "azimuth0_deg": float(azimuth0),
        "lights_nominal": nominal,
        "lights_true": true,
        "slant_nominal_deg": slant_nom,
        "azimuth_nominal_deg": az_nom,
        "deviations_deg": dev,
        "light_error_deg": angular_error_deg(true, nominal),
        "intensities": e,
        "albedo": albedo_desc,
        "shadows": shadows,
        "shadow_fraction": shadow_fraction,
        "specular": specular,
        "noise": float(noise),
        "shot_noise": float(shot_noise),
        "bit_depth": bit_depth,
        "height_range_mm": [float(hf.height.min()), float(hf.height.max())],
        "defects": list(hf.defects),
        "scene_params": hf.params,
    }
    return _write_folder(ensure_dir(out_dir), np.stack(images).astype(np.float64), nominal, _rgb_intensities(e, n),
                         np.ones(hf.shape, bool), hf.normals, hf.height, content)


def _deviations(deviate, n: int) -> np.ndarray:
    """Per-light [slant, azimuth] deviations (n, 2) in degrees from None, (n,) or (n, 2)."""
    dev = np.zeros((n, 2)) if deviate is None else as_array(deviate, "deviate", ndim=(1, 2))
    if dev.ndim == 1:
        if dev.shape != (n,):
            raise InputError(f"deviate: expected {n} slant deviations (one per light), got {len(dev)}")
        dev = np.column_stack([dev, np.zeros(n)])
    if dev.shape != (n, 2):
        raise InputError(f"deviate: expected shape ({n}, 2), got {dev.shape}")
    return dev


def _albedo(albedo, size, seed: int):
    """The albedo of a rendered folder and its description for scene.json."""
    if isinstance(albedo, str) and albedo == "texture":
        return (texture_albedo(size, seed=seed),
                {"kind": "texture", "low": 0.55, "high": 0.9, "scale_px": 12.0, "seed": seed})
    if albedo is None or (not isinstance(albedo, str) and np.ndim(albedo) == 0):
        rho = 1.0 if albedo is None else positive(albedo, "albedo")
        return rho, {"kind": "constant", "value": rho}
    raise InputError(f"albedo: expected a number, 'texture' or None, got {albedo!r}")
