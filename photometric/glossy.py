"""Normals of glossy parts: a Lambertian albedo plus a GGX specular lobe, fitted per pixel (issue 32, item 2).

A Lambertian solve of a glossy part tilts every normal to absorb the gloss: the
images stay close to the Lambertian prediction (the residual only doubles) while
the heights bend by tenths of a millimetre. This module fits the reflectance the
images show instead::

    I_k = albedo * (s_k . n + c * F_k(n)),   F_k(n) = |s_k| D(n . h_k) G(n, l_k, v) / (4 n . v)

with the scaled light vectors ``s_k`` of the solve (far field ``e_k l_k``, near field
:func:`photometric.leds.light_field`), the view direction ``v``, the half vector
``h_k = (l_k + v) / |l_k + v|``, the GGX (Trowbridge-Reitz) distribution ``D`` and
Smith's masking ``G`` of roughness ``alpha`` (Walter et al., "Microfacet models for
refraction through rough surfaces", EGSR 2007, eqs. 33-34), and one lobe weight
``c`` for the part: ``c = pi * k_s / k_d`` for a lobe of reflectance ``k_s`` beside a
diffuse albedo ``k_d`` (the lobe of :func:`datasets_synthetic.mitsuba_scenes.material`
``"lambertian_ggx"`` is ``k_s / k_d = specular``).

* :func:`ggx_lobe` evaluates ``F_k``;
* :func:`lobe_weight` measures ``c`` on a reference part of known normals (a level
  plate: ``n = (0, 0, 1)``);
* :func:`fit_glossy` refines per pixel the normal (its slopes ``p, q``) and the
  albedo by damped Gauss-Newton (Levenberg-Marquardt) from a Lambertian start, all
  pixels at once, a block of rows at a time.

``alpha`` and ``c`` are properties of the material and the rig (calibrated once);
with them, 4 or more lights fix the 3 unknowns of each pixel.
"""

from __future__ import annotations

import numpy as np

from surfaces.validate import InputError, as_array, positive

__all__ = ["fit_glossy", "ggx_lobe", "lobe_weight"]

#: Rows per block of :func:`fit_glossy` (memory: about 60 float64 planes of (N, rows, W)).
BLOCK_ROWS = 32


def _view(view, shape) -> np.ndarray:
    v = as_array(view, "view")
    if v.shape not in ((3,), tuple(shape) + (3,)):
        raise InputError(f"view: expected (3,) or {tuple(shape) + (3,)}, got {v.shape}")
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(length <= 0):
        raise InputError("view: zero-length view direction")
    return np.broadcast_to(v / length, tuple(shape) + (3,))


def _smith(cos: np.ndarray, a2: float) -> np.ndarray:
    """Smith's GGX masking of one direction, ``2 / (1 + sqrt(1 + alpha^2 tan^2))``."""
    c2 = cos * cos
    return 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - c2) / c2))


