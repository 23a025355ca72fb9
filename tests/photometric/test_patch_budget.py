"""The fit's default patch budget through the pipeline and ``--max-patches`` on the command line (issue 33 item 9)."""

import json

import numpy as np

from photometric.pipeline import reconstruct
from photometric.stages import MIN_PATCH_BUDGET, patch_budget
from workbench.cli import main


def _lambertian(n=48):
    """A wavy surface (detail a cubic patch of 8 px cannot follow) lit from four directions; the closed-form
    normals give the images."""
    r, c = np.mgrid[0:n, 0:n].astype(float)
    # z = sin(c / 3) cos(r / 4) in pixel units: dz/dx along columns, dz/dy = -dz/dr (y up)
    p = np.cos(c / 3) * np.cos(r / 4) / 3
    q = np.sin(c / 3) * np.sin(r / 4) / 4
    nrm = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    s = np.radians(35.0)
    L = np.array([[np.sin(s) * np.cos(a), np.sin(s) * np.sin(a), np.cos(s)] for a in np.radians([0, 90, 180, 270])])
    return np.clip(0.8 * nrm @ L.T, 0, 1).transpose(2, 0, 1).astype(np.float32), L


def test_default_budget_without_a_mask_only():
    images, L = _lambertian()
    full = reconstruct(images, lights=L)
    assert full.summary["surface_max_patches"] == patch_budget(images.shape[1:]) == MIN_PATCH_BUDGET
    assert not full.summary["surface_budget_reached"]
    mask = np.zeros(images.shape[1:], bool)
    mask[4:-4, 4:-4] = True
    masked = reconstruct(images, lights=L, mask=mask)
    assert masked.summary["surface_max_patches"] is None
    assert patch_budget((2040, 2720)) == 2040 * 2720 // 256


def test_cli_max_patches(tmp_path):
    images, L = _lambertian()
    files = []
    for k, img in enumerate(images):
        files.append(str(tmp_path / f"im{k}.npy"))
        np.save(files[-1], img)
    np.savetxt(tmp_path / "lights.txt", L)
    base = ["photometric", "reconstruct", "--images", *files, "--lights", str(tmp_path / "lights.txt"), "--step", "8",
            "--surface-tolerance", "1e-6"]
    assert main([*base, "--out", str(tmp_path / "free")]) == 0
    free = json.loads((tmp_path / "free" / "summary.json").read_text())
    assert main([*base, "--max-patches", "40", "--out", str(tmp_path / "b")]) == 0
    budget = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert free["n_patches"] > 40 and not free["surface_budget_reached"]
    assert budget["surface_max_patches"] == 40 and budget["surface_budget_reached"]
    assert 36 <= budget["n_patches"] <= 40  # level 0 (6 x 6 cells) and one refined cell at most
    assert budget["surface_max_dev_mm"] > free["surface_max_dev_mm"]
