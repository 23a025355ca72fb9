"""workbench.runs.photometric: the photometric pipeline's result written into a folder."""

import inspect
import json

import cv2
import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.camera import make_camera
from photometric.nearfield import NotConvergedError
from photometric.pipeline import reconstruct
from photometric.rig import read_rig
from surfaces.grid import pixel_grid
from surfaces.io import read_mesh
from workbench.runs.folder import COMPLETE_MARKER
from workbench.runs.photometric import (
    FILES,
    NEARFIELD_FILES,
    calibrate_to_rig,
    reconstruct_to_folder,
    write_result,
    write_rig,
)


@pytest.fixture(scope="module")
def plate_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("plate")
    make_triad_folder(out, scene="plate", size=128, noise=0.0, shadows="attached", deviate=None,
                      albedo=0.8, pixel_size=0.2, seed=1)
    return out


def test_reconstruct_folder_writes_everything(plate_folder, tmp_path):
    stages = []
    summary = reconstruct_to_folder(plate_folder, tmp_path / "out", integrator="dct", progress=stages.append)
    assert stages == ["read", "normals", "height", "surface", "defects", "write"]
    out = tmp_path / "out"
    assert sorted(p.name for p in out.iterdir()) == sorted((*FILES, COMPLETE_MARKER))
    assert summary["files"] == sorted(FILES)
    normals = np.load(out / "normals.npy")
    assert normals.shape == (128, 128, 3) and normals.dtype == np.float32
    assert np.allclose(np.linalg.norm(normals, axis=2), 1, atol=1e-5)
    assert np.load(out / "valid.npy").dtype == bool
    assert summary == json.loads((out / "summary.json").read_text())
    assert summary["pixel_size_mm"] == 0.2 and summary["pixel_size_source"] == "scene.json"
    assert summary["mean_angular_error_deg"] < 0.05
    assert list(summary["timings_s"]) == ["read", "solve", "integrate", "surface", "defects", "write", "total"]
    assert summary["timings_s"]["total"] >= summary["timings_s"]["write"] >= 0
    defects = json.loads((out / "defects.json").read_text())
    assert defects["units"] == "mm" and len(defects["defects"]) == summary["n_defects"] == 3
    assert defects["pixel_size_mm"] == 0.2 and defects["background"] == "plane"


def test_files_hold_the_library_result(plate_folder, tmp_path):
    res = reconstruct(plate_folder, step=16)
    summary = write_result(res, tmp_path)
    for name in ("normals", "albedo", "p", "q", "valid", "height"):
        np.testing.assert_array_equal(np.load(tmp_path / f"{name}.npy"), getattr(res, name))
    same = {k: v for k, v in res.summary.items() if k != "timings_s"}
    assert {k: v for k, v in summary.items() if k not in ("timings_s", "files")} == json.loads(json.dumps(same))
    mesh = read_mesh(tmp_path / "surface.ply")
    np.testing.assert_allclose(mesh.vertices, res.mesh.vertices, atol=1e-5)


def test_surface_ply_is_on_the_centred_pixel_grid(tmp_path):
    """A vertex of surface.ply over a pixel centre (a patch corner) has that pixel's x and y."""
    make_triad_folder(tmp_path / "in", scene="sphere", size=65, noise=0.0, shadows="none", deviate=None,
                      albedo=1.0, bit_depth=None, pixel_size=0.1)
    reconstruct_to_folder(tmp_path / "in", tmp_path / "out", step=8, samples=8, surface="coons")
    v = read_mesh(tmp_path / "out" / "surface.ply").vertices
    height = np.load(tmp_path / "out" / "height.npy")
    x, y = pixel_grid((65, 65), 0.1)
    for row, col in ((0, 64), (16, 8), (40, 48)):
        d = np.hypot(v[:, 0] - x[row, col], v[:, 1] - y[row, col])
        assert d.min() < 1e-5, (row, col)
        assert v[np.argmin(d), 2] == pytest.approx(height[row, col], abs=1e-5)


def test_previews_readable(plate_folder, tmp_path):
    reconstruct_to_folder(plate_folder, tmp_path / "p", step=16)
    for name in ("normals.png", "albedo.png", "height.png"):
        img = cv2.imread(str(tmp_path / "p" / name), cv2.IMREAD_UNCHANGED)
        assert img is not None and img.shape[:2] == (128, 128) and img.dtype == np.uint8
    normals = cv2.imread(str(tmp_path / "p" / "normals.png"))[..., ::-1].astype(float)
    # a flat plate faces the camera: blue (z) near 255, red/green near the middle
    assert np.median(normals[..., 2]) > 250 and abs(np.median(normals[..., 0]) - 127.5) < 2
    albedo = cv2.imread(str(tmp_path / "p" / "albedo.png"))
    assert np.percentile(albedo, 50) > 200  # constant albedo 0.8, stretched to its percentile


def test_signature_lists_the_library_options():
    """Batch manifests check option names against this signature."""
    params = list(inspect.signature(reconstruct_to_folder).parameters)
    assert params[:2] == ["source", "out_dir"]
    # out: the streamed normals and albedo, which reconstruct_to_folder passes itself
    # and the run's own texture (photometric reconstruct --texture)
    assert set(params[2:]) == set(inspect.signature(reconstruct).parameters) - {"source", "out"} | {"texture"}
    with pytest.raises(TypeError):
        reconstruct_to_folder("x", "y", no_such_option=1)


