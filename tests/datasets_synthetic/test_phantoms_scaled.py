"""Ellipsoid and kidney: one outline scaled along z; areas against fine meshes, the kidney's fold."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms import make_phantom
from datasets_synthetic.phantoms.scaled import Ellipsoid, Kidney, ScaledSection
from slices.polygons import signed_area


def _parametric_area(points):
    """Area of a (U, V, 3) grid of surface points, as two triangles per cell."""
    a, b = points[:-1, :-1], points[1:, :-1]
    c, d = points[:-1, 1:], points[1:, 1:]
    return 0.5 * (np.linalg.norm(np.cross(b - a, c - a), axis=-1).sum()
                  + np.linalg.norm(np.cross(b - d, c - d), axis=-1).sum())


def _richardson(area_of, n):
    """Mesh area extrapolated from n and 2n subdivisions (triangle areas converge as h^2)."""
    coarse, fine = area_of(n), area_of(2 * n)
    return (4.0 * fine - coarse) / 3.0


@pytest.mark.parametrize("axes", [(30.0, 20.0, 25.0), (10.0, 10.0, 10.0), (20.0, 20.0, 8.0),
                                  (5.0, 12.0, 30.0)])
def test_ellipsoid_area_against_a_fine_mesh(axes):
    ph = make_phantom("ellipsoid", a=axes[0], b=axes[1], c=axes[2])

    def mesh_area(n):
        th, ph_ = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, 2 * n + 1),
                              indexing="ij")
        return _parametric_area(np.stack([axes[0] * np.sin(th) * np.cos(ph_),
                                          axes[1] * np.sin(th) * np.sin(ph_), axes[2] * np.cos(th)],
                                         axis=-1))

    assert ph.area_mm2 == pytest.approx(_richardson(mesh_area, 200), rel=1e-5)
    if len(set(axes)) == 1:
        assert ph.area_mm2 == pytest.approx(4 * np.pi * axes[0] ** 2, rel=1e-12)


def test_kidney_area_against_a_fine_mesh():
    ph = make_phantom("kidney")

    def mesh_area(n):
        outline = ph.outline(np.linspace(0.0, 1.0, 2 * n + 1))[0]
        theta = np.linspace(-np.pi / 2, np.pi / 2, n + 1)
        z = np.broadcast_to((ph.c * np.sin(theta))[:, None, None], (n + 1, 2 * n + 1, 1))
        return _parametric_area(np.concatenate([np.cos(theta)[:, None, None] * outline[None], z],
                                               axis=-1))

    assert ph.area_mm2 == pytest.approx(_richardson(mesh_area, 250), rel=1e-5)
    assert ph.area_accuracy_mm2 < 1e-6 * ph.area_mm2
    assert 2 * ph.c == 70.0


def test_kidney_sections_fold_about_their_centroid():
    ph = make_phantom("kidney")
    contour = ph.contours(5.0, n_points=400)[len(ph.plane_positions(5.0)) // 2]["points"]
    x, y = contour[:, 0], contour[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    centroid = np.array([np.sum((x + np.roll(x, -1)) * cross), np.sum((y + np.roll(y, -1)) * cross)])
    centroid /= 3.0 * cross.sum()
    np.testing.assert_allclose(centroid, ph.center[:2], atol=1e-3)
    assert signed_area(contour) == pytest.approx(ph.base_area_mm2, rel=1e-3)
    counts = []
    for ang in np.linspace(-np.pi, np.pi, 360, endpoint=False):
        d = np.array([np.cos(ang), np.sin(ang)])
        rel = contour - centroid
        side = rel @ [-d[1], d[0]]
        nxt = np.roll(side, -1)
        t = side / (side - nxt + 1e-300)
        hit = rel + (np.roll(rel, -1, axis=0) - rel) * t[:, None]
        counts.append(np.sum((np.sign(side) != np.sign(nxt)) & (hit @ d > 0)))
    counts = np.array(counts)
    assert set(counts) == {1, 3}
    assert (counts == 3).mean() > 0.15


@pytest.mark.parametrize("cls", [Ellipsoid, Kidney])
def test_sections_scale_with_the_middle_one(cls):
    ph = cls(center=(1.0, -2.0, 3.0))
    assert isinstance(ph, ScaledSection)
    z = 3.0 + ph.c * np.array([-1.0, -0.5, 0.0, 0.6, 1.0])
    np.testing.assert_allclose(ph.section_area_mm2(z), ph.base_area_mm2 * np.array([0, 0.75, 1, 0.64, 0]), atol=1e-9)
    assert ph.volume_mm3 == pytest.approx(ph.base_area_mm2 * 4 * ph.c / 3, rel=1e-15)
    assert ph.volume_between_mm3(3.0, 3.0 + ph.c) == pytest.approx(ph.volume_mm3 / 2, rel=1e-14)
    assert ph.z_range == (3.0 - ph.c, 3.0 + ph.c)
    # the outline at scale s encloses s^2 of the middle section
    outline = ph._curves(3.0 + 0.6 * ph.c)[0](np.arange(4000) / 4000)
    assert signed_area(outline) == pytest.approx(0.64 * ph.base_area_mm2, rel=1e-5)
    assert ph._curves(3.0 + ph.c) == []


def test_ellipsoid_closed_forms():
    ph = Ellipsoid(a=3.0, b=2.0, c=1.0)
    assert ph.volume_mm3 == pytest.approx(4 / 3 * np.pi * 6, rel=1e-15)
    assert ph.base_area_mm2 == pytest.approx(6 * np.pi, rel=1e-15)
    assert make_phantom("ellipsoid", a=5.0, b=5.0, c=5.0).area_mm2 == pytest.approx(100 * np.pi, rel=1e-12)
