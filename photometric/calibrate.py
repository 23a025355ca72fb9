"""LED positions from images of mirror spheres (near-field rig calibration), and distant
light directions from one mirror sphere (:func:`calibrate_mirror_sphere`).

A calibration set is one image per LED of a polished sphere of known radius ``R`` and
centre ``c`` (``sphere.json``, rig frame, mm), or of a sphere found by its outline and
taken to rest on the reference plane (``c_z = R``). For each image:

1. the specular highlight: the brightest spot inside the sphere's disc; its sub-pixel
   position is the peak of a 2-D Gaussian fitted to the spot (a quadric fitted to the log
   of the intensity above the local background over the 3 x 3 pixels around the peak,
   weighted by the intensity), or, for a spot too sharp to fit (within one pixel), the
   intensity-weighted centroid with the uncertainty of a position known only to its pixel;
2. the camera ray through the centroid meets the sphere at ``S``; the sphere normal
   there is ``n = (S - c) / R``, the direction to the camera ``v`` (``(0, 0, 1)`` for an
   orthographic camera, ``(C - S) / |C - S|`` for a perspective one);
3. the LED lies on the reflected ray ``S + t r``, ``r = 2 (n . v) n - v``
   (returning ``n`` itself is the classic bug).

With two or more sets (spheres at different places, or one sphere at two known
heights) each LED is the least-squares nearest point of its rays,
``(sum_i (I - r_i r_i^T)) P = sum_i (I - r_i r_i^T) S_i``; each ray's distance to it is
its residual. The uncertainty propagates each highlight's noise (estimated from the image
noise around the highlight, at least a floor for the spot model's own error) through the
whole construction (the Jacobian of ``P`` with respect to every highlight, by central
differences), then is scaled by the Birge ratio of the rays' own residuals,
``max(1, sqrt(chi2 / dof))``, pooled over all LEDs (``dof = N (2 K - 3)``: each ray's
residual is a 2-vector, each LED 3 unknowns), so that misses the noise does not explain
(a lens not corrected, a sphere slightly off) widen the stated u instead of being
ignored. A warning is given when the ratio exceeds what chi2 allows at the 1 % level.
The covariance of each LED is also reported along its mean reflected ray and across it
(the along-ray part is the triangulation's weak direction) with advice on where to
place the spheres.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from photometric.camera import Camera, Orthographic, Perspective, camera_from_dict, pixel_offsets, pixel_rays
from surfaces.validate import as_array, InputError, positive, reads_file

__all__ = ["SphereImages", "read_sphere_set", "sphere_from_outline", "highlight_centroids", "fit_spot",
           "reflected_rays", "nearest_point", "birge_check", "calibrate_positions", "calibrate_rig", "sphere_from_mask",
           "calibrate_mirror_sphere"]

#: Half width (pixels) of the window around the highlight peak.
WINDOW_PX = 4
#: Smallest highlight uncertainty assumed (pixels) for a spot the Gaussian model fits, added in quadrature
#: to the fit's own (noise and misfit) uncertainty: the sampling of a highlight the fit cannot see.
#: Noise-free pixel-integrated Gaussians 0.5-1.5 px wide give 0.004-0.0001 px; rendered LED discs
#: (datasets_synthetic.spheres, lens blur 1 px) 0.003-0.008 px, 0.004-0.01 px after an undistortion by
#: bicubic resampling (bilinear: 0.01-0.04 px, a bias). A spot within one pixel gets SHARP_SIGMA_PX.
MIN_CENTROID_SIGMA_PX = 0.01
#: Uncertainty of a highlight too sharp for the fit (all its light in about one pixel): its position is
#: known to its pixel, a uniform distribution of width 1 px, standard deviation 1 / sqrt(12).
SHARP_SIGMA_PX = 1.0 / np.sqrt(12.0)
#: A fitted Gaussian narrower than this (standard deviation, pixels) is taken as too sharp to locate
#: better than its pixel: below 0.5 px the log-quadric's peak is biased by up to 0.2 px (0.3 px wide)
#: or 0.7 px (0.2 px wide) with the sub-pixel phase.
SHARP_WIDTH_PX = 0.5
#: chi2 / dof of the rays' residuals above its 99 % quantile: the warning that the stated u does not
#: explain the residuals (the u is scaled by the Birge ratio either way).
BIRGE_QUANTILE = 0.99
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
    """Sub-pixel highlight positions inside a sphere's image disc.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        One image per LED (of a distortion-free camera: undistort them first).
    camera : Orthographic or Perspective
    centre_mm : array_like, shape (3,)
    radius_mm : float
    window_px : int, optional
        Half width of the window around the peak (background, noise, fallback centroid).

    Returns
    -------
    rows, cols : numpy.ndarray, shape (N,), float64
        The peak of a 2-D Gaussian fitted to ``I - background`` around the brightest pixel
        (:func:`fit_spot`; pixel centres at integers); the background is the median of the
        window's border. A spot too sharp for the fit gives the intensity-weighted centroid
        of the window.
    sigma_px : numpy.ndarray, shape (N,), float64
        Their standard uncertainty (pixels): the fit's propagation of the border's noise (or
        of the fit's misfit when larger) and :data:`MIN_CENTROID_SIGMA_PX` in quadrature;
        :data:`SHARP_SIGMA_PX` for a sharp spot's centroid.

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
        fitted = fit_spot(win - bg, noise)
        if fitted is not None:
            rows[i], cols[i], sig[i] = lo_r + fitted[0], lo_c + fitted[1], float(np.hypot(MIN_CENTROID_SIGMA_PX,
                                                                                              fitted[2]))
        else:
            yy, xx = np.mgrid[lo_r:hi_r, lo_c:hi_c]
            rows[i] = float((weight * yy).sum() / total)
            cols[i] = float((weight * xx).sum() / total)
            sig[i] = SHARP_SIGMA_PX
        if (rows[i] - r0) ** 2 + (cols[i] - c0) ** 2 >= (0.98 * rad) ** 2:
            raise InputError(f"images: the highlight of image {i} is at the rim of the sphere's disc")
    return rows, cols, sig


def fit_spot(window, noise: float = 0.0) -> tuple[float, float, float, float] | None:
    """Peak of a 2-D Gaussian fitted to a bright spot (sub-pixel), or None when the spot is too sharp.

    ``log v = a + b y + c x + d y^2 + e x^2 + f x y`` is fitted by least squares to the 3 x 3
    pixels around the brightest one, each weighted by its value ``v`` (the log's noise is
    ``noise / v``); the peak is where the quadric's gradient vanishes.

    Parameters
    ----------
    window : array_like, shape (h, w)
        Spot values above the background (at least 3 x 3; the brightest pixel not on the
        border).
    noise : float, optional
        Standard deviation of each value (image units), for the peak's uncertainty.

    Returns
    -------
    (row, col, sigma_px, width_px) or None
        Peak position in the window's pixel indices, its standard uncertainty (pixels,
        root mean of the two axes' variances, propagated from ``noise`` or from the fit's
        own residual scatter when larger; 0 for an exact Gaussian without noise) and the fitted Gaussian's
        smaller standard deviation (pixels). None when fewer than 6 of the 9 values exceed
        twice the noise, the quadric has no maximum, the peak falls more than one pixel from
        the brightest pixel, or the spot is narrower than :data:`SHARP_WIDTH_PX`.

    Examples
    --------
    >>> yy, xx = np.mgrid[0:7, 0:7]
    >>> spot = np.exp(-((yy - 3.3) ** 2 + (xx - 2.8) ** 2) / (2 * 1.2**2))
    >>> [round(v, 6) for v in fit_spot(spot)]
    [3.3, 2.8, 0.0, 1.2]
    """
    win = as_array(window, "window", ndim=2)
    h, w = win.shape
    pr, pc = np.unravel_index(int(np.argmax(win)), win.shape)
    if not (0 < pr < h - 1 and 0 < pc < w - 1):
        return None
    v = win[pr - 1:pr + 2, pc - 1:pc + 2].ravel()
    y, x = (a.ravel().astype(np.float64) for a in np.mgrid[-1:2, -1:2])
    ok = v > max(2.0 * float(noise), 1e-12 * float(v.max()))
    if ok.sum() < 6 or not (ok[[1, 7]].any() and ok[[3, 5]].any()):
        return None
    y, x, v = y[ok], x[ok], v[ok]
    A = np.stack([np.ones_like(x), y, x, y * y, x * x, x * y], axis=1) * v[:, None]
    theta, _, rank, _ = np.linalg.lstsq(A, np.log(v) * v, rcond=None)
    if rank < 6:
        return None
    H = np.array([[2.0 * theta[3], theta[5]], [theta[5], 2.0 * theta[4]]])
    eig = np.linalg.eigvalsh(H)
    if eig[-1] >= 0:
        return None
    peak = -np.linalg.solve(H, theta[1:3])
    width = float(np.sqrt(-1.0 / eig[0]))  # the narrower axis: log v = -x^2 / (2 s^2), curvature -1/s^2
    if np.abs(peak).max() > 1.0 or width < SHARP_WIDTH_PX:
        return None
    sigma = 0.0
    # the values' noise, or the fit's own misfit when larger (a spot that is not quite a Gaussian): the
    # weighted residuals are in image units, like the noise
    misfit = np.sum((A @ theta - np.log(v) * v) ** 2)
    scatter = float(np.sqrt(misfit / (len(v) - 6))) if len(v) > 6 else 0.0
    noise = max(float(noise), scatter)
    if noise > 0:
        # d peak = -H^-1 (d g + d H peak), g = (b, c): the peak's Jacobian in the six coefficients
        Hi = np.linalg.inv(H)
        J = np.zeros((2, 6))
        J[:, 1], J[:, 2] = -Hi[:, 0], -Hi[:, 1]
        J[:, 3] = -Hi[:, 0] * 2.0 * peak[0]
        J[:, 4] = -Hi[:, 1] * 2.0 * peak[1]
        J[:, 5] = -(Hi[:, 0] * peak[1] + Hi[:, 1] * peak[0])
        cov = np.linalg.inv(A.T @ A) * float(noise) ** 2  # rows weighted by v: unit-variance log residuals
        sigma = float(np.sqrt(np.trace(J @ cov @ J.T) / 2.0))
    return float(pr + peak[0]), float(pc + peak[1]), sigma, width


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


def _positions(sets, camera, shape, rows, cols) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """LED positions (N, 3), ray distances (N, K), residual vectors (N, K, 3) (from each ray's closest
    point to the LED) and the reflected rays' unit directions (N, K, 3) from highlights (K, N)."""
    n = rows.shape[1]
    S = np.empty((len(sets), n, 3))
    r = np.empty((len(sets), n, 3))
    for i, s in enumerate(sets):
        S[i], r[i] = reflected_rays(camera, shape, rows[i], cols[i], s.centre_mm, s.radius_mm)
    P = np.empty((n, 3))
    dist = np.empty((n, len(sets)))
    for k in range(n):
        P[k], dist[k] = nearest_point(S[:, k], r[:, k])
    gap = P[None] - S  # (K, N, 3)
    resid = gap - np.einsum("kni,kni->kn", gap, r)[..., None] * r
    return P, dist, resid.transpose(1, 0, 2), r.transpose(1, 0, 2)


def calibrate_positions(sets, camera: Camera, *, window_px: int = WINDOW_PX, pixel_sigma_px: float = 0.0,
                        principal_point_sigma_px=0.0, focal_length_sigma_px: float = 0.0) -> tuple[np.ndarray, dict]:
    """LED positions from two or more mirror-sphere calibration sets.

    Parameters
    ----------
    sets : sequence of SphereImages
        Two or more sets, each with one image per LED in the same light order and size.
    camera : Orthographic or Perspective
    window_px : int, optional
        Highlight centroid window (:func:`highlight_centroids`).
    pixel_sigma_px : float, optional
        A further standard uncertainty of every highlight position (pixels), added in
        quadrature: the lens calibration's error where the images were undistorted (e.g.
        the checkerboard's RMS reprojection error). Default 0.
    principal_point_sigma_px : float or (float, float), optional
        Standard uncertainty of the camera's principal point (column, row), pixels (e.g.
        OpenCV's ``stdDeviationsIntrinsics`` of a checkerboard calibration); propagated as a
        shift common to every highlight (it tilts every camera ray alike). Default 0.
    focal_length_sigma_px : float, optional
        Standard uncertainty of a perspective camera's focal length, pixels (the same
        source); propagated through the whole construction. Default 0.

    Returns
    -------
    positions : numpy.ndarray, shape (N, 3)
        LED positions, mm.
    info : dict
        ``method``, ``sets`` (source, centre, radius, where the centre came from),
        ``highlights_px`` (per set, per LED: row, col), ``residuals_mm`` (per LED, the
        distances of its rays to the point), ``rms_residual_mm``,
        ``uncertainty_mm`` (per LED, standard uncertainty of x, y, z: the highlights'
        noise propagated, times ``uncertainty_scale``), ``uncertainty_from_noise_mm`` (before
        the scale), ``covariance_mm2`` (per LED, 3 x 3, scaled), ``birge_ratio``,
        ``birge_bound`` (its 99 % quantile), ``chi2``, ``dof``, ``uncertainty_scale``
        (``max(1, birge_ratio)``), ``centroid_sigma_px`` (per set, per LED),
        ``sensitivity`` (per LED: ``along_ray_mm``, ``across_ray_mm``, ``ray_direction``,
        ``ray_angle_deg``), ``advice`` and ``warnings`` (lists of sentences).

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
    sigma = np.hypot(np.stack([f[2] for f in found]), positive(pixel_sigma_px, "pixel_sigma_px", allow_zero=True))
    P, dist, resid, rays = _positions(sets, camera, shape, rows, cols)
    # linear propagation of every highlight's noise (central differences of the whole construction): the
    # LEDs' covariances and the expected squared residual vectors
    cov = np.zeros((n, 3, 3))
    expect = np.zeros(dist.shape)  # E |e|^2 per LED and ray
    eps = 0.05
    for i in range(len(sets)):
        for which in (rows, cols):
            plus, minus = which.copy(), which.copy()
            plus[i] += eps
            minus[i] -= eps
            args_p = (plus, cols) if which is rows else (rows, plus)
            args_m = (minus, cols) if which is rows else (rows, minus)
            (P_p, _, e_p, _), (P_m, _, e_m, _) = (_positions(sets, camera, shape, *args_p),
                                                  _positions(sets, camera, shape, *args_m))
            dP = (P_p - P_m) / (2 * eps) * sigma[i][:, None]
            cov += dP[:, :, None] * dP[:, None, :]
            expect += np.sum(((e_p - e_m) / (2 * eps) * sigma[i][:, None, None]) ** 2, axis=2)
    pp_sigma = np.broadcast_to(np.asarray(principal_point_sigma_px, np.float64), (2,))
    if np.any(pp_sigma < 0) or not np.all(np.isfinite(pp_sigma)):
        raise InputError(f"principal_point_sigma_px: expected values >= 0, got {principal_point_sigma_px!r}")
    f_sigma = positive(focal_length_sigma_px, "focal_length_sigma_px", allow_zero=True)
    if f_sigma > 0 and isinstance(camera, Perspective):
        h_f = 1e-3 * camera.focal_length_px
        (P_p, _, e_p, _), (P_m, _, e_m, _) = (
            _positions(sets, replace(camera, focal_length_px=camera.focal_length_px + h_f), shape, rows, cols),
            _positions(sets, replace(camera, focal_length_px=camera.focal_length_px - h_f), shape, rows, cols))
        dP = (P_p - P_m) / (2 * h_f) * f_sigma
        cov += dP[:, :, None] * dP[:, None, :]
        expect += np.sum(((e_p - e_m) / (2 * h_f) * f_sigma) ** 2, axis=2)
    for which, sd in ((cols, pp_sigma[0]), (rows, pp_sigma[1])):
        if sd > 0:  # every highlight of every set moves alike
            (P_p, _, e_p, _), (P_m, _, e_m, _) = (
                _positions(sets, camera, shape, *((rows, cols + eps) if which is cols else (rows + eps, cols))),
                _positions(sets, camera, shape, *((rows, cols - eps) if which is cols else (rows - eps, cols))))
            dP = (P_p - P_m) / (2 * eps) * sd
            cov += dP[:, :, None] * dP[:, None, :]
            expect += np.sum(((e_p - e_m) / (2 * eps) * sd) ** 2, axis=2)
    rms, expected = float(np.sqrt(np.mean(dist**2))), float(np.sqrt(np.mean(expect)))
    if rms > RESIDUAL_FACTOR * expected:
        floating = [s.source for s in sets if s.centre_from == "outline"]
        raise InputError(
            f"spheres: the LEDs' reflected rays do not meet: rms residual {rms:.3g} mm, about {expected:.2g} mm "
            f"expected from the highlight noise; a sphere's radius or centre is wrong (check radius_mm and "
            f"center_mm in sphere.json"
            + (f"; {', '.join(floating)} without sphere.json is taken to rest on the reference plane: a sphere "
               "above it needs sphere.json" if floating else "") + ", or the lens distortion is not corrected)")
    honest = birge_check(dist, expect)
    scaled = cov * honest["scale"] ** 2
    sens, advice = _sensitivity(scaled, rays, sets)
    notes = []
    if honest["exceeds"]:
        notes.append(
            f"spheres: the rays miss each other by more than the highlight noise allows (rms {rms:.3g} mm, "
            f"{expected:.2g} mm expected; Birge ratio {honest['birge_ratio']:.2f} above the 99 % bound "
            f"{honest['bound']:.2f} for {honest['dof']} degrees of freedom): the stated uncertainty is scaled by "
            f"{honest['scale']:.2f}; check the lens distortion (--checkerboard), the spheres' radius and centre")
        warnings.warn(notes[-1], UserWarning, stacklevel=2)
    info = {
        "method": "mirror spheres: highlight from a 2-D Gaussian fit, reflected ray 2(n.v)n - v, least-squares "
                  "nearest point; u scaled by the Birge ratio of the rays' residuals",
        "sets": [{"source": s.source, "centre_mm": s.centre_mm.tolist(), "radius_mm": s.radius_mm,
                  "centre_from": s.centre_from} for s in sets],
        "highlights_px": np.stack([rows, cols], axis=2).tolist(),
        "residuals_mm": dist.tolist(),
        "rms_residual_mm": rms,
        "expected_residual_mm": expected,
        "uncertainty_mm": np.sqrt(np.einsum("kii->ki", scaled)).tolist(),
        "uncertainty_from_noise_mm": np.sqrt(np.einsum("kii->ki", cov)).tolist(),
        "covariance_mm2": scaled.tolist(),
        "uncertainty_note": "standard uncertainty u (k = 1) per axis: the highlights' noise propagated, times "
                            "max(1, Birge ratio); U = 2 u covers about 95 %",
        "birge_ratio": honest["birge_ratio"],
        "birge_bound": honest["bound"],
        "chi2": honest["chi2"],
        "dof": honest["dof"],
        "uncertainty_scale": honest["scale"],
        "centroid_sigma_px": sigma.tolist(),
        "sensitivity": sens,
        "advice": advice,
        "warnings": notes,
    }
    return P, info


def birge_check(distances, expected_sq) -> dict:
    """The Birge ratio of the rays' residuals against what the highlights' noise explains.

    Parameters
    ----------
    distances : array_like, shape (N, K)
        Each LED's ray residuals (distance of each ray to the LED), mm.
    expected_sq : array_like, shape (N, K)
        Their expected squares from the propagated highlight noise, mm^2.

    Returns
    -------
    dict
        ``chi2`` (sum of squared residuals over the expected, rescaled to ``dof``),
        ``dof`` (``N (2 K - 3)``), ``birge_ratio`` ``sqrt(chi2 / dof)``, ``bound`` (the
        ratio's 99 % quantile for ``dof``), ``exceeds`` (ratio above the bound) and
        ``scale`` = ``max(1, birge_ratio)``, the factor for the stated u.

    Examples
    --------
    >>> r = birge_check(np.full((4, 2), 0.3), np.full((4, 2), 0.01))
    >>> round(r["birge_ratio"], 3), r["dof"], r["exceeds"], round(r["scale"], 3)
    (3.0, 4, True, 3.0)
    """
    from scipy.stats import chi2 as chi2_dist

    d = as_array(distances, "distances", ndim=2)
    e = as_array(expected_sq, "expected_sq", shape=d.shape)
    n, k = d.shape
    dof = n * (2 * k - 3)
    total = float(e.sum())
    if dof < 1 or total <= 0:
        return {"chi2": None, "dof": dof, "birge_ratio": None, "bound": None, "exceeds": False, "scale": 1.0}
    # sum |e|^2 / E sum |e|^2 is chi2 / dof for residuals that the noise explains
    ratio2 = float(np.sum(d**2)) / total
    bound = float(np.sqrt(chi2_dist.ppf(BIRGE_QUANTILE, dof) / dof))
    ratio = float(np.sqrt(ratio2))
    return {"chi2": ratio2 * dof, "dof": int(dof), "birge_ratio": ratio, "bound": bound,
            "exceeds": bool(ratio > bound), "scale": max(1.0, ratio)}


#: Along-ray u above this many times the across-ray u: advise a wider sphere placement.
ALONG_RAY_FACTOR = 3.0


def _sensitivity(cov: np.ndarray, rays: np.ndarray, sets) -> tuple[list, list]:
    """Per LED: u along and across its mean reflected ray, the widest angle between its rays; advice."""
    out, weak = [], []
    for k in range(len(cov)):
        a = rays[k].sum(axis=0)
        a /= np.linalg.norm(a)
        along = float(np.sqrt(max(a @ cov[k] @ a, 0.0)))
        across = float(np.sqrt(max(np.trace(cov[k]) - along**2, 0.0) / 2.0))
        cosines = np.clip(rays[k] @ rays[k].T, -1.0, 1.0)
        angle = float(np.degrees(np.arccos(cosines.min())))
        out.append({"along_ray_mm": along, "across_ray_mm": across, "ray_direction": a.tolist(),
                    "ray_angle_deg": angle})
        if along > ALONG_RAY_FACTOR * max(across, 1e-12):
            weak.append(k)
    advice = []
    if weak:
        angles = [out[k]["ray_angle_deg"] for k in weak]
        advice.append(
            f"LEDs {', '.join(str(k) for k in weak)}: the uncertainty along the ray towards the LED is more than "
            f"{ALONG_RAY_FACTOR:g} times the one across it (their rays meet at {min(angles):.1f}-{max(angles):.1f} "
            "deg): place the spheres farther apart across the field, or at clearly different heights, so that "
            "each LED's rays cross at a wider angle")
    if len(sets) == 2:
        advice.append("two sphere placements give each LED one degree of freedom per pair of rays to check the "
                      "fit; a third placement (away from the line through the first two) makes the residual "
                      "check and the Birge ratio far more reliable")
    return out, advice


def calibrate_rig(*, spheres=None, light_positions=None, camera: Camera | None = None, flat_field=None,
                  flat_albedo: float | None = None, led_mu=None, intensities=None, window_px: int | None = None,
                  pixel_sigma_px: float = 0.0, principal_point_sigma_px=0.0, focal_length_sigma_px: float = 0.0):
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
    pixel_sigma_px, principal_point_sigma_px, focal_length_sigma_px : optional
        The lens calibration's own uncertainty, propagated into the LED positions'
        (:func:`calibrate_positions`; e.g. a checkerboard's RMS reprojection error and
        OpenCV's standard deviations of the principal point and focal length). Default 0.

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
        positions, info = calibrate_positions(sets, camera, window_px=window_px or WINDOW_PX,
                                              pixel_sigma_px=pixel_sigma_px,
                                              principal_point_sigma_px=principal_point_sigma_px,
                                              focal_length_sigma_px=focal_length_sigma_px)
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
