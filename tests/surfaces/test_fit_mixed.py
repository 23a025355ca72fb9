"""surfaces.mixed: patches of mixed sizes from a fit, tessellated without cracks, stored and measured."""

import numpy as np
import pytest

from datasets_synthetic.heightfields import v_crack
from surfaces.fit import fit_height
from surfaces.io import load_patches, save_patches
from surfaces.measure import area
from surfaces.mesh import tessellate
from surfaces.mixed import MixedPatches


@pytest.fixture(scope="module")
def crack_fit():
    hf = v_crack(64, 0.05, depth_mm=0.2, width_mm=0.8, length_mm=1.6, axis_deg=20.0)
    fit = fit_height(hf.height, hf.p, hf.q, pixel_size=0.05, step=8)
    assert len(fit.patch_sizes()) >= 3  # T-junctions between 8, 4, 2 and 1 px patches
    return fit


@pytest.mark.parametrize("samples", [1, 2, 4])
def test_tessellation_is_crack_free_at_t_junctions(crack_fit, samples):
    mesh = tessellate(crack_fit.patches, samples=samples)
    _, counts = mesh.edge_counts()
    assert counts.max() == 2 and mesh.is_oriented()
    # the only boundary is the outer rectangle, the pixel edges half a pixel beyond the centres
    v = mesh.vertices[np.unique(mesh.boundary_edges())]
    on_rim = np.isclose(np.abs(v[:, 0]), 1.6) | np.isclose(np.abs(v[:, 1]), 1.6)
    assert on_rim.all()
    assert (mesh.face_normals()[:, 2] > 0).all()
    # every vertex is on the surface: the patch values at the lattice points
    assert np.isfinite(mesh.vertices).all() and np.isfinite(mesh.vertex_normals).all()


def test_tessellated_area_converges_to_the_patch_area(crack_fit):
    exact = area(crack_fit.patches)
    coarse = tessellate(crack_fit.patches, samples=1).surface_area()
    fine = tessellate(crack_fit.patches, samples=4).surface_area()
    assert coarse <= fine <= exact * (1 + 1e-12)  # inscribed meshes underestimate
    assert abs(fine - exact) < abs(coarse - exact)
    assert exact > 3.2 * 3.2  # the crack's walls add area to the flat square


def test_save_and_load_keep_the_lattice(tmp_path, crack_fit):
    path = save_patches(crack_fit.patches, tmp_path / "p.npz")
    back = load_patches(path)
    assert isinstance(back, MixedPatches)
    np.testing.assert_array_equal(back.cells, crack_fit.patches.cells)
    np.testing.assert_array_equal(back.control, crack_fit.patches.control)


def test_flipped_and_transformed_stay_on_the_lattice(crack_fit):
    patches = crack_fit.patches
    flipped = patches.flipped()
    assert isinstance(flipped, MixedPatches)
    assert (tessellate(flipped, samples=2).face_normals()[:, 2] < 0).all()
    moved = patches.transformed(offset=[1.0, 2.0, 3.0])
    np.testing.assert_array_equal(moved.cells, patches.cells)
    np.testing.assert_allclose(moved.control - patches.control, np.broadcast_to([1.0, 2.0, 3.0], patches.control.shape))


def test_bad_cells_are_a_clear_error():
    control = np.zeros((2, 1, 4, 4, 3))
    with pytest.raises(ValueError, match="cells: required"):
        MixedPatches(control)
    with pytest.raises(ValueError, match="cells: expected integers of shape"):
        MixedPatches(control, cells=[[0, 0, 1]])
    with pytest.raises(ValueError, match="sizes >= 1"):
        MixedPatches(control, cells=[[0, 0, 1], [0, 1, 0]])
    with pytest.raises(ValueError, match="open sheet"):
        MixedPatches(control, closed_u=True, cells=[[0, 0, 1], [0, 1, 1]])
    with pytest.raises(ValueError, match="control"):
        MixedPatches(np.zeros((1, 2, 4, 4, 3)), cells=[[0, 0, 1]])


def test_global_parameters_are_lattice_coordinates(crack_fit):
    """evaluate_global on the flat patch list reads the lattice, as the grid form reads its patch grid."""
    patches = crack_fit.patches
    # lattice (row + 0.5, col + 0.5) is the centre of pixel (row, col)
    centres = patches.evaluate_global(np.arange(64) + 0.5, np.arange(64) + 0.5)
    np.testing.assert_allclose(centres, crack_fit.surface[np.arange(64), np.arange(64)], atol=1e-12)
    with pytest.raises(ValueError, match="no patch covers"):
        patches.evaluate_global([70.0], [3.0])
