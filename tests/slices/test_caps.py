"""End caps: cap kinds per end, fan and prism columns, dome rings, Green's-theorem areas, flat-cap meshes."""

from __future__ import annotations

import numpy as np
import pytest

from slices import caps
from surfaces import measure
from surfaces.bezier import BezierPatches
from surfaces.mesh import tessellate
from tests.slices._stacks import circle


def _polygon_curve(corners, z=0.0) -> np.ndarray:
    """Straight Bezier segments between the corners (collinear control points), in the plane z."""
    a, b = corners, np.roll(corners, -1, axis=0)
    w = np.arange(4) / 3.0
    curve = a[:, None, :] + w[None, :, None] * (b - a)[:, None, :]
    return np.concatenate([curve, np.full(curve.shape[:2] + (1,), z)], axis=2)


SQUARE = np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float)


@pytest.mark.parametrize("kind", caps.CAP_KINDS)
def test_end_kinds(kind):
    assert caps.end_kinds(kind, "end", "end") == (kind, kind)
    assert caps.end_kinds(kind, "merge", "branch") == ("half", "half")
    with pytest.raises(ValueError, match="caps"):
        caps.end_kinds("round", "end", "end")


def test_curve_area_of_a_square_both_ways():
    curve = _polygon_curve(SQUARE)
    assert caps.curve_area(curve) == pytest.approx(16.0, rel=1e-12)
    assert caps.curve_area(_polygon_curve(SQUARE[::-1])) == pytest.approx(-16.0, rel=1e-12)


def test_prism_column_encloses_area_times_height():
    curve = _polygon_curve(SQUARE, z=1.0)
    below = caps.prism_column(curve, -2.0)
    assert below.shape == (4, 1, 4, 4, 3)
    np.testing.assert_allclose(below[:, 0, :, 0, 2], -1.0)  # v starts 2 mm below the curve
    np.testing.assert_allclose(below[:, 0, :, 3], curve)  # and ends on it
    above = caps.prism_column(curve, 2.0)
    np.testing.assert_allclose(above[:, 0, :, 0], curve)


def test_closed_grid_volume_is_exact_for_a_box():
    bottom = _polygon_curve(SQUARE, z=0.0)
    grid = caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5, "half", "half")
    assert grid.side_columns == slice(1, 3) and grid.end_planes == (-1.5, 1.5)
    assert [s for _, s in grid.flat_caps] == [-1.0, 1.0]
    patches = BezierPatches(grid.control, closed_u=True)
    assert measure.volume(patches) == pytest.approx(16.0 * 3.0, rel=1e-12)
    assert grid.flat_cap_area == pytest.approx(32.0, rel=1e-12)
    open_grid = caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5, "half", "none")
    # "none" keeps its fan column (the grid still encloses the volume) but no flat cap
    assert len(open_grid.flat_caps) == 1 and open_grid.control.shape[1] == 3


def test_dome_rings_close_in_a_pole():
    curve = np.repeat(circle(0, 0, 10, 16)[:, None, :], 4, axis=1)
    curve = np.concatenate([curve, np.zeros(curve.shape[:2] + (1,))], axis=2)
    rings = caps.dome_rings(curve, [0, 0, 0], 2.0, upward=True, n_rings=3)
    np.testing.assert_allclose(rings[-1], np.broadcast_to([0, 0, 2.0], rings[-1].shape))
    # ring k on the quarter ellipse: radius 10 cos(t_k), height 2 sin(t_k)
    t = np.pi / 6
    np.testing.assert_allclose(np.linalg.norm(rings[0][..., :2], axis=-1), 10 * np.cos(t))
    np.testing.assert_allclose(rings[0][..., 2], 2 * np.sin(t))
    stack, prepend = caps.add_dome_rings(curve[None], np.zeros((1, 3)), 2.0, "dome", "flat")
    assert prepend == caps.DOME_RINGS and len(stack) == caps.DOME_RINGS + 1
    assert stack[0, 0, 0, 2] == pytest.approx(-2.0)


