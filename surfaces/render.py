"""Headless ray-cast pictures of meshes and patch models (seed 001's ray-traced views).

:func:`render` ray-casts one or several views with open3d's ``RaycastingScene``
(CPU, Embree; no display, no GPU): one cast for all camera rays, shading by
Lambert plus Blinn-Phong from barycentrically interpolated *vertex* normals,
optional shadow rays, per-vertex colours or scalars with a colour bar, the
views tiled into one picture and an optional control-net overlay.
:func:`render_view` returns one view with its per-pixel hit data.

Conventions
-----------
Cameras and standard views are those of :mod:`surfaces.camera`. Pictures are
RGB, ``(H, W, 3)``; row 0 is the top row. Light directions point from the
surface towards the light and are given in the camera frame (x right, y up,
z towards the viewer) so that one light setting works for every view.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from surfaces.bezier import BezierPatches, control_net_segments
from surfaces.camera import Camera, fit_camera
from surfaces.colormap import apply_colormap, colorbar_image, scalar_range, vertex_values
from surfaces.mesh import PATCH_SAMPLES, as_mesh, vertex_normals
from surfaces.validate import as_array, InputError, positive
from surfaces.vectors import unit

__all__ = ["DEFAULT_LIGHT", "DEFAULT_COLOR", "RenderResult", "parse_size", "render_view", "render"]

DEFAULT_LIGHT = (-0.35, 0.45, 0.82)
DEFAULT_COLOR = (0.72, 0.76, 0.82)


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
    n = unit(np.einsum("kj,kjc->kc", bary, scene.normals[tri]))
    direction = rays[idx, 3:]
    geometric = hits["primitive_normals"][idx]
    # two-sided lighting: open surfaces seen from behind are lit like their front
    facing = np.where(np.einsum("kc,kc->k", geometric, direction) > 0, -1.0, 1.0).astype(np.float32)
    n *= facing[:, None]
    geometric = geometric * facing[:, None]
    right, up, back = camera.basis()
    l_world = unit(light[0] * right + light[1] * up + light[2] * back).astype(np.float32)
    if camera.perspective:
        half = unit(l_world - direction)
        ndoth = np.einsum("kc,kc->k", n, half)
    else:
        # one viewing direction for every orthographic ray: one half vector
        ndoth = n @ unit(l_world + back.astype(np.float32))
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


def parse_size(size) -> tuple[int, int]:
    """Picture size from ``"WIDTHxHEIGHT"`` or ``(width, height)``.

    Parameters
    ----------
    size : str or (int, int)
        For example ``"1024x768"``; each side at least 8 pixels.

    Returns
    -------
    (int, int)
        ``(width, height)`` in pixels.

    Examples
    --------
    >>> parse_size("640x480")
    (640, 480)
    """
    if isinstance(size, str):
        parts = size.lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise InputError(f"size: expected WIDTHxHEIGHT such as 1024x768, got {size!r}")
        size = (int(parts[0]), int(parts[1]))
    if len(size) != 2 or min(int(size[0]), int(size[1])) < 8:
        raise InputError(f"size: expected (width, height) of at least 8 pixels each, got {size!r}")
    return int(size[0]), int(size[1])


def _prepare_scene(geometry, colors, scalars, samples, vmin, vmax):
    mesh = as_mesh(geometry, "geometry", samples)
    if mesh.n_triangles == 0:
        raise InputError("geometry: has no triangles")
    colors, scalars = vertex_values(mesh.n_vertices, colors, scalars)
    if colors is None:
        colors = mesh.vertex_colors
    vrange = (0.0, 1.0) if scalars is None else scalar_range(scalars, vmin, vmax)
    normals = mesh.vertex_normals
    if normals is None:
        normals = vertex_normals(mesh.vertices, mesh.triangles)
    scene = _Scene(mesh.vertices, mesh.triangles, unit(normals.astype(np.float32)),
                   None if colors is None else colors.astype(np.float32), scalars)
    return scene, geometry if isinstance(geometry, BezierPatches) else None, vrange


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
    width, height = parse_size(size)
    opts = _shading_options(**options)
    scene, _, vrange = _prepare_scene(
        geometry, opts.pop("colors"), opts.pop("scalars"), opts.pop("samples"), opts.pop("vmin"), opts.pop("vmax")
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
    samples: int = PATCH_SAMPLES,
) -> dict:
    light_vec = as_array(light, "light", shape=(3,))
    if np.linalg.norm(light_vec) == 0:
        raise InputError("light: the zero vector has no direction")
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

    Examples
    --------
    >>> from surfaces.mesh import TriangleMesh
    >>> square = TriangleMesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    >>> picture = render(square, "top", (64, 48))
    >>> picture.shape, picture.dtype.name
    ((48, 64, 3), 'uint8')
    >>> bool((picture[24, 32] < 255).any()), picture[0, 0].tolist()  # the square, on white
    (True, [255, 255, 255])
    """
    import cv2

    width, height = parse_size(size)
    if projection not in ("orthographic", "perspective"):
        raise InputError(f"projection: expected 'orthographic' or 'perspective', got {projection!r}")
    ss = int(positive(antialias, "antialias"))
    if isinstance(views, (str, Camera)):
        views = [views]
    views = list(views)
    if not views:
        raise InputError("views: give at least one view")
    opts = _shading_options(**options)
    scene, patches, vrange = _prepare_scene(
        geometry, opts.pop("colors"), opts.pop("scalars"), opts.pop("samples"), opts.pop("vmin"), opts.pop("vmax")
    )
    segments = None
    if isinstance(net, np.ndarray):
        segments = as_array(net, "net", shape=(None, 2, 3))
    elif net:
        if patches is None:
            raise InputError("net: a control net needs BezierPatches as geometry (or segments)")
        segments = control_net_segments(patches)
    bar_w = 0
    if colorbar and scene.scalars is not None:
        bar_w = min(120, width // 4)
    area_w = width - bar_w
    n_cols = int(np.ceil(np.sqrt(len(views))))
    n_rows = int(np.ceil(len(views) / n_cols))
    tile_w, tile_h = area_w // n_cols, height // n_rows
    if min(tile_w, tile_h) < 8:
        raise InputError(f"size: {width}x{height} is too small for {len(views)} views")
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
