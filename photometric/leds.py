"""Near-field LEDs: the point-light model of an inspection rig (positions, axes, lobes, falloff).

The one :class:`PointLights` of the workbench (the synthetic renderer, the near-field
solver, the rig and its calibration use it); far-field directions and their convention
are :mod:`photometric.lights`', the reader of ``light_positions.txt`` is
:func:`photometric.io.load_light_positions`.

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photometric.lights import as_intensities, validate_lights
from surfaces.validate import as_array, InputError

__all__ = ["PointLights", "point_lights", "light_field"]


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
    intensities : numpy.ndarray or None, shape (N,) or (N, 3), float64
        Intensities ``e_k`` (grey or RGB) when the lights carry them (the synthetic
        renderer's rigs, :func:`datasets_synthetic.point_lights.point_lights`); None: the
        solve takes them separately (``intensities`` of the input, or a flat field).
    """

    positions: np.ndarray
    axes: np.ndarray
    mu: np.ndarray
    mu_known: bool = True
    intensities: np.ndarray | None = None

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

    def subset(self, keep) -> PointLights:
        """The lights ``keep`` (an index array or a boolean mask over the lights) selects."""
        return PointLights(self.positions[keep], self.axes[keep], self.mu[keep], self.mu_known,
                           None if self.intensities is None else self.intensities[keep])

    def as_dict(self) -> dict:
        """The lights as ``scene.json`` states them (``lights`` of the near-field folder contract)."""
        e = np.ones(len(self)) if self.intensities is None else self.intensities
        return {"model": "point", "positions_mm": self.positions.tolist(), "axes": self.axes.tolist(),
                "mu": self.mu.tolist(), "intensities": e.tolist(), "d0_mm": self.d0.tolist()}


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
        raise InputError(f"lights: expected PointLights (photometric.leds.point_lights), got {type(lights).__name__}")
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
