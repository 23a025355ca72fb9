"""Small analytic scenes for the photometric tests (independent of datasets_synthetic)."""

from __future__ import annotations

import numpy as np


def sphere_normals(size: int = 64, radius: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """Normals (H, W, 3) of a hemisphere seen from +z, y up (row 0 at the top), and its mask."""
    c = (np.arange(size) - (size - 1) / 2) / size
    x = c[None, :].repeat(size, 0)
    y = -c[:, None].repeat(size, 1)
    rr = x**2 + y**2
    mask = rr < (0.95 * radius) ** 2
    z = np.sqrt(np.clip(radius**2 - rr, 0, None))
    n = np.stack([x, y, np.where(mask, z, 1.0)], axis=2)
    n[~mask] = (0.0, 0.0, 1.0)
    return n / np.linalg.norm(n, axis=2, keepdims=True), mask


def render(normals, lights, albedo=1.0, intensities=None):
    """Lambertian images I_k = albedo * E_k * max(0, n . l_k); (N, H, W) or (N, H, W, 3)."""
    shade = np.clip(np.einsum("hwc,kc->khw", normals, lights), 0, None)
    alb = np.asarray(albedo, float)
    if alb.ndim == 3 or intensities is not None and np.ndim(intensities) == 2:
        a = alb if alb.ndim == 3 else np.broadcast_to(alb, normals.shape[:2] + (3,))
        e = np.ones((len(lights), 3)) if intensities is None else np.asarray(intensities, float)
        return (shade[..., None] * a[None] * e[:, None, None, :]).astype(np.float32)
    e = np.ones(len(lights)) if intensities is None else np.asarray(intensities, float)
    return (shade * alb * e[:, None, None]).astype(np.float32)


def ring(n: int, slant_deg: float, azimuth0_deg: float = 90.0) -> np.ndarray:
    """n unit lights evenly spaced in azimuth at one slant."""
    s = np.radians(slant_deg)
    a = np.radians(azimuth0_deg + 360.0 * np.arange(n) / n)
    return np.stack([np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.full(n, np.cos(s))], 1)
