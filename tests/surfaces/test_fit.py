"""surfaces.fit: least-squares fit of a height field and its slopes, refinement, trimmed mesh."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from skimage.measure import find_contours

from datasets_synthetic.heightfields import sphere_cap, v_crack
from surfaces.fit import RELATIVE_TOLERANCE, SurfaceFit, default_step, find_discontinuities, fit_height, fit_mesh
from surfaces.grid import pixel_grid, xy_to_pixel
from surfaces.mixed import MixedPatches


def _poly(kind, shape, h):
    """Height and exact slopes of polynomials up to bicubic on the centred pixel grid."""
    x, y = pixel_grid(shape, h)
    if kind == "plane":
        return 0.3 + 0.2 * x - 0.1 * y, np.full(shape, 0.2), np.full(shape, -0.1)
    if kind == "quadratic":
        return x * x - 0.5 * x * y + 0.3 * y * y, 2 * x - 0.5 * y, -0.5 * x + 0.6 * y
    if kind == "cubic":
        return 0.1 * x**3 - 0.2 * y**3 + x * y, 0.3 * x * x + y, -0.6 * y * y + x
    if kind == "bicubic":
        z = 0.02 * x**3 * y**2 - 0.01 * y**3 + 0.003 * x**3 * y**3 + 0.05 * x * y
        p = 0.06 * x**2 * y**2 + 0.009 * x**2 * y**3 + 0.05 * y
        q = 0.04 * x**3 * y - 0.03 * y**2 + 0.009 * x**3 * y**2 + 0.05 * x
        return z, p, q
    raise ValueError(kind)


def _patch_values(fit: SurfaceFit, rows, cols):
    """Points and per-pixel derivatives d/ds, d/dt evaluated on the patches themselves."""
    patch, u, v = fit.patches.locate_lattice(np.asarray(rows, float) + 0.5, np.asarray(cols, float) + 0.5)
    assert (patch >= 0).all()
    d = fit.patches.derivatives(patch, 0, u, v)
    size = fit.patches.sizes[patch][:, None]
    return d.point, d.du / size, d.dv / size


@pytest.mark.parametrize("kind", ["plane", "quadratic", "cubic", "bicubic"])
@pytest.mark.parametrize("shape,step", [((40, 48), 8), ((37, 50), 8), ((33, 21), 4)])
def test_polynomials_up_to_bicubic_are_reproduced_exactly(kind, shape, step):
    h = 0.1
    z, p, q = _poly(kind, shape, h)
    fit = fit_height(z, p, q, pixel_size=h, step=step)
    scale = max(1.0, float(np.abs(z).max()))
    assert fit.max_deviation < 1e-9 * scale
    # the patches themselves: heights and slopes at every pixel centre
    rows, cols = np.nonzero(np.ones(shape, bool))
    point, ds, dt = _patch_values(fit, rows, cols)
    x, y = pixel_grid(shape, h)
    np.testing.assert_allclose(point[:, 0], x.ravel(), atol=1e-12)
    np.testing.assert_allclose(point[:, 1], y.ravel(), atol=1e-12)
    np.testing.assert_allclose(point[:, 2], z.ravel(), atol=1e-9 * scale)
    np.testing.assert_allclose(dt[:, 2] / h, p.ravel(), atol=1e-8 * scale)  # dz/dx = p
    np.testing.assert_allclose(-ds[:, 2] / h, q.ravel(), atol=1e-8 * scale)  # dz/dy = q (y up)
    # the pixel values the fit reports are those of the patches
    np.testing.assert_allclose(fit.surface.reshape(-1, 3), point, atol=1e-9 * scale)
    expected = np.stack([-p, -q, np.ones(shape)], axis=2) / np.sqrt(1 + p * p + q * q)[..., None]
    np.testing.assert_allclose(fit.normals, expected, atol=1e-8 * scale)


@pytest.mark.parametrize("kind", ["quadratic", "bicubic"])
def test_exact_through_refinement_and_masks(kind):
    """Forced refinement (a tolerance far below rounding) and missing pixels keep bicubics exact:
    the overlays fit zero residuals, and the smoothing term's null space is the bicubics."""
    shape, h = (48, 40), 0.1
    z, p, q = _poly(kind, shape, h)
    mask = np.ones(shape, bool)
    mask[10:20, 5:30] = False
    mask[30:, 30:] = False
    fit = fit_height(np.where(mask, z, np.nan), p, q, mask=mask, pixel_size=h, step=8, tolerance=1e-30)
    assert len(fit.levels) == 4 and len(fit.patch_sizes()) > 1
    rows, cols = np.nonzero(mask)
    point, _, _ = _patch_values(fit, rows, cols)
    scale = max(1.0, float(np.abs(z).max()))
    np.testing.assert_allclose(point[:, 2], z[mask], atol=1e-8 * scale)
    # the gap is filled by the same polynomial
    gap = ~mask & fit.covered
    np.testing.assert_allclose(fit.surface[gap][:, 2], z[gap], atol=1e-7 * scale)


