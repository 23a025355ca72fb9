"""The fitted surface of a perspective near-field rig lies at the back-projected points.

A perspective camera sees pixel (row, col) at the point where its ray meets the part,
not at the orthographic grid position: :func:`photometric.pipeline.reconstruct` passes
those points (``xy``) to :func:`surfaces.fit.fit_height`, which fits x and y with z.
"""

import numpy as np
import pytest

from datasets_synthetic.nearfield import make_near_field_folder
from photometric.pipeline import reconstruct
from surfaces.grid import pixel_grid


@pytest.fixture(scope="module")
def perspective_plate(tmp_path_factory):
    out = tmp_path_factory.mktemp("persp_plate")
    # a short lens close to the part: x and y of the seen points leave the reference grid
    # by up to x z / camera_height, well above the tolerance below
    make_near_field_folder(out, "plate", 96, lights=4, light_distance=150.0, led_mu=1.0, camera="perspective",
                           focal_length_px=160.0, camera_height=80.0, noise=0.0, bit_depth=None, shadows="attached",
                           albedo=0.8, seed=1)
    return reconstruct(out, flat_field=False)


def _surface_at_pixels(patches, shape):
    """Surface points at the pixel centres (the fit's lattice unit is one pixel)."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    pi, u, v = patches.locate_lattice(rows.ravel() + 0.5, cols.ravel() + 0.5)
    on = pi >= 0
    pts = np.full((rows.size, 3), np.nan)
    pts[on] = patches.evaluate(pi[on], 0, u[on], v[on])
    return pts.reshape(*shape, 3)


def test_fitted_vertices_at_back_projected_points(perspective_plate):
    res = perspective_plate
    assert res.summary["camera"]["model"] == "perspective"
    assert res.xy is not None
    shape = res.height.shape
    pts = _surface_at_pixels(res.patches, shape)
    inner = res.valid.copy()
    inner[:3], inner[-3:], inner[:, :3], inner[:, -3:] = False, False, False, False
    use = inner & np.isfinite(pts[..., 0])
    assert use.sum() > 0.8 * inner.sum()
    seen = np.concatenate([res.xy, res.height[..., None]], axis=-1)
    err = np.linalg.norm(pts - seen, axis=-1)[use]
    tol = res.summary["surface_tolerance_mm"]
    # the fit's own deviation is this 3-D distance; on the plate it stays within the tolerance
    # except on the crack walls (2 % of this small plate), where the refinement stops at one pixel
    assert err.max() <= res.summary["surface_max_dev_mm"] * (1 + 1e-9) + 1e-12
    assert np.median(err) < 0.01 * tol and np.mean(err > tol) < 0.03
    assert np.linalg.norm(pts[..., :2] - res.xy, axis=-1)[use].max() < 2 * tol
    # the orthographic grid would be off by far more: the test can fail
    x, y = pixel_grid(shape, res.summary["pixel_size_mm"])
    grid_err = np.hypot(x - res.xy[..., 0], y - res.xy[..., 1])[use]
    assert grid_err.max() > 4 * tol and np.median(grid_err) > 20 * np.median(err)
    # mesh vertices lie on the same surface: each is within the tolerance of a seen point
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(seen[res.valid]).query(res.mesh.vertices)
    assert np.median(dist) < res.summary["pixel_size_mm"]
