"""Geometry the demo draws: the true height field as a mesh on the centred grid, contour lines."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surfaces.grid import pixel_grid
from workbench.demo.meshes import contour_segments, heightfield_mesh


def test_flat_field_orientation_area_and_centred_grid():
    """Counter-clockwise seen from +z, area of a flat field exact, origin at the image centre."""
    mesh = heightfield_mesh(np.zeros((5, 6)), 0.5)
    assert mesh.n_triangles == 2 * 4 * 5
    assert np.all(mesh.face_normals()[:, 2] > 0.99)
    assert mesh.surface_area() == pytest.approx(2.0 * 2.5)
    x, y = pixel_grid((5, 6), 0.5)
    assert mesh.vertices[:, 0].min() == pytest.approx(x.min())
    assert mesh.vertices[:, 0].max() == pytest.approx(x.max())
    assert mesh.vertices[:, 1].max() == pytest.approx(y.max())
    assert np.allclose(mesh.vertices[:, :2].mean(axis=0), 0.0)


def test_tilted_plane_is_exact_and_y_points_up():
    """A plane z = a x + b y on the centred grid (y up) is reproduced at every vertex."""
    x, y = pixel_grid((7, 9), 0.25)
    height = 0.3 * x - 0.2 * y + 1.0
    mesh = heightfield_mesh(height, 0.25)
    v = mesh.vertices
    np.testing.assert_allclose(v[:, 2], 0.3 * v[:, 0] - 0.2 * v[:, 1] + 1.0, atol=1e-12)
    # row 0 is the top: its height (y = +0.75) is the smallest for b < 0
    top = v[np.isclose(v[:, 1], y.max())]
    assert top[:, 2].mean() == pytest.approx(height[0].mean())
    n = mesh.face_normals()
    np.testing.assert_allclose(n, np.broadcast_to([-0.3, 0.2, 1.0] / np.linalg.norm([-0.3, 0.2, 1.0]),
                                                  n.shape), atol=1e-9)


def test_exaggeration():
    x, y = pixel_grid((9, 9), 1.0)
    height = 0.01 * (x**2 + y**2)
    plain = heightfield_mesh(height, 1.0)
    tall = heightfield_mesh(height, 1.0, exaggeration=10.0)
    np.testing.assert_allclose(tall.vertices[:, 2], 10.0 * plain.vertices[:, 2])
    np.testing.assert_allclose(tall.vertices[:, :2], plain.vertices[:, :2])
    np.testing.assert_allclose(np.sort(plain.vertices[:, 2]), np.sort(height.ravel()), atol=1e-12)


@pytest.mark.parametrize("kwargs, message", [
    ({"height": np.zeros(4)}, "height"),
    ({"height": np.zeros((1, 4))}, "height"),
    ({"height": np.full((3, 3), np.nan)}, "height"),
    ({"pixel_size": 0.0}, "pixel_size"),
    ({"exaggeration": -1.0}, "exaggeration"),
])
def test_bad_input_names_the_argument(kwargs, message):
    args = {"height": np.zeros((3, 3)), "pixel_size": 1.0, **kwargs}
    with pytest.raises(ValueError, match=message):
        heightfield_mesh(**args)


def test_contour_segments_close_each_contour(tmp_path):
    f = tmp_path / "contours.json"
    f.write_text(json.dumps({"contours": [
        {"z": 0.0, "points": [[0, 0], [2, 0], [2, 1], [0, 1]]},
        {"z": 2.5, "points": [[0, 0], [1, 0], [0, 1]]},
    ]}))
    segs = contour_segments(f)
    assert segs.shape == (7, 2, 3)
    # every segment's end is the next one's start within a contour, and each contour closes
    np.testing.assert_array_equal(segs[3], [[0, 1, 0], [0, 0, 0]])
    np.testing.assert_array_equal(segs[:3, 1], segs[1:4, 0])
    np.testing.assert_array_equal(segs[4:, :, 2], 2.5)
    lengths = np.linalg.norm(segs[:4, 1] - segs[:4, 0], axis=1)
    assert lengths.sum() == pytest.approx(6.0)


def test_contour_segments_empty_file(tmp_path):
    f = tmp_path / "contours.json"
    f.write_text('{"contours": []}')
    with pytest.raises(ValueError, match="no contours"):
        contour_segments(f)
