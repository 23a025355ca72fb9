"""CT phantoms: exact volumes and areas against numerical integrals, contours on the true outline."""

from __future__ import annotations

import json
from collections import defaultdict

import numpy as np
import pytest
from scipy.integrate import quad, simpson
from skimage.measure import points_in_poly

from datasets_synthetic.phantoms import SHAPES, Kidney, make_phantom, polygon_area, write_phantom


def _plane_areas(contours):
    """Area per plane from polygons; a contour nested in an odd number of others is a hole."""
    planes = defaultdict(list)
    for c in contours:
        planes[c["z"]].append(c["points"])
    zs = np.array(sorted(planes))
    areas = []
    for z in zs:
        polys = planes[z]
        total = 0.0
        for i, p in enumerate(polys):
            depth = sum(points_in_poly(p[:1], q)[0] for j, q in enumerate(polys) if j != i)
            total += (-1) ** depth * abs(polygon_area(p))
        areas.append(total)
    return zs, np.array(areas)


@pytest.mark.parametrize("shape", SHAPES)
def test_volume_between_end_planes_matches_the_section_integral(shape):
    ph = make_phantom(shape)
    lo, hi = ph.z_range
    assert ph.volume_between_mm3(lo, hi) == pytest.approx(ph.volume_mm3, rel=1e-10)
    assert ph.volume_between_mm3(lo - 5, hi + 5) == pytest.approx(ph.volume_mm3, rel=1e-10)
    a, b = lo + 0.3 * (hi - lo), lo + 0.8 * (hi - lo)
    numeric = quad(lambda z: float(ph.section_area_mm2(np.array([z]))[0]), a, b, limit=200,
                   epsrel=1e-11)[0]
    assert ph.volume_between_mm3(a, b) == pytest.approx(numeric, rel=1e-7)
    assert ph.volume_between_mm3(b, b) == 0.0


@pytest.mark.parametrize("shape", SHAPES)
def test_exact_volume_agrees_with_integrated_contour_areas(shape):
    ph = make_phantom(shape)
    contours = ph.contours(0.5, n_points=900, seed=1)
    zs, areas = _plane_areas(contours)
    np.testing.assert_allclose(areas, ph.section_area_mm2(zs), rtol=2e-3, atol=0.05)
    between = ph.volume_between_mm3(zs[0], zs[-1])
    assert simpson(areas, x=zs) == pytest.approx(between, rel=2e-3)
    truth = ph.truth(0.5)
    assert truth["volume_between_end_planes_mm3"] == pytest.approx(between)
    assert truth["z_first_contour_mm"] == zs[0] and truth["z_last_contour_mm"] == zs[-1]


@pytest.mark.parametrize("shape", SHAPES)
def test_inside_agrees_with_the_volume(shape):
    ph = make_phantom(shape)
    lower, upper = ph.bounds
    rng = np.random.default_rng(0)
    pts = lower + rng.random((200000, 3)) * (upper - lower)
    estimate = ph.inside(pts).mean() * np.prod(upper - lower)
    assert estimate == pytest.approx(ph.volume_mm3, rel=0.02)


def _on_boundary(ph, pts, eps=1e-6):
    rng = np.random.default_rng(5)
    dirs = rng.standard_normal((8, pts.shape[1]))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    if pts.shape[1] == 2:
        raise AssertionError("pass 3-D points")
    states = np.stack([ph.inside(pts + eps * d) for d in dirs])
    return states.any(axis=0) & ~states.all(axis=0)


@pytest.mark.parametrize("shape", SHAPES)
def test_contour_points_lie_on_the_true_outline(shape):
    ph = make_phantom(shape)
    contours = ph.contours(2.5, n_points=48, seed=2)
    counts = [len(c["points"]) for c in contours]
    assert len(set(counts)) > 1  # unequal numbers of points per contour
    for c in contours:
        assert c["points"].shape[1] == 2 and c["points"].dtype == np.float64
        assert polygon_area(c["points"]) > 0  # counter-clockwise
    pts = np.concatenate([np.column_stack([c["points"], np.full(len(c["points"]), c["z"])])
                          for c in contours])
    assert _on_boundary(ph, pts).mean() > 0.97
    assert not _on_boundary(ph, pts + [0.05, 0.05, 0.0]).any()


@pytest.mark.parametrize("shape", SHAPES)
def test_surface_points_lie_on_the_surface(shape):
    ph = make_phantom(shape)
    pts = ph.surface_points(3000, seed=3)
    assert pts.shape == (3000, 3)
    assert _on_boundary(ph, pts).mean() > 0.97
    np.testing.assert_array_equal(pts, ph.surface_points(3000, seed=3))


def test_surface_points_are_uniform_by_area():
    ring = make_phantom("ring", major_mm=25.0, minor_mm=10.0)
    pts = ring.surface_points(40000, seed=0)
    outer = np.hypot(pts[:, 0], pts[:, 1]) > 25.0
    assert outer.mean() == pytest.approx((np.pi * 25 + 20) / (2 * np.pi * 25), abs=0.01)
    cyl = make_phantom("tilted_cylinder", radius_mm=10.0, length_mm=40.0, tilt_deg=30.0)
    pts = cyl.surface_points(40000, seed=0)
    on_cap = np.abs(np.abs((pts - cyl.center) @ cyl.axis) - 20.0) < 1e-9
    assert on_cap.mean() == pytest.approx(2 * np.pi * 100 / cyl.area_mm2, abs=0.01)


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
    assert polygon_area(contour) == pytest.approx(ph.base_area_mm2, rel=1e-3)
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


