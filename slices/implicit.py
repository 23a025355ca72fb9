"""Branching and multi-body structures as one implicit surface: shape-based interpolation (issue 34).

Each plane's contours become a signed distance (mm, negative inside; an even-odd fill, so holes
and islands come out right): at the pixels beside the fill's edge, the signed distance to the
outline's local tangent line at its nearest point (the outline resampled at one pixel, SciPy's
k-d tree), so the zero level follows the contour to a small fraction of a pixel; elsewhere the
distance to the outline point of the nearest such pixel (OpenCV's distance transform with labels),
so the field is smooth, without the raster's half-pixel steps. The planes'
distances are blended across the planes with the seed's parabolic blending
(:func:`surfaces.blending.blend_weights`: the surface through three neighbouring planes, blended;
it passes through every plane's field), limited to keep the sign where two neighbouring planes
agree (so the parabolas' dips beside a ridge make no islands), sampled at :func:`z_samples` levels
per slice gap, and the zero level is extracted with scikit-image's Lewiner marching cubes on a padded volume, so the
surface is closed, manifold and one shell per connected part: bodies that meet are one solid, not
bodies touching along a seam.

Ends: beyond the first and the last plane a pad plane one slice spacing away holds
``-f (d / delta - 1)`` inside the end contours and ``f`` outside (``f`` the end plane's distance),
so the surface closes ``delta`` beyond the end plane: half a spacing for ``caps="half"`` (and
``"dome"``), :data:`FLAT_FRACTION` of it for ``"flat"`` (and ``"none"``: an implicit surface is
closed); single contours on an end plane (nothing on the neighbouring plane) always get a slab of
one spacing, as the seed's single-contour bodies do. Bodies that end inside the structure (a branch
stops, or a body lies on one plane) close half-way to the next plane (:func:`close_ends`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slices.io import Contour
from surfaces.mesh import TriangleMesh

#: Pixels (mm) of the in-plane raster: the structure's size (square root of its largest plane's
#: area) over this, clipped to :data:`PIXEL_RANGE_MM`.
PIXELS_ACROSS = 64

#: Finest and coarsest in-plane pixel (mm).
PIXEL_RANGE_MM = (0.25, 1.0)

#: Most grid values of the blended volume; a larger structure gets a coarser pixel.
MAX_VOXELS = 40_000_000

#: Signed distances are clipped to this many slice spacings (at least 8 pixels): far values would
#: reach across planes through the blend's negative weights (an empty plane beside a body).
CLAMP_SPACINGS = 3.0

#: Grid values closer to the level than this fraction of a pixel are moved to it (either side): every
#: vertex then lies at least about that far from a grid node and from the other vertices.
NODE_CLEARANCE = 0.02

#: Flat caps close this fraction of the slice spacing beyond the end planes (a zero-thickness cap
#: would put marching-cubes vertices on grid nodes: degenerate triangles).
FLAT_FRACTION = 0.01


@dataclass
class ImplicitSurface:
    """A structure's solid from its blended signed distances.

    Attributes
    ----------
    mesh : TriangleMesh
        The closed, outward oriented isosurface in mm.
    volume_mm3, area_mm2 : float
        The mesh's enclosed volume and area.
    pixel_mm : float
        In-plane raster pixel.
    z_samples : int
        Levels per slice gap (the blended field is sampled there; marching cubes interpolates
        linearly between them).
    cap_offset_mm : float
        How far beyond the end planes the surface closes.
    end_areas_mm2 : (float, float)
        Areas of the contours on the lowest and the highest plane (holes subtracted) that got the
        caps asked for (less the single contours there, which always get a slab of one spacing).
    spacing : float
        Slice spacing (mm).
    contours : list of Contour
        What the surface was built from.
    """

    mesh: TriangleMesh
    volume_mm3: float
    area_mm2: float
    pixel_mm: float
    z_samples: int
    cap_offset_mm: float
    end_areas_mm2: tuple[float, float]
    spacing: float
    contours: list = field(repr=False, default_factory=list)
    _deviation: float | None = field(default=None, repr=False)

    def volume_with_caps(self, caps: str) -> float:
        """The volume had the structure's end planes been capped with ``caps`` (mm^3).

        A cap ``delta`` beyond an end plane adds that plane's area times ``delta`` (``half``: half a
        spacing; ``flat``/``none``: none), against the cap the mesh got.
        """
        delta = self.spacing / 2 if caps in ("half", "dome") else 0.0
        return float(self.volume_mm3 + (delta - self.cap_offset_mm) * sum(self.end_areas_mm2))

    @property
    def max_deviation_mm(self) -> float:
        """Largest distance from a contour point to the nearest mesh vertex (mm; an upper bound of
        the distance to the surface, computed once when asked)."""
        if self._deviation is None:
            from scipy.spatial import cKDTree

            pts = np.concatenate([np.column_stack([c.points, np.full(len(c.points), c.z)]) for c in self.contours])
            self._deviation = float(cKDTree(self.mesh.vertices).query(pts)[0].max())
        return self._deviation


def pixel_size(z: np.ndarray, area: np.ndarray, extent: np.ndarray, n_planes: int, z_levels: int) -> float:
    """In-plane pixel (mm) for a structure: its size over :data:`PIXELS_ACROSS`, within :data:`PIXEL_RANGE_MM`
    and coarse enough that the blended volume stays under :data:`MAX_VOXELS` values.

    Parameters
    ----------
    z : numpy.ndarray, shape (C,)
        Each contour's plane (mm).
    area : numpy.ndarray, shape (C,)
        Each contour's area (mm^2).
    extent : numpy.ndarray, shape (2,)
        The structure's x and y extent (mm).
    n_planes, z_levels : int
        Planes and levels per gap of the blended volume.
    """
    per_plane = np.bincount(np.unique(np.round(z, 6), return_inverse=True)[1], np.abs(area))
    pixel = float(np.clip(np.sqrt(per_plane.max()) / PIXELS_ACROSS, *PIXEL_RANGE_MM))
    box = extent + 8 * pixel
    levels = max(n_planes - 1, 1) * z_levels + 5
    return float(max(pixel, np.sqrt(box[0] * box[1] * levels / MAX_VOXELS)))


def z_samples(spacing: float, pixel: float) -> int:
    """Levels per slice gap: about one per two pixels of the gap, 2 to 4 (the blend's mid-levels)."""
    return int(np.clip(np.ceil(spacing / (2.0 * pixel)), 2, 4))


def plane_distances(contours: list[Contour], hole: np.ndarray, plane_of: np.ndarray, n_planes: int,
                    lo: np.ndarray, shape: tuple[int, int], pixel: float, clamp: float) -> np.ndarray:
    """Signed distance (mm, negative inside) of every pixel centre of every plane to its contours.

    Parameters
    ----------
    contours : list of Contour
        Counter-clockwise contours.
    hole : numpy.ndarray, shape (N,) bool
        Which contours are holes (:class:`slices.chaining.Outlines`).
    plane_of : numpy.ndarray, shape (N,) int
        Each contour's plane index (0 .. n_planes - 1).
    n_planes : int
    lo : numpy.ndarray, shape (2,)
        x, y (mm) of pixel (0, 0)'s centre.
    shape : (int, int)
        Rows (y) and columns (x).
    pixel : float
        Pixel size (mm).
    clamp : float
        Distances are clipped to ``[-clamp, clamp]`` (mm): the blend's negative weights must not
        carry far values across planes.

    Returns
    -------
    numpy.ndarray, shape (n_planes, rows, cols) float32
        Planes without contours hold ``clamp``.
    """
    import cv2
    from scipy.spatial import cKDTree

    far = np.float32(clamp)
    sdf = np.full((n_planes, *shape), far, dtype=np.float32)
    # each plane in the box of its contours widened by the clamp: beyond it every distance is clamped
    pad = int(np.ceil(clamp / pixel)) + 2
    pix = [(c.points - lo) / pixel for c in contours]
    bands = []
    masks = np.zeros((n_planes, *shape), dtype=np.uint8)
    boxes = {}
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    for k in np.unique(plane_of):
        members = np.flatnonzero(plane_of == k)
        box_lo = np.floor(np.min([pix[i].min(axis=0) for i in members], axis=0)).astype(int) - pad
        box_hi = np.ceil(np.max([pix[i].max(axis=0) for i in members], axis=0)).astype(int) + pad + 1
        c0, r0 = np.maximum(box_lo, 0)
        c1, r1 = np.minimum(box_hi, (shape[1], shape[0]))
        m = np.zeros((r1 - r0, c1 - c0), np.uint8)
        img = np.empty_like(m)
        for i in members:
            img[:] = 0
            poly = np.round((pix[i] - (c0, r0)) * 16).astype(np.int32)
            cv2.fillPoly(img, [poly], 1, lineType=cv2.LINE_8, shift=4)
            m ^= img
        masks[k, r0:r1, c0:c1] = m
        boxes[int(k)] = (r0, r1, c0, c1)
        # the band: pixels with a 4-neighbour across the fill's edge
        rr, cc = np.nonzero((m != cv2.erode(m, cross)) | (m != cv2.dilate(m, cross)))
        bands.append((np.full(len(rr), k), rr + r0, cc + c0))
    # the outline resampled at one pixel, with its outward normals (outward of the solid: right of a
    # counter-clockwise outer contour, left of a hole's)
    samples, normals, planes, owners = [], [], [], []
    for k, c in enumerate(contours):
        p = c.points
        q = np.roll(p, -1, axis=0)
        seg = q - p
        length = np.linalg.norm(seg, axis=1)
        n_sub = np.maximum(np.ceil(length / pixel).astype(np.int64), 1)
        idx = np.repeat(np.arange(len(p)), n_sub)
        t = (np.arange(n_sub.sum()) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)) / n_sub[idx]
        samples.append(p[idx] + seg[idx] * t[:, None])
        direction = seg[idx] / np.maximum(length[idx], 1e-300)[:, None]
        out = np.column_stack([direction[:, 1], -direction[:, 0]])
        normals.append(-out if hole[k] else out)
        planes.append(np.full(len(idx), plane_of[k]))
        owners.append(np.full(len(idx), bool(hole[k])))
    samples, normals, planes = np.concatenate(samples), np.concatenate(normals), np.concatenate(planes)
    owners = np.concatenate(owners)
    kk, rr, cc = (np.concatenate(a) for a in zip(*bands))
    # the band: the signed distance to the tangent line at the nearest point of the outline
    big = 10.0 * (max(shape) + 2) * pixel  # planes far apart in the tree's third coordinate
    tree = cKDTree(np.column_stack([samples, planes * big]))
    xy = np.column_stack([lo[0] + cc * pixel, lo[1] + rr * pixel])
    _, near = tree.query(np.column_stack([xy, kk * big]))
    value = np.einsum("ij,ij->i", xy - samples[near], normals[near])
    # the tangent line's side can be wrong beside a corner; the fill cannot be, one way: OpenCV fills
    # every pixel the outline touches, so a pixel left out of an outer contour's fill is outside the
    # solid, and one left in beside a hole's outline is inside it
    filled = masks[kk, rr, cc] > 0
    by_hole = owners[near]
    value = np.where(~by_hole & ~filled, np.abs(value), np.where(by_hole & filled, -np.abs(value), value))
    nearest = samples[near]
    # elsewhere: the distance to the outline point of the nearest band pixel (OpenCV's distance transform
    # with the label of the nearest band pixel), its sign the fill's: consistent with the band's, so the
    # blend between planes sees a smooth field, not the raster's half-pixel steps
    start = np.searchsorted(kk, np.arange(n_planes + 1))
    for k, (r0, r1, c0, c1) in boxes.items():
        sl = slice(start[k], start[k + 1])
        src = np.ones((r1 - r0, c1 - c0), np.uint8)
        src[rr[sl] - r0, cc[sl] - c0] = 0
        _, labels = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, cv2.DIST_MASK_5,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
        lut = np.zeros(int(labels.max()) + 1, dtype=np.int64)
        lut[labels[rr[sl] - r0, cc[sl] - c0]] = np.arange(start[k], start[k + 1])
        owner = lut[labels]
        gy = (lo[1] + np.arange(r0, r1) * pixel)[:, None]
        gx = (lo[0] + np.arange(c0, c1) * pixel)[None, :]
        dist = np.sqrt((gx - nearest[owner, 0]) ** 2 + (gy - nearest[owner, 1]) ** 2)
        crop = np.where(masks[k, r0:r1, c0:c1] > 0, -dist, dist).astype(np.float32)
        crop[rr[sl] - r0, cc[sl] - c0] = value[sl]
        sdf[k, r0:r1, c0:c1] = np.clip(crop, -far, far)
    lonely = close_ends(sdf, masks, boxes)
    return sdf, lonely


