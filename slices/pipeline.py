"""A contour input in, one solid with its volume, area and summary out (nothing written).

:func:`reconstruct` reads any supported input (:func:`slices.io.load`),
reconstructs its bodies (:func:`slices.structure.reconstruct_contours`), unites
them or composes the ROI with others (:func:`slices.compose.compose_rois`),
compares with the smoothing B-spline reference (:func:`slices.reference.compare`)
and returns a :class:`SlicesReconstruction`. The command line, the demo and
batch jobs write its files with :func:`workbench.runs.slices.reconstruct_to_folder`.
"""

from __future__ import annotations

import importlib
import time
from dataclasses import dataclass

from slices.compose import compose_rois
from slices.io import ContourStack
from slices.options import ReadOptions, SurfaceOptions, split_options
from slices.reference import compare
from slices.structure import Reconstruction, read_roi, reconstruct_contours
from slices.summary import count_noun, summarize
from surfaces.bezier import BezierPatches
from surfaces.mesh import TriangleMesh
from surfaces.threads import prepare as prepare_threads
from surfaces.validate import InputError

#: Above this many triangles ``union="auto"`` concatenates the bodies instead of uniting them
#: (a memory guard: the meshes of :data:`slices.body.MESH_BUDGET` vertices stay far below it,
#: so every structure comes out as one solid).
UNION_LIMIT = 2_000_000

#: Values of the ``union`` option.
UNION_MODES = ("auto", "yes", "no", True, False)

#: Modules the surface and union stages call. Their own modules import them lazily, so that
#: ``import slices`` stays light; :func:`reconstruct` loads them before its clocks start, so that
#: ``surface_time_s`` and ``union_time_s`` time the work and not a fresh process's first imports
#: (~0.2 s of SciPy, manifold3d and the checks, against ~10 ms of surface for an ordinary organ; scikit-image
#: loads its marching cubes lazily, 0.4 s, on the implicit path's first call).
STAGE_MODULES = ("scipy.sparse.csgraph", "scipy.spatial", "manifold3d", "surfaces.intersect", "surfaces.folds",
                 "surfaces.measure", "surfaces.mixed", "cv2", "scipy.sparse", "skimage.measure._marching_cubes_lewiner")


def _load_stage_modules() -> None:
    """Import :data:`STAGE_MODULES` (a dictionary lookup each once loaded) and take the view of the
    thread pools they bring (:func:`surfaces.threads.prepare`)."""
    for name in STAGE_MODULES:
        importlib.import_module(name)
    prepare_threads()


@dataclass
class SlicesReconstruction:
    """A structure reconstructed from its input, ready to be written.

    Attributes
    ----------
    stack : ContourStack
        The base ROI's contours (with the readers' and the reconstruction's notes).
    reconstruction : Reconstruction
        Its bodies, patches and meshes.
    mesh : TriangleMesh
        The solid: the bodies united (or concatenated), or the composition.
    union : bool
        Whether the bodies were united.
    composition : dict or None
        The composition's record (:func:`slices.compose.compose_rois`).
    reference : dict or None
        The smoothing B-spline comparison (:func:`slices.reference.compare`).
    summary : dict
        Input, options and figures (:func:`slices.summary.summarize`).
    """

    stack: ContourStack
    reconstruction: Reconstruction
    mesh: TriangleMesh
    union: bool
    composition: dict | None
    reference: dict | None
    summary: dict

    @property
    def patches(self) -> list[BezierPatches]:
        """Every body's closed patch grid, in the order of the bodies."""
        return [b.patches for b in self.reconstruction.bodies]

    @property
    def display_mesh(self) -> TriangleMesh:
        """What a picture shows: the bodies with flat-shaded caps, or the composed solid (patient coordinates)."""
        if self.composition is not None:
            return self.mesh
        shown = self.reconstruction.display_mesh
        return shown if shown is None else to_patient(shown, self.stack.frame)


def to_patient(mesh: TriangleMesh, frame) -> TriangleMesh:
    """A mesh built in the plane frame of oblique contours turned into patient coordinates.

    Parameters
    ----------
    mesh : TriangleMesh
        Vertices (V, 3) in the frame's ``u, v, n`` coordinates (mm).
    frame : numpy.ndarray, shape (3, 3), or None
        Rows ``u, v, n`` (:attr:`slices.io.ContourStack.frame`); None: the mesh as it is.

    Returns
    -------
    TriangleMesh
        Vertices ``q @ frame`` (a rotation: orientation, volume and area kept).
    """
    if frame is None:
        return mesh
    normals = None if mesh.vertex_normals is None else mesh.vertex_normals @ frame
    return TriangleMesh(mesh.vertices @ frame, mesh.triangles, vertex_normals=normals)