def _seam_mismatch(patches: MixedPatches, m: int = 7):
    """Largest differences of position and of the gradient per lattice unit across every seam."""
    rows, cols = patches.lattice_shape
    t = (np.arange(m) + 0.5) / m
    worst = [0.0, 0.0]
    cells = patches.cells
    for axis in (0, 1):
        r0, c0, size = cells[:, 0], cells[:, 1], cells[:, 2]
        # points along the far edge (bottom for axis 0, right for axis 1) of every patch
        along = (r0 if axis == 1 else c0)[:, None] + size[:, None] * t[None, :]
        edge = ((r0 + size) if axis == 0 else (c0 + size))[:, None] * np.ones(m)
        lr, lc = (edge, along) if axis == 0 else (along, edge)
        inside = (lr < rows) & (lc < cols)
        here = np.repeat(np.arange(len(cells)), m).reshape(-1, m)
        pa, ua, va = here[inside], *(np.zeros(0),) * 2
        ua = ((lr - r0[:, None]) / size[:, None])[inside]
        va = ((lc - c0[:, None]) / size[:, None])[inside]
        pb, ub, vb = patches.locate_lattice(lr[inside], lc[inside])
        keep = pb >= 0
        da = patches.derivatives(pa[keep], 0, ua[keep], va[keep])
        db = patches.derivatives(pb[keep], 0, ub[keep], vb[keep])
        sa, sb = patches.sizes[pa[keep]][:, None], patches.sizes[pb[keep]][:, None]
        worst[0] = max(worst[0], float(np.abs(da.point - db.point).max()))
        grad = max(float(np.abs(da.du / sa - db.du / sb).max()), float(np.abs(da.dv / sa - db.dv / sb).max()))
        worst[1] = max(worst[1], grad)
    return worst


def test_seams_are_c1_including_t_junctions():
    hf = v_crack(128, 0.05, depth_mm=0.2, width_mm=0.6, length_mm=1.5, axis_deg=25.0)
    fit = fit_height(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size, step=16)
    sizes = fit.patch_sizes()
    assert len(sizes) >= 3 and max(sizes) == 16  # mixed sizes: T-junctions exist
    position, gradient = _seam_mismatch(fit.patches)
    assert position < 1e-9 and gradient < 1e-9


def test_v_crack_has_no_overshoot_above_the_plate():
    """The plate is z = 0 outside the crack; the fit must not rise above it by more than the tolerance."""
    hf = v_crack(128, 0.05, depth_mm=0.6, width_mm=2.0, length_mm=4.0, axis_deg=30.0)
    tol = 0.005
    fit = fit_height(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size, tolerance=tol)
    z = fit.surface[..., 2]
    assert z.max() <= tol
    assert fit.max_deviation <= 2 * tol  # one-pixel patches cannot bend through the kink exactly
    assert np.percentile(np.abs(fit.deviation), 99) <= tol
    # the flat plate away from the crack stays in few large patches
    assert max(fit.patch_sizes()) == default_step(hf.shape)
    # the default tolerance is RELATIVE_TOLERANCE of the height range
    default = fit_height(hf.height, hf.p, hf.q, pixel_size=hf.pixel_size)
    assert default.tolerance == pytest.approx(RELATIVE_TOLERANCE * 0.6, rel=0.05)


