"""Demo section 3 (DiLiGenT bear): the display scaling and the absent-data report."""

from __future__ import annotations

import numpy as np

from photometric.io import PhotometricData
from workbench.demo.real import display_image, section_real

from .test_context import quick_context


def test_display_image_divides_by_the_light_intensities():
    images = np.zeros((2, 4, 5, 3), np.float32)
    images[1] = [0.2, 0.4, 0.1]
    images[1, 0, 0] = [2.0, 2.0, 2.0]  # a highlight outside the mask does not set the scale
    mask = np.ones((4, 5), bool)
    mask[0, 0] = False
    data = PhotometricData(images, np.eye(3)[:2], np.array([[1, 1, 1], [0.5, 1.0, 0.25]]), mask,
                           None, ("a.png", "b.png"))
    img = display_image(data, 1)
    assert img.dtype == np.uint8 and img.shape == (4, 5, 3)
    # divided by the intensities every channel is 0.4: the object's 99.5th percentile, shown white
    assert np.all(img[1:, :] == 255) and np.all(img[0, 1:] == 255)


def test_absent_data_is_reported(tmp_path):
    """Without ../shared the section says so; nothing is faked."""
    ctx = quick_context(tmp_path)
    section_real(ctx)
    assert list(ctx.unavailable) == ["Real captures"]
    assert "absent" in ctx.unavailable["Real captures"]
    assert ctx.numbers["real"] == {"folder": str(tmp_path / "absent" / "diligent_bear")}
    html = ctx.report.write().read_text()
    assert html.count("not available") == 1 and "<img" not in html