def close_ends(sdf: np.ndarray, masks: np.ndarray, boxes: dict) -> tuple[np.ndarray, np.ndarray]:
    """Let every body (and every hole) that ends inside the structure close half-way to the next plane (in place).

    Where a connected region of a plane's fill overlaps nothing on the neighbouring plane (a branch
    or body stops there, or the next plane is empty), the neighbour's distances inside that region
    are lowered to the region's depth: ``min(d_next, |d_here|)`` (and those of the plane beyond, which
    the blend reaches too); where a hole of a plane meets only fill on the neighbour, the neighbour's
    distances there are raised to ``max(d_next, -|d_here|)``.
    They keep their sign (the neighbour's own zero level is untouched) and the blend changes sign
    half-way, the end-slice convention of the planning systems and of rasterise + marching cubes;
    unchanged, a small body would close a few tenths of the gap from its plane against a far
    neighbour.

    Parameters
    ----------
    sdf : numpy.ndarray, shape (P, rows, cols) float32
        The planes' signed distances (mm, negative inside), changed in place.
    masks : numpy.ndarray, shape (P, rows, cols) uint8
        The planes' even-odd fills.
    boxes : dict
        Plane index -> ``(r0, r1, c0, c1)``, the box holding that plane's fill and its clamp margin.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray), each shape (rows, cols) bool
        The regions of the first and of the last plane that overlap nothing on their neighbour (single
        contours: a slab of one spacing, whatever the caps).
    """
    import cv2

    n = len(sdf)
    lonely = [np.zeros(sdf.shape[1:], dtype=bool), np.zeros(sdf.shape[1:], dtype=bool)]
    for k, (r0, r1, c0, c1) in boxes.items():
        m = masks[k, r0:r1, c0:c1]
        count, labels = cv2.connectedComponents(m, connectivity=8)
        if count < 2:
            continue
        # the holes: components of the unfilled pixels that do not reach the box's border
        n_holes, hole_labels = cv2.connectedComponents((m == 0).astype(np.uint8), connectivity=4)
        border = np.unique(np.concatenate([hole_labels[0], hole_labels[-1], hole_labels[:, 0], hole_labels[:, -1]]))
        here = sdf[k, r0:r1, c0:c1]
        for other in (k - 1, k + 1):
            if not 0 <= other < n:
                continue  # beyond the end planes: the pad planes close the structure
            there = masks[other, r0:r1, c0:c1] > 0
            target = sdf[other, r0:r1, c0:c1]
            touched = np.zeros(count, dtype=bool)
            touched[labels[there]] = True
            touched[0] = True
            if not touched.all():
                region = ~touched[labels]
                for end, plane in enumerate((0, n - 1)):
                    if k == plane:
                        lonely[end][r0:r1, c0:c1] |= region
                # the fill's edge pixels may lie just outside the outline (OpenCV fills every pixel it touches):
                # their depth is their distance, never a sign change on the neighbour
                depth = np.abs(here[region])
                target[region] = np.minimum(target[region], depth)
                if 0 <= 2 * other - k < n:
                    # the plane beyond too, so that the blend (which reaches two planes) closes half-way
                    beyond = sdf[2 * other - k, r0:r1, c0:c1]
                    beyond[region] = np.minimum(beyond[region], depth)
            if n_holes > 1:
                # a hole that ends (the neighbour is filled all across it) closes half-way too
                open_ = np.zeros(n_holes, dtype=bool)
                open_[hole_labels[~there]] = True
                open_[0] = True
                open_[border] = True
                if not open_.all():
                    region = ~open_[hole_labels]
                    depth = -np.abs(here[region])
                    target[region] = np.maximum(target[region], depth)
                    if 0 <= 2 * other - k < n:
                        beyond = sdf[2 * other - k, r0:r1, c0:c1]
                        beyond[region] = np.maximum(beyond[region], depth)
    if n == 1:
        lonely = [masks[0] > 0, masks[0] > 0]
    return lonely[0], lonely[1]