def test_refinement_follows_the_tolerance():
    hf = v_crack(128, 0.05, depth_mm=0.6, width_mm=2.0, length_mm=4.0, axis_deg=30.0)
    coarse = fit_height(hf.height, hf.p, hf.q, pixel_size=0.05, tolerance=0.05)
    fine = fit_height(hf.height, hf.p, hf.q, pixel_size=0.05, tolerance=0.002)
    assert coarse.patches.n_patches < fine.patches.n_patches
    assert fine.max_deviation < coarse.max_deviation
    # small patches only near the crack
    small = fine.patches.cells[fine.patches.sizes == 1]
    pixel = small[:, :2]  # a one-pixel patch at lattice (row, col) covers pixel (row, col)
    # a failing cell and its neighbours are refined: at most three level-0 cells (6 px) away
    distance = ndimage.distance_transform_edt(~hf.defect_mask)
    assert fine.step == 2 and distance[pixel[:, 0], pixel[:, 1]].max() <= 3 * fine.step
    assert (fine.patches.sizes == 1).sum() < 0.2 * hf.height.size  # one-pixel patches cover < 20 % of the image


def test_bad_input_is_a_clear_error():
    z, p, q = _poly("plane", (16, 16), 1.0)
    with pytest.raises(ValueError, match="tolerance"):
        fit_height(z, p, q, tolerance=0.0)
    with pytest.raises(ValueError, match="tolerance"):
        fit_height(z, p, q, tolerance=-1.0)
    bad = z.copy()
    bad[3, 4] = np.nan
    message = r"height: 1 non-finite value\(s\) inside the mask \(first at row 3, column 4\)"
    with pytest.raises(ValueError, match=message):
        fit_height(bad, p, q)
    mask = np.ones_like(bad, bool)
    mask[3, 4] = False
    assert fit_height(bad, p, q, mask=mask).region.sum() == 255  # NaN outside the mask is fine
    qq = q.copy()
    qq[0, 0] = np.inf
    with pytest.raises(ValueError, match="q: 1 non-finite"):
        fit_height(z, p, qq)
    with pytest.raises(ValueError, match="p"):
        fit_height(z, p[:, :-1], q)
    with pytest.raises(ValueError, match="mask"):
        fit_height(z, p, q, mask=np.ones((16, 15), bool))
    with pytest.raises(ValueError, match="mask: no pixel"):
        fit_height(z, p, q, mask=np.zeros((16, 16), bool))
    with pytest.raises(ValueError, match="step"):
        fit_height(z, p, q, step=0)
    with pytest.raises(ValueError, match="pixel_size"):
        fit_height(z, p, q, pixel_size=0)
    for angle in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="slope_angle"):
            fit_height(z, p, q, slope_angle=angle)
    with pytest.raises(ValueError, match="xy"):
        fit_height(z, p, q, xy=np.zeros((16, 16, 3)))
    with pytest.raises(ValueError, match="height"):
        fit_height(np.zeros((1, 5)), np.zeros((1, 5)), np.zeros((1, 5)))
    with pytest.raises(ValueError, match="spacing"):
        fit_mesh(fit_height(z, p, q), spacing=0)
    with pytest.raises(ValueError, match="fit"):
        fit_mesh(None)


def test_step_is_a_power_of_two():
    z, p, q = _poly("plane", (40, 40), 1.0)
    assert fit_height(z, p, q, step=12).step == 8
    assert default_step((512, 612)) == 8 and default_step((2048, 2048)) == 32 and default_step((8, 8)) == 1


