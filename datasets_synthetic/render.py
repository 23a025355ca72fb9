"""Lambertian image sets of analytic height fields, with shadows, noise and wrong lights.

The image model (seed 002a) is ``I_k = albedo * e_k * max(0, n . l_k)`` for light
``k`` of intensity ``e_k`` and unit direction ``l_k`` (from the surface towards the
light, :data:`datasets_synthetic.heightfields.CONVENTION`), optionally plus a
Blinn-Phong term ``k_s e_k max(0, n . h_k)^s`` with ``h_k = (l_k + v) / |l_k + v|``.
Cast shadows come from an exact horizon test on the height field (see
:func:`cast_shadow_mask`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from datasets_synthetic.heightfields import CONVENTION, HeightField, make_scene
from datasets_synthetic.io import ensure_dir
from surfaces.io import atomic_write_bytes, atomic_write_text, png_bytes, save_npy, write_json
from surfaces.validate import as_array, positive

SHADOW_MODES = ("attached", "cast", "none")


def ring_lights(n: int, slant_deg: float, azimuth0_deg: float = 90.0) -> np.ndarray:
    """``n`` unit light directions on a cone of half-angle ``slant_deg`` around +z.

    ``l_k = (sin s cos a_k, sin s sin a_k, cos s)`` with ``a_k = a_0 + 360 k / n``
    degrees, azimuth from +x towards +y (y up). Three lights 120 deg apart are
    best conditioned at ``tan(s) = sqrt(2)``, s = 54.74 deg (Drbohlav & Chantler 2005).

    Parameters
    ----------
    n : int
        Number of lights (>= 1).
    slant_deg : float
        Angle between each light and the viewing direction +z, in [0, 90) degrees.
    azimuth0_deg : float
        Azimuth of the first light (default 90: the first light comes from the top).

    Returns
    -------
    (n, 3) float64 array of unit vectors.
    """
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a whole number of lights >= 1, got {n!r}")
    slant = float(slant_deg)
    if not (0.0 <= slant < 90.0):
        raise ValueError(f"slant_deg: must lie in [0, 90) degrees, got {slant_deg!r}")
    s = np.deg2rad(slant)
    a = np.deg2rad(float(azimuth0_deg) + 360.0 * np.arange(int(n)) / int(n))
    return np.column_stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.full(a.shape, np.cos(s))])


def slant_azimuth(lights) -> tuple[np.ndarray, np.ndarray]:
    """Slant (from +z) and azimuth (from +x towards +y) of unit light directions, degrees.

    Parameters
    ----------
    lights : (N, 3) array_like
        Unit directions.

    Returns
    -------
    slant, azimuth : (N,) float64 arrays in degrees.
    """
    lights = _unit_lights(lights)
    slant = np.rad2deg(np.arccos(np.clip(lights[:, 2], -1.0, 1.0)))
    azimuth = np.rad2deg(np.arctan2(lights[:, 1], lights[:, 0]))
    return slant, azimuth


def deviate_lights(lights, deviations) -> np.ndarray:
    """Rotate each light by a slant and an azimuth deviation (the "wrong lights" of seed 002a).

    Light k with slant ``s_k`` and azimuth ``a_k`` becomes the unit vector with slant
    ``s_k + ds_k`` and azimuth ``a_k + da_k``.

    Parameters
    ----------
    lights : (N, 3) array_like
        Unit light directions.
    deviations : (N, 2) or (N,) array_like
        ``[ds, da]`` per light in degrees; a 1-D array gives slant deviations only.

    Returns
    -------
    (N, 3) float64 array of unit vectors.
    """
    lights = _unit_lights(lights)
    dev = as_array(deviations, "deviations", ndim=(1, 2))
    if dev.ndim == 1:
        dev = np.column_stack([dev, np.zeros_like(dev)])
    if dev.shape != (len(lights), 2):
        raise ValueError(
            f"deviations: expected shape ({len(lights)}, 2) or ({len(lights)},), got {dev.shape}")
    slant, azimuth = slant_azimuth(lights)
    s = np.deg2rad(slant + dev[:, 0])
    a = np.deg2rad(azimuth + dev[:, 1])
    return np.column_stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.cos(s)])


def angle_between_deg(a, b) -> np.ndarray:
    """Angles between corresponding unit vectors, degrees.

    Parameters
    ----------
    a, b : (N, 3) array_like

    Returns
    -------
    (N,) float64 array.
    """
    a = _unit_lights(a, "a")
    b = _unit_lights(b, "b")
    if a.shape != b.shape:
        raise ValueError(f"a and b: shapes differ ({a.shape} vs {b.shape})")
    # atan2 of |a x b| and a . b keeps small angles accurate
    return np.rad2deg(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


def _unit_lights(lights, name: str = "lights") -> np.ndarray:
    lights = as_array(lights, name, ndim=(1, 2))
    if lights.ndim == 1:
        lights = lights[None, :]
    if lights.shape[1] != 3 or len(lights) < 1:
        raise ValueError(f"{name}: expected shape (N, 3), got {lights.shape}")
    norm = np.linalg.norm(lights, axis=1)
    if np.any(np.abs(norm - 1.0) > 1e-6):
        raise ValueError(f"{name}: rows must be unit vectors (norms {np.round(norm, 6).tolist()})")
    return lights / norm[:, None]


def cast_shadow_mask(
    height, light, pixel_size: float, step: float = 0.25, method: str = "auto"
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
    from scipy.ndimage import map_coordinates

    z = as_array(height, "height", ndim=2)
    lz = _unit_lights(light, "light")[0]
    ps = positive(pixel_size, "pixel_size")
    step = positive(step, "step")
    if method not in ("auto", "march", "raycast"):
        raise ValueError(f"method: expected 'auto', 'march' or 'raycast', got {method!r}")
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


def _raycast_shadow(z: np.ndarray, light: np.ndarray, ps: float) -> np.ndarray:
    """Cast shadows by open3d ray casting over the height-field mesh (see cast_shadow_mask)."""
    import open3d as o3d

    h, w = z.shape
    rows, cols = np.mgrid[0:h, 0:w]
    # the mesh in the image convention: x = col * ps, y = -row * ps (y up), z = height
    verts = np.column_stack([cols.ravel() * ps, -rows.ravel() * ps, z.ravel()]).astype(np.float32)
    idx = (rows * w + cols)[:-1, :-1].ravel()
    tris = np.concatenate([np.column_stack([idx, idx + w, idx + 1]),
                           np.column_stack([idx + 1, idx + w, idx + w + 1])]).astype(np.uint32)
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

    from surfaces.grid import image_shape

    h, w = image_shape(size)
    if not (0.0 < low < high <= 1.0):
        raise ValueError(f"low, high: need 0 < low < high <= 1, got {low}, {high}")
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
    shadow_step: float = 0.25,
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
    if not isinstance(hf, HeightField):
        raise ValueError(f"hf: expected a HeightField, got {type(hf).__name__}")
    if shadows not in SHADOW_MODES:
        raise ValueError(f"shadows: expected one of {SHADOW_MODES}, got {shadows!r}")
    if bit_depth not in (None, 8, 16):
        raise ValueError(f"bit_depth: expected None, 8 or 16, got {bit_depth!r}")
    L = _unit_lights(lights)
    n_lights = len(L)
    h, w = hf.shape
    e = np.ones(n_lights) if intensities is None else as_array(intensities, "intensities", ndim=(1, 2))
    if e.shape not in ((n_lights,), (n_lights, 3)) or np.any(e < 0):
        raise ValueError(f"intensities: expected non-negative ({n_lights},) or ({n_lights}, 3), "
                         f"got shape {e.shape}")
    rho = np.asarray(1.0) if albedo is None else as_array(albedo, "albedo", ndim=(0, 2, 3))
    if rho.ndim and rho.shape not in ((h, w), (h, w, 3)):
        raise ValueError(f"albedo: expected a scalar, ({h}, {w}) or ({h}, {w}, 3), got {rho.shape}")
    if np.any(rho < 0):
        raise ValueError("albedo: must be non-negative")
    noise = positive(noise, "noise", allow_zero=True)
    shot_noise = positive(shot_noise, "shot_noise", allow_zero=True)
    rgb = e.ndim == 2 or rho.ndim == 3
    spec = None
    if specular is not None:
        unknown = set(specular) - {"ks", "shininess", "view"}
        if unknown:
            raise ValueError(f"specular: unknown keys {sorted(unknown)}")
        view = _unit_lights(specular.get("view", (0.0, 0.0, 1.0)), "specular['view']")[0]
        spec = (positive(specular.get("ks", 0.5), "specular['ks']", allow_zero=True),
                positive(specular.get("shininess", 20.0), "specular['shininess']"), view)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    if cast_masks is not None:
        cast_masks = as_array(cast_masks, "cast_masks", shape=(n_lights, h, w), dtype=bool)

    n = hf.normals
    out = np.empty((n_lights, h, w, 3) if rgb else (n_lights, h, w), np.float32)
    for k in range(n_lights):
        ndotl = n @ L[k]
        diffuse = ndotl if shadows == "none" else np.maximum(ndotl, 0.0)
        highlight = np.zeros((h, w))
        if spec is not None:
            half = L[k] + spec[2]
            half /= np.linalg.norm(half)
            highlight = spec[0] * np.maximum(n @ half, 0.0) ** spec[1] * (ndotl > 0)
        if shadows == "cast":
            lit = ~(cast_masks[k] if cast_masks is not None
                    else cast_shadow_mask(hf.height, L[k], hf.pixel_size, shadow_step))
            diffuse = diffuse * lit
            highlight = highlight * lit
        if rgb:
            ek = np.broadcast_to(e[k], (3,)) if e.ndim == 2 else np.full(3, e[k])
            r = rho if rho.ndim == 3 else np.broadcast_to(rho[..., None], (h, w, 3)) if rho.ndim else rho
            img = r * ek * diffuse[..., None] + ek * highlight[..., None]
        else:
            img = rho * e[k] * diffuse + e[k] * highlight
        if shot_noise > 0:
            img = shot_noise * rng.poisson(np.maximum(img, 0.0) / shot_noise)
        if noise > 0:
            img = img + rng.normal(0.0, noise, img.shape)
        if shadows != "none" or bit_depth is not None:
            img = np.clip(img, 0.0, 1.0)
        if bit_depth is not None:
            full = 2.0**bit_depth - 1.0
            img = np.round(img * full) / full
        out[k] = img
    return out


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
        raise ValueError(f"images: colour images need 3 channels, got shape {imgs.shape}")
    if imgs.min() < 0 or imgs.max() > 1:
        raise ValueError(f"images: values must lie in [0, 1], got [{imgs.min()}, {imgs.max()}]")
    lights = _unit_lights(lights_nominal, "lights_nominal")
    if len(lights) != n:
        raise ValueError(f"lights_nominal: {len(lights)} rows for {n} images")
    e = as_array(intensities, "intensities", ndim=(1, 2))
    if e.ndim == 1:
        e = np.repeat(e[:, None], 3, axis=1)
    if e.shape != (n, 3):
        raise ValueError(f"intensities: expected ({n},) or ({n}, 3), got {e.shape}")
    m = as_array(mask, "mask", shape=(h, w), dtype=bool)
    ngt = as_array(normal_gt, "normal_gt", shape=(h, w, 3))
    hgt = as_array(height_gt, "height_gt", shape=(h, w))
    names = [f"{k + 1:03d}.png" for k in range(n)]
    for name, img in zip(names, imgs):
        atomic_write_bytes(out / name, png_bytes(np.round(img * 65535.0).astype(np.uint16)))
    atomic_write_bytes(out / "mask.png", png_bytes(m.astype(np.uint8) * 255))
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
                        "normal_gt": "normal_gt.npy", "height_gt": "height_gt.npy"}
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
        Number of ring lights (:func:`ring_lights` at ``slant``/``azimuth0``) or the
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
        nominal = _unit_lights(lights, "lights")
    n = len(nominal)
    dev = np.zeros((n, 2)) if deviate is None else as_array(deviate, "deviate", ndim=(1, 2))
    if dev.ndim == 1:
        if dev.shape != (n,):
            raise ValueError(f"deviate: expected {n} slant deviations (one per light), got {len(dev)}")
        dev = np.column_stack([dev, np.zeros(n)])
    if dev.shape != (n, 2):
        raise ValueError(f"deviate: expected shape ({n}, 2), got {dev.shape}")
    true = deviate_lights(nominal, dev)
    e = np.ones(n) if intensities is None else as_array(intensities, "intensities", ndim=(1, 2))
    if albedo == "texture":
        rho = texture_albedo(size, seed=seed)
        albedo_desc = {"kind": "texture", "low": 0.55, "high": 0.9, "scale_px": 12.0, "seed": seed}
    elif albedo is None or np.ndim(albedo) == 0:
        rho = 1.0 if albedo is None else positive(albedo, "albedo")
        albedo_desc = {"kind": "constant", "value": rho}
    else:
        raise ValueError(f"albedo: expected a number, 'texture' or None, got {albedo!r}")
    rng = np.random.default_rng(seed)
    images, shadow_fraction = [], []
    for k in tqdm(range(n), desc="render", unit="image", disable=not progress):
        cast = (cast_shadow_mask(hf.height, true[k], hf.pixel_size) if shadows == "cast"
                else np.zeros(hf.shape, bool))
        img = render(hf, true[k:k + 1], e[k:k + 1], rho, shadows=shadows, specular=specular,
                     noise=noise, shot_noise=shot_noise, bit_depth=bit_depth, seed=rng,
                     cast_masks=cast[None])[0]
        images.append(np.clip(img, 0.0, 1.0))
        shadow_fraction.append(float(np.mean(cast)))
    slant_nom, az_nom = slant_azimuth(nominal)
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
        "light_error_deg": angle_between_deg(true, nominal),
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
    return write_diligent_folder(Path(out_dir), np.stack(images), nominal, e, np.ones(hf.shape, bool),
                                 hf.normals, hf.height, content)
