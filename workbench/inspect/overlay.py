"""The overlay picture of one inspected part (``overlay.png``), sized for the lot report.

Two panels side by side: the shaded height (a hillshade of the measured height with the
background's mean slope removed and the relief exaggerated by a stated factor, lit from the
upper left) and the albedo. On both, each imperfection's true outline (the contour of its
region in the measurement's label image, :func:`imperfection_outlines`) coloured by its verdict
(green pass, amber uncertain, red fail, grey when it lies outside the inspected region) with
its id, the region of interest and exclusion zones, and a scale bar in mm whose label lies
inside the panel. Below: zoomed views of the deciding imperfections on the shaded height, and
one line per check (:func:`overlay_text`), e.g. ``#0 FAIL  depth 0.120 +- 0.004 mm (k = 2) > 0.100
limit``; the same lines go into ``result.json`` (``overlay_text``).

The picture is :data:`REPORT_WIDTH` pixels wide, so the lot report shows it at its own size and
its text keeps :data:`TEXT_PX` pixels (cap height). Drawn with OpenCV; the height is shaded at
full resolution, then shrunk (area average), so it stays cheap on 5 MP images. Positions in mm
(region of interest, exclusions, the box outline when no label image is given) map to pixels on
the grid of :data:`surfaces.grid.GRID_CONVENTION` with the nominal pixel size (for a perspective
camera: the scale at the reference plane).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage

from surfaces.grid import xy_to_pixel
from workbench import images
from workbench.inspect.decide import Decision
from workbench.inspect.spec import Spec

__all__ = ["COLOURS", "REPORT_WIDTH", "TEXT_PX", "check_label", "draw_scale_bar", "imperfection_outlines",
           "overlay_image", "overlay_text", "scale_bar_mm", "shaded_height"]

#: RGB colour per verdict; ``None``: the imperfection does not decide (outside the region)
COLOURS = {"pass": (40, 200, 40), "uncertain": (255, 176, 0), "fail": (235, 30, 30), "not_measured": (120, 150, 255),
           None: (150, 150, 150)}
#: width of the overlay picture, pixels: the lot report's column (report.html, 1200 px less its padding)
REPORT_WIDTH = 1120
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_SCALE = 0.55  # font scale of every label
#: cap height of the labels, pixels (OpenCV's Hershey simplex at :data:`_SCALE`)
TEXT_PX = cv2.getTextSize("H", _FONT, _SCALE, 1)[0][1]
_BACK = (30, 30, 30)
_GAP = 8
_LINE = TEXT_PX + 9  # legend line pitch
_MAX_LINES = 16
_ZOOMS = 4  # zoomed imperfections at most
_SAMPLES = 200_000  # pixels the shading's statistics (median height and slope, roughness) are taken on
_NAMES = {"max_depth_mm": ("depth", "mm"), "length_mm": ("length", "mm"), "mean_width_mm": ("width", "mm"),
          "max_width_mm": ("max width", "mm"), "area_mm2": ("area", "mm^2"), "volume_mm3": ("volume", "mm^3"),
          "count": ("count", ""), "total_area_mm2": ("total area", "mm^2"), "min_distance_mm": ("distance", "mm")}
_SEVERITY = {"fail": 0, "uncertain": 1, "pass": 2, None: 3}


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


def _round_down_125(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above ``x`` (``x >= 1``)."""
    base = 10.0 ** np.floor(np.log10(x))
    return float(max(m * base for m in (1.0, 2.0, 5.0) if m * base <= x * (1 + 1e-9)))