def test_mesh_is_trimmed_along_the_mask_outline():
    shape = (60, 80)
    z, p, q = _poly("quadratic", shape, 0.1)
    r, c = np.mgrid[0:60, 0:80]
    mask = ((r - 30) ** 2 / 600 + (c - 40) ** 2 / 900) < 1
    mask[25:35, 35:45] = False  # a hole
    fit = fit_height(np.where(mask, z, np.nan), p, q, mask=mask, pixel_size=0.1, step=8)
    mesh = fit_mesh(fit)
    assert mesh.is_oriented() and (mesh.face_normals()[:, 2] > 0).all()
    _, counts = mesh.edge_counts()
    assert counts.max() == 2
    boundary = np.unique(mesh.boundary_edges())
    row, col = xy_to_pixel(mesh.vertices[boundary, 0], mesh.vertices[boundary, 1], shape, 0.1)
    # on the 0.5 line of the smoothed mask exactly, and a fraction of a pixel from the mask's own outline
    smooth = np.concatenate(find_contours(ndimage.gaussian_filter(mask * 1.0, 0.7, mode="constant"), 0.5))
    assert cKDTree(smooth).query(np.stack([row, col], 1))[0].max() < 1e-9
    outline = np.concatenate(find_contours(np.pad(mask, 1) * 1.0, 0.5)) - 1
    assert cKDTree(outline).query(np.stack([row, col], 1))[0].max() < 0.3
    # two boundary loops (outer rim and hole): as many boundary edges as boundary vertices
    assert len(mesh.boundary_edges()) == boundary.size
    # every vertex lies on the patches: inside the mask the surface is the polynomial
    x, y = pixel_grid(shape, 0.1)
    inner = ndimage.binary_erosion(mask, iterations=2)
    vr, vc = xy_to_pixel(mesh.vertices[:, 0], mesh.vertices[:, 1], shape, 0.1)
    ir, ic = np.rint(vr).astype(int), np.rint(vc).astype(int)
    sel = np.isclose(vr, ir) & np.isclose(vc, ic) & inner[ir.clip(0, 59), ic.clip(0, 79)]
    assert sel.sum() > 1000
    np.testing.assert_allclose(mesh.vertices[sel, 2], z[ir[sel], ic[sel]], atol=1e-9)


def test_full_rectangle_mesh_is_one_sheet_to_the_image_edges():
    z, p, q = _poly("cubic", (32, 24), 0.5)
    fit = fit_height(z, p, q, pixel_size=0.5, step=8)
    mesh = fit_mesh(fit, smoothing=0.0)
    _, counts = mesh.edge_counts()
    assert counts.max() == 2 and mesh.is_oriented()
    # the sheet reaches the pixel edges: x from -6 to 6 mm, y from -8 to 8 mm (half a pixel beyond the centres)
    lo, hi = mesh.vertices[:, :2].min(axis=0), mesh.vertices[:, :2].max(axis=0)
    np.testing.assert_allclose(lo, [-6.0, -8.0], atol=1e-9)
    np.testing.assert_allclose(hi, [6.0, 8.0], atol=1e-9)
    # coarser lattice: fewer vertices, same outline
    assert fit_mesh(fit, spacing=2.0).n_vertices < mesh.n_vertices / 3


