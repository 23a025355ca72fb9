"""Light directions: the coordinate convention, reading, validation, calibration.

Convention (stated once for the whole workbench; DiLiGenT's)
------------------------------------------------------------
Camera frame, orthographic view along ``-z``:

* ``x`` points to the right (increasing column index),
* ``y`` points **up** (row 0 is the TOP row, so ``y`` decreases with the row index),
* ``z`` points from the surface towards the camera.

A light direction ``l`` is the unit vector from the surface point towards the light.
A height field ``z(x, y)`` has derivatives ``p = dz/dx`` and ``q = dz/dy`` (y up), and
its unit normal is ``n = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``, so ``p = -n_x / n_z`` and
``q = -n_y / n_z`` (seed 002(a)). Slant is the angle between ``l`` and ``+z``; tilt is the
azimuth of ``l`` in the image plane, counter-clockwise from ``+x`` (tilt 90 deg: light from
the top of the image), the way industrial vision software states it.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from surfaces.validate import as_array

CONVENTION = (
    "DiLiGenT camera frame: x right (columns), y up (row 0 is the top row), z towards the "
    "camera; light vectors point from the surface to the light; p = dz/dx = -n_x/n_z, "
    "q = dz/dy = -n_y/n_z; slant from +z, tilt counter-clockwise from +x."
)

#: Relative tolerance on ``|l| - 1`` before :func:`validate_lights` warns and normalises.
UNIT_TOLERANCE = 1e-3
#: Smallest singular value relative to the largest below which lights count as coplanar.
COPLANAR_TOLERANCE = 1e-6


def validate_lights(lights, name: str = "lights") -> np.ndarray:
    """Check light directions and return them as unit vectors.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Light directions in the camera frame of :data:`CONVENTION`.
    name : str, optional
        Argument name used in messages.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Unit light directions. Rows whose length differs from 1 by more than
        :data:`UNIT_TOLERANCE` are normalised with a ``UserWarning``.

    Raises
    ------
    ValueError
        Wrong shape, fewer than 3 lights, NaN/inf, a zero-length row, or lights that
        are coplanar (the light matrix has rank < 3, so ``rho n = L^-1 I`` of seed
        002(a) has no unique solution).
    """
    arr = as_array(lights, name, shape=(None, 3))
    if arr.shape[0] < 3:
        raise ValueError(f"{name}: photometric stereo needs at least 3 lights, got {arr.shape[0]}")
    norms = np.linalg.norm(arr, axis=1)
    if np.any(norms < 1e-12):
        bad = np.flatnonzero(norms < 1e-12).tolist()
        raise ValueError(f"{name}: zero-length light direction(s) at rows {bad}")
    off = np.abs(norms - 1.0) > UNIT_TOLERANCE
    if np.any(off):
        warnings.warn(
            f"{name}: {int(off.sum())} light direction(s) not unit (lengths "
            f"{np.round(norms[off], 4).tolist()[:5]}); normalised",
            UserWarning,
            stacklevel=2,
        )
    unit = arr / norms[:, None]
    s = np.linalg.svd(unit, compute_uv=False)
    if s[-1] <= COPLANAR_TOLERANCE * s[0]:
        raise ValueError(
            f"{name}: light directions are coplanar (singular values {np.round(s, 6).tolist()}); "
            "the normal is not determined"
        )
    return unit


def condition_number(lights) -> float:
    """Condition number of the light matrix (ratio of its extreme singular values).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Light directions (normalised first, see :func:`validate_lights`).

    Returns
    -------
    float
        ``sigma_max / sigma_min`` of the unit light matrix; 1 is ideal (three lights
        120 deg apart at slant 54.74 deg, Drbohlav & Chantler 2005). Noise in the
        images is amplified by up to this factor in ``rho n``.
    """
    unit = validate_lights(lights)
    s = np.linalg.svd(unit, compute_uv=False)
    return float(s[0] / s[-1])


def lights_from_slant_tilt(slant_deg, tilt_deg) -> np.ndarray:
    """Unit light directions from slant and tilt angles.

    Parameters
    ----------
    slant_deg : array_like, shape (N,)
        Angle between each light and the camera axis ``+z``, degrees, in [0, 90].
    tilt_deg : array_like, shape (N,)
        Azimuth in the image plane, counter-clockwise from ``+x`` (right) towards
        ``+y`` (up), degrees.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        ``l = (sin s cos t, sin s sin t, cos s)``.
    """
    slant = as_array(slant_deg, "slant_deg", ndim=(0, 1)).reshape(-1)
    tilt = as_array(tilt_deg, "tilt_deg", ndim=(0, 1)).reshape(-1)
    if slant.shape != tilt.shape:
        raise ValueError(f"slant_deg and tilt_deg: lengths differ ({slant.size} vs {tilt.size})")
    if np.any((slant < 0) | (slant > 90)):
        raise ValueError(f"slant_deg: must lie in [0, 90] degrees, got {slant.tolist()}")
    s, t = np.radians(slant), np.radians(tilt)
    return np.stack([np.sin(s) * np.cos(t), np.sin(s) * np.sin(t), np.cos(s)], axis=1)


def slant_tilt_from_lights(lights) -> tuple[np.ndarray, np.ndarray]:
    """Slant and tilt angles (degrees) of unit light directions; inverse of
    :func:`lights_from_slant_tilt`.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Light directions.

    Returns
    -------
    slant_deg, tilt_deg : numpy.ndarray, shape (N,)
        Slant in [0, 180], tilt in (-180, 180].
    """
    arr = as_array(lights, "lights", shape=(None, 3))
    unit = arr / np.maximum(np.linalg.norm(arr, axis=1, keepdims=True), 1e-300)
    slant = np.degrees(np.arccos(np.clip(unit[:, 2], -1.0, 1.0)))
    tilt = np.degrees(np.arctan2(unit[:, 1], unit[:, 0]))
    return slant, tilt


def _read_table(path: Path, name: str) -> np.ndarray:
    """Numbers from a text, .npy or JSON file (JSON: list, or dict handled by callers)."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return np.load(path, allow_pickle=False)
    try:
        return np.loadtxt(path, ndmin=2, delimiter="," if suffix == ".csv" else None)
    except ValueError as exc:
        raise ValueError(f"{name}: {path} is not a table of numbers ({exc})") from None