def _geometry(S: np.ndarray, E: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit light vectors and half vectors (N, ..., 3): they do not depend on the normal."""
    unit = S / np.where(E > 0, E, 1.0)[..., None]
    h = unit + v[None]
    h /= np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-12)
    return unit, h


def _lobe(n: np.ndarray, S: np.ndarray, E: np.ndarray, v: np.ndarray, a2: float, geometry=None) -> np.ndarray:
    """``F_k`` on checked arrays: n (..., 3), S (N, ..., 3), E = |S| (N, ...), v (..., 3)."""
    unit, h = _geometry(S, E, v) if geometry is None else geometry
    nh = np.einsum("k...i,...i->k...", h, n)
    nl = np.einsum("k...i,...i->k...", unit, n)
    nv = np.einsum("...i,...i->...", v, n)[None]
    lit = (nl > 1e-6) & (nv > 1e-6) & (nh > 0)
    nh, nl, nvc = np.clip(nh, 1e-6, 1.0), np.clip(nl, 1e-6, 1.0), np.clip(nv, 1e-6, 1.0)
    d = a2 / (np.pi * (nh * nh * (a2 - 1.0) + 1.0) ** 2)
    return np.where(lit, E * d * _smith(nl, a2) * _smith(nvc, a2) / (4.0 * nvc), 0.0)


def ggx_lobe(normals, light_vectors, view, alpha: float) -> np.ndarray:
    """The GGX lobe term ``F_k(n)`` of every light at every pixel (see the module docstring).

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Unit normals.
    light_vectors : (N, 3) or (N, H, W, 3) array_like
        Scaled light vectors ``s_k`` (``|s_k|`` the irradiance).
    view : (3,) or (H, W, 3) array_like
        Direction from the surface towards the camera (orthographic: ``(0, 0, 1)``).
    alpha : float
        GGX roughness (> 0).

    Returns
    -------
    (N, H, W) float64 array
        ``|s_k| D G / (4 n . v)``; 0 where the light or the camera is below the surface.

    Examples
    --------
    Light and camera straight above a level pixel: ``D = 1 / (pi alpha^2)``, ``G = 1``:

    >>> f = ggx_lobe([[[0.0, 0.0, 1.0]]], [[0.0, 0.0, 2.0]], (0.0, 0.0, 1.0), 0.5)
    >>> round(float(f[0, 0, 0]), 6), round(2.0 / (np.pi * 0.25) / 4.0, 6)
    (0.63662, 0.63662)
    """
    n = as_array(normals, "normals", shape=(None, None, 3))
    shape = n.shape[:2]
    S = as_array(light_vectors, "light_vectors")
    if S.ndim == 2 and S.shape[1] == 3:
        S = np.broadcast_to(S[:, None, None, :], (len(S),) + shape + (3,))
    if S.ndim != 4 or S.shape[1:] != shape + (3,):
        raise InputError(f"light_vectors: expected (N, 3) or (N, {shape[0]}, {shape[1]}, 3), got {S.shape}")
    a = positive(alpha, "alpha")
    return _lobe(n, S, np.linalg.norm(S, axis=-1), _view(view, shape), a * a)


def lobe_weight(images, light_vectors, normals, view, alpha: float, valid=None) -> float:
    """The lobe weight ``c`` of a reference part of known normals (calibration).

    Per pixel ``I_k = a s_k . n + b F_k(n)`` is linear in ``a`` (the albedo) and ``b``
    (``albedo * c``); ``c`` is the median of ``b / a`` over the pixels with a solution.

    Parameters
    ----------
    images : (N, H, W) array_like
        The reference part's images (grey).
    light_vectors : (N, 3) or (N, H, W, 3) array_like
        Scaled light vectors at its points.
    normals : (H, W, 3) array_like
        Its known normals (a level plate: ``(0, 0, 1)`` everywhere).
    view : (3,) or (H, W, 3) array_like
        Direction towards the camera.
    alpha : float
        GGX roughness.
    valid : (H, W) bool array_like, optional
        Pixels to use (default all).

    Returns
    -------
    float
        ``c`` (0 for a matte part); NaN when no pixel has a solution.
    """
    imgs = as_array(images, "images", ndim=3)
    n = as_array(normals, "normals", shape=imgs.shape[1:] + (3,))
    F = ggx_lobe(n, light_vectors, view, alpha)
    S = as_array(light_vectors, "light_vectors")
    S = np.broadcast_to(S[:, None, None, :], F.shape + (3,)) if S.ndim == 2 else S
    sn = np.maximum(np.einsum("khwi,hwi->khw", S, n), 0.0)
    a00, a01, a11 = (sn * sn).sum(0), (sn * F).sum(0), (F * F).sum(0)
    b0, b1 = (sn * imgs).sum(0), (F * imgs).sum(0)
    det = a00 * a11 - a01 * a01
    ok = det > 1e-12 * np.maximum(a00 * a11, 1e-300)
    if valid is not None:
        ok &= as_array(valid, "valid", shape=imgs.shape[1:], dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (a11 * b0 - a01 * b1) / det
        b = (a00 * b1 - a01 * b0) / det
    ok &= a > 0
    return float(np.median(b[ok] / a[ok])) if ok.any() else float("nan")


def _normal(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    d = np.sqrt(1.0 + p * p + q * q)
    return np.stack([-p / d, -q / d, 1.0 / d], axis=-1)


def fit_glossy(images, light_vectors, view, alpha: float, weight: float, normals, albedo, valid=None,
               iterations: int = 15, dark: float | None = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Refine normals and albedo per pixel under the Lambertian + GGX model (see the module docstring).

    Minimises ``sum_k (I_k - albedo (s_k . n + c F_k(n)))^2`` over the slopes ``p, q`` of
    ``n = (-p, -q, 1) / |.|`` and the albedo, by Levenberg-Marquardt from the given
    (Lambertian) start, every pixel at once (the Jacobian's slope columns by forward
    differences); a step is kept only where it lowers the pixel's cost.

    Parameters
    ----------
    images : (N, H, W) array_like
        Grey images (N >= 4).
    light_vectors : (N, 3) or (N, H, W, 3) array_like
        Scaled light vectors ``s_k`` at the pixels' points.
    view : (3,) or (H, W, 3) array_like
        Direction towards the camera.
    alpha : float
        GGX roughness of the material.
    weight : float
        Lobe weight ``c`` (:func:`lobe_weight`; 0 gives the Lambertian least squares).
    normals : (H, W, 3) array_like
        Starting normals (e.g. the Lambertian solve's).
    albedo : (H, W) array_like
        Starting albedo.
    valid : (H, W) bool array_like, optional
        Pixels to refine (others are returned unchanged).
    iterations : int
        Levenberg-Marquardt steps.
    dark : float or None
        Observations darker than ``dark * albedo * |s_k|`` (the starting albedo) are left
        out of the pixel's fit: cast shadows, which neither model holds (as the outlier
        mode of :func:`photometric.nearfield.solve_nearfield` does); a pixel keeps at least
        4 observations (its brightest). None: every observation.

    Returns
    -------
    normals : (H, W, 3) float64 array
        Refined unit normals.
    albedo : (H, W) float64 array
        Refined albedo.
    rms : (H, W) float64 array
        RMS residual per pixel over the observations fitted (image units).

    Raises
    ------
    InputError
        Fewer than 4 images, bad shapes, or a negative weight.
    """
    imgs = as_array(images, "images", ndim=3)
    n_img, h, w = imgs.shape
    if n_img < 4:
        raise InputError(f"images: the glossy model needs at least 4 lights, got {n_img}")
    S = as_array(light_vectors, "light_vectors")
    if S.shape == (n_img, 3):
        S = np.broadcast_to(S[:, None, None, :], (n_img, h, w, 3))
    if S.shape != (n_img, h, w, 3):
        raise InputError(f"light_vectors: expected ({n_img}, 3) or ({n_img}, {h}, {w}, 3), got {S.shape}")
    v = _view(view, (h, w))
    a2 = positive(alpha, "alpha") ** 2
    c = positive(weight, "weight", allow_zero=True)
    n0 = as_array(normals, "normals", shape=(h, w, 3))
    rho0 = as_array(albedo, "albedo", shape=(h, w))
    ok = np.ones((h, w), bool) if valid is None else as_array(valid, "valid", shape=(h, w), dtype=bool)
    iterations = int(positive(iterations, "iterations", allow_zero=True))
    out_n = n0.astype(np.float64, copy=True)
    out_rho = rho0.astype(np.float64, copy=True)
    rms = np.zeros((h, w))
    for r0 in range(0, h, BLOCK_ROWS):
        rows = slice(r0, min(h, r0 + BLOCK_ROWS))
        m = ok[rows]
        if not m.any():
            continue
        X = imgs[:, rows][:, m]
        Sb = S[:, rows][:, m]
        rb = rho0[rows][m]
        W = None
        if dark is not None:
            bright = X >= dark * rb[None] * np.linalg.norm(Sb, axis=-1)
            # at least 4 observations: the brightest ones where shadows leave fewer
            rank = np.argsort(np.argsort(-X, axis=0), axis=0)
            W = (bright | (rank < 4)).astype(np.float64)
        nn, rr, res = _fit_pixels(X, Sb, v[rows][m], a2, c, n0[rows][m], rb, iterations, W)
        out_n[rows][m] = nn
        out_rho[rows][m] = rr
        rms[rows][m] = res
    return out_n, out_rho, rms


def _fit_pixels(X, S, v, a2, c, n0, rho, iterations, W=None):
    """Levenberg-Marquardt over P pixels: X (N, P), S (N, P, 3), v (P, 3), n0 (P, 3), rho (P,), weights W (N, P)."""
    W = np.ones(X.shape) if W is None else W
    E = np.linalg.norm(S, axis=-1)
    nz = np.where(np.abs(n0[:, 2]) > 1e-6, n0[:, 2], 1e-6)
    p, q = -n0[:, 0] / nz, -n0[:, 1] / nz
    rho = rho.astype(np.float64)

    geometry = _geometry(S, E, v)

    def model(pp, qq):
        n = _normal(pp, qq)
        return np.maximum(np.einsum("kpi,pi->kp", S, n), 0.0) + c * _lobe(n, S, E, v, a2, geometry)

    m = model(p, q)
    cost = (W * (X - rho * m) ** 2).sum(0)
    lam = np.full(p.shape, 1e-3)
    eps = 1e-6
    for _ in range(iterations):
        jp = rho * (model(p + eps, q) - m) / eps
        jq = rho * (model(p, q + eps) - m) / eps
        J = np.stack([jp, jq, m], axis=-1)  # d(prediction) / d(p, q, rho): (N, P, 3)
        A = np.einsum("kpi,kpj->pij", J * W[..., None], J)
        g = np.einsum("kpi,kp->pi", J, W * (X - rho * m))
        diag = np.einsum("pii->pi", A)
        A = A + (lam[:, None] * np.maximum(diag, 1e-12))[:, :, None] * np.eye(3)[None]
        try:
            d = np.linalg.solve(A, g[..., None])[..., 0]
        except np.linalg.LinAlgError:  # a singular pixel: no step anywhere this round
            break
        p2, q2, rho2 = p + d[:, 0], q + d[:, 1], rho + d[:, 2]
        m2 = model(p2, q2)
        cost2 = (W * (X - rho2 * m2) ** 2).sum(0)
        better = (cost2 < cost) & np.isfinite(cost2)
        p, q, rho = np.where(better, p2, p), np.where(better, q2, q), np.where(better, rho2, rho)
        m = np.where(better[None], m2, m)
        cost = np.where(better, cost2, cost)
        lam = np.where(better, lam * 0.3, lam * 10.0)
    return _normal(p, q), rho, np.sqrt(cost / W.sum(0))