def shaded_height(height, pixel_size: float, mask=None, exaggeration: float | None = None) -> tuple[np.ndarray, float]:
    """Hillshade of a height map, lit from the upper left at 45 degrees elevation.

    The median slope of the valid pixels is removed first (a tilted plane shades evenly
    anyway; without it an exaggerated tilt would saturate the picture), then the slopes are
    multiplied by ``exaggeration``.

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height, mm; NaN where not measured.
    pixel_size : float
        Pixel size, mm.
    mask : array_like, shape (H, W), bool, optional
        Pixels to shade (default: the finite ones); the rest are 0.
    exaggeration : float, optional
        Relief factor; default: a round number (1, 2 or 5 times a power of ten, at least 1)
        that brings the 90th percentile of the slope residual (the background's roughness and
        noise, which most pixels are) near 0.15, so the background shows a faint texture and an
        imperfection stands out dark or bright whatever its direction.

    Returns
    -------
    shade : numpy.ndarray, shape (H, W), float32
        Lambertian shading in [0, 1]: a flat surface reads 0.71.
    exaggeration : float
        The relief factor used.
    """
    z = np.asarray(height)
    ok = np.isfinite(z) if mask is None else np.isfinite(z) & np.asarray(mask, bool)
    if not ok.any():
        return np.zeros(z.shape, np.float32), 1.0 if exaggeration is None else float(exaggeration)
    some = np.flatnonzero(ok)[::max(1, int(ok.sum()) // _SAMPLES)]  # the statistics on a spread sample
    filled = np.where(ok, z - np.median(z.flat[some]), 0.0).astype(np.float32)
    gr, gc = np.gradient(filled, np.float32(pixel_size))
    slope = np.array([np.median(gr.flat[some]), np.median(gc.flat[some])], np.float32)
    gr -= slope[0]
    gc -= slope[1]
    if exaggeration is None:
        top = float(np.percentile(np.hypot(gr.flat[some], gc.flat[some]), 90.0))
        # a plane (rounding only): 1
        exaggeration = (_round_down_125(max(1.0, min(1e4, 0.15 / top))) if top > 1e-5 * (1 + np.abs(slope).max())
                        else 1.0)
    e = float(exaggeration)
    # normal (-dz/dx, -dz/dy, 1) with y up (dz/dy = -dz/drow); light from (-x, +y) at 45 degrees
    gc *= np.float32(e)
    gr *= np.float32(-e)  # now dz/dx, dz/dy
    light = np.array([-0.5, 0.5, np.sqrt(0.5)], np.float32)
    shade = (-gc * light[0] - gr * light[1] + light[2]) / np.sqrt(1.0 + gc * gc + gr * gr)
    np.clip(shade, 0.0, 1.0, out=shade)
    shade[~ok] = 0.0
    return shade, e


def imperfection_outlines(labels, grow: int = 0) -> dict[int, list[np.ndarray]]:
    """The outline of each imperfection's region: the contours of its pixels.

    Parameters
    ----------
    labels : array_like, shape (H, W), int
        ``id + 1`` on each imperfection's pixels, 0 elsewhere (the label image of
        :func:`photometric.defects.measure_defects` with ``return_labels``).
    grow : int, optional
        Dilate each region by this many pixels first (a disc), so that a line drawn on the
        outline lies just outside the region and leaves it visible.

    Returns
    -------
    dict
        Imperfection id -> list of closed contours (outer boundaries, the largest first), each
        an array (N, 2) of ``(column, row)`` pixel centres on the region's edge.
    """
    lab = np.asarray(labels)
    out = {}
    for k, box in enumerate(ndimage.find_objects(lab), start=1):
        if box is None:
            continue
        g = max(0, int(grow))
        part = np.pad((lab[box] == k).astype(np.uint8), g + 1)
        if g:
            part = cv2.dilate(part, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * g + 1, 2 * g + 1)))
        contours, _ = cv2.findContours(part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        shift = np.array([box[1].start - g - 1, box[0].start - g - 1], float)
        polys = sorted((c[:, 0, :].astype(float) + shift for c in contours), key=len, reverse=True)
        out[k - 1] = polys
    return out


def _decimals(U: float | None, default: int = 3) -> int:
    """Decimals a value with expanded uncertainty ``U`` supports (two digits of U when it starts with 1 or 2)."""
    if U is None or not np.isfinite(U) or U <= 0:
        return default
    lead = int(np.floor(np.log10(U)))
    first = int(np.floor(round(U / 10.0 ** lead, 9)))
    return int(np.clip(-lead + (1 if first < 3 else 0), 0, 6))


def check_label(check: dict) -> str:
    """One check as text: the quantity, its U with k, the comparison and the limit.

    Parameters
    ----------
    check : dict
        ``{"quantity", "value", "U", "limit", "limit_kind", "rule", "verdict"}``
        (:class:`workbench.inspect.decide.Decision`).

    Returns
    -------
    str

    Examples
    --------
    >>> check_label({"quantity": "max_depth_mm", "value": 0.0991, "U": 0.0042, "limit": 0.08,
    ...              "limit_kind": "max", "rule": "guard_band", "verdict": "fail"})
    'depth 0.099 +- 0.004 mm (k = 2) > 0.080 limit'
    >>> check_label({"quantity": "count", "value": 2, "U": 0.0, "limit": 1, "limit_kind": "max",
    ...              "rule": "simple", "verdict": "fail"})
    'count 2 > 1 limit'
    """
    q = check["quantity"]
    name, unit = _NAMES.get(q, (q, ""))
    value, U, limit = check["value"], check.get("U"), check["limit"]
    unit = f" {unit}" if unit else ""
    if q == "count":
        text = f"{name} {int(value)}"
        lim = f"{int(limit)}" if float(limit).is_integer() else f"{limit:g}"
    else:
        d = _decimals(U)
        lim = f"{limit:.{d}f}" if round(float(limit), d) == float(limit) else f"{limit:g}"
        if U is None:
            text = f"{name} {value:.{d}f}{unit} (U not stated)"
        else:
            text = f"{name} {value:.{d}f} +- {U:.{d}f}{unit} (k = 2)"
    lower = check.get("limit_kind") == "min"
    verdict = check["verdict"]
    if verdict == "uncertain":
        op = "within U of"
    elif verdict == "fail":
        op = "<" if lower else ">"
    elif check.get("rule") == "guard_band" and U:
        op = ">" if lower else "<"
    else:
        op = ">=" if lower else "<="
    return f"{text} {op} {lim} limit"


def _ordered(decision: Decision) -> list:
    """Imperfections worst first: by verdict (fail, uncertain, pass, not deciding), then deepest first."""
    def depth(rec):
        return float(rec["values"].get("max_depth_mm", {}).get("value", 0.0))
    return sorted(decision.imperfections, key=lambda r: (_SEVERITY.get(r["verdict"], 3), -depth(r)))


def _decider(entry: str) -> str:
    """``imperfection 3 max_depth_mm`` -> ``#3 depth``; ``part count`` -> ``part count``."""
    words = entry.split(" ")
    name = _NAMES.get(words[-1], (words[-1],))[0]
    return f"#{words[1]} {name}" if words[0] == "imperfection" and len(words) == 3 else f"{words[0]} {name}"


def overlay_text(decision: Decision) -> list[str]:
    """The overlay's text: the part's verdict, then one line per check (every label of the picture).

    Parameters
    ----------
    decision : Decision
        What :func:`workbench.inspect.decide.judge` decided.

    Returns
    -------
    list of str
        First the verdict line (rule and what decided it), then per imperfection, worst
        first, ``#<id> <VERDICT>  <check_label>`` for each of its checks (or what it measures
        and why it does not decide), then the part checks ``part <VERDICT>  <check_label>``.
    """
    rule = "guard band, ISO 14253-1" if decision.rule == "guard_band" else "simple: value against limit"
    why = ("decided by " + ", ".join(_decider(d) for d in decision.decided_by) if decision.decided_by
           else "every check passed")
    lines = [f"{decision.verdict.upper()} ({rule}): {why}"]
    for rec in _ordered(decision):
        tag = f"#{rec['id']}"
        if rec["checks"]:
            lines += [f"{tag} {c['verdict'].upper()}  {check_label(c)}" for c in rec["checks"]]
            continue
        depth = rec["values"].get("max_depth_mm", {})
        U = depth.get("U")
        d = _decimals(U)
        figure = (f"depth {depth.get('value', float('nan')):.{d}f}"
                  + (f" +- {U:.{d}f} mm (k = 2)" if U is not None else " mm"))
        why = {"outside_roi": "outside the region of interest, not decided",
               "excluded": "in an exclusion zone, not decided"}.get(rec["region"], "no limit in the spec")
        lines.append(f"{tag} {figure}: {why}")
    lines += [f"part {c['verdict'].upper()}  {check_label(c)}" for c in decision.part_checks]
    return lines


def _text(pic, text: str, org, colour, scale: float = _SCALE, thick: int = 1, fit: bool = False
          ) -> tuple[int, int, int, int]:
    """Put ``text`` with a dark halo, moved inside the picture; return its box (x0, y0, x1, y1).

    With ``fit``, a text wider than the picture is drawn smaller (down to 0.3) rather than cut.
    """
    (tw, th), base = cv2.getTextSize(text, _FONT, scale, thick)
    h, w = pic.shape[:2]
    while fit and tw > w - 4 and scale > 0.3:
        scale = max(0.3, scale - 0.05)
        (tw, th), base = cv2.getTextSize(text, _FONT, scale, thick)
    x = int(np.clip(org[0], 2, max(2, w - tw - 2)))
    y = int(np.clip(org[1], th + 2, max(th + 2, h - base - 2)))
    for dx, dy in ((-1, -1), (-1, 1), (1, -1), (1, 1), (0, 2), (0, -2), (2, 0), (-2, 0)):  # a dark halo
        cv2.putText(pic, text, (x + dx, y + dy), _FONT, scale, (0, 0, 0), thick, cv2.LINE_AA)
    cv2.putText(pic, text, (x, y), _FONT, scale, colour, thick, cv2.LINE_AA)
    return x, y - th, x + tw, y + base


def draw_scale_bar(panel: np.ndarray, mm_per_px: float) -> tuple[int, int, int, int]:
    """Draw a scale bar and its label in the lower left corner of a panel (in place).

    Parameters
    ----------
    panel : numpy.ndarray, shape (h, w, 3), uint8
        The panel (a view into the picture).
    mm_per_px : float
        Size of one panel pixel, mm.

    Returns
    -------
    tuple of int
        The label's box ``(x0, y0, x1, y1)`` in panel pixels: inside the panel.
    """
    h, w = panel.shape[:2]
    bar = scale_bar_mm(w * mm_per_px)
    bar_px = max(1, round(bar / mm_per_px))
    x0, y0 = 8, h - 10
    cv2.rectangle(panel, (x0 - 2, y0 - 5), (x0 + bar_px + 2, y0 + 5), (0, 0, 0), -1)
    cv2.rectangle(panel, (x0, y0 - 3), (x0 + bar_px, y0 + 3), (255, 255, 255), -1)
    return _text(panel, f"{bar:g} mm", (x0, y0 - 10), (255, 255, 255), fit=True)


def _grey(image) -> np.ndarray:
    a = np.asarray(image)
    return a.mean(axis=2) if a.ndim == 3 else a


def _resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Resize to (width, height): area average when shrinking, linear when enlarging."""
    shrink = size[0] < image.shape[1]
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


def _draw_outline(panel, polys, scale: float, offset, colour, thick: int = 2) -> None:
    """Closed contours (column, row pixel centres of the image) onto a panel scaled by ``scale``."""
    pts = [np.round(((p - offset + 0.5) * scale - 0.5) * 16).astype(np.int32) for p in polys]
    cv2.polylines(panel, pts, True, colour, thick, cv2.LINE_AA, shift=4)


def _mm_polygon(points_mm, shape, pixel_size: float) -> np.ndarray:
    """Polygon in mm -> (column, row) image pixels."""
    pts = np.asarray(points_mm, float)
    row, col = xy_to_pixel(pts[:, 0], pts[:, 1], shape, pixel_size)
    return np.stack([col, row], axis=1)


def overlay_image(albedo, mask, decision: Decision, spec: Spec, pixel_size: float, *, height=None, labels=None,
                  width: int = REPORT_WIDTH) -> np.ndarray:
    """Draw the overlay of one part (layout in the module docstring).

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
    height : array_like, shape (H, W), optional
        Measured height, mm (NaN where not measured): the shaded panel and the zooms. Without
        it the left panel is the albedo too.
    labels : array_like, shape (H, W), int, optional
        ``id + 1`` on each imperfection's pixels (:func:`imperfection_outlines`). Without it
        each imperfection is drawn as its ``outline_mm`` rectangle (length by maximum width).
    width : int, optional
        Width of the picture, pixels.

    Returns
    -------
    numpy.ndarray, shape (h, width, 3), uint8
        RGB picture (:func:`surfaces.io.write_png`).
    """
    grey = np.asarray(_grey(albedo), np.float32)
    shape = grey.shape
    mask = np.ones(shape, bool) if mask is None else np.asarray(mask, bool)

    # panel size: two across the width, at most 1.3 times as tall as wide
    pw = (width - 3 * _GAP) // 2
    scale = pw / shape[1]
    if shape[0] * scale > 1.3 * pw:
        scale = 1.3 * pw / shape[0]
    pw, ph = max(1, round(shape[1] * scale)), max(1, round(shape[0] * scale))
    scale = pw / shape[1]

    # the albedo scaled on the panel's pixels (area averages: the same percentile to a few 1e-3)
    small = cv2.resize(mask.astype(np.uint8), (pw, ph), interpolation=cv2.INTER_NEAREST) > 0
    right = images.albedo_image(_resize(np.where(mask, grey, 0.0).astype(np.float32), (pw, ph)), small)
    if height is not None:
        shade, exag = shaded_height(height, pixel_size, mask)
        left = np.repeat((255.0 * _resize(shade, (pw, ph)) + 0.5).astype(np.uint8)[..., None], 3, axis=2)
        left_title = f"shaded height (relief x {exag:g}, light from upper left)"
    else:
        shade, left, left_title = None, right, "albedo (no height given)"

    cache = {}

    def outlines(grow: int) -> dict:
        """Imperfection id -> contours, each region grown by ``grow`` pixels (the box without labels)."""
        if grow not in cache:
            got = imperfection_outlines(labels, grow) if labels is not None else {}
            cache[grow] = {rec["id"]: got.get(int(rec["id"])) or [_mm_polygon(rec["outline_mm"], shape, pixel_size)]
                           for rec in decision.imperfections}
        return cache[grow]

    def grow_for(s: float) -> int:
        """Grow the regions by about 3 display pixels: the line lies just outside the region and leaves it seen."""
        return int(max(1, np.ceil(3.0 / s)))

    ordered = _ordered(decision)
    zoomed = [r for r in ordered if r["region"] == "inspected"][:_ZOOMS] if shade is not None else []
    lines = overlay_text(decision)
    head_line = lines[0]
    lines = lines[1:]  # the verdict line is the picture's head
    shown = lines if len(lines) <= _MAX_LINES else lines[:_MAX_LINES - 1] + [
        f"... and {len(lines) - _MAX_LINES + 1} more lines (result.json: overlay_text)"]

    head = 34
    title = _LINE
    zs = (width - (_ZOOMS + 1) * _GAP) // _ZOOMS
    zoom_h = (title + zs + _GAP) if zoomed else 0
    zones = [name for name, there in (("blue: the region of interest", spec.roi is not None),
                                      ("grey boxes: exclusion zones", bool(spec.exclusions))) if there]
    notes = ["; ".join(zones) + " (imperfections outside are drawn grey and do not decide)"] if zones else []
    total_h = head + title + ph + _GAP + zoom_h + (len(shown) + len(notes)) * _LINE + _GAP
    pic = np.empty((total_h, width, 3), np.uint8)
    pic[:] = _BACK

    # the verdict line
    verdict = decision.verdict
    (vw, _), _ = cv2.getTextSize(verdict.upper(), _FONT, 0.9, 2)
    _text(pic, verdict.upper(), (_GAP, 27), COLOURS.get(verdict, COLOURS[None]), 0.9, 2)
    _text(pic, head_line[len(verdict) + 1:], (_GAP + vw + 12, 25), (235, 235, 235))

    y_panel = head + title
    for i, (image, name) in enumerate([(left, left_title), (right, "albedo")]):
        x_panel = _GAP + i * (pw + _GAP)
        _text(pic, name, (x_panel, y_panel - 6), (235, 235, 235))
        panel = pic[y_panel:y_panel + ph, x_panel:x_panel + pw]
        panel[:] = image
        zones = [(spec.roi, (80, 160, 255))] + [(z, (150, 150, 150)) for z in spec.exclusions]
        for zone, colour in zones:
            if zone is not None:
                _draw_outline(panel, [_mm_polygon(zone, shape, pixel_size)], scale, 0.0, colour, 1)
        polys = outlines(grow_for(scale))
        for rec in ordered[::-1]:  # the worst drawn last, on top
            colour = COLOURS.get(rec["verdict"], COLOURS[None])
            _draw_outline(panel, polys[rec["id"]], scale, 0.0, colour)
            pts = (np.concatenate(polys[rec["id"]]) + 0.5) * scale - 0.5
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            if (hi - lo).max() < 8:  # too small to see at this scale: a ring around it
                cv2.circle(panel, tuple(int(v) for v in np.round((lo + hi) / 2)), 10, colour, 1, cv2.LINE_AA)
            right = pts[np.argmax(pts[:, 0])]  # the id beside the outline's rightmost point
            _text(panel, f"#{rec['id']}", (int(right[0]) + 6, int(right[1]) + TEXT_PX // 2), colour)
        draw_scale_bar(panel, pixel_size / scale)

    y = y_panel + ph + _GAP
    if zoomed:
        _text(pic, "zooms on the shaded height, worst first, centred on each imperfection (outline just outside "
              "its measured region)", (_GAP, y + title - 6), (235, 235, 235))
        y += title
        exact = outlines(0)
        for i, rec in enumerate(zoomed):
            x0 = _GAP + i * (zs + _GAP)
            tile = pic[y:y + zs, x0:x0 + zs]
            pts = np.concatenate(exact[rec["id"]])
            row, col = xy_to_pixel(*np.asarray(rec["center_mm"], float), shape, pixel_size)
            c = np.array([col, row], float)
            # the whole region with a margin; a long scratch: its middle, at least twice the panel's scale and
            # about 10 widths across, so its cross-section shows
            across = float(rec["values"].get("max_width_mm", {}).get("value", np.inf)) / pixel_size
            side = int(np.clip(1.6 * float((pts.max(axis=0) - pts.min(axis=0)).max()) + 4, 24,
                               max(24.0, min(zs / (2.0 * scale), 10.0 * across))))
            c0 = np.floor(c - side / 2).astype(int)
            crop = np.zeros((side, side), np.float32)
            r0, r1 = max(0, c0[1]), min(shape[0], c0[1] + side)
            q0, q1 = max(0, c0[0]), min(shape[1], c0[0] + side)
            if r1 > r0 and q1 > q0:
                crop[r0 - c0[1]:r1 - c0[1], q0 - c0[0]:q1 - c0[0]] = shade[r0:r1, q0:q1]
            tile[:] = np.repeat((255.0 * _resize(crop, (zs, zs)) + 0.5).astype(np.uint8)[..., None], 3, axis=2)
            z = zs / side
            colour = COLOURS.get(rec["verdict"], COLOURS[None])
            _draw_outline(tile, outlines(grow_for(z))[rec["id"]], z, c0.astype(float), colour)
            _text(tile, f"#{rec['id']}", (6, TEXT_PX + 6), colour)
            draw_scale_bar(tile, pixel_size / z)
        y += zs + _GAP

    for line in shown:
        head_word = line.split(" ")[1] if line.startswith("#") or line.startswith("part ") else ""
        colour = COLOURS.get(head_word.lower(), (235, 235, 235)) if head_word else (235, 235, 235)
        if line.startswith("#") and head_word.lower() not in COLOURS:
            colour = COLOURS[None]
        _text(pic, line, (_GAP, y + TEXT_PX + 3), colour)
        y += _LINE
    for line in notes:
        _text(pic, line, (_GAP, y + TEXT_PX + 3), (170, 170, 170))
        y += _LINE
    return pic
