"""``slices.pipeline.reconstruct`` on every phantom shape of ``datasets_synthetic`` at 1, 2.5 and 5 mm."""

from __future__ import annotations

import pytest

from datasets_synthetic.phantoms import SHAPES, make_phantom
from slices.pipeline import reconstruct
from surfaces.io import write_json


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("spacing", [1.0, 2.5, 5.0])
def test_reconstruct_every_phantom(shape, spacing, tmp_path):
    ph = make_phantom(shape)
    path = write_json(tmp_path / "contours.json", {"units": "mm", "contours": ph.contours(spacing, n_points=48)})
    result = reconstruct(path, surface_path="coons", caps="flat", n_rays=32, samples=1, reference=False)
    summary = result.summary
    truth = ph.truth(spacing)
    assert summary["n_slices"] == truth["n_planes"]
    assert summary["max_control_point_deviation_mm"] < 1e-6
    assert summary["mesh_watertight"] and summary["mesh_oriented"]
    exact = truth["volume_between_end_planes_mm3"]
    assert summary["volume_mm3"] == pytest.approx(exact, rel=3e-2)
    mesh = result.mesh
    assert mesh.is_watertight() and mesh.is_oriented() and mesh.signed_volume() > 0