def test_ring_sections_have_holes_and_lobes_branch():
    ring = make_phantom("ring")
    contours = ring.contours(2.0, n_points=64)
    per_plane = defaultdict(list)
    for c in contours:
        per_plane[c["z"]].append(c["points"])
    assert all(len(v) == 2 for v in per_plane.values())
    outer, inner = per_plane[0.0]
    assert points_in_poly(inner, outer).all()
    lobes = make_phantom("lobes")
    n_per_plane = defaultdict(int)
    for c in lobes.contours(1.0, n_points=64):
        n_per_plane[c["z"]] += 1
    assert set(n_per_plane.values()) == {1, 2}


def test_tilted_cylinder_end_sections_are_truncated():
    cyl = make_phantom("tilted_cylinder", radius_mm=10.0, length_mm=40.0, tilt_deg=30.0)
    full = np.pi * 10.0**2 / np.cos(np.radians(30.0))
    zs = cyl.plane_positions(1.0)
    areas = cyl.section_area_mm2(zs)
    assert areas.max() == pytest.approx(full, rel=1e-12)
    assert areas[0] < 0.5 * full and areas[-1] < 0.5 * full
    assert cyl.volume_mm3 == pytest.approx(np.pi * 100 * 40)
    assert cyl.area_mm2 == pytest.approx(2 * np.pi * 10 * 50)


def test_lobes_closed_forms():
    lobes = make_phantom("lobes", radii_mm=(10.0, 10.0), centers_mm=((0, 0, 0), (10.0, 0, 0)))
    # two equal spheres at distance r: each buried cap has height r/2
    r = 10.0
    lens = 2 * np.pi * (r / 2) ** 2 * (3 * r - r / 2) / 3
    assert lobes.volume_mm3 == pytest.approx(2 * 4 / 3 * np.pi * r**3 - lens)
    assert lobes.area_mm2 == pytest.approx(2 * (4 * np.pi * r * r - 2 * np.pi * r * r / 2))


def test_torus_closed_forms_and_signed_distance():
    ring = make_phantom("ring", major_mm=20.0, minor_mm=5.0)
    assert ring.volume_mm3 == pytest.approx(2 * np.pi**2 * 20 * 25)
    assert ring.area_mm2 == pytest.approx(4 * np.pi**2 * 20 * 5)
    np.testing.assert_allclose(ring.signed_distance([[20, 0, 0], [30, 0, 0], [0, 0, 0]]), [-5, 5, 15])


@pytest.mark.parametrize("shape", ["ring", "lobes", "tilted_cylinder"])
def test_signed_distance_against_a_dense_surface_sample(shape):
    from scipy.spatial import cKDTree

    ph = make_phantom(shape)
    surface = ph.surface_points(200000, seed=1)
    lower, upper = ph.bounds
    pts = lower - 3 + np.random.default_rng(2).random((2000, 3)) * (upper - lower + 6)
    sd = ph.signed_distance(pts)
    np.testing.assert_array_equal(sd <= 0, ph.inside(pts))
    nearest = cKDTree(surface).query(pts)[0]
    # the sample spacing is ~0.3 mm: the sample's distance is never smaller, and close
    assert np.all(nearest >= np.abs(sd) - 1e-9)
    assert np.all(nearest - np.abs(sd) < 0.5)
    assert np.mean(nearest - np.abs(sd)) < 0.15


def test_contour_noise_is_reproducible_and_of_the_stated_size():
    ph = make_phantom("ellipsoid")
    clean = ph.contours(5.0, n_points=200, seed=4)
    noisy = ph.contours(5.0, n_points=200, noise_mm=0.1, seed=4)
    diff = np.concatenate([n["points"] - c["points"] for n, c in zip(noisy, clean)])
    assert np.std(diff) == pytest.approx(0.1, rel=0.1)
    again = ph.contours(5.0, n_points=200, noise_mm=0.1, seed=4)
    np.testing.assert_array_equal(again[3]["points"], noisy[3]["points"])


def test_write_phantom_json(tmp_path):
    ph = make_phantom("lobes")
    truth = write_phantom(tmp_path, ph, spacing=3.0, pixel=1.0, fmt="json", n_surface=500)
    data = json.loads((tmp_path / "contours.json").read_text())
    assert data["units"] == "mm"
    assert {"z", "points"} <= set(data["contours"][0])
    assert len(data["contours"]) == truth["n_contours"]
    stored = json.loads((tmp_path / "truth.json").read_text())
    for key in ("volume_mm3", "volume_between_end_planes_mm3", "area_mm2"):
        assert stored[key] == pytest.approx(getattr(ph, key) if key != "volume_between_end_planes_mm3"
                                            else truth[key])
    assert np.load(tmp_path / "surface_points.npy").shape == (500, 3)
    assert not (tmp_path / "ct").exists()


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: make_phantom("cube"), "shape"),
        (lambda: make_phantom("ring", major_mm=5.0, minor_mm=6.0), "minor_mm"),
        (lambda: make_phantom("ellipsoid", radius=3.0), "params"),
        (lambda: make_phantom("lobes", centers_mm=((0, 0, 0), (50, 0, 0))), "centers_mm"),
        (lambda: make_phantom("tilted_cylinder", tilt_deg=0.0), "tilt_deg"),
        (lambda: Kidney(bend_radius_mm=5.0, thickness_mm=8.0), "bend_radius_mm"),
        (lambda: make_phantom("ellipsoid").contours(100.0, offset_mm=50.0), "spacing_mm"),
        (lambda: make_phantom("ellipsoid").contours(2.0, n_points=3), "n_points"),
        (lambda: make_phantom("ellipsoid").inside(np.zeros((4, 2))), "points"),
        (lambda: write_phantom("/tmp", make_phantom("ring"), 2.0, 1.0, fmt="nifti"), "fmt"),
    ],
)
def test_bad_input_names_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()
