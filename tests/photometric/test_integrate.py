import numpy as np
import pytest

from datasets_synthetic.heightfields import make_scene
from photometric.integrate import height_to_patches, integrate
from surfaces.grid import pixel_grid


def _rmse_rel(z, ref, mask=None):
    m = np.isfinite(z) if mask is None else mask
    ref = ref - ref[m].mean()
    return float(np.sqrt(np.mean((z[m] - z[m].mean() - ref[m]) ** 2)) / np.ptp(ref[m]))


@pytest.mark.parametrize("scene", ["sphere", "vase"])
@pytest.mark.parametrize("method", ["dct", "lsq"])
def test_smooth_scenes_within_0p2_percent(scene, method):
    hf = make_scene(scene, 512, 0.05)
    z = integrate(hf.p, hf.q, method, pixel_size=hf.pixel_size)
    assert z.shape == (512, 512) and z.dtype == np.float64
    assert _rmse_rel(z, hf.height) < 0.002


@pytest.mark.parametrize("method,tol", [("fc", 0.01), ("dct", 0.01)])
def test_crack_plate(method, tol):
    """Slope kinks at the defect rims: first order there, so a looser bound at 256 px."""
    hf = make_scene("plate", 256, 0.1)
    z = integrate(hf.p, hf.q, method, pixel_size=hf.pixel_size)
    assert _rmse_rel(z, hf.height) < tol


def test_dct_and_lsq_agree_on_rectangle():
    hf = make_scene("bumps", 96, 0.05, seed=2)
    a = integrate(hf.p, hf.q, "dct", pixel_size=0.05)
    b = integrate(hf.p, hf.q, "lsq", pixel_size=0.05)
    assert np.abs(a - b).max() < 1e-8 * np.ptp(a) + 1e-12


@pytest.mark.parametrize("a,b", [(0.2, 0.0), (0.0, 0.3), (-0.1, 0.25)])
@pytest.mark.parametrize("method", ["dct", "lsq"])
def test_plane_signs_y_up(a, b, method):
    """z = a x + b y with x = col h, y = -row h (row 0 at the top)."""
    h, n = 0.5, 40
    z = integrate(np.full((n, n), a), np.full((n, n), b), method, pixel_size=h)
    rows, cols = np.indices((n, n))
    ref = a * cols * h - b * rows * h
    assert np.allclose(z, ref - ref.mean(), atol=1e-9)


@pytest.mark.parametrize("method", ["dct", "lsq", "fc"])
def test_bump_lands_up_right(method):
    """A Gaussian bump centred at x > 0, y > 0 must appear right of centre and ABOVE it
    (smaller row index): catches a flipped q."""
    n, h = 64, 1.0
    rows, cols = np.indices((n, n)).astype(float)
    x, y = cols - 31.5, 31.5 - rows
    z = np.exp(-((x - 10.5) ** 2 + (y - 8.5) ** 2) / 30.0)
    p = z * -2 * (x - 10.5) / 30.0
    q = z * -2 * (y - 8.5) / 30.0
    out = integrate(p, q, method, pixel_size=h)
    r, c = np.unravel_index(np.argmax(out), out.shape)
    assert (r, c) == np.unravel_index(np.argmax(z), z.shape) == (23, 42)
    assert np.abs(out - (z - z.mean())).max() < 0.02  # trapezoidal error at 4 px width


def test_pixel_size_scales_height():
    hf = make_scene("sphere", 64, 1.0)
    z1 = integrate(hf.p, hf.q, "dct", pixel_size=1.0)
    z3 = integrate(hf.p, hf.q, "dct", pixel_size=3.0)
    assert np.allclose(z3, 3 * z1)


def test_lsq_masked_domain_with_hole_and_two_parts():
    n = 120
    rows, cols = np.indices((n, n)).astype(float)
    x, y = cols, -rows
    z = 1e-3 * (x - 60) ** 2 + 2e-3 * (y + 50) * (x - 30)
    p = 2e-3 * (x - 60) + 2e-3 * (y + 50)
    q = 2e-3 * (x - 30)
    mask = ((rows - 60) ** 2 + (cols - 50) ** 2 < 45**2) & ~((rows - 60) ** 2 + (cols - 50) ** 2 < 10**2)
    mask |= (rows > 5) & (rows < 20) & (cols > 100) & (cols < 115)  # a separate part
    # garbage outside the domain must not leak in
    p = np.where(mask, p, 50.0)
    q = np.where(mask, q, -50.0)
    out = integrate(p, q, "lsq", mask=mask)
    assert np.isnan(out[~mask]).all()
    from scipy import ndimage

    labels, count = ndimage.label(mask)
    assert count == 2
    for k in (1, 2):
        part = labels == k
        ref = z[part] - z[part].mean()
        assert np.abs(out[part] - ref).max() < 1e-3 * np.ptp(z[mask])
        assert abs(out[part].mean()) < 1e-9


