"""Solids whose sections are one outline scaled by ``s(z) = sqrt(1 - ((z - z0) / c)^2)``.

The section at ``z`` has area ``A0 s^2`` (``A0`` the middle section's), so
``V = A0 4c/3`` and the volume between two planes is
``A0 c [(u - u^3 / 3)]`` between their ``u = (z - z0) / c``, in closed form:

- ``ellipsoid``: the outline an ellipse, ``A0 = pi a b``; the area by
  Legendre's elliptic-integral formula.
- ``kidney``: a bean outline with a deep concave hilum (rays from its centroid
  cross it three times, the fold case of seed 000), ``A0 = pi A B`` exactly;
  the area by spectrally accurate quadrature (stated in ``area_accuracy_mm2``).
"""

from __future__ import annotations

from abc import abstractmethod

import numpy as np

from datasets_synthetic.phantoms.base import (
    Curve,
    Phantom,
    clamped_unit,
    ellipse_curve,
    rejection_sample,
    uniform_sphere,
)
from surfaces.validate import as_array, InputError, positive


class ScaledSection(Phantom):
    """A solid of half height ``c`` whose sections are one outline scaled by ``s(z)``.

    Subclasses set ``c`` (mm) and give :attr:`base_area_mm2` and the outline at
    a scale (:meth:`_section_curve`); sections, volumes and the z range follow.
    """

    c: float

    @property
    @abstractmethod
    def base_area_mm2(self) -> float:
        """Area of the middle section ``A0``, mm^2 (exact)."""

    @abstractmethod
    def _section_curve(self, s: float) -> Curve:
        """The section's closed counter-clockwise outline at scale ``0 < s <= 1``."""

    @property
    def z_range(self):
        return (float(self.center[2] - self.c), float(self.center[2] + self.c))

    @property
    def volume_mm3(self):
        return self.base_area_mm2 * 4.0 * self.c / 3.0

    def section_area_mm2(self, z):
        u = clamped_unit(z, self.center[2], self.c)
        return self.base_area_mm2 * (1.0 - u * u)

    def volume_between_mm3(self, z0, z1):
        u0, u1 = clamped_unit([z0, z1], self.center[2], self.c)
        return float(self.base_area_mm2 * self.c * ((u1 - u1**3 / 3) - (u0 - u0**3 / 3)))

    def _curves(self, z):
        u = float(clamped_unit(z, self.center[2], self.c))
        s = np.sqrt(max(1.0 - u * u, 0.0))
        return [self._section_curve(s)] if s > 0 else []


class Ellipsoid(ScaledSection):
    """Ellipsoid ``((x-x0)/a)^2 + ((y-y0)/b)^2 + ((z-z0)/c)^2 <= 1``.

    Parameters
    ----------
    a, b, c : float
        Semi-axes along x, y, z in mm.
    center : (3,) array_like
        Centre in mm.
    """

    name = "ellipsoid"
    methods = {"volume": "closed form", "volume_between": "closed form",
               "area": "closed form (Legendre, incomplete elliptic integrals)"}

    def __init__(self, a: float = 30.0, b: float = 20.0, c: float = 25.0, center=(0.0, 0.0, 0.0)):
        super().__init__(center)
        self.a, self.b, self.c = (positive(a, "a"), positive(b, "b"), positive(c, "c"))

    def _params(self):
        return {"a_mm": self.a, "b_mm": self.b, "c_mm": self.c}

    @property
    def base_area_mm2(self) -> float:
        """Area of the middle section, ``pi a b`` (exact)."""
        return float(np.pi * self.a * self.b)

    @property
    def area_mm2(self):
        """Legendre's formula with incomplete elliptic integrals (a >= b >= c sorted)."""
        from scipy.special import ellipeinc, ellipkinc

        a, b, c = sorted((self.a, self.b, self.c), reverse=True)
        if a - c <= 1e-12 * a:
            return 4.0 * np.pi * a * a
        phi = np.arccos(c / a)
        m = (a * a * (b * b - c * c)) / (b * b * (a * a - c * c))
        s = np.sin(phi)
        return float(2.0 * np.pi * c * c + 2.0 * np.pi * a * b / s
                     * (ellipeinc(phi, m) * s * s + ellipkinc(phi, m) * np.cos(phi) ** 2))

    def _section_curve(self, s):
        return ellipse_curve(self.center[0], self.center[1], self.a * s, self.b * s)

    def _inside(self, p):
        d = (p - self.center) / np.array([self.a, self.b, self.c])
        return np.sum(d * d, axis=1) <= 1.0

    def _pieces(self):
        abc = np.array([self.a, self.b, self.c])

        def propose(rng, m):
            u = uniform_sphere(rng, m)
            # area element of the map u -> abc * u, relative to the unit sphere
            dens = np.sqrt(np.sum((u * (self.a * self.b * self.c) / abc) ** 2, axis=1))
            return self.center + u * abc, dens

        dmax = max(self.a * self.b, self.a * self.c, self.b * self.c)
        return [(self.area_mm2, lambda rng, m: rejection_sample(rng, m, propose, dmax))]


