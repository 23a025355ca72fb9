"""Mirror-sphere calibration images: the specular highlight of each near LED on a polished sphere.

The last section of the shared near-field format contract. A polished sphere
of radius ``R`` with centre ``S`` (rig frame, mm; resting on the reference
plane when ``S_z = R``) is seen by an orthographic or perspective camera
(:mod:`datasets_synthetic.cameras`) under point LEDs
(:mod:`datasets_synthetic.point_lights`). Each LED is a small emitting disc of
radius ``rho`` centred on its position ``P_k`` and facing along its axis
``a_k``. For a camera ray that meets the sphere at ``X`` (normal
``n = (X - S) / R``) the mirror sends it on along ``r = d - 2 (d . n) n``; the
pixel sees the LED where that ray crosses the disc, with radiance
``e_k max(0, -r . a_k)^mu_k`` (the LED lobe). A weak Lambertian term (the
contract's irradiance ``E_k(X) max(0, n . l_k)``) makes the sphere's outline
visible; the reference plane around it is a matte background (black by
default) that the sphere shadows. Each pixel of the diffuse image is the mean
of ``supersample x supersample`` rays inside the sphere's image (one ray at
the centre elsewhere). The highlight, often much smaller than a pixel, is
traced on its own grid of ``highlight_samples`` rays a side over a box about
the exact reflection point (sized from the mirror's magnification, grown
until the highlight lies inside it); every ray that sees the LED is spread
over the pixels by a Gaussian lens point-spread function of ``psf_sigma_px``
pixels integrated over each pixel (erf differences), so that the highlight's
centroid is sub-pixel exact. One radiance scale per render makes the
highlight term of the brightest highlight pixel ``highlight``.

A lens with OpenCV's distortion (``distortion = (k1, k2, p1, p2, k3)``, stated in the
perspective camera's ``K``, :func:`datasets_synthetic.mitsuba_scenes.lens_matrix`)
moves every image point ``u`` to ``u_d = K distort(K^-1 u)``: each highlight ray is
splatted at its distorted position (``cv2.projectPoints``, so the highlight stays
sub-pixel exact and ``highlights_px`` are the distorted positions), and the smooth
diffuse image is resampled (:func:`datasets_synthetic.mitsuba_scenes.distort_image`).

:func:`reflection_points` gives the exact highlight: the point on the sphere
whose normal bisects the directions to the camera and to the LED centre
(a one-dimensional root in the plane through ``S``, the camera and ``P_k``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from datasets_synthetic.cameras import Camera, make_camera, project, view_directions, vignetting_map
from datasets_synthetic.io import ensure_dir
from datasets_synthetic.point_lights import PointLights, _light_vector, rig_lights
from datasets_synthetic.render import sensor
from surfaces.io import atomic_write_text, write_json, write_png
from surfaces.validate import as_array, InputError, positive

#: Highlight term of the brightest highlight pixel of a render (full scale 1; the diffuse term adds to it).
HIGHLIGHT = 0.9
#: Standard deviation of the Gaussian lens point-spread function that blurs the highlight, pixels.
PSF_SIGMA = 1.0
#: Value of a sphere point facing an LED of intensity 1 at the LED's distance from the origin.
DIFFUSE = 0.05
#: Rays per chunk of the supersampled passes (keeps memory flat for large spheres).
CHUNK = 1 << 20


@dataclass(frozen=True)
class SphereRender:
    """Rendered mirror-sphere images with their exact highlights.

    Attributes
    ----------
    images : (N, H, W) float32 array
        One image per LED, values in [0, 1].
    center_mm : (3,) float64 array
        Sphere centre.
    radius_mm : float
        Sphere radius.
    highlights_mm : (N, 3) float64 array
        Exact reflection point of each LED centre on the sphere (:func:`reflection_points`).
    highlights_px : (N, 2) float64 array
        Where the camera sees them: (row, col), pixel centres at whole numbers.
    camera : Camera
        The camera.
    lights : PointLights
        The LEDs.
    settings : dict
        LED disc radius, supersampling, highlight and diffuse levels, background albedo,
        vignetting, noise and bit depth.
    """

    images: np.ndarray
    center_mm: np.ndarray
    radius_mm: float
    highlights_mm: np.ndarray
    highlights_px: np.ndarray
    camera: Camera
    lights: PointLights
    settings: dict


def _check_sphere(camera: Camera, lights: PointLights, center_mm, radius_mm):
    """Checked centre and radius of a sphere the camera can see and no LED is inside."""
    c = as_array(center_mm, "center_mm", shape=(3,))
    r = positive(radius_mm, "radius_mm")
    if c[2] < r * (1.0 - 1e-9):
        raise InputError(f"center_mm: a sphere of radius {r} mm centred at z = {c[2]} mm cuts the reference plane "
                         "z = 0 (a sphere resting on it has z = radius)")
    if camera.model == "perspective" and camera.camera_height_mm <= c[2] + r:
        raise InputError(f"camera_height_mm: the camera ({camera.camera_height_mm} mm) must be above the sphere, "
                         f"whose top is at z = {c[2] + r} mm")
    inside = np.flatnonzero(np.linalg.norm(lights.positions - c, axis=1) <= r)
    if inside.size:
        raise InputError(f"center_mm: LED(s) {(inside + 1).tolist()} lie inside the sphere")
    return c, r


def reflection_points(camera: Camera, lights: PointLights, center_mm, radius_mm: float) -> np.ndarray:
    """The specular point of each LED centre on a mirror sphere.

    Parameters
    ----------
    camera : Camera
        The camera (orthographic: the view direction is +z everywhere).
    lights : PointLights
        The LEDs.
    center_mm : (3,) array_like
        Sphere centre, mm.
    radius_mm : float
        Sphere radius, mm.

    Returns
    -------
    (N, 3) float64 array
        Points ``X`` on the sphere whose normal bisects the unit vectors from ``X`` to
        the camera and to ``P_k``.

    Notes
    -----
    The point lies in the plane through the centre ``S`` spanned by ``u`` (towards the
    camera) and the part ``w`` of ``P_k - S`` normal to ``u``: ``X(t) = S + R (cos t u +
    sin t w)`` with ``t`` between 0 and the angle of ``P_k``. There the tangential part
    of (unit vector to the camera + unit vector to the LED) falls from positive to
    negative; 80 bisection steps find its root for all LEDs at once.

    Examples
    --------
    >>> from datasets_synthetic.cameras import orthographic_camera
    >>> from datasets_synthetic.point_lights import point_lights
    >>> x = reflection_points(orthographic_camera(8, 1.0), point_lights([[0.0, 0.0, 100.0]]), [0, 0, 10], 10.0)
    >>> x.round(9).tolist()
    [[0.0, 0.0, 20.0]]
    """
    c, r = _check_sphere(camera, lights, center_mm, radius_mm)
    n = len(lights)
    if camera.model == "orthographic":
        u = np.tile([0.0, 0.0, 1.0], (n, 1))
    else:
        u = np.tile(np.array([0.0, 0.0, camera.camera_height_mm]) - c, (n, 1))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
    to_led = lights.positions - c
    w = to_led - np.sum(to_led * u, axis=1, keepdims=True) * u
    wn = np.linalg.norm(w, axis=1, keepdims=True)
    w = np.where(wn > 1e-12, w / np.maximum(wn, 1e-300), 0.0)
    lo = np.zeros(n)
    hi = np.arctan2(wn[:, 0], np.sum(to_led * u, axis=1))

    def point(t):
        return c + r * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * w)

    for _ in range(80):
        mid = 0.5 * (lo + hi)
        x = point(mid)
        tangent = -np.sin(mid)[:, None] * u + np.cos(mid)[:, None] * w
        g = np.sum((view_directions(camera, x) + _unit(lights.positions - x)) * tangent, axis=1)
        lo = np.where(g > 0, mid, lo)
        hi = np.where(g > 0, hi, mid)
    return point(0.5 * (lo + hi))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def render_mirror_sphere(
    camera: Camera,
    lights: PointLights,
    center_mm,
    radius_mm: float,
    led_radius_mm: float = 1.0,
    supersample: int = 4,
    highlight_samples: int = 96,
    psf_sigma_px: float = PSF_SIGMA,
    highlight: float = HIGHLIGHT,
    diffuse: float = DIFFUSE,
    background: float = 0.0,
    vignetting: dict | None = None,
    noise: float = 0.0,
    bit_depth: int | None = None,
    seed: int | np.random.Generator = 0,
    distortion=None,
) -> SphereRender:
    """Render one mirror-sphere placement: per LED one image of its highlight.

    Parameters
    ----------
    camera : Camera
        Orthographic or perspective camera.
    lights : PointLights
        The LEDs (positions, axes, lobes, intensities; grey intensities only).
    center_mm : (3,) array_like
        Sphere centre in mm, ``z >= radius`` (on or above the reference plane).
    radius_mm : float
        Sphere radius, mm.
    led_radius_mm : float
        Radius of each LED's emitting disc, mm (default 1).
    supersample : int
        Rays per pixel side inside the sphere's image (default 4).
    highlight_samples : int
        Rays per side of the box traced about each highlight (default 96).
    psf_sigma_px : float
        Gaussian point-spread function of the lens applied to the highlight, pixels
        (default 1; 0: none, the highlight is then often a single pixel).
    highlight : float
        Highlight term of the brightest highlight pixel (one LED radiance scale for all
        images; the diffuse term adds to it).
    diffuse : float
        Weak Lambertian term: value of a sphere point facing an LED of intensity 1 at
        the distance ``d0`` (the contract's irradiance times ``diffuse``).
    background : float
        Albedo of the matte reference plane around the sphere (default 0: black).
    vignetting : dict, optional
        :func:`~datasets_synthetic.cameras.vignetting_map` specification.
    noise : float
        Gaussian noise, full-scale units.
    bit_depth : {None, 8, 16}
        Quantisation.
    seed : int or numpy.random.Generator
        Noise seed.
    distortion : (5,) array_like, optional
        Lens distortion ``k1, k2, p1, p2, k3`` (OpenCV's model, in the camera's ``K``);
        None: a distortion-free lens.

    Returns
    -------
    SphereRender

    Raises
    ------
    ValueError
        A sphere cutting the reference plane, a camera not above it, an LED inside it,
        RGB intensities or bad options.
    """
    if not isinstance(camera, Camera):
        raise InputError(f"camera: expected a Camera, got {type(camera).__name__}")
    if not isinstance(lights, PointLights):
        raise InputError(f"lights: expected PointLights, got {type(lights).__name__}")
    if lights.intensities.ndim != 1:
        raise InputError("lights: mirror-sphere images are grey; give one intensity per LED")
    c, r = _check_sphere(camera, lights, center_mm, radius_mm)
    rho = positive(led_radius_mm, "led_radius_mm")
    s = int(supersample)
    f = int(highlight_samples)
    if s < 1 or f < 8 or s != supersample or f != highlight_samples:
        raise InputError(f"supersample, highlight_samples: expected integers >= 1 and >= 8, got {supersample!r}, "
                         f"{highlight_samples!r}")
    sigma = positive(psf_sigma_px, "psf_sigma_px", allow_zero=True)
    level = positive(highlight, "highlight")
    if level > 1:
        raise InputError(f"highlight: must lie in (0, 1], got {level}")
    weak = positive(diffuse, "diffuse", allow_zero=True)
    back = positive(background, "background", allow_zero=True)
    if bit_depth not in (None, 8, 16):
        raise InputError(f"bit_depth: expected None, 8 or 16, got {bit_depth!r}")
    noise = positive(noise, "noise", allow_zero=True)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    lens = _lens(camera, distortion)
    shader = _Shader(camera, lights, c, r, rho, weak, back, lens)
    h, w = camera.shape
    n = len(lights)
    rows, cols = np.mgrid[0:h, 0:w]
    box = _sphere_box(camera, c, r)
    inside = (rows >= box[0]) & (rows <= box[1]) & (cols >= box[2]) & (cols <= box[3])
    lit = np.zeros((n, h, w))
    lit[:, ~inside] = shader.pixels(rows[~inside], cols[~inside], 1)
    lit[:, inside] = shader.pixels(rows[inside], cols[inside], s)
    if lens is not None:
        from datasets_synthetic.mitsuba_scenes import distort_image

        lit = distort_image(lit, *lens).astype(np.float64)
    exact = reflection_points(camera, lights, c, r)
    ideal_r, ideal_c = project(camera, exact)  # the spot's ray box is traced about the pinhole position
    hr, hc = (ideal_r, ideal_c) if lens is None else distort_pixels(ideal_r, ideal_c, *lens)
    visible = (hr > -0.5) & (hr < h - 0.5) & (hc > -0.5) & (hc < w - 0.5)
    if not visible.any():
        raise InputError("center_mm: no LED highlight falls inside the image; move the sphere into the field")
    spots = np.stack([shader.spot(k, exact[k], (ideal_r[k], ideal_c[k]), f, sigma) if visible[k] else np.zeros((h, w))
                      for k in range(n)])
    radiance = level / spots.max()
    clean = (lit + radiance * spots) * vignetting_map(camera, vignetting)
    images = np.stack([sensor(img, rng, noise, 0.0, bit_depth, clip=True) for img in clean]).astype(np.float32)
    settings = {"led_radius_mm": rho, "supersample": s, "highlight_samples": f, "psf_sigma_px": sigma,
                "highlight": level, "highlight_radiance": radiance, "diffuse": weak, "background": back,
                "vignetting": vignetting, "noise": noise, "bit_depth": bit_depth,
                "distortion": None if lens is None else lens[1].tolist()}
    return SphereRender(images, c, r, exact, np.column_stack([hr, hc]), camera, lights, settings)


def _lens(camera: Camera, distortion):
    """``(K, (k1, k2, p1, p2, k3))`` of a distorting lens, or None."""
    if distortion is None:
        return None
    d = as_array(distortion, "distortion", ndim=1)
    if not 1 <= d.size <= 5:
        raise InputError(f"distortion: expected k1[, k2[, p1[, p2[, k3]]]] (OpenCV's order), got {d.size} values")
    d = np.concatenate([d, np.zeros(5 - d.size)])
    if not d.any():
        return None
    if camera.model != "perspective":
        raise InputError("distortion: the lens option needs a perspective camera (a focal length in pixels)")
    from datasets_synthetic.mitsuba_scenes import lens_matrix

    return lens_matrix(camera), d


def distort_pixels(rows, cols, camera_matrix, distortion) -> tuple[np.ndarray, np.ndarray]:
    """Where a lens with OpenCV's distortion records ideal (pinhole) pixel positions.

    Parameters
    ----------
    rows, cols : array_like, shape (M,)
        Ideal pixel positions (pixel centres at whole numbers).
    camera_matrix : (3, 3) array_like
        ``K`` (0-based principal point).
    distortion : (5,) array_like
        ``k1, k2, p1, p2, k3``.

    Returns
    -------
    rows, cols : numpy.ndarray, shape (M,)
        ``u_d = K distort(K^-1 u)`` (``cv2.projectPoints`` of the normalised rays).
    """
    import cv2

    K = as_array(camera_matrix, "camera_matrix", shape=(3, 3))
    r = np.asarray(rows, np.float64).ravel()
    c = np.asarray(cols, np.float64).ravel()
    rays = np.stack([(c - K[0, 2]) / K[0, 0], (r - K[1, 2]) / K[1, 1], np.ones_like(r)], axis=1)
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, as_array(distortion, "distortion", shape=(5,)))
    out = out.reshape(-1, 2)
    return out[:, 1].reshape(np.shape(rows)), out[:, 0].reshape(np.shape(cols))


def _sphere_box(camera: Camera, c: np.ndarray, r: float) -> tuple[int, int, int, int]:
    """Pixel rows and columns (first, last) that may see the sphere: its bounding cube projected, plus one."""
    corners = c + r * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    row, col = project(camera, corners)
    h, w = camera.shape
    return (max(int(np.floor(row.min())) - 1, 0), min(int(np.ceil(row.max())) + 1, h - 1),
            max(int(np.floor(col.min())) - 1, 0), min(int(np.ceil(col.max())) + 1, w - 1))


class _Shader:
    """Rays through sub-pixel positions, their first hit (sphere or plane), the diffuse values and LED images."""

    def __init__(self, camera, lights, c, r, rho, diffuse, background, lens=None):
        self.camera, self.lights, self.c, self.r, self.rho, self.lens = camera, lights, c, r, rho, lens
        self.diffuse, self.background = diffuse, background

    def pixels(self, rows: np.ndarray, cols: np.ndarray, s: int) -> np.ndarray:
        """(N, M) means of the diffuse values over ``s x s`` rays per pixel."""
        m = rows.size
        offsets = (np.arange(s) + 0.5) / s - 0.5
        dr, dc = (a.ravel() for a in np.meshgrid(offsets, offsets, indexing="ij"))
        lit = np.zeros((len(self.lights), m))
        per = max(1, CHUNK // (s * s))
        for start in range(0, m, per):
            sl = slice(start, start + per)
            rr = (rows[sl, None] + dr).ravel()
            cc = (cols[sl, None] + dc).ravel()
            lit[:, sl] = self._rays(rr, cc)[0].reshape(len(self.lights), -1, s * s).mean(axis=2)
        return lit

    def spot(self, k: int, point: np.ndarray, pixel, samples: int, sigma: float) -> np.ndarray:
        """(H, W) image of LED ``k`` in the mirror: rays on a box about its reflection point, spread by the PSF."""
        h, w = self.camera.shape
        depth = 1.0 if self.camera.model == "orthographic" else self.camera.camera_height_mm - point[2]
        mm_per_px = self.camera.reference_pixel_mm * (depth if self.camera.model == "orthographic"
                                                      else depth / self.camera.camera_height_mm)
        # a convex mirror of radius R shows a disc of radius rho at distance D about R rho / (2 D) wide
        half = max(3.0 * self.r * self.rho / (2.0 * np.linalg.norm(self.lights.positions[k] - point)) / mm_per_px,
                   0.05)
        for _ in range(12):
            grid = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
            rr, cc = np.meshgrid(pixel[0] + half * grid, pixel[1] + half * grid, indexing="ij")
            radiance = self._rays(rr.ravel(), cc.ravel(), k)[1][0].reshape(samples, samples)
            edge = np.concatenate([radiance[0], radiance[-1], radiance[:, 0], radiance[:, -1]])
            if radiance.any() and not edge.any():
                break
            half *= 2.0 if edge.any() else 0.5
        else:
            raise InputError(f"lights: the highlight of LED {k + 1} could not be enclosed; check the sphere and LED")
        lit = radiance > 0
        weights = radiance[lit] * (2.0 * half / samples) ** 2  # radiance times the ray's area, px^2
        at_r, at_c = rr[lit], cc[lit]
        if self.lens is not None:  # where the lens records these rays (the spot's brightness scale aside)
            at_r, at_c = distort_pixels(at_r, at_c, *self.lens)
        return _splat(at_r, at_c, weights, (h, w), sigma)

    def _rays(self, rows: np.ndarray, cols: np.ndarray, only: int | None = None):
        """(N, M) diffuse values and LED-image radiances ``e_k lobe`` (0 off the disc) of single rays."""
        origins, d = self.camera.rays(rows, cols)
        if self.camera.model == "orthographic":
            origins = origins.copy()
            origins[:, 2] = self.c[2] + 2.0 * self.r  # above the sphere
        oc = origins - self.c
        b = np.einsum("ij,ij->i", d, oc)
        disc = b * b - (np.einsum("ij,ij->i", oc, oc) - self.r**2)
        on_sphere = disc > 0
        t_sphere = -b - np.sqrt(np.maximum(disc, 0.0))
        t_plane = origins[:, 2] / -d[:, 2]
        t = np.where(on_sphere, t_sphere, t_plane)
        x = origins + t[:, None] * d
        normal = np.where(on_sphere[:, None], (x - self.c) / self.r, [0.0, 0.0, 1.0])
        mirrored = d - 2.0 * np.einsum("ij,ij->i", d, normal)[:, None] * normal
        which = range(len(self.lights)) if only is None else [only]
        lit = np.zeros((len(which), rows.size))
        spot = np.zeros((len(which), rows.size))
        albedo = np.where(on_sphere, self.diffuse, self.background)
        for i, k in enumerate(which):
            p, a = self.lights.positions[k], self.lights.axes[k]
            e, mu = self.lights.intensities[k], self.lights.mu[k]
            if only is None:
                towards, falloff = _light_vector(self.lights, k, x)
                shade = albedo * e * falloff * np.maximum(0.0, np.einsum("ij,ij->i", normal, towards))
                lit[i] = np.where(on_sphere, shade, shade * ~self._blocked(x, p)) if self.background > 0 else shade
            facing = mirrored @ a
            t_led = ((p - x) @ a) / np.where(facing < 0, facing, -1.0)
            q = x + t_led[:, None] * mirrored - p
            disc_hit = on_sphere & (facing < 0) & (t_led > 0) & (np.einsum("ij,ij->i", q, q) <= self.rho**2)
            lobe = np.maximum(0.0, -facing) ** mu if mu > 0 else 1.0
            spot[i] = e * lobe * disc_hit
        return lit, spot

    def _blocked(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Plane points whose segment to the LED at ``p`` passes through the sphere."""
        d = p - x
        length = np.linalg.norm(d, axis=1)
        d = d / length[:, None]
        oc = x - self.c
        b = np.einsum("ij,ij->i", d, oc)
        disc = b * b - (np.einsum("ij,ij->i", oc, oc) - self.r**2)
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        return (disc > 0) & (t > 0) & (t < length)


def _splat(rows: np.ndarray, cols: np.ndarray, weights: np.ndarray, shape, sigma: float) -> np.ndarray:
    """Point samples spread by a Gaussian PSF and integrated over whole pixels (a box when ``sigma`` is 0)."""
    from scipy.special import ndtr

    h, w = shape
    reach = 4.0 * sigma + 1.0
    r0, r1 = max(int(np.floor(rows.min() - reach)), 0), min(int(np.ceil(rows.max() + reach)), h - 1)
    c0, c1 = max(int(np.floor(cols.min() - reach)), 0), min(int(np.ceil(cols.max() + reach)), w - 1)
    image = np.zeros((h, w))
    if r1 < r0 or c1 < c0:
        return image

    def share(centres, first, last):
        edges = np.arange(first, last + 2) - 0.5
        if sigma > 0:
            cdf = ndtr((edges[None, :] - centres[:, None]) / sigma)
        else:
            cdf = (edges[None, :] > centres[:, None]).astype(float)
        return np.diff(cdf, axis=1)

    image[r0:r1 + 1, c0:c1 + 1] = (share(rows, r0, r1) * weights[:, None]).T @ share(cols, c0, c1)
    return image


def write_sphere_folder(out_dir: str | os.PathLike, rendered: SphereRender, scene: dict | None = None) -> dict:
    """Write one calibration folder of the contract.

    Files: ``001.png ...`` (16-bit, one per LED in light order), ``filenames.txt``,
    ``sphere.json`` (``{"radius_mm": R, "center_mm": [x, y, z]}``) and ``scene.json``
    (the camera, as the contract writes it, and the truth: the LEDs, the LED disc
    radius, the exact highlights and the render settings).

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    rendered : SphereRender
        The render.
    scene : dict, optional
        More keys for ``scene.json``.

    Returns
    -------
    dict
        The content of ``scene.json``.
    """
    if not isinstance(rendered, SphereRender):
        raise InputError(f"rendered: expected a SphereRender, got {type(rendered).__name__}")
    out = ensure_dir(out_dir)
    names = [f"{k + 1:03d}.png" for k in range(len(rendered.images))]
    for name, img in zip(names, rendered.images):
        write_png(out / name, np.round(img.astype(np.float64) * 65535.0).astype(np.uint16))
    atomic_write_text(out / "filenames.txt", "".join(f"{s}\n" for s in names))
    write_json(out / "sphere.json", {"radius_mm": rendered.radius_mm, "center_mm": rendered.center_mm.tolist()})
    content = dict(scene or {})
    content.update({
        "model": "mirror-sphere",
        "camera": rendered.camera.as_dict(),
        "image_size": list(rendered.camera.shape),
        "radius_mm": rendered.radius_mm,
        "center_mm": rendered.center_mm.tolist(),
        "lights": rendered.lights.as_dict(),
        "highlights_mm": rendered.highlights_mm.tolist(),
        "highlights_px": rendered.highlights_px.tolist(),
        "highlights_note": "exact reflection point of each LED centre and its (row, col) pixel position",
        **rendered.settings,
        "files": {"images": names, "sphere": "sphere.json"},
    })
    write_json(out / "scene.json", content)
    return content


def make_sphere_folders(
    out_dir: str | os.PathLike,
    centers,
    radius: float = 10.0,
    size=512,
    lights=3,
    slant: float = 45.0,
    light_distance: float = 200.0,
    azimuth0: float = 90.0,
    led_mu=None,
    camera: str = "orthographic",
    pixel_size: float | None = None,
    focal_length_px: float | None = None,
    camera_height: float | None = None,
    led_radius: float = 1.0,
    supersample: int = 4,
    highlight_samples: int = 96,
    psf_sigma_px: float = PSF_SIGMA,
    background: float = 0.0,
    deviate=None,
    intensities=None,
    vignetting: dict | None = None,
    noise: float = 0.0,
    bit_depth: int | None = 16,
    seed: int = 0,
    distortion=None,
) -> dict:
    """Render a mirror sphere at several placements: one calibration folder each.

    Writes ``out_dir/sphere_01``, ``sphere_02``, ... (:func:`write_sphere_folder`) and
    ``out_dir/scene.json`` with the TRUE LED positions (nominal ones deviated by
    ``deviate``), the nominal ones, the camera and each placement's folder, centre and
    exact highlights.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder.
    centers : (M, 3) array_like
        Sphere centres in mm, one per placement.
    radius : float
        Sphere radius, mm.
    size, camera, pixel_size, focal_length_px, camera_height
        The camera (:func:`~datasets_synthetic.cameras.make_camera`).
    lights, slant, light_distance, azimuth0, led_mu, deviate, intensities
        The LEDs (:func:`~datasets_synthetic.point_lights.rig_lights`).
    led_radius, supersample, highlight_samples, psf_sigma_px, background, vignetting, noise, bit_depth
        See :func:`render_mirror_sphere`.
    seed : int
        Noise seed.
    distortion : (5,) array_like, optional
        Lens distortion ``k1, k2, p1, p2, k3`` (:func:`render_mirror_sphere`); written to
        ``scene.json`` as ``lens_distortion`` (the camera entry stays the pinhole's).

    Returns
    -------
    dict
        The content of the top-level ``scene.json``.
    """
    cam = make_camera(camera, size, pixel_size, focal_length_px, camera_height)
    nominal, true, dev = rig_lights(lights, slant, light_distance, azimuth0, 0.0 if led_mu is None else led_mu,
                                    intensities, deviate)
    c = as_array(centers, "centers", ndim=2)
    if c.shape[1] != 3 or len(c) < 1:
        raise InputError(f"centers: expected (M, 3) sphere centres in mm, got shape {c.shape}")
    rng = np.random.default_rng(seed)
    renders = [render_mirror_sphere(cam, true, centre, radius, led_radius, supersample, highlight_samples,
                                    psf_sigma_px, background=background, vignetting=vignetting, noise=noise,
                                    bit_depth=bit_depth, seed=rng, distortion=distortion)
               for centre in c]
    out = ensure_dir(out_dir)
    spheres = []
    for m, rendered in enumerate(renders):
        name = f"sphere_{m + 1:02d}"
        write_sphere_folder(out / name, rendered, {"seed": int(seed)})
        spheres.append({"folder": name, "center_mm": rendered.center_mm.tolist(),
                        "highlights_mm": rendered.highlights_mm.tolist(),
                        "highlights_px": rendered.highlights_px.tolist()})
    content = {
        "model": "mirror-sphere calibration",
        "camera": cam.as_dict(),
        "image_size": list(cam.shape),
        "radius_mm": float(radius),
        "led_radius_mm": float(led_radius),
        "n_lights": len(true),
        "lights": true.as_dict(),
        "light_positions_nominal_mm": nominal.positions.tolist(),
        "deviations_deg": dev.tolist(),
        "spheres": spheres,
        "settings": renders[0].settings,
        "lens_distortion": renders[0].settings["distortion"],
    }
    write_json(out / "scene.json", content)
    return content
