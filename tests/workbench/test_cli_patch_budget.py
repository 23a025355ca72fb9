"""``photometric reconstruct --max-patches``.

Moved from tests/photometric/test_patch_budget.py: the library's tests do not run the workbench.
"""

import json

import numpy as np

from tests.photometric.test_patch_budget import _lambertian


def test_cli_max_patches(tmp_path):
    from workbench.cli import main

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
