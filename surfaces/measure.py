"""Area and enclosed volume of the patch model, by Gauss-Legendre quadrature.

Both integrate over the patches themselves, not over a triangle mesh:

* area ``A = sum_patches  int int |S_u x S_v| du dv``. The integrand is the
  square root of a polynomial; ``order``-point rules converge fast for smooth
  patches (on a 32x16 Coons sphere, 8 points per direction agree with 16 to
  better than 1e-9 relative). :func:`area` can return the difference to an
  ``order + 4`` rule as an error estimate.
* volume by the divergence theorem with ``F = x / 3``:
  ``V = 1/3 sum_patches int int S . (S_u x S_v) du dv``. For bicubic patches the
  integrand is a polynomial of degree 8 in each parameter, so the 5-point rule
  (exact to degree 9) is exact up to rounding. The sign is positive when
  ``S_u x S_v`` points out of the enclosed region.
* a tube (closed around, open at its ends, e.g. a swept pipe) gets the flux
  through cone caps over its end curves (:func:`cap_flux`), so that
  :func:`area_and_volume` reports the volume of the solid it bounds.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from surfaces.bezier import BezierPatches, bernstein
from surfaces.vectors import cross
from surfaces.validate import InputError

#: Quadrature points (patches times nodes) evaluated per chunk: the temporaries of a chunk (~200 kB
#: each) stay in the CPU caches, in few enough chunks that the per-operation costs stay small (measured
#: on real sides of 4,000-12,000 patches: 7 % faster than chunks of 6,400, three times faster than none).
_POINT_CHUNK = 25600


def gauss_legendre(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on ``[0, 1]``: the quadrature rule of every integral here.

    Exact for polynomials up to degree ``2 order - 1``. One rule for the package
    and its callers (``slices.caps`` integrates its extrusions' curve lengths with
    it), made once per order and shared read-only.

    Parameters
    ----------
    order : int
        Number of nodes (at least 1).

    Returns
    -------
    nodes, weights : numpy.ndarray, shape (order,), float64
        Read-only; the weights sum to 1.

    Raises
    ------
    InputError
        When ``order`` is below 1.

    Examples
    --------
    >>> t, w = gauss_legendre(3)
    >>> bool(abs(w @ t**5 - 1 / 6) < 1e-15), bool(abs(w @ t**6 - 1 / 7) > 1e-5)  # exact to degree 5, not 6
    (True, True)
    """
    order = int(order)
    if order < 1:
        raise InputError(f"order: need at least 1 quadrature point, got {order}")
    return _gauss_cached(order)


@lru_cache(maxsize=32)
def _gauss_cached(order: int) -> tuple[np.ndarray, np.ndarray]:
    # leggauss solves an eigenproblem on every call; measuring many small bodies asks for the
    # same few orders again and again. Read-only, so no caller can alter the shared nodes.
    x, w = np.polynomial.legendre.leggauss(order)
    nodes, weights = 0.5 * (x + 1.0), 0.5 * w
    nodes.flags.writeable = False
    weights.flags.writeable = False
    return nodes, weights