def implicit_surface(contours: list[Contour], spacing: float, *, caps: str = "flat",
                     irregular: bool = False, outlines=None) -> ImplicitSurface:
    """One closed surface of a structure from its contours' blended signed distances (module docstring).

    Parameters
    ----------
    contours : list of Contour
        Counter-clockwise contours in mm (several per plane, holes inside outer ones).
    spacing : float
        Slice spacing in mm (planes are ``z0 + k spacing``; planes without contours are empty).
    caps : {"none", "flat", "half", "dome"}
        How far beyond the end planes the surface closes (module docstring).
    irregular : bool
        The planes are where the contours are (unequal spacing); the blend uses their positions.
    outlines : slices.chaining.Outlines, optional
        The contours' table when the caller has built it already.

    Returns
    -------
    ImplicitSurface

    Examples
    --------
    A cylinder of radius 10 mm drawn as 64-point circles on four planes 2 mm apart; half caps
    make it 8 mm tall, a closed surface of volume ``pi r^2 h`` (the polygons' area, to marching
    cubes' chamfered rims):

    >>> import numpy as np
    >>> from slices.io import Contour
    >>> t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    >>> disc = 10 * np.stack([np.cos(t), np.sin(t)], axis=1)
    >>> imp = implicit_surface([Contour(z, disc) for z in (0.0, 2.0, 4.0, 6.0)], 2.0, caps="half")
    >>> imp.mesh.is_watertight(), round(imp.volume_mm3 / (np.pi * 100 * 8), 2)
    (True, 1.0)
    """
    from scipy import sparse
    from skimage.measure import marching_cubes

    from slices.chaining import Outlines
    from surfaces.blending import blend_weights

    outlines = Outlines.of(contours) if outlines is None else outlines
    zc = np.round([c.z for c in contours], 6)
    z_all = np.unique(zc)
    if irregular or len(z_all) < 2:
        planes = z_all
    else:
        steps = np.round((z_all - z_all[0]) / spacing).astype(np.int64)
        planes = z_all[0] + spacing * np.arange(steps[-1] + 1)
    n = len(planes)
    plane_of = np.clip(np.searchsorted(planes, zc - 1e-6 * max(spacing, 1.0)), 0, n - 1)
    pts = np.concatenate([c.points for c in contours])
    extent = np.ptp(pts, axis=0)
    levels = z_samples(spacing, pixel_size(zc, outlines.area, extent, n, 4))
    pixel = pixel_size(zc, outlines.area, extent, n, levels)
    margin = 4 * pixel
    lo = pts.min(axis=0) - margin
    shape = (int(np.ceil((pts[:, 1].max() + margin - lo[1]) / pixel)) + 1,
             int(np.ceil((pts[:, 0].max() + margin - lo[0]) / pixel)) + 1)
    clamp = max(CLAMP_SPACINGS * spacing, 8 * pixel)
    sdf, lonely = plane_distances(contours, outlines.hole, plane_of, n, lo, shape, pixel, clamp)
    sdf = sdf.reshape(n, -1)

    # the fine levels: parabolic blending between planes (Bernstein weights of the Bezier rows)
    delta = spacing / 2 if caps in ("half", "dome") else FLAT_FRACTION * spacing
    if n > 1:
        w = blend_weights(n, planes if irregular else None)  # (n - 1, 4, n)
        t = np.arange(levels) / levels
        bern = np.stack([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t**2 * (1 - t), t**3], axis=1)  # (L, 4)
        rows = np.einsum("lb,jbk->jlk", bern, w).reshape(-1, n)
        rows = np.vstack([rows, np.eye(n)[-1:]])
        z_fine = np.concatenate([(planes[:-1, None] + np.diff(planes)[:, None] * t[None, :]).ravel(), planes[-1:]])
        fine = (sparse.csr_matrix(np.where(np.abs(rows) < 1e-12, 0.0, rows)) @ sdf).astype(np.float32)
        # sign-preserving: where two neighbouring planes agree in sign the blend keeps it (at least a
        # quarter of the smaller magnitude), so it changes sign only where they differ: no islands where the
        # parabolas dip below zero beside a ridge, and the blend's overshoot is kept elsewhere (a limit to
        # the two values would flatten every extremum across the planes into a rib)
        inner = fine[:-1].reshape(n - 1, levels, -1)
        a, b = sdf[:-1], sdf[1:]
        big = np.float32(np.abs(sdf).max() * 4 + 1)
        low = np.where((a > 0) & (b > 0), 0.25 * np.minimum(a, b), -big).astype(np.float32)
        high = np.where((a < 0) & (b < 0), 0.25 * np.maximum(a, b), big).astype(np.float32)
        np.clip(inner, low[:, None, :], high[:, None, :], out=inner)
        del low, high
    else:
        z_fine, fine = planes, sdf.astype(np.float32)
    del sdf
    # single contours on an end plane (nothing above or below on the neighbour) keep a slab of one spacing
    ratio_lo = np.where(lonely[0].ravel(), np.float32(1.0), np.float32(spacing / delta - 1.0))
    ratio_hi = np.where(lonely[1].ravel(), np.float32(1.0), np.float32(spacing / delta - 1.0))
    first, last = fine[0], fine[-1]
    pad_lo = np.where(first < 0, -first * ratio_lo, first)
    pad_hi = np.where(last < 0, -last * ratio_hi, last)
    outer = np.float32(np.abs(fine).max() + spacing)
    # two levels around the cap between each end plane and its pad (at t * delta / spacing with t = 1/2 and
    # 3/2 for flat caps, 1/2 and 3/2 of half a gap for half caps): the cap's rim is then chamfered over a
    # third of the gap or less, not over the whole gap
    t_cap = delta / spacing
    low, high = 0.5 * t_cap, t_cap + 0.5 * min(t_cap, 1.0 - t_cap)
    field_ = np.empty((len(fine) + 8, fine.shape[1]), dtype=np.float32)
    field_[0], field_[1] = outer, pad_lo
    field_[2], field_[3] = first + np.float32(high) * (pad_lo - first), first + np.float32(low) * (pad_lo - first)
    field_[4:-4] = fine
    field_[-4], field_[-3] = last + np.float32(low) * (pad_hi - last), last + np.float32(high) * (pad_hi - last)
    field_[-2], field_[-1] = pad_hi, outer
    del fine
    z_grid = np.concatenate([[planes[0] - 2 * spacing, planes[0] - spacing, planes[0] - high * spacing,
                              planes[0] - low * spacing], z_fine,
                             [planes[-1] + low * spacing, planes[-1] + high * spacing, planes[-1] + spacing,
                              planes[-1] + 2 * spacing]])
    # no value at or near the level: marching cubes would put vertices on or next to grid nodes
    # (degenerate triangles, and vertices that a weld would merge into non-manifold edges)
    tiny = np.float32(NODE_CLEARANCE * pixel)
    near = np.abs(field_) < tiny
    field_[near] = np.where(field_[near] < 0, -tiny, tiny)
    volume = field_.reshape(len(z_grid), *shape)
    verts, faces, _, _ = marching_cubes(volume, 0.0, method="lewiner", allow_degenerate=False)
    xyz = np.column_stack([lo[0] + verts[:, 2] * pixel, lo[1] + verts[:, 1] * pixel,
                           np.interp(verts[:, 0], np.arange(len(z_grid)), z_grid)])
    faces = faces.astype(np.int64)
    # volume and area in one pass over the triangles
    corner = xyz[faces]
    cross = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    enclosed = float(np.einsum("ij,ij->", corner[:, 0], cross)) / 6.0
    surface = 0.5 * float(np.sqrt(np.einsum("ij,ij->i", cross, cross)).sum())
    if enclosed < 0:
        faces, enclosed = np.ascontiguousarray(faces[:, ::-1]), -enclosed
    mesh = TriangleMesh.unchecked(xyz, faces)
    sign = np.where(outlines.hole, -1.0, 1.0)
    area = np.abs(outlines.area) * sign
    # the end planes' areas that got the caps asked for (single contours there got a whole slab)
    ends = tuple(max(float(area[plane_of == p].sum()) - float(lone.sum()) * pixel**2, 0.0)
                 for p, lone in ((0, lonely[0]), (n - 1, lonely[1])))
    return ImplicitSurface(mesh, enclosed, surface, pixel,
                           levels, float(delta), ends, float(spacing), list(contours))