def test_bad_input():
    with pytest.raises(ValueError, match="method"):
        integrate(np.zeros((4, 4)), np.zeros((4, 4)), "poisson")
    with pytest.raises(ValueError, match="q"):
        integrate(np.zeros((4, 4)), np.zeros((4, 5)))
    with pytest.raises(ValueError, match="pixel_size"):
        integrate(np.zeros((4, 4)), np.zeros((4, 4)), pixel_size=0)
    with pytest.raises(ValueError, match="mask"):
        integrate(np.zeros((4, 4)), np.zeros((4, 4)), mask=np.zeros((4, 4), bool))


@pytest.mark.parametrize("step", [4, 7])
def test_height_to_patches_interpolates_and_uses_measured_tangents(step):
    hf = make_scene("sphere", 65, 0.1)
    patches = height_to_patches(hf.height, hf.p, hf.q, pixel_size=0.1, step=step)
    n_r = int(np.ceil(64 / step)) + 1
    assert patches.shape == (n_r - 1, n_r - 1)
    # the grid corners are interpolated
    corners = patches.control[:, :, 0, 0]
    s = 64 / (n_r - 1)
    rows = np.arange(n_r - 1) * s
    cols = np.arange(n_r - 1) * s
    # centred pixel grid (surfaces.grid): pixel (row, col) at ((col - 32) h, (32 - row) h)
    assert np.allclose(corners[..., 0], (cols[None, :] - 32) * 0.1)
    assert np.allclose(corners[..., 1], (32 - rows[:, None]) * 0.1)
    if step == 4:  # the node over pixel (4, 8) has that pixel's x and y from the scene itself
        x, y = pixel_grid(hf.shape, 0.1)
        np.testing.assert_allclose(corners[1, 2, :2], [x[4, 8], y[4, 8]], atol=1e-12)
    if step == 4:  # integer grid positions: heights exactly
        assert np.allclose(corners[..., 2], hf.height[::4, ::4][:-1, :-1])
        # tangent along v at a node is dP/dj = 3 (b01 - b00) = s h (1, 0, p)
        tv = 3 * (patches.control[:, :, 0, 1] - patches.control[:, :, 0, 0])
        assert np.allclose(tv[..., 2], s * 0.1 * hf.p[::4, ::4][:-1, :-1])
    # surface normals point up (+z) and match the analytic ones at patch centres
    pi, pj = np.meshgrid(np.arange(patches.shape[0]), np.arange(patches.shape[1]), indexing="ij")
    half = np.full(pi.size, 0.5)
    nrm = patches.normals(pi.ravel(), pj.ravel(), half, half)
    assert (nrm[:, 2] > 0).all()


