"""LED positions from images of mirror spheres (near-field rig calibration), and distant
light directions from one mirror sphere (:func:`calibrate_mirror_sphere`).

A calibration set is one image per LED of a polished sphere of known radius ``R`` and
centre ``c`` (``sphere.json``, rig frame, mm), or of a sphere found by its outline and
taken to rest on the reference plane (``c_z = R``). For each image:

1. the specular highlight: the brightest spot inside the sphere's disc, its
   intensity-weighted centroid (sub-pixel) over a small window above the local
   background (the weak diffuse term);
2. the camera ray through the centroid meets the sphere at ``S``; the sphere normal
   there is ``n = (S - c) / R``, the direction to the camera ``v`` (``(0, 0, 1)`` for an
   orthographic camera, ``(C - S) / |C - S|`` for a perspective one);
3. the LED lies on the reflected ray ``S + t r``, ``r = 2 (n . v) n - v``
   (returning ``n`` itself is the classic bug).

With two or more sets (spheres at different places, or one sphere at two known
heights) each LED is the least-squares nearest point of its rays,
``(sum_i (I - r_i r_i^T)) P = sum_i (I - r_i r_i^T) S_i``; each ray's distance to it is
its residual. The uncertainty propagates each centroid's noise (estimated from the image
noise around the highlight) through the whole construction (the Jacobian of ``P`` with
respect to every centroid, by central differences).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from photometric.camera import Camera, Orthographic, Perspective, camera_from_dict, pixel_offsets, pixel_rays
from surfaces.validate import as_array, InputError, positive, reads_file

__all__ = ["SphereImages", "read_sphere_set", "sphere_from_outline", "highlight_centroids", "reflected_rays",
           "nearest_point", "calibrate_positions", "calibrate_rig", "sphere_from_mask", "calibrate_mirror_sphere"]

#: Half width (pixels) of the window around the highlight peak.
WINDOW_PX = 4
#: Smallest centroid uncertainty assumed (pixels): sampling of a highlight a few pixels wide.
MIN_CENTROID_SIGMA_PX = 0.02
#: Rays whose rms residual exceeds this many times the one the highlight noise explains (linear
#: propagation of the centroid noise to the residuals) do not meet: a sphere's radius or centre is
#: wrong. Rendered sets (datasets_synthetic.spheres) with the right geometry give 1.1-1.5 times; a
#: radius 20 % off 2.6-17 times, a floating sphere taken to rest on the plane 50 times.
RESIDUAL_FACTOR = 3.0


@dataclass(frozen=True)
class SphereImages:
    """One calibration set.

    Attributes
    ----------
    images : numpy.ndarray, shape (N, H, W), float32
        One grey image per LED, in light order.
    centre_mm : numpy.ndarray, shape (3,)
        Sphere centre in the rig frame, mm.
    radius_mm : float
        Sphere radius, mm.
    source : str
        Where it came from (a folder name), for reports.
    centre_from : str
        ``"sphere.json"`` or ``"outline"``.
    """

    images: np.ndarray
    centre_mm: np.ndarray
    radius_mm: float
    source: str = ""
    centre_from: str = "sphere.json"


@reads_file("sphere image folder")
def read_sphere_set(folder, camera: Camera | None = None) -> tuple[SphereImages, Camera | None]:
    """Read one mirror-sphere calibration folder.

    Parameters
    ----------
    folder : str or Path
        ``filenames.txt`` (one image per LED, in light order), the images, and
        ``sphere.json`` (``{"radius_mm": R, "center_mm": [x, y, z]}``); without
        ``sphere.json`` the sphere is found from its outline and taken to rest on the
        reference plane (:func:`sphere_from_outline`). A ``scene.json`` ``camera`` is
        used when ``camera`` is not given.
    camera : Orthographic or Perspective, optional

    Returns
    -------
    SphereImages
    camera : Orthographic, Perspective or None
        ``camera``, else the folder's.
    """
    from photometric.io import read_images, read_scene

    d = Path(folder)
    if not d.is_dir():
        raise NotADirectoryError(f"spheres: {d} is not a folder")
    names_file = d / "filenames.txt"
    if not names_file.is_file():
        raise FileNotFoundError(f"spheres: {names_file} is missing (one image name per LED, in light order)")
    names = [line.strip() for line in names_file.read_text().splitlines() if line.strip()]
    images = _grey(read_images([d / n for n in names]))
    if camera is None:
        scene = read_scene(d)
        if isinstance(scene.get("camera"), dict):
            camera = camera_from_dict(scene["camera"], f"camera ({d / 'scene.json'})")
    sphere_file = d / "sphere.json"
    if sphere_file.is_file():
        try:
            sphere = json.loads(sphere_file.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"spheres: {sphere_file} is not valid JSON ({exc})") from None
        if not isinstance(sphere, dict) or "radius_mm" not in sphere or "center_mm" not in sphere:
            raise InputError(f"spheres: {sphere_file} needs 'radius_mm' and 'center_mm'")
        centre = as_array(sphere["center_mm"], f"center_mm ({sphere_file})", shape=(3,))
        radius = positive(sphere["radius_mm"], f"radius_mm ({sphere_file})")
        return SphereImages(images, centre, radius, str(d), "sphere.json"), camera
    if camera is None:
        raise InputError(f"camera: {d} has no sphere.json and no camera; give the camera options")
    centre, radius = sphere_from_outline(images, camera)
    return SphereImages(images, centre, radius, str(d), "outline"), camera


def _grey(images) -> np.ndarray:
    arr = as_array(images, "images", ndim=(3, 4), dtype=np.float32)
    return arr.mean(axis=3, dtype=np.float32) if arr.ndim == 4 else arr


def _project(camera: Camera, shape, centre: np.ndarray, radius: float) -> tuple[float, float, float]:
    """Image disc of a sphere: centre (row, col) and radius, pixels (perspective: the tangent cone's
    axis and its angle at the principal point, a close disc for the search window)."""
    h, w = shape
    if isinstance(camera, Orthographic):
        ps = camera.pixel_size_mm
        return (h - 1) / 2.0 - centre[1] / ps, centre[0] / ps + (w - 1) / 2.0, radius / ps
    cx, cy = camera.centre(shape)
    depth = camera.camera_height_mm - centre[2]
    if depth <= radius:
        raise InputError(f"sphere: centre {centre.tolist()} mm with radius {radius} mm reaches the camera")
    f = camera.focal_length_px
    dist = float(np.linalg.norm([centre[0], centre[1], depth]))
    return cy - camera.fy * centre[1] / depth, cx + f * centre[0] / depth, f * radius / np.sqrt(dist**2 - radius**2)


def sphere_from_outline(images, camera: Camera, *, threshold: float | None = None) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere resting on the reference plane, from its outline.

    The lit sphere (the brightest of each pixel over the images, smoothed) is separated
    from a darker background by Otsu's threshold (or ``threshold``, in image units);
    the largest region's boundary pixels fit a circle (orthographic) or, as rays, a
    circular cone ``d . b = 1`` (perspective, linear least squares: axis ``b / |b|``,
    half-angle ``acos(1 / |b|)``); the sphere touches ``z = 0``, so ``c_z = R``.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        The calibration images.
    camera : Orthographic or Perspective
    threshold : float, optional
        Brightness separating sphere and background.

    Returns
    -------
    centre : numpy.ndarray, shape (3,)
        mm, rig frame.
    radius : float
        mm.

    Raises
    ------
    ValueError
        No region, or too few outline pixels (give ``sphere.json`` instead).
    """
    imgs = _grey(images)
    top = cv2.GaussianBlur(imgs.max(axis=0), (0, 0), 1.0)
    hi = float(top.max())
    if hi <= 0:
        raise InputError("images: all black; no sphere outline (give sphere.json)")
    if threshold is None:
        scaled = np.clip(top / hi * 255.0, 0, 255).astype(np.uint8)
        level, _ = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        thr = (level + 0.5) / 255.0 * hi
    else:
        thr = float(threshold)
    count, labels, stats, _ = cv2.connectedComponentsWithStats((top > thr).astype(np.uint8), connectivity=8)
    if count < 2:
        raise InputError("images: no sphere outline found above the background (give sphere.json)")
    region = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    region = cv2.morphologyEx(region.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    kernel = np.ones((3, 3), np.uint8)
    # the outline lies between the last pixels inside and the first outside: fit both, average
    inner = region.astype(bool) & ~cv2.erode(region, kernel).astype(bool)
    outer = cv2.dilate(region, kernel).astype(bool) & ~region.astype(bool)
    fits = [_fit_outline(edge, camera, imgs.shape[1:]) for edge in (inner, outer)]
    if isinstance(camera, Orthographic):
        (a0, b0, r0), (a1, b1, r1) = fits
        radius = 0.5 * (r0 + r1)
        return np.array([0.5 * (a0 + a1), 0.5 * (b0 + b1), radius]), float(radius)
    axis = fits[0][0] + fits[1][0]
    axis /= np.linalg.norm(axis)
    sin_a = 0.5 * (fits[0][1] + fits[1][1])
    # the centre is at distance R / sin(alpha) along the axis and at height R
    radius = camera.camera_height_mm / (1.0 - axis[2] / sin_a)
    centre = np.array([0.0, 0.0, camera.camera_height_mm]) + radius / sin_a * axis
    return centre, float(radius)


def _fit_outline(edge: np.ndarray, camera: Camera, shape) -> tuple:
    """Circle ``(x0, y0, r)`` in mm (orthographic, Kasa fit) or cone ``(axis, sin alpha)`` of rays
    (perspective, ``d . b = 1``) through the outline pixels, those on the image border left out."""
    rows, cols = np.nonzero(edge)
    keep = (rows > 0) & (cols > 0) & (rows < shape[0] - 1) & (cols < shape[1] - 1)
    rows, cols = rows[keep], cols[keep]
    if rows.size < 20:
        raise InputError(f"images: sphere outline has only {rows.size} pixels (give sphere.json)")
    if isinstance(camera, Orthographic):
        # x^2 + y^2 = 2 a x + 2 b y + c
        u, v = pixel_offsets(camera, shape)
        x, y = u[cols], v[rows]
        A = np.stack([2 * x, 2 * y, np.ones_like(x)], axis=1)
        (a, b, c), *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
        return a, b, float(np.sqrt(c + a * a + b * b))
    _, d = pixel_rays(camera, shape, rows.astype(float), cols.astype(float))
    b, *_ = np.linalg.lstsq(d, np.ones(len(d)), rcond=None)
    norm = float(np.linalg.norm(b))
    if norm <= 1.0:
        raise InputError("images: the sphere outline does not fit a cone (give sphere.json)")
    return b / norm, float(np.sqrt(1.0 - 1.0 / norm**2))


def highlight_centroids(images, camera: Camera, centre_mm, radius_mm: float, *,
                        window_px: int = WINDOW_PX) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel highlight centroids inside a sphere's image disc.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        One image per LED.
    camera : Orthographic or Perspective
    centre_mm : array_like, shape (3,)
    radius_mm : float
    window_px : int, optional
        Half width of the centroid window around the peak.

    Returns
    -------
    rows, cols : numpy.ndarray, shape (N,), float64
        Intensity-weighted centroids of ``I - background`` over the window (pixel
        centres at integers); the background is the median of the window's border.
    sigma_px : numpy.ndarray, shape (N,), float64
        Their noise (pixels): ``sigma_n sqrt(sum (x - c)^2) / sum w`` from the border's
        noise ``sigma_n``, at least :data:`MIN_CENTROID_SIGMA_PX`.

    Raises
    ------
    ValueError
        No highlight inside the disc in some image, or a highlight at the disc's rim.
    """
    imgs = _grey(images)
    c = as_array(centre_mm, "centre_mm", shape=(3,))
    radius = positive(radius_mm, "radius_mm")
    h, w = imgs.shape[1:]
    r0, c0, rad = _project(camera, (h, w), c, radius)
    rr, cc = np.mgrid[0:h, 0:w]
    disc = (rr - r0) ** 2 + (cc - c0) ** 2 < (0.98 * rad) ** 2
    if disc.sum() < 9:
        raise InputError(f"sphere: its image disc (centre row {r0:.1f}, col {c0:.1f}, radius {rad:.1f} px) "
                         "has fewer than 9 pixels inside the image")
    k = int(window_px)
    if k < 1:
        raise InputError(f"window_px: must be at least 1, got {window_px}")
    rows, cols, sig = np.empty(len(imgs)), np.empty(len(imgs)), np.empty(len(imgs))
    for i, img in enumerate(imgs):
        smooth = cv2.blur(img, (3, 3))
        score = np.where(disc, smooth, -np.inf)
        pr, pc = np.unravel_index(int(np.argmax(score)), score.shape)
        lo_r, hi_r, lo_c, hi_c = max(pr - k, 0), min(pr + k + 1, h), max(pc - k, 0), min(pc + k + 1, w)
        win = img[lo_r:hi_r, lo_c:hi_c].astype(np.float64)
        border = np.concatenate([win[0], win[-1], win[1:-1, 0], win[1:-1, -1]])
        bg = float(np.median(border))
        noise = 1.4826 * float(np.median(np.abs(border - bg)))
        weight = np.clip(win - bg - 2.0 * noise, 0.0, None)
        total = weight.sum()
        if total <= 0 or float(smooth[pr, pc]) <= bg:
            raise InputError(f"images: no highlight inside the sphere's disc in image {i}")
        yy, xx = np.mgrid[lo_r:hi_r, lo_c:hi_c]
        rows[i] = float((weight * yy).sum() / total)
        cols[i] = float((weight * xx).sum() / total)
        spread = np.sqrt(((weight > 0) * ((yy - rows[i]) ** 2 + (xx - cols[i]) ** 2)).sum() / 2.0)
        sig[i] = max(MIN_CENTROID_SIGMA_PX, noise * spread / total)
        if (rows[i] - r0) ** 2 + (cols[i] - c0) ** 2 >= (0.98 * rad) ** 2:
            raise InputError(f"images: the highlight of image {i} is at the rim of the sphere's disc")
    return rows, cols, sig


def reflected_rays(camera: Camera, shape, rows, cols, centre_mm, radius_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Rays from the highlight points towards the LEDs.

    Parameters
    ----------
    camera : Orthographic or Perspective
    shape : (H, W)
    rows, cols : array_like, shape (K,)
        Highlight centroids (fractional pixels).
    centre_mm : array_like, shape (3,)
    radius_mm : float

    Returns
    -------
    points : numpy.ndarray, shape (K, 3)
        Where the camera rays meet the sphere, ``S``, mm.
    directions : numpy.ndarray, shape (K, 3)
        Unit reflected directions ``r = 2 (n . v) n - v``.

    Examples
    --------
    The top of a sphere seen by a telecentric camera reflects straight up:

    >>> from photometric.camera import make_camera
    >>> cam = make_camera("orthographic", pixel_size_mm=0.1)
    >>> S, r = reflected_rays(cam, (101, 101), [50.0], [50.0], [0.0, 0.0, 10.0], 10.0)
    >>> S.tolist(), r.tolist()
    ([[0.0, 0.0, 20.0]], [[0.0, 0.0, 1.0]])
    """
    c = as_array(centre_mm, "centre_mm", shape=(3,))
    radius = positive(radius_mm, "radius_mm")
    origins, d = pixel_rays(camera, shape, rows, cols)
    oc = origins - c
    b = np.einsum("ki,ki->k", d, oc)
    disc = b * b - (np.einsum("ki,ki->k", oc, oc) - radius * radius)
    if np.any(disc < 0):
        raise InputError(f"highlights {np.flatnonzero(disc < 0).tolist()}: the camera ray misses the sphere "
                         "(wrong centre, radius or camera?)")
    # the first hit along the downward ray (orthographic origins lie on z = 0, where t < 0 is fine)
    t = -b - np.sqrt(disc)
    S = origins + t[:, None] * d
    n = (S - c) / radius
    v = -d
    r = 2.0 * np.einsum("ki,ki->k", n, v)[:, None] * n - v
    return S, r / np.linalg.norm(r, axis=1, keepdims=True)


def nearest_point(points, directions) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares nearest point of rays (lines through ``points`` along ``directions``).

    Parameters
    ----------
    points, directions : array_like, shape (K, 3)
        K >= 2 rays, unit directions, not all parallel.

    Returns
    -------
    point : numpy.ndarray, shape (3,)
        ``(sum_i (I - r_i r_i^T))^-1 sum_i (I - r_i r_i^T) S_i``.
    distances : numpy.ndarray, shape (K,)
        Distance of the point to each ray.

    Examples
    --------
    >>> P, d = nearest_point([[0, 0, 0], [10, 0, 0]], [[0, 0, 1], [-0.6, 0, 0.8]])
    >>> (np.round(P, 9) + 0.0).tolist(), np.round(d, 9).tolist()
    ([0.0, 0.0, 13.333333333], [0.0, 0.0])
    """
    S = as_array(points, "points", ndim=2)
    r = as_array(directions, "directions", shape=S.shape)
    if S.shape[1] != 3 or S.shape[0] < 2:
        raise InputError(f"points: expected shape (K, 3) with K >= 2, got {S.shape}")
    proj = np.eye(3)[None] - r[:, :, None] * r[:, None, :]
    M = proj.sum(axis=0)
    s = np.linalg.svd(M, compute_uv=False)
    if s[-1] <= 1e-9 * s[0]:
        raise InputError("directions: the rays are parallel; they do not determine a point "
                         "(use spheres at different places or heights)")
    P = np.linalg.solve(M, np.einsum("kij,kj->i", proj, S))
    dist = np.linalg.norm(np.einsum("kij,kj->ki", proj, P[None] - S), axis=1)
    return P, dist


def _positions(sets, camera, shape, rows, cols) -> tuple[np.ndarray, np.ndarray]:
    """LED positions (N, 3) and ray distances (N, K) from centroids (K, N)."""
    n = rows.shape[1]
    S = np.empty((len(sets), n, 3))
    r = np.empty((len(sets), n, 3))
    for i, s in enumerate(sets):
        S[i], r[i] = reflected_rays(camera, shape, rows[i], cols[i], s.centre_mm, s.radius_mm)
    P = np.empty((n, 3))
    dist = np.empty((n, len(sets)))
    for k in range(n):
        P[k], dist[k] = nearest_point(S[:, k], r[:, k])
    return P, dist


def calibrate_positions(sets, camera: Camera, *, window_px: int = WINDOW_PX) -> tuple[np.ndarray, dict]:
    """LED positions from two or more mirror-sphere calibration sets.

    Parameters
    ----------
    sets : sequence of SphereImages
        Two or more sets, each with one image per LED in the same light order and size.
    camera : Orthographic or Perspective
    window_px : int, optional
        Highlight centroid window (:func:`highlight_centroids`).

    Returns
    -------
    positions : numpy.ndarray, shape (N, 3)
        LED positions, mm.
    info : dict
        ``method``, ``sets`` (source, centre, radius, where the centre came from),
        ``highlights_px`` (per set, per LED: row, col), ``residuals_mm`` (per LED, the
        distances of its rays to the point), ``rms_residual_mm``,
        ``uncertainty_mm`` (per LED, standard deviation of x, y, z from the
        centroids' noise) and ``centroid_sigma_px``.

    Raises
    ------
    ValueError
        Fewer than two sets, different image counts or sizes, missing highlights,
        parallel rays.
    """
    sets = list(sets)
    if len(sets) < 2:
        raise InputError(f"spheres: need at least 2 calibration sets (spheres at different places or "
                         f"heights), got {len(sets)}")
    if not isinstance(camera, (Orthographic, Perspective)):
        raise InputError(f"camera: expected Orthographic or Perspective, got {type(camera).__name__}")
    n, shape = sets[0].images.shape[0], sets[0].images.shape[1:3]
    for s in sets[1:]:
        if s.images.shape[0] != n:
            raise InputError(f"spheres: {s.source or 'a set'} has {s.images.shape[0]} images, "
                             f"{sets[0].source or 'the first'} has {n} (one per LED in each)")
        if s.images.shape[1:3] != shape:
            raise InputError(f"spheres: {s.source or 'a set'} images are {s.images.shape[1:3]}, "
                             f"{sets[0].source or 'the first'} {shape}")
    if n < 3:
        raise InputError(f"spheres: need images of at least 3 LEDs, got {n}")
    found = [highlight_centroids(s.images, camera, s.centre_mm, s.radius_mm, window_px=window_px) for s in sets]
    rows = np.stack([f[0] for f in found])
    cols = np.stack([f[1] for f in found])
    sigma = np.stack([f[2] for f in found])
    P, dist = _positions(sets, camera, shape, rows, cols)
    # linear propagation of every centroid's noise (central differences of the whole construction)
    var = np.zeros((n, 3))
    var_dist = np.zeros_like(dist)  # the residuals' spread from the same noise, by the same differences
    eps = 0.05
    for i in range(len(sets)):
        for which in (rows, cols):
            plus, minus = which.copy(), which.copy()
            plus[i] += eps
            minus[i] -= eps
            args_p = (plus, cols) if which is rows else (rows, plus)
            args_m = (minus, cols) if which is rows else (rows, minus)
            (P_p, d_p), (P_m, d_m) = _positions(sets, camera, shape, *args_p), _positions(sets, camera, shape, *args_m)
            var += ((P_p - P_m) / (2 * eps) * sigma[i][:, None]) ** 2
            var_dist += ((d_p - d_m) / (2 * eps) * sigma[i][:, None]) ** 2
    rms, expected = float(np.sqrt(np.mean(dist**2))), float(np.sqrt(np.mean(var_dist)))
    if rms > RESIDUAL_FACTOR * expected:
        floating = [s.source for s in sets if s.centre_from == "outline"]
        raise InputError(
            f"spheres: the LEDs' reflected rays do not meet: rms residual {rms:.3g} mm, about {expected:.2g} mm "
            f"expected from the highlight noise; a sphere's radius or centre is wrong (check radius_mm and "
            f"center_mm in sphere.json"
            + (f"; {', '.join(floating)} without sphere.json is taken to rest on the reference plane: a sphere "
               "above it needs sphere.json" if floating else "") + ")")
    info = {
        "method": "mirror spheres: highlight centroid, reflected ray 2(n.v)n - v, least-squares nearest point",
        "sets": [{"source": s.source, "centre_mm": s.centre_mm.tolist(), "radius_mm": s.radius_mm,
                  "centre_from": s.centre_from} for s in sets],
        "highlights_px": np.stack([rows, cols], axis=2).tolist(),
        "residuals_mm": dist.tolist(),
        "rms_residual_mm": rms,
        "expected_residual_mm": expected,
        "uncertainty_mm": np.sqrt(var).tolist(),
        "centroid_sigma_px": sigma.tolist(),
    }
    return P, info


def calibrate_rig(*, spheres=None, light_positions=None, camera: Camera | None = None, flat_field=None,
                  flat_albedo: float | None = None, led_mu=None, intensities=None, window_px: int | None = None):
    """A calibrated rig from mirror spheres (or known LED positions) and optional flat-field images.

    Parameters
    ----------
    spheres : sequence of str, Path or SphereImages, optional
        Two or more calibration sets (:func:`read_sphere_set`).
    light_positions : str, Path or array_like, shape (N, 3), optional
        Known LED positions (mm) instead of spheres; then ``flat_field`` gives the
        image size.
    camera : Orthographic or Perspective, optional
        Default: the first sphere folder's ``scene.json`` camera.
    flat_field : sequence of paths or array_like (N, H, W[, 3]), optional
        Flat-field images, one per light (:func:`photometric.rig.flat_field_gains`).
    flat_albedo : float, optional
        The flat target's albedo (default 1).
    led_mu : float or array_like, optional
        LED lobe exponents (unknown when omitted).
    intensities : str, Path, float or array_like, optional
        LED intensities to store.
    window_px : int, optional
        Highlight window (:func:`highlight_centroids`).

    Returns
    -------
    photometric.rig.Rig
    """
    from photometric.io import load_intensities, load_light_positions, read_images
    from photometric.leds import point_lights
    from photometric.lights import as_intensities
    from photometric.rig import FLAT_SMOOTHING_PX, Rig, flat_field_gains
    from photometric.stereo import _check_images

    if (spheres is None) == (light_positions is None):
        raise InputError("spheres: give either mirror-sphere folders (--spheres) or --light-positions")
    flats = None
    if flat_field is not None:
        if isinstance(flat_field, (list, tuple)) and all(isinstance(f, (str, Path)) for f in flat_field):
            flats = read_images(list(flat_field))
        else:
            flats = _check_images(flat_field)
    if spheres is not None:
        sets = []
        for item in spheres:
            if isinstance(item, SphereImages):
                sets.append(item)
            else:
                found, camera = read_sphere_set(item, camera)
                sets.append(found)
        if camera is None:
            raise InputError("camera: the sphere folders state no camera; give --camera with --pixel-size, or "
                             "--focal-length-px and --camera-height")
        positions, info = calibrate_positions(sets, camera, window_px=window_px or WINDOW_PX)
        shape = sets[0].images.shape[1:3]
    else:
        positions = load_light_positions(light_positions) if isinstance(light_positions, (str, Path)) else \
            point_lights(light_positions).positions
        if flats is None:
            raise InputError("flat_field: with --light-positions the rig needs flat-field images (they give its "
                             "gains and image size)")
        if camera is None:
            raise InputError("camera: give --camera with --pixel-size, or --focal-length-px and --camera-height")
        info = {"method": "known LED positions"}
        shape = flats.shape[1:3]
    lights = point_lights(positions, mu=led_mu)
    n = len(lights)
    gains, albedo, smoothing = None, None, 0.0
    if flats is not None:
        if flats.shape[0] != n:
            raise InputError(f"flat_field: {flats.shape[0]} flat-field image(s) for {n} lights (one per light)")
        if flats.shape[1:3] != tuple(shape):
            raise InputError(f"flat_field: flat-field images are {flats.shape[1]} x {flats.shape[2]} px, the "
                             f"sphere images {shape[0]} x {shape[1]} px")
        albedo = 1.0 if flat_albedo is None else positive(flat_albedo, "flat_albedo")
        smoothing = FLAT_SMOOTHING_PX
        gains = flat_field_gains(flats, lights, camera, albedo, smoothing_px=smoothing)
    intens = None
    if intensities is not None:
        intens = load_intensities(intensities, n) if isinstance(intensities, (str, Path)) else \
            as_intensities(intensities, n)
    return Rig(lights, camera, (int(shape[0]), int(shape[1])), intens, gains, albedo, smoothing, info)


# ----------------------------------------------------------------------------- distant lights from one sphere


def sphere_from_mask(mask) -> tuple[float, float, float]:
    """Circle of a sphere's silhouette from its binary mask (area and centroid).

    Parameters
    ----------
    mask : array_like, shape (H, W)
        True on the sphere.

    Returns
    -------
    row, col, radius : float
        Centre in pixel indices (pixel centres at integers) and radius in pixels,
        ``r = sqrt(area / pi)``; both moments are unbiased for a digitised disc.
    """
    m = as_array(mask, "mask", ndim=2, dtype=bool)
    area = int(m.sum())
    if area < 20:
        raise InputError(f"mask: sphere silhouette has only {area} pixels")
    rows, cols = np.nonzero(m)
    return float(rows.mean()), float(cols.mean()), float(np.sqrt(area / np.pi))


def calibrate_mirror_sphere(
    images, mask, *, threshold: float = 0.8
) -> tuple[np.ndarray, dict]:
    """Light directions from images of a mirror (chrome) sphere.

    For each image the specular highlight's intensity-weighted centroid ``(r, c)``
    inside the sphere gives the sphere normal there,
    ``n = ((c - c0) / R, -(r - r0) / R, sqrt(1 - n_x^2 - n_y^2))`` (y up), and the
    light is the mirror reflection of the view direction ``v = (0, 0, 1)``:
    ``l = 2 (n . v) n - v`` (returning ``n`` itself is the classic bug).

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, C)
        Images of the sphere, one per light; colour is averaged to grey.
    mask : array_like, shape (H, W)
        Sphere silhouette (True inside).
    threshold : float, optional
        Pixels above ``threshold * max`` of each image (inside the mask) form the
        highlight.

    Returns
    -------
    lights : numpy.ndarray, shape (N, 3), float64
        Unit light directions in the convention of :data:`photometric.lights.CONVENTION`.
    info : dict
        ``center_rc`` (row, col), ``radius_px``, ``highlights_rc`` (N, 2) list.
    """
    imgs = as_array(images, "images", ndim=(3, 4), dtype=np.float32)
    if imgs.ndim == 4:
        imgs = imgs.mean(axis=3)
    m = as_array(mask, "mask", shape=imgs.shape[1:], dtype=bool)
    if not 0 < threshold < 1:
        raise InputError(f"threshold: must lie in (0, 1), got {threshold}")
    r0, c0, radius = sphere_from_mask(m)
    inside = np.where(m[None], imgs, 0.0)
    peak = inside.reshape(len(imgs), -1).max(axis=1)
    if np.any(peak <= 0):
        raise InputError(f"images: no highlight inside the sphere in image(s) {np.flatnonzero(peak <= 0).tolist()}")
    weight = np.clip(inside - threshold * peak[:, None, None], 0.0, None)
    rows = np.arange(m.shape[0], dtype=np.float64)[None, :, None]
    cols = np.arange(m.shape[1], dtype=np.float64)[None, None, :]
    total = weight.sum(axis=(1, 2), dtype=np.float64)
    hr = (weight * rows).sum(axis=(1, 2), dtype=np.float64) / total
    hc = (weight * cols).sum(axis=(1, 2), dtype=np.float64) / total
    nx = (hc - c0) / radius
    ny = -(hr - r0) / radius
    rr = nx**2 + ny**2
    if np.any(rr >= 1.0):
        raise InputError(f"images: highlight outside the sphere circle in image(s) {np.flatnonzero(rr >= 1).tolist()}")
    n = np.stack([nx, ny, np.sqrt(1.0 - rr)], axis=1)
    v = np.array([0.0, 0.0, 1.0])
    lights = 2.0 * (n @ v)[:, None] * n - v
    info = {
        "center_rc": [r0, c0],
        "radius_px": radius,
        "highlights_rc": np.stack([hr, hc], axis=1).tolist(),
    }
    return lights / np.linalg.norm(lights, axis=1, keepdims=True), info
