"""The working distance of a near-field rig from its images: the height that fits them best.

A near-field rig whose LEDs are fixed to the camera (positions known in the camera frame,
:mod:`photometric.importers`) still needs the camera's height ``H`` above the part's
reference plane. A wrong ``H`` puts every pixel's point at the wrong distance from the
LEDs, and the near-field solve (:func:`photometric.nearfield.solve_nearfield`) then bends
the surface (a bowl or a dome) to explain the falloff: the across-part depth changes
several-fold between ``H`` = 150, 200 and 300 mm on the real 8-LED capture
``nearps_hehe12``. The images tell ``H``: with the LEDs' radiant intensities fixed, the
Lambertian model at the right distance explains the images best.

:func:`estimate_camera_height` solves the near-field problem at several heights on a
block-averaged copy of the images and minimises the **photometric residual**: the RMS
over the valid pixels and the lights of ``I_k - albedo * max(0, s_k(X) . n)`` in image
units (full scale 1), ``s_k`` the LED's light vector at the solved point ``X`` with
``E_k = I_k^rad / |P_k - X|^2 ...`` (the radiant intensities ``e_k d0_k^2`` kept as ``H``
moves, :func:`photometric.rig.at_camera_height`; equal radiant intensities when the rig
has none). A coarse geometric grid brackets the lowest interior minimum, a bounded Brent search refines
it, and five heights around it (``+-2.5 %``, ``+-5 %``) give the curvature and the
uncertainty:

* ``u_curvature_mm``: the least-squares standard uncertainty ``sqrt(2 s^2 / SSR'')`` with
  ``SSR`` the residual sum of squares over all ``n`` observations and ``s^2 = SSR_min / n``;
  it treats the residuals as independent, so it is a lower bound where they are not
  (specular spots, shadows, a model error that spans many pixels).
* ``u_jackknife_mm``: the delete-one-block jackknife over eight equal-count blocks of the
  valid pixels along the part's longest axis: each block's part of the same solves, the
  minimum of the parabola through the five heights without it. It sees the spread that
  correlated model errors cause.

``u_mm`` is the larger. :func:`height_warning` says when a given height is far from the
estimate (outside its ``U = 2 u`` and more than 10 % away).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from photometric.camera import Perspective, make_camera
from photometric.leds import light_field
from photometric.options import MAX_ITERATIONS
from photometric.rig import Rig, at_camera_height
from surfaces.validate import as_array, InputError, positive

__all__ = ["DistanceEstimate", "WORKING_PIXELS", "BLOCKS", "FAR_FRACTION", "estimate_camera_height",
           "photometric_residual", "height_warning"]

#: Pixels of the block-averaged copy the search solves on (``binning = ceil(sqrt(H W / WORKING_PIXELS))``).
WORKING_PIXELS = 150_000
#: Spatial blocks of the jackknife.
BLOCKS = 8
#: A given height further than this fraction from the estimate (and outside its U) is warned about.
FAR_FRACTION = 0.10
#: Relative offsets of the five heights that give the curvature.
_LOCAL = np.array([-0.05, -0.025, 0.0, 0.025, 0.05])


@dataclass(frozen=True)
class DistanceEstimate:
    """What :func:`estimate_camera_height` found.

    Attributes
    ----------
    camera_height_mm : float
        The estimate of the camera's height above the reference plane, mm.
    u_mm : float
        Its standard uncertainty, mm: the larger of the two below.
    u_curvature_mm, u_jackknife_mm : float
        From the residual's curvature (independent residuals) and from the spatial jackknife.
    residual_rms : float
        The photometric residual at the estimate, image units (full scale 1).
    heights_mm, residuals_rms : numpy.ndarray, shape (K,)
        Every height solved and its residual, in the order solved.
    binning : int
        Block size of the averaged copy solved on, pixels.
    observations : int
        Lights times valid pixels of that copy at the estimate.
    intensities : str
        ``"rig"`` (the rig's radiant intensities) or ``"equal"`` (assumed).
    """

    camera_height_mm: float
    u_mm: float
    u_curvature_mm: float
    u_jackknife_mm: float
    residual_rms: float
    heights_mm: np.ndarray
    residuals_rms: np.ndarray
    binning: int
    observations: int
    intensities: str

    def to_dict(self) -> dict:
        """JSON-ready (``summary.json`` ``working_distance``, ``rig.json`` ``calibration``)."""
        return {"camera_height_mm": self.camera_height_mm, "u_mm": self.u_mm, "U_k2_mm": 2 * self.u_mm,
                "u_curvature_mm": self.u_curvature_mm, "u_jackknife_mm": self.u_jackknife_mm,
                "residual_rms": self.residual_rms, "heights_mm": self.heights_mm.tolist(),
                "residuals_rms": self.residuals_rms.tolist(), "binning": self.binning,
                "observations": self.observations, "intensities": self.intensities,
                "method": "minimum of the near-field photometric residual over the camera height "
                          "(photometric.distance)"}


def _binned(images: np.ndarray, mask: np.ndarray, b: int) -> tuple[np.ndarray, np.ndarray]:
    n, h, w = images.shape
    hb, wb = h // b, w // b
    if b == 1:
        return images, mask
    imgs = np.stack([cv2.resize(np.ascontiguousarray(x[:hb * b, :wb * b]), (wb, hb), interpolation=cv2.INTER_AREA)
                     for x in images])
    inside = cv2.resize(mask[:hb * b, :wb * b].astype(np.float32), (wb, hb), interpolation=cv2.INTER_AREA)
    return imgs, inside > 0.999


def _camera(cam: Perspective, b: int, height: float) -> Perspective:
    cx, cy = cam.principal_point_px
    return make_camera("perspective", focal_length_px=(cam.focal_length_px / b, cam.fy / b), camera_height_mm=height,
                       principal_point_px=((cx + 0.5) / b - 0.5, (cy + 0.5) / b - 0.5))


def photometric_residual(images, rig: Rig, camera_height_mm: float, *, mask=None, integrator: str = "lsq",
                         max_iterations: int = MAX_ITERATIONS, binning: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel squared photometric residual of a near-field solve with the camera at one height.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        Linear images, full scale 1 (ambient already subtracted); colour is averaged.
    rig : Rig
        A perspective rig without a flat field; it is moved to ``camera_height_mm``
        (:func:`photometric.rig.at_camera_height`).
    camera_height_mm : float
    mask : array_like, shape (H, W), optional
    integrator : str, optional
        The solve's integrator (default ``lsq``: the masked domain).
    max_iterations : int, optional
    binning : int, optional
        Block size of the averaged copy (1: full resolution).

    Returns
    -------
    sq : numpy.ndarray, shape (h, w)
        Sum over the lights of the squared residual, image units squared; NaN where the
        solve has no valid normal.
    valid : numpy.ndarray, shape (h, w), bool
    """
    from photometric.nearfield import solve_nearfield

    imgs, m = _grey_mask(images, mask)
    imgs, m = _binned(imgs, m, int(binning))
    moved = at_camera_height(rig, camera_height_mm)
    cam = _camera(moved.camera, int(binning), float(camera_height_mm))
    e = np.ones(len(moved.lights)) if moved.intensities is None else moved.intensities.mean(axis=1)
    res = solve_nearfield(imgs, moved.lights, cam, intensities=e, mask=m, integrator=integrator,
                          max_iterations=max_iterations, residual=False)
    v = res.valid
    X = np.concatenate([res.xy, res.height[..., None]], axis=-1)[v]
    S = light_field(moved.lights, X, e)
    albedo = res.albedo.mean(axis=-1) if res.albedo.ndim == 3 else res.albedo
    pred = albedo[v] * np.maximum(0.0, np.einsum("nkc,kc->nk", S, res.normals[v]))
    sq = np.full(v.shape, np.nan)
    sq[v] = np.sum((imgs[:, v] - pred) ** 2, axis=0)
    return sq, v


def _grey_mask(images, mask) -> tuple[np.ndarray, np.ndarray]:
    imgs = as_array(images, "images", ndim=(3, 4), dtype=np.float32)
    if imgs.ndim == 4:
        imgs = imgs.mean(axis=3, dtype=np.float32)
    m = np.ones(imgs.shape[1:3], bool) if mask is None else as_array(mask, "mask", shape=imgs.shape[1:3]) != 0
    if not m.any():
        raise InputError("mask: no pixel is selected")
    return imgs, m


def _vertex(h: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """Vertex and second derivative of the least-squares parabola through (h, f)."""
    a, b, _ = np.polyfit(h, f, 2)
    return (-b / (2 * a) if a > 0 else float("nan")), 2 * a


def estimate_camera_height(images, rig: Rig, *, mask=None, bounds_mm=None, integrator: str = "lsq",
                           max_iterations: int = MAX_ITERATIONS, binning: int | None = None,
                           grid: int = 11) -> DistanceEstimate:
    """Estimate the camera's height above the reference plane from the photometric residual.

    Parameters
    ----------
    images : array_like, shape (N, H, W) or (N, H, W, 3)
        Linear images, full scale 1, ambient subtracted; one per LED of ``rig``.
    rig : Rig
        A perspective rig without a flat field (its own camera height is only the start
        of the frame; the LEDs move with the camera).
    mask : array_like, shape (H, W), optional
        The part.
    bounds_mm : (float, float), optional
        Heights searched, mm (default: 1.2 to 6 times the LEDs' largest depth in front of
        the camera).
    integrator : str, optional
    max_iterations : int, optional
    binning : int, optional
        Block size of the averaged copy (default ``ceil(sqrt(H W / WORKING_PIXELS))``).
    grid : int, optional
        Heights of the coarse geometric grid.

    Returns
    -------
    DistanceEstimate

    Raises
    ------
    InputError
        An orthographic rig, a flat field, images that do not match, or a residual without
        a minimum inside the bounds (the data do not tell the height there).
    """
    from scipy.optimize import minimize_scalar

    if not isinstance(rig.camera, Perspective):
        raise InputError("working distance: an orthographic (telecentric) rig has no camera height to estimate")
    imgs, m = _grey_mask(images, mask)
    if imgs.shape[0] != len(rig.lights):
        raise InputError(f"working distance: {imgs.shape[0]} images for {len(rig.lights)} LEDs")
    h, w = imgs.shape[1:]
    b = int(binning) if binning is not None else max(1, int(np.ceil(np.sqrt(h * w / WORKING_PIXELS))))
    imgs, m = _binned(imgs, m, b)
    # the rig of the averaged copy: its camera's focal lengths and principal point in blocks
    rig_b = replace(rig, camera=_camera(rig.camera, b, float(rig.camera.camera_height_mm)), image_size=imgs.shape[1:])
    depth = float(rig.camera.camera_height_mm - rig.lights.positions[:, 2].min())
    lo, hi = (1.2 * depth, 6.0 * depth) if bounds_mm is None else (positive(bounds_mm[0], "bounds_mm"),
                                                                  positive(bounds_mm[1], "bounds_mm"))
    if not lo < hi or lo <= depth:
        raise InputError(f"bounds_mm: need {depth:.4g} mm (the LEDs' depth) < low < high, got ({lo:g}, {hi:g})")
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    order: list[float] = []

    def sq_at(height: float) -> np.ndarray:
        key = round(float(height), 6)
        if key not in cache:
            cache[key] = photometric_residual(imgs, rig_b, key, mask=m, integrator=integrator,
                                              max_iterations=max_iterations, binning=1)
            order.append(key)
        return cache[key][0]

    def rms(height: float) -> float:
        sq = sq_at(height)
        return float(np.sqrt(np.nanmean(sq) / imgs.shape[0]))

    coarse = np.geomspace(lo, hi, int(grid))
    values = np.array([rms(x) for x in coarse])
    # the lowest interior local minimum: near the LEDs' own depth the residual can fall again (grazing light
    # explains little), which is no working distance
    interior = [j for j in range(1, len(coarse) - 1) if values[j] <= values[j - 1] and values[j] <= values[j + 1]]
    if not interior:
        k = int(np.argmin(values))
        raise InputError(f"working distance: the photometric residual has no minimum inside [{lo:.4g}, {hi:.4g}] mm "
                         f"(lowest at {coarse[k]:.4g} mm); give bounds_mm or the camera height")
    k = min(interior, key=lambda j: values[j])
    best = minimize_scalar(rms, bounds=(coarse[k - 1], coarse[k + 1]), method="bounded",
                           options={"xatol": 5e-3 * coarse[k]})
    h0 = float(best.x)
    local = h0 * (1.0 + _LOCAL)
    sqs = [sq_at(x) for x in local]
    common = np.all([np.isfinite(s) for s in sqs], axis=0)
    n_pix = int(common.sum())
    f = np.array([np.sum(s[common]) for s in sqs])  # SSR over the common pixels
    vertex, curv = _vertex(local, f)
    n_obs = n_pix * imgs.shape[0]
    s2 = float(f.min()) / n_obs
    u_curv = float(np.sqrt(2 * s2 / curv)) if curv > 0 else float("inf")
    # jackknife over equal-count blocks along the valid pixels' longest axis
    rows, cols = np.nonzero(common)
    pts = np.stack([rows, cols], axis=1).astype(float)
    pts -= pts.mean(axis=0)
    axis = np.linalg.svd(pts, full_matrices=False)[2][0]
    label = np.minimum((np.argsort(np.argsort(pts @ axis)) * BLOCKS) // len(pts), BLOCKS - 1)
    per_block = np.array([[np.sum(s[common][label == j]) for j in range(BLOCKS)] for s in sqs])  # (5, BLOCKS)
    reps = np.array([_vertex(local, f - per_block[:, j])[0] for j in range(BLOCKS)])
    if np.all(np.isfinite(reps)):
        u_jack = float(np.sqrt((BLOCKS - 1) / BLOCKS * np.sum((reps - reps.mean()) ** 2)))
    else:
        u_jack = float("inf")
    estimate = vertex if np.isfinite(vertex) and abs(vertex - h0) < 0.05 * h0 else h0
    heights = np.array(order)
    return DistanceEstimate(float(estimate), max(u_curv, u_jack), u_curv, u_jack, rms(h0), heights,
                            np.array([float(np.sqrt(np.nanmean(cache[x][0]) / imgs.shape[0])) for x in order]),
                            b, n_obs, "equal" if rig.intensities is None else "rig")


def height_warning(given_mm: float, estimate: DistanceEstimate) -> str | None:
    """A warning when a given camera height is far from the estimate, else None.

    Far: outside the estimate's ``U = 2 u`` and more than :data:`FAR_FRACTION` away.

    Examples
    --------
    >>> est = DistanceEstimate(200.0, 3.0, 1.0, 3.0, 0.03, np.array([200.0]), np.array([0.03]), 4, 100, "rig")
    >>> height_warning(205.0, est) is None, height_warning(300.0, est)[:40]
    (True, 'camera height: the given 300 mm is 50 % ')
    """
    gap = float(given_mm) - estimate.camera_height_mm
    if abs(gap) <= 2 * estimate.u_mm or abs(gap) <= FAR_FRACTION * estimate.camera_height_mm:
        return None
    return (f"camera height: the given {given_mm:g} mm is {100 * abs(gap) / estimate.camera_height_mm:.0f} % from "
            f"the height the images fit best, {estimate.camera_height_mm:.1f} mm (U = "
            f"{2 * estimate.u_mm:.1f} mm, k = 2; photometric residual {estimate.residual_rms:.4g}); the surface's "
            "curvature depends on it")
