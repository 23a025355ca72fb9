"""The surface step of the photometric pipeline: the least-squares fit (default) and the Coons grid."""

import json

import numpy as np
import pytest

from datasets_synthetic.render import make_triad_folder
from photometric.pipeline import SURFACES, reconstruct
from scipy.spatial import cKDTree

from surfaces.grid import pixel_grid
from surfaces.mixed import MixedPatches


@pytest.fixture(scope="module")
def crack_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("crack")
    make_triad_folder(out, scene="crack", size=256, noise=0.0, shadows="none", deviate=None,
                      albedo=0.8, bit_depth=None, pixel_size=0.05, seed=0)
    return out


@pytest.fixture(scope="module")
def both(crack_folder):
    return {s: reconstruct(crack_folder, surface=s) for s in SURFACES}


def _depth(folder):
    return json.loads((folder / "scene.json").read_text())["defects"][0]["depth_mm"]


def test_fit_follows_the_height_better_than_the_coons_grid(both, crack_folder):
    fit, coons = both["fit"].summary, both["coons"].summary
    assert fit["surface"] == "fit" and coons["surface"] == "coons"
    for s in (fit, coons):
        assert s["surface_max_dev_mm"] >= s["surface_rms_dev_mm"] > 0 and s["n_patches"] > 0
    # the figure: within 2 % of the crack's depth (the Coons grid misses by 15 %)
    assert fit["surface_max_dev_mm"] < 0.02 * _depth(crack_folder)
    assert fit["surface_max_dev_mm"] < 0.2 * coons["surface_max_dev_mm"]
    assert isinstance(both["fit"].patches, MixedPatches)
    sizes = {int(k): v for k, v in fit["surface_patch_sizes_px"].items()}
    assert sum(sizes.values()) == fit["n_patches"] and len(sizes) > 1
    assert max(sizes) == 4 and sizes[4] > sizes[1]  # large patches on the flat plate
    assert "surface_tolerance_mm" not in coons
    json.dumps(fit)  # JSON-ready


def test_fit_mesh_is_on_the_centred_grid_and_follows_the_height(both):
    res = both["fit"]
    x, y = pixel_grid(res.height.shape, 0.05)
    tree = cKDTree(res.mesh.vertices[:, :2])
    dist, nearest = tree.query(np.stack([x.ravel(), y.ravel()], axis=1))
    assert dist.max() < 1e-9  # the default mesh lattice puts a vertex on every pixel centre
    dz = np.abs(res.mesh.vertices[nearest, 2] - res.height.ravel())
    assert dz.max() <= res.summary["surface_max_dev_mm"] + 1e-12


def _normal_error_p99(res):
    """99th percentile of the angle (deg) between the nearest mesh vertex's normal and the solved normal."""
    x, y = pixel_grid(res.height.shape, 0.05)
    _, nearest = cKDTree(res.mesh.vertices[:, :2]).query(np.stack([x.ravel(), y.ravel()], axis=1))
    cos = np.clip((res.mesh.vertex_normals[nearest] * res.normals.reshape(-1, 3)).sum(axis=1), -1, 1)
    return np.percentile(np.degrees(np.arccos(cos)), 99)


def test_fit_normals_follow_the_measured_normals(both):
    fit, coons = _normal_error_p99(both["fit"]), _normal_error_p99(both["coons"])
    assert fit < 4.0 and fit < 0.5 * coons


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"surface": "nurbs"}, "surface: expected one of"),
        ({"surface_tolerance": 0.0}, "surface_tolerance"),
        ({"surface_tolerance": -1.0}, "surface_tolerance"),
        ({"step": 0}, "step"),
    ],
)
def test_bad_surface_options(crack_folder, kwargs, message):
    with pytest.raises(ValueError, match=message):
        reconstruct(crack_folder, **kwargs)
