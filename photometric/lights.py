"""Lights: the coordinate convention, distant light directions and angles, their validation.

The one home of far-field light geometry in the workbench: the synthetic renderer and the
error analysis take their lights from here. Near-field LEDs (:class:`~photometric.leds.PointLights`)
live in :mod:`photometric.leds`, the readers of light files (:func:`~photometric.io.load_lights`,
:func:`~photometric.io.load_intensities`, :func:`~photometric.io.load_light_positions`) in
:mod:`photometric.io`, and mirror-sphere calibration in :mod:`photometric.calibrate`.

Convention (stated once for the whole workbench; DiLiGenT's)
------------------------------------------------------------
Camera frame, orthographic view along ``-z``:

* ``x`` points to the right (increasing column index),
* ``y`` points **up** (row 0 is the TOP row, so ``y`` decreases with the row index),
* ``z`` points from the surface towards the camera.

A light direction ``l`` is the unit vector from the surface point towards the light.
A height field ``z(x, y)`` has derivatives ``p = dz/dx`` and ``q = dz/dy`` (y up), and
its unit normal is ``n = (-p, -q, 1) / sqrt(1 + p^2 + q^2)``, so ``p = -n_x / n_z`` and
``q = -n_y / n_z`` (seed 002(a)). The **slant** ``s`` is the angle between ``l`` and
``+z``; the **azimuth** ``a`` is the angle of ``l`` in the image plane, counter-clockwise
from ``+x`` towards ``+y`` (azimuth 90 deg: light from the top of the image), so
``l = (sin s cos a, sin s sin a, cos s)``. Industrial vision software calls the azimuth
"tilt"; the readers accept that name as an alias.

Validation
----------
:func:`validate_lights` is the one validator: rows whose length differs from 1 by more
than :data:`UNIT_TOLERANCE` are normalised with a ``UserWarning``; zero-length or
non-finite rows, too few lights and coplanar lights raise ``ValueError``. Public
functions validate their input once; the private helpers (``_vectors``, ``_angles``,
``_basis``, ``_deviate``, ``_rotate``) take already validated unit lights and are what
the rest of :mod:`photometric` calls inside.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from surfaces.validate import as_array, InputError

__all__ = [
    "CONVENTION",
    "UNIT_TOLERANCE",
    "COPLANAR_TOLERANCE",
    "validate_lights",
    "condition_number",
    "lights_from_angles",
    "light_angles",
    "ring_lights",
    "tangent_basis",
    "deviate_lights",
    "rotate_lights",
    "rotation_matrix",
    "as_intensities",
]

CONVENTION = (
    "DiLiGenT camera frame: x right (columns), y up (row 0 is the top row), z towards the "
    "camera; light vectors point from the surface to the light; p = dz/dx = -n_x/n_z, "
    "q = dz/dy = -n_y/n_z; slant from +z, azimuth counter-clockwise from +x towards +y "
    "(l = (sin s cos a, sin s sin a, cos s))."
)

#: Largest ``| |l| - 1 |`` accepted silently; longer or shorter rows are normalised with a warning.
UNIT_TOLERANCE = 1e-3
#: Smallest singular value relative to the largest below which lights count as coplanar.
COPLANAR_TOLERANCE = 1e-6


# ----------------------------------------------------------------------------- validation


def validate_lights(lights, name: str = "lights", *, min_lights: int = 3, batched: bool = False) -> np.ndarray:
    """Check light directions and return them as unit vectors.

    Parameters
    ----------
    lights : array_like, shape (N, 3), or (..., N, 3) with ``batched=True``
        Light directions in the camera frame of :data:`CONVENTION`.
    name : str, optional
        Argument name used in messages.
    min_lights : int, optional
        Fewest lights per set (3 for photometric stereo; 1 to render with one light).
        When it is 3 or more, each set must also determine a normal (not coplanar).
    batched : bool, optional
        Accept leading batch dimensions (several light sets at once).

    Returns
    -------
    numpy.ndarray, same shape, float64
        Unit light directions. Rows whose length differs from 1 by more than
        :data:`UNIT_TOLERANCE` are normalised with a ``UserWarning``.

    Raises
    ------
    ValueError
        Wrong shape, fewer than ``min_lights`` lights, NaN/inf, a zero-length row, or
        (``min_lights >= 3``) lights that are coplanar: the light matrix has rank < 3, so
        ``rho n = L^-1 I`` of seed 002(a) has no unique solution.

    Examples
    --------
    >>> validate_lights([[0, 0, 1], [1, 0, 0], [0, 1, 0]]).tolist()
    [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    >>> validate_lights([[0, 0, 1], [1, 0, 0], [1, 0, 0]])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: lights: light directions are coplanar (singular values [1.414214, 1.0, 0.0]); ...
    """
    arr = as_array(lights, name)
    if batched:
        if arr.ndim < 2 or arr.shape[-1] != 3:
            raise InputError(f"{name}: expected shape (..., N, 3), got {arr.shape}")
    elif arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name}: expected shape (N, 3), got {arr.shape}")
    n = arr.shape[-2]
    if n < min_lights:
        raise InputError(f"{name}: needs at least {min_lights} light direction(s), got {n}")
    norms = np.linalg.norm(arr, axis=-1)
    if np.any(norms < 1e-12):
        bad = np.argwhere(norms < 1e-12).tolist()
        raise InputError(f"{name}: zero-length light direction(s) at {bad}")
    off = np.abs(norms - 1.0) > UNIT_TOLERANCE
    if np.any(off):
        warnings.warn(
            f"{name}: {int(off.sum())} light direction(s) not unit (lengths "
            f"{np.round(norms[off], 4).tolist()[:5]}); normalised",
            UserWarning,
            stacklevel=2,
        )
    unit = arr / norms[..., None]
    if min_lights >= 3:
        s = np.linalg.svd(unit, compute_uv=False)
        flat = s[..., -1] <= COPLANAR_TOLERANCE * s[..., 0]
        if np.any(flat):
            where = "" if not batched else f" in set(s) {np.argwhere(flat).tolist()[:5]}"
            worst = s[np.unravel_index(np.argmax(flat), flat.shape)] if batched else s
            raise InputError(
                f"{name}: light directions are coplanar{where} (singular values "
                f"{np.round(worst, 6).tolist()}); the normal is not determined"
            )
    return unit


def _condition(unit: np.ndarray) -> float:
    s = np.linalg.svd(unit, compute_uv=False)
    return float(s[0] / s[-1])


def condition_number(lights) -> float:
    """Condition number of the light matrix (ratio of its extreme singular values).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Light directions (validated by :func:`validate_lights`).

    Returns
    -------
    float
        ``sigma_max / sigma_min`` of the unit light matrix; 1 is ideal (three lights
        120 deg apart at slant 54.74 deg, Drbohlav & Chantler 2005). Noise in the
        images is amplified by up to this factor in ``rho n``.

    Examples
    --------
    >>> round(condition_number(ring_lights(3, 45.0)), 6)  # sqrt(2)
    1.414214
    """
    return _condition(validate_lights(lights))


# ----------------------------------------------------------------------------- angles


def _vectors(slant_rad, azimuth_rad) -> np.ndarray:
    """``(sin s cos a, sin s sin a, cos s)`` for broadcast angles in radians: (..., 3)."""
    s, a = np.broadcast_arrays(slant_rad, azimuth_rad)
    return np.stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.cos(s)], axis=-1)


def _angles(unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slant and azimuth in degrees of unit vectors (..., 3)."""
    slant = np.degrees(np.arccos(np.clip(unit[..., 2], -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(unit[..., 1], unit[..., 0]))
    return slant, azimuth


def _alias(value, alias, name: str, alias_name: str):
    """The value given under ``name`` or under its alias (exactly one of them)."""
    if (value is None) == (alias is None):
        raise InputError(f"{name}: give either {name} or its alias {alias_name} (exactly one)")
    return value if value is not None else alias


def lights_from_angles(slant_deg, azimuth_deg=None, *, tilt_deg=None) -> np.ndarray:
    """Unit light directions from slant and azimuth angles.

    Parameters
    ----------
    slant_deg : array_like
        Angle between each light and the camera axis ``+z``, degrees, in [0, 90].
    azimuth_deg : array_like
        Angle in the image plane, counter-clockwise from ``+x`` (right) towards ``+y``
        (up), degrees; broadcast against ``slant_deg``.
    tilt_deg : array_like, optional
        Alias of ``azimuth_deg`` (give one of the two).

    Returns
    -------
    numpy.ndarray, shape ``broadcast(slant, azimuth) + (3,)``, float64
        ``l = (sin s cos a, sin s sin a, cos s)``.

    Examples
    --------
    >>> np.round(lights_from_angles([0.0, 90.0], [0.0, 90.0]), 12).tolist()
    [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
    >>> np.allclose(lights_from_angles(30.0, tilt_deg=45.0), lights_from_angles(30.0, 45.0))
    True
    """
    azimuth_deg = _alias(azimuth_deg, tilt_deg, "azimuth_deg", "tilt_deg")
    slant = as_array(slant_deg, "slant_deg")
    azimuth = as_array(azimuth_deg, "azimuth_deg")
    if np.any((slant < 0) | (slant > 90)):
        raise InputError(f"slant_deg: must lie in [0, 90] degrees, got {np.round(slant, 6).tolist()}")
    try:
        np.broadcast_shapes(slant.shape, azimuth.shape)
    except ValueError:
        raise InputError(f"slant_deg, azimuth_deg: shapes {slant.shape} and {azimuth.shape} do not broadcast") from None
    return _vectors(np.radians(slant), np.radians(azimuth))


def light_angles(lights) -> tuple[np.ndarray, np.ndarray]:
    """Slant and azimuth of light directions (inverse of :func:`lights_from_angles`).

    Parameters
    ----------
    lights : array_like, shape (..., N, 3)
        Light directions (validated by :func:`validate_lights`, any number).

    Returns
    -------
    slant_deg, azimuth_deg : numpy.ndarray, shape (..., N), float64
        Slant in [0, 180], azimuth in (-180, 180]; the azimuth of a light on the z axis
        is 0.

    Examples
    --------
    >>> s, a = light_angles(lights_from_angles([45.0], [120.0]))
    >>> round(float(s[0]), 9), round(float(a[0]), 9)
    (45.0, 120.0)
    """
    return _angles(validate_lights(lights, min_lights=1, batched=True))


def ring_lights(n: int, slant_deg: float, azimuth0_deg: float = 90.0) -> np.ndarray:
    """``n`` lights at one slant, equally spaced in azimuth (the standard triad for n = 3).

    ``l_k = (sin s cos a_k, sin s sin a_k, cos s)`` with ``a_k = a_0 + 360 k / n``
    degrees. Three lights 120 deg apart are best conditioned at ``tan(s) = sqrt(2)``,
    s = 54.74 deg (Drbohlav & Chantler 2005).

    Parameters
    ----------
    n : int
        Number of lights (>= 1).
    slant_deg : float
        Angle between each light and the viewing direction +z, degrees, in [0, 90].
    azimuth0_deg : float, optional
        Azimuth of the first light (default 90: the first light comes from the top).

    Returns
    -------
    numpy.ndarray, shape (n, 3), float64
        Unit light directions.

    Examples
    --------
    >>> np.round(ring_lights(3, 45.0), 4).tolist()
    [[0.0, 0.7071, 0.7071], [-0.6124, -0.3536, 0.7071], [0.6124, -0.3536, 0.7071]]
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise InputError(f"n: expected a whole number of lights >= 1, got {n!r}")
    slant = float(slant_deg)
    if not 0.0 <= slant <= 90.0:
        raise InputError(f"slant_deg: must lie in [0, 90] degrees, got {slant_deg!r}")
    azimuth = float(azimuth0_deg) + 360.0 * np.arange(int(n)) / int(n)
    return _vectors(np.radians(slant), np.radians(azimuth))


# ----------------------------------------------------------------------------- deviations


def _basis(unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``e_s`` and ``e_a`` of unit lights (..., 3)."""
    s, a = _angles(unit)
    s, a = np.radians(s), np.radians(a)
    e_s = np.stack([np.cos(s) * np.cos(a), np.cos(s) * np.sin(a), -np.sin(s)], axis=-1)
    e_a = np.stack([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)
    return e_s, e_a


def tangent_basis(lights) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangent vectors of the light directions along slant and azimuth.

    ``e_s = dl/ds = (cos s cos a, cos s sin a, -sin s)`` and
    ``e_a = (-sin a, cos a, 0)`` (``dl/da = sin s e_a``).

    Parameters
    ----------
    lights : array_like, shape (..., N, 3)
        Light directions.

    Returns
    -------
    e_slant, e_azimuth : numpy.ndarray, shape (..., N, 3), float64
        Together with ``l`` an orthonormal basis.
    """
    return _basis(validate_lights(lights, min_lights=1, batched=True))


def _deviate(unit: np.ndarray, deviations_deg: np.ndarray) -> np.ndarray:
    """``l(s + d_slant, a + d_azimuth)`` for unit lights (N, 3) and deviations (..., N, 2)."""
    s, a = _angles(unit)
    return _vectors(np.radians(s + deviations_deg[..., 0]), np.radians(a + deviations_deg[..., 1]))


def deviate_lights(lights, deviations_deg) -> np.ndarray:
    """Deviate each light by increments of its slant and azimuth (the "wrong lights" of seed 002(a)).

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal light directions.
    deviations_deg : array_like, shape (N,) or (..., N, 2)
        ``[d_slant, d_azimuth]`` per light, degrees; leading dimensions give a batch of
        light sets. A 1-D array gives slant deviations only.

    Returns
    -------
    numpy.ndarray, shape (N, 3) or (..., N, 3), float64
        Deviated unit lights ``l(s + d_slant, a + d_azimuth)``.

    Examples
    --------
    >>> nominal = lights_from_angles([45.0, 45.0, 45.0], [90.0, 210.0, 330.0])
    >>> s, a = light_angles(deviate_lights(nominal, [[2.0, 0.0], [0.0, -5.0], [0.0, 0.0]]))
    >>> np.round(s, 9).tolist(), np.round(a, 9).tolist()
    ([47.0, 45.0, 45.0], [90.0, -155.0, -30.0])
    """
    unit = validate_lights(lights, min_lights=1)
    n = unit.shape[0]
    d = as_array(deviations_deg, "deviations_deg")
    if d.ndim == 1 and d.shape == (n,):
        d = np.stack([d, np.zeros_like(d)], axis=-1)
    if d.ndim < 2 or d.shape[-2:] != (n, 2):
        raise InputError(f"deviations_deg: expected shape ({n},) or (..., {n}, 2), got {d.shape}")
    return _deviate(unit, d)


def _rotate(unit: np.ndarray, angle_deg, direction_deg) -> np.ndarray:
    """Unit lights (N, 3) turned by angles towards tangent directions, both broadcast to (..., N)."""
    delta, phi = np.broadcast_arrays(np.radians(angle_deg), np.radians(direction_deg))
    e_s, e_a = _basis(unit)
    u = np.cos(phi)[..., None] * e_s + np.sin(phi)[..., None] * e_a
    return np.cos(delta)[..., None] * unit + np.sin(delta)[..., None] * u


def rotate_lights(lights, angle_deg, direction_deg) -> np.ndarray:
    """Turn each light by an angle towards a direction in its tangent plane.

    ``l' = cos(delta) l + sin(delta) (cos(phi) e_s + sin(phi) e_a)``: a rotation
    about the axis ``l x u`` perpendicular to the light, so ``angle(l, l') = |delta|``.

    Parameters
    ----------
    lights : array_like, shape (N, 3)
        Nominal light directions.
    angle_deg : array_like, broadcastable to (..., N)
        Rotation angle ``delta`` per light, degrees.
    direction_deg : array_like, broadcastable to (..., N)
        Direction ``phi`` of the motion, degrees: 0 = increasing slant,
        90 = increasing azimuth.

    Returns
    -------
    numpy.ndarray, shape (..., N, 3), float64
        Unit light directions.
    """
    unit = validate_lights(lights, min_lights=1)
    delta = as_array(angle_deg, "angle_deg")
    phi = as_array(direction_deg, "direction_deg")
    try:
        shape = np.broadcast_shapes(delta.shape, phi.shape)
    except ValueError:
        raise InputError(f"angle_deg, direction_deg: shapes {delta.shape} and {phi.shape} do not broadcast") from None
    if len(shape) and shape[-1] not in (1, unit.shape[0]):
        raise InputError(f"angle_deg/direction_deg: last axis must have {unit.shape[0]} entries, got {shape}")
    return _rotate(unit, delta, phi)


def rotation_matrix(axis, angle_deg: float) -> np.ndarray:
    """Rotation matrix about an axis (Rodrigues' formula), e.g. a common rotation of a light rig.

    Parameters
    ----------
    axis : array_like, shape (3,)
        Rotation axis (any non-zero length).
    angle_deg : float
        Right-handed rotation angle, degrees.

    Returns
    -------
    numpy.ndarray, shape (3, 3), float64
        Orthogonal matrix ``R``; a rotated light is ``R @ l``.

    Examples
    --------
    >>> np.round(rotation_matrix([0, 0, 1], 90.0) @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    k = as_array(axis, "axis", shape=(3,))
    norm = np.linalg.norm(k)
    if norm == 0:
        raise InputError("axis: must be a non-zero vector")
    k = k / norm
    t = math.radians(float(angle_deg))
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(t) * K + (1.0 - math.cos(t)) * (K @ K)



# ----------------------------------------------------------------------------- intensities


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
        raise InputError(f"{name}: expected a scalar, ({n},) or ({n}, 3) values, got shape {arr.shape}")
    if np.any(arr <= 0):
        raise InputError(f"{name}: intensities must be positive, got minimum {arr.min()}")
    return arr
