"""The fit's default patch budget through the pipeline and ``--max-patches`` on the command line (issue 33 item 9)."""


import numpy as np

from photometric.pipeline import reconstruct
from photometric.stages import MIN_PATCH_BUDGET, patch_budget


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
