"""Ray-cast rendering and open3d conversion (surfaces.view) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from surfaces import view
from surfaces.io import write_png

o3d = pytest.importorskip("open3d")


@pytest.fixture(scope="module")
def sphere():
    """Unit sphere at the origin, about 20k triangles, exact vertex normals."""
    mesh = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=100)
    verts = np.asarray(mesh.vertices)
    return verts, np.asarray(mesh.triangles)


def _top_camera(height: float = 3.0) -> view.Camera:
    return view.Camera(eye=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov_deg=None, ortho_height=height)


def _pixel_of(point_xy, size, height):
    """Continuous (col, row) of a world (x, y) seen by the top orthographic camera."""
    w, h = size
    scale = h / height
    return w / 2 + point_xy[0] * scale, h / 2 - point_xy[1] * scale


@pytest.mark.parametrize("light", [(0.3, 0.4, 0.866), (-0.5, 0.2, 0.84), (0.0, -0.6, 0.8)])
def test_highlight_at_half_vector(sphere, light):
    """Specular only: the brightest pixel is where the normal equals the half vector."""
    size = (301, 301)
    res = view.render_view(sphere, _top_camera(), size, light=light, ambient=0.0, diffuse=0.0,
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
    res = view.render_view(sphere, _top_camera(), size, light=light, ambient=0.0, diffuse=1.0,
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
    shade = res.image[inside][:, 0] / view.DEFAULT_COLOR[0]
    assert np.allclose(shade, np.clip(cosine, 0, 1), atol=2e-2)


@pytest.mark.parametrize("ortho_height,size", [(3.0, (320, 240)), (2.5, (200, 200)), (4.0, (400, 300))])
def test_orthographic_silhouette_radius(sphere, ortho_height, size):
    """The silhouette of a unit sphere has radius H / ortho_height pixels (area pi r^2)."""
    res = view.render_view(sphere, _top_camera(ortho_height), size)
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
    cam = view.Camera(eye=(0, 0, distance), target=(0, 0, 0), up=(0, 1, 0), fov_deg=fov)
    res = view.render_view(sphere, cam, size)
    want = size[1] / 2 * np.tan(np.arcsin(1 / distance)) / np.tan(np.radians(fov) / 2)
    got = np.sqrt(res.hit.sum() / np.pi)
    assert abs(got - want) / want < 1e-2
    assert np.all(res.depth[res.hit] > distance - 1.0 - 1e-3)


def test_projection_matches_rays(sphere):
    """Camera.project sends the hit points back to their own pixel centres."""
    for cam in (_top_camera(), view.Camera((3, -4, 2), (0, 0, 0), (0, 0, 1), fov_deg=35.0)):
        size = (64, 48)
        rays = cam.rays(*size).reshape(-1, 6).astype(float)
        res = view.render_view(sphere, cam, size)
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
    cam = view.Camera((-0.5, 0, 10), (-0.5, 0, 0), (0, 1, 0), None, 8.0)
    size = (600, 400)
    res = view.render_view((np.asarray(scene.vertices), np.asarray(scene.triangles)), cam, size,
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
    plain = view.render_view((np.asarray(scene.vertices), np.asarray(scene.triangles)), cam, size,
                             light=light, shadows=False)
    assert not plain.shadow.any()


@pytest.mark.parametrize("views", [["front"], ["front", "side", "top"], ["iso", "top", "side", "front"]])
def test_tiled_views_not_blank(sphere, views):
    """Every tile of a multi-view picture shows the object, shaded (not one flat colour)."""
    size = (480, 360)
    scalars = sphere[0][:, 2]
    img = view.render(sphere, views, size, scalars=scalars, colorbar_label="z")
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


def test_colormap_and_colorbar_ends():
    """The colour map reaches matplotlib's end colours; the bar runs top=vmax to bottom=vmin."""
    import matplotlib

    rgb = view.apply_colormap(np.array([0.0, 5.0, 10.0, np.nan]), "viridis", 0.0, 10.0)
    cm = matplotlib.colormaps["viridis"]
    assert np.allclose(rgb[0], cm(0.0)[:3], atol=1e-6) and np.allclose(rgb[2], cm(1.0)[:3], atol=1e-6)
    assert np.allclose(rgb[3], 0.6)
    bar = view.colorbar_image(300, -1.0, 2.0, "viridis", "mm")
    column = bar[:, 15].astype(float) / 255
    inside = np.nonzero(np.abs(column - np.asarray(cm(1.0)[:3])).sum(axis=1) < 0.03)[0]
    bottom = np.nonzero(np.abs(column - np.asarray(cm(0.0)[:3])).sum(axis=1) < 0.03)[0]
    assert inside.size and bottom.size and inside.mean() < bottom.mean()