class Kidney(ScaledSection):
    """Kidney-shaped solid whose sections fold (non-star-shaped about their centroid).

    The base outline bends the ellipse ``(u, v) = (A cos w, -B sin w)``, ``w = -2 pi t``, around a
    circle of radius ``Rb``: ``P = (Rb - v) (cos(u / Rb), sin(u / Rb))``. The map
    preserves area on average, so the outline encloses exactly ``A0 = pi A B``;
    its concave hilum faces -x. Centred on its centroid and scaled by
    ``s(z) = sqrt(1 - ((z - z0) / c)^2)``, the section at z has area ``A0 s^2`` and
    ``V = A0 4c/3``. The surface area is a double integral with a smooth integrand
    (z = z0 + c sin(theta)): trapezoid rule in w (periodic) times Gauss-Legendre
    in theta; ``area_accuracy_mm2`` is the change against half the resolution.

    Parameters
    ----------
    length_mm : float
        Extent along z (2c), default 70 mm.
    arc_mm : float
        Half length A of the bean along its bent axis.
    thickness_mm : float
        Half thickness B.
    bend_radius_mm : float
        Bend radius Rb (> B, and A / Rb < pi).
    center : (3,) array_like
        Position of the centroid of the middle section, mm.
    """

    name = "kidney"
    methods = {"volume": "closed form", "volume_between": "closed form",
               "area": "quadrature: periodic trapezoid x Gauss-Legendre, see area_accuracy_mm2"}

    def __init__(self, length_mm: float = 70.0, arc_mm: float = 32.0, thickness_mm: float = 8.0,
                 bend_radius_mm: float = 11.5, center=(0.0, 0.0, 0.0)):
        super().__init__(center)
        self.c = positive(length_mm, "length_mm") / 2.0
        self.A = positive(arc_mm, "arc_mm")
        self.B = positive(thickness_mm, "thickness_mm")
        self.Rb = positive(bend_radius_mm, "bend_radius_mm")
        if self.Rb <= self.B:
            raise InputError(f"bend_radius_mm: must exceed thickness_mm ({self.B}), got {self.Rb}")
        if self.A / self.Rb >= 0.95 * np.pi:
            raise InputError("arc_mm / bend_radius_mm: the bean would close on itself (need < 0.95 pi)")
        dense = self._bent(np.arange(20000) / 20000)[0]
        x, y = dense[:, 0], dense[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        area = 0.5 * cross.sum()
        self._centroid = np.array([np.sum((x + np.roll(x, -1)) * cross),
                                   np.sum((y + np.roll(y, -1)) * cross)]) / (6.0 * area)
        self._area = None

    def _bent(self, t):
        """Outline point and derivative d/dt in bend coordinates."""
        # w runs backwards so that the outline is counter-clockwise after bending
        w = -2.0 * np.pi * np.asarray(t, dtype=np.float64)
        u, v = self.A * np.cos(w), -self.B * np.sin(w)
        du, dv = 2.0 * np.pi * self.A * np.sin(w), 2.0 * np.pi * self.B * np.cos(w)
        phi, rho = u / self.Rb, self.Rb - v
        c, s = np.cos(phi), np.sin(phi)
        dphi, drho = du / self.Rb, -dv
        pts = np.column_stack([rho * c, rho * s])
        der = np.column_stack([drho * c - rho * s * dphi, drho * s + rho * c * dphi])
        return pts, der

    def outline(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Base outline C0(t) about its centroid and C0'(t), for t in [0, 1].

        Parameters
        ----------
        t : (K,) array_like

        Returns
        -------
        points, derivatives : (K, 2) float64 arrays, mm and mm per unit t.
        """
        pts, der = self._bent(as_array(t, "t", ndim=1))
        return pts - self._centroid, der

    def _params(self):
        return {"length_mm": 2 * self.c, "arc_mm": self.A, "thickness_mm": self.B,
                "bend_radius_mm": self.Rb, "base_area_mm2": self.base_area_mm2}

    @property
    def base_area_mm2(self) -> float:
        """Area of the middle section, ``pi A B`` (exact)."""
        return float(np.pi * self.A * self.B)

    def _area_at(self, n_t: int, n_theta: int) -> float:
        pts, der = self.outline(np.arange(n_t) / n_t)
        cross2 = (pts[:, 0] * der[:, 1] - pts[:, 1] * der[:, 0]) ** 2
        speed2 = np.sum(der * der, axis=1)
        x, wts = np.polynomial.legendre.leggauss(n_theta)
        th = x * np.pi / 2.0
        ct, st = np.cos(th)[:, None], np.sin(th)[:, None]
        dens = ct * np.sqrt(self.c**2 * ct**2 * speed2 + st**2 * cross2)
        return float(np.sum(wts[:, None] * dens) * (np.pi / 2.0) / n_t)

    @property
    def area_mm2(self):
        if self._area is None:
            self._area = self._area_at(8192, 192)
            self._area_accuracy = abs(self._area - self._area_at(4096, 96))
        return self._area

    @property
    def area_accuracy_mm2(self) -> float:
        """Change of ``area_mm2`` against half the quadrature resolution (an error bound), mm^2."""
        _ = self.area_mm2
        return self._area_accuracy

    def _section_curve(self, s):
        cx, cy = self.center[0], self.center[1]
        return lambda t: self.outline(np.atleast_1d(t))[0] * s + (cx, cy)

    def _inside(self, p):
        u = (p[:, 2] - self.center[2]) / self.c
        s = np.sqrt(np.clip(1.0 - u * u, 0.0, None))
        ok = s > 0
        safe = np.where(ok, s, 1.0)
        local = (p[:, :2] - self.center[:2]) / safe[:, None] + self._centroid
        rho = np.hypot(local[:, 0], local[:, 1])
        phi = np.arctan2(local[:, 1], local[:, 0])
        uu, vv = self.Rb * phi, self.Rb - rho
        return ok & ((uu / self.A) ** 2 + (vv / self.B) ** 2 <= 1.0)

    def _pieces(self):
        def density(t, th):
            pts, der = self.outline(t)
            cross2 = (pts[:, 0] * der[:, 1] - pts[:, 1] * der[:, 0]) ** 2
            ct, st = np.cos(th), np.sin(th)
            return ct * np.sqrt(self.c**2 * ct**2 * np.sum(der * der, axis=1) + st**2 * cross2)

        tg, thg = np.meshgrid(np.arange(512) / 512, np.linspace(-np.pi / 2, np.pi / 2, 257))
        dmax = 1.05 * float(density(tg.ravel(), thg.ravel()).max())

        def propose(rng, m):
            t = rng.random(m)
            th = (rng.random(m) - 0.5) * np.pi
            pts = self.outline(t)[0] * np.cos(th)[:, None] + self.center[:2]
            return np.column_stack([pts, self.center[2] + self.c * np.sin(th)]), density(t, th)

        return [(self.area_mm2, lambda rng, m: rejection_sample(rng, m, propose, dmax))]
