"""Two overlapping spheres: sections are one circle, two circles, or one merged outline.

The section splits into two contours where the lobes branch. The union's volume
and area follow from the spherical-cap (lens) formulas; the volume between two
planes by adaptive quadrature of the exact section area.
"""

from __future__ import annotations

import numpy as np

from datasets_synthetic.phantoms.base import DistancePhantom, ellipse_curve, rejection_sample, uniform_sphere
from surfaces.validate import as_array, InputError


class Lobes(DistancePhantom):
    """Two overlapping spheres: sections are one circle, two circles, or one merged outline.

    Parameters
    ----------
    radii_mm : (2,) array_like
        Sphere radii.
    centers_mm : (2, 3) array_like
        Sphere centres (offsets from ``center``); their distance d must satisfy
        ``|r1 - r2| < d < r1 + r2``.
    center : (3,) array_like
        Offset of both spheres, mm.
    """

    name = "lobes"
    methods = {"volume": "closed form (spherical caps)",
               "volume_between": "adaptive quadrature of the exact section area, split at "
                                 "topology changes (relative accuracy ~1e-11)",
               "area": "closed form (spherical caps)"}

    def __init__(self, radii_mm=(20.0, 15.0), centers_mm=((-10.0, 0.0, 0.0), (14.0, 0.0, 8.0)),
                 center=(0.0, 0.0, 0.0)):
        super().__init__(center)
        self.radii = as_array(radii_mm, "radii_mm", shape=(2,))
        if np.any(self.radii <= 0):
            raise InputError("radii_mm: must be positive")
        self.centers = as_array(centers_mm, "centers_mm", shape=(2, 3)) + self.center
        d = float(np.linalg.norm(self.centers[1] - self.centers[0]))
        r1, r2 = self.radii
        if not (abs(r1 - r2) < d < r1 + r2):
            raise InputError(f"centers_mm: sphere distance {d} must lie between |r1 - r2| and r1 + r2")
        self.d = d
        # plane of the intersection circle: distance a from centre 1 along the centre line
        a = (d * d + r1 * r1 - r2 * r2) / (2.0 * d)
        self.caps = (r1 - a, r2 - (d - a))  # heights of the caps buried in the other sphere

    def _params(self):
        return {"radii_mm": self.radii.tolist(), "sphere_centers_mm": self.centers.tolist()}

    @property
    def z_range(self):
        lo = self.centers[:, 2] - self.radii
        hi = self.centers[:, 2] + self.radii
        return (float(lo.min()), float(hi.max()))

    @property
    def volume_mm3(self):
        (r1, r2), (h1, h2) = self.radii, self.caps
        lens = np.pi * h1 * h1 * (3 * r1 - h1) / 3.0 + np.pi * h2 * h2 * (3 * r2 - h2) / 3.0
        return float(4.0 / 3.0 * np.pi * (r1**3 + r2**3) - lens)

    @property
    def area_mm2(self):
        (r1, r2), (h1, h2) = self.radii, self.caps
        return float(4.0 * np.pi * (r1 * r1 + r2 * r2) - 2.0 * np.pi * (r1 * h1 + r2 * h2))

    def _discs(self, z):
        z = np.asarray(z, dtype=np.float64)
        w2 = self.radii[:, None] ** 2 - (np.atleast_1d(z)[None, :] - self.centers[:, 2:3]) ** 2
        return np.sqrt(np.clip(w2, 0.0, None))  # (2, Z) section radii

    def section_area_mm2(self, z):
        w = self._discs(z)
        delta = float(np.hypot(*(self.centers[1, :2] - self.centers[0, :2])))
        w1, w2 = w
        lens = np.zeros_like(w1)
        small = np.minimum(w1, w2)
        contained = delta <= np.abs(w1 - w2)
        lens[contained] = np.pi * small[contained] ** 2
        part = ~contained & (delta < w1 + w2)
        if np.any(part):
            a, b = w1[part], w2[part]
            lens[part] = (a * a * np.arccos(np.clip((delta**2 + a * a - b * b) / (2 * delta * a), -1, 1))
                          + b * b * np.arccos(np.clip((delta**2 + b * b - a * a) / (2 * delta * b), -1, 1))
                          - 0.5 * np.sqrt(np.clip((-delta + a + b) * (delta + a - b) * (delta - a + b)
                                                  * (delta + a + b), 0.0, None)))
        out = np.pi * (w1 * w1 + w2 * w2) - lens
        return out if np.ndim(z) else float(out[0])

    def _kinks(self) -> np.ndarray:
        """z where the section's topology changes (integrand not smooth there)."""
        from scipy.optimize import brentq

        lo, hi = self.z_range
        ends = np.concatenate([self.centers[:, 2] - self.radii, self.centers[:, 2] + self.radii])
        delta = float(np.hypot(*(self.centers[1, :2] - self.centers[0, :2])))
        zs = np.linspace(lo, hi, 4001)
        kinks = list(ends)

        def touch(z, sign):  # zero where the two discs touch from outside (+1) or inside (-1)
            w = self._discs(z)
            return np.abs(w[0] + sign * w[1]) - delta

        both = (self._discs(zs) > 0).all(axis=0)
        for sign in (1.0, -1.0):
            vals = np.where(both, touch(zs, sign), np.nan)
            for i in np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)[0]:
                kinks.append(brentq(lambda z, s=sign: float(touch(np.array([z]), s)[0]),
                                    zs[i], zs[i + 1], xtol=1e-13))
        return np.unique(np.clip(kinks, lo, hi))

    def volume_between_mm3(self, z0, z1):
        """Volume between two planes by adaptive quadrature of the exact section area.

        The section area (union of two discs) is integrated piecewise between the z
        values where the topology changes, to a relative accuracy of about 1e-11.
        """
        from scipy.integrate import quad

        lo, hi = self.z_range
        a, b = max(float(z0), lo), min(float(z1), hi)
        if b <= a:
            return 0.0
        knots = np.concatenate([[a], [k for k in self._kinks() if a < k < b], [b]])
        total = 0.0
        for s, e in zip(knots[:-1], knots[1:]):
            total += quad(lambda z: self.section_area_mm2(z), s, e, epsabs=0.0, epsrel=1e-12,
                          limit=200)[0]
        return float(total)

    def _curves(self, z):
        (w1, w2) = self._discs(z)[:, 0]
        (x1, y1), (x2, y2) = self.centers[0, :2], self.centers[1, :2]
        delta = float(np.hypot(x2 - x1, y2 - y1))
        circles = [c for c in ((x1, y1, w1), (x2, y2, w2)) if c[2] > 0]
        if len(circles) < 2 or delta >= w1 + w2:
            return [ellipse_curve(x, y, w, w) for x, y, w in circles]
        if delta <= abs(w1 - w2):
            x, y, w = circles[0] if w1 > w2 else circles[1]
            return [ellipse_curve(x, y, w, w)]
        base = np.arctan2(y2 - y1, x2 - x1)
        a = (delta**2 + w1**2 - w2**2) / (2.0 * delta)
        hc = np.sqrt(max(w1**2 - a * a, 0.0))
        al1, al2 = np.arctan2(hc, a), np.arctan2(hc, delta - a)
        # CCW: circle 1 from the upper crossing round its far side, then circle 2 round its far side
        span1, span2 = 2.0 * (np.pi - al1), 2.0 * (np.pi - al2)
        f1 = w1 * span1 / (w1 * span1 + w2 * span2)

        def curve(t):
            t = np.mod(np.asarray(t, dtype=np.float64), 1.0 + 1e-15)
            first = t <= f1
            ang1 = base + al1 + span1 * t / f1
            ang2 = base + (-(np.pi - al2)) + span2 * (t - f1) / (1.0 - f1)
            ang = np.where(first, ang1, ang2)
            cx = np.where(first, x1, x2)
            cy = np.where(first, y1, y2)
            r = np.where(first, w1, w2)
            return np.column_stack([cx + r * np.cos(ang), cy + r * np.sin(ang)])

        return [curve]

    def _signed_distance(self, p):
        # outside, the distance to a union is the smaller of the two sphere distances; inside, the
        # nearest boundary point is the radial projection onto a sphere (when that projection is not
        # buried in the other sphere) or a point of the intersection circle
        rel = p[:, None, :] - self.centers[None]  # (N, 2, 3)
        dist = np.linalg.norm(rel, axis=2)
        outside = np.min(dist - self.radii[None], axis=1)
        inside = outside <= 0
        if not inside.any():
            return outside
        q = p[inside]
        cands = []
        for k in range(2):
            d = np.linalg.norm(q - self.centers[k], axis=1)
            unit = (q - self.centers[k]) / np.where(d > 0, d, 1.0)[:, None]
            proj = self.centers[k] + self.radii[k] * unit
            buried = np.linalg.norm(proj - self.centers[1 - k], axis=1) < self.radii[1 - k]
            cands.append(np.where(buried, np.inf, np.abs(d - self.radii[k])))
        axis = (self.centers[1] - self.centers[0]) / self.d
        a = (self.d**2 + self.radii[0] ** 2 - self.radii[1] ** 2) / (2.0 * self.d)
        rim = np.sqrt(self.radii[0] ** 2 - a * a)
        rel0 = q - self.centers[0]
        along = rel0 @ axis
        radial = np.linalg.norm(rel0 - along[:, None] * axis, axis=1)
        cands.append(np.hypot(along - a, radial - rim))
        result = outside.copy()
        result[inside] = -np.min(cands, axis=0)
        return result

    def _inside(self, p):
        # the sign of the distance, without computing it
        d = np.linalg.norm(p[:, None, :] - self.centers[None], axis=2)
        return np.any(d <= self.radii[None], axis=1)

    def _pieces(self):
        pieces = []
        for k in range(2):
            other = 1 - k
            exposed = 4.0 * np.pi * self.radii[k] ** 2 - 2.0 * np.pi * self.radii[k] * self.caps[k]

            def propose(rng, m, k=k, other=other):
                pts = self.centers[k] + self.radii[k] * uniform_sphere(rng, m)
                outside = np.linalg.norm(pts - self.centers[other], axis=1) > self.radii[other]
                return pts, outside.astype(np.float64)

            pieces.append((float(exposed), lambda rng, m, f=propose: rejection_sample(rng, m, f, 1.0)))
        return pieces