@pytest.mark.parametrize("outward", [1.0, -1.0])
@pytest.mark.parametrize("outline", ["star", "u_shape"])
@pytest.mark.parametrize("clockwise", [False, True])
def test_flat_cap_triangles_face_outward_consistently(outward, outline, clockwise):
    if outline == "star":
        corners = circle(1.0, -2.0, 8.0, 12)
    else:  # not star-shaped about its vertex mean: constrained triangulation
        corners = np.array([(0, 0), (10, 0), (10, 10), (7, 10), (7, 3), (3, 3), (3, 10), (0, 10)], float)
    if clockwise:
        corners = corners[::-1]
    curve = _polygon_curve(corners, z=5.0)
    cap = caps.planar_cap_mesh(curve, 3, outward)
    assert cap.is_oriented()
    nz = cap.face_normals(normalize=False)[:, 2]
    assert np.all(np.sign(nz[np.abs(nz) > 1e-12]) == outward)
    assert 0.5 * abs(nz.sum()) == pytest.approx(abs(caps.curve_area(curve)), rel=1e-12)


def test_welded_box_is_watertight():
    bottom = _polygon_curve(SQUARE, z=0.0)
    grid = caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5, "half", "half")
    side = tessellate(BezierPatches(grid.control[:, grid.side_columns], closed_u=True), 3)
    mesh, display = caps.weld_flat_caps(side, grid, 3)
    assert mesh.is_watertight() and mesh.is_oriented()
    assert mesh.signed_volume() == pytest.approx(48.0, rel=1e-9)
    assert not display.is_watertight()  # caps kept apart for shading
    open_grid = caps.close_side(grid.control[:, grid.side_columns], bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5,
                                "none", "none")
    assert caps.weld_flat_caps(side, open_grid, 3) == (side, side)
    with pytest.raises(ValueError, match="single slice"):
        caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5, "flat", "none")
    with pytest.raises(ValueError, match="low_center"):
        caps.close_side(None, bottom, bottom, (2.0, 2.0, 0.0), (2.0, 2.0), 1.5, "half", "half")
    with pytest.raises(ValueError, match="high_center"):
        caps.close_side(None, bottom, bottom, (2.0, 2.0), (np.nan, 2.0), 1.5, "half", "half")


def test_dome_rings_leave_the_curves_as_they_are_without_domes():
    curve = _polygon_curve(SQUARE, z=0.0)
    curves = np.stack([curve, curve + [0.0, 0.0, 2.0]])
    stack, prepend = caps.add_dome_rings(curves, np.zeros((2, 3)), 1.0, "half", "flat")
    # the public function hands back its own array; the body's private path reads the curves in place
    assert prepend == 0 and np.array_equal(stack, curves) and not np.shares_memory(stack, curves)
    inner, _ = caps._add_dome_rings(curves, np.zeros((2, 3)), 1.0, "half", "flat")
    assert inner is curves
    domed, prepend = caps.add_dome_rings(curves, np.zeros((2, 3)), 1.0, "dome", "flat")
    assert prepend > 0 and np.array_equal(domed[prepend:], curves)