def test_depth_discontinuity_is_a_border_not_a_ramp():
    """Two plateaus 10 px apart in height, slopes zero: the jump is unexplained, so it is cut."""
    h = 0.1
    z = np.zeros((40, 48))
    z[:, 24:] = 1.0
    p = q = np.zeros_like(z)
    border = find_discontinuities(z, p, q, np.ones(z.shape, bool), pixel_size=h)
    assert border[:, 23:25].all() and border.sum() == 80
    fit = fit_height(z, p, q, pixel_size=h, step=8, tolerance=0.01)
    assert not fit.region[:, 23:25].any() and fit.region.sum() == 40 * 46
    assert fit.max_deviation <= 0.01
    mesh = fit_mesh(fit)
    # two sheets, each on its plateau: no triangle across the gap; the outline lies half a
    # pixel into the gap, where the surface has begun to turn (6.4 % of the jump measured)
    zs = mesh.vertices[:, 2]
    assert np.all((np.abs(zs) < 0.1) | (np.abs(zs - 1.0) < 0.1))
    tri_z = zs[mesh.triangles]
    assert np.all(np.ptp(tri_z, axis=1) < 0.1)
    tri = mesh.triangles
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]]])
    graph = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(mesh.n_vertices,) * 2)
    assert connected_components(graph, directed=False)[0] == 2
    # a ramp that the slopes explain is not a discontinuity
    ramp = np.tile(np.arange(48) * 0.5 * h, (40, 1))
    assert not find_discontinuities(ramp, np.full(z.shape, 0.5), q, np.ones(z.shape, bool), pixel_size=h).any()


def test_mask_border_pulls_no_spike():
    """A sphere cap cut out by its silhouette, the flat base outside it left out of the mask:
    the trimmed surface continues the sphere to the outline, never pulled towards the base."""
    hf = sphere_cap(96, 0.05, height_mm=1.0)  # rim slope about 60 deg, base z = 0 outside
    mask = hf.defect_mask
    fit = fit_height(hf.height, hf.p, hf.q, mask=mask, pixel_size=0.05)
    mesh = fit_mesh(fit)
    R, cap = hf.params["radius_mm"], hf.params["height_mm"]
    v = mesh.vertices
    sphere = np.sqrt(R * R - v[:, 0] ** 2 - v[:, 1] ** 2) - (R - cap)
    assert np.abs(v[:, 2] - sphere).max() < 0.05 * fit.tolerance
    # patches only around the cap: none far out in the background
    # patches only over cells with data and a margin of one cell: centres within 1.5 cells
    centre = fit.patches.cells[:, :2] + fit.patches.cells[:, 2:] / 2.0
    distance = ndimage.distance_transform_edt(~mask)
    reach = distance[centre[:, 0].astype(int).clip(0, 95), centre[:, 1].astype(int).clip(0, 95)]
    assert reach.max() <= 1.5 * np.sqrt(2) * fit.step + 1e-9


def test_perspective_xy_fits_three_coordinates():
    """Pixels that see points at known x, y (a perspective camera over a tilted plane)."""
    shape, f, px = (40, 50), 400.0, 1.0
    r, c = np.mgrid[0:40, 0:50].astype(float)
    a, b, d = 0.2, -0.1, 100.0  # z = a x + b y - d, seen by a pinhole at the origin looking down -z
    ux, uy = (c - 24.5) / f, (19.5 - r) / f  # x = ux * (-z), y = uy * (-z)
    zc = -d / (1 + a * ux + b * uy)
    x, y = ux * -zc, uy * -zc
    z = zc + d
    fit = fit_height(z, np.full(shape, a), np.full(shape, b), pixel_size=px, xy=np.stack([x, y], 2), tolerance=1e-4)
    assert fit.max_deviation <= 1e-4
    pts = fit.surface
    np.testing.assert_allclose(pts[..., 0], x, atol=1e-4)
    np.testing.assert_allclose(pts[..., 2], z, atol=1e-4)
    n = np.array([-a, -b, 1.0]) / np.sqrt(1 + a * a + b * b)
    assert np.abs(fit.normals - n).max() < 1e-3
    control = fit.patches.control
    assert not np.allclose(control[..., 0], np.round(control[..., 0]))  # x fitted, not the grid


