"""Fixtures shared by the tests of ``surfaces``."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest


@pytest.fixture(scope="module")
def sphere():
    """Unit sphere at the origin as ``(vertices, triangles)``, about 20k triangles."""
    mesh = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=100)
    verts = np.asarray(mesh.vertices)
    return verts, np.asarray(mesh.triangles)