def test_written_cap_shades_flat_with_its_own_normal():
    # a cylinder with flat-topped half caps: the welded mesh keeps the side's normals on the rim, and
    # the ring just inside it carries +-z, so the cap is evenly lit when rendered from the file
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([5 * np.cos(t), 5 * np.sin(t)], axis=1)
    bottom = _polygon_curve(ring, z=0.0)
    grid = caps.close_side(None, bottom, bottom, (0.0, 0.0), (0.0, 0.0), 1.0, "half", "half")
    side = tessellate(BezierPatches(grid.control[:, grid.side_columns], closed_u=True), 3)
    mesh, _ = caps.weld_flat_caps(side, grid, 3)
    assert mesh.is_watertight() and mesh.is_oriented()
    assert mesh.signed_volume() == pytest.approx(2 * abs(caps.curve_area(bottom)), rel=1e-9)
    z = mesh.vertices[:, 2]
    # the rim: cap-plane vertices of the side's triangles
    off_plane = np.zeros(mesh.n_vertices, bool)
    for plane, sign in ((-1.0, -1.0), (1.0, 1.0)):
        on = np.abs(z - plane) < 1e-9
        side_tri = ~on[mesh.triangles].all(axis=1)
        off_plane[:] = False
        off_plane[mesh.triangles[side_tri].ravel()] = True
        in_cap = np.flatnonzero(on)
        rim = off_plane[in_cap]
        nz = mesh.vertex_normals[in_cap, 2]
        np.testing.assert_allclose(nz[~rim], sign)
        np.testing.assert_allclose(nz[rim], 0.0, atol=1e-9)  # the side's normal on the crease
        assert (~rim).sum() >= rim.sum()
    # the band of side normals is a small fraction of an edge wide: each inner vertex lies that close
    # to the rim
    edge = float(np.linalg.norm(ring[1] - ring[0])) / 3
    rim_xy, inner_xy = mesh.vertices[in_cap[rim], :2], mesh.vertices[in_cap[~rim], :2]
    gap = np.linalg.norm(inner_xy[:, None] - rim_xy[None], axis=2).min(axis=1)
    assert np.sort(gap)[len(rim_xy) - 1] <= 1.5 * caps.CAP_INSET * edge


def test_cap_over_a_narrow_slot_still_covers_the_outline_once():
    # a U whose slot is far narrower than its edges: the band shrinks (or goes) rather than overlapping
    corners = np.array([(0, 0), (10, 0), (10, 10), (5.01, 10), (5.01, 1), (4.99, 1), (4.99, 10), (0, 10)], float)
    cap = caps.planar_cap_mesh(_polygon_curve(corners, z=2.0), 2, 1.0)
    nz = cap.face_normals(normalize=False)[:, 2]
    assert np.all(nz > 0)
    assert 0.5 * nz.sum() == pytest.approx(abs(caps.curve_area(_polygon_curve(corners))), rel=1e-9)


def test_fan_apex_moves_into_the_kernel_so_the_cap_patches_do_not_fold():
    # an L: star-shaped about its inner corner region, not about its vertex mean's neighbourhood corner
    corners = np.array([(0, 0), (12, 0), (12, 2), (2, 2), (2, 12), (0, 12)], float)
    curve = _polygon_curve(corners, z=0.0)
    hint = np.array([10.0, 10.0])  # outside the L: the fan from here folds
    apex = caps.fan_apex(curve, hint)
    assert 0 < apex[0] < 2 and 0 < apex[1] < 2
    np.testing.assert_allclose(caps.fan_apex(curve, apex), apex)  # a good apex stays
    for p in (hint, apex):
        fan = BezierPatches(caps.fan_column(curve, np.append(p, 0.0), False), closed_u=True)
        _, area = measure.integrals(fan)
        folded = not np.allclose(p, apex)
        assert (area > 1.01 * abs(caps.curve_area(curve))) == folded
    assert area == pytest.approx(abs(caps.curve_area(curve)), rel=1e-9)


