"""CT phantoms: solids with exactly known volume and surface area, cut into contour stacks.

Coordinates are patient millimetres; z runs along the slice normal. Every
cross-section is a union of closed curves that the phantom can evaluate
exactly, so sampled contours lie ON the true outline (before optional noise),
and the volume between any two planes is known:

- ``ellipsoid``: ``V = 4/3 pi a b c``, area by Legendre's elliptic-integral formula.
- ``kidney``: a bean outline with a deep concave hilum (rays from its centroid
  cross it three times, the fold case of seed 000), scaled by
  ``s(z) = sqrt(1 - (z/c)^2)``: ``V = A0 * 4c/3`` with ``A0 = pi A B`` exactly;
  the area by spectrally accurate quadrature (stated in ``area_accuracy_mm2``).
- ``ring``: a torus around the z axis (every section has a hole):
  ``V = 2 pi^2 R r^2``, ``S = 4 pi^2 R r``.
- ``lobes``: two overlapping spheres (sections split into two contours where the
  lobes branch): union volume and area by the spherical-cap (lens) formulas.
- ``tilted_cylinder``: a right circular cylinder whose axis leans in the x-z plane,
  flat caps (end sections are truncated ellipses): ``V = pi r^2 L``,
  ``S = 2 pi r (L + r)``, volume between planes in closed form.
"""

from __future__ import annotations

import os
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path

import numpy as np

from surfaces.validate import as_array, positive

Curve = Callable[[np.ndarray], np.ndarray]
SHAPES = ("ellipsoid", "kidney", "ring", "lobes", "tilted_cylinder")

#: Sections smaller than this fraction of the largest section are not emitted as contours.
MIN_SECTION_FRACTION = 1e-6


def polygon_area(points) -> float:
    """Signed shoelace area of a closed polygon (positive when counter-clockwise).

    Parameters
    ----------
    points : (K, 2) array_like
        Vertices in order; the closing edge is implied.

    Returns
    -------
    float
        Area in the square of the input unit.
    """
    pts = as_array(points, "points", shape=(None, 2), min_size=6)
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _sample_closed(curve: Curve, n: int, phase: float) -> np.ndarray:
    """n points at equal arc length on a closed parametric curve, starting at ``phase``."""
    m = max(4096, 16 * n)
    t = np.arange(m + 1) / m
    dense = curve(t)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    target = (np.arange(n) + phase) / n * s[-1]
    return curve(np.interp(target, s, t))


def _perimeter(curve: Curve) -> float:
    dense = curve(np.arange(2049) / 2048)
    return float(np.sum(np.linalg.norm(np.diff(dense, axis=0), axis=1)))


def _ellipse_curve(cx, cy, a, b) -> Curve:
    def curve(t):
        w = 2.0 * np.pi * np.asarray(t)
        return np.column_stack([cx + a * np.cos(w), cy + b * np.sin(w)])

    return curve


