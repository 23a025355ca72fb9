"""Lights: the coordinate convention, directions and angles, point lights, reading, calibration.

The one home of light geometry in the workbench: the synthetic renderer and the
error analysis take their lights from here.

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

Point lights (near-field rigs)
------------------------------
An LED at position ``P_k`` (mm, rig frame of :mod:`photometric.camera`: origin on the
optical axis in the reference plane ``z = 0``), aimed along the unit axis ``a_k``
(default: at the origin, ``a_k = -P_k / |P_k|``), with radiance lobe ``cos^mu_k`` and
reference distance ``d0_k = |P_k|``, lights a surface point ``X`` along
``l_k(X) = (P_k - X) / |P_k - X|`` with the irradiance
``E_k(X) = e_k (d0_k / |P_k - X|)^2 max(0, -l_k . a_k)^mu_k`` (an LED aimed at the origin
gives ``e_k`` there). Photometric stereo uses the scaled light vector
``s_k(X) = E_k(X) l_k(X)`` (:func:`light_field`), so a Lambertian pixel reads
``I_k = albedo * max(0, s_k . n)``. :class:`PointLights` holds the positions, axes and
lobe exponents; a light at or below the reference plane is an error.

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

import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from surfaces.validate import as_array, InputError, reads_file

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
    "load_lights",
    "as_intensities",
    "load_intensities",
    "sphere_from_mask",
    "calibrate_mirror_sphere",
    "PointLights",
    "point_lights",
    "load_light_positions",
    "light_field",
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


# ----------------------------------------------------------------------------- point lights


@dataclass(frozen=True)
class PointLights:
    """Near-field LEDs (see "Point lights" in the module docstring).

    Attributes
    ----------
    positions : numpy.ndarray, shape (N, 3), float64
        LED positions ``P_k``, mm, all above the reference plane (``z > 0``).
    axes : numpy.ndarray, shape (N, 3), float64
        Unit LED axes ``a_k`` (from the LED into the scene).
    mu : numpy.ndarray, shape (N,), float64
        Lobe exponents (0: isotropic).
    mu_known : bool
        False when the exponents were not given (then ``mu`` is 0; a flat field measures
        the lobe instead).
    """

    positions: np.ndarray
    axes: np.ndarray
    mu: np.ndarray
    mu_known: bool = True

    @property
    def d0(self) -> np.ndarray:
        """Reference distances ``d0_k = |P_k|``, mm, shape (N,)."""
        return np.linalg.norm(self.positions, axis=1)

    @property
    def directions(self) -> np.ndarray:
        """Unit directions from the origin to each LED, (N, 3): the far-field lights."""
        return self.positions / self.d0[:, None]

    def __len__(self) -> int:
        return int(self.positions.shape[0])


def point_lights(positions, axes=None, mu=None, name: str = "light_positions") -> PointLights:
    """Check LED positions, axes and lobe exponents.

    Parameters
    ----------
    positions : array_like, shape (N, 3)
        LED positions, mm, N >= 3, each above the reference plane (``z > 0``) and not
        all in one plane through the origin (their directions from the origin must
        determine a normal, as :func:`validate_lights` checks).
    axes : array_like, shape (N, 3), optional
        LED axes (normalised here); default aimed at the origin, ``-P_k / |P_k|``.
    mu : float or array_like, shape (N,), optional
        Lobe exponents ``>= 0``; one value for all LEDs; default 0 (isotropic), marked
        as not known.
    name : str, optional
        Argument name used in messages.

    Returns
    -------
    PointLights

    Raises
    ------
    ValueError
        Wrong shape, NaN, a light at or below the reference plane, coplanar
        directions, a zero axis, an axis pointing away from the reference plane, or a
        negative exponent.

    Examples
    --------
    >>> lights = point_lights([[100, 0, 100], [-50, 86.6, 100], [-50, -86.6, 100]])
    >>> np.round(lights.axes[0], 4).tolist(), lights.mu.tolist()
    ([-0.7071, -0.0, -0.7071], [0.0, 0.0, 0.0])
    >>> point_lights([[100, 0, 100], [-50, 86.6, 0], [-50, -86.6, 100]])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: light_positions: light 1 at z = 0 mm is at or below the reference plane z = 0 ...
    """
    pos = as_array(positions, name)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise InputError(f"{name}: expected shape (N, 3) (x y z in mm per LED), got {pos.shape}")
    if pos.shape[0] < 3:
        raise InputError(f"{name}: needs at least 3 lights, got {pos.shape[0]}")
    low = np.flatnonzero(pos[:, 2] <= 0)
    if low.size:
        k = int(low[0])
        raise InputError(f"{name}: light {k} at z = {pos[k, 2]:g} mm is at or below the reference plane z = 0 "
                         "(LEDs must be above the part)")
    validate_lights(pos / np.linalg.norm(pos, axis=1, keepdims=True), f"{name} (directions from the origin)")
    n = pos.shape[0]
    if axes is None:
        ax = -pos / np.linalg.norm(pos, axis=1, keepdims=True)
    else:
        ax = as_array(axes, "led_axes", shape=(n, 3))
        norm = np.linalg.norm(ax, axis=1)
        if np.any(norm < 1e-12):
            raise InputError(f"led_axes: zero-length axis for light(s) {np.flatnonzero(norm < 1e-12).tolist()}")
        ax = ax / norm[:, None]
        if np.any(ax[:, 2] >= 0):
            raise InputError(f"led_axes: axis of light(s) {np.flatnonzero(ax[:, 2] >= 0).tolist()} does not point "
                             "down towards the part")
    known = mu is not None
    m = np.zeros(n) if mu is None else as_array(mu, "led_mu", ndim=(0, 1))
    if m.ndim == 0:
        m = np.full(n, float(m))
    if m.shape != (n,):
        raise InputError(f"led_mu: expected one value or {n} values, got shape {m.shape}")
    if np.any(m < 0):
        raise InputError(f"led_mu: lobe exponents must be >= 0, got {m.tolist()}")
    return PointLights(pos, ax, m, known)


@reads_file("light position file")
def load_light_positions(path) -> np.ndarray:
    """Read LED positions (``light_positions.txt``: one ``x y z`` row in mm per image).

    Parameters
    ----------
    path : str or Path
        Text (whitespace or ``.csv`` comma separated), ``.npy`` ``(N, 3)`` or ``.json``
        (a list of ``[x, y, z]`` or an object with ``"positions_mm"``).

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Positions in mm, checked by :func:`point_lights`.
    """
    p = _existing(path, "light_positions")
    if p.suffix.lower() == ".json":
        data = _read_json(p, "light_positions")
        if isinstance(data, dict):
            data = data.get("positions_mm")
            if data is None:
                raise InputError(f"light_positions: {p} needs a 'positions_mm' list")
    else:
        data = _read_table(p, "light_positions")
    return point_lights(data, name=f"light_positions ({p.name})").positions


def _scaled_vectors(position, axis, mu: float, strength, x, y, z, lobe: bool = True):
    """``s = strength * max(0, -l . a)^mu / r^2 * l`` at points (x, y, z) (broadcast, float32).

    The one implementation of the point-light model: :func:`light_field` (checked,
    float64) and the near-field solver's whole-image passes (float32 blocks) call it.
    Returns the three components; ``strength`` is ``e d0^2`` (or a per-pixel map).
    """
    dtype = np.result_type(x, y, z)
    if np.ndim(strength) == 0:
        strength = dtype.type(strength)
    dx = dtype.type(position[0]) - x
    dy = dtype.type(position[1]) - y
    dz = dtype.type(position[2]) - z
    r2 = dz * dz
    r2 = r2 + dx * dx
    r2 = r2 + dy * dy
    inv_r = 1.0 / np.sqrt(r2)
    c = (strength * inv_r) / r2
    if lobe and mu > 0:
        cos = (dx * dtype.type(-axis[0]) + dy * dtype.type(-axis[1]) + dz * dtype.type(-axis[2])) * inv_r
        np.maximum(cos, 0, out=cos)
        c = c * (cos if mu == 1 else cos ** dtype.type(mu))
    return c * dx, c * dy, c * dz


def light_field(lights: PointLights, points, intensities=None) -> np.ndarray:
    """Scaled light vectors ``s_k(X) = E_k(X) l_k(X)`` of point lights at surface points.

    Parameters
    ----------
    lights : PointLights
        From :func:`point_lights`.
    points : array_like, shape (..., 3)
        Surface points ``X``, mm, below every light.
    intensities : None, float or array_like, shape (N,), optional
        ``e_k`` (grey; default 1).

    Returns
    -------
    numpy.ndarray, shape (N, ..., 3), float64
        ``E_k(X) l_k(X)`` with ``E_k = e_k (d0_k / |P_k - X|)^2 max(0, -l_k . a_k)^mu_k``;
        ``|s_k|`` is the irradiance and a Lambertian pixel reads
        ``albedo * max(0, s_k . n)``.

    Examples
    --------
    An LED 100 mm above the origin gives ``e = 1`` there, a quarter at twice the distance:

    >>> lights = point_lights([[0, 0, 100], [100, 0, 100], [0, 100, 100]])
    >>> s = light_field(lights, [[0, 0, 0], [0, 0, -100]])
    >>> np.round(s[0], 6).tolist()
    [[0.0, 0.0, 1.0], [0.0, 0.0, 0.25]]
    """
    if not isinstance(lights, PointLights):
        raise InputError(f"lights: expected PointLights (photometric.lights.point_lights), got {type(lights).__name__}")
    X = as_array(points, "points")
    if X.ndim < 1 or X.shape[-1] != 3:
        raise InputError(f"points: expected shape (..., 3), got {X.shape}")
    n = len(lights)
    e = np.ones(n) if intensities is None else as_intensities(intensities, n).mean(axis=1)
    above = X[..., 2][None] < lights.positions[:, 2].reshape((n,) + (1,) * (X.ndim - 1))
    if not np.all(above):
        raise InputError("points: a point lies at or above the height of a light")
    strength = e * lights.d0**2
    out = np.empty((n,) + X.shape)
    for k in range(n):
        sx, sy, sz = _scaled_vectors(lights.positions[k], lights.axes[k], float(lights.mu[k]), strength[k],
                                     X[..., 0], X[..., 1], X[..., 2])
        out[k, ..., 0], out[k, ..., 1], out[k, ..., 2] = sx, sy, sz
    return out


# ----------------------------------------------------------------------------- files


def _read_table(path: Path, name: str) -> np.ndarray:
    """Numbers from a text or .npy file."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return np.load(path, allow_pickle=False)
    try:
        return np.loadtxt(path, ndmin=2, delimiter="," if suffix == ".csv" else None)
    except ValueError as exc:
        raise InputError(f"{name}: {path} is not a table of numbers ({exc})") from None