def test_height_to_patches_fills_nan():
    hf = make_scene("vase", 33, 0.1)
    z = hf.height.copy()
    z[:5] = np.nan
    p = hf.p.copy()
    p[:5] = np.nan
    patches = height_to_patches(z, p, hf.q, 0.1, step=8)
    # nodes on row 0 take the nearest finite height, the one five rows down
    np.testing.assert_allclose(patches.control[0, :, 0, 0, 2], hf.height[5, 0:32:8], atol=1e-12)
    np.testing.assert_allclose(patches.control[-1, -1, 3, 3, 2], hf.height[32, 32], atol=1e-12)
    # a NaN slope counts as 0: the tangent along the row there is flat
    tv = 3 * (patches.control[0, :, 0, 1] - patches.control[0, :, 0, 0])
    np.testing.assert_allclose(tv[:, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(tv[:, 0], 8 * 0.1, atol=1e-12)
    with pytest.raises(ValueError, match="step"):
        height_to_patches(hf.height, hf.p, hf.q, 0.1, step=0)


@pytest.mark.parametrize("scene,tol", [("bumps", 1e-4), ("vase", 1e-2)])
def test_robust_equals_lsq_on_smooth_fields(scene, tol):
    """Integrable slopes: nothing to cut, the robust integral is the least-squares one.

    The vase's steeper flanks (slopes up to 1.5) leave a discretisation curl of the
    trapezoidal predictions that the reweighting sees, hence the looser bound there; the
    robust result is no farther from the true height than least squares.
    """
    hf = make_scene(scene, 96, 0.05, seed=2)
    mask = np.hypot(*np.indices(hf.shape) - 47.5) < 44  # a masked domain, not the rectangle
    a = integrate(hf.p, hf.q, "lsq", mask=mask, pixel_size=0.05)
    b = integrate(hf.p, hf.q, "robust", mask=mask, pixel_size=0.05)
    assert np.isnan(b[~mask]).all()
    assert np.abs(a - b)[mask].max() < tol * np.ptp(a[mask])
    assert _rmse_rel(b, hf.height, mask) <= _rmse_rel(a, hf.height, mask) + 1e-5


def test_robust_exact_on_polynomial():
    """Quadratic heights: the trapezoidal edge predictions are exact, so is the result."""
    n = 40
    rows, cols = np.indices((n, n)).astype(float)
    x, y = cols * 0.5, -rows * 0.5
    z = 0.1 * x**2 - 0.05 * x * y + 0.2 * y
    out = integrate(0.2 * x - 0.05 * y, -0.05 * x + 0.2, "robust", pixel_size=0.5)
    np.testing.assert_allclose(out, z - z.mean(), atol=1e-9)


@pytest.mark.parametrize("shape", [(32, 128), (48, 96)])
def test_robust_keeps_a_step_that_lsq_smears(shape):
    """Two planes with a depth jump along the seam col = W/2 - 1/2 that grows down the rows.

    Left ``z = a x``, right ``z = a x + b y + c``: the slopes (a, 0) and (a, b) carry the
    jump only in the curl of the squares on the seam. The minimiser of the absolute
    residuals puts the whole disagreement on the seam (its edges are the shortest way
    from the curl to the border), so each half is its own plane exactly and the jump
    across the seam is ``b y`` up to one constant; least squares bends both halves.
    """
    H, W = shape
    h, slope_a, slope_b = 0.2, 0.3, 0.4
    p = np.full(shape, slope_a)
    q = np.zeros(shape)
    q[:, W // 2:] = slope_b
    rows, cols = np.indices(shape).astype(float)
    ref = slope_a * cols * h + np.where(cols >= W // 2, -slope_b * rows * h, 0.0)
    z = integrate(p, q, "robust", pixel_size=h)
    for half in (slice(0, W // 2), slice(W // 2, W)):
        d = z[:, half] - ref[:, half]
        assert np.ptp(d) < 1e-6 * np.ptp(ref)  # each half is its plane, up to a constant
    jump = z[:, W // 2] - z[:, W // 2 - 1]
    np.testing.assert_allclose(np.diff(jump), -slope_b * h, atol=1e-6)  # the jump grows b h per row
    lsq = integrate(p, q, "lsq", pixel_size=h)
    d = lsq[:, : W // 2] - ref[:, : W // 2]
    assert np.ptp(d) > 0.05 * np.ptp(ref)
    assert np.abs(np.diff(lsq[:, W // 2] - lsq[:, W // 2 - 1]) + slope_b * h).max() > 0.2 * slope_b * h


def test_robust_two_parts_and_bad_input():
    from photometric.integrate import robust_least_squares

    n = 40
    rows, cols = np.indices((n, n)).astype(float)
    mask = (cols < 15) | (cols > 25)
    out = robust_least_squares(np.full((n, n), 0.5), np.zeros((n, n)), mask=mask)
    for part in (cols < 15, cols > 25):
        np.testing.assert_allclose(out[part], (cols[part] - cols[part].mean()) * 0.5, atol=1e-9)
    assert np.isnan(out[~mask]).all()
    with pytest.raises(ValueError, match="eps"):
        robust_least_squares(np.zeros((4, 4)), np.zeros((4, 4)), eps=0)
    with pytest.raises(ValueError, match="iterations"):
        robust_least_squares(np.zeros((4, 4)), np.zeros((4, 4)), iterations=-1)
    with pytest.raises(ValueError, match="mask"):
        robust_least_squares(np.zeros((4, 4)), np.zeros((4, 4)), mask=np.zeros((4, 4), bool))


def test_nearfield_takes_the_robust_integrator():
    """A masked plane under point lights: the robust integral is the least-squares one (no curl)."""
    from photometric.camera import make_camera, pixel_offsets
    from photometric.leds import light_field, point_lights
    from photometric.nearfield import INTEGRATORS, solve_nearfield

    assert "robust" in INTEGRATORS
    cam = make_camera("orthographic", pixel_size_mm=0.4)
    shape = (30, 34)
    a = np.radians(90.0 + 120.0 * np.arange(3))
    pos = 150.0 * np.stack([np.sin(np.pi / 4) * np.cos(a), np.sin(np.pi / 4) * np.sin(a),
                            np.full(3, np.cos(np.pi / 4))], axis=1)
    x, y = np.meshgrid(*pixel_offsets(cam, shape))
    X = np.stack([x, y, 0.1 * x], axis=-1)
    n = np.array([-0.1, 0.0, 1.0]) / np.hypot(0.1, 1.0)
    images = (0.8 * light_field(point_lights(pos), X) @ n).astype(np.float32)
    mask = np.zeros(shape, bool)
    mask[4:26, 3:30] = True
    out = {m: solve_nearfield(images, point_lights(pos), cam, mask=mask, integrator=m, tolerance_mm=1e-5)
           for m in ("lsq", "robust")}
    assert np.isnan(out["robust"].height[~mask]).all()
    plane = X[..., 2][mask]
    # the anchor puts the median valid pixel at z = 0
    np.testing.assert_allclose(out["robust"].height[mask], plane - np.median(plane), atol=2e-4)
    np.testing.assert_allclose(out["robust"].height[mask], out["lsq"].height[mask], atol=1e-5)
