"""``surface="none"`` (``--surface none``): a normals-and-height run without the surface model (issue 33 item 9)."""

import json

import numpy as np
import pytest

from photometric.options import PhotometricOptions
from photometric.pipeline import reconstruct
from photometric.stages import patch_budget
from workbench.cli import main


def _lambertian(n=48):
    """A paraboloid cap lit from four directions (the closed-form normals give the images)."""
    y, x = np.mgrid[0:n, 0:n] - (n - 1) / 2.0
    z = -0.01 * (x**2 + y**2)
    p, q = -0.02 * x, 0.02 * y  # dz/dx, dz/dy (y up: rows down)
    nrm = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    s = np.radians(35.0)
    L = np.array([[np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.cos(s)] for a in np.radians([0, 90, 180, 270])])
    return np.clip(0.8 * nrm @ L.T, 0, 1).transpose(2, 0, 1).astype(np.float32), L, z


def test_none_skips_the_surface_and_keeps_the_height():
    images, L, _ = _lambertian()
    full = reconstruct(images, lights=L)
    bare = reconstruct(images, lights=L, surface="none")
    assert bare.patches is None and bare.mesh is None
    assert bare.summary["surface"] == "none" and bare.summary["n_patches"] == 0 and "mesh" not in bare.summary
    np.testing.assert_allclose(bare.height, full.height, atol=1e-5)  # float32 sums in another order
    np.testing.assert_allclose(bare.normals, full.normals, atol=1e-6)
    assert full.summary["surface_max_patches"] == patch_budget(images.shape[1:]) and \
        not full.summary["surface_budget_reached"]
    with pytest.raises(ValueError, match="surface"):
        PhotometricOptions(surface="nurbs")


def test_cli_surface_none_writes_no_mesh(tmp_path, capsys):
    images, L, _ = _lambertian()
    files = []
    for k, img in enumerate(images):
        files.append(str(tmp_path / f"im{k}.npy"))
        np.save(files[-1], img)
    np.savetxt(tmp_path / "lights.txt", L)
    out = tmp_path / "out"
    assert main(["photometric", "reconstruct", "--images", *files, "--lights", str(tmp_path / "lights.txt"),
                 "--surface", "none", "--out", str(out)]) == 0
    assert "no surface model" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert not (out / "surface.ply").exists() and "surface.ply" not in summary["files"]
    assert (out / "height.npy").is_file() and summary["surface"] == "none"
    assert main(["photometric", "reconstruct", "--images", *files, "--lights", str(tmp_path / "lights.txt"),
                 "--max-patches", "20", "--step", "8", "--out", str(tmp_path / "b")]) == 0
    budget = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert budget["surface_max_patches"] == 20 and budget["n_patches"] <= 36  # level 0 (6 x 6 cells) stays