def _existing(path, name: str) -> Path:
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: file {p} does not exist")
    return p


def load_lights(path) -> np.ndarray:
    """Read light directions from a file.

    Parameters
    ----------
    path : str or Path
        One of

        * text (``.txt``, ``.csv``, ...): one ``x y z`` row per light (DiLiGenT
          ``light_directions.txt``), or two columns ``slant tilt`` in degrees;
        * ``.npy``: an ``(N, 3)`` array;
        * ``.json``: a list of ``[x, y, z]``, or an object with ``"lights"``
          (list of ``[x, y, z]``) or ``"slant_deg"`` and ``"tilt_deg"`` lists.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Unit light directions, validated by :func:`validate_lights`.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        Unreadable content or invalid lights.
    """
    p = _existing(path, "lights")
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(p.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"lights: {p} is not valid JSON ({exc})") from None
        if isinstance(data, dict):
            if "lights" in data:
                return validate_lights(data["lights"], f"lights ({p.name})")
            if "slant_deg" in data and "tilt_deg" in data:
                return validate_lights(lights_from_slant_tilt(data["slant_deg"], data["tilt_deg"]))
            raise ValueError(f"lights: {p} needs a 'lights' list or 'slant_deg' and 'tilt_deg'")
        return validate_lights(data, f"lights ({p.name})")
    table = _read_table(p, "lights")
    if table.ndim == 2 and table.shape[1] == 2:
        return validate_lights(lights_from_slant_tilt(table[:, 0], table[:, 1]))
    return validate_lights(table, f"lights ({p.name})")