def _uniform_sphere(rng, m):
    v = rng.standard_normal((m, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _rejection(rng, m, propose, density_max):
    """Draw m samples from ``propose`` accepted with probability density / density_max."""
    out, have = [], 0
    while have < m:
        pts, dens = propose(rng, 2 * (m - have) + 64)
        keep = rng.random(len(pts)) * density_max < dens
        out.append(pts[keep])
        have += int(keep.sum())
    return np.concatenate(out)[:m]


class Phantom(ABC):
    """A solid with exact volume, area and cross-sections (z along the slice normal, mm).

    Subclasses give the exact cross-section curves, section areas, membership
    test and surface sampler; this base class cuts contour stacks and collects
    the ground truth.
    """

    name: str = ""
    # how the truth is computed, written to truth.json so users can judge "exact"
    methods: dict = {"volume": "closed form", "volume_between": "closed form", "area": "closed form"}

    def __init__(self, center=(0.0, 0.0, 0.0)) -> None:
        self.center = as_array(center, "center", shape=(3,))

    @property
    def params(self) -> dict:
        """Shape parameters (JSON-serialisable)."""
        return {"center_mm": self.center.tolist(), **self._params()}

    @abstractmethod
    def _params(self) -> dict:
        """Shape-specific parameters."""

    @property
    @abstractmethod
    def z_range(self) -> tuple[float, float]:
        """Lowest and highest z of the solid, mm."""

    @property
    @abstractmethod
    def volume_mm3(self) -> float:
        """Exact volume, mm^3."""

    @property
    @abstractmethod
    def area_mm2(self) -> float:
        """Exact surface area, mm^2."""

    @abstractmethod
    def section_area_mm2(self, z) -> np.ndarray:
        """Exact cross-section area at heights ``z`` (array), mm^2 (holes subtracted)."""

    @abstractmethod
    def volume_between_mm3(self, z0: float, z1: float) -> float:
        """Exact volume of the solid between the planes z0 <= z1, mm^3."""

    @abstractmethod
    def _curves(self, z: float) -> list[Curve]:
        """Closed counter-clockwise curves t in [0, 1] -> (K, 2) of the section at z."""

    @abstractmethod
    def _inside(self, p: np.ndarray) -> np.ndarray:
        """Membership of validated (N, 3) points."""

    @abstractmethod
    def _pieces(self) -> list[tuple[float, Callable]]:
        """Surface pieces as (area, sampler(rng, m) -> (m, 3) area-uniform points)."""

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (lower, upper) corners in mm, from a dense surface sample."""
        pts = self.surface_points(20000, seed=12345)
        return pts.min(axis=0), pts.max(axis=0)

    def inside(self, points) -> np.ndarray:
        """Whether points lie inside the solid (boundary counts as inside).

        Parameters
        ----------
        points : (N, 3) array_like
            Points in mm.

        Returns
        -------
        (N,) bool array
        """
        return self._inside(as_array(points, "points", shape=(None, 3)))

    def surface_points(self, n: int, seed: int = 0) -> np.ndarray:
        """Points drawn uniformly (by area) on the true surface.

        Parameters
        ----------
        n : int
            Number of points.
        seed : int
            Random seed.

        Returns
        -------
        (n, 3) float64 array, mm.
        """
        if int(n) != n or n < 1:
            raise ValueError(f"n: expected a whole number >= 1, got {n!r}")
        rng = np.random.default_rng(seed)
        pieces = self._pieces()
        areas = np.array([a for a, _ in pieces])
        counts = rng.multinomial(int(n), areas / areas.sum())
        pts = [sampler(rng, int(c)) for (_, sampler), c in zip(pieces, counts) if c > 0]
        out = np.concatenate(pts)
        return out[rng.permutation(len(out))]

    def plane_positions(self, spacing_mm: float, offset_mm: float = 0.0) -> np.ndarray:
        """Slice planes ``z_c + offset + j * spacing`` strictly inside the solid's z range.

        Parameters
        ----------
        spacing_mm : float
            Slice spacing.
        offset_mm : float
            Shift of the plane grid from the solid's centre plane ``z_c``.

        Returns
        -------
        (P,) float64 array, increasing.
        """
        h = positive(spacing_mm, "spacing_mm")
        lo, hi = self.z_range
        zc = float(self.center[2]) + float(offset_mm)
        j = np.arange(np.floor((lo - zc) / h) - 1, np.ceil((hi - zc) / h) + 2)
        z = zc + j * h
        z = z[(z > lo + 1e-9 * h) & (z < hi - 1e-9 * h)]
        z = z[~self._sliver(z)]
        if len(z) == 0:
            raise ValueError(f"spacing_mm: {h} mm leaves no slice plane inside z {lo}..{hi} mm")
        return z

    def _sliver(self, z: np.ndarray) -> np.ndarray:
        """Planes whose exact section is too thin to give a simple polygon (area below
        :data:`MIN_SECTION_FRACTION` of the solid's largest section)."""
        if len(z) == 0:
            return np.zeros(0, dtype=bool)
        lo, hi = self.z_range
        largest = float(np.max(self.section_area_mm2(np.linspace(lo, hi, 257)[1:-1])))
        return self.section_area_mm2(np.asarray(z, dtype=np.float64)) < MIN_SECTION_FRACTION * largest

    def skipped_planes(self, spacing_mm: float, offset_mm: float = 0.0) -> np.ndarray:
        """Planes of the grid inside the z range that :meth:`plane_positions` leaves out (sliver sections).

        Parameters
        ----------
        spacing_mm, offset_mm : float
            As for :meth:`plane_positions`.

        Returns
        -------
        (S,) float64 array, mm; usually empty.
        """
        h = positive(spacing_mm, "spacing_mm")
        lo, hi = self.z_range
        zc = float(self.center[2]) + float(offset_mm)
        j = np.arange(np.floor((lo - zc) / h) - 1, np.ceil((hi - zc) / h) + 2)
        z = zc + j * h
        z = z[(z > lo + 1e-9 * h) & (z < hi - 1e-9 * h)]
        return z[self._sliver(z)]

    def contours(
        self, spacing_mm: float, n_points: int = 64, noise_mm: float = 0.0, seed: int = 0,
        offset_mm: float = 0.0,
    ) -> list[dict]:
        """Cut the solid into planar contours (CT-style stack).

        Each closed outline of each section becomes one entry; holes are separate
        inner contours on the same z. Points are equally spaced along the true
        outline from a random start, ``n_k = max(8, round(n_points * sqrt(P_k / P_max)
        * (0.8 + 0.4 U)))`` of them (P_k the outline's perimeter, U uniform), so
        contours have unequal point counts; isotropic Gaussian noise of
        ``noise_mm`` is added afterwards.

        Parameters
        ----------
        spacing_mm : float
            Slice spacing (see :meth:`plane_positions`).
        n_points : int
            Points on the longest outline (before the random factor).
        noise_mm : float
            Standard deviation of the in-plane noise, mm.
        seed : int
            Random seed (start points, counts, noise).
        offset_mm : float
            Shift of the plane grid.

        Returns
        -------
        list of dict
            ``{"z": float, "points": (K, 2) float64}`` counter-clockwise, sorted by z.
        """
        if int(n_points) != n_points or n_points < 8:
            raise ValueError(f"n_points: expected a whole number >= 8, got {n_points!r}")
        noise = positive(noise_mm, "noise_mm", allow_zero=True)
        rng = np.random.default_rng(seed)
        # a separate stream for the noise: the same seed gives the same points with or without it
        rng_noise = np.random.default_rng([int(seed), 1])
        planes = self.plane_positions(spacing_mm, offset_mm)
        per_plane = [(float(z), self._curves(float(z))) for z in planes]
        perims = [[_perimeter(c) for c in curves] for _, curves in per_plane]
        p_max = max(max(p) for p in perims if p)
        out = []
        for (z, curves), ps in zip(per_plane, perims):
            for curve, per in zip(curves, ps):
                k = max(8, int(round(n_points * np.sqrt(per / p_max) * (0.8 + 0.4 * rng.random()))))
                pts = _sample_closed(curve, k, rng.random())
                if noise > 0:
                    pts = pts + rng_noise.normal(0.0, noise, pts.shape)
                out.append({"z": z, "points": pts})
        return out

    def truth(self, spacing_mm: float, offset_mm: float = 0.0) -> dict:
        """Ground truth for a stack cut at ``spacing_mm``.

        Returns
        -------
        dict
            ``shape, params, units, volume_mm3, volume_ml, area_mm2,
            volume_between_end_planes_mm3`` (between the first and last planes),
            ``z_first_contour_mm, z_last_contour_mm, n_planes, spacing_mm, offset_mm,
            z_range_mm, section_areas_mm2`` (exact, per plane) and ``planes_mm``.
        """
        planes = self.plane_positions(spacing_mm, offset_mm)
        return {
            "shape": self.name,
            "params": self.params,
            "units": "mm",
            "volume_mm3": self.volume_mm3,
            "volume_ml": self.volume_mm3 / 1000.0,
            "area_mm2": self.area_mm2,
            "volume_between_end_planes_mm3": self.volume_between_mm3(planes[0], planes[-1]),
            "z_first_contour_mm": float(planes[0]),
            "z_last_contour_mm": float(planes[-1]),
            "n_planes": int(len(planes)),
            "spacing_mm": float(spacing_mm),
            "offset_mm": float(offset_mm),
            "z_range_mm": list(self.z_range),
            "planes_mm": planes.tolist(),
            "skipped_planes_mm": self.skipped_planes(spacing_mm, offset_mm).tolist(),
            "skipped_planes_rule": f"planes inside the z range whose exact section area is below "
                                   f"{MIN_SECTION_FRACTION:g} of the largest section are not emitted "
                                   "(no simple polygon); volumes between end planes use the emitted planes",
            "section_areas_mm2": self.section_area_mm2(planes).tolist(),
            "methods": dict(self.methods),
        }


def _clamped_unit(z, zc, c):
    return np.clip((np.asarray(z, dtype=np.float64) - zc) / c, -1.0, 1.0)


class Ellipsoid(Phantom):
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
    def z_range(self):
        return (float(self.center[2] - self.c), float(self.center[2] + self.c))

    @property
    def volume_mm3(self):
        return 4.0 / 3.0 * np.pi * self.a * self.b * self.c

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

    def section_area_mm2(self, z):
        u = _clamped_unit(z, self.center[2], self.c)
        return np.pi * self.a * self.b * (1.0 - u * u)

    def volume_between_mm3(self, z0, z1):
        u0, u1 = _clamped_unit([z0, z1], self.center[2], self.c)
        return float(np.pi * self.a * self.b * self.c * ((u1 - u1**3 / 3) - (u0 - u0**3 / 3)))

    def _curves(self, z):
        u = float(_clamped_unit(z, self.center[2], self.c))
        s = np.sqrt(max(1.0 - u * u, 0.0))
        return [_ellipse_curve(self.center[0], self.center[1], self.a * s, self.b * s)] if s > 0 else []

    def _inside(self, p):
        d = (p - self.center) / np.array([self.a, self.b, self.c])
        return np.sum(d * d, axis=1) <= 1.0

    def _pieces(self):
        abc = np.array([self.a, self.b, self.c])

        def propose(rng, m):
            u = _uniform_sphere(rng, m)
            # area element of the map u -> abc * u, relative to the unit sphere
            dens = np.sqrt(np.sum((u * (self.a * self.b * self.c) / abc) ** 2, axis=1))
            return self.center + u * abc, dens

        dmax = max(self.a * self.b, self.a * self.c, self.b * self.c)
        return [(self.area_mm2, lambda rng, m: _rejection(rng, m, propose, dmax))]


class Kidney(Phantom):
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
            raise ValueError(f"bend_radius_mm: must exceed thickness_mm ({self.B}), got {self.Rb}")
        if self.A / self.Rb >= 0.95 * np.pi:
            raise ValueError("arc_mm / bend_radius_mm: the bean would close on itself (need < 0.95 pi)")
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

    @property
    def z_range(self):
        return (float(self.center[2] - self.c), float(self.center[2] + self.c))

    @property
    def volume_mm3(self):
        return self.base_area_mm2 * 4.0 * self.c / 3.0

    def section_area_mm2(self, z):
        u = _clamped_unit(z, self.center[2], self.c)
        return self.base_area_mm2 * (1.0 - u * u)

    def volume_between_mm3(self, z0, z1):
        u0, u1 = _clamped_unit([z0, z1], self.center[2], self.c)
        return float(self.base_area_mm2 * self.c * ((u1 - u1**3 / 3) - (u0 - u0**3 / 3)))

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

    def _curves(self, z):
        u = float(_clamped_unit(z, self.center[2], self.c))
        s = np.sqrt(max(1.0 - u * u, 0.0))
        if s == 0:
            return []
        cx, cy = self.center[0], self.center[1]
        return [lambda t: self.outline(np.atleast_1d(t))[0] * s + (cx, cy)]

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

        return [(self.area_mm2, lambda rng, m: _rejection(rng, m, propose, dmax))]


class Ring(Phantom):
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
            raise ValueError(f"minor_mm: must be below major_mm ({self.R}), got {self.r}")

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
        t = _clamped_unit(z, self.center[2], self.r) * self.r
        return 4.0 * np.pi * self.R * np.sqrt(self.r**2 - t * t)

    def volume_between_mm3(self, z0, z1):
        t0, t1 = _clamped_unit([z0, z1], self.center[2], self.r) * self.r

        def seg(t):  # integral of sqrt(r^2 - t^2)
            return 0.5 * (t * np.sqrt(self.r**2 - t * t) + self.r**2 * np.arcsin(t / self.r))

        return float(4.0 * np.pi * self.R * (seg(t1) - seg(t0)))

    def _curves(self, z):
        t = float(_clamped_unit(z, self.center[2], self.r)) * self.r
        w = np.sqrt(max(self.r**2 - t * t, 0.0))
        if w == 0:
            return []
        cx, cy = self.center[0], self.center[1]
        return [_ellipse_curve(cx, cy, self.R + w, self.R + w),
                _ellipse_curve(cx, cy, self.R - w, self.R - w)]

    def signed_distance(self, points) -> np.ndarray:
        """Exact signed distance to the torus (negative inside), mm.

        Parameters
        ----------
        points : (N, 3) array_like

        Returns
        -------
        (N,) float64 array
        """
        p = as_array(points, "points", shape=(None, 3)) - self.center
        return np.hypot(np.hypot(p[:, 0], p[:, 1]) - self.R, p[:, 2]) - self.r

    def _inside(self, p):
        return self.signed_distance(p) <= 0.0

    def _pieces(self):
        def propose(rng, m):
            psi = rng.random(m) * 2.0 * np.pi
            th = rng.random(m) * 2.0 * np.pi
            rad = self.R + self.r * np.cos(th)
            pts = np.column_stack([rad * np.cos(psi), rad * np.sin(psi), self.r * np.sin(th)])
            return pts + self.center, rad

        return [(self.area_mm2, lambda rng, m: _rejection(rng, m, propose, self.R + self.r))]


class Lobes(Phantom):
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
            raise ValueError("radii_mm: must be positive")
        self.centers = as_array(centers_mm, "centers_mm", shape=(2, 3)) + self.center
        d = float(np.linalg.norm(self.centers[1] - self.centers[0]))
        r1, r2 = self.radii
        if not (abs(r1 - r2) < d < r1 + r2):
            raise ValueError(f"centers_mm: sphere distance {d} must lie between |r1 - r2| and r1 + r2")
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
            return [_ellipse_curve(x, y, w, w) for x, y, w in circles]
        if delta <= abs(w1 - w2):
            x, y, w = circles[0] if w1 > w2 else circles[1]
            return [_ellipse_curve(x, y, w, w)]
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

    def signed_distance(self, points) -> np.ndarray:
        """Exact signed distance to the union of the two spheres (negative inside), mm.

        Outside, the distance to a union is the smaller of the two sphere distances.
        Inside, the nearest boundary point is either the radial projection onto a
        sphere (when that projection is not buried in the other sphere) or a point of
        the intersection circle.

        Parameters
        ----------
        points : (N, 3) array_like

        Returns
        -------
        (N,) float64 array
        """
        p = as_array(points, "points", shape=(None, 3))
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
        d = np.linalg.norm(p[:, None, :] - self.centers[None], axis=2)
        return np.any(d <= self.radii[None], axis=1)

    def _pieces(self):
        pieces = []
        for k in range(2):
            other = 1 - k
            exposed = 4.0 * np.pi * self.radii[k] ** 2 - 2.0 * np.pi * self.radii[k] * self.caps[k]

            def propose(rng, m, k=k, other=other):
                pts = self.centers[k] + self.radii[k] * _uniform_sphere(rng, m)
                outside = np.linalg.norm(pts - self.centers[other], axis=1) > self.radii[other]
                return pts, outside.astype(np.float64)

            pieces.append((float(exposed), lambda rng, m, f=propose: _rejection(rng, m, f, 1.0)))
        return pieces


class TiltedCylinder(Phantom):
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
            raise ValueError(f"tilt_deg: must lie in (0, 80], got {tilt_deg}")
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

    def signed_distance(self, points) -> np.ndarray:
        """Exact signed distance to the capped cylinder (negative inside), mm.

        Parameters
        ----------
        points : (N, 3) array_like

        Returns
        -------
        (N,) float64 array
        """
        p = as_array(points, "points", shape=(None, 3)) - self.center
        t = p @ self.axis
        rad = np.hypot(p @ self.e1, p @ self.e2)
        dr, da = rad - self.r, np.abs(t) - 0.5 * self.L
        return np.minimum(np.maximum(dr, da), 0.0) + np.hypot(np.maximum(dr, 0.0), np.maximum(da, 0.0))

    def _inside(self, p):
        return self.signed_distance(p) <= 0.0

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


_CLASSES = {"ellipsoid": Ellipsoid, "kidney": Kidney, "ring": Ring, "lobes": Lobes,
            "tilted_cylinder": TiltedCylinder}


def make_phantom(shape: str, **params) -> Phantom:
    """Build a phantom by name.

    Parameters
    ----------
    shape : str
        ``"ellipsoid"``, ``"kidney"``, ``"ring"``, ``"lobes"`` or ``"tilted_cylinder"``.
    **params
        Keyword arguments of the class (:class:`Ellipsoid`, :class:`Kidney`,
        :class:`Ring`, :class:`Lobes`, :class:`TiltedCylinder`), all in mm/degrees.

    Returns
    -------
    Phantom
    """
    if shape not in _CLASSES:
        raise ValueError(f"shape: unknown phantom {shape!r}; expected one of {', '.join(SHAPES)}")
    try:
        return _CLASSES[shape](**params)
    except TypeError as exc:
        raise ValueError(f"params: {exc}") from None


def write_phantom(
    out_dir: str | os.PathLike,
    phantom: Phantom,
    spacing: float,
    pixel: float,
    fmt: str = "json",
    n_points: int = 64,
    noise_mm: float = 0.0,
    seed: int = 0,
    offset_mm: float = 0.0,
    n_surface: int = 20000,
    progress: bool = False,
) -> dict:
    """Write a phantom's contour stack, optional DICOM files and its ground truth.

    Always writes ``contours.json`` (``{"units": "mm", "contours": [{"z", "points"}]}``),
    ``truth.json`` and ``surface_points.npy`` ((n_surface, 3) float64, mm). With
    ``fmt="dicom"`` also a CT series in ``ct/`` (one file per slice, see
    :func:`datasets_synthetic.dicom.write_ct_series`); with ``fmt="rtstruct"`` the CT
    series and ``rtstruct.dcm`` referencing it.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created when missing).
    phantom : Phantom
        The solid.
    spacing : float
        Slice spacing in mm (contour planes and CT slices).
    pixel : float
        In-plane CT pixel size in mm.
    fmt : {"json", "dicom", "rtstruct"}
        Which extra files to write.
    n_points : int
        Points on the longest contour (see :meth:`Phantom.contours`).
    noise_mm : float
        Contour noise, mm.
    seed : int
        Random seed (contours, surface sample, CT noise and UIDs).
    offset_mm : float
        Shift of the slice grid from the phantom's centre plane.
    n_surface : int
        Size of the surface sample.
    progress : bool
        Show tqdm progress bars (command line only).

    Returns
    -------
    dict
        The ``truth.json`` content (see :meth:`Phantom.truth`) plus ``n_contours``,
        ``points_per_contour`` (min, max), ``pixel_mm``, ``noise_mm``, ``seed``,
        ``format`` and ``files``.
    """
    from datasets_synthetic.io import ensure_dir, save_npy, write_json

    if not isinstance(phantom, Phantom):
        raise ValueError(f"phantom: expected a Phantom, got {type(phantom).__name__}")
    if fmt not in ("json", "dicom", "rtstruct"):
        raise ValueError(f"fmt: expected 'json', 'dicom' or 'rtstruct', got {fmt!r}")
    spacing = positive(spacing, "spacing")
    pixel = positive(pixel, "pixel")
    out = ensure_dir(out_dir)
    contours = phantom.contours(spacing, n_points=n_points, noise_mm=noise_mm, seed=seed,
                                offset_mm=offset_mm)
    truth = phantom.truth(spacing, offset_mm)
    counts = [len(c["points"]) for c in contours]
    truth.update({"n_contours": len(contours), "points_per_contour": [min(counts), max(counts)],
                  "pixel_mm": pixel, "noise_mm": float(noise_mm), "seed": int(seed), "format": fmt})
    if isinstance(phantom, Kidney):
        truth["area_accuracy_mm2"] = phantom.area_accuracy_mm2
    files = {"contours": "contours.json", "truth": "truth.json", "surface_points": "surface_points.npy"}
    write_json(out / "contours.json", {"units": "mm", "contours": [
        {"z": c["z"], "points": c["points"]} for c in contours]})
    save_npy(out / "surface_points.npy", phantom.surface_points(int(n_surface), seed=seed))
    if fmt in ("dicom", "rtstruct"):
        from datasets_synthetic.dicom import write_ct_series, write_rtstruct

        series = write_ct_series(Path(out) / "ct", phantom, spacing, pixel, offset_mm=offset_mm,
                                 seed=seed, progress=progress)
        files["ct"] = "ct"
        truth["ct"] = {k: v for k, v in series.items() if k != "slices"}
        if fmt == "rtstruct":
            write_rtstruct(Path(out) / "rtstruct.dcm", contours, series, roi_name=phantom.name,
                           seed=seed)
            files["rtstruct"] = "rtstruct.dcm"
    truth["files"] = files
    write_json(out / "truth.json", truth)
    return truth
