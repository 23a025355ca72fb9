"""The overlay picture of one inspected part (``overlay.png``).

The albedo in grey, each imperfection's outline (its length along its axis by its maximum
width, :func:`workbench.inspect.decide.outline_mm`) drawn and labelled with its id and
depth, coloured by its verdict (green pass, amber uncertain, red fail, grey when it lies
outside the inspected region), the region of interest and exclusion zones, the part's
verdict in the corner and a scale bar in mm. Drawn with OpenCV at the picture's final size
(at most :data:`MAX_SIDE` pixels on the long side), so it stays cheap on 5 MP images.
Positions in mm map to pixels on the grid of :data:`surfaces.grid.GRID_CONVENTION` with the
nominal pixel size (for a perspective camera: the scale at the reference plane).
"""

from __future__ import annotations

import cv2
import numpy as np

from surfaces.grid import xy_to_pixel
from workbench import images
from workbench.inspect.decide import Decision
from workbench.inspect.spec import Spec

__all__ = ["COLOURS", "MAX_SIDE", "overlay_image", "scale_bar_mm"]

#: RGB colour per verdict; ``None``: the imperfection does not decide (outside the region)
COLOURS = {"pass": (40, 200, 40), "uncertain": (255, 176, 0), "fail": (235, 30, 30), None: (150, 150, 150)}
#: long side of the overlay picture, pixels (larger images are shrunk before drawing)
MAX_SIDE = 1600


def scale_bar_mm(field_mm: float) -> float:
    """A round scale-bar length (1, 2 or 5 times a power of ten) near a fifth of the field.

    Parameters
    ----------
    field_mm : float
        Width of the picture in mm.

    Returns
    -------
    float

    Examples
    --------
    >>> scale_bar_mm(60.0), scale_bar_mm(3.0), scale_bar_mm(400.0)
    (10.0, 0.5, 50.0)
    """
    target = max(float(field_mm), 1e-9) / 5.0
    base = 10.0 ** np.floor(np.log10(target))
    return float(max(m * base for m in (1.0, 2.0, 5.0) if m * base <= target))


def _to_pixel(points_mm, shape, pixel_size: float, zoom: float) -> np.ndarray:
    pts = np.asarray(points_mm, float)
    row, col = xy_to_pixel(pts[:, 0], pts[:, 1], shape, pixel_size)
    return np.round(np.stack([col, row], axis=1) * zoom).astype(np.int32)


def overlay_image(albedo, mask, decision: Decision, spec: Spec, pixel_size: float,
                  max_side: int = MAX_SIDE) -> np.ndarray:
    """Draw the overlay of one part.

    Parameters
    ----------
    albedo : array_like, shape (H, W) or (H, W, 3)
        Reconstructed albedo.
    mask : array_like, shape (H, W), bool
        Object mask (black outside).
    decision : Decision
        What :func:`workbench.inspect.decide.judge` decided.
    spec : Spec
        Its region of interest and exclusion zones are drawn.
    pixel_size : float
        Nominal pixel size, mm.
    max_side : int, optional
        Long side of the picture, pixels (larger images are shrunk first).

    Returns
    -------
    numpy.ndarray, shape (h, w, 3), uint8
        RGB picture (:func:`surfaces.io.write_png`).
    """
    a = np.asarray(albedo)
    grey = a.mean(axis=2) if a.ndim == 3 else a
    shape = grey.shape
    zoom = min(1.0, float(max_side) / max(shape))
    if zoom < 1.0:
        size = (max(1, round(shape[1] * zoom)), max(1, round(shape[0] * zoom)))
        grey = cv2.resize(np.asarray(grey, np.float32), size, interpolation=cv2.INTER_AREA)
        mask = cv2.resize(np.asarray(mask, np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    pic = np.ascontiguousarray(images.albedo_image(grey, mask))
    h, w = pic.shape[:2]
    thick = max(1, round(w / 600))
    font = max(0.4, w / 1600)

    for zone, colour in [(spec.roi, (80, 160, 255))] + [(z, (150, 150, 150)) for z in spec.exclusions]:
        if zone is not None:
            cv2.polylines(pic, [_to_pixel(zone, shape, pixel_size, zoom)], True, colour, thick, cv2.LINE_AA)
    for rec in decision.imperfections:
        colour = COLOURS[rec["verdict"]]
        box = _to_pixel(rec["outline_mm"], shape, pixel_size, zoom)
        # a hair-thin defect would vanish at this scale: draw at least a few pixels across
        centre = box.mean(axis=0)
        box = np.where(np.abs(box - centre) < 3, centre + np.sign(box - centre + 1e-9) * 3, box).astype(np.int32)
        cv2.polylines(pic, [box], True, colour, thick, cv2.LINE_8)
        depth = rec["values"].get("max_depth_mm", {})
        text = f"{rec['id']}: {depth.get('value', float('nan')):.3f}"
        if depth.get("U") is not None:
            text += f"+-{depth['U']:.3f}"
        text += " mm"
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font, thick)
        x = int(np.clip(box[:, 0].max() + 4, 0, max(0, w - tw - 2)))
        y = int(np.clip(box[:, 1].min() + th, th + 2, h - 2))
        cv2.putText(pic, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, font, (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.putText(pic, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, font, colour, thick, cv2.LINE_AA)

    verdict = decision.verdict.upper()
    org = (int(10 * font), int(34 * font))
    cv2.putText(pic, verdict, org, cv2.FONT_HERSHEY_SIMPLEX, 1.4 * font, (0, 0, 0), thick + 3, cv2.LINE_AA)
    cv2.putText(pic, verdict, org, cv2.FONT_HERSHEY_SIMPLEX, 1.4 * font, COLOURS[decision.verdict], thick + 1,
                cv2.LINE_AA)

    field = shape[1] * pixel_size
    bar = scale_bar_mm(field)
    bar_px = max(1, round(bar / pixel_size * zoom))
    x0, y0 = int(10 * font), h - int(14 * font)
    cv2.rectangle(pic, (x0 - 2, y0 - thick - 4), (x0 + bar_px + 2, y0 + thick + 4), (0, 0, 0), -1)
    cv2.rectangle(pic, (x0, y0 - thick - 2), (x0 + bar_px, y0 + thick + 2), (255, 255, 255), -1)
    label = f"{bar:g} mm"
    cv2.putText(pic, label, (x0, y0 - int(10 * font)), cv2.FONT_HERSHEY_SIMPLEX, font, (0, 0, 0), thick + 2,
                cv2.LINE_AA)
    cv2.putText(pic, label, (x0, y0 - int(10 * font)), cv2.FONT_HERSHEY_SIMPLEX, font, (255, 255, 255), thick,
                cv2.LINE_AA)
    return pic