def test_out_dir_that_is_a_file(plate_folder, tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="out_dir"):
        reconstruct_to_folder(plate_folder, tmp_path / "f")


# ----------------------------------------------------------------------------- near-field


def _near_plane_images(shape=(40, 48), ps=0.5):
    """Closed-form images of the plane z = 0 under three isotropic LEDs 150 mm away (0.5 mm pixels)."""
    a = np.radians([90.0, 210.0, 330.0])
    pos = 150.0 * np.stack([np.sin(np.pi / 4) * np.cos(a), np.sin(np.pi / 4) * np.sin(a),
                            np.full(3, np.cos(np.pi / 4))], axis=1)
    x, y = pixel_grid(shape, ps)
    X = np.stack([x, y, np.zeros(shape)], axis=-1)
    images = []
    for P in pos:
        d = P - X
        r = np.linalg.norm(d, axis=-1)
        images.append(0.7 * (150.0 / r) ** 2 * d[..., 2] / r)
    return np.array(images, np.float32), pos, X


def test_near_field_folder_has_xy(tmp_path):
    images, pos, X = _near_plane_images()
    summary = reconstruct_to_folder(images, tmp_path / "o", light_positions=pos, pixel_size=0.5)
    out = tmp_path / "o"
    assert sorted(p.name for p in out.iterdir() if p.name != COMPLETE_MARKER) == sorted(NEARFIELD_FILES)
    assert sorted(NEARFIELD_FILES) == summary["files"] and (out / COMPLETE_MARKER).is_file()
    xy = np.load(out / "xy.npy")
    assert xy.shape == (40, 48, 2) and xy.dtype == np.float64
    np.testing.assert_allclose(xy, X[..., :2])
    np.testing.assert_allclose(np.load(out / "height.npy"), 0.0, atol=1e-4)
    assert summary["light_model"] == "point" and summary["converged"] is True


def test_near_field_no_convergence_writes_only_the_summary(tmp_path):
    images, pos, _ = _near_plane_images()
    images[:, :, :20] *= 1.3  # inconsistent shading: the height keeps changing
    with pytest.raises(NotConvergedError, match="nothing else written") as info:
        reconstruct_to_folder(images, tmp_path / "o", light_positions=pos, pixel_size=0.5, max_iterations=1,
                              tolerance_mm=1e-9)
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == sorted(["summary.json", COMPLETE_MARKER])
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary == json.loads(json.dumps({**info.value.summary, "files": ["summary.json"]}))
    assert summary["converged"] is False and summary["size"]["images"] == 3


def test_write_rig_and_calibrate_to_rig(tmp_path):
    images, pos, X = _near_plane_images()
    np.savetxt(tmp_path / "P.txt", pos)
    flats = []
    for k, img in enumerate(images):
        flats.append(tmp_path / f"flat{k}.npy")
        np.save(flats[-1], img / 0.7 * 0.5)  # the same plane as a target of albedo 0.5
    doc = calibrate_to_rig(tmp_path / "cal" / "my_rig.json", light_positions=tmp_path / "P.txt",
                           camera=make_camera("orthographic", pixel_size_mm=0.5), flat_field=flats,
                           flat_albedo=0.5)
    assert doc["flat_field"]["gains"] == "my_rig_gains.npz"
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == ["my_rig.json", "my_rig_gains.npz"]
    rig = read_rig(tmp_path / "cal" / "my_rig.json")
    assert rig.image_size == (40, 48) and rig.gains.shape == (3, 40, 48)
    res = reconstruct(images, rig=tmp_path / "cal" / "my_rig.json")
    np.testing.assert_allclose(res.albedo[3:-3, 3:-3], 0.7, rtol=2e-3)
    again = write_rig(rig, tmp_path / "again.json")
    assert again == json.loads((tmp_path / "again.json").read_text())
    with pytest.raises(IsADirectoryError, match="rig.json file name"):
        write_rig(rig, tmp_path / "cal")


def test_reconstruct_folder_with_uncertainty_writes_its_files(plate_folder, tmp_path):
    from photometric.uncertainty import Tolerances
    from workbench.runs.photometric import UNCERTAINTY_FILES

    stages = []
    summary = reconstruct_to_folder(plate_folder, tmp_path / "out", progress=stages.append,
                                    uncertainty=Tolerances(light_tolerance_deg=0.5, noise_sigma=0.001))
    assert stages == ["read", "normals", "height", "surface", "defects", "uncertainty", "write"]
    out = tmp_path / "out"
    written = sorted(p.name for p in out.iterdir() if p.name != COMPLETE_MARKER)
    assert written == sorted(FILES + UNCERTAINTY_FILES) == summary["files"]
    assert np.load(out / "p_u.npy").dtype == np.float32
    defects = json.loads((out / "defects.json").read_text())["defects"]
    budget = json.loads((out / "uncertainty.json").read_text())
    assert [d["id"] for d in budget["defects"]] == [d["id"] for d in defects]
    assert all(d["uncertainty_k2"]["max_depth_mm"] > 0 for d in defects)
    assert summary["timings_s"]["uncertainty"] >= 0