def test_patch_sizes_and_lattice():
    hf = v_crack(64, 0.05, depth_mm=0.3, width_mm=1.0, length_mm=2.0)
    fit = fit_height(hf.height, hf.p, hf.q, pixel_size=0.05, step=8)
    sizes = fit.patch_sizes()
    assert list(sizes) == sorted(sizes, reverse=True) and sum(sizes.values()) == fit.patches.n_patches
    # the leaves tile the 64 x 64 pixel squares exactly once
    assert (fit.patches.patch_map() >= 0).all() and fit.patches.lattice_shape == (64, 64)
    assert sum(k * k * n for k, n in sizes.items()) == 64 * 64


def test_level_zero_is_scipys_least_squares_spline(monkeypatch):
    """Without refinement and smoothing, the fit is the tensor-product least-squares cubic spline
    of heights and slopes on the uniform knots ``-0.5 + i step``: the same problem posed with
    scipy's B-spline basis and solved by a dense least-squares solver gives the same surface."""
    from scipy.interpolate import BSpline

    import surfaces.fit as fit_module

    monkeypatch.setattr(fit_module, "SMOOTHING", 0.0)
    rng = np.random.default_rng(3)
    H, W, k, h, lam = 24, 32, 8, 0.2, 0.7
    x, y = pixel_grid((H, W), h)
    z = np.sin(1.3 * x) * np.cos(0.7 * y) + 0.1 * rng.standard_normal((H, W))
    p = 1.3 * np.cos(1.3 * x) * np.cos(0.7 * y) + 0.2 * rng.standard_normal((H, W))
    q = -0.7 * np.sin(1.3 * x) * np.sin(0.7 * y) + 0.2 * rng.standard_normal((H, W))
    fit = fit_height(z, p, q, pixel_size=h, step=k, tolerance=1e3, slope_weight=lam, jump=1e3)
    assert len(fit.levels) == 1

    def basis(n_px):
        cells = -(-n_px // k)
        knots = -0.5 + k * np.arange(-3, cells + 4)
        spline = BSpline(knots, np.eye(cells + 3), 3)
        s = np.arange(n_px, dtype=float)
        return spline(s), spline.derivative()(s)  # values and d/d(pixel)

    Bs, Ds = basis(H)
    Bt, Dt = basis(W)
    # rows: heights, slopes along rows (z_s = -q h) and columns (z_t = p h), slope rows weighted by sqrt(lam)
    design = np.concatenate([np.kron(Bs, Bt), np.sqrt(lam) * np.kron(Ds, Bt), np.sqrt(lam) * np.kron(Bs, Dt)])
    target = np.concatenate([z.ravel(), np.sqrt(lam) * (-q * h).ravel(), np.sqrt(lam) * (p * h).ravel()])
    coef = np.linalg.lstsq(design, target, rcond=None)[0]
    peer = (np.kron(Bs, Bt) @ coef).reshape(H, W)
    np.testing.assert_allclose(fit.surface[..., 2], peer, atol=1e-10)
    # and the patches carry it: the Bezier conversion is exact
    point, ds, dt = _patch_values(fit, *np.nonzero(np.ones((H, W), bool)))
    np.testing.assert_allclose(point[:, 2], peer.ravel(), atol=1e-10)
    np.testing.assert_allclose(dt[:, 2], (np.kron(Bs, Dt) @ coef), atol=1e-10)


def test_deviation_statistics_match_the_deviation_map():
    hf = v_crack(64, 0.05, depth_mm=0.6, width_mm=2.0, length_mm=2.0, axis_deg=30.0)
    rng = np.random.default_rng(3)
    z = hf.height + 0.002 * rng.standard_normal(hf.height.shape)
    mask = np.ones(z.shape, bool)
    mask[:, :5] = False
    fit = fit_height(z, hf.p, hf.q, mask=mask, pixel_size=0.05, tolerance=0.01)
    assert np.isnan(fit.deviation[~fit.region]).all()
    dev = fit.deviation[fit.region]
    # signed: the surface minus the height
    assert np.allclose(dev, fit.surface[..., 2][fit.region] - z[fit.region], rtol=0, atol=1e-12)
    assert fit.max_deviation == pytest.approx(np.abs(dev).max(), rel=1e-12)
    assert fit.rms_deviation == pytest.approx(np.sqrt(np.mean(dev**2)), rel=1e-12)


def test_lookup_in_and_out_of_range_agree():
    from surfaces.fit import _Lookup

    i, j = np.array([0, 2, 5]), np.array([1, 3, 4])
    look = _Lookup(i, j, (6, 6))
    assert look(np.array([2, 5]), np.array([3, 4])).tolist() == [1, 2]
    # queries beyond the padded map take the checked path and find nothing there
    far = look(np.array([2, -50, 5]), np.array([3, 0, 400]))
    assert far.tolist() == [1, -1, -1]
    assert look(np.array([1, 2]), np.array([1, 3])).tolist() == [-1, 1]


def test_blas_thread_count_is_restored():
    from threadpoolctl import threadpool_info

    from surfaces.threads import one_blas_thread

    def blas_threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = blas_threads()
    with one_blas_thread():
        assert all(n == 1 for n in blas_threads())
    assert blas_threads() == before
    r, c = np.mgrid[0:32, 0:32]
    fit_height(0.5 * c - 0.25 * r, np.full((32, 32), 0.5), np.full((32, 32), 0.25))
    assert blas_threads() == before


def test_default_tolerance_stays_above_the_height_noise():
    """A noisy measured height is fitted with large patches, not chased down to single pixels."""
    from surfaces.fit import MIN_TOLERANCE_PX, NOISE_TOLERANCE, height_noise

    rng = np.random.default_rng(3)
    r, c = np.mgrid[0:256, 0:256].astype(float)
    clean = 0.002 * c - 0.001 * r
    noisy = clean + rng.normal(0.0, 0.004, clean.shape)
    p, q = np.full(clean.shape, 0.002), np.full(clean.shape, 0.001)
    quiet = fit_height(clean, p, q)
    assert quiet.tolerance == pytest.approx(max(0.005 * np.ptp(np.percentile(clean, [0.5, 99.5])),
                                                MIN_TOLERANCE_PX))
    fit = fit_height(noisy, p, q)
    sigma = height_noise(noisy, np.ones(clean.shape, bool), fit.step / 2.0)
    assert 0.003 < sigma < 0.005
    assert fit.tolerance == pytest.approx(NOISE_TOLERANCE * sigma)
    # hardly a cell chases the noise (a few pixels beyond 4 sigma refine theirs); at the
    # tolerance without the noise floor the fit breaks up into many more patches
    sizes = fit.patch_sizes()
    assert sizes[fit.step] * fit.step**2 >= 0.95 * clean.size
    chased = fit_height(noisy, p, q, tolerance=quiet.tolerance)
    assert chased.patches.n_patches > 5 * fit.patches.n_patches
    # and the surface follows the plane more closely than the noisy heights do
    off_plane = (fit.deviation + (noisy - clean))[fit.region]  # deviation = surface - noisy height
    assert np.sqrt(np.mean(off_plane**2)) < 0.7 * np.sqrt(np.mean((noisy - clean) ** 2))


def _angles(fit, p, q):
    """Angle (degrees) between the fit's normals and the normals of slopes ``p, q`` on its region."""
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((fit.normals * n).sum(axis=-1), -1.0, 1.0)))[fit.region]


