"""photometric.pipeline.reconstruct: input to measured surface, returned (no files written)."""

import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.io import read_folder
from datasets_synthetic.truth import height_errors, read_truth
from photometric.pipeline import PhotometricReconstruction, reconstruct
from surfaces.grid import pixel_grid, xy_to_pixel


@pytest.fixture(scope="module")
def plate_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("plate")
    make_triad_folder(out, scene="plate", size=128, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    return out


def test_reconstruct_folder_returns_everything(plate_folder, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = sorted(plate_folder.iterdir())
    res = reconstruct(plate_folder, integrator="dct")
    assert isinstance(res, PhotometricReconstruction)
    assert list(tmp_path.iterdir()) == [] and sorted(plate_folder.iterdir()) == before  # writes nothing
    assert res.normals.shape == (128, 128, 3) and res.normals.dtype == np.float32
    assert np.allclose(np.linalg.norm(res.normals, axis=2), 1, atol=1e-5)
    assert res.valid.dtype == bool and res.mask.all() and res.height.shape == (128, 128)
    summary = res.summary
    assert summary["pixel_size_mm"] == 0.2 and summary["pixel_size_source"] == "scene.json"
    # 16-bit quantisation only: normals within a few hundredths of a degree
    assert summary["mean_angular_error_deg"] < 0.05
    # the ground truth's height is compared outside the library (the synthetic side)
    assert "height_rmse_mm" not in summary
    errors = height_errors(res.height, res.valid, read_truth(plate_folder))
    assert errors["height_rmse_mm"] < 0.01 * summary["height_range_mm"]
    assert summary["invalid_fraction"] == 0.0
    assert summary["light_condition_number"] == pytest.approx(np.sqrt(2), rel=1e-6)
    assert set(summary["timings_s"]) == {"read", "solve", "integrate", "surface", "defects", "total"}
    assert "files" not in summary
    assert len(res.defects) == summary["n_defects"] == 3
    assert summary["mesh"] == {"vertices": res.mesh.n_vertices, "triangles": res.mesh.n_triangles}
    assert list(res.patches.shape) == summary["patches"]


def test_reconstruct_images_and_lights_arrays(tmp_path):
    data_dir = tmp_path / "d"
    make_triad_folder(data_dir, scene="sphere", size=64, noise=0.0, shadows="none", deviate=None,
                      albedo=0.7, bit_depth=None, seed=0)
    data = read_folder(data_dir)
    res = reconstruct(data.images, lights=data.lights, pixel_size=0.5, integrator="lsq", step=8, samples=2,
                      surface="coons")
    summary = res.summary
    assert summary["size"] == {"height": 64, "width": 64, "images": 3, "channels": 1}
    assert summary["patches"] == [8, 8] and summary["pixel_size_source"] == "option"
    assert summary["input"] == {"kind": "array"}
    assert res.height.shape == (64, 64)
    assert "mean_angular_error_deg" not in summary  # no ground truth with an array


def test_mesh_lies_on_the_centred_pixel_grid(tmp_path):
    """A mesh vertex over a pixel centre has that pixel's x, y (surfaces.grid) and height."""
    make_triad_folder(tmp_path, scene="sphere", size=65, noise=0.0, shadows="none", deviate=None,
                      albedo=1.0, bit_depth=None, pixel_size=0.1)
    res = reconstruct(tmp_path, step=8, samples=4, surface="coons")
    x, y = pixel_grid((65, 65), 0.1)
    v = res.mesh.vertices
    for row, col in ((0, 0), (8, 16), (32, 32), (64, 40)):
        hit = np.flatnonzero((np.abs(v[:, 0] - x[row, col]) < 1e-9) & (np.abs(v[:, 1] - y[row, col]) < 1e-9))
        assert hit.size == 1, (row, col)
        assert v[hit[0], 2] == pytest.approx(res.height[row, col], abs=1e-9)
    # the image centre is the origin
    assert np.allclose(v[:, :2].min(axis=0), [-3.2, -3.2]) and np.allclose(v[:, :2].max(axis=0), [3.2, 3.2])


def test_mesh_is_trimmed_to_the_mask(tmp_path):
    make_triad_folder(tmp_path, scene="sphere", size=64, noise=0.0, shadows="none", deviate=None,
                      albedo=1.0, bit_depth=None, pixel_size=0.1)
    mask = np.zeros((64, 64), bool)
    mask[10:40, 20:60] = True  # off centre: a top-left origin would trim the wrong place
    res = reconstruct(tmp_path, mask=mask, step=4, samples=4)
    centroid = res.mesh.vertices[res.mesh.triangles].mean(axis=1)
    row, col = xy_to_pixel(centroid[:, 0], centroid[:, 1], (64, 64), 0.1)
    inside = mask[np.clip(np.rint(row), 0, 63).astype(int), np.clip(np.rint(col), 0, 63).astype(int)]
    assert inside.all()
    # and the kept triangles cover the valid pixels of the mask (black pixels at the sphere's
    # shadowed rim are invalid): about 2 triangles per pixel
    assert (res.valid & mask).sum() < mask.sum()
    assert res.mesh.n_triangles == pytest.approx(2 * (res.valid & mask).sum(), rel=0.1)


def test_options_are_checked_before_any_file_is_read():
    with pytest.raises(ValueError, match="dark"):
        reconstruct("/definitely/not/here", dark=-1.0)
    with pytest.raises(ValueError, match="integrator"):
        reconstruct("/definitely/not/here", integrator="magic")
    with pytest.raises(NotADirectoryError, match="input"):
        reconstruct("/definitely/not/here")
    with pytest.raises(ValueError, match="lights"):
        reconstruct(np.ones((3, 4, 4), np.float32))
