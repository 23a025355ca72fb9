"""A torus around the z axis: every section has a hole.

``V = 2 pi^2 R r^2``, ``S = 4 pi^2 R r``; the section at height ``t`` from the
centre plane is the annulus between radii ``R -+ sqrt(r^2 - t^2)``.
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.phantoms.base import DistancePhantom, clamped_unit, ellipse_curve, rejection_sample
from surfaces.validate import InputError, positive


class Ring(DistancePhantom):
    """Torus around the z axis: tube radius r, centre-line radius R > r (holes in every section).

    Parameters
    ----------
    major_mm : float
        R, radius of the tube's centre line.
    minor_mm : float
        r, tube radius.
    center : (3,) array_like
        Centre in mm.
    """

    name = "ring"

    def __init__(self, major_mm: float = 25.0, minor_mm: float = 10.0, center=(0.0, 0.0, 0.0)):
        super().__init__(center)
        self.R = positive(major_mm, "major_mm")
        self.r = positive(minor_mm, "minor_mm")
        if self.r >= self.R:
            raise InputError(f"minor_mm: must be below major_mm ({self.R}), got {self.r}")

    def _params(self):
        return {"major_mm": self.R, "minor_mm": self.r}

    @property
    def z_range(self):
        return (float(self.center[2] - self.r), float(self.center[2] + self.r))

    @property
    def volume_mm3(self):
        return 2.0 * np.pi**2 * self.R * self.r**2

    @property
    def area_mm2(self):
        return 4.0 * np.pi**2 * self.R * self.r

    def section_area_mm2(self, z):
        t = clamped_unit(z, self.center[2], self.r) * self.r
        return 4.0 * np.pi * self.R * np.sqrt(self.r**2 - t * t)

    def volume_between_mm3(self, z0, z1):
        t0, t1 = clamped_unit([z0, z1], self.center[2], self.r) * self.r

        def seg(t):  # integral of sqrt(r^2 - t^2)
            return 0.5 * (t * np.sqrt(self.r**2 - t * t) + self.r**2 * np.arcsin(t / self.r))

        return float(4.0 * np.pi * self.R * (seg(t1) - seg(t0)))

    def _curves(self, z):
        t = float(clamped_unit(z, self.center[2], self.r)) * self.r
        w = np.sqrt(max(self.r**2 - t * t, 0.0))
        if w == 0:
            return []
        cx, cy = self.center[0], self.center[1]
        return [ellipse_curve(cx, cy, self.R + w, self.R + w),
                ellipse_curve(cx, cy, self.R - w, self.R - w)]

    def _signed_distance(self, p):
        p = p - self.center
        return np.hypot(np.hypot(p[:, 0], p[:, 1]) - self.R, p[:, 2]) - self.r

    def _pieces(self):
        def propose(rng, m):
            psi = rng.random(m) * 2.0 * np.pi
            th = rng.random(m) * 2.0 * np.pi
            rad = self.R + self.r * np.cos(th)
            pts = np.column_stack([rad * np.cos(psi), rad * np.sin(psi), self.r * np.sin(th)])
            return pts + self.center, rad

        return [(self.area_mm2, lambda rng, m: rejection_sample(rng, m, propose, self.R + self.r))]