def _ripples(amplitude=0.1, wavelength=8.0):
    """A tilted plane with fine ripples (height under a noise-set tolerance, slopes of 4.5 deg)."""
    r, c = np.mgrid[0:128, 0:128].astype(float)
    k = 2.0 * np.pi / wavelength
    z = 0.01 * c + amplitude * np.sin(k * c) * np.sin(k * r)
    p = 0.01 + amplitude * k * np.cos(k * c) * np.sin(k * r)
    q = -amplitude * k * np.sin(k * c) * np.cos(k * r)  # y up: dz/dy = -dz/drow
    return z, p, q


def test_slope_check_keeps_the_detail_a_noise_set_tolerance_lets_go():
    """Fine ripples read as noise loosen the tolerance; the slope check still follows their normals."""
    from surfaces.fit import SLOPE_ANGLE, SLOPE_CELL_PX

    z, p, q = _ripples()
    fit = fit_height(z, p, q, step=16)
    # the noise term set the tolerance above the ripples' amplitude: the height alone
    # would keep the 16 px patches (same tolerance, explicit: no slope check)
    assert fit.tolerance > 0.1
    loose = fit_height(z, p, q, step=16, tolerance=fit.tolerance)
    assert loose.patch_sizes() == {16: 64}
    assert _angles(loose, p, q).mean() > 2.0
    # with the check the cells refine down to half of SLOPE_CELL_PX and follow the normals
    assert min(fit.patch_sizes()) == SLOPE_CELL_PX // 2
    assert _angles(fit, p, q).mean() < 0.5 * SLOPE_ANGLE
    assert fit.max_deviation <= fit.tolerance
    # an explicit slope_angle applies at any tolerance
    forced = fit_height(z, p, q, step=16, tolerance=fit.tolerance, slope_angle=SLOPE_ANGLE)
    assert forced.patch_sizes() == fit.patch_sizes()


