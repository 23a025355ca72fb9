"""The phantom base class: exact sections cut into contour stacks, and the ground truth.

A :class:`Phantom` gives its exact cross-section curves, section areas,
membership test and area-uniform surface sampler; the base class cuts contour
stacks (:meth:`Phantom.contours`) and collects the truth (:meth:`Phantom.truth`).
:class:`DistancePhantom` adds an exact signed distance. The helpers below sample
closed curves and surfaces for every shape.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from surfaces.validate import as_array, InputError, positive

#: A closed plane curve: ``t`` of shape (K,) in [0, 1] -> (K, 2) points in mm.
Curve = Callable[[np.ndarray], np.ndarray]

#: Sections smaller than this fraction of the largest section are not emitted as contours.
MIN_SECTION_FRACTION = 1e-6


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


def ellipse_curve(cx: float, cy: float, a: float, b: float) -> Curve:
    """Closed counter-clockwise ellipse ``t -> (cx + a cos 2 pi t, cy + b sin 2 pi t)``.

    Parameters
    ----------
    cx, cy : float
        Centre, mm.
    a, b : float
        Semi-axes along x and y, mm.

    Returns
    -------
    callable
        ``curve(t)`` for t of shape (K,) in [0, 1] -> (K, 2) float64 points, mm.

    Examples
    --------
    >>> ellipse_curve(1.0, 2.0, 3.0, 1.0)([0.0, 0.25]).round(12).tolist()
    [[4.0, 2.0], [1.0, 3.0]]
    """

    def curve(t):
        w = 2.0 * np.pi * np.asarray(t)
        return np.column_stack([cx + a * np.cos(w), cy + b * np.sin(w)])

    return curve


def uniform_sphere(rng: np.random.Generator, m: int) -> np.ndarray:
    """``m`` points drawn uniformly on the unit sphere, shape (m, 3).

    Parameters
    ----------
    rng : numpy.random.Generator
    m : int

    Returns
    -------
    numpy.ndarray, shape (m, 3)
    """
    v = rng.standard_normal((m, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def rejection_sample(rng: np.random.Generator, m: int, propose: Callable, density_max: float) -> np.ndarray:
    """Draw ``m`` samples from ``propose``, accepted with probability ``density / density_max``.

    Parameters
    ----------
    rng : numpy.random.Generator
    m : int
        Samples wanted.
    propose : callable
        ``propose(rng, k) -> (points (k, 3), density (k,))``.
    density_max : float
        Upper bound of the density.

    Returns
    -------
    numpy.ndarray, shape (m, 3)
    """
    out, have = [], 0
    while have < m:
        pts, dens = propose(rng, 2 * (m - have) + 64)
        keep = rng.random(len(pts)) * density_max < dens
        out.append(pts[keep])
        have += int(keep.sum())
    return np.concatenate(out)[:m]


def clamped_unit(z, zc: float, c: float) -> np.ndarray:
    """``(z - zc) / c`` clipped to [-1, 1]: the relative height in a solid of half height c.

    Parameters
    ----------
    z : array_like
        Heights, mm.
    zc, c : float
        Centre height and half height, mm.

    Returns
    -------
    numpy.ndarray, the shape of ``z``
    """
    return np.clip((np.asarray(z, dtype=np.float64) - zc) / c, -1.0, 1.0)


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
            raise InputError(f"n: expected a whole number >= 1, got {n!r}")
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
        z = self._plane_grid(h, offset_mm)
        z = z[~self._sliver(z)]
        if len(z) == 0:
            lo, hi = self.z_range
            raise InputError(f"spacing_mm: {h} mm leaves no slice plane inside z {lo}..{hi} mm")
        return z

    def _plane_grid(self, h: float, offset_mm: float) -> np.ndarray:
        """Planes ``z_c + offset + j h`` strictly inside the z range (slivers included)."""
        lo, hi = self.z_range
        zc = float(self.center[2]) + float(offset_mm)
        j = np.arange(np.floor((lo - zc) / h) - 1, np.ceil((hi - zc) / h) + 2)
        z = zc + j * h
        return z[(z > lo + 1e-9 * h) & (z < hi - 1e-9 * h)]

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
        z = self._plane_grid(positive(spacing_mm, "spacing_mm"), offset_mm)
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
            raise InputError(f"n_points: expected a whole number >= 8, got {n_points!r}")
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


class DistancePhantom(Phantom):
    """A phantom with an exact signed distance to its surface; membership is its sign."""

    def signed_distance(self, points) -> np.ndarray:
        """Exact signed distance to the surface (negative inside), mm.

        Parameters
        ----------
        points : (N, 3) array_like
            Points in mm.

        Returns
        -------
        (N,) float64 array
        """
        return self._signed_distance(as_array(points, "points", shape=(None, 3)))

    @abstractmethod
    def _signed_distance(self, p: np.ndarray) -> np.ndarray:
        """Signed distance of validated (N, 3) points."""

    def _inside(self, p: np.ndarray) -> np.ndarray:
        return self._signed_distance(p) <= 0.0
