"""Seeing surfaces: open3d conversion, control nets, and headless ray-cast pictures.

Seed 001 shows its Bezier patches through OpenGL and, in finer detail, by ray
tracing. This module does both without a display or a GPU:

* :func:`to_open3d` and :func:`control_net_lineset` build open3d geometry for an
  interactive window (meshes or patch models, optional per-vertex colours or
  scalars mapped through a colour map, and the control net, seed 001's
  "carcass", as a line set).
* :func:`render` ray-casts one or several views with open3d's
  ``RaycastingScene`` (CPU, Embree): one cast for all camera rays, shading by
  Lambert plus Blinn-Phong from barycentrically interpolated *vertex* normals,
  optional shadow rays, per-vertex colours or scalars with a colour bar, and an
  optional control-net overlay.

Conventions
-----------
World coordinates are those of the geometry (mm for CT and height fields).
Standard views assume z is "up" for the front/side views; "top" looks down the
z axis, which is the camera view of a photometric height field (x right, y up,
z towards the camera). Images are RGB, ``(H, W, 3)``; pixel ``(row, col)`` has
its centre at ``col + 0.5``, ``row + 0.5``; row 0 is the top row.
Light directions point from the surface towards the light and are given in the
camera frame (x right, y up, z towards the viewer) so that one light setting
works for every view.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from surfaces.validate import as_array, positive

# view name -> (direction from the target towards the eye, camera up vector)
STANDARD_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "top": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "bottom": ((0.0, 0.0, -1.0), (0.0, -1.0, 0.0)),
    "iso": ((1.0, -1.0, 1.0), (0.0, 0.0, 1.0)),
}

DEFAULT_LIGHT = (-0.35, 0.45, 0.82)
DEFAULT_COLOR = (0.72, 0.76, 0.82)


@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera.

    Attributes
    ----------
    eye, target, up : (3,) float64
        Camera position, the point it looks at, and the approximate up direction
        (world units). ``up`` need not be orthogonal to the viewing direction.
    fov_deg : float or None
        Vertical field of view in degrees for a perspective camera; ``None``
        for an orthographic camera.
    ortho_height : float
        Height of the orthographic view window in world units (ignored for a
        perspective camera).
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float | None = None
    ortho_height: float = 2.0

    def __post_init__(self) -> None:
        for name in ("eye", "target", "up"):
            object.__setattr__(self, name, as_array(getattr(self, name), name, shape=(3,)))
        if np.linalg.norm(self.target - self.eye) == 0:
            raise ValueError("camera: eye and target coincide")
        if self.fov_deg is not None and not 0.0 < float(self.fov_deg) < 180.0:
            raise ValueError(f"fov_deg: must lie in (0, 180) degrees, got {self.fov_deg}")
        positive(self.ortho_height, "ortho_height")
        forward = self.target - self.eye
        if np.linalg.norm(np.cross(forward, self.up)) <= 1e-12 * np.linalg.norm(forward):
            raise ValueError("camera: up is parallel to the viewing direction")

    @property
    def perspective(self) -> bool:
        """True for a perspective camera."""
        return self.fov_deg is not None

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal camera frame.

        Returns
        -------
        right, up, back : (3,) float64
            Image x (right), image y (up) and the direction towards the viewer
            (``back = -forward``), a right-handed frame.
        """
        back = self.eye - self.target
        back = back / np.linalg.norm(back)
        right = np.cross(self.up, back)
        right /= np.linalg.norm(right)
        return right, np.cross(back, right), back

    def _half_extent(self, width: int, height: int) -> tuple[float, float]:
        """Half width and half height of the image plane at unit distance (or ortho window)."""
        aspect = width / height
        if self.perspective:
            half_h = float(np.tan(np.radians(self.fov_deg) / 2.0))
        else:
            half_h = self.ortho_height / 2.0
        return half_h * aspect, half_h

    def rays(self, width: int, height: int) -> np.ndarray:
        """Camera rays through every pixel centre.

        Parameters
        ----------
        width, height : int
            Image size in pixels.

        Returns
        -------
        (height, width, 6) float32
            Origin (3) and direction (3) per pixel, in the RaycastingScene
            layout. Perspective directions are unit vectors; orthographic rays
            start on the image plane through ``eye`` and share the viewing
            direction.
        """
        right, up, back = self.basis()
        half_w, half_h = self._half_extent(width, height)
        x = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * half_w
        y = (1.0 - (np.arange(height) + 0.5) / height * 2.0) * half_h
        rays = np.empty((height, width, 6), np.float32)
        plane = x[None, :, None] * right + y[:, None, None] * up
        if self.perspective:
            direction = plane - back
            direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
            rays[..., :3] = self.eye
            rays[..., 3:] = direction
        else:
            rays[..., :3] = self.eye + plane
            rays[..., 3:] = -back
        return rays

    def project(self, points: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Project world points into the image.

        Parameters
        ----------
        points : (N, 3) array_like
            World points.
        width, height : int
            Image size in pixels.

        Returns
        -------
        pixels : (N, 2) float64
            ``(col, row)`` image coordinates (continuous; pixel centres at +0.5).
        depth : (N,) float64
            Distance in front of the camera along the viewing direction
            (negative behind it).
        """
        pts = as_array(points, "points", shape=(None, 3))
        right, up, back = self.basis()
        rel = pts - self.eye
        xc, yc, depth = rel @ right, rel @ up, -(rel @ back)
        if self.perspective:
            safe = np.where(np.abs(depth) > 1e-12, depth, 1e-12)
            xc, yc = xc / safe, yc / safe
        half_w, half_h = self._half_extent(width, height)
        col = (xc / half_w + 1.0) * width / 2.0
        row = (1.0 - yc / half_h) * height / 2.0
        return np.stack([col, row], axis=1), depth


def fit_camera(
    bounds: np.ndarray,
    view: str | Sequence[float] = "iso",
    aspect: float = 4.0 / 3.0,
    *,
    fov_deg: float | None = None,
    margin: float = 1.08,
    up: Sequence[float] | None = None,
    points: np.ndarray | None = None,
) -> Camera:
    """Camera that frames an axis-aligned box from a standard or given direction.

    Parameters
    ----------
    bounds : (2, 3) array_like
        Box minimum and maximum corners (world units).
    view : str or (3,) array_like
        A name from :data:`STANDARD_VIEWS` (``front``, ``back``, ``side``,
        ``left``, ``top``, ``bottom``, ``iso``) or a direction from the box
        centre towards the eye.
    aspect : float
        Image width / height.
    fov_deg : float, optional
        Vertical field of view for a perspective camera; orthographic when None.
    margin : float
        Extra room around the box (1 = tight).
    up : (3,) array_like, optional
        Up vector; defaults to the standard view's (z, or y for top/bottom).
    points : (N, 3) array_like, optional
        Points to frame tightly (for example the mesh vertices, which must lie in
        the box); the box corners are framed when omitted.

    Returns
    -------
    Camera
        The fitted camera: the box's eight corners project inside the image.
    """
    box = as_array(bounds, "bounds", shape=(2, 3))
    positive(aspect, "aspect")
    positive(margin, "margin")
    if isinstance(view, str):
        if view not in STANDARD_VIEWS:
            raise ValueError(f"view: unknown view {view!r}; choose from {', '.join(STANDARD_VIEWS)}")
        direction, default_up = STANDARD_VIEWS[view]
    else:
        direction = as_array(view, "view", shape=(3,))
        default_up = (0.0, 0.0, 1.0)
        if abs(direction[2]) > 0.99 * np.linalg.norm(direction):
            default_up = (0.0, 1.0, 0.0)
    d = np.asarray(direction, float)
    if np.linalg.norm(d) == 0:
        raise ValueError("view: direction is the zero vector")
    d /= np.linalg.norm(d)
    up_vec = as_array(default_up if up is None else up, "up", shape=(3,))
    centre = box.mean(axis=0)
    radius = max(float(np.linalg.norm(box[1] - box[0])) / 2.0, 1e-9)
    corners = np.array(np.meshgrid(*box.T, indexing="ij")).reshape(3, -1).T
    probe = Camera(centre + d * radius * 4.0, centre, up_vec)
    right, cam_up, back = probe.basis()
    rel = (corners if points is None else as_array(points, "points", shape=(None, 3))) - centre
    ext_x = float(np.abs(rel @ right).max())
    ext_y = float(np.abs(rel @ cam_up).max())
    half_h = max(ext_y, ext_x / aspect, 1e-9) * margin
    if fov_deg is None:
        # the eye sits outside the box so that no corner lies behind the image plane
        return Camera(centre + d * radius * 3.0, centre, up_vec, None, 2.0 * half_h)
    tan_half = np.tan(np.radians(fov_deg) / 2.0)
    distance = half_h / tan_half + radius
    return Camera(centre + d * distance, centre, up_vec, float(fov_deg))


@dataclass(frozen=True)
class RenderResult:
    """One ray-cast view.

    Attributes
    ----------
    image : (H, W, 3) float32
        Shaded RGB in [0, 1].
    hit : (H, W) bool
        Pixels whose ray hit the geometry.
    depth : (H, W) float32
        Ray parameter of the hit (distance along unit rays); ``inf`` on misses.
    normal : (H, W, 3) float32
        Interpolated unit vertex normal at the hit, turned towards the viewer
        (zero on misses).
    scalar : (H, W) float32 or None
        Interpolated per-vertex scalar at the hit (NaN on misses) when scalars
        were given.
    shadow : (H, W) bool
        Hit pixels whose shadow ray was blocked (all False without shadows).
    """

    image: np.ndarray
    hit: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    scalar: np.ndarray | None
    shadow: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]
    return v / np.where(n > 0, n, 1.0)


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals of a triangle mesh.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertex positions.
    triangles : (T, 3) array_like of int
        Vertex indices, counter-clockwise seen from the front.

    Returns
    -------
    (V, 3) float64
        Unit normals (sum of the adjacent face cross products, which weights
        each face by twice its area); zero for unused vertices.
    """
    v = as_array(vertices, "vertices", shape=(None, 3))
    t = as_array(triangles, "triangles", shape=(None, 3), dtype=np.int64)
    face = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    # bincount sums the face vectors per vertex far faster than np.add.at
    idx = t.ravel()
    normals = np.stack(
        [np.bincount(idx, np.repeat(face[:, c], 3), minlength=len(v)) for c in range(3)], axis=1
    )
    return _unit(normals)


def _mesh_arrays(geometry, samples: int = 8):
    """(vertices, triangles, vertex normals or None, vertex colours or None, patches or None)."""
    if hasattr(geometry, "control") and hasattr(geometry, "evaluate_grid"):
        from surfaces.mesh import tessellate

        mesh = tessellate(geometry, samples=samples)
        return (
            np.asarray(mesh.vertices, float),
            np.asarray(mesh.triangles, np.int64),
            None if mesh.vertex_normals is None else np.asarray(mesh.vertex_normals, float),
            None if mesh.vertex_colors is None else np.asarray(mesh.vertex_colors, float),
            geometry,
        )
    if hasattr(geometry, "vertices") and hasattr(geometry, "triangles"):
        verts = np.asarray(geometry.vertices, float)
        tris = np.asarray(geometry.triangles, np.int64)
        normals = getattr(geometry, "vertex_normals", None)
        colors = getattr(geometry, "vertex_colors", None)
        normals = None if normals is None or len(normals) != len(verts) else np.asarray(normals, float)
        colors = None if colors is None or len(colors) != len(verts) else np.asarray(colors, float)
        return verts, tris, normals, colors, None
    if isinstance(geometry, tuple) and len(geometry) == 2:
        return np.asarray(geometry[0], float), np.asarray(geometry[1], np.int64), None, None, None
    raise ValueError(
        "geometry: expected a TriangleMesh, BezierPatches, open3d TriangleMesh or a "
        f"(vertices, triangles) tuple, got {type(geometry).__name__}"
    )


def apply_colormap(
    values: np.ndarray,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    nan_color: Sequence[float] = (0.6, 0.6, 0.6),
) -> np.ndarray:
    """Map scalars to RGB through a matplotlib colour map.

    Parameters
    ----------
    values : array_like, any shape
        Scalars; NaN allowed (drawn in ``nan_color``).
    cmap : str
        Matplotlib colour-map name.
    vmin, vmax : float, optional
        Value range mapped to the ends of the colour map; the finite minimum
        and maximum of ``values`` when omitted.

    Returns
    -------
    (..., 3) float32
        RGB in [0, 1], same leading shape as ``values``.
    """
    import matplotlib

    vals = as_array(values, "values", finite=False)
    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError:
        raise ValueError(f"cmap: unknown matplotlib colour map {cmap!r}") from None
    lo, hi = scalar_range(vals, vmin, vmax)
    finite = np.isfinite(vals)
    t = np.clip((np.where(finite, vals, lo) - lo) / (hi - lo), 0.0, 1.0)
    rgb = colormap(t)[..., :3].astype(np.float32)
    rgb[~finite] = np.asarray(nan_color, np.float32)
    return rgb


def scalar_range(values: np.ndarray, vmin: float | None = None, vmax: float | None = None) -> tuple[float, float]:
    """Value range for a colour map: given ends, else the finite min/max (never empty).

    Parameters
    ----------
    values : array_like
        Scalars (NaN ignored).
    vmin, vmax : float, optional
        Explicit ends.

    Returns
    -------
    (float, float)
        ``lo < hi``.
    """
    vals = np.asarray(values, float)
    finite = vals[np.isfinite(vals)]
    lo = float(vmin) if vmin is not None else (float(finite.min()) if finite.size else 0.0)
    hi = float(vmax) if vmax is not None else (float(finite.max()) if finite.size else 1.0)
    if not hi > lo:
        pad = max(abs(lo), 1.0) * 1e-6
        lo, hi = lo - pad, hi + pad
    return lo, hi


def colorbar_image(
    height: int,
    vmin: float,
    vmax: float,
    cmap: str = "viridis",
    label: str = "",
    width: int = 120,
    background: Sequence[float] = (1.0, 1.0, 1.0),
) -> np.ndarray:
    """A vertical colour bar with tick labels, to place beside a picture.

    Parameters
    ----------
    height : int
        Picture height in pixels.
    vmin, vmax : float
        Values at the bottom and the top of the bar.
    cmap : str
        Matplotlib colour-map name.
    label : str
        Short title written above the bar (units included, e.g. ``"mm"``).
    width : int
        Strip width in pixels.
    background : (3,) float
        RGB background in [0, 1].

    Returns
    -------
    (height, width, 3) uint8
        RGB strip.
    """
    import cv2

    height = int(positive(height, "height"))
    width = int(positive(width, "width"))
    strip = np.empty((height, width, 3), np.uint8)
    strip[:] = (np.asarray(background) * 255).astype(np.uint8)
    top, bottom = min(40, height // 6), max(height - min(14, height // 10), 2)
    bar_h = max(bottom - top, 2)
    values = np.linspace(vmax, vmin, bar_h)
    bar_w = max(min(22, width // 4), 4)
    x0 = 8
    colors = apply_colormap(values, cmap, vmin, vmax)
    strip[top : top + bar_h, x0 : x0 + bar_w] = (colors[:, None, :] * 255).astype(np.uint8)
    ink = (30, 30, 30)
    cv2.rectangle(strip, (x0, top), (x0 + bar_w - 1, top + bar_h - 1), ink, 1)
    scale = max(min(height / 900.0, 0.5), 0.3)
    from matplotlib.ticker import MaxNLocator

    ticks = MaxNLocator(6 if bar_h > 150 else 3).tick_values(vmin, vmax)
    span = vmax - vmin
    for value in ticks[(ticks >= vmin - 1e-9 * span) & (ticks <= vmax + 1e-9 * span)]:
        frac = (vmax - value) / span
        y = int(round(top + frac * (bar_h - 1)))
        cv2.line(strip, (x0 + bar_w, y), (x0 + bar_w + 4, y), ink, 1, cv2.LINE_AA)
        value = 0.0 if abs(value) < 1e-9 * span else value
        cv2.putText(strip, f"{value:.3g}", (x0 + bar_w + 7, y + 4), cv2.FONT_HERSHEY_SIMPLEX,
                    scale, ink, 1, cv2.LINE_AA)
    if label:
        cv2.putText(strip, label[:16], (4, max(top - 10, 10)), cv2.FONT_HERSHEY_SIMPLEX, scale, ink,
                    1, cv2.LINE_AA)
    return strip


def control_net_segments(patches) -> np.ndarray:
    """Line segments of the Bezier control net (seed 001's "carcass").

    Parameters
    ----------
    patches : BezierPatches
        Patch model with ``control`` of shape (R, C, 4, 4, 3).

    Returns
    -------
    (K, 2, 3) float64
        Segment end points: for every patch, the 4 control polygons along u and
        the 4 along v (3 segments each), K = 24 R C. Edges shared by two patches
        appear twice.
    """
    ctrl = as_array(getattr(patches, "control", patches), "patches.control", shape=(None, None, 4, 4, 3))
    along_u = np.stack([ctrl[:, :, :-1, :], ctrl[:, :, 1:, :]], axis=-2)
    along_v = np.stack([ctrl[:, :, :, :-1], ctrl[:, :, :, 1:]], axis=-2)
    return np.concatenate([along_u.reshape(-1, 2, 3), along_v.reshape(-1, 2, 3)])


def control_net_lineset(patches, color: Sequence[float] = (0.1, 0.1, 0.1)):
    """The control net as an open3d line set.

    Parameters
    ----------
    patches : BezierPatches
        Patch model.
    color : (3,) float
        RGB in [0, 1] for every line.

    Returns
    -------
    open3d.geometry.LineSet
        One line per control-polygon segment (see :func:`control_net_segments`).
    """
    import open3d as o3d

    seg = control_net_segments(patches)
    col = as_array(color, "color", shape=(3,))
    lines = o3d.geometry.LineSet()
    lines.points = o3d.utility.Vector3dVector(seg.reshape(-1, 3))
    lines.lines = o3d.utility.Vector2iVector(np.arange(2 * len(seg)).reshape(-1, 2))
    lines.colors = o3d.utility.Vector3dVector(np.tile(col, (len(seg), 1)))
    return lines


def _vertex_colors(n_vertices, colors, scalars, cmap, vmin, vmax):
    if colors is not None and scalars is not None:
        raise ValueError("colors, scalars: give per-vertex colours or scalars, not both")
    if colors is not None:
        col = as_array(colors, "colors", shape=(n_vertices, 3))
        if col.min() < 0 or col.max() > 1:
            raise ValueError("colors: RGB values must lie in [0, 1]")
        return col
    if scalars is not None:
        vals = as_array(scalars, "scalars", shape=(n_vertices,), finite=False)
        return apply_colormap(vals, cmap, vmin, vmax).astype(np.float64)
    return None


def to_open3d(
    geometry,
    colors: np.ndarray | None = None,
    scalars: np.ndarray | None = None,
    *,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    samples: int = 8,
):
    """Convert a mesh or a patch model to an open3d triangle mesh for viewing.

    Parameters
    ----------
    geometry : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        What to show. Patches are tessellated with ``samples`` points per patch
        edge; their vertex normals come from the patches (``du x dv``).
    colors : (V, 3) array_like, optional
        Per-vertex RGB in [0, 1] (V counts the tessellated vertices).
    scalars : (V,) array_like, optional
        Per-vertex values (height, deviation, ...) mapped through ``cmap``.
    cmap, vmin, vmax
        Colour map and its value range (see :func:`apply_colormap`).
    samples : int
        Tessellation density for patches.

    Returns
    -------
    open3d.geometry.TriangleMesh
        With vertex normals (from the input, else area-weighted) and vertex
        colours when given or present in the input.
    """
    import open3d as o3d

    verts, tris, normals, vcols, _ = _mesh_arrays(geometry, samples)
    chosen = _vertex_colors(len(verts), colors, scalars, cmap, vmin, vmax)
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(verts), o3d.utility.Vector3iVector(tris.astype(np.int32))
    )
    mesh.vertex_normals = o3d.utility.Vector3dVector(
        normals if normals is not None else vertex_normals(verts, tris)
    )
    if chosen is not None or vcols is not None:
        mesh.vertex_colors = o3d.utility.Vector3dVector(chosen if chosen is not None else vcols)
    return mesh


def deviation(vertices: np.ndarray, reference) -> np.ndarray:
    """Signed distance from points to a reference surface.

    Parameters
    ----------
    vertices : (N, 3) array_like
        Query points (world units).
    reference : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        Reference surface.

    Returns
    -------
    (N,) float64
        Distance to the closest point of the reference, positive on the side its
        face normals point to (outside for an outward-oriented closed surface).
    """
    import open3d as o3d

    pts = as_array(vertices, "vertices", shape=(None, 3))
    rv, rt, _, _, _ = _mesh_arrays(reference)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(rv.astype(np.float32)), o3d.core.Tensor(rt.astype(np.uint32)))
    closest = scene.compute_closest_points(o3d.core.Tensor(pts.astype(np.float32)))
    foot = closest["points"].numpy().astype(np.float64)
    normal = closest["primitive_normals"].numpy().astype(np.float64)
    dist = np.linalg.norm(pts - foot, axis=1)
    side = np.einsum("ij,ij->i", pts - foot, normal)
    return np.where(side < 0, -dist, dist)


class _Scene:
    """Triangles in an Embree BVH plus the per-vertex data used for shading."""

    def __init__(self, vertices, triangles, normals, colors, scalars):
        import open3d as o3d

        self.o3d = o3d
        self.vertices = vertices
        self.triangles = triangles
        self.normals = normals
        self.colors = colors
        self.scalars = scalars
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(
            o3d.core.Tensor(np.ascontiguousarray(vertices, np.float32)),
            o3d.core.Tensor(np.ascontiguousarray(triangles, np.uint32)),
        )
        self.bounds = np.stack([vertices.min(axis=0), vertices.max(axis=0)])
        self.diagonal = float(np.linalg.norm(self.bounds[1] - self.bounds[0])) or 1.0

    def cast(self, rays: np.ndarray) -> dict[str, np.ndarray]:
        out = self.scene.cast_rays(self.o3d.core.Tensor(rays.reshape(-1, 6)))
        return {k: out[k].numpy() for k in ("t_hit", "primitive_ids", "primitive_uvs", "primitive_normals")}

    def occluded(self, rays: np.ndarray) -> np.ndarray:
        return self.scene.test_occlusions(self.o3d.core.Tensor(rays)).numpy().astype(bool)


def _shade(
    scene: _Scene,
    rays: np.ndarray,
    hits: dict[str, np.ndarray],
    camera: Camera,
    light: np.ndarray,
    ambient: float,
    diffuse: float,
    specular: float,
    shininess: float,
    shadows: bool,
    base_color: np.ndarray,
    cmap: str,
    vrange: tuple[float, float],
    background: np.ndarray,
):
    """Shade one view's hits (flat arrays); returns image, hit, depth, normal, scalar, shadow."""
    n_px = rays.shape[0]
    t_hit = hits["t_hit"]
    hit = np.isfinite(t_hit)
    idx = np.flatnonzero(hit)
    tri = scene.triangles[hits["primitive_ids"][idx].astype(np.int64)]
    # float32 throughout: shading needs no more, and it halves the memory traffic
    uv = hits["primitive_uvs"][idx]
    bary = np.column_stack([1.0 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]]).astype(np.float32)
    n = _unit(np.einsum("kj,kjc->kc", bary, scene.normals[tri]))
    direction = rays[idx, 3:]
    geometric = hits["primitive_normals"][idx]
    # two-sided lighting: open surfaces seen from behind are lit like their front
    facing = np.where(np.einsum("kc,kc->k", geometric, direction) > 0, -1.0, 1.0).astype(np.float32)
    n *= facing[:, None]
    geometric = geometric * facing[:, None]
    right, up, back = camera.basis()
    l_world = _unit(light[0] * right + light[1] * up + light[2] * back).astype(np.float32)
    if camera.perspective:
        half = _unit(l_world - direction)
        ndoth = np.einsum("kc,kc->k", n, half)
    else:
        # one viewing direction for every orthographic ray: one half vector
        ndoth = n @ _unit(l_world + back.astype(np.float32))
    ndotl = n @ l_world
    lit = np.ones(len(idx), bool)
    if shadows and len(idx):
        points = rays[idx, :3].astype(np.float64) + direction * t_hit[idx, None]
        origin = points + geometric * (1e-4 * scene.diagonal)
        shadow_rays = np.empty((len(idx), 6), np.float32)
        shadow_rays[:, :3] = origin
        shadow_rays[:, 3:] = l_world
        lit = ~scene.occluded(shadow_rays)
    lit &= ndotl > 0
    scalar_img = None
    if scene.scalars is not None:
        s = np.einsum("kj,kj->k", bary, scene.scalars[tri])
        albedo = apply_colormap(s, cmap, *vrange)
        scalar_img = np.full(n_px, np.nan, np.float32)
        scalar_img[idx] = s
    elif scene.colors is not None:
        albedo = np.einsum("kj,kjc->kc", bary, scene.colors[tri])
    else:
        albedo = np.broadcast_to(base_color, (len(idx), 3))
    spec = np.where(lit, specular * np.clip(ndoth, 0.0, 1.0) ** np.float32(shininess), 0.0)
    lambert = np.where(lit, diffuse * np.clip(ndotl, 0.0, 1.0), 0.0).astype(np.float32)
    rgb = albedo * (ambient + lambert)[:, None] + spec[:, None]
    image = np.empty((n_px, 3), np.float32)
    image[:] = background
    image[idx] = np.clip(rgb, 0.0, 1.0)
    normal = np.zeros((n_px, 3), np.float32)
    normal[idx] = n
    shadow = np.zeros(n_px, bool)
    if shadows:
        shadow[idx] = ~lit & (ndotl > 0)
    depth = np.where(hit, t_hit, np.inf).astype(np.float32)
    return image, hit, depth, normal, scalar_img, shadow


def _parse_size(size) -> tuple[int, int]:
    if isinstance(size, str):
        parts = size.lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise ValueError(f"size: expected WIDTHxHEIGHT such as 1024x768, got {size!r}")
        size = (int(parts[0]), int(parts[1]))
    if len(size) != 2 or min(int(size[0]), int(size[1])) < 8:
        raise ValueError(f"size: expected (width, height) of at least 8 pixels each, got {size!r}")
    return int(size[0]), int(size[1])


def _prepare_scene(geometry, colors, scalars, samples, cmap, vmin, vmax):
    verts, tris, normals, vcols, patches = _mesh_arrays(geometry, samples)
    if len(tris) == 0:
        raise ValueError("geometry: has no triangles")
    if tris.min() < 0 or tris.max() >= len(verts):
        raise ValueError("geometry: triangle indices out of range")
    if not np.all(np.isfinite(verts)):
        raise ValueError("geometry: vertices contain NaN or infinite values")
    if colors is not None and scalars is not None:
        raise ValueError("colors, scalars: give per-vertex colours or scalars, not both")
    if colors is not None:
        vcols = as_array(colors, "colors", shape=(len(verts), 3))
    svals = None
    vrange = (0.0, 1.0)
    if scalars is not None:
        svals = as_array(scalars, "scalars", shape=(len(verts),), finite=False)
        vrange = scalar_range(svals, vmin, vmax)
    if normals is None or not np.all(np.isfinite(normals)):
        normals = vertex_normals(verts, tris)
    scene = _Scene(verts, tris, _unit(np.asarray(normals, np.float32)),
                   None if vcols is None else np.asarray(vcols, np.float32), svals)
    return scene, patches, vrange


def render_view(
    geometry,
    camera: Camera,
    size: tuple[int, int] | str = (1024, 768),
    **options,
) -> RenderResult:
    """Ray-cast one view (see :func:`render` for the shading options).

    Parameters
    ----------
    geometry : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        What to render.
    camera : Camera
        The camera.
    size : (width, height) or "WxH"
        Image size in pixels.
    **options
        ``colors``, ``scalars``, ``cmap``, ``vmin``, ``vmax``, ``light``,
        ``ambient``, ``diffuse``, ``specular``, ``shininess``, ``shadows``,
        ``color``, ``background``, ``samples``, as in :func:`render`.

    Returns
    -------
    RenderResult
        Image and per-pixel hit data, float32 arrays of shape (H, W[, 3]).
    """
    width, height = _parse_size(size)
    opts = _shading_options(**options)
    scene, _, vrange = _prepare_scene(
        geometry, opts.pop("colors"), opts.pop("scalars"), opts.pop("samples"), opts["cmap"],
        opts.pop("vmin"), opts.pop("vmax"),
    )
    rays = camera.rays(width, height).reshape(-1, 6)
    hits = scene.cast(rays)
    image, hit, depth, normal, scalar, shadow = _shade(scene, rays, hits, camera, vrange=vrange, **opts)
    shape = (height, width)
    return RenderResult(
        image.reshape(*shape, 3),
        hit.reshape(shape),
        depth.reshape(shape),
        normal.reshape(*shape, 3),
        None if scalar is None else scalar.reshape(shape),
        shadow.reshape(shape),
    )


def _shading_options(
    colors=None,
    scalars=None,
    cmap: str = "viridis",
    vmin=None,
    vmax=None,
    light=DEFAULT_LIGHT,
    ambient: float = 0.12,
    diffuse: float = 0.78,
    specular: float = 0.25,
    shininess: float = 40.0,
    shadows: bool = False,
    color=DEFAULT_COLOR,
    background=(1.0, 1.0, 1.0),
    samples: int = 8,
) -> dict:
    light_vec = as_array(light, "light", shape=(3,))
    if np.linalg.norm(light_vec) == 0:
        raise ValueError("light: the zero vector has no direction")
    for name, value in (("ambient", ambient), ("diffuse", diffuse), ("specular", specular)):
        positive(value, name, allow_zero=True)
    positive(shininess, "shininess")
    return dict(
        colors=colors, scalars=scalars, cmap=cmap, vmin=vmin, vmax=vmax,
        light=light_vec / np.linalg.norm(light_vec), ambient=float(ambient), diffuse=float(diffuse),
        specular=float(specular), shininess=float(shininess), shadows=bool(shadows),
        base_color=as_array(color, "color", shape=(3,)),
        background=as_array(background, "background", shape=(3,)).astype(np.float32),
        samples=int(positive(samples, "samples")),
    )


def _visible_segments(scene: _Scene, segments: np.ndarray, camera: Camera, pieces: int) -> np.ndarray:
    """Split segments into ``pieces`` parts; keep the parts whose midpoint the camera sees.

    A part is hidden when a ray from the camera towards its midpoint hits the
    geometry more than 0.5 % of the scene diagonal before reaching it, so lines
    lying on the surface (contours) stay visible.
    """
    t = np.linspace(0.0, 1.0, pieces + 1)
    a, b = segments[:, 0], segments[:, 1]
    pts = a[:, None, :] + (b - a)[:, None, :] * t[None, :, None]
    parts = np.stack([pts[:, :-1], pts[:, 1:]], axis=2).reshape(-1, 2, 3)
    mid = parts.mean(axis=1)
    right, up, back = camera.basis()
    if camera.perspective:
        origin = np.broadcast_to(camera.eye, mid.shape)
        direction = mid - origin
    else:
        origin = mid + back * (2.0 * scene.diagonal + float(np.abs((mid - camera.eye) @ back).max()))
        direction = mid - origin
    dist = np.linalg.norm(direction, axis=1)
    rays = np.empty((len(mid), 6), np.float32)
    rays[:, :3] = origin
    rays[:, 3:] = direction / np.where(dist > 0, dist, 1.0)[:, None]
    t_hit = scene.cast(rays)["t_hit"]
    return parts[~(t_hit < dist - 5e-3 * scene.diagonal)]


def _draw_net(tile: np.ndarray, segments: np.ndarray, camera: Camera, scale: int, color) -> None:
    import cv2

    h, w = tile.shape[:2]
    px, depth = camera.project(segments.reshape(-1, 3), w // scale, h // scale)
    px = px.reshape(-1, 2, 2) * scale
    keep = np.all(depth.reshape(-1, 2) > 0, axis=1) & np.all(np.abs(px) < 4 * max(h, w), axis=(1, 2))
    shift = 4
    pts = np.round(px[keep] * (1 << shift)).astype(np.int32).reshape(-1, 2, 1, 2)
    if len(pts):
        cv2.polylines(tile, list(pts), False, color, max(1, scale), cv2.LINE_AA, shift)


def render(
    geometry,
    views: Sequence[str | Camera] | str | Camera = ("iso",),
    size: tuple[int, int] | str = (1024, 768),
    *,
    projection: str = "orthographic",
    fov_deg: float = 30.0,
    net: bool | np.ndarray = False,
    net_color: Sequence[float] = (0.08, 0.08, 0.08),
    net_hidden: bool = False,
    colorbar: bool = True,
    colorbar_label: str = "",
    labels: bool = True,
    antialias: int = 1,
    **options,
) -> np.ndarray:
    """Ray-cast a mesh or patch model from one or several views into one picture.

    The geometry is put into one Embree BVH and all views' camera rays are cast
    together. Shading per hit (Blinn-Phong, Blinn 1977)::

        c = albedo * (ambient + diffuse * max(0, n.l) * s) + specular * max(0, n.h)^shininess * s

    with ``n`` the vertex normals interpolated with the hit's barycentric
    coordinates (Phong shading), ``l`` the light direction, ``h = (l + v)/|l + v|``
    the half vector towards viewer ``v`` and ``s`` 0 where a shadow ray from the
    hit towards the light is blocked (``shadows=True``), else 1.

    Parameters
    ----------
    geometry : TriangleMesh, BezierPatches, open3d TriangleMesh or (vertices, triangles)
        What to render; patches are tessellated (``samples`` per patch edge)
        with normals from the patches.
    views : str, Camera or sequence of them
        Standard view names (``front``, ``side``, ``top``, ``iso``, ``back``,
        ``left``, ``bottom``) fitted to the geometry's bounding box, or explicit
        cameras. Several views are tiled in a grid (columns = ceil(sqrt(n))).
    size : (width, height) or "WxH"
        Size of the whole picture in pixels, colour bar included.
    projection : {"orthographic", "perspective"}
        Projection of the fitted standard views.
    fov_deg : float
        Vertical field of view of fitted perspective views.
    net : bool or (K, 2, 3) array
        Overlay the control net (True: of the BezierPatches given as geometry)
        or the given world-space segments, drawn anti-aliased on top.
    net_color : (3,) float
        RGB of the net lines.
    net_hidden : bool
        Hide the parts of the lines that the geometry occludes (each segment is
        split in 4 and an occlusion ray is cast to each part's midpoint); lines
        on the surface itself, such as CT contours, stay visible.
    colorbar : bool
        Add a colour bar on the right when ``scalars`` are given.
    colorbar_label : str
        Title of the colour bar (with units).
    labels : bool
        Write each view's name into its tile when several views are shown.
    antialias : int
        Supersampling factor (1 = one ray per pixel; 2 = four).
    **options
        ``colors`` (V, 3) per-vertex RGB in [0, 1]; ``scalars`` (V,) per-vertex
        values; ``cmap``, ``vmin``, ``vmax``; ``light`` (3,) direction towards
        the light in the camera frame (x right, y up, z to the viewer);
        ``ambient``, ``diffuse``, ``specular``, ``shininess``; ``shadows``;
        ``color`` (3,) base RGB; ``background`` (3,) RGB; ``samples``.

    Returns
    -------
    (height, width, 3) uint8
        RGB picture.
    """
    import cv2

    width, height = _parse_size(size)
    if projection not in ("orthographic", "perspective"):
        raise ValueError(f"projection: expected 'orthographic' or 'perspective', got {projection!r}")
    ss = int(positive(antialias, "antialias"))
    if isinstance(views, (str, Camera)):
        views = [views]
    views = list(views)
    if not views:
        raise ValueError("views: give at least one view")
    opts = _shading_options(**options)
    scene, patches, vrange = _prepare_scene(
        geometry, opts.pop("colors"), opts.pop("scalars"), opts.pop("samples"), opts["cmap"],
        opts.pop("vmin"), opts.pop("vmax"),
    )
    segments = None
    if isinstance(net, np.ndarray):
        segments = as_array(net, "net", shape=(None, 2, 3))
    elif net:
        if patches is None:
            raise ValueError("net: a control net needs BezierPatches as geometry (or segments)")
        segments = control_net_segments(patches)
    bar_w = 0
    if colorbar and scene.scalars is not None:
        bar_w = min(120, width // 4)
    area_w = width - bar_w
    n_cols = int(np.ceil(np.sqrt(len(views))))
    n_rows = int(np.ceil(len(views) / n_cols))
    tile_w, tile_h = area_w // n_cols, height // n_rows
    if min(tile_w, tile_h) < 8:
        raise ValueError(f"size: {width}x{height} is too small for {len(views)} views")
    bounds = scene.bounds
    # framing the vertices (a strided subset of at most ~20k) is tighter than the box corners
    frame = scene.vertices[:: max(1, len(scene.vertices) // 20000)]
    extremes = scene.vertices[np.concatenate([scene.vertices.argmin(0), scene.vertices.argmax(0)])]
    frame = np.concatenate([frame, extremes])
    cameras = []
    for view in views:
        if isinstance(view, Camera):
            cameras.append(view)
        else:
            fov = fov_deg if projection == "perspective" else None
            cameras.append(fit_camera(bounds, view, tile_w / tile_h, fov_deg=fov, points=frame))
    rw, rh = tile_w * ss, tile_h * ss
    rays = np.concatenate([cam.rays(rw, rh).reshape(-1, 6) for cam in cameras])
    hits = scene.cast(rays)
    picture = np.empty((height, width, 3), np.uint8)
    picture[:] = (opts["background"] * 255).astype(np.uint8)
    n_px = rw * rh
    for k, cam in enumerate(cameras):
        part = slice(k * n_px, (k + 1) * n_px)
        view_hits = {key: val[part] for key, val in hits.items()}
        image = _shade(scene, rays[part], view_hits, cam, vrange=vrange, **opts)[0]
        tile = (image.reshape(rh, rw, 3) * 255 + 0.5).astype(np.uint8)
        if segments is not None:
            drawn = _visible_segments(scene, segments, cam, 4) if net_hidden else segments
            _draw_net(tile, drawn, cam, ss, tuple(int(255 * c) for c in net_color))
        if ss > 1:
            tile = cv2.resize(tile, (tile_w, tile_h), interpolation=cv2.INTER_AREA)
        if labels and len(views) > 1:
            name = views[k] if isinstance(views[k], str) else f"view {k + 1}"
            cv2.putText(tile, name, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (40, 40, 40), 1,
                        cv2.LINE_AA)
        r, c = divmod(k, n_cols)
        picture[r * tile_h : (r + 1) * tile_h, c * tile_w : (c + 1) * tile_w] = tile
    if bar_w:
        picture[:, area_w:] = colorbar_image(height, *vrange, opts["cmap"], colorbar_label, bar_w,
                                             opts["background"])
    return picture