def _read_json(path: Path, name: str):
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}: {path} is not valid JSON ({exc})") from None


def _existing(path, name: str) -> Path:
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: file {p} does not exist")
    return p


@reads_file("light file")
def load_lights(path) -> np.ndarray:
    """Read light directions from a file.

    Parameters
    ----------
    path : str or Path
        One of

        * text (``.txt``, ``.csv``, ...): one ``x y z`` row per light (DiLiGenT
          ``light_directions.txt``), or two columns ``slant azimuth`` in degrees (the
          "slant tilt" form of vision software: tilt is the azimuth);
        * ``.npy``: an ``(N, 3)`` array;
        * ``.json``: a list of ``[x, y, z]``, or an object with ``"lights"``
          (list of ``[x, y, z]``) or ``"slant_deg"`` and ``"azimuth_deg"`` lists
          (``"tilt_deg"`` is accepted for ``"azimuth_deg"``).

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Unit light directions, validated once by :func:`validate_lights`.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        Unreadable content or invalid lights.
    """
    p = _existing(path, "lights")
    name = f"lights ({p.name})"
    if p.suffix.lower() == ".json":
        data = _read_json(p, "lights")
        if isinstance(data, dict):
            if "lights" in data:
                data = data["lights"]
            elif "slant_deg" in data and ("azimuth_deg" in data or "tilt_deg" in data):
                data = lights_from_angles(data["slant_deg"], data.get("azimuth_deg"), tilt_deg=data.get("tilt_deg"))
            else:
                raise InputError(f"lights: {p} needs a 'lights' list or 'slant_deg' and 'azimuth_deg' (or 'tilt_deg')")
        return validate_lights(data, name)
    table = _read_table(p, "lights")
    if table.ndim == 2 and table.shape[1] == 2:
        table = lights_from_angles(table[:, 0], table[:, 1])
    return validate_lights(table, name)


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


@reads_file("light intensity file")
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
        data = _read_json(p, "intensities")
        if isinstance(data, dict):
            data = data.get("intensities")
            if data is None:
                raise InputError(f"intensities: {p} needs an 'intensities' list")
        return as_intensities(data, n, f"intensities ({p.name})")
    table = _read_table(p, "intensities")
    if table.ndim == 2 and table.shape[0] == 1 and n != 1:
        table = table.reshape(-1)
    return as_intensities(table, n, f"intensities ({p.name})")


# ----------------------------------------------------------------------------- calibration


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
        Unit light directions in the convention of :data:`CONVENTION`.
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
