"""Ray-cast rendering (surfaces.render) against closed forms."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from surfaces.camera import Camera
from surfaces.render import DEFAULT_COLOR, parse_size, render, render_view


def _top_camera(height: float = 3.0) -> Camera:
    return Camera(eye=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov_deg=None, ortho_height=height)


def _pixel_of(point_xy, size, height):
    """Continuous (col, row) of a world (x, y) seen by the top orthographic camera."""
    w, h = size
    scale = h / height
    return w / 2 + point_xy[0] * scale, h / 2 - point_xy[1] * scale


@pytest.mark.parametrize("light", [(0.3, 0.4, 0.866), (-0.5, 0.2, 0.84), (0.0, -0.6, 0.8)])
def test_highlight_at_half_vector(sphere, light):
    """Specular only: the brightest pixel is where the normal equals the half vector."""
    size = (301, 301)
    res = render_view(sphere, _top_camera(), size, light=light, ambient=0.0, diffuse=0.0,
                           specular=1.0, shininess=400.0)
    lum = np.where(res.hit, res.image.sum(axis=2), -1.0)
    row, col = np.unravel_index(np.argmax(lum), lum.shape)
    half = np.asarray(light, float) / np.linalg.norm(light) + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half)
    want_col, want_row = _pixel_of(half[:2], size, 3.0)
    assert abs(col + 0.5 - want_col) <= 1.5 and abs(row + 0.5 - want_row) <= 1.5
    assert np.degrees(np.arccos(np.clip(res.normal[row, col] @ half, -1, 1))) < 1.5


@pytest.mark.parametrize("light", [(0.3, 0.4, 0.866), (-0.6, -0.3, 0.74)])
def test_lambert_peak_at_light(sphere, light):
    """Diffuse only: the brightest pixel is where the normal equals the light direction."""
    size = (301, 301)
    res = render_view(sphere, _top_camera(), size, light=light, ambient=0.0, diffuse=1.0,
                           specular=0.0)
    lum = np.where(res.hit, res.image.sum(axis=2), -1.0)
    l_unit = np.asarray(light) / np.linalg.norm(light)
    # the Lambert maximum is flat: compare the intensity-weighted centroid of the top pixels
    top = lum >= np.quantile(lum[res.hit], 0.999)
    rows, cols = np.nonzero(top)
    want_col, want_row = _pixel_of(l_unit[:2], size, 3.0)
    assert abs(cols.mean() + 0.5 - want_col) < 2.0 and abs(rows.mean() + 0.5 - want_row) < 2.0
    # Lambert: the lit value equals n.l with interpolated normals
    inside = res.hit & (res.image[..., 0] > 0)
    cosine = res.normal[inside] @ l_unit
    shade = res.image[inside][:, 0] / DEFAULT_COLOR[0]
    assert np.allclose(shade, np.clip(cosine, 0, 1), atol=2e-2)


@pytest.mark.parametrize("ortho_height,size", [(3.0, (320, 240)), (2.5, (200, 200)), (4.0, (400, 300))])
def test_orthographic_silhouette_radius(sphere, ortho_height, size):
    """The silhouette of a unit sphere has radius H / ortho_height pixels (area pi r^2)."""
    res = render_view(sphere, _top_camera(ortho_height), size)
    r_px = size[1] / ortho_height
    area_radius = np.sqrt(res.hit.sum() / np.pi)
    # a 100-segment polygonal sphere is inscribed: its silhouette is at most 0.1 % smaller
    assert abs(area_radius - r_px) / r_px < 6e-3
    rows = np.nonzero(res.hit.any(axis=1))[0]
    assert abs((rows[-1] - rows[0] + 1) / 2 - r_px) <= 1.0


@pytest.mark.parametrize("distance,fov", [(4.0, 40.0), (6.0, 25.0)])
def test_perspective_silhouette_radius(sphere, distance, fov):
    """Pinhole camera: silhouette radius = (H/2) tan(asin(1/d)) / tan(fov/2) pixels."""
    size = (300, 300)
    cam = Camera(eye=(0, 0, distance), target=(0, 0, 0), up=(0, 1, 0), fov_deg=fov)
    res = render_view(sphere, cam, size)
    want = size[1] / 2 * np.tan(np.arcsin(1 / distance)) / np.tan(np.radians(fov) / 2)
    got = np.sqrt(res.hit.sum() / np.pi)
    assert abs(got - want) / want < 1e-2
    assert np.all(res.depth[res.hit] > distance - 1.0 - 1e-3)


def test_projection_matches_rays(sphere):
    """Camera.project sends the hit points back to their own pixel centres."""
    for cam in (_top_camera(), Camera((3, -4, 2), (0, 0, 0), (0, 0, 1), fov_deg=35.0)):
        size = (64, 48)
        rays = cam.rays(*size).reshape(-1, 6).astype(float)
        res = render_view(sphere, cam, size)
        flat = res.hit.ravel()
        pts = rays[flat, :3] + rays[flat, 3:] * res.depth.ravel()[flat, None]
        px, depth = cam.project(pts, *size)
        rows, cols = np.divmod(np.flatnonzero(flat), size[0])
        assert np.allclose(px[:, 0], cols + 0.5, atol=1e-3)
        assert np.allclose(px[:, 1], rows + 0.5, atol=1e-3)
        assert np.all(depth > 0)


def test_shadow_of_sphere_on_plane():
    """A sphere above a plane casts the ellipse that projecting along the light gives."""
    ball = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=80).translate((0, 0, 3))
    floor = o3d.geometry.TriangleMesh.create_box(12, 8, 0.01).translate((-8, -4, -0.01))
    scene = ball + floor
    light = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)
    cam = Camera((-0.5, 0, 10), (-0.5, 0, 0), (0, 1, 0), None, 8.0)
    size = (600, 400)
    res = render_view((np.asarray(scene.vertices), np.asarray(scene.triangles)), cam, size,
                           light=light, shadows=True)
    scale = size[1] / 8.0
    on_floor = res.hit & (res.depth > 9.9)
    area = np.count_nonzero(res.shadow & on_floor) / scale**2
    # the light is towards +x: the shadow of the unit sphere at height 3 is an ellipse centred at
    # x = -3 with semi-axes sqrt 2 (along x) and 1
    assert abs(area - np.pi * np.sqrt(2)) / (np.pi * np.sqrt(2)) < 0.03
    cx = (np.nonzero(res.shadow & on_floor)[1].mean() + 0.5 - size[0] / 2) / scale - 0.5
    assert abs(cx + 3.0) < 0.05
    lit_floor = on_floor & ~res.shadow
    assert res.image[res.shadow & on_floor].mean() < 0.5 * res.image[lit_floor].mean()
    plain = render_view((np.asarray(scene.vertices), np.asarray(scene.triangles)), cam, size,
                             light=light, shadows=False)
    assert not plain.shadow.any()


@pytest.mark.parametrize("views", [["front"], ["front", "side", "top"], ["iso", "top", "side", "front"]])
def test_tiled_views_not_blank(sphere, views):
    """Every tile of a multi-view picture shows the object, shaded (not one flat colour)."""
    size = (480, 360)
    scalars = sphere[0][:, 2]
    img = render(sphere, views, size, scalars=scalars, colorbar_label="z")
    assert img.shape == (360, 480, 3) and img.dtype == np.uint8
    n_cols = int(np.ceil(np.sqrt(len(views))))
    n_rows = int(np.ceil(len(views) / n_cols))
    area_w = 480 - min(120, 480 // 4)
    tw, th = area_w // n_cols, 360 // n_rows
    for k in range(len(views)):
        r, c = divmod(k, n_cols)
        tile = img[r * th : (r + 1) * th, c * tw : (c + 1) * tw].astype(float)
        covered = np.any(tile < 250, axis=2).mean()
        assert 0.1 < covered < 0.95
        assert tile.std() > 20
    bar = img[:, area_w:]
    assert len(np.unique(bar.reshape(-1, 3), axis=0)) > 50


def test_net_overlay_draws_segments(sphere):
    """Given world segments are drawn where the camera projects them."""
    seg = np.array([[[-1.2, 0.0, 1.5], [1.2, 0.0, 1.5]]])
    cam = _top_camera()
    plain = render(sphere, cam, (300, 300))
    lined = render(sphere, cam, (300, 300), net=seg, net_color=(1.0, 0.0, 0.0))
    changed = np.any(plain != lined, axis=2)
    rows, cols = np.nonzero(changed)
    assert abs(rows.mean() - 149.5) < 1.5
    assert cols.min() < 40 and cols.max() > 260
    assert lined[150, 150, 0] > 200 and lined[150, 150, 1] < 60


def test_patches_render_with_net():
    """A Bezier patch model renders with normals from the patches and its control net on top."""
    from surfaces.bezier import BezierPatches

    u = np.linspace(0.0, 3.0, 4)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1)
    ctrl = np.concatenate([grid, 0.2 * np.sin(grid[..., :1] + grid[..., 1:])], axis=-1)
    patches = BezierPatches(ctrl[None, None])
    plain = render(patches, "iso", (200, 150))
    netted = render(patches, "iso", (200, 150), net=True)
    assert np.any(plain < 250) and np.count_nonzero(np.any(plain != netted, axis=2)) > 200


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(size="abc"), "size"),
        (dict(views="diagonal"), "view"),
        (dict(projection="fisheye"), "projection"),
        (dict(light=(0, 0, 0)), "light"),
        (dict(scalars=np.zeros(3)), "scalars"),
        (dict(net=True), "net"),
    ],
)
def test_bad_input(sphere, kwargs, match):
    with pytest.raises(ValueError, match=match):
        render(sphere, **kwargs)


def test_hidden_net_lines(sphere):
    """With net_hidden, a segment behind the sphere disappears; one in front stays."""
    cam = _top_camera()
    behind = np.array([[[-0.5, 0.0, -1.5], [0.5, 0.0, -1.5]]])
    front = np.array([[[-0.5, 0.0, 1.5], [0.5, 0.0, 1.5]]])
    plain = render(sphere, cam, (200, 200))
    for seg, visible in ((behind, False), (front, True)):
        img = render(sphere, cam, (200, 200), net=seg, net_hidden=True, net_color=(1, 0, 0))
        assert np.any(img != plain) == visible
        img = render(sphere, cam, (200, 200), net=seg, net_hidden=False, net_color=(1, 0, 0))
        assert np.any(img != plain)


def test_parse_size():
    assert parse_size("640x480") == (640, 480) and parse_size((32, 16)) == (32, 16)
    for bad in ("640", "axb", (4, 100)):
        with pytest.raises(ValueError, match="size"):
            parse_size(bad)