@lru_cache(maxsize=32)
def _node_basis(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Tensor weights of the 16 control points for ``S``, ``S_u``, ``S_v`` at the nodes (3 order^2, 16),
    and the node weights (order^2,); read-only, made once per order."""
    t, w = gauss_legendre(order)
    b0, b1 = bernstein(t), bernstein(t, 1)

    def tensor(bu, bv):
        return (bu[:, None, :, None] * bv[None, :, None, :]).reshape(-1, 16)

    basis = np.vstack([tensor(b0, b0), tensor(b1, b0), tensor(b0, b1)])
    weights = np.outer(w, w).ravel()
    basis.flags.writeable = False
    weights.flags.writeable = False
    return basis, weights


@lru_cache(maxsize=32)
def _derivative_basis(order: int) -> np.ndarray:
    """The ``S_u`` and ``S_v`` rows of :func:`_node_basis` (2 order^2, 16), contiguous and read-only."""
    basis, weights = _node_basis(order)
    out = np.ascontiguousarray(basis[len(weights):])
    out.flags.writeable = False
    return out


def _per_patch(patches: BezierPatches, order: int, integrands) -> list[np.ndarray]:
    """Integrate each ``integrand(points, normal)`` over every patch; one array (P,) per integrand."""
    if not isinstance(patches, BezierPatches):
        raise InputError(f"patches: expected BezierPatches, got {type(patches).__name__}")
    return _quadrature(patches.control, int(order), integrands)


def _quadrature(control: np.ndarray, order: int, integrands) -> list[np.ndarray]:
    """:func:`_per_patch` on control points (R, C, 4, 4, 3) as they are (a view of a grid's columns too).

    ``points`` and ``normal`` (the unnormalised ``S_u x S_v``) are (x, y, z) tuples of
    (order^2, chunk) arrays, one column per patch; one matrix product per chunk evaluates ``S``,
    ``S_u`` and ``S_v`` at every node, and one more sums the integrand with the node weights.
    """
    basis, weights = _node_basis(order)
    q = len(weights)
    n_rows, n_cols = control.shape[:2]
    out = [np.empty(n_rows * n_cols) for _ in integrands]
    # chunks of whole patch rows: a view of some columns is copied a chunk at a time
    rows = max(1, _POINT_CHUNK // (q * n_cols))
    for r in range(0, n_rows, rows):
        part = control[r:r + rows]
        k = part.shape[0] * n_cols
        start = r * n_cols
        # coordinate-major (16, 3, k) in one copy: every component below is a contiguous (q, k) block
        coords = np.ascontiguousarray(part.transpose(2, 3, 4, 0, 1)).reshape(16, 3 * k)
        values = (basis @ coords).reshape(3, q, 3, k)
        s, du, dv = values
        ux, uy, uz = du[:, 0], du[:, 1], du[:, 2]
        vx, vy, vz = dv[:, 0], dv[:, 1], dv[:, 2]
        # the cross product written out: numpy's over a short last axis costs more than the arithmetic
        nx = uy * vz
        nx -= uz * vy
        ny = uz * vx
        ny -= ux * vz
        nz = ux * vy
        nz -= uy * vx
        point, normal = (s[:, 0], s[:, 1], s[:, 2]), (nx, ny, nz)
        for arr, integrand in zip(out, integrands):
            arr[start:start + k] = weights @ integrand(point, normal)
    return out


def side_integrals(control: np.ndarray, order: int = 5) -> tuple[float, float]:
    """Summed flux of ``(0, 0, z)`` and area of the patches ``control`` (R, C, 4, 4, 3), unchecked.

    Over a closed grid the flux is its volume (:func:`flux_z`; positive when ``S_u x S_v`` points
    outward), and equals :func:`integrals`' volume up to rounding; over some of its columns it is their
    share of it. For callers that hold a valid grid (a view of some of its columns too), without
    building :class:`surfaces.bezier.BezierPatches`.

    Patches whose ``z`` depends on ``v`` alone (every row of control points at one height, as a side
    surface's between planar slices) have ``S_u`` horizontal: their integrands are formed from ``x``
    and ``y`` at the nodes and each patch's ``z(v)`` (the same integrals, a third of the work less).

    Parameters
    ----------
    control : numpy.ndarray, shape (R, C, 4, 4, 3)
        Finite control points (mm), taken as they are.
    order : int
        Quadrature points per direction (5: the flux is exact).

    Returns
    -------
    flux, area : float
        mm^3 and mm^2.
    """
    order = int(order)
    basis, weights = _node_basis(order)
    q, n = len(weights), order
    derivatives = _derivative_basis(order)
    v_weighted, v_derivative = _v_basis(order)
    w = gauss_legendre(order)[1]
    n_rows, n_cols = control.shape[:2]
    flux = area = 0.0
    # chunks of whole patch rows: a view of some columns is copied a chunk at a time
    rows = max(1, _POINT_CHUNK // (q * n_cols))
    # every chunk in the same memory (fresh arrays per chunk cost their allocations' page faults)
    size = min(rows, n_rows) * n_cols
    copy_buffer, x_buffer, y_buffer = np.empty(48 * size), np.empty(2 * q * size), np.empty(2 * q * size)
    nz_buffer, t_buffer = np.empty(q * size), np.empty(q * size)
    for r in range(0, n_rows, rows):
        part = control[r:r + rows]
        k = part.shape[0] * n_cols
        # coordinate-major (16, 3, k) in one copy: every component below is one contiguous (q, k) block
        coords = copy_buffer[:48 * k].reshape(16, 3, k)
        coords.reshape(4, 4, 3, part.shape[0], n_cols)[...] = part.transpose(2, 3, 4, 0, 1)
        ux, vx = np.matmul(derivatives, coords[:, 0], out=x_buffer[:2 * q * k].reshape(2 * q, k)).reshape(2, q, k)
        uy, vy = np.matmul(derivatives, coords[:, 1], out=y_buffer[:2 * q * k].reshape(2 * q, k)).reshape(2, q, k)
        cz = coords[:, 2]
        nz = np.multiply(ux, vy, out=nz_buffer[:q * k].reshape(q, k))
        t = np.multiply(uy, vx, out=t_buffer[:q * k].reshape(q, k))
        nz -= t
        if not (cz[4:].reshape(3, 4, k) != cz[:4]).any():
            # every row of control points at one height (a side between planar slices): S_u is
            # horizontal, z and z_v vary with v alone, and |S_u x S_v|^2 = (x_u^2 + y_u^2) z_v^2 + nz^2.
            # The flux sum_ij w_i w_j z_j nz_ij: nz summed over u first, then against the weighted z
            flux += float(np.dot(w @ nz.reshape(n, n * k), (v_weighted @ cz[:4]).reshape(-1)))
            dz = v_derivative @ cz[:4]
            dz *= dz
            ux *= ux
            uy *= uy
            ux += uy
            ux.reshape(n, n, k)[:] *= dz
            nz *= nz
            ux += nz
            area += float(np.dot(np.sqrt(ux, out=ux).sum(axis=1), weights))
            continue
        z = basis[:q] @ cz
        uz, vz = (derivatives @ cz).reshape(2, q, k)
        z *= nz
        flux += float(np.sum(weights @ z))
        # the rest of S_u x S_v written out, one scratch array for the products subtracted
        np.multiply(uz, vy, out=t)
        nx = uy * vz
        nx -= t
        np.multiply(ux, vz, out=t)
        ny = uz * vx
        ny -= t
        nx *= nx
        ny *= ny
        nx += ny
        nz *= nz
        nx += nz
        area += float(np.sum(weights @ np.sqrt(nx, out=nx)))
    return flux, area


@lru_cache(maxsize=32)
def _v_basis(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Bernstein weights (order, 4) of the points, times the nodes' Gauss weights, and of the derivatives
    at the ``v`` nodes (read-only)."""
    t, w = gauss_legendre(order)
    b0, b1 = w[:, None] * bernstein(t), bernstein(t, 1)
    b0.flags.writeable = False
    b1.flags.writeable = False
    return b0, b1


def _area_density(s, n):
    a = n[0] * n[0]
    a += n[1] * n[1]
    a += n[2] * n[2]
    return np.sqrt(a, out=a)


def _volume_density(s, n):
    v = s[0] * n[0]
    v += s[1] * n[1]
    v += s[2] * n[2]
    v /= 3.0
    return v


def _result(values: np.ndarray, patches: BezierPatches, per_patch: bool):
    return values.reshape(patches.shape) if per_patch else float(values.sum())


def area(patches: BezierPatches, order: int = 8, return_error: bool = False, per_patch: bool = False):
    """Surface area by Gauss-Legendre quadrature over every patch.

    Parameters
    ----------
    patches : BezierPatches
        The surface.
    order : int
        Quadrature points per direction and patch (default 8).
    return_error : bool
        Also return ``|A(order) - A(order + 4)|`` as an error estimate.
    per_patch : bool
        Return the ``(R, C)`` array of every patch's area instead of the sum.

    Returns
    -------
    float or numpy.ndarray, and optionally the error estimate
        Area in squared model units (mm^2 for CT surfaces).

    Examples
    --------
    >>> from surfaces.coons import from_grid
    >>> x, y = np.meshgrid([0.0, 1.0], [0.0, 1.0], indexing="ij")
    >>> area(from_grid(np.stack([x, y, np.zeros_like(x)], axis=-1)))  # the unit square
    1.0
    """
    (value,) = _per_patch(patches, order, [_area_density])
    if not return_error:
        return _result(value, patches, per_patch)
    (finer,) = _per_patch(patches, order + 4, [_area_density])
    return _result(value, patches, per_patch), _result(np.abs(finer - value), patches, per_patch)


class InwardOrientationWarning(UserWarning):
    """A closed surface whose ``S_u x S_v`` points inward: its signed volume is negative."""


def encloses(patches: BezierPatches) -> bool:
    """Whether the patches bound a solid on their own: closed in both directions, or closed in one
    with both ends of the other collapsed to poles (a sphere grid either way round).

    Parameters
    ----------
    patches : BezierPatches

    Returns
    -------
    bool

    Examples
    --------
    >>> from surfaces.coons import from_grid
    >>> th, ph = np.meshgrid(np.linspace(0, np.pi, 9), np.linspace(0, 2 * np.pi, 16, endpoint=False), indexing="ij")
    >>> ball = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    >>> encloses(from_grid(ball, closed_v=True)), encloses(from_grid(ball[1:-1], closed_v=True))
    (True, False)
    """
    c = patches.control
    tol = 1e-12 * max(1.0, float(np.abs(c).max()))

    def collapsed(*edges) -> bool:
        return all(np.ptp(e.reshape(-1, 3), axis=0).max() <= tol for e in edges)

    if patches.closed_u and patches.closed_v:
        return True
    if patches.closed_v:
        return collapsed(c[0, :, 0], c[-1, :, 3])
    if patches.closed_u:
        return collapsed(c[:, 0, :, 0], c[:, -1, :, 3])
    return False


def volume(patches: BezierPatches, order: int = 5, per_patch: bool = False):
    """Enclosed volume by the divergence theorem, integrated over the patches.

    Parameters
    ----------
    patches : BezierPatches
        A closed surface (or an open one whose missing parts the caller adds
        as further flux terms).
    order : int
        Quadrature points per direction (5 is exact for bicubic patches).
    per_patch : bool
        Return the ``(R, C)`` array of every patch's flux contribution instead of the sum.

    Returns
    -------
    float or numpy.ndarray
        ``1/3 * flux of x`` through the surface, in cubed model units; positive
        when ``S_u x S_v`` points outward. The sign is kept (callers add signed
        fluxes); a surface that :func:`encloses` a solid with a negative total
        gets an :class:`InwardOrientationWarning` saying so (use
        ``patches.flipped()`` or :func:`area_and_volume`, which orients it).

    Warns
    -----
    InwardOrientationWarning
        The patches enclose a solid and ``S_u x S_v`` points inward (not with
        ``per_patch``).

    Examples
    --------
    A torus of radii 3 and 1 from a closed 24 x 12 grid: ``2 pi^2 R r^2 = 59.22`` (the
    Coons patches through the grid points enclose slightly less).

    >>> from surfaces.coons import from_grid
    >>> a, b = np.meshgrid(np.linspace(0, 2 * np.pi, 24, endpoint=False),
    ...                    np.linspace(0, 2 * np.pi, 12, endpoint=False), indexing="ij")
    >>> ring = np.stack([(3 + np.cos(b)) * np.cos(a), (3 + np.cos(b)) * np.sin(a), np.sin(b)], -1)
    >>> v = volume(from_grid(ring, closed_u=True, closed_v=True))
    >>> bool(abs(v / (2 * np.pi**2 * 3) - 1) < 5e-3)
    True

    A sphere grid with the angle around first (``S_u x S_v`` inward) warns and
    keeps its sign:

    >>> import warnings
    >>> ph, th = np.meshgrid(np.linspace(0, 2 * np.pi, 16, endpoint=False), np.linspace(0, np.pi, 9), indexing="ij")
    >>> ball = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     v = volume(from_grid(ball, closed_u=True))
    >>> round(v, 2), caught[0].category.__name__
    (-4.18, 'InwardOrientationWarning')
    """
    value = _signed_volume(patches, order, per_patch)
    if not per_patch:
        _warn_inward(value, patches)
    return value


def _warn_inward(value: float, patches: BezierPatches) -> None:
    if value < 0 and encloses(patches):
        import warnings

        warnings.warn(f"volume: the patches enclose a solid but S_u x S_v points inward, so the signed volume is "
                      f"{value:.6g} (returned as it is; patches.flipped() or area_and_volume() orient it: "
                      f"{-value:.6g})", InwardOrientationWarning, stacklevel=3)


def _signed_volume(patches: BezierPatches, order: int = 5, per_patch: bool = False):
    (value,) = _per_patch(patches, order, [_volume_density])
    return _result(value, patches, per_patch)


def integrals(patches: BezierPatches, order: int = 5, per_patch: bool = False):
    """Volume and area in one pass (one evaluation of the patches).

    Parameters
    ----------
    patches : BezierPatches
        The surface.
    order : int
        Quadrature points per direction (5: exact volume, area to about 1e-8
        relative on smooth surfaces).
    per_patch : bool
        Return ``(R, C)`` arrays instead of sums.

    Returns
    -------
    volume, area : float or numpy.ndarray
        As :func:`volume` (with its :class:`InwardOrientationWarning`) and :func:`area`.
    """
    vol, ar = _per_patch(patches, order, [_volume_density, _area_density])
    vol = _result(vol, patches, per_patch)
    if not per_patch:
        _warn_inward(vol, patches)
    return vol, _result(ar, patches, per_patch)


def flux_z(patches: BezierPatches, order: int = 5) -> float:
    """Flux of the field ``F = (0, 0, z)`` through the surface.

    For a closed surface this is also the enclosed volume; for a surface open
    at planes ``z = const`` (a CT stack) the missing planar caps contribute
    ``z0 * (signed cap area)``, which makes capping a volume computation easy.

    Parameters
    ----------
    patches : BezierPatches
        The surface.
    order : int
        Quadrature points per direction (5 is exact for bicubic patches).

    Returns
    -------
    float
        ``int z n_z dA`` in cubed model units.
    """
    (value,) = _per_patch(patches, order, [lambda s, n: s[2] * n[2]])
    return float(value.sum())


def _vector_area(segments: np.ndarray) -> np.ndarray:
    """``1/2 closed-integral x cross dx`` of closed piecewise-cubic Bezier curves (S, 4, 3)."""
    t, w = gauss_legendre(3)  # the integrand has degree 5: three Gauss points are exact
    x = np.einsum("ta,sak->stk", bernstein(t), segments)
    dx = np.einsum("ta,sak->stk", bernstein(t, 1), segments)
    return 0.5 * np.einsum("t,stk->k", w, cross(x, dx))


def cap_flux(patches: BezierPatches) -> float:
    """Flux ``int x . n dA`` through cone caps closing the v-ends of a tube (closed in u).

    The cap of an end curve is the cone from its control-point centroid ``c``;
    its flux is ``c . A`` with ``A`` the curve's vector area, exact for planar ends
    (any cap with that boundary gives the same flux up to the volume between caps).
    Oriented to continue the patches' ``S_u x S_v`` orientation.

    Parameters
    ----------
    patches : BezierPatches
        A tube: closed in u, open in v.

    Returns
    -------
    float
        Sum of both caps' fluxes in cubed model units (divide by 3 for their
        volume contribution).
    """
    if not patches.closed_u or patches.closed_v:
        raise InputError("patches: caps close a surface that is closed in u and open in v")
    start = patches.control[:, 0, :, 0]  # (R, 4, 3): v = 0 boundary, u increasing
    end = patches.control[:, -1, :, 3]
    c0, c1 = start.reshape(-1, 3).mean(0), end.reshape(-1, 3).mean(0)
    return float(-np.dot(c0, _vector_area(start)) + np.dot(c1, _vector_area(end)))


def area_and_volume(patches: BezierPatches) -> dict:
    """Area and enclosed volume of a surface, closing the open ends of a tube by caps.

    Volume: the divergence theorem over the patches (:func:`volume`) plus
    :func:`cap_flux` / 3 for a tube open at its ends; ``None`` when the surface does
    not bound a solid (open in u and not closed off by poles, e.g. a helicoid).

    Parameters
    ----------
    patches : BezierPatches
        The surface (e.g. a kinematic surface's ``to_bezier()``).

    Returns
    -------
    dict
        ``area`` (model units^2), ``volume`` (units^3, absolute) or None,
        ``volume_method`` (str), ``orientation`` ("outward"/"inward"/None: of ``S_u x S_v``).
    """
    out = {"area": float(area(patches)), "volume": None, "volume_method": None, "orientation": None}
    if patches.closed_u and patches.closed_v:
        signed, method = _signed_volume(patches), "divergence theorem (closed surface)"
    elif patches.closed_u:
        signed, method = _signed_volume(patches) + cap_flux(patches) / 3.0, "divergence theorem + end caps"
    elif patches.closed_v and encloses(patches):
        signed, method = _signed_volume(patches), "divergence theorem (closed by poles)"
    else:
        return out
    out.update(volume=abs(float(signed)), volume_method=method,
               orientation="outward" if signed >= 0 else "inward")
    return out