def reconstruct(input_path, *, roi=None, union="auto", minus=(), plus=(), repair: bool = False,
                reference: bool = True, progress=None, reading: ReadOptions | None = None,
                options: SurfaceOptions | None = None, **keywords) -> SlicesReconstruction:
    """Read a contour input and reconstruct one solid, its volume and area.

    Parameters
    ----------
    input_path : str or os.PathLike
        RTSTRUCT, CT folder, mask stack or contour JSON (see :func:`slices.io.load`).
    roi : str or int, optional
        ROI name or number for RTSTRUCT input.
    union : {"auto", "yes", "no"} or bool
        Several bodies: one solid (manifold3d union, :meth:`Reconstruction.solid_mesh`)
        or their meshes side by side; ``"auto"`` unites up to :data:`UNION_LIMIT` triangles.
    minus, plus : sequence of str or int
        ROIs subtracted from / added to ``roi``: the solid is
        ``(roi u plus...) - (minus...)`` (:func:`slices.compose.compose_rois`).
    repair : bool
        Repair the meshes before composing; without ``minus``/``plus``, repair the written solid
        (:func:`surfaces.repair.repair_mesh`: weld, drop degenerate and duplicate triangles, orient,
        fill small holes), what was done in ``summary["mesh_repair"]``.
    reference : bool
        Compare with the smoothing B-spline reference (seed 000, ref. [5]).
    progress : callable, optional
        Called with finished and total bodies (of every ROI reconstructed).
    reading : ReadOptions, optional
        Base reading options.
    options : SurfaceOptions, optional
        Base surface options.
    **keywords
        Fields of :class:`slices.options.ReadOptions` (``hu_min``, ``hu_max``,
        ``spacing``, ``resample``) and :class:`slices.options.SurfaceOptions`
        (``method``, ``n_rays``, ``caps``, ``lattice_factor``, ``lattice_mode``,
        ``correspondence``, ``start_angle`` in radians, ``samples``).

    Returns
    -------
    SlicesReconstruction

    Examples
    --------
    A cube's worth of square contours, 2 mm apart, read from a contour file:

    >>> import json, tempfile
    >>> from pathlib import Path
    >>> square = [[0, 0], [10, 0], [10, 10], [0, 10]]
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "contours.json"
    ...     _ = path.write_text(json.dumps({"contours": [{"z": z, "points": square} for z in range(0, 12, 2)]}))
    ...     result = reconstruct(path, caps="half", n_rays=16, samples=2, reference=False)
    >>> result.summary["n_slices"], result.summary["slab_volume_mm3"]
    (6, 1000.0)
    >>> result.mesh.is_watertight(), result.union
    (True, False)
    """
    _load_stage_modules()  # start-up, not a stage: before the clocks
    t0 = time.perf_counter()
    read, opts = split_options(keywords, reading, options)
    if union not in UNION_MODES:
        raise InputError(f"union: must be 'auto', 'yes' or 'no', got {union!r}")
    if opts.caps == "none" and (minus or plus):
        raise InputError("caps: set operations need closed solids; use --caps flat, half or dome, not none")
    stack, layout = read_roi(input_path, roi, reading=read)
    # the surface's clock starts with the contours in memory, as a rasteriser's would
    t_read = time.perf_counter()
    rec = reconstruct_contours(stack.contours, progress=progress, options=opts, **layout)
    t_surface = time.perf_counter() - t_read
    t_read -= t0
    rebuilt = [b for b in rec.bodies if b.self_intersecting_faces is not None
               and not b.surface.startswith(opts.method)]
    if rebuilt:
        stack.notes.append(f"{count_noun(len(rebuilt), 'body', 'bodies')} folded with the seed's surface and "
                           f"{'was' if len(rebuilt) == 1 else 'were'} rebuilt "
                           f"({', '.join(sorted({b.surface for b in rebuilt}))})")
    folded = sum(b.self_intersecting_faces or 0 for b in rec.bodies)
    if folded:
        stack.notes.append(f"WARNING: {count_noun(folded, 'self-intersecting face')} "
                           f"{'remains' if folded == 1 else 'remain'} in the bodies' meshes "
                           "after every fallback")
    limited = sum(b.n_limited for b in rec.bodies)
    if limited:
        stack.notes.append(f"the blend across slices was limited (monotone, shape-preserving) at {limited} "
                           f"{'curve point' if limited == 1 else 'curve points'} where the seed's parabolic blending "
                           "would overshoot")
    composition = None
    t_union = time.perf_counter()
    n_tri = sum(b.mesh.n_triangles for b in rec.bodies)
    if minus or plus:
        mesh, composition = compose_rois(input_path, stack, rec, minus=minus, plus=plus, repair=bool(repair),
                                         reading=read, progress=progress)
        united = len(rec.bodies) > 1
    elif union in ("yes", True) or (union == "auto" and n_tri <= UNION_LIMIT):
        mesh, united = rec.solid_mesh()
    else:
        mesh, united = rec.mesh, False
        if len(rec.bodies) > 1:
            stack.notes.append(f"bodies' meshes concatenated, not united ({n_tri} triangles; "
                               "--union yes forces the union)")
    t_union = time.perf_counter() - t_union
    mesh_repair = None
    if repair and not (minus or plus):
        from surfaces.repair import repair_mesh

        mesh, mesh_repair = repair_mesh(mesh, f"ROI {stack.name!r} solid")
        stack.notes.append("--repair: " + (", ".join(f"{k.replace('_', ' ')} {v}" for k, v in mesh_repair.items()
                                                      if k != "repaired" and v) or "nothing to repair"))
    mesh = to_patient(mesh, stack.frame)
    # checked once here; the summary reports the same two flags
    checks = {"watertight": mesh.is_watertight(), "oriented": mesh.is_oriented()}
    if opts.caps != "none" and not (checks["watertight"] and checks["oriented"] and mesh.signed_volume() > 0):
        # never expected (tests check every capped breast ROI); said loudly rather than returned silently
        stack.notes.append("WARNING: the capped mesh is not a closed, consistently and outward oriented solid "
                           f"(watertight {checks['watertight']}, oriented {checks['oriented']}, "
                           f"signed volume {mesh.signed_volume():.6g} mm^3)")
    t_ref = time.perf_counter()
    ref = compare(rec) if reference else None
    t_ref = time.perf_counter() - t_ref
    summary = summarize(input_path, stack, rec, mesh, united, composition, ref,
                        {"read_time_s": t_read, "surface_time_s": t_surface, "union_time_s": t_union,
                         "reference_time_s": t_ref}, checks=checks)
    if mesh_repair is not None:
        summary["mesh_repair"] = mesh_repair
    summary["time_s"] = time.perf_counter() - t0
    return SlicesReconstruction(stack, rec, mesh, united, composition, ref, summary)