def _wavy_curve(rng, n: int = 40) -> np.ndarray:
    """A closed counter-clockwise curve: a random star-shaped outline, or a thick C (whose kernel is empty)."""
    if rng.uniform() < 0.5:
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        r = 10 * rng.uniform(0.4, 1.0, n)
        return _polygon_curve(np.column_stack([r * np.cos(t), r * np.sin(t)]))
    gap = rng.uniform(0.2, 2.5)  # the C spans 2 pi - 2 gap: more than pi, so no point sees all of it
    t = np.linspace(gap, 2 * np.pi - gap, n // 2)
    outer, inner = 10 * rng.uniform(0.9, 1.1, len(t)), rng.uniform(3.0, 7.0) * rng.uniform(0.9, 1.1, len(t))
    xy = np.concatenate([np.column_stack([outer * np.cos(t), outer * np.sin(t)]),
                         np.column_stack([inner * np.cos(t), inner * np.sin(t)])[::-1]])
    return _polygon_curve(xy)


def test_kernel_margin_equals_the_linear_programme():
    from scipy.optimize import linprog

    rng = np.random.default_rng(11)
    for _ in range(60):
        n = rng.integers(4, 200)
        angle = rng.uniform(0, 2 * np.pi, n)
        a = np.column_stack([np.cos(angle), np.sin(angle)])
        b = rng.uniform(-3, 10, n)
        margin, point = caps.kernel_margin(a, b)
        res = linprog([0.0, 0.0, -1.0], A_ub=np.hstack([a, np.ones((n, 1))]), b_ub=b,
                      bounds=[(None, None), (None, None), (None, 1e6)], method="highs")
        if not np.isfinite(margin):
            # a half-circle of directions is left open: the margin grows without bound
            assert res.x[2] == pytest.approx(1e6)
            continue
        assert margin == pytest.approx(res.x[2], abs=1e-7)
        assert np.min(b - a @ point) == pytest.approx(margin, abs=1e-9)  # reached at the point


def test_fan_apex_skips_the_programme_only_where_it_would_find_no_kernel(monkeypatch):
    rng = np.random.default_rng(5)
    curves = [_wavy_curve(rng) for _ in range(40)]
    hint = np.array([12.0, 0.0])  # outside every outline: the programme decides
    fast = [caps.fan_apex(c, hint) for c in curves]
    monkeypatch.setattr(caps, "_no_kernel", lambda *args: False)
    slow = [caps.fan_apex(c, hint) for c in curves]
    np.testing.assert_array_equal(fast, slow)
    moved = sum(not np.array_equal(p, hint) for p in slow)
    assert 5 <= moved <= 35  # both outcomes occur: apexes moved into a kernel, and empty kernels

def _slotted(depth: float, width: float = 0.4, n: int = 6) -> np.ndarray:
    """A square of side 10 with a slot cut in from the top: its walls face apart, so no kernel."""
    x0, x1 = 5 - width / 2, 5 + width / 2
    bottom = [(10 * k / n, 0) for k in range(n)]  # many corners, many tangent lines
    return np.array(bottom + [(10, 0), (10, 10), (x1, 10), (x1, 10 - depth), (x0, 10 - depth), (x0, 10), (0, 10)],
                    float)


@pytest.mark.parametrize("outline", ["slot 0.5", "slot 9", "C", "L"])
def test_fan_apex_proves_an_empty_kernel_without_the_linear_programme(monkeypatch, outline):
    import scipy.optimize

    if outline == "L":
        corners, hint = np.array([(0, 0), (12, 0), (12, 2), (2, 2), (2, 12), (0, 12)], float), np.array([10.0, 10.0])
    elif outline == "C":
        # three quarters of a ring: no two walls face apart, three tangent lines make the proof
        th = np.radians(np.linspace(0, 270, 30))
        corners = np.vstack([np.stack([10 * np.cos(th), 10 * np.sin(th)], 1),
                             np.stack([6 * np.cos(th[::-1]), 6 * np.sin(th[::-1])], 1)]) + [100.0, -300.0]
        hint = np.array([100.0, -300.0])
    else:
        corners, hint = _slotted(float(outline.split()[1])), np.array([5.0, 9.95])
    curve = _polygon_curve(corners, z=1.0)
    proven = caps.fan_apex(curve, hint)
    monkeypatch.setattr(caps, "_no_kernel", lambda *a: False)
    solved = caps.fan_apex(curve, hint)
    monkeypatch.undo()
    np.testing.assert_array_equal(proven, solved)  # the same answer with or without the proof
    if outline == "L":
        assert 0 < solved[0] < 2 and 0 < solved[1] < 2  # the linear programme's point in the kernel
        return
    np.testing.assert_array_equal(solved, hint)

    def refuse(*args, **kwargs):
        raise AssertionError("linprog called on an empty kernel")

    monkeypatch.setattr(scipy.optimize, "linprog", refuse)
    np.testing.assert_array_equal(caps.fan_apex(curve, hint), hint)


def test_no_kernel_proves_only_what_holds():
    rng = np.random.default_rng(11)
    for _ in range(40):
        # random star-shaped outlines about the origin: the origin is in the kernel
        t = np.sort(rng.uniform(0, 2 * np.pi, rng.integers(6, 30)))
        r = rng.uniform(2, 8, len(t))
        ring = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
        edge = np.roll(ring, -1, axis=0) - ring
        edge /= np.linalg.norm(edge, axis=1)[:, None]
        a = np.stack([edge[:, 1], -edge[:, 0]], axis=1)  # outward normals: inside is a . p < b
        b = np.einsum("ij,ij->i", a, ring)
        start = np.arange(len(a)) % 3 == 0
        if np.all(b > 0):
            assert not caps._no_kernel(a, b, start, 1e-9)
        # every line moved 1 past the origin (the normals of a closed outline surround it): every point
        # misses some line by 1 at least, which the proof finds
        assert caps._no_kernel(a, np.full_like(b, -1.0), start, 1e-9)
        assert not caps._no_kernel(a, np.full_like(b, -1e-10), start, 1e-9)  # not beyond the margin


@pytest.mark.parametrize("inset", [True, False])
def test_welding_caps_by_index_is_the_spatial_weld(monkeypatch, inset):
    # a blob with half caps and two subdivisions around: the caps' rims are joined to the side's lattice
    # rows by index arithmetic; the spatial weld (forced) gives the same mesh
    t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    ring = np.stack([(6 + np.cos(3 * t)) * np.cos(t), (6 + np.cos(3 * t)) * np.sin(t)], axis=1)
    bottom = _polygon_curve(ring, z=2.0)
    grid = caps.close_side(None, bottom, bottom, (0.0, 0.0), (0.0, 0.0), 1.25, "half", "half")
    side = tessellate(BezierPatches(grid.control[:, grid.side_columns], closed_u=True), (2, 3))
    mesh, display = caps.weld_flat_caps(side, grid, 2, inset=inset)
    assert caps._rim_weld_map(display, side, [caps.planar_cap_mesh(c, 2, s, inset) for c, s in grid.flat_caps],
                              grid.flat_caps, 2, np.flatnonzero(np.abs(np.abs(side.vertices[:, 2] - 2.0) - 1.25)
                                                                < 1e-9)) is not None
    monkeypatch.setattr(caps, "_rim_weld_map", lambda *a: None)
    spatial, _ = caps.weld_flat_caps(side, grid, 2, inset=inset)
    np.testing.assert_array_equal(mesh.triangles, spatial.triangles)
    np.testing.assert_array_equal(mesh.vertices, spatial.vertices)
    np.testing.assert_array_equal(mesh.vertex_normals, spatial.vertex_normals)
    assert mesh.is_watertight() and mesh.is_oriented()


@pytest.mark.parametrize("case", ["closed around", "open around", "unused vertex"])
def test_welded_is_compact_of_the_remapped_mesh(case):
    # a lattice closed around (its triangles' middle corners cover it), one open around (its first row
    # only in first and last corners) and a side with a vertex no triangle uses: _welded gives what
    # compact gives on the merged mesh with the cap's triangles renumbered
    from surfaces.mesh import TriangleMesh, compact, merge_meshes

    bottom = _polygon_curve(SQUARE, z=0.0)
    grid = caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.5, "half", "half")
    side = tessellate(BezierPatches(grid.control[:, grid.side_columns], closed_u=case != "open around"), 2)
    if case == "unused vertex":
        side = TriangleMesh(np.vstack([side.vertices, [[9.0, 9.0, 9.0]]]), side.triangles,
                            np.vstack([side.vertex_normals, [[0.0, 0.0, 1.0]]]))
    cap = caps.planar_cap_mesh(bottom, 2, -1.0)
    merged = merge_meshes([side, cap])
    # the cap's boundary onto the side's first vertices, its other vertices kept
    rep = np.arange(merged.n_vertices)
    rep[side.n_vertices:side.n_vertices + 8] = np.arange(8)
    out = caps._welded(merged, side, rep)
    expected = compact(TriangleMesh(merged.vertices, rep[merged.triangles], merged.vertex_normals))
    np.testing.assert_array_equal(out.vertices, expected.vertices)
    np.testing.assert_array_equal(out.triangles, expected.triangles)
    np.testing.assert_array_equal(out.vertex_normals, expected.vertex_normals)
    assert out.n_vertices == merged.n_vertices - 8 - (case == "unused vertex")


