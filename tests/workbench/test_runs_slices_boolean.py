"""Set operations (surfaces.boolean) on ROIs that ``workbench.runs.slices`` reconstructs from a real RTSTRUCT.

Moved from tests/surfaces/test_boolean.py: the library's tests do not run the workbench.
"""

from __future__ import annotations

import pytest

from surfaces import boolean as bl
from tests.surfaces.test_boolean import all_ops, assert_identities


def test_reconstructed_tumour_bed_inside_its_block(shared_data, tmp_path):
    """Real RTSTRUCT (breast plan): the tumour bed and the block drawn around it, reconstructed."""
    from workbench.runs.slices import reconstruct_to_folder as reconstruct
    from surfaces.io import read_mesh

    rtss = shared_data / "rtstruct_breast" / "rtss.dcm"
    meshes = {}
    for roi in ("Tumor Bed", "Tumor Bed Block"):
        out = tmp_path / roi.replace(" ", "_")
        reconstruct(rtss, out, roi=roi, render=False, reference=False, samples=2)
        meshes[roi] = read_mesh(out / "surface.ply")
    bed, block = meshes["Tumor Bed"], meshes["Tumor Bed Block"]
    res = all_ops(block, bed)
    assert_identities(res)
    # the block is drawn around the bed: nearly all of the bed lies inside it
    assert res["intersection"].volume > 0.99 * res["union"].volume_b
    mesh, summary = bl.compose(block, minus=[bed], names={"base": "Tumor Bed Block", "minus": ["Tumor Bed"]})
    assert summary["volume"] == pytest.approx(res["difference"].volume, rel=1e-9)
    assert summary["removed_volume"] == pytest.approx(res["intersection"].volume, rel=1e-9)
    # the bed pokes through the block's wall in one place: one closed intersection curve
    assert res["difference"].curves_closed == (True,)
