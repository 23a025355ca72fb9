"""A right circular cylinder with flat caps whose axis leans in the x-z plane.

``V = pi r^2 L``, ``S = 2 pi r (L + r)``; sections through the side wall are
ellipses, the end sections truncated ellipses; section areas and the volume
between planes in closed form.
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.phantoms.base import DistancePhantom
from surfaces.validate import InputError, positive


class TiltedCylinder(DistancePhantom):
    """Right circular cylinder with flat caps, axis tilted by ``tilt_deg`` from z in the x-z plane.

    Sections through the side wall are ellipses (semi-axes ``r / cos(tilt)`` and r);
    near the ends they are ellipses cut by straight chords. Every section area and
    the volume between any two planes are closed-form (segment areas of a circle,
    scaled by ``1 / cos(tilt)``, integrated analytically).

    Parameters
    ----------
    radius_mm : float
        r.
    length_mm : float
        L, along the axis.
    tilt_deg : float
        Angle between the axis and z, in (0, 80] degrees.
    center : (3,) array_like
        Centre in mm.
    """

    name = "tilted_cylinder"

    def __init__(self, radius_mm: float = 12.0, length_mm: float = 60.0, tilt_deg: float = 30.0,
                 center=(0.0, 0.0, 0.0)):
        super().__init__(center)
        self.r = positive(radius_mm, "radius_mm")
        self.L = positive(length_mm, "length_mm")
        tilt = positive(tilt_deg, "tilt_deg")
        if tilt > 80.0:
            raise InputError(f"tilt_deg: must lie in (0, 80], got {tilt_deg}")
        self.tilt = np.deg2rad(tilt)
        st, ct = np.sin(self.tilt), np.cos(self.tilt)
        self.axis = np.array([st, 0.0, ct])
        self.e1 = np.array([ct, 0.0, -st])
        self.e2 = np.array([0.0, 1.0, 0.0])

    def _params(self):
        return {"radius_mm": self.r, "length_mm": self.L, "tilt_deg": float(np.rad2deg(self.tilt))}

    @property
    def z_range(self):
        half = 0.5 * self.L * np.cos(self.tilt) + self.r * np.sin(self.tilt)
        return (float(self.center[2] - half), float(self.center[2] + half))

    @property
    def volume_mm3(self):
        return float(np.pi * self.r**2 * self.L)

    @property
    def area_mm2(self):
        return float(2.0 * np.pi * self.r * (self.L + self.r))

    def _bounds_u(self, z):
        """Limits of the in-plane coordinate u = x cos - z sin imposed by the caps."""
        dz = np.asarray(z, dtype=np.float64) - self.center[2]
        half = 0.5 * self.L * np.cos(self.tilt)
        st = np.sin(self.tilt)
        return (-half - dz) / st, (half - dz) / st

    def _F(self, h):
        """Area of the disc u^2 + v^2 <= r^2 with u <= h (h clamped to [-r, r])."""
        r = self.r
        h = np.clip(h, -r, r)
        return r * r * np.arcsin(h / r) + h * np.sqrt(r * r - h * h) + 0.5 * np.pi * r * r

    def _Phi(self, h):
        """Integral of F(clamp(eta)) d eta from -r to h (any real h)."""
        r = self.r
        hc = np.clip(h, -r, r)

        def prim(x):
            return (r * r * (x * np.arcsin(x / r) + np.sqrt(r * r - x * x))
                    - (r * r - x * x) ** 1.5 / 3.0 + 0.5 * np.pi * r * r * x)

        return prim(hc) - prim(-r) + np.pi * r * r * np.clip(h - r, 0.0, None)

    def section_area_mm2(self, z):
        lo, hi = self._bounds_u(z)
        return np.maximum(self._F(hi) - self._F(lo), 0.0) / np.cos(self.tilt)

    def volume_between_mm3(self, z0, z1):
        lo0, hi0 = self._bounds_u(z0)
        lo1, hi1 = self._bounds_u(z1)
        st, ct = np.sin(self.tilt), np.cos(self.tilt)
        # u-limits are linear in z with slope -1/sin(tilt): dz = -sin(tilt) du
        return float(-st * ((self._Phi(hi1) - self._Phi(hi0)) - (self._Phi(lo1) - self._Phi(lo0))) / ct)

    def _curves(self, z):
        lo, hi = (float(v) for v in self._bounds_u(z))
        if hi <= -self.r or lo >= self.r or hi <= lo:
            return []
        dz = z - self.center[2]
        st, ct = np.sin(self.tilt), np.cos(self.tilt)
        cx, cy = self.center[0], self.center[1]
        r = self.r
        lo, hi = max(lo, -r), min(hi, r)
        # The section {u^2 + v^2 <= r^2, lo <= u <= hi} is convex: its outline is traced by rays from
        # an inside point p = (u0, 0), each ending at the circle or at a chord u = lo / u = hi,
        # whichever comes first (clipping the circle's u instead would leave zero-width spikes
        # along a chord that cuts beyond the axis, a polygon that retraces itself).
        u0 = 0.5 * (lo + hi)

        def curve(t):
            w = 2.0 * np.pi * np.asarray(t, dtype=np.float64)
            du, dv = np.cos(w), np.sin(w)
            # circle: |p + s d| = r  ->  s = -u0 du + sqrt((u0 du)^2 - (u0^2 - r^2))
            s = -u0 * du + np.sqrt(np.maximum((u0 * du) ** 2 - (u0 * u0 - r * r), 0.0))
            with np.errstate(divide="ignore", invalid="ignore"):
                to_chord = np.where(du > 0, (hi - u0) / du, np.where(du < 0, (lo - u0) / du, np.inf))
            s = np.minimum(s, to_chord)
            u, v = u0 + s * du, s * dv
            return np.column_stack([cx + (u + dz * st) / ct, cy + v])

        return [curve]

    def _signed_distance(self, p):
        p = p - self.center
        t = p @ self.axis
        rad = np.hypot(p @ self.e1, p @ self.e2)
        dr, da = rad - self.r, np.abs(t) - 0.5 * self.L
        return np.minimum(np.maximum(dr, da), 0.0) + np.hypot(np.maximum(dr, 0.0), np.maximum(da, 0.0))

    def _frame(self, t, a, b):
        return self.center + t[:, None] * self.axis + a[:, None] * self.e1 + b[:, None] * self.e2

    def _pieces(self):
        def side(rng, m):
            th = rng.random(m) * 2.0 * np.pi
            t = (rng.random(m) - 0.5) * self.L
            return self._frame(t, self.r * np.cos(th), self.r * np.sin(th))

        def cap(sign):
            def sample(rng, m):
                rad = self.r * np.sqrt(rng.random(m))
                th = rng.random(m) * 2.0 * np.pi
                return self._frame(np.full(m, sign * 0.5 * self.L), rad * np.cos(th), rad * np.sin(th))

            return sample

        disc = np.pi * self.r**2
        return [(2.0 * np.pi * self.r * self.L, side), (disc, cap(1.0)), (disc, cap(-1.0))]
