"""Every emitted phantom contour is a simple polygon with the exact section area; sliver planes are skipped."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms import MIN_SECTION_FRACTION, SHAPES, make_phantom
from slices.polygons import signed_area


def _orient(p, q, r):
    d = (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
    scale = np.abs(q - p).max() * np.abs(r - p).max() + 1e-300
    return np.where(np.abs(d) <= 1e-12 * scale, 0.0, np.sign(d))


def _segments_cross(points: np.ndarray) -> int:
    """Pairs of non-adjacent edges of a closed polygon that cross, or overlap on a common line (retrace)."""
    a = points
    b = np.roll(points, -1, axis=0)
    n = len(a)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))
    i, j = i[keep], j[keep]
    o1, o2 = _orient(a[i], b[i], a[j]), _orient(a[i], b[i], b[j])
    o3, o4 = _orient(a[j], b[j], a[i]), _orient(a[j], b[j], b[i])
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    # collinear pairs: retracing when their projections on edge i overlap
    d = b[i] - a[i]
    length2 = np.einsum("ij,ij->i", d, d)
    t0 = np.einsum("ij,ij->i", a[j] - a[i], d) / length2
    t1 = np.einsum("ij,ij->i", b[j] - a[i], d) / length2
    overlap = (np.minimum(np.maximum(t0, t1), 1.0) - np.maximum(np.minimum(t0, t1), 0.0)) > 1e-9
    collinear = (o1 == 0) & (o2 == 0) & overlap
    return int(np.count_nonzero(proper | collinear))


def _inside(point: np.ndarray, polygon: np.ndarray) -> bool:
    """Even-odd point-in-polygon test."""
    x, y = point
    a, b = polygon, np.roll(polygon, -1, axis=0)
    straddle = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(straddle & (xc > x)) % 2)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("spacing", [1.0, 2.5, 5.0])
def test_contours_are_simple_with_exact_areas(shape, spacing):
    ph = make_phantom(shape)
    contours = ph.contours(spacing, n_points=96)
    truth = ph.truth(spacing)
    assert sorted({c["z"] for c in contours}) == pytest.approx(truth["planes_mm"])
    for c in contours:
        assert _segments_cross(c["points"]) == 0, f"{shape} z={c['z']}: contour crosses or retraces itself"
    # holes (contours inside another contour of the plane) are subtracted
    per_plane: dict = {}
    for c in contours:
        others = [o["points"] for o in contours if o["z"] == c["z"] and o is not c]
        depth = sum(_inside(c["points"][0], o) for o in others)
        per_plane[c["z"]] = per_plane.get(c["z"], 0.0) + (-1) ** depth * abs(signed_area(c["points"]))
    z = np.array(sorted(per_plane))
    exact = ph.section_area_mm2(z)
    got = np.array([per_plane[k] for k in z])
    np.testing.assert_allclose(got, exact, rtol=2e-2, atol=0.02 * spacing)


def test_tilted_cylinder_section_beyond_the_axis_has_no_spikes():
    """A cap chord that cuts the circle beyond the axis (the old z = -30 plane at 2.5 mm)."""
    cyl = make_phantom("tilted_cylinder")
    (c,) = [c for c in cyl.contours(2.5, n_points=128) if abs(c["z"] + 30.0) < 1e-9]
    x = c["points"][:, 0]
    lo, _ = cyl._bounds_u(-30.0)
    chord_x = (lo + (-30.0) * np.sin(cyl.tilt)) / np.cos(cyl.tilt)
    on_chord = np.abs(x - chord_x) < 1e-9
    # the chord's points lie within the circle: |y| <= sqrt(r^2 - lo^2)
    assert on_chord.any()
    assert np.all(np.abs(c["points"][on_chord, 1]) <= np.sqrt(cyl.r**2 - lo**2) + 1e-9)


def test_sliver_planes_are_skipped_and_reported():
    cyl = make_phantom("tilted_cylinder", radius_mm=10.0, length_mm=40.0, tilt_deg=30.0)
    lo, hi = cyl.z_range
    z_sliver = lo + 1e-6
    offset = z_sliver - np.floor(z_sliver)  # a 1 mm grid with a plane 1e-6 mm above the lowest point
    largest = cyl.section_area_mm2(np.array([0.0]))[0]
    assert cyl.section_area_mm2(np.array([z_sliver]))[0] < MIN_SECTION_FRACTION * largest
    truth = cyl.truth(1.0, offset_mm=offset)
    assert truth["skipped_planes_mm"] == pytest.approx([z_sliver])
    planes = cyl.plane_positions(1.0, offset_mm=offset)
    assert planes[0] == pytest.approx(z_sliver + 1.0)
    zs = {c["z"] for c in cyl.contours(1.0, offset_mm=offset)}
    assert min(zs) == pytest.approx(planes[0]) and truth["z_first_contour_mm"] == pytest.approx(planes[0])
    assert truth["volume_between_end_planes_mm3"] == pytest.approx(cyl.volume_between_mm3(planes[0], planes[-1]))
    assert truth["n_planes"] == len(planes) == len(zs)
    assert make_phantom("ellipsoid").truth(2.5)["skipped_planes_mm"] == []