def test_welding_caps_by_index_falls_back_where_points_nearly_meet():
    # a rim vertex doubled (a zero-length lattice step): the index map is refused, the spatial weld decides
    corners = np.array([(0, 0), (4, 0), (4, 0), (4, 4), (0, 4)], float)
    bottom = _polygon_curve(corners, z=0.0)
    grid = caps.close_side(None, bottom, bottom, (2.0, 2.0), (2.0, 2.0), 1.0, "half", "half")
    side = tessellate(BezierPatches(grid.control[:, grid.side_columns], closed_u=True), 1)
    cap_meshes = [caps.planar_cap_mesh(c, 1, s) for c, s in grid.flat_caps]
    from surfaces.mesh import merge_meshes

    merged = merge_meshes([side] + cap_meshes)
    rim = np.flatnonzero(np.abs(np.abs(side.vertices[:, 2]) - 1.0) < 1e-9)
    assert caps._rim_weld_map(merged, side, cap_meshes, grid.flat_caps, 1, rim) is None


def _wavy_side(n_rows=12, n_cols=3, clockwise=False):
    """A blended-looking side (M, S, 4, 4, 3): a wobbling ring whose radius and centre change with z."""
    t = np.linspace(0, 2 * np.pi, 3 * n_rows + 1)[:-1]
    if clockwise:
        t = -t
    z = np.linspace(0.0, 6.0, 3 * n_cols + 1)
    r = 3 + 0.4 * np.cos(3 * t)[:, None] + 0.2 * np.sin(z)[None, :]
    pts = np.stack([r * np.cos(t)[:, None] + 0.1 * z, r * np.sin(t)[:, None], np.broadcast_to(z, r.shape)], -1)
    pts = np.concatenate([pts, pts[:1]])
    ctrl = np.empty((n_rows, n_cols, 4, 4, 3))
    for i in range(4):
        for j in range(4):
            ctrl[:, :, i, j] = pts[i:i + 3 * n_rows:3][:, j:j + 3 * n_cols:3]
    return ctrl