def test_net_overlay_draws_segments(sphere):
    """Given world segments are drawn where the camera projects them."""
    seg = np.array([[[-1.2, 0.0, 1.5], [1.2, 0.0, 1.5]]])
    cam = _top_camera()
    plain = view.render(sphere, cam, (300, 300))
    lined = view.render(sphere, cam, (300, 300), net=seg, net_color=(1.0, 0.0, 0.0))
    changed = np.any(plain != lined, axis=2)
    rows, cols = np.nonzero(changed)
    assert abs(rows.mean() - 149.5) < 1.5
    assert cols.min() < 40 and cols.max() > 260
    assert lined[150, 150, 0] > 200 and lined[150, 150, 1] < 60


def test_control_net_segments_and_lineset():
    """24 segments per patch; the line set has the same points."""
    rng = np.random.default_rng(0)
    ctrl = rng.normal(size=(2, 3, 4, 4, 3))
    seg = view.control_net_segments(ctrl)
    assert seg.shape == (24 * 6, 2, 3)
    assert np.allclose(seg[0], ctrl[0, 0, :2, 0])
    lines = view.control_net_lineset(ctrl, color=(1, 0, 0))
    assert len(lines.lines) == len(seg)
    assert np.allclose(np.asarray(lines.points), seg.reshape(-1, 3))


def test_to_open3d_colours_and_normals(sphere):
    verts, tris = sphere
    mesh = view.to_open3d(sphere, scalars=verts[:, 2], cmap="coolwarm")
    assert len(mesh.triangles) == len(tris)
    normals = np.asarray(mesh.vertex_normals)
    assert np.allclose(np.einsum("ij,ij->i", normals, verts), 1.0, atol=2e-3)
    colors = np.asarray(mesh.vertex_colors)
    assert colors.shape == verts.shape and np.ptp(colors) > 0.5
    with pytest.raises(ValueError, match="scalars"):
        view.to_open3d(sphere, scalars=verts[:10, 2])


def test_deviation_signed(sphere):
    """Points 0.1 outside / inside the unit sphere are at +0.1 / -0.1 (tessellation tolerance)."""
    rng = np.random.default_rng(1)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = view.deviation(1.1 * d, sphere)
    inn = view.deviation(0.9 * d, sphere)
    assert np.allclose(out, 0.1, atol=2e-3) and np.allclose(inn, -0.1, atol=2e-3)


def test_patches_render_with_net():
    """A Bezier patch model renders with normals from the patches and its control net on top."""
    from surfaces.bezier import BezierPatches

    u = np.linspace(0.0, 3.0, 4)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1)
    ctrl = np.concatenate([grid, 0.2 * np.sin(grid[..., :1] + grid[..., 1:])], axis=-1)
    patches = BezierPatches(ctrl[None, None])
    plain = view.render(patches, "iso", (200, 150))
    netted = view.render(patches, "iso", (200, 150), net=True)
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
        view.render(sphere, **kwargs)


