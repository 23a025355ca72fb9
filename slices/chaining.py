"""Several contours per slice: holes by containment, bodies by overlap across slices.

On each plane a contour inside an odd number of other contours is a hole
(inner contour); the others are outer contours (an island inside a hole is
outer again). Contours of the same kind on neighbouring planes (one slice
spacing apart) are linked when their polygons overlap (rasterised test). A
chain continues while a contour has exactly one linked successor and that
successor exactly one linked predecessor; a branching (two successors), a
merge (two predecessors), a gap in the planes or the end of the structure ends
it. Every chain is one body, reconstructed on its own; hole bodies are
subtracted.

Branchings and merges are joined as SlicerRT joins them, without a shelf: where
one contour overlaps several on the next plane (and each of those overlaps it
alone), the contour is split along the mid-line between the others'
projections (:func:`split_contour`: every point of the parent goes to the
nearest child), and each part starts its child's chain on the parent's plane.
The parent's chain and the children's meet there in flat, coincident caps
(chain ends ``"split"``), which the union of the bodies removes. A merge is the
mirror image. Contours that both merge and branch keep the half caps that meet
half-way between the planes (ends ``"branch"``/``"merge"``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slices.polygons import signed_area
from slices.io import SPACING_RTOL, Contour
from surfaces.validate import InputError

#: Pixels along the longer side of the raster used for overlap tests.
_RASTER = 256

#: Pixels along the longer side of the raster that finds the mid-line of a split contour.
SPLIT_RASTER = 512

#: Largest ratio between a child's area and its part of a split contour (either way round). Beyond
#: it the child does not continue its part (a small lobe tip beside a large parent would have to
#: loft from a wide wedge into a small outline, and such lofts fold); the half caps stay.
SPLIT_AREA_RATIO = 2.5


@dataclass(frozen=True)
class Body:
    """One chain of contours on consecutive planes.

    Attributes
    ----------
    kind : str
        ``"outer"`` or ``"hole"``.
    contours : tuple of Contour
        One per plane, increasing ``z``.
    start : str
        Why the chain starts: ``"end"`` (nothing below), ``"branch"`` (the contour
        below splits), ``"merge"``, or ``"split"`` (its first contour is this
        chain's part of a contour split at a branching or merge, or the chain
        continues from such a split above its first plane: a flat joint).
    stop : str
        Why it stops: ``"end"``, ``"branch"``, ``"merge"``, ``"split"``; or ``"step"``
        (start and stop) where :func:`slices.body.build_stepped` cut a chain at a slab that
        folds in every surface.
    """

    kind: str
    contours: tuple[Contour, ...]
    start: str
    stop: str

    @property
    def z(self) -> np.ndarray:
        """Plane positions in mm, shape (K,)."""
        return np.array([c.z for c in self.contours])


@dataclass(frozen=True)
class Outlines:
    """All contours of a structure as one ragged table (vertices concatenated, each closed).

    Built once per structure by :meth:`of` (every figure by one array reduction over all
    contours, not a loop per contour) and shared by :func:`chain`, :func:`classify_holes`,
    :func:`slab_volume`, :func:`planning_volumes` and :func:`offset_sensitivity`.

    Attributes
    ----------
    points : numpy.ndarray, shape (N, 2)
        Every contour's vertices in mm, contour after contour.
    start, size : numpy.ndarray, shape (C,) int
        Where contour ``k``'s vertices start in ``points``, and how many it has.
    after : numpy.ndarray, shape (N,) int
        Each vertex's successor along its own closed contour.
    area : numpy.ndarray, shape (C,)
        Signed areas in mm^2 (positive counter-clockwise).
    perimeter : numpy.ndarray, shape (C,)
        Perimeters in mm.
    centroid : numpy.ndarray, shape (C, 2)
        Area centroids in mm (the vertex mean of a contour without area).
    low, high : numpy.ndarray, shape (C, 2)
        Bounding boxes in mm.
    z : numpy.ndarray, shape (C,)
        Plane positions rounded to 1e-6 mm.
    planes : numpy.ndarray, shape (P,)
        The distinct planes, increasing.
    plane_of : numpy.ndarray, shape (C,) int
        Each contour's plane (index into ``planes``).
    hole : numpy.ndarray, shape (C,) bool
        Inner contours: inside an odd number of other contours of their plane
        (each contour's first vertex, crossing-number test).
    """

    points: np.ndarray
    start: np.ndarray
    size: np.ndarray
    after: np.ndarray
    area: np.ndarray
    perimeter: np.ndarray
    centroid: np.ndarray
    low: np.ndarray
    high: np.ndarray
    z: np.ndarray
    planes: np.ndarray
    plane_of: np.ndarray
    hole: np.ndarray

    @classmethod
    def of(cls, contours: list[Contour]) -> Outlines:
        """The table of ``contours`` (a list of :class:`slices.io.Contour`, at least one)."""
        size = np.array([len(c.points) for c in contours])
        start = size.cumsum() - size
        p = np.concatenate([np.asarray(c.points, dtype=np.float64) for c in contours])
        after = np.arange(1, len(p) + 1)
        after[start + size - 1] = start
        q = p.take(after, axis=0)  # faster than p[after] for (N, 2) rows
        cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
        area = np.add.reduceat(cross, start) / 2.0
        d = q - p
        perimeter = np.add.reduceat(np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2), start)
        low, high = np.minimum.reduceat(p, start), np.maximum.reduceat(p, start)
        moment = np.add.reduceat((p + q) * cross[:, None], start)
        flat = np.abs(area) < 1e-12 * np.maximum(1.0, (high - low).max(axis=1)) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            centroid = np.where(flat[:, None], np.add.reduceat(p, start) / size[:, None],
                                moment / (6.0 * area[:, None]))
        z = np.round(np.array([c.z for c in contours]), 6)
        # np.unique(z, return_inverse=True)'s own steps (the same sort), without its wrapper
        order = z.argsort()
        sorted_z = z[order]
        new_plane = np.empty(len(z), dtype=bool)
        new_plane[:1] = True
        np.not_equal(sorted_z[1:], sorted_z[:-1], out=new_plane[1:])
        planes = sorted_z[new_plane]
        plane_of = np.empty(len(z), dtype=np.intp)
        plane_of[order] = new_plane.cumsum() - 1
        if sorted_z[-1] != sorted_z[-1]:  # NaN planes: np.unique's, which holds them as one
            planes, plane_of = np.unique(z, return_inverse=True)
        table = cls(p, start, size, after, area, perimeter, centroid, low, high, z, planes, plane_of,
                    np.zeros(len(contours), dtype=bool))
        # holes by containment among the contours of each plane: all pairs of one plane at once
        i, j = table.same_plane_pairs()
        if len(i):
            inside = table.crossings(p[start[i]], j)[0]
            table.hole[:] = np.bincount(i, inside, minlength=len(contours)).astype(int) % 2 == 1
        return table

    def members(self) -> list[np.ndarray]:
        """The contours of each plane, in order of the planes (a list of P index arrays)."""
        order = np.argsort(self.plane_of, kind="stable")
        return np.split(order, np.bincount(self.plane_of, minlength=len(self.planes)).cumsum()[:-1])

    def same_plane_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Every ordered pair ``(i, j)``, ``i != j``, of contours on one plane (two index arrays)."""
        if len(self.planes) == len(self.plane_of):  # one contour per plane (most structures): no pairs
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        pairs = [(m.repeat(len(m)), np.tile(m, len(m))) for m in self.members() if len(m) > 1]
        if not pairs:
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        i, j = (np.concatenate(x) for x in zip(*pairs))
        return i[i != j], j[i != j]

    def neighbour_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Every pair ``(i, j)`` of a contour ``i`` and a contour ``j`` on the next plane up (two index arrays).

        Ordered by plane, then by ``i``, then by ``j`` (contours in input order within a plane).
        """
        order = np.argsort(self.plane_of, kind="stable")
        count = np.bincount(self.plane_of, minlength=len(self.planes))
        first = np.concatenate([[0], count.cumsum()[:-1]])
        block = count[:-1] * count[1:]  # pairs between plane p and p + 1
        p = np.arange(len(block)).repeat(block)
        r = np.arange(len(p)) - (block.cumsum() - block).repeat(block)
        return order[first[p] + r // count[p + 1]], order[first[p + 1] + r % count[p + 1]]

    def edges_of(self, polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Edge (first-vertex) indices of the contours ``polygon`` (Q,), and which query each belongs to."""
        n = self.size[polygon]
        query = np.arange(len(polygon)).repeat(n)
        first = n.cumsum() - n
        return np.arange(len(query)) - (first - self.start[polygon]).repeat(n), query

    def crossings(self, point: np.ndarray, polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whether each point (Q, 2) is inside contour ``polygon[k]`` (crossing number, as
        :func:`slices.polygons.points_in_polygon`), and its distance to that outline in mm."""
        e, k = self.edges_of(polygon)
        # x and y apart: gathers of single floats run many times faster than of (N, 2) rows
        px, py = self.points[:, 0], self.points[:, 1]
        f = self.after[e]
        ax, ay, qx, qy = px[e], py[e], point[:, 0][k], point[:, 1][k]
        dx, dy = px[f] - ax, py[f] - ay
        wx, wy = qx - ax, qy - ay
        # the crossing only on the edges that straddle the point's line (few; dy is not 0 there)
        at = ((ay > qy) != (py[f] > qy)).nonzero()[0]
        xc = ax[at] + wy[at] * dx[at] / dy[at]
        crossings = np.bincount(k[at[qx[at] < xc]], minlength=len(polygon))
        n = self.size[polygon]
        first = n.cumsum() - n
        length2 = dx**2 + dy**2
        t = np.divide(wx * dx + wy * dy, length2, out=np.zeros(len(e)), where=length2 > 0)
        np.minimum(np.maximum(t, 0.0, out=t), 1.0, out=t)  # np.clip without its wrapper
        gap = np.sqrt(np.minimum.reduceat((wx - t * dx) ** 2 + (wy - t * dy) ** 2, first))
        return crossings % 2 == 1, gap

    def inside_depth(self, point: np.ndarray, polygon: np.ndarray) -> np.ndarray:
        """Signed distance of each point (Q, 2) to contour ``polygon[k]`` in mm: positive inside."""
        inside, gap = self.crossings(point, polygon)
        return np.where(inside, gap, -gap)


def classify_holes(contours: list[Contour]) -> np.ndarray:
    """Mark inner contours (holes) by containment on their own plane.

    Parameters
    ----------
    contours : list of Contour
        All contours of a structure.

    Returns
    -------
    numpy.ndarray, shape (N,) bool
        True for holes (inside an odd number of other contours of the same plane).
    """
    return Outlines.of(contours).hole.copy()


def overlaps(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two polygons overlap (rasterised on their joint bounding box).

    Parameters
    ----------
    a, b : numpy.ndarray, shape (n, 2)
        Polygons in mm.

    Returns
    -------
    bool
    """
    import cv2

    lo = np.minimum(a.min(axis=0), b.min(axis=0))
    hi = np.maximum(a.max(axis=0), b.max(axis=0))
    if np.any(np.maximum(a.min(axis=0), b.min(axis=0)) > np.minimum(a.max(axis=0), b.max(axis=0))):
        return False
    scale = (_RASTER - 1) / max(float((hi - lo).max()), 1e-9)
    size = (int(np.ceil((hi[1] - lo[1]) * scale)) + 2, int(np.ceil((hi[0] - lo[0]) * scale)) + 2)
    masks = []
    for poly in (a, b):
        img = np.zeros(size, np.uint8)
        cv2.fillPoly(img, [np.round((poly - lo) * scale * 16).astype(np.int32)], 1, shift=4)
        masks.append(img)
    return bool(np.any(masks[0] & masks[1]))


#: Raster pixels a point must lie inside both polygons for :func:`_overlapping` to skip the raster:
#: a disc of this radius in both is a whole filled pixel in both of :func:`overlaps`' masks.
_SURE_PIXELS = 3.0


def _overlapping(table: Outlines, contours: list[Contour], i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """:func:`overlaps` of contours ``i[k]`` and ``j[k]`` for every pair at once, shape (P,) bool.

    Pairs whose boxes are apart do not overlap; a pair where either contour's centroid lies inside
    both outlines, farther than :data:`_SURE_PIXELS` of the raster's pixels from both, overlaps in
    the raster too (its disc holds a filled pixel of each mask); only the others are rasterised.
    """
    out = np.zeros(len(i), dtype=bool)
    if not len(i):
        return out
    lo_i, hi_i, lo_j, hi_j = table.low[i], table.high[i], table.low[j], table.high[j]
    meet = (np.maximum(lo_i, lo_j) <= np.minimum(hi_i, hi_j)).all(axis=1)
    pixel = (np.maximum(hi_i, hi_j) - np.minimum(lo_i, lo_j)).max(axis=1) / (_RASTER - 1)
    k = meet.nonzero()[0]
    if not len(k):
        return out
    # each pair's two centroids, each tested against both outlines: i's centroid first, j's only
    # where that does not settle the pair (usually none: neighbouring slices overlap around them)
    margin = _SURE_PIXELS * pixel[k]
    sure = np.zeros(len(k), dtype=bool)
    for a, b in ((i, j), (j, i)):
        ask = (~sure).nonzero()[0]
        if not len(ask):
            break
        own, other = a[k[ask]], b[k[ask]]
        point = table.centroid[own]
        depth = table.inside_depth(np.concatenate([point, point]), np.concatenate([own, other]))
        sure[ask] = (depth[:len(ask)] > margin[ask]) & (depth[len(ask):] > margin[ask])
    out[k[sure]] = True
    for m in k[~sure]:
        out[m] = overlaps(contours[i[m]].points, contours[j[m]].points)
    return out


def _segment_distance(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of every point to a closed polygon's boundary, shape (N,)."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    d = b - a
    t = np.einsum("pkj,kj->pk", points[:, None, :] - a[None], d) / np.maximum(np.einsum("kj,kj->k", d, d), 1e-300)
    foot = a[None] + np.clip(t, 0.0, 1.0)[..., None] * d[None]
    return np.linalg.norm(points[:, None, :] - foot, axis=2).min(axis=1)


def split_contour(parent: np.ndarray, children: list[np.ndarray]) -> list[np.ndarray] | None:
    """Split a contour along the mid-lines between the projections of the contours it branches into.

    Every point of the parent goes to the nearest child (a Voronoi partition
    of the children's rasterised projections, by a Euclidean distance
    transform); child ``i``'s part is bounded by the parent's own vertices
    nearest to it and by the mid-line to its neighbours. The parts cover the
    parent once, so each child's surface rises from its own part of the parent
    (no flat shelf, nothing detached), as SlicerRT's branching does.

    Parameters
    ----------
    parent : numpy.ndarray, shape (n, 2)
        Counter-clockwise contour in mm.
    children : list of numpy.ndarray, each shape (m, 2)
        The contours it overlaps on the neighbouring plane (two or more).

    Returns
    -------
    list of numpy.ndarray or None
        One counter-clockwise part per child, in the children's order; None
        when a child's part is empty, not one piece, or its area differs from
        the child's by more than :data:`SPLIT_AREA_RATIO` (then the caller keeps
        the half caps that meet half-way between the planes).
    """
    import cv2
    from scipy import ndimage
    from scipy.spatial import cKDTree
    from skimage.measure import find_contours

    from slices.polygons import clean_contour

    everything = np.vstack([parent, *children])
    lo = everything.min(axis=0)
    h = float((everything.max(axis=0) - lo).max()) / (SPLIT_RASTER - 1)
    shape = tuple(int(v) for v in np.ceil((everything.max(axis=0) - lo) / h)[::-1] + 3)

    def fill(poly, value, img):
        cv2.fillPoly(img, [np.round((poly - lo) / h * 16 + 16).astype(np.int32)], value, shift=4)
        return img

    inside = fill(parent, 1, np.zeros(shape, np.uint8)).astype(bool)
    ids = np.zeros(shape, np.int32)
    for i, c in enumerate(children):
        fill(c, i + 1, ids)
    if not ids.any():
        return None
    _, (ri, ci) = ndimage.distance_transform_edt(ids == 0, return_indices=True)
    nearest = ids[ri, ci] - 1

    def to_mm(rc):
        return lo + (rc[:, ::-1] - 1.0) * h

    px = np.clip(np.round((parent - lo) / h + 1).astype(int), 0, np.array(shape[::-1]) - 1)
    vertex_owner = nearest[px[:, 1], px[:, 0]]
    step = max(1, int(round(float(np.median(np.linalg.norm(np.diff(parent, axis=0), axis=1))) / h)))
    parts = []
    for i in range(len(children)):
        region = inside & (nearest == i)
        loops = [c for c in find_contours(np.pad(region.astype(np.float64), 1), 0.5) if len(c) > 3]
        if not loops:
            return None
        sizes = np.array([abs(np.sum(c[:-1, 0] * c[1:, 1] - c[1:, 0] * c[:-1, 1])) for c in loops])
        if np.sum(sizes > 0.02 * sizes.max()) > 1:
            return None  # the child's share of the parent is in pieces
        loop = to_mm(loops[int(np.argmax(sizes))][:-1] - 1.0)
        # the loop's points off the parent's outline lie on the mid-line; on the outline, the parent's
        # own vertices are used, so the part keeps the parent's shape exactly there
        mid = np.flatnonzero(_segment_distance(loop, parent) > 2.0 * h)
        mid = mid[::step] if len(mid) else mid
        own = np.flatnonzero(vertex_owner == i)
        points = np.vstack([parent[own], loop[mid]])
        if len(points) < 3:
            return None
        _, where = cKDTree(loop).query(points)
        points = points[np.argsort(where, kind="stable")]
        try:
            part = clean_contour(points, f"part {i} of a split contour")
        except ValueError:
            return None
        ratio = signed_area(part) / max(abs(signed_area(children[i])), 1e-300)
        if not 1 / SPLIT_AREA_RATIO <= ratio <= SPLIT_AREA_RATIO:
            return None
        parts.append(part)
    return parts


def chain(contours: list[Contour], spacing: float | None, outlines: Outlines | None = None) -> list[Body]:
    """Group contours into bodies (see module docstring).

    Parameters
    ----------
    contours : list of Contour
        All contours of one structure, counter-clockwise.
    spacing : float or None
        Slice spacing in mm (neighbouring planes are this far apart; a larger
        gap separates bodies and is an error where contours overlap across it).
        None: every pair of consecutive planes are neighbours (unequally spaced
        stacks).
    outlines : Outlines, optional
        The contours' table (:meth:`Outlines.of`) when the caller has built it already.

    Returns
    -------
    list of Body
        Outer bodies first, then holes; each ordered by its lowest ``z``.
    """
    n = len(contours)
    table = Outlines.of(contours) if outlines is None else outlines
    hole, z, planes = table.hole, table.z, table.planes
    succ: list[list[int]] = [[] for _ in range(n)]
    pred: list[list[int]] = [[] for _ in range(n)]
    lower, upper = table.neighbour_pairs()
    gap = planes[1:] - planes[:-1]
    wide = np.zeros(len(gap), dtype=bool) if spacing is None else np.abs(gap - spacing) > SPACING_RTOL * spacing
    gapped = wide[table.plane_of[lower]]
    # missing planes are fine between separate bodies, not inside one
    ask = gapped | (hole[lower] == hole[upper])
    meets = np.zeros(len(lower), dtype=bool)
    meets[ask] = _overlapping(table, contours, lower[ask], upper[ask])
    if (meets & gapped).any():
        p0 = z[lower[meets & gapped][0]]
        p1 = z[upper[meets & gapped][0]]
        raise InputError(
            f"contours: unequal slice spacing, no plane between z={p0:.3f} and z={p1:.3f} mm "
            f"({spacing:.3f} mm elsewhere) although the structure continues across; use "
            "--resample to blend at the true slice positions"
        )
    for a, b in zip(lower[meets].tolist(), upper[meets].tolist()):
        succ[a].append(b)
        pred[b].append(a)
    linked = [len(succ[i]) == 1 and len(pred[succ[i][0]]) == 1 for i in range(n)]
    starts = [i for i in range(n) if not (len(pred[i]) == 1 and linked[pred[i][0]])]
    below, above = _split_joints(contours, succ, pred)
    bodies = []
    for s in starts:
        members = [s]
        while linked[members[-1]]:
            members.append(succ[members[-1]][0])
        first, last = members[0], members[-1]
        start = "end" if not pred[first] else ("merge" if len(pred[first]) > 1 else "branch")
        if not succ[last]:
            stop = "end"
        elif len(succ[last]) > 1:
            stop = "branch"
        else:
            stop = "merge"
        chained = [contours[m] for m in members]
        if first in below:
            chained = ([] if below[first] is None else [below[first]]) + chained
            start = "split"
        if last in above:
            chained += [] if above[last] is None else [above[last]]
            stop = "split"
        bodies.append(Body("hole" if hole[first] else "outer", tuple(chained), start, stop))
    bodies.sort(key=lambda b: (b.kind != "outer", b.contours[0].z))
    return bodies


def _split_joints(contours: list[Contour], succ: list, pred: list) -> tuple[dict, dict]:
    """The parts of split contours that start or end chains (:func:`split_contour`).

    Returns
    -------
    below : dict
        Contour index -> the part (a Contour on the plane below) its chain starts
        with, or None when the chain starts on the split contour itself (a merge's
        result: its chain starts there with a flat joint).
    above : dict
        Contour index -> the part its chain ends with, or None when the chain ends on
        the split contour itself (a branching's parent).
    """
    below: dict = {}
    above: dict = {}
    for i in range(len(contours)):
        # a branching whose children come from this contour alone, and a merge whose parents go
        # into this contour alone; a contour that does both keeps the half caps
        branch = len(succ[i]) > 1 and all(len(pred[j]) == 1 for j in succ[i])
        merge = len(pred[i]) > 1 and all(len(succ[j]) == 1 for j in pred[i])
        if branch == merge:
            continue
        others = succ[i] if branch else pred[i]
        if any(j in below or j in above for j in others):
            continue
        parts = split_contour(contours[i].points, [contours[j].points for j in others])
        if parts is None:
            continue
        for j, part in zip(others, parts):
            (below if branch else above)[j] = Contour(contours[i].z, part)
        (above if branch else below)[i] = None
    return below, above


def _plane_sums(contours: list[Contour], outlines: Outlines | None, term) -> tuple[np.ndarray, np.ndarray]:
    """Distinct planes (P,) and the sum over each plane's contours of ``term(table, sign)`` (P,).

    ``term`` gets the :class:`Outlines` table and each contour's sign (+1 outer, -1 hole) and
    returns one value per contour.
    """
    table = Outlines.of(contours) if outlines is None else outlines
    sign = np.where(table.hole, -1.0, 1.0)
    return table.planes, np.bincount(table.plane_of, term(table, sign), minlength=len(table.planes))


def slab_volume(contours: list[Contour], spacing: float | None, outlines: Outlines | None = None) -> float:
    """Volume as treatment-planning systems count it.

    Per plane, outer contour areas minus hole areas, times the slice spacing;
    the first and last plane of the structure count half (dicompyler-core's
    polygon method).

    Parameters
    ----------
    contours : list of Contour
    spacing : float or None
        Slice spacing in mm; None for unequally spaced planes (then the
        trapezoid rule over the actual plane positions, which is the same
        count for equal spacing).
    outlines : Outlines, optional
        The contours' table (:meth:`Outlines.of`) when the caller has built it already.

    Returns
    -------
    float
        Volume in mm^3.
    """
    planes, area = _plane_sums(contours, outlines, lambda table, sign: sign * np.abs(table.area))
    if spacing is None:
        if len(planes) < 2:
            return 0.0
        return float(np.sum((area[1:] + area[:-1]) / 2 * np.diff(planes)))
    weight = np.ones(len(planes))
    weight[[0, -1]] = 0.5
    return float(np.sum(area * weight) * spacing)


#: Contours up to which a structure counts as small (lens, chiasm): there the end convention dominates.
SMALL_STRUCTURE_CONTOURS = 5


def planning_volumes(contours: list[Contour], spacing: float | None, outlines: Outlines | None = None) -> dict:
    """The volume as treatment-planning systems count it, under both end conventions.

    Planning systems give every contour a slab of one slice spacing (area x
    spacing, outer contours minus holes) and differ at the ends of the
    structure: ``slab_full_ends`` keeps the end contours' whole slabs (the
    structure reaches half a spacing beyond its end planes), ``slab_half_ends``
    keeps half of them (:func:`slab_volume`, the trapezoid rule between the end
    planes, dicompyler-core's count). For small structures (lens, chiasm:
    1-5 contours) the two differ by tens of percent, and an interpolating
    surface, which bulges between the planes, lies between or above them.

    Parameters
    ----------
    contours : list of Contour
    spacing : float or None
        Slice spacing in mm; None for unequally spaced planes (then each plane's
        slab reaches half-way to its neighbours, and the end planes' outer halves
        use the median spacing).
    outlines : Outlines, optional
        The contours' table (:meth:`Outlines.of`) when the caller has built it already.

    Returns
    -------
    dict
        ``slab_full_ends`` and ``slab_half_ends`` in mm^3, ``n_planes``, and
        ``small_structure`` (True for at most :data:`SMALL_STRUCTURE_CONTOURS` planes).

    Examples
    --------
    A 10 mm square on three planes 2 mm apart: 3 x 100 x 2 with full end slabs, 2 x 100 x 2 with half:

    >>> square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    >>> planning_volumes([Contour(z, square) for z in (0.0, 2.0, 4.0)], 2.0)
    {'slab_full_ends': 600.0, 'slab_half_ends': 400.0, 'n_planes': 3, 'small_structure': True}
    """
    planes, area = _plane_sums(contours, outlines, lambda table, sign: sign * np.abs(table.area))
    if spacing is None:
        gaps = np.diff(planes)
        d = float(np.median(gaps)) if len(gaps) else 0.0
        thickness = np.concatenate([[d / 2], gaps / 2]) + np.concatenate([gaps / 2, [d / 2]])
    else:
        thickness = np.full(len(planes), float(spacing))
    return {"slab_full_ends": float(np.sum(area * thickness)),
            "slab_half_ends": slab_volume(contours, spacing, outlines),
            "n_planes": int(len(planes)),
            "small_structure": bool(len(planes) <= SMALL_STRUCTURE_CONTOURS)}


def offset_sensitivity(contours: list[Contour], spacing: float | None, offset: float = 0.5,
                       outlines: Outlines | None = None) -> float:
    """Change of the slab volume when every contour grows outward by ``offset``.

    Steiner's formula per contour: an outer contour's area grows by
    ``perimeter * offset + pi * offset**2``, a hole's shrinks by
    ``perimeter * offset - pi * offset**2`` (exact for convex outlines with
    rounded corners, first-order exact for any outline); the planes are summed
    as :func:`slab_volume` sums them. This is the figure a planning physicist
    uses to judge whether two systems' volumes really differ.

    Parameters
    ----------
    contours : list of Contour
    spacing : float or None
        Slice spacing in mm (None: unequally spaced planes, trapezoid rule).
    offset : float
        Outward offset of every contour in mm.
    outlines : Outlines, optional
        The contours' table (:meth:`Outlines.of`) when the caller has built it already.

    Returns
    -------
    float
        Volume change in mm^3 (positive for a positive offset).

    Examples
    --------
    A disc of radius 10 mm on two planes 2 mm apart: ``(2 pi 10 * 0.5 + pi 0.25) * 2``.

    >>> t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    >>> disc = 10 * np.stack([np.cos(t), np.sin(t)], axis=1)
    >>> round(offset_sensitivity([Contour(0.0, disc), Contour(2.0, disc)], 2.0), 2)
    64.4
    """
    planes, grow = _plane_sums(contours, outlines,
                               lambda table, sign: table.perimeter * offset + sign * np.pi * offset**2)
    if spacing is None:
        if len(planes) < 2:
            return 0.0
        return float(np.sum((grow[1:] + grow[:-1]) / 2 * np.diff(planes)))
    weight = np.ones(len(planes))
    weight[[0, -1]] = 0.5
    return float(np.sum(grow * weight) * spacing)