def as_intensities(values, n: int, name: str = "intensities") -> np.ndarray:
    """Per-light RGB intensities from ``None``, a scalar, ``(N,)`` or ``(N, 3)`` values.

    Parameters
    ----------
    values : None, float or array_like, shape (N,) or (N, 3)
        Light intensities (relative units); ``None`` means all ones; a scalar or a
        per-light scalar is used for all three channels.
    n : int
        Number of lights.
    name : str, optional
        Argument name used in messages.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Positive intensities, one column per channel (R, G, B).
    """
    if values is None:
        return np.ones((n, 3))
    arr = as_array(values, name, ndim=(0, 1, 2))
    if arr.ndim == 0:
        arr = np.full((n, 3), float(arr))
    elif arr.ndim == 1 and arr.shape[0] == n:
        arr = np.repeat(arr[:, None], 3, axis=1)
    elif arr.ndim == 2 and arr.shape == (n, 1):
        arr = np.repeat(arr, 3, axis=1)
    elif arr.shape != (n, 3):
        raise ValueError(f"{name}: expected a scalar, ({n},) or ({n}, 3) values, got shape {arr.shape}")
    if np.any(arr <= 0):
        raise ValueError(f"{name}: intensities must be positive, got minimum {arr.min()}")
    return arr


def load_intensities(path, n: int) -> np.ndarray:
    """Read per-light intensities (DiLiGenT ``light_intensities.txt``: ``r g b`` per row).

    Parameters
    ----------
    path : str or Path
        Text (one value or one ``r g b`` row per light), ``.npy`` or ``.json`` (a list,
        or an object with an ``"intensities"`` list).
    n : int
        Number of lights the file must describe.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        See :func:`as_intensities`.
    """
    p = _existing(path, "intensities")
    if p.suffix.lower() == ".json":
        try:
            data = json.loads(p.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"intensities: {p} is not valid JSON ({exc})") from None
        if isinstance(data, dict):
            data = data.get("intensities")
            if data is None:
                raise ValueError(f"intensities: {p} needs an 'intensities' list")
        return as_intensities(data, n, f"intensities ({p.name})")
    table = _read_table(p, "intensities")
    if table.ndim == 2 and table.shape[0] == 1 and n != 1:
        table = table.reshape(-1)
    return as_intensities(table, n, f"intensities ({p.name})")


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
        raise ValueError(f"mask: sphere silhouette has only {area} pixels")
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
        Unit light directions in the convention of :data:`CONVENTION`.
    info : dict
        ``center_rc`` (row, col), ``radius_px``, ``highlights_rc`` (N, 2) list.
    """
    imgs = as_array(images, "images", ndim=(3, 4), dtype=np.float32)
    if imgs.ndim == 4:
        imgs = imgs.mean(axis=3)
    m = as_array(mask, "mask", shape=imgs.shape[1:], dtype=bool)
    if not 0 < threshold < 1:
        raise ValueError(f"threshold: must lie in (0, 1), got {threshold}")
    r0, c0, radius = sphere_from_mask(m)
    inside = np.where(m[None], imgs, 0.0)
    peak = inside.reshape(len(imgs), -1).max(axis=1)
    if np.any(peak <= 0):
        raise ValueError(f"images: no highlight inside the sphere in image(s) {np.flatnonzero(peak <= 0).tolist()}")
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
        raise ValueError(f"images: highlight outside the sphere circle in image(s) {np.flatnonzero(rr >= 1).tolist()}")
    n = np.stack([nx, ny, np.sqrt(1.0 - rr)], axis=1)
    v = np.array([0.0, 0.0, 1.0])
    lights = 2.0 * (n @ v)[:, None] * n - v
    info = {
        "center_rc": [r0, c0],
        "radius_px": radius,
        "highlights_rc": np.stack([hr, hc], axis=1).tolist(),
    }
    return lights / np.linalg.norm(lights, axis=1, keepdims=True), info