def test_bad_camera():
    with pytest.raises(ValueError, match="coincide"):
        view.Camera((0, 0, 0), (0, 0, 0), (0, 1, 0))
    with pytest.raises(ValueError, match="parallel"):
        view.Camera((0, 0, 1), (0, 0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="fov"):
        view.Camera((0, 0, 1), (0, 0, 0), (0, 1, 0), fov_deg=200)


def test_fit_camera_frames_box():
    box = np.array([[-1.0, -2.0, 0.0], [3.0, 1.0, 0.5]])
    corners = np.array(np.meshgrid(*box.T, indexing="ij")).reshape(3, -1).T
    for name in view.STANDARD_VIEWS:
        for fov in (None, 30.0):
            cam = view.fit_camera(box, name, 4 / 3, fov_deg=fov)
            px, depth = cam.project(corners, 400, 300)
            assert np.all(depth > 0)
            assert np.all((px >= 0) & (px <= [400, 300]))


def test_save_png_roundtrip(tmp_path):
    import cv2

    img = np.zeros((10, 12, 3), np.uint8)
    img[..., 0] = 200
    path = write_png(tmp_path / "sub" / "a.png", img)
    back = cv2.imread(str(path))
    assert back.shape == (10, 12, 3) and back[0, 0, 2] == 200 and back[0, 0, 0] == 0
    assert [p.name for p in path.parent.iterdir()] == ["a.png"]
    with pytest.raises(ValueError, match="dtype|uint8"):
        write_png(tmp_path / "b.png", img.astype(float))


def test_render_and_view_commands(tmp_path, sphere, capsys, monkeypatch):
    """``workbench surfaces render`` writes the PNG and its JSON; ``view`` without display says so."""
    import json

    import cv2

    from surfaces.io import write_mesh
    from surfaces.mesh import TriangleMesh
    from workbench.cli import main

    verts, tris = sphere
    write_mesh(TriangleMesh(verts, tris.astype(np.int64), None, None), tmp_path / "a.ply")
    write_mesh(TriangleMesh(1.02 * verts, tris.astype(np.int64), None, None), tmp_path / "b.ply")
    out = tmp_path / "v.png"
    code = main(["surfaces", "render", str(tmp_path / "a.ply"), "--out", str(out), "--views",
                 "front,top", "--size", "320x200", "--colour", "deviation", "--reference",
                 str(tmp_path / "b.ply")])
    assert code == 0
    img = cv2.imread(str(out))
    assert img.shape == (200, 320, 3) and img.std() > 10
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["views"] == ["front", "top"] and summary["triangles"] == len(tris)
    assert abs(summary["deviation_rms"] - 0.02) < 2e-3
    assert main(["surfaces", "render", str(tmp_path / "a.ply"), "--out", str(out),
                 "--colour", "deviation"]) == 2
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    capsys.readouterr()
    assert main(["view", str(tmp_path / "a.ply")]) == 1
    said = capsys.readouterr().out.strip().splitlines()
    assert len(said) == 1 and "--png" in said[0]
    assert main(["view", str(tmp_path / "a.ply"), str(tmp_path / "b.ply"), "--png",
                 str(tmp_path / "both.png"), "--size", "200x150"]) == 0
    assert cv2.imread(str(tmp_path / "both.png")).shape == (150, 200, 3)


def test_hidden_net_lines(sphere):
    """With net_hidden, a segment behind the sphere disappears; one in front stays."""
    cam = _top_camera()
    behind = np.array([[[-0.5, 0.0, -1.5], [0.5, 0.0, -1.5]]])
    front = np.array([[[-0.5, 0.0, 1.5], [0.5, 0.0, 1.5]]])
    plain = view.render(sphere, cam, (200, 200))
    for seg, visible in ((behind, False), (front, True)):
        img = view.render(sphere, cam, (200, 200), net=seg, net_hidden=True, net_color=(1, 0, 0))
        assert np.any(img != plain) == visible
        img = view.render(sphere, cam, (200, 200), net=seg, net_hidden=False, net_color=(1, 0, 0))
        assert np.any(img != plain)


def test_view_command_opens_window_with_display(tmp_path, monkeypatch):
    """With DISPLAY set, ``workbench view`` hands meshes and control nets to open3d's viewer."""
    import open3d.visualization as vis

    from surfaces.bezier import BezierPatches
    from surfaces.io import save_patches
    from workbench.cli import main

    u = np.linspace(0.0, 3.0, 4)
    grid = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1)
    ctrl = np.concatenate([grid, 0.2 * np.sin(grid[..., :1] + grid[..., 1:])], axis=-1)
    save_patches(BezierPatches(ctrl[None, None]), tmp_path / "p.npz")
    shown = []
    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(vis, "draw_geometries", lambda geoms, **kw: shown.extend(geoms))
    assert main(["view", str(tmp_path / "p.npz"), "--net"]) == 0
    kinds = sorted(type(g).__name__ for g in shown)
    assert kinds == ["LineSet", "TriangleMesh"]
    mesh = next(g for g in shown if type(g).__name__ == "TriangleMesh")
    assert mesh.has_vertex_normals() and mesh.has_vertex_colors()
