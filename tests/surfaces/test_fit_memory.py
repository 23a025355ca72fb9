"""surfaces.fit in bounded memory (issue 20): float32 kept float32, block passes, the lattice field."""

import tracemalloc

import numpy as np
import pytest
from scipy import ndimage

import surfaces.fit as F
import surfaces.fit_mesh as FM
from datasets_synthetic.heightfields import sphere_cap, v_crack
from surfaces.fit import fit_height, fit_mesh, height_noise
from surfaces.mixed import MixedPatches


def _scene(size=192):
    hf = v_crack(size, 0.05, depth_mm=0.4, width_mm=1.2, length_mm=5.0, axis_deg=30.0)
    cap = sphere_cap(size, 0.05, height_mm=0.8)
    mask = np.ones(hf.shape, bool)
    mask[:, : size // 10] = False
    mask[size // 3: size // 2, -size // 8:] = False
    return hf.height + cap.height, hf.p + cap.p, hf.q + cap.q, mask


def _same_fit(a, b, atol):
    assert a.patch_sizes() == b.patch_sizes() and a.levels == b.levels
    np.testing.assert_array_equal(a.region, b.region)
    np.testing.assert_array_equal(a.covered, b.covered)
    np.testing.assert_array_equal(a.patches.cells, b.patches.cells)
    np.testing.assert_allclose(a.patches.control, b.patches.control, rtol=0, atol=atol)
    for va, vb in zip(a.values, b.values):
        np.testing.assert_allclose(va, vb, rtol=0, atol=atol)
    np.testing.assert_array_equal(np.isnan(a.deviation), np.isnan(b.deviation))
    np.testing.assert_allclose(a.deviation, b.deviation, rtol=0, atol=atol)
    assert a.max_deviation == pytest.approx(b.max_deviation, abs=atol)
    assert a.rms_deviation == pytest.approx(b.rms_deviation, abs=atol)


def test_float32_inputs_stay_float32_and_fit_as_float64_does():
    z, p, q, mask = _scene()
    fit64 = fit_height(z, p, q, mask=mask, pixel_size=0.05)
    fit32 = fit_height(z.astype(np.float32), p.astype(np.float32), q.astype(np.float32), mask=mask,
                       pixel_size=0.05)
    assert all(v.dtype == np.float32 for v in fit32.values) and fit32.deviation.dtype == np.float32
    assert all(v.dtype == np.float64 for v in fit64.values) and fit64.deviation.dtype == np.float64
    assert fit32.tolerance == pytest.approx(fit64.tolerance, rel=1e-5)
    # float32 rounding of heights up to about 1 mm, a few ulps after the refinement
    _same_fit(fit32, fit64, atol=2e-6)
    assert fit32.surface.dtype == np.float64 and np.isfinite(fit32.normals[fit32.covered]).all()
    mesh32, mesh64 = fit_mesh(fit32), fit_mesh(fit64)
    np.testing.assert_array_equal(mesh32.triangles, mesh64.triangles)
    np.testing.assert_allclose(mesh32.vertices, mesh64.vertices, rtol=0, atol=2e-6)


@pytest.mark.parametrize("with_xy", [False, True])
def test_blocks_give_the_whole_image_result(monkeypatch, with_xy):
    """Block passes (targets, level 0, refined cells, deviations, noise, jumps) change nothing but rounding."""
    z, p, q, mask = _scene(96)
    xy = None
    if with_xy:
        r, c = np.indices(z.shape)
        xy = np.stack([(c - 47.5) * 0.05 * (1 + 0.01 * r / 96), (47.5 - r) * 0.05], axis=-1)
    whole = fit_height(z, p, q, mask=mask, pixel_size=0.05, xy=xy, step=16)
    monkeypatch.setattr(F, "BLOCK_PIXELS", 300)  # many blocks, smaller than one row of level-0 cells
    blocked = fit_height(z, p, q, mask=mask, pixel_size=0.05, xy=xy, step=16)
    _same_fit(blocked, whole, atol=1e-12)
    np.testing.assert_array_equal(F.find_discontinuities(z, p, q, mask, 0.05, 0.01),
                                  _jumps_whole(z, p, q, mask, 0.05, 0.01))
    assert height_noise(z, mask, 4.0) == pytest.approx(_noise_whole(z, mask, 4.0), rel=1e-9)


def _jumps_whole(z, p, q, mask, h, jump):
    """The jump test on the whole image at once (its definition)."""
    zz = np.where(mask, z, 0.0)
    out = np.zeros(z.shape, bool)
    down = mask[:-1] & mask[1:] & (np.abs(zz[1:] - zz[:-1] + 0.5 * h * (q[1:] + q[:-1])) > jump)
    right = mask[:, :-1] & mask[:, 1:] & (np.abs(zz[:, 1:] - zz[:, :-1] - 0.5 * h * (p[:, 1:] + p[:, :-1])) > jump)
    out[:-1] |= down
    out[1:] |= down
    out[:, :-1] |= right
    out[:, 1:] |= right
    return out


def _noise_whole(z, m, scale):
    w = ndimage.gaussian_filter(m.astype(float), scale, mode="constant")
    smooth = ndimage.gaussian_filter(np.where(m, z, 0.0), scale, mode="constant")
    d = (z - smooth / np.maximum(w, 1e-12))[m & (w > 0.99)]
    return 1.4826 * np.median(np.abs(d - np.median(d)))


@pytest.mark.parametrize("sigma, spacing", [(0.0, 1.0), (0.7, 1.0), (0.7, 0.5), (1.3, 2.5), (0.7, 0.3)])
def test_lattice_field_is_the_interpolated_smoothed_mask(sigma, spacing):
    rng = np.random.default_rng(4)
    m = ndimage.binary_opening(rng.random((37, 52)) > 0.3)
    H, W = m.shape
    s = np.arange(-1, int(np.ceil((H - 1) / spacing)) + 2) * spacing
    t = np.arange(-1, int(np.ceil((W - 1) / spacing)) + 2) * spacing
    S, T = np.meshgrid(s, t, indexing="ij")
    field = ndimage.gaussian_filter(m.astype(float), sigma, mode="constant") if sigma else m * 1.0
    want = ndimage.map_coordinates(field, [S.ravel(), T.ravel()], order=1, mode="constant", cval=0.0)
    np.testing.assert_allclose(FM._lattice_field(m, sigma, s, t), want.reshape(S.shape), rtol=0, atol=1e-14)


def test_patch_map_on_coarse_units_is_the_lattice_map():
    z, p, q, mask = _scene(96)
    fit = fit_height(z, p, q, mask=mask, pixel_size=0.05, step=16, tolerance=0.002)
    patches = fit.patches
    assert min(fit.patch_sizes()) < 16
    rows, cols = patches.lattice_shape
    want = np.full((rows, cols), -1, np.int64)
    for k, (r, c, size) in enumerate(patches.cells):
        want[r:r + size, c:c + size] = k
    np.testing.assert_array_equal(patches.patch_map(), want)
    unit, coarse = patches._unit_map
    assert unit == min(fit.patch_sizes()) and coarse.dtype == np.int32
    rng = np.random.default_rng(0)
    r, c = rng.uniform(-1, rows + 1, 2000), rng.uniform(-1, cols + 1, 2000)
    r[:50], c[:50] = np.floor(r[:50]), np.floor(c[:50])  # seams
    patch, u, v = patches.locate_lattice(r, c)
    inside = (r >= 0) & (c >= 0) & (r <= rows) & (c <= cols)
    ir, ic = np.clip(np.floor(r).astype(int), 0, rows - 1), np.clip(np.floor(c).astype(int), 0, cols - 1)
    np.testing.assert_array_equal(patch, np.where(inside, want[ir, ic], -1))
    hit = patch >= 0
    assert hit.sum() > 1000
    cell = patches.cells[patch[hit]]
    np.testing.assert_allclose(u[hit], np.clip((r[hit] - cell[:, 0]) / cell[:, 2], 0, 1))
    np.testing.assert_allclose(v[hit], np.clip((c[hit] - cell[:, 1]) / cell[:, 2], 0, 1))


def test_mixed_patches_of_odd_corners_use_unit_squares():
    ctrl = np.zeros((2, 1, 4, 4, 3))
    m = MixedPatches(ctrl, cells=[[0, 0, 3], [0, 3, 2]])
    assert m._unit_map[0] == 1
    np.testing.assert_array_equal(m.patch_map(), [[0, 0, 0, 1, 1], [0, 0, 0, 1, 1], [0, 0, 0, -1, -1]])


def test_fit_of_a_float32_megapixel_holds_a_few_planes():
    """A hemisphere refined to one-pixel patches along its outline, float32 inputs: 12 bytes per pixel
    of fitted values and derivatives, 4 of deviations, one-byte masks, a few MB of blocks and what the
    refined cells need (384 bytes of control points per one-pixel patch); before issue 20 this fit
    peaked at 160 bytes per pixel."""
    n = 1024
    y, x = np.mgrid[-1:1:n * 1j, -1:1:n * 1j].astype(np.float32)
    r2 = x * x + y * y
    inside = r2 < 0.64
    z = np.where(inside, np.sqrt(np.clip(0.64 - r2, 0, None)), 0).astype(np.float32) * 400
    p = np.where(inside, -x / np.maximum(z / 400, 0.05), 0).astype(np.float32)
    q = np.where(inside, y / np.maximum(z / 400, 0.05), 0).astype(np.float32)
    del y, x, r2
    tracemalloc.start()
    try:
        fit = fit_height(z, p, q, mask=inside)
        held, peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        fit_mesh(fit, spacing=fit.step / 8)
        _, mesh_peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert min(fit.patch_sizes()) == 1
    assert peak / z.size < 80, peak / z.size
    # a vertex every 2 pixels (0.13 per pixel); the whole-image field is gone (112 bytes per pixel before)
    assert (mesh_peak - held) / z.size < 80, (mesh_peak - held) / z.size
