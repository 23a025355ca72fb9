"""The tilted cylinder: closed forms, truncated end sections, signed distance, cap sampling."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.phantoms.cylinder import TiltedCylinder


def test_end_sections_are_truncated():
    cyl = TiltedCylinder(radius_mm=10.0, length_mm=40.0, tilt_deg=30.0)
    full = np.pi * 10.0**2 / np.cos(np.radians(30.0))
    zs = cyl.plane_positions(1.0)
    areas = cyl.section_area_mm2(zs)
    assert areas.max() == pytest.approx(full, rel=1e-12)
    assert areas[0] < 0.5 * full and areas[-1] < 0.5 * full
    assert cyl.volume_mm3 == pytest.approx(np.pi * 100 * 40)
    assert cyl.area_mm2 == pytest.approx(2 * np.pi * 10 * 50)


def test_caps_are_sampled_by_their_area():
    cyl = TiltedCylinder(radius_mm=10.0, length_mm=40.0, tilt_deg=30.0)
    pts = cyl.surface_points(40000, seed=0)
    on_cap = np.abs(np.abs((pts - cyl.center) @ cyl.axis) - 20.0) < 1e-9
    assert on_cap.mean() == pytest.approx(2 * np.pi * 100 / cyl.area_mm2, abs=0.01)


def test_signed_distance_along_the_axis_and_across():
    cyl = TiltedCylinder(radius_mm=10.0, length_mm=40.0, tilt_deg=30.0, center=(1.0, 2.0, 3.0))
    c = cyl.center
    pts = np.array([c, c + 25 * cyl.axis, c + 15 * cyl.e2, c + 15 * cyl.e1 + 23 * cyl.axis])
    np.testing.assert_allclose(cyl.signed_distance(pts), [-10, 5, 5, np.hypot(5, 3)], atol=1e-12)


def test_tilt_range():
    with pytest.raises(ValueError, match="tilt_deg"):
        TiltedCylinder(tilt_deg=0.0)
    with pytest.raises(ValueError, match=r"tilt_deg: must lie in \(0, 80\]"):
        TiltedCylinder(tilt_deg=85.0)