def test_slope_check_does_not_chase_noisy_normals():
    """Noisy normals and their integral: the height's own normals miss them as much, no refinement."""
    from photometric.integrate import dct_poisson

    rng = np.random.default_rng(1)
    p = 0.01 + rng.normal(0.0, 0.05, (128, 128))
    q = rng.normal(0.0, 0.05, (128, 128))
    z = dct_poisson(p, q)
    fit = fit_height(z, p, q, step=16)
    plain = fit_height(z, p, q, step=16, tolerance=fit.tolerance)  # no slope check
    assert fit.tolerance > 10 * RELATIVE_TOLERANCE * np.ptp(np.percentile(z, [0.5, 99.5]))  # noise-set
    assert fit.patch_sizes() == plain.patch_sizes()
    assert min(fit.patch_sizes()) >= 8


@pytest.mark.parametrize("shape,scale", [((120, 90), 8.0), ((64, 64), 0.5), ((5, 7), 4.0), ((40, 33), 2.0)])
def test_height_noise_fast_paths_match_direct_filters(shape, scale):
    """The FFT Gaussian and a full mask's separable weights give the direct filters' noise."""
    from surfaces.fit import _gaussian, height_noise

    rng = np.random.default_rng(3)
    rows, cols = np.indices(shape)
    z = 0.3 * np.sin(rows / 20.0) * np.cos(cols / 15.0) + rng.normal(0.0, 0.002, shape)
    np.testing.assert_allclose(_gaussian(z, scale), ndimage.gaussian_filter(z, scale, mode="constant"),
                               rtol=0, atol=1e-14)
    for m in (np.ones(shape, bool), rng.random(shape) > 0.2):
        w = ndimage.gaussian_filter(m.astype(float), scale, mode="constant")
        smooth = ndimage.gaussian_filter(np.where(m, z, 0.0), scale, mode="constant")
        inner = m & (w > 0.99)
        expected = 0.0
        if inner.any():
            d = (z - smooth / np.maximum(w, 1e-12))[inner]
            expected = 1.4826 * np.median(np.abs(d - np.median(d)))
        assert height_noise(z, m, scale) == pytest.approx(expected, rel=1e-9, abs=1e-15)


def test_fit_mesh_keeps_its_old_import_path():
    """The trimmed mesh moved to surfaces.fit_mesh; ``surfaces.fit.fit_mesh`` is the same function."""
    import surfaces.fit
    import surfaces.fit_mesh

    assert surfaces.fit.fit_mesh is surfaces.fit_mesh.fit_mesh
    with pytest.raises(AttributeError):
        surfaces.fit.no_such_name  # noqa: B018
