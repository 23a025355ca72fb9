"""Near-field point lights (LEDs) of an inspection rig: positions, axes, lobes, falloff.

The light model of the shared near-field format contract. Light ``k`` sits at
``P_k`` (mm, rig frame, ``z > 0``), points its axis ``a_k`` into the scene
(default: at the origin, ``a_k = -P_k / |P_k|``) and has a lobe exponent
``mu_k >= 0`` and an intensity ``e_k``. At a surface point ``X``::

    l_k(X) = (P_k - X) / |P_k - X|
    E_k(X) = e_k (d0_k / |P_k - X|)^2 max(0, -l_k . a_k)^mu_k,   d0_k = |P_k|

so an LED aimed at the origin delivers ``e_k`` there. A light at slant ``s``,
azimuth ``a`` and distance ``D`` from the origin sits at
``P = D (sin s cos a, sin s sin a, cos s)``; the directions come from
:mod:`photometric.lights` (the one home of light geometry) and the lights are
:class:`photometric.leds.PointLights` (the one class; here with their intensities ``e_k``).
The renderer's factory :func:`point_lights` takes any number of lights (a solve needs 3).
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.render import _deviations
from photometric.leds import PointLights
from photometric.lights import deviate_lights, ring_lights
from surfaces.validate import as_array, InputError, positive


def point_lights(positions, axes=None, mu=0.0, intensities=None) -> PointLights:
    """Check and assemble the point lights of a rendered rig (:class:`photometric.leds.PointLights`,
    the one class of the workbench, with their intensities).

    Parameters
    ----------
    positions : (N, 3) array_like
        LED positions in mm; every ``z`` must be positive (above the reference plane).
    axes : (N, 3) array_like, optional
        LED axes (normalised here); default: each LED aimed at the origin.
    mu : float or (N,) array_like
        Lobe exponents ``>= 0``.
    intensities : float, (N,) or (N, 3) array_like, optional
        Positive intensities; ones by default.

    Returns
    -------
    PointLights

    Raises
    ------
    ValueError
        A light at or below z = 0, a zero axis, a negative ``mu``, non-positive
        intensities or wrong shapes.

    Examples
    --------
    >>> lights = point_lights([[0.0, 0.0, 200.0], [100.0, 0.0, 100.0]], mu=1.0)
    >>> lights.axes.round(4).tolist(), lights.d0.round(4).tolist()
    ([[-0.0, -0.0, -1.0], [-0.7071, -0.0, -0.7071]], [200.0, 141.4214])
    """
    pos = as_array(positions, "positions", shape=(None, 3))
    n = len(pos)
    if n < 1:
        raise InputError("positions: needs at least one light")
    low = np.flatnonzero(pos[:, 2] <= 0)
    if low.size:
        raise InputError(f"positions: light(s) {(low + 1).tolist()} at z = {pos[low, 2].tolist()} mm are not above "
                         "the reference plane z = 0")
    if axes is None:
        ax = -pos / np.linalg.norm(pos, axis=1)[:, None]
    else:
        ax = as_array(axes, "axes", shape=(n, 3))
        length = np.linalg.norm(ax, axis=1)
        if np.any(length < 1e-12):
            raise InputError(f"axes: zero-length LED axis for light(s) {(np.flatnonzero(length < 1e-12) + 1).tolist()}")
        ax = ax / length[:, None]
    m = as_array(mu, "mu", ndim=(0, 1))
    m = np.broadcast_to(m, (n,)).copy() if m.ndim == 0 or m.shape == (1,) else m
    if m.shape != (n,) or np.any(m < 0):
        raise InputError(f"mu: expected one exponent >= 0 or {n} of them, got {np.asarray(mu).tolist()}")
    e = np.ones(n) if intensities is None else as_array(intensities, "intensities", ndim=(0, 1, 2))
    if e.ndim == 0:
        e = np.full(n, float(e))
    if e.shape not in ((n,), (n, 3)) or np.any(e <= 0):
        raise InputError(f"intensities: expected positive values, one or one RGB triple per light ({n}), "
                         f"got shape {e.shape}")
    return PointLights(pos, ax, m, True, e)


def ring_point_lights(n: int, slant_deg: float, distance_mm: float, azimuth0_deg: float = 90.0, mu=0.0,
                      intensities=None, deviations_deg=None) -> PointLights:
    """``n`` LEDs on a ring at one slant and distance from the origin, aimed at the origin.

    Parameters
    ----------
    n : int
        Number of lights.
    slant_deg : float
        Slant from +z, degrees, below 90 (a light at 90 deg lies in the reference plane).
    distance_mm : float
        Distance D of every LED from the origin, mm.
    azimuth0_deg : float
        Azimuth of the first light, counter-clockwise from +x, degrees (default 90: top).
    mu, intensities
        As :func:`point_lights`.
    deviations_deg : (n,) or (n, 2) array_like, optional
        Slant (and azimuth) deviations of each LED's place on its sphere of radius D
        (:func:`photometric.lights.deviate_lights`); the axes stay aimed at the origin.

    Returns
    -------
    PointLights
        ``P_k = D (sin s cos a_k, sin s sin a_k, cos s)``.

    Examples
    --------
    >>> ring_point_lights(3, 45.0, 200.0).positions.round(3).tolist()[0]
    [0.0, 141.421, 141.421]
    """
    d = positive(distance_mm, "distance_mm")
    slant = float(slant_deg)
    if not 0.0 <= slant < 90.0:
        raise InputError(f"slant_deg: must lie in [0, 90) degrees (a light at 90 deg or more is not above the "
                         f"reference plane z = 0), got {slant_deg!r}")
    unit = ring_lights(n, slant, azimuth0_deg)
    if deviations_deg is not None:
        unit = deviate_lights(unit, deviations_deg)
    return point_lights(d * unit, None, mu, intensities)


def rig_lights(lights, slant_deg: float, distance_mm: float, azimuth0_deg: float = 90.0, mu=0.0, intensities=None,
               deviate=None) -> tuple[PointLights, PointLights, np.ndarray]:
    """Nominal and true LEDs of a rendered rig: a ring (or given positions), the true ones deviated.

    Parameters
    ----------
    lights : int or (N, 3) array_like
        Number of ring LEDs (:func:`ring_point_lights` at ``slant_deg``, ``distance_mm``,
        ``azimuth0_deg``), or their nominal positions in mm.
    slant_deg, distance_mm, azimuth0_deg
        The ring (ignored for given positions).
    mu, intensities
        As :func:`point_lights` (the same for nominal and true LEDs).
    deviate : (N,) or (N, 2) array_like, optional
        Slant (and azimuth) deviations, degrees, of each true LED from its nominal place on
        its sphere about the origin; the true axes are aimed at the origin.

    Returns
    -------
    nominal, true : PointLights
    deviations : (N, 2) float64 array
        [slant, azimuth] deviations in degrees.

    Examples
    --------
    >>> nominal, true, dev = rig_lights(3, 45.0, 200.0, deviate=[2.0, 0.0, 0.0])
    >>> round(float(np.degrees(np.arccos(true.positions[0, 2] / 200.0))), 6), dev.shape
    (47.0, (3, 2))
    """
    m = as_array(mu, "led_mu", ndim=(0, 1))
    if np.ndim(lights) == 0:
        nominal = ring_point_lights(int(lights), slant_deg, distance_mm, azimuth0_deg, m, intensities)
    else:
        nominal = point_lights(lights, None, m, intensities)
    dev = _deviations(deviate, len(nominal))
    if not np.any(dev):
        return nominal, nominal, dev
    moved = nominal.d0[:, None] * deviate_lights(nominal.directions, dev)
    return nominal, point_lights(moved, None, m, nominal.intensities), dev


def light_vectors(lights: PointLights, points) -> tuple[np.ndarray, np.ndarray]:
    """Unit light vectors and geometric irradiance factors at surface points.

    Parameters
    ----------
    lights : PointLights
        The lights.
    points : (..., 3) array_like
        Surface points X in mm.

    Returns
    -------
    l : (N, ..., 3) float64 array
        ``l_k(X) = (P_k - X) / |P_k - X|``.
    falloff : (N, ...) float64 array
        ``(d0_k / |P_k - X|)^2 max(0, -l_k . a_k)^mu_k``, so that
        ``E_k = e_k * falloff_k`` (per channel for RGB intensities).

    Examples
    --------
    >>> lights = point_lights([[0.0, 0.0, 100.0]], mu=2.0)
    >>> l, g = light_vectors(lights, [[0.0, 0.0, 0.0], [0.0, 0.0, 50.0], [100.0, 0.0, 0.0]])
    >>> g.round(6).tolist()
    [[1.0, 4.0, 0.25]]
    """
    pts = as_array(points, "points")
    if pts.ndim < 1 or pts.shape[-1] != 3:
        raise InputError(f"points: expected shape (..., 3), got {pts.shape}")
    pairs = [_light_vector(lights, k, pts) for k in range(len(lights))]
    return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])


def _light_vector(lights: PointLights, k: int, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``l_k`` and the falloff of light ``k`` at checked points (one light at a time keeps memory flat)."""
    v = lights.positions[k] - pts
    r2 = np.einsum("...i,...i->...", v, v)
    r = np.sqrt(r2)
    unit = v / r[..., None]
    falloff = lights.d0[k] ** 2 / r2
    if lights.mu[k] > 0:
        falloff = falloff * np.maximum(0.0, -(unit @ lights.axes[k])) ** lights.mu[k]
    return unit, falloff


