"""Issue 32 item 5: what the pixel size resolves (photometric.resolution) and where a spec meets the rig."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_synthetic.heightfields import v_crack
from datasets_synthetic.render import render
from photometric.lights import ring_lights
from photometric.pipeline import reconstruct
from photometric.resolution import check_resolution


def test_resolution_verdicts_follow_the_pixels_across():
    """Below two pixels across: refused (no depth to predict); a few pixels: a warning with the
    predicted shortfall; wide grooves: ok. Blur makes the same groove read shallower."""
    hairline = check_resolution(0.035, 0.1)
    assert hairline.status == "refuse" and hairline.depth_shortfall is None
    assert hairline.pixels_across == pytest.approx(0.35)
    narrow, blurred = check_resolution(0.3, 0.05), check_resolution(0.3, 0.05, blur_px=0.6)
    assert narrow.status == "warn" and narrow.pixels_across == pytest.approx(6.0)
    assert blurred.depth_shortfall > narrow.depth_shortfall + 0.03
    wide = check_resolution(1.0, 0.05)
    assert wide.status == "ok" and wide.depth_shortfall < 0.10 and wide.message == ""
    with pytest.raises(ValueError, match="narrowest_mm"):
        check_resolution(-0.1, 0.05)


def test_predicted_shortfall_matches_the_rendered_groove():
    """The prediction against the whole pipeline: a V-scratch 6 px wide along the rows, its bottom
    between two rows, rendered and reconstructed, reads as shallow as predicted (to 3 % of the depth)."""
    h, L = 0.05, ring_lights(3, 45.0)
    hf = v_crack(120, h, depth_mm=0.05, width_mm=0.3, length_mm=3.0, center_px=(60.5, 60.3), axis_deg=0.0)
    rec = reconstruct(render(hf, L, albedo=0.8), lights=L, pixel_size=h).defects[0]
    measured = 1.0 - rec["max_depth_mm"] / 0.05
    assert measured == pytest.approx(check_resolution(0.3, h).depth_shortfall, abs=0.03)


def _line_cover(n: int, h: float, width: float, length: float, axis_deg: float, centre, sub: int = 8) -> np.ndarray:
    """Fraction of each pixel covered by a stadium ``width`` x ``length`` mm (8 x 8 samples per pixel)."""
    import math

    o = (np.arange(sub) + 0.5) / sub - 0.5
    r, c = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = math.radians(axis_deg)
    ux, uy = math.cos(a), math.sin(a)
    frac = np.zeros((n, n))
    for dr in o:
        for dc in o:
            x, y = (c + dc - centre[1]) * h, -(r + dr - centre[0]) * h
            along = np.clip(x * ux + y * uy, -0.5 * (length - width), 0.5 * (length - width))
            frac += np.hypot(x - along * ux, y - along * uy) < 0.5 * width
    return frac / sub**2


@pytest.mark.parametrize("axis_deg", [0.0, 30.0])
def test_hairline_crack_is_reported_from_the_albedo_with_its_length(axis_deg):
    """Issue 32: a crack 0.035 mm wide (a third of a 0.1 mm pixel) is a dark line in the images
    (each pixel darkened by the part of it the crack covers) but no groove in the height: the
    height finds nothing, the albedo's ridges find one crack of the right length and axis, its
    depth "not resolved"; a clean textured plate gives none."""
    from datasets_synthetic.heightfields import plane
    from datasets_synthetic.render import texture_albedo
    from photometric.defects import find_hairline_cracks

    n, h, L = 120, 0.1, ring_lights(4, 45.0)
    texture = texture_albedo(n, 0.6, 0.85, 12.0, seed=1)
    cover = _line_cover(n, h, 0.035, 6.0, axis_deg, (60.3, 59.6))
    res = reconstruct(render(plane(n, h), L, albedo=texture * (1.0 - 0.5 * cover), noise=0.004, seed=0),
                      lights=L, pixel_size=h)
    assert res.defects == []  # the height does not resolve it
    cracks = find_hairline_cracks(res.albedo, h)
    assert len(cracks) == 1
    crack = cracks[0]
    assert crack["length_mm"] == pytest.approx(6.0, abs=h)
    assert abs((crack["axis_deg"] - axis_deg + 90.0) % 180.0 - 90.0) < 2.0
    assert crack["max_depth_mm"] is None and crack["depth_status"] == "not resolved"
    clean = reconstruct(render(plane(n, h), L, albedo=texture, noise=0.004, seed=0), lights=L, pixel_size=h)
    assert find_hairline_cracks(clean.albedo, h) == []