@pytest.mark.parametrize("clockwise", [False, True])
@pytest.mark.parametrize("low,high", [("flat", "flat"), ("half", "half"), ("none", "half"), ("half", "none"),
                                      ("flat", "half"), ("none", "none")])
def test_grid_integrals_equal_the_quadrature_of_every_column(low, high, clockwise):
    side = _wavy_side(clockwise=clockwise)
    grid = caps.close_side(side, side[:, 0, :, 0], side[:, -1, :, 3], (0.2, 0.1), (0.3, -0.1), 1.25, low, high)
    assert grid.extrusions == (1.25 if low == "half" else 0.0, 1.25 if high == "half" else 0.0)
    vol_pp, area_pp = measure.integrals(BezierPatches(grid.control, closed_u=True), per_patch=True)
    volume, area = caps.grid_integrals(grid)
    assert volume == pytest.approx(vol_pp.sum(), rel=1e-12)
    assert area == pytest.approx(area_pp[:, grid.side_columns].sum() + grid.flat_cap_area, rel=1e-12)
    assert (volume > 0) != clockwise


def test_grid_integrals_of_a_half_capped_single_slice():
    curve = _polygon_curve(SQUARE, z=2.0)
    grid = caps.close_side(None, curve, curve, (2, 2), (2, 2), 0.5, "half", "half")
    volume, area = caps.grid_integrals(grid)
    # a 4 x 4 x 1 box: its volume and its whole surface (walls and both caps)
    assert volume == pytest.approx(16.0, rel=1e-12)
    assert area == pytest.approx(16.0 + 16.0 + 16.0, rel=1e-12)