def shading(lights: PointLights, k: int, points: tuple, normals: tuple) -> np.ndarray:
    """``E_k(X) / e_k * max(0, n . l_k(X))`` of light ``k`` from coordinate planes (the renderers' hot path).

    Parameters
    ----------
    lights : PointLights
        The lights.
    k : int
        Light index.
    points : (x, y, z) tuple of float64 arrays, one shape
        Surface points in mm, one array per coordinate (contiguous planes are faster than
        an interleaved (..., 3) array).
    normals : (nx, ny, nz) tuple of float64 arrays, same shape
        Unit normals there.

    Returns
    -------
    float64 array (same shape)
        ``(d0_k / r)^2 max(0, -l . a_k)^mu_k max(0, n . l)``, ``r = |P_k - X|``.

    Examples
    --------
    >>> lights = point_lights([[0.0, 0.0, 100.0]])
    >>> x = np.array([0.0, 100.0])
    >>> shading(lights, 0, (x, 0 * x, 0 * x), (0 * x, 0 * x, 0 * x + 1)).round(6).tolist()
    [1.0, 0.353553]
    """
    px, py, pz = lights.positions[k]
    dx = px - points[0]
    dy = py - points[1]
    dz = pz - points[2]
    inv = dx * dx
    inv += dy * dy
    inv += dz * dz
    falloff = lights.d0[k] ** 2 / inv
    np.sqrt(inv, out=inv)
    np.divide(1.0, inv, out=inv)
    cos = normals[0] * dx
    cos += normals[1] * dy
    cos += normals[2] * dz
    cos *= inv
    np.maximum(cos, 0.0, out=cos)
    cos *= falloff
    mu = lights.mu[k]
    if mu > 0:
        ax, ay, az = lights.axes[k]
        lobe = dx * -ax
        lobe -= ay * dy
        lobe -= az * dz
        lobe *= inv
        np.maximum(lobe, 0.0, out=lobe)
        cos *= lobe if mu == 1 else lobe * lobe if mu == 2 else lobe**mu
    return cos
