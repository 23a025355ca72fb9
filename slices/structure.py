"""All bodies of one structure: reconstructed one by one, then united into one solid.

:func:`reconstruct_contours` chains the contours into bodies
(:func:`slices.chaining.chain`) and builds each (:func:`slices.body.build_body`);
:meth:`Reconstruction.solid_mesh` unites the outer bodies and subtracts the
holes with manifold3d; :func:`read_roi` reads one ROI (or the whole input) into contours and
:func:`reconstruct_roi` reads and reconstructs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slices.body import BodySurface, build_body, build_body_once, build_stepped
from slices.chaining import Outlines, chain, offset_sensitivity, slab_volume
from slices.implicit import ImplicitSurface, implicit_surface
from slices.io import (SPACING_RTOL, Contour, ContourStack, check_spacing, load, parse_spacing,
                       referenced_slice_thickness)
from slices.options import ReadOptions, SurfaceOptions, surface_options
from surfaces.mesh import TriangleMesh, merge_meshes, weld
from surfaces.threads import one_blas_thread
from surfaces.validate import InputError, positive


#: Outward contour offset (mm) of the volume sensitivity (issue 17: what a planning physicist compares).
SENSITIVITY_OFFSET_MM = 0.5

#: Edges of the united solid shorter than these fractions of the bodies' extent are the boolean's
#: slivers (the bodies overlap by 1e-8 of it at shared caps): the first are always collapsed, the
#: second only where the first leave a fold, the third (the overlap itself) only at the faces that
#: still fold after that (:func:`_unfold_slivers`).
SLIVER_FRACTIONS = (1e-10, 1e-9, 1e-8)


def _merged(meshes: list) -> TriangleMesh | None:
    meshes = [m for m in meshes if m is not None]
    if not meshes:
        return None
    return meshes[0] if len(meshes) == 1 else merge_meshes(meshes)


@dataclass
class Reconstruction:
    """All bodies of one structure.

    Attributes
    ----------
    bodies : list of BodySurface
    volume_mm3 : float
        Outer bodies' volumes minus the holes'.
    area_mm2 : float
        All bodies' areas.
    slab_volume_mm3 : float
        The planning systems' count (:func:`slices.chaining.slab_volume`).
    spacing : float
        Slice spacing in mm.
    options : SurfaceOptions
        The options asked for (``samples=None``: each body got the density
        of :func:`slices.body.mesh_samples`).
    sensitivity_mm3 : float
        Change of the volume when every contour grows outward by
        :data:`SENSITIVITY_OFFSET_MM` (:func:`slices.chaining.offset_sensitivity`).
    implicit : ImplicitSurface or None
        The structure's one implicit surface (:func:`slices.implicit.implicit_surface`); then
        ``bodies`` is empty and the volume, area and mesh are the isosurface's.
    """

    bodies: list
    volume_mm3: float
    area_mm2: float
    slab_volume_mm3: float
    spacing: float
    options: SurfaceOptions
    sensitivity_mm3: float = 0.0
    implicit: ImplicitSurface | None = None

    @property
    def surface_path(self) -> str:
        """``"implicit"`` (:mod:`slices.implicit`) or ``"coons"`` (the seed's patches, body by body)."""
        return "coons" if self.implicit is None else "implicit"

    def volume_by_caps(self) -> dict:
        """The structure's volume under each end-slice convention, and the slab count.

        Returns
        -------
        dict
            ``none``, ``flat``, ``half`` (mm^3: outer bodies minus holes, every
            body capped that way, :meth:`slices.body.BodySurface.volume_with_caps`;
            bodies with domes are built again without a mesh) and ``slab``
            (:attr:`slab_volume_mm3`).
        """
        sign = {"outer": 1.0, "hole": -1.0}
        out = {}
        if self.implicit is not None:
            out = {caps: self.implicit.volume_with_caps(caps) for caps in ("none", "flat", "half")}
            out["slab"] = float(self.slab_volume_mm3)
            return out
        for caps in ("none", "flat", "half"):
            total = 0.0
            for b in self.bodies:
                v = b.volume_with_caps(caps)
                if v is None:
                    v = build_body(b.body, self.spacing, surface_options(self.options, caps=caps, samples=1),
                                   mesh=False).volume_mm3
                total += sign[b.body.kind] * v
            out[caps] = float(total)
        out["slab"] = float(self.slab_volume_mm3)
        return out

    @property
    def mesh(self) -> TriangleMesh | None:
        """All bodies' triangles concatenated in one mesh (None when no mesh was built).

        Bodies that meet half-way between planes at a branching keep their
        caps there (internal walls); see :meth:`solid_mesh`. The implicit surface's mesh when there is one.
        """
        if self.implicit is not None:
            return self.implicit.mesh
        return _merged([b.mesh for b in self.bodies])

    @property
    def display_mesh(self) -> TriangleMesh | None:
        """All bodies' display meshes (caps shaded with their own normals), or the implicit surface's mesh."""
        if self.implicit is not None:
            return self.implicit.mesh
        return _merged([b.display_mesh for b in self.bodies])

    @property
    def max_deviation_mm(self) -> float:
        """Largest control-point deviation over all bodies (the implicit surface: contour point to nearest vertex)."""
        if self.implicit is not None:
            return self.implicit.max_deviation_mm
        return max((b.max_deviation_mm for b in self.bodies), default=0.0)

    def solid_mesh(self) -> tuple[TriangleMesh | None, bool]:
        """One solid: manifold3d union of the outer bodies minus the holes.

        Returns
        -------
        mesh : TriangleMesh or None
            Without internal walls; the concatenated :attr:`mesh` when the
            union fails (or there is only one body).
        union : bool
            Whether the union was made.
        """
        if sum(b.mesh is not None for b in self.bodies) > 1:
            solid = solid_union(self.bodies)
            if solid is not None:
                return solid, True
        return self.mesh, False


def reconstruct_contours(contours: list[Contour], *, spacing: float | None = None, irregular: bool = False,
                         mesh: bool = True, progress=None, options: SurfaceOptions | None = None,
                         **keywords) -> Reconstruction:
    """Reconstruct a structure from validated contours in memory.

    Parameters
    ----------
    contours : list of Contour
        Counter-clockwise contours (see :func:`slices.polygons.clean_contour`).
    spacing : float, optional
        Slice spacing in mm; checked against the planes (taken from them when omitted).
    irregular : bool
        Accept unequally spaced planes: consecutive planes are neighbours and
        the blending in ``v`` uses the slice positions (non-uniform parabolas)
        instead of failing.
    mesh : bool
        Build triangle meshes.
    progress : callable, optional
        Called with the number of finished bodies and the total.
    options : SurfaceOptions, optional
        Method, rays, caps, lattice, ray rotation and tessellation (the defaults when omitted).
    **keywords
        Fields of :class:`slices.options.SurfaceOptions` that override ``options``.
        ``samples=None`` (default) gives every body mesh edges of about
        :data:`slices.body.EDGE_MM` around and across the slices
        (:func:`slices.body.mesh_samples`).

    Returns
    -------
    Reconstruction

    Examples
    --------
    A cylinder of radius 10 mm and height 20 mm, drawn as circles of 64 points
    on five planes 5 mm apart, with flat caps: the surface passes through every
    point and encloses the cylinder's volume ``pi r^2 h`` (to the curve's
    interpolation between the points):

    >>> import numpy as np
    >>> from slices.io import Contour
    >>> t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    >>> circle = 10 * np.stack([np.cos(t), np.sin(t)], axis=1)
    >>> rec = reconstruct_contours([Contour(z, circle) for z in (0.0, 5.0, 10.0, 15.0, 20.0)], mesh=False, caps="flat")
    >>> len(rec.bodies), rec.max_deviation_mm < 1e-9
    (1, True)
    >>> round(rec.volume_mm3 / (np.pi * 10**2 * 20), 4)
    1.0
    """
    opts = surface_options(options, **keywords)
    if not contours:
        raise InputError("contours: no contours given")
    # the contours' areas, perimeters, boxes, planes and holes once, for the chains and both slab figures
    outlines = Outlines.of(contours)
    planes = outlines.planes
    if irregular and len(planes) > 1:
        d = float(np.median(np.diff(planes)))
    else:
        d = check_spacing(planes, "contours", allow_gaps=True)
    if spacing is not None and not irregular:
        s = positive(spacing, "spacing")
        if d and abs(s - d) > SPACING_RTOL * d:
            raise InputError(f"spacing: {s} mm given but the planes are {d} mm apart")
        d = s
    if d == 0:
        raise InputError("contours: a single plane has no slice spacing and the input states no slab "
                         "thickness; give it (--slice-thickness MM on the command line)")
    slab = slab_volume(contours, None if irregular else d, outlines)
    sensitivity = offset_sensitivity(contours, None if irregular else d, SENSITIVITY_OFFSET_MM, outlines)
    # a single chain (one contour per plane, no hole) gets the seed's patches; the others one implicit surface
    single = (not outlines.hole.any() and len(planes) == len(contours))
    path = opts.surface_path
    bodies = chain(contours, None if irregular else d, outlines) if path == "coons" or single else []
    if path == "implicit" or (path == "auto" and (not single or len(bodies) != 1)):
        return _implicit(contours, d, irregular, opts, slab, sensitivity, progress, outlines)
    built = []
    # a body's work is thousands of thin products (16 control points a patch): BLAS threads only wait
    with one_blas_thread():
        if path == "auto" and mesh and opts.unfold:
            # one chain: the seed's patches as asked for; if their mesh folds, the implicit surface (one clean
            # solid, as fast as a raster) rather than the slower fallback surfaces and stepped slabs
            from surfaces.intersect import is_fold_free

            first = build_body_once(bodies[0], d, opts, mesh=True)
            if not is_fold_free(first.mesh.vertices, first.mesh.triangles):
                return _implicit(contours, d, irregular, opts, slab, sensitivity, progress, outlines)
            first.surface, first.self_intersecting_faces = f"{opts.method} ({opts.correspondence})", 0
            built.append(first)
            if progress is not None:
                progress(1, 1)
        else:
            for i, body in enumerate(bodies):
                built.extend(build_stepped(body, d, opts, mesh=mesh))
                if progress is not None:
                    progress(i + 1, len(bodies))
    sign = {"outer": 1.0, "hole": -1.0}
    volume = sum(sign[b.body.kind] * b.volume_mm3 for b in built)
    area = sum(b.area_mm2 for b in built)
    return Reconstruction(built, float(volume), float(area), slab, d, opts, sensitivity)


def _implicit(contours, d, irregular, opts, slab, sensitivity, progress, outlines) -> Reconstruction:
    """The structure as one implicit surface (:func:`slices.implicit.implicit_surface`)."""
    imp = implicit_surface(contours, d, caps=opts.caps, irregular=irregular, outlines=outlines)
    if progress is not None:
        progress(1, 1)
    return Reconstruction([], imp.volume_mm3, imp.area_mm2, slab, d, opts, sensitivity, implicit=imp)


def read_roi(input_path, roi=None, *, reading: ReadOptions | None = None) -> tuple[ContourStack, dict]:
    """Read one ROI (or the whole input) into contours in memory, ready for :func:`reconstruct_contours`.

    Parameters
    ----------
    input_path : str or os.PathLike
        RTSTRUCT, CT folder, mask stack or contour JSON (see :func:`slices.io.load`).
    roi : str or int, optional
        ROI name or number (RTSTRUCT).
    reading : ReadOptions, optional
        Intensity window, voxel spacing, slice thickness (the slab of a single plane of
        contours: ``slice_thickness``, else the z of ``spacing``, else the structure set's
        ``ContourSlabThickness``, else the SliceThickness of the CT images beside it,
        :func:`slices.io.referenced_slice_thickness`), resampling. With ``resample``, contour
        inputs (RTSTRUCT, JSON) are blended at their true plane positions
        (``irregular`` of :func:`reconstruct_contours`).

    Returns
    -------
    stack : ContourStack
    layout : dict
        ``spacing`` (mm or None: the slab of a single plane, given by ``--spacing``) and
        ``irregular`` (bool), the keywords of :func:`reconstruct_contours` for ``stack.contours``.
    """
    read = ReadOptions() if reading is None else reading
    stack = load(input_path, roi, read.hu_min, read.hu_max, read.spacing, bool(read.resample))
    spacing = None
    if len(stack.planes) == 1:
        # one plane has no spacing of its own: its slab is --slice-thickness, the z of --spacing z,y,x,
        # the structure set's ContourSlabThickness or the SliceThickness of the images beside it
        source = ""
        if read.slice_thickness is not None:
            spacing, source = positive(read.slice_thickness, "--slice-thickness"), "--slice-thickness"
        elif read.spacing is not None:
            given = read.spacing
            single = isinstance(given, int | float) or (isinstance(given, str) and "," not in given)
            spacing = positive(given, "--spacing") if single else parse_spacing(given)[0]
            source = "--spacing"
        elif stack.thickness_mm:
            spacing, source = stack.thickness_mm, stack.thickness_source
        elif stack.source == "rtstruct":
            spacing, source = referenced_slice_thickness(input_path)
        if spacing:
            stack.notes.append(f"a single plane of contours: reconstructed as a slab {spacing:g} mm thick "
                               f"(from {source})")
    return stack, {"spacing": spacing,
                   "irregular": bool(read.resample) and stack.source in ("rtstruct", "json")}


def reconstruct_roi(input_path, roi=None, *, reading: ReadOptions | None = None,
                    options: SurfaceOptions | None = None, progress=None) -> tuple[ContourStack, Reconstruction]:
    """Read one ROI (or the whole input) and reconstruct it.

    Parameters
    ----------
    input_path : str or os.PathLike
        RTSTRUCT, CT folder, mask stack or contour JSON (see :func:`slices.io.load`).
    roi : str or int, optional
        ROI name or number (RTSTRUCT).
    reading : ReadOptions, optional
        How the input is read (see :func:`read_roi`).
    options : SurfaceOptions, optional
        How the contours become a surface.
    progress : callable, optional
        See :func:`reconstruct_contours`.

    Returns
    -------
    stack : ContourStack
    reconstruction : Reconstruction
    """
    stack, layout = read_roi(input_path, roi, reading=reading)
    return stack, reconstruct_contours(stack.contours, progress=progress, options=options, **layout)


def solid_union(bodies: list[BodySurface]) -> TriangleMesh | None:
    """Union of the outer bodies' meshes minus the holes (manifold3d).

    Parameters
    ----------
    bodies : list of BodySurface
        Bodies with meshes (holes oriented into the hole).

    Returns
    -------
    TriangleMesh or None
        The solid, or None when a mesh is not watertight or manifold3d fails.
    """
    import manifold3d

    closed = [b for b in bodies if b.mesh is not None and b.mesh.is_watertight()]
    if len(closed) != len(bodies):
        return None
    centre = np.mean([b.mesh.vertices.mean(axis=0) for b in closed], axis=0)
    extent = max(float(np.ptp(b.mesh.vertices, axis=0).max()) for b in closed)

    def solid(b: BodySurface, outward: bool):
        mesh = b.mesh
        verts = mesh.vertices - centre
        # bodies that meet at a branching plane only touch there (coplanar half caps); a tiny
        # overlap lets the union remove the shared caps instead of keeping them as inner walls
        eps = 1e-8 * extent
        z = verts[:, 2]
        for why, plane, step in ((b.body.start, z.min(), -eps), (b.body.stop, z.max(), eps)):
            if why != "end":
                verts = verts.copy()
                verts[np.abs(z - plane) <= 1e-9 * extent, 2] += step
        tri = mesh.triangles if outward else mesh.triangles[:, ::-1]
        m = manifold3d.Manifold(manifold3d.Mesh64(
            vert_properties=np.ascontiguousarray(verts, dtype=np.float64),
            tri_verts=np.ascontiguousarray(tri, dtype=np.uint64)))
        return m if m.status() == manifold3d.Error.NoError else None

    outer = [solid(b, True) for b in closed if b.body.kind == "outer"]
    holes = [solid(b, False) for b in closed if b.body.kind == "hole"]
    if not outer or any(m is None for m in outer + holes):
        return None
    result = manifold3d.Manifold.batch_boolean(outer, manifold3d.OpType.Add) if len(outer) > 1 else outer[0]
    if holes:
        result = manifold3d.Manifold.batch_boolean([result] + holes, manifold3d.OpType.Subtract)
    if result.status() != manifold3d.Error.NoError or result.is_empty():
        return None
    out = result.to_mesh64()
    verts = np.asarray(out.vert_properties, dtype=np.float64)[:, :3] + centre
    tri = np.asarray(out.tri_verts, dtype=np.int64).reshape(-1, 3)
    merge_from = np.asarray(out.merge_from_vert, dtype=np.int64)
    if len(merge_from):
        remap = np.arange(len(verts))
        remap[merge_from] = np.asarray(out.merge_to_vert, dtype=np.int64)
        tri = remap[tri]
    return _unfold_slivers(TriangleMesh(verts, tri), extent)


def _unfold_slivers(mesh: TriangleMesh, extent: float) -> TriangleMesh:
    """The union's mesh with its slivers collapsed, wider ones too where the smallest leave a fold.

    Edges under ``SLIVER_FRACTIONS[0] * extent`` (mm) are collapsed (:func:`_collapse_slivers`).
    Where a face then still crosses another within the z ranges of the edges under
    ``SLIVER_FRACTIONS[2] * extent`` (the bodies' overlap), every edge under ``SLIVER_FRACTIONS[1] *
    extent`` is collapsed as well, if that unfolds them (the breast BODY: an edge of 5e-8 mm left where
    three bodies' flat caps meet a fourth's at z = -104.44 mm, its needle piercing the wall); failing
    that, the edges under ``SLIVER_FRACTIONS[2] * extent`` among the faces around the crossings only, if
    that unfolds them (BODY with dome caps: a needle of 2e-6 mm at the same plane; collapsing every such
    edge of the solid would fold others). Every other mesh comes back as the smallest collapse gives it.
    """
    out = _collapse_slivers(mesh, SLIVER_FRACTIONS[0] * extent)
    widest = SLIVER_FRACTIONS[2] * extent
    band = _sliver_band(out, widest)
    if band is None or not _folds_in_band(out, band):
        return out
    unfolded = _collapse_slivers(mesh, SLIVER_FRACTIONS[1] * extent)
    if unfolded is not mesh and not _folds_in_band(unfolded, band):
        return unfolded
    return _unfold_around_folds(out, band, widest)


def _unfold_around_folds(mesh: TriangleMesh, band: tuple[np.ndarray, np.ndarray], tiny: float) -> TriangleMesh:
    """The mesh with the edges shorter than ``tiny`` (mm) collapsed among the faces at its folds in ``band``.

    Only the faces that share a vertex with a crossing face take part; the result is kept when it
    is closed, oriented and free of crossings in the band, else the mesh comes back as it is.
    """
    folded = _band_folds(mesh, band)
    tri = mesh.triangles
    around = np.isin(tri, np.unique(tri[folded])).any(axis=1)
    short = (_edge_lengths(mesh) < tiny) & around[:, None]
    if not short.any():
        return mesh
    welded = weld(mesh, tiny, candidates=np.unique(tri[short | np.roll(short, -1, axis=1)]))
    if welded.is_watertight() and welded.is_oriented() and not _folds_in_band(welded, band):
        return welded
    return mesh


def _edge_lengths(mesh: TriangleMesh) -> np.ndarray:
    """Lengths (T, 3) of each triangle's edges (mm), edge ``k`` ending at corner ``k``."""
    tri = mesh.triangles
    return np.linalg.norm(mesh.vertices[tri] - mesh.vertices[np.roll(tri, 1, axis=1)], axis=-1)


def _sliver_band(mesh: TriangleMesh, tiny: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The z ranges (mm) of the faces at the edges shorter than ``tiny``: merged, sorted, widened by ``tiny``.

    Returns
    -------
    (low, high) or None
        Starts (K,) in increasing order and the running maximum of the ends (K,); None without such edges.
    """
    tri = mesh.triangles
    short = _edge_lengths(mesh) < tiny
    if not short.any():
        return None
    ends = np.unique(tri[short | np.roll(short, -1, axis=1)])
    z = mesh.vertices[tri[np.isin(tri, ends).any(axis=1)], 2]
    order = np.argsort(z.min(axis=1))
    return z.min(axis=1)[order] - tiny, np.maximum.accumulate(z.max(axis=1)[order]) + tiny


def _in_band(mesh: TriangleMesh, band: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Which faces (T,) reach into the z ranges of :func:`_sliver_band`."""
    low, high = band
    z = mesh.vertices[mesh.triangles, 2]
    # the ranges starting below a face's top; it meets one of them if the highest of their ends reaches its bottom
    last = np.searchsorted(low, z.max(axis=1), side="right") - 1
    return (last >= 0) & (high[np.maximum(last, 0)] >= z.min(axis=1))


def _folds_in_band(mesh: TriangleMesh, band: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether faces within the z ranges of :func:`_sliver_band` cross each other.

    A face that crosses one at a sliver shares its z range, so the faces outside the band need no test.
    """
    from surfaces.intersect import self_intersections

    return self_intersections(mesh.vertices, mesh.triangles[_in_band(mesh, band)], first=True).n_faces > 0


def _band_folds(mesh: TriangleMesh, band: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Which faces (T,) within the z ranges of :func:`_sliver_band` cross another (every one of them)."""
    from surfaces.intersect import self_intersections

    near = np.flatnonzero(_in_band(mesh, band))
    out = np.zeros(mesh.n_triangles, dtype=bool)
    out[near] = self_intersections(mesh.vertices, mesh.triangles[near]).faces
    return out


def _collapse_slivers(mesh: TriangleMesh, tiny: float) -> TriangleMesh:
    """The mesh with its edges shorter than ``tiny`` (mm) collapsed, when that keeps it closed and oriented.

    Where caps coincide the boolean can leave edges far below the overlap eps: needles and
    points that the self-intersection test sees piercing their neighbours.
    """
    tri = mesh.triangles
    short = _edge_lengths(mesh) < tiny
    if not short.any():
        return mesh
    welded = weld(mesh, tiny, candidates=np.unique(tri[short | np.roll(short, -1, axis=1)]))
    return welded if welded.is_watertight() and welded.is_oriented() else mesh
