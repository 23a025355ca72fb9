"""One body (a chain of contours on consecutive planes) to a closed surface, volume and area.

Seed 000, sections II-III: slice curves on a common lattice
(:func:`slices.surface.slice_curves`), the side surface across them
(:func:`slices.surface.side_surface`), the caps (:mod:`slices.caps`), the
volume and area of the closed patch grid (:func:`slices.caps.grid_integrals`: quadrature on the side,
closed forms on the caps), the deviation at the control points and the triangle mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from slices import caps as capmod
from slices.chaining import Body
from slices.io import SPACING_RTOL
from slices.options import SurfaceOptions
from slices.surface import _side_surface, blend_overshoot, lattice_size, ruled_surface, slice_curves
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh, tessellate
from surfaces.validate import InputError, positive

#: Most vertices a body's mesh gets with ``samples=None`` (the density drops below
#: :data:`EDGE_MM` edges to stay under it).
MESH_BUDGET = 250_000

#: Longest mesh edge (mm) aimed at with ``samples=None``, along and across the slices: the
#: lattice already holds two intervals per point of the largest contour, so most bodies keep
#: one interval per edge around and get a few edges between two slices (a 0.5 mm raster's
#: marching cubes has edges of 0.5-0.7 mm).
EDGE_MM = 2.0

#: Most subdivisions per patch side with ``samples=None``.
MAX_SAMPLES = 6


@dataclass
class BodySurface:
    """One reconstructed body.

    Attributes
    ----------
    body : Body
        The chained contours.
    patches : BezierPatches
        Closed grid (side and cap columns; with ``caps="none"`` the cap columns
        are still there so the patches enclose the volume between end planes).
    side_columns : slice
        Patch columns of the open side surface (with half-cap extrusions and domes).
    mesh : TriangleMesh or None
        Triangles, oriented outward of the solid (holes point into the hole);
        caps welded to the side, watertight when capped.
    display_mesh : TriangleMesh or None
        The same triangles with the caps' vertices kept apart, so flat caps
        shade with their own normals.
    volume_mm3 : float
        Enclosed volume (positive, also for holes).
    area_mm2 : float
        Surface area (side plus caps).
    max_deviation_mm : float
        Largest distance between a control point and the surface at its parameters.
    n_points : int
        Control points used.
    n_turning : int
        Turning points that got eq. 4 parameters.
    n_lattice : int
        Size of the body's common ``u`` lattice (patch rows).
    start_angle : float
        Direction of ray 0 in radians from +x.
    n_limited : int
        Curve Bezier points whose blend across slices was limited (monotone),
        see :func:`slices.surface.blend_overshoot`.
    caps_used : (str, str)
        The caps the low and the high end got (:func:`slices.caps.end_kinds`).
    end_areas_mm2 : (float, float)
        Areas enclosed by the lowest and the highest slice curve (mm^2).
    spacing : float
        Slice spacing used for the caps (mm).
    surface : str
        Which side surface was kept (:data:`FALLBACKS`; empty when not checked).
    self_intersecting_faces : int or None
        Self-intersecting faces of the body's mesh (None when not checked).
    mesh_samples : (int, int) or None
        Tessellation subdivisions of every patch around and across the slices
        (:func:`mesh_samples` with ``samples=None``); None without a mesh.
    extrusions_mm : (float, float)
        Heights of the low and the high end's prism (half caps: half a spacing; trend
        caps that do not close within a spacing: the trend's volume over the end area,
        :func:`slices.caps.resolve_trend`); 0 where none.
    cap_volumes_mm3 : (float, float)
        Volume the surface encloses beyond the low and the high end plane (mm^3, positive): the
        prism of a half cap, the rings of a trend cap (:func:`slices.caps.trend_rings`) or a dome;
        0 for flat caps and none (:func:`slices.caps.cap_volumes`).
    mid_bulge_mm3 : float
        A two-plane trend body's side blends through a virtual mid slice (:func:`slices.caps.mid_ring`):
        the volume that adds to the side blended straight between the two planes (mm^3; 0 otherwise).
        :meth:`volume_with_caps` takes it off, so other caps count the side they would get.
    """

    body: Body
    patches: BezierPatches
    side_columns: slice
    mesh: TriangleMesh | None
    display_mesh: TriangleMesh | None
    volume_mm3: float
    area_mm2: float
    max_deviation_mm: float
    n_points: int
    n_turning: int
    n_lattice: int
    start_angle: float
    n_limited: int = 0
    caps_used: tuple[str, str] = ("flat", "flat")
    end_areas_mm2: tuple[float, float] = (0.0, 0.0)
    spacing: float = 0.0
    surface: str = ""
    self_intersecting_faces: int | None = None
    mesh_samples: tuple[int, int] | None = None
    extrusions_mm: tuple[float, float] = (0.0, 0.0)
    cap_volumes_mm3: tuple[float, float] = (0.0, 0.0)
    mid_bulge_mm3: float = 0.0

    def volume_with_caps(self, caps: str) -> float | None:
        """The body's volume had it been capped with ``caps`` (none, flat or half).

        A half cap adds a prism of the end curve's area times half a spacing to
        the flat-capped volume; ``none`` encloses what flat caps enclose. Ends
        at a branching keep their half caps (:func:`slices.caps.end_kinds`).

        Parameters
        ----------
        caps : {"none", "flat", "half"}

        Returns
        -------
        float or None
            mm^3 (positive, also for holes); None when an end has a dome (no
            closed form: build the body again).
        """
        if caps not in ("none", "flat", "half"):
            raise InputError(f"caps: must be 'none', 'flat' or 'half', got {caps!r}")
        if "dome" in self.caps_used:
            return None
        wanted = capmod.end_kinds(caps, self.body.start, self.body.stop, len(self.body.contours))
        # what half and trend caps enclose beyond the end planes off, the wanted half caps' prisms on
        extra = sum(a * (w == "half") * self.spacing / 2 - (u in capmod.PRISM_KINDS) * v
                    for a, w, u, v in zip(self.end_areas_mm2, wanted, self.caps_used, self.cap_volumes_mm3))
        extra -= self.mid_bulge_mm3
        return float(self.volume_mm3 + extra)


def _flip(mesh: TriangleMesh) -> TriangleMesh:
    """The same triangles with the opposite orientation."""
    normals = None if mesh.vertex_normals is None else -mesh.vertex_normals
    return TriangleMesh(mesh.vertices, mesh.triangles[:, ::-1].copy(), normals)


#: Patches per chunk in :func:`_polygon_lengths` (temporaries of ~400 kB in single precision; measured
#: on real sides of 4,000-12,000 patches, 5 % faster than half as many, and than twice as many).
_SAMPLES_CHUNK = 2048

#: Bound on the relative error of :func:`mesh_samples`'s single-precision polygon lengths, relative to
#: the polygon's length plus the largest coordinate (some ten roundings of 2^-24 each; 2^-18 is 64).
_SINGLE_ERROR = 2.0**-18


def _samples(median: float) -> int:
    """Subdivisions for a median control polygon length (mm)."""
    x = median / EDGE_MM
    if 0.0 < x < MAX_SAMPLES:  # the usual case in plain Python (numpy's clip of a scalar costs ~3 us)
        return math.ceil(x)
    return int(np.clip(np.ceil(x), 1, MAX_SAMPLES))


def mesh_samples(control: np.ndarray, budget: int = MESH_BUDGET) -> tuple[int, int]:
    """Subdivisions of every patch around (``u``) and across the slices (``v``) for the mesh.

    Parameters
    ----------
    control : numpy.ndarray, shape (rows, cols, 4, 4, 3)
        Bezier points of the side patches (mm).
    budget : int
        Most vertices (``rows * cols * su * sv``).

    Returns
    -------
    (int, int)
        ``(su, sv)``: the median control polygon length in each
        direction over :data:`EDGE_MM`, rounded up, in ``[1, MAX_SAMPLES]``; the
        larger is lowered while the mesh would exceed ``budget`` vertices.

    Examples
    --------
    Patches 0.8 mm around and 5 mm across (edges of at most :data:`EDGE_MM`, 2 mm):

    >>> c = np.zeros((10, 2, 4, 4, 3))
    >>> c[..., 0] = 0.8 * np.arange(4)[:, None] / 3
    >>> c[..., 2] = 5.0 * np.arange(4)[None, :] / 3
    >>> mesh_samples(c)
    (1, 3)
    """
    # the medians in single precision (half the memory traffic), trusted where the bound on their error
    # cannot move them across a multiple of EDGE_MM: an order statistic moves no further than the values
    # do, each by at most _SINGLE_ERROR (length + reach). Where it could, or for coordinates whose
    # squares a float32 might not hold, the double-precision polygons decide
    with np.errstate(over="ignore", invalid="ignore"):  # coordinates beyond float32 become inf
        polygons, reach = _polygon_lengths(control, np.float32)
    picked = [None]
    if reach < 1e15:
        picked = []
        for p in polygons:
            m = capmod._median(p)
            margin = 2 * _SINGLE_ERROR * (m + reach)
            low, high = _samples(m - margin), _samples(m + margin)
            picked.append(low if low == high else None)
    if None in picked:
        picked = [_samples(capmod._median(p)) for p in _polygon_lengths(control, np.float64)[0]]
    su, sv = picked
    n = control.shape[0] * control.shape[1]
    while su * sv * n > budget and max(su, sv) > 1:
        su, sv = (su - 1, sv) if su >= sv else (su, sv - 1)
    return su, sv


def _polygon_lengths(control: np.ndarray, dtype: type) -> tuple[tuple[np.ndarray, np.ndarray], float]:
    """Lengths of the patches' control polygons along ``u`` and along ``v`` and the largest coordinate.

    Returns ``((polygon_u, polygon_v), reach)``: shapes (rows * cols, 4) in mm, computed in ``dtype``
    (float64 or float32) from the copied points on, and the largest absolute coordinate as copied (mm;
    NaN or inf when some is).
    """
    # the points copied as they lie (a cast of whole contiguous rows of patches, no transposing copy), so
    # that the legs along u and along v are one long subtraction each (points 4 and 1 apart in a patch's
    # 16, coordinates interleaved); the few pairs that straddle two patches are computed and left out:
    # numpy's loops over the short axes of (R, C, 4, 4, 3) cost more than that. In chunks of whole patch
    # rows whose temporaries stay in the CPU caches, every chunk in the same memory (fresh arrays per
    # chunk cost their allocations' page faults)
    rows, cols = control.shape[:2]
    n = rows * cols
    polygon_u, polygon_v = np.empty((n, 4), dtype), np.empty((n, 4), dtype)
    chunk_rows = max(1, _SAMPLES_CHUNK // cols)
    size = min(rows, chunk_rows) * cols * 16
    flat, diff = np.empty((2, 3 * size), dtype)
    lengths = np.empty(size, dtype)
    reach = 0.0
    for r in range(0, rows, chunk_rows):
        block = control[r:r + chunk_rows]
        k = block.shape[0] * cols * 16
        points, d = flat[:3 * k], diff[:3 * k]
        points.reshape(block.shape)[...] = block
        reach = float(np.max([reach, points.max(), -points.min()]))  # NaN stays NaN
        start, stop = r * cols, r * cols + k // 16
        for step, polygon in ((4, polygon_u[start:stop]), (1, polygon_v[start:stop])):
            apart = 3 * step
            np.subtract(points[apart:], points[:-apart], out=d[:-apart])
            d[-apart:] = 0.0
            np.square(d, out=d)
            length = np.add(d[0::3], d[1::3], out=lengths[:k])
            length += d[2::3]
            leg = np.sqrt(length, out=length).reshape(-1, 16)  # leg from point 4 i + j of each patch
            if step == 4:  # along u: rows i = 0..2 of legs, one polygon per j
                np.add(leg[:, 0:4], leg[:, 4:8], out=polygon)
                polygon += leg[:, 8:12]
            else:  # along v: legs j = 0..2 of each row i
                np.add(leg[:, 0::4], leg[:, 1::4], out=polygon)
                polygon += leg[:, 2::4]
    return (polygon_u, polygon_v), reach


def body_lattice_size(body: Body, lattice_factor: float) -> int:
    """Lattice size ``M`` of a body: :func:`slices.surface.lattice_size` of its largest contour.

    Parameters
    ----------
    body : Body
    lattice_factor : float
        Lattice values per point of the largest contour.

    Returns
    -------
    int
    """
    return lattice_size(max(len(c.points) for c in body.contours), lattice_factor)


#: Surfaces tried, in order, when a body's mesh folds (:func:`build_body` with ``options.unfold``).
FALLBACKS = (
    ("seed blend", {}),
    ("arc-length blend", {"correspondence": "arc", "monotone": True}),
    ("arc-length ruled", {"correspondence": "arc", "method": "ruled"}),
    ("aligned arc-length blend", {"correspondence": "aligned", "monotone": True}),
    ("aligned arc-length ruled", {"correspondence": "aligned", "method": "ruled"}),
)


def build_body(body: Body, spacing: float, options: SurfaceOptions | None = None,
               mesh: bool = True) -> BodySurface:
    """Surface, volume and area of one body, rebuilt more conservatively while its mesh folds.

    With ``options.unfold`` and a mesh, the mesh is checked for self-intersecting
    faces (:func:`surfaces.folds.is_fold_free`: the exact test of
    :func:`surfaces.intersect.self_intersections` on the faces that the certificate
    of :func:`surfaces.folds.fold_suspects` cannot clear); a folded body is built
    again with the next surface of :data:`FALLBACKS` (the blend linking the
    slices by arc length, limited to be monotone; then straight lines between
    the slices; then both again with the arc length's origin following the
    shape, :func:`slices.surface.aligned_arcs`), and the first clean one, or the one with the fewest folded
    faces, is kept (``surface`` and ``self_intersecting_faces`` say which).
    See :func:`build_body_once` for the parameters.
    """
    return _build_unfolded(body, spacing, options, mesh)[0]


def _build_unfolded(body: Body, spacing: float, options: SurfaceOptions | None, mesh: bool,
                    fewest: bool = True) -> tuple[BodySurface, np.ndarray | None]:
    """:func:`build_body`, and the folded-face mask of the surface kept (None when clean or unchecked).

    With ``fewest=False`` a body on which every surface folds keeps the last one tried, whose
    folds alone are counted (the stepped slabs' cheaper choice: the aligned ruled surface folds
    in the fewest slabs, and counting every surface's folds costs more than the steps).
    """
    from surfaces.folds import folded_faces, is_fold_free

    opts = SurfaceOptions() if options is None else options
    first = build_body_once(body, spacing, opts, mesh=mesh)
    if not (mesh and opts.unfold):
        return first, None
    folded = []
    for i, (name, change) in enumerate(FALLBACKS):
        if i and (opts.method != "blending" or len(body.contours) < 2):
            # one contour's side is the same prism whatever the blend (and has no slice-to-slice alignment)
            break
        b = first if i == 0 else build_body_once(body, spacing, replace(opts, **{k: v for k, v in change.items()
                                                                                 if k != "method"}),
                                                 mesh=True, ruled=change.get("method") == "ruled")
        b.surface = name if i else f"{opts.method} ({opts.correspondence})"
        # the mesh as written: a blend can fold inside a patch, below any coarser check's resolution;
        # a surface that folds is passed over at its first fold, its folds are counted only if all fold.
        # The exact test runs on the faces the layered certificate cannot clear (usually a few bands)
        if is_fold_free(b.mesh.vertices, b.mesh.triangles):
            b.self_intersecting_faces = 0
            return b, None
        folded.append(b)
    if not fewest:
        folded = folded[-1:]
    masks = []
    for b in folded:
        masks.append(folded_faces(b.mesh.vertices, b.mesh.triangles))
        b.self_intersecting_faces = int(masks[-1].sum())
    # the first of the fewest folded faces
    best = min(range(len(folded)), key=lambda i: folded[i].self_intersecting_faces)
    return folded[best], masks[best]


def build_stepped(body: Body, spacing: float, options: SurfaceOptions | None = None,
                  mesh: bool = True) -> list[BodySurface]:
    """:func:`build_body`, with the slabs it cannot unfold stepped: the last resort that never folds.

    When every surface of :data:`FALLBACKS` folds, the chain is cut at every
    slab (pair of neighbouring planes) where the last surface tried (with the
    blending method the aligned ruled one, which folds in the fewest slabs) holds a folded face, and each piece
    is built again the same way (and cut again while it folds). Across a cut the
    lower piece ends in a half cap a half spacing above its last plane and the
    upper piece starts in one a half spacing below its first (chain ends
    ``"step"``, as at a branching), so the slab becomes two prisms that meet in
    the mid-plane, where the union of the bodies (:func:`slices.structure.solid_union`)
    joins them: a step in the wall instead of faces that cut through each other.
    Such a slab encloses ``d (A_k + A_k+1) / 2``, the trapezoid rule the blend
    approximates.

    Parameters
    ----------
    body : Body
        Contours on consecutive planes.
    spacing : float
        Slice spacing in mm.
    options : SurfaceOptions, optional
        As for :func:`build_body_once`; the slabs are stepped only with
        ``unfold`` and a mesh.
    mesh : bool
        Build the triangle mesh.

    Returns
    -------
    list of BodySurface
        The body, or its pieces in order of ``z`` (each with its own ``surface``;
        ``body.start``/``body.stop`` say ``"step"`` at a cut). A piece of one contour
        that still folds (its outline crosses itself) is kept as it is.
    """
    built, folds = _build_unfolded(body, spacing, options, mesh, fewest=False)
    if folds is None or len(body.contours) < 2:
        return [built]
    centre_z = built.mesh.vertices[built.mesh.triangles[folds], 2].mean(axis=1)
    slab = np.searchsorted(body.z, centre_z) - 1
    cuts = np.unique(slab[(slab >= 0) & (slab < len(body.contours) - 1)])
    if not len(cuts):
        # folds in the caps only: nothing to step, the surface with the fewest folded faces is kept
        return [build_body(body, spacing, options, mesh)]
    bounds = np.concatenate([[0], cuts + 1, [len(body.contours)]])
    out = []
    for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        piece = Body(body.kind, body.contours[a:b], body.start if i == 0 else "step",
                     body.stop if b == len(body.contours) else "step")
        out.extend(build_stepped(piece, spacing, options, mesh))
    return out


def _pieced_side(stack: np.ndarray, split: tuple[int, int], opts: SurfaceOptions,
                 out: np.ndarray | None) -> tuple[BezierPatches, object, int]:
    """The side surface over ``stack`` (K', M, 4, 3), blended in pieces: the first ``split[0]`` and the last
    ``split[1]`` intervals (trend caps' rings) apart from the ones between (the slice curves).

    The pieces share their boundary curves, so the columns join exactly (C0 at the end planes). Returns
    the patches (written into ``out`` when given), the corner evaluator of :func:`slices.surface.side_surface`
    and the count of limited tangents between the slice curves (:func:`slices.surface.blend_overshoot`, 0 unless
    monotone blending). The rings are always blended monotone (limited tangents: no overshoot, no fold).
    """
    from slices.surface import _corner_eval

    z = stack[:, 0, 0, 2]
    last = len(stack) - 1
    bounds = sorted({0, split[0], last - split[1], last})
    monotone = opts.monotone and opts.method == "blending"
    if len(bounds) == 2:
        side, node_eval = _side_surface(stack, opts.method, z, opts.monotone, out=out)
        return side, node_eval, (blend_overshoot(stack, z) if monotone else 0)
    controls, n_limited = [], 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        piece = stack[a:b + 1]
        # the rings always monotone: a cap flatter than its outline is wide folds where the blend overshoots
        ring = (a == 0 and split[0] > 0) or (b == last and split[1] > 0)
        part, _ = _side_surface(piece, opts.method, z[a:b + 1], opts.monotone or ring,
                                out=None if out is None else out[:, a:b])
        controls.append(part.control)
        if monotone and not ring:
            n_limited += blend_overshoot(piece, z[a:b + 1])
    control = out if out is not None else np.concatenate(controls, axis=1)
    side = BezierPatches.unchecked(control, closed_u=True)
    return side, _corner_eval(side, len(stack)), n_limited


def build_body_once(body: Body, spacing: float, options: SurfaceOptions | None = None,
                    mesh: bool = True, ruled: bool = False) -> BodySurface:
    """Surface, volume and area of one body (seed 000 sections II-III).

    Parameters
    ----------
    body : Body
        Contours on consecutive planes.
    spacing : float
        Slice spacing in mm (unequally spaced planes, accepted by a reconstruction
        with ``irregular=True``, give caps of half the median interval).
    options : SurfaceOptions, optional
        Method, rays, caps, lattice, ray rotation and tessellation (the defaults
        when omitted). ``samples=None`` gives this body's mesh edges of about
        :data:`EDGE_MM` each way (:func:`mesh_samples`), at most :data:`MESH_BUDGET` vertices.
    mesh : bool
        Build the triangle mesh.
    ruled : bool
        Straight lines between the slices (:func:`slices.surface.ruled_surface`)
        instead of ``options.method``.

    Returns
    -------
    BodySurface
        Ends where the chain splits (branching or merging contours) always get
        half caps, so neighbouring bodies meet half-way between the planes; a
        single contour gets half caps where none/flat would give it no
        thickness (the slab planning systems count), see
        :func:`slices.caps.end_kinds`; ``caps_used`` records what each end got.
    """
    opts = SurfaceOptions() if options is None else options
    z = body.z
    low, high = capmod.end_kinds(opts.caps, body.start, body.stop, n_contours=len(z))
    d = positive(spacing, "spacing")
    if len(z) > 1 and (np.abs(z[1:] - z[:-1] - d) > SPACING_RTOL * d).any():
        d = float(np.median(np.diff(z)))
    sc = slice_curves([c.points for c in body.contours], z, opts.n_rays, body_lattice_size(body, opts.lattice_factor),
                      start_angle=opts.start_angle, correspondence=opts.correspondence,
                      lattice_mode=opts.lattice_mode)
    curves = sc.curves
    centers = np.empty((len(z), 3))
    centers[:, :2] = [p.center for p in sc.params]
    centers[:, 2] = z
    # rings of dome caps, and of trend caps that close within a spacing (shaped as the area trend says);
    # the other trend ends are prisms of the trend's volume (resolve_trend)
    stack, prepend, append, low_shape, high_shape = capmod._add_cap_rings(curves, centers, d, low, high)
    contour_at = np.arange(prepend, prepend + len(curves))  # each slice curve's index in the stack
    if len(curves) == 2 and low == high == "trend" and not ruled:
        # two planes: a virtual slice half-way whose area follows the sphere's curvature that the volume
        # model gives the two planes (slices.volume), so the side bulges as that model does
        stack = np.concatenate([stack[:prepend + 1], capmod._mid_ring(curves[0], curves[1])[None],
                                stack[prepend + 1:]])
        contour_at[1] += 1
    heights = capmod.resolve_trend(curves, d, low_shape, high_shape)  # extrusions: half caps d/2, trend prisms
    n_limited = 0
    buffer = None
    if len(stack) >= 2 and not ruled and opts.method == "blending":
        # the blend writes the side straight into the capped grid's columns (no copy of the ~1.5 MB side)
        buffer, mid = capmod._grid_buffer(stack.shape[1], len(stack) - 1, low_shape, high_shape)
    if len(stack) >= 2:
        if ruled:
            side, node_eval = ruled_surface(stack)
        else:
            # a trend cap's rings are blended on their own, from the end curve to the apex: the side between
            # the planes keeps the contours' own tangents (the rings' steep fall would bulge it)
            split = (prepend if low == "trend" and low_shape == "dome" else 0,
                     append if high == "trend" and high_shape == "dome" else 0)
            side, node_eval, n_limited = _pieced_side(stack, split, opts, None if buffer is None else buffer[:, mid])
        side_ctrl, bottom, top = side.control, side.control[:, 0, :, 0], side.control[:, -1, :, 3]
    else:
        side_ctrl, bottom = None, curves[0]
        top = bottom

        def node_eval(j, kk):
            return curves[0][j, 0]

    if buffer is None:
        grid = capmod.close_side(side_ctrl, bottom, top, centers[0, :2], centers[-1, :2], heights, low_shape,
                                 high_shape)
    else:
        grid = capmod._close_grid(buffer, bottom, top, centers[0, :2], centers[-1, :2], heights, low_shape,
                                  high_shape)
    # the grid's columns are the checked side's and caps over its end curves: finite and closed as the
    # side is (close_side checks its inputs)
    patches = BezierPatches.unchecked(grid.control, closed_u=True)
    side_patches = BezierPatches.unchecked(grid.control[:, grid.side_columns], closed_u=True)
    volume, area = capmod.grid_integrals(grid)
    cap_volumes = capmod.cap_volumes(grid, curves, prepend, append)
    bulge = 0.0
    if len(curves) == 2 and contour_at[1] - contour_at[0] == 2:
        # the mid slice's share: the side's flux over its two columns against the side blended straight
        from surfaces.measure import side_integrals

        start = grid.side_columns.start + (grid.extrusions[0] > 0)  # the stack's first interval's column
        cols = slice(start + contour_at[0], start + contour_at[1])
        straight = _side_surface(curves, opts.method, z, opts.monotone)[0].control
        bulge = side_integrals(grid.control[:, cols])[0] - side_integrals(straight)[0]
    # deviation at the control points, evaluated on the final surface
    j = np.concatenate(sc.nodes)
    kk = np.repeat(contour_at, [len(n) for n in sc.nodes])
    pts = np.concatenate(sc.points)
    # the largest distance as the root of the largest sum of squares (np.linalg.norm's sum, in its order)
    gap = node_eval(j, kk) - pts
    gap *= gap
    dev = math.sqrt(float((gap[:, 0] + gap[:, 1] + gap[:, 2]).max()))
    tri_mesh = display = density = None
    if mesh:
        if opts.samples:
            density = (opts.samples, opts.samples)
            tri_mesh, display = capmod.weld_flat_caps(tessellate(side_patches, opts.samples), grid, opts.samples,
                                                      inset=body.kind == "outer")
        else:
            # as many subdivisions as each direction needs, not the same count both ways (the caps'
            # rims follow the subdivisions around)
            su, sv = density = mesh_samples(side_patches.control)
            tri_mesh, display = capmod.weld_flat_caps(tessellate(side_patches, (su, sv)), grid, su,
                                                      inset=body.kind == "outer")
    if body.kind == "hole":
        patches = patches.flipped()
        if tri_mesh is not None:
            tri_mesh, display = _flip(tri_mesh), _flip(display)
    return BodySurface(
        body, patches, grid.side_columns, tri_mesh, display, volume, area, dev,
        int(len(pts)), int(np.count_nonzero(np.concatenate([p.turning for p in sc.params]))), int(curves.shape[1]),
        float(sc.start_angle), n_limited, (low, high),
        (abs(capmod._curve_area(curves[0])), abs(capmod._curve_area(curves[-1]))), float(d),
        mesh_samples=density, extrusions_mm=grid.extrusions, cap_volumes_mm3=cap_volumes,
        mid_bulge_mm3=float(bulge),
    )
