"""The acceptance specification of an inspection (``spec.json``): read and checked before any work.

``spec.json`` holds the drawing's tolerances in mm (every key optional except that at
least one limit must be given)::

    {"max_depth_mm": 0.10, "max_length_mm": 5.0, "max_width_mm": 0.5, "max_area_mm2": 2.0,
     "max_count": 3, "max_total_area_mm2": 4.0, "min_distance_mm": 2.0,
     "roi_mm": [[x, y], ...], "exclusion_zones_mm": [[[x, y], ...], ...],
     "decision_rule": "guard_band", "name": "cover plate A", "min_width_mm": 0.2}

Per imperfection (ISO 8785): ``max_depth_mm`` limits its maximum depth, ``max_length_mm``
its length along its axis, ``max_width_mm`` its mean width, ``max_area_mm2`` its area.
Per part: ``max_count`` imperfections, ``max_total_area_mm2`` their summed area and
``min_distance_mm`` the smallest gap between two of them. ``roi_mm`` (a polygon in the rig
frame, mm, x right, y up) is the inspected region; imperfections whose centre lies outside
it, or inside an exclusion zone, are listed but do not decide. ``decision_rule`` is
``simple`` (value against limit, the default) or ``guard_band`` (ISO 14253-1, see
:mod:`workbench.inspect.decide`). ``min_width_mm`` (optional, not a limit) is the width of
the narrowest imperfection the inspection must judge: :func:`check_spec_field` refuses a rig
whose pixels do not resolve it and warns where its depth would read markedly shallow
(:func:`photometric.resolution.require_resolution`).

Areal texture (ISO 25178-2, :mod:`workbench.runs.texture`): the keys of
:data:`TEXTURE_LIMITS` (``max_Sa_um``, ``max_Sq_um``, ``max_Sz_um``, ``max_Sp_um``,
``max_Sv_um``, ``max_Sdq``, ``max_Sdr_pct``, ``max_Sk_um``, ``max_Spk_um``, ``max_Svk_um``,
``max_Vmp_ml_m2``, ``max_Vvv_ml_m2``) are upper limits of the part's texture parameters,
decided with the same rules; ``texture: {"s_filter_mm": X, "l_filter_mm": Y, "form":
"plane"|"poly2"}`` states the filters and the F-operator (defaults
:data:`workbench.runs.texture.TEXTURE_DEFAULTS`). With either, every part's texture is
measured over its valid pixels and recorded in ``result.json``.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photometric.rig import loads_unique
from surfaces.grid import pixel_axes
from surfaces.validate import InputError
from workbench.runs.texture import TEXTURE_LIMITS, texture_options

__all__ = ["DECISION_RULES", "IMPERFECTION_LIMITS", "PART_LIMITS", "TEXTURE_LIMITS", "SPEC_KEYS", "Spec",
           "check_spec_field", "load_spec", "parse_spec"]

#: decision rules a spec may name
DECISION_RULES = ("simple", "guard_band")
#: spec key -> the imperfection quantity it limits (a key of photometric.defects.measure_defects)
IMPERFECTION_LIMITS: dict[str, str] = {
    "max_depth_mm": "max_depth_mm",
    "max_length_mm": "length_mm",
    "max_width_mm": "mean_width_mm",
    "max_area_mm2": "area_mm2",
}
#: spec key -> the part quantity it limits (``min_distance_mm`` is a lower limit)
PART_LIMITS: dict[str, str] = {
    "max_count": "count",
    "max_total_area_mm2": "total_area_mm2",
    "min_distance_mm": "min_distance_mm",
}
#: every key spec.json may hold
SPEC_KEYS = (*IMPERFECTION_LIMITS, *PART_LIMITS, "roi_mm", "exclusion_zones_mm", "decision_rule", "name",
             "min_width_mm", *TEXTURE_LIMITS, "texture")
#: every limit key (imperfection, part, texture)
_LIMIT_KEYS = (*IMPERFECTION_LIMITS, *PART_LIMITS, *TEXTURE_LIMITS)


@dataclass(frozen=True)
class Spec:
    """A checked acceptance specification.

    Attributes
    ----------
    limits : dict
        Spec key -> limit (mm, mm^2, or a count for ``max_count``), only the keys given.
    roi : numpy.ndarray or None, shape (V, 2)
        Inspected region (polygon, mm); None: the whole part.
    exclusions : tuple of numpy.ndarray, each (V, 2)
        Exclusion zones (polygons, mm).
    decision_rule : {"simple", "guard_band"}
    name : str
        Free text naming the spec ("" when not given).
    min_width_mm : float or None
        Width of the narrowest imperfection of interest, mm (None when not given).
    texture : dict or None
        The texture's filters and form (``s_filter_mm``, ``l_filter_mm``, ``form``) when
        the spec limits a texture parameter or gives a ``texture`` key; None: no texture
        is measured.
    texture_given : bool
        ``spec.json`` held the ``texture`` key (it is then recorded as given).
    """

    limits: dict
    roi: np.ndarray | None
    exclusions: tuple
    decision_rule: str
    name: str = ""
    min_width_mm: float | None = None
    texture: dict | None = None
    texture_given: bool = False

    def to_dict(self) -> dict:
        """Return the spec as in ``spec.json`` (JSON-ready; what ``result.json`` records)."""
        out: dict = dict(self.limits)
        if self.roi is not None:
            out["roi_mm"] = self.roi.tolist()
        if self.exclusions:
            out["exclusion_zones_mm"] = [z.tolist() for z in self.exclusions]
        out["decision_rule"] = self.decision_rule
        if self.name:
            out["name"] = self.name
        if self.min_width_mm is not None:
            out["min_width_mm"] = self.min_width_mm
        if self.texture_given:
            out["texture"] = dict(self.texture)
        return out

    @property
    def sha256(self) -> str:
        """sha256 (64 hex digits) of the canonical JSON of :meth:`to_dict` (keys sorted, no spaces).

        What ``result.json`` and ``results.csv`` record as ``spec_sha256``: the spec a part was
        decided against, checkable from the ``spec`` entry of its result.json.
        """
        text = json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"), ensure_ascii=False)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _limit(doc: dict, key: str, where: str) -> float:
    value = doc[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} {key}: expected a finite number, got {value!r}")
    if value < 0:
        raise InputError(f"{where} {key}: must not be negative, got {value!r}")
    if key == "max_count" and value != int(value):
        raise InputError(f"{where} {key}: expected a whole number of imperfections, got {value!r}")
    return int(value) if key == "max_count" else float(value)


def _segments_cross(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Whether segments a-b and c-d properly cross (arrays of points, broadcast)."""

    def orient(p, q, r):
        return np.sign((q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1])
                       - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0]))

    return (orient(a, b, c) * orient(a, b, d) < 0) & (orient(c, d, a) * orient(c, d, b) < 0)


def _polygon(value, name: str) -> np.ndarray:
    """A simple polygon of at least three finite (x, y) vertices with a non-zero area."""
    try:
        pts = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a list of [x, y] vertices in mm, got {value!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InputError(f"{name}: expected a list of [x, y] vertices in mm, got shape {pts.shape}")
    if len(pts) >= 2 and np.array_equal(pts[0], pts[-1]):
        pts = pts[:-1]  # a closing repeat of the first vertex
    if len(pts) < 3:
        raise InputError(f"{name}: a polygon needs at least 3 vertices, got {len(pts)}")
    if not np.isfinite(pts).all():
        raise InputError(f"{name}: vertices must be finite numbers")
    nxt = np.roll(pts, -1, axis=0)
    n = len(pts)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # the first and last edges share a vertex
    i, j = i[keep], j[keep]
    # crossing first: a bow-tie's two lobes cancel in the signed area, and "no area" would hide why
    if _segments_cross(pts[i], nxt[i], pts[j], nxt[j]).any():
        raise InputError(f"{name}: the polygon is self-intersecting (its edges cross; give the vertices in order "
                         "around the outline)")
    area = 0.5 * float(np.sum(pts[:, 0] * nxt[:, 1] - nxt[:, 0] * pts[:, 1]))
    if abs(area) <= 1e-12 * max(1.0, float(np.ptp(pts)) ** 2):
        raise InputError(f"{name}: the polygon has no area (collinear or repeated vertices)")
    return pts


def parse_spec(doc, source: str = "spec") -> Spec:
    """Check a specification given as a dict (the content of ``spec.json``).

    Parameters
    ----------
    doc : dict
        See the module docstring for the keys.
    source : str
        Where it came from, for messages (e.g. the file name).

    Returns
    -------
    Spec

    Raises
    ------
    ValueError
        On an unknown key, a negative or non-numeric limit, a bad polygon, an unknown
        ``decision_rule`` or no limit at all; the message names the key.

    Examples
    --------
    >>> parse_spec({"max_depth_mm": 0.1, "decision_rule": "guard_band"}).limits
    {'max_depth_mm': 0.1}
    >>> parse_spec({"max_depth": 0.1})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: spec: unknown key 'max_depth' (known: max_depth_mm, max_length_mm, ..., texture)
    >>> parse_spec({"max_Sa_um": 0.8}).texture
    {'s_filter_mm': None, 'l_filter_mm': None, 'form': 'plane'}
    """
    if not isinstance(doc, dict):
        raise InputError(f"{source}: expected a JSON object of limits, got {type(doc).__name__}")
    unknown = [k for k in doc if k not in SPEC_KEYS]
    if unknown:
        raise InputError(f"{source}: unknown key {unknown[0]!r} (known: {', '.join(SPEC_KEYS)})")
    limits = {k: _limit(doc, k, source) for k in _LIMIT_KEYS if k in doc}
    if not limits:
        raise InputError(f"{source}: no limit given (give at least one of "
                         f"{', '.join(_LIMIT_KEYS)})")
    rule = doc.get("decision_rule", "simple")
    if rule not in DECISION_RULES:
        raise InputError(f"{source} decision_rule: expected one of {', '.join(DECISION_RULES)}, got {rule!r}")
    roi = _polygon(doc["roi_mm"], f"{source} roi_mm") if doc.get("roi_mm") is not None else None
    zones = doc.get("exclusion_zones_mm") or []
    if not isinstance(zones, list):
        raise InputError(f"{source} exclusion_zones_mm: expected a list of polygons, got {zones!r}")
    exclusions = tuple(_polygon(z, f"{source} exclusion_zones_mm[{k}]") for k, z in enumerate(zones))
    name = doc.get("name", "")
    if not isinstance(name, str):
        raise InputError(f"{source} name: expected text, got {name!r}")
    narrowest = _limit(doc, "min_width_mm", source) if "min_width_mm" in doc else None
    if narrowest is not None and narrowest <= 0:
        raise InputError(f"{source} min_width_mm: must be positive, got {narrowest!r}")
    given = doc.get("texture") is not None
    texture = None
    if given or any(k in TEXTURE_LIMITS for k in limits):
        texture = texture_options(doc.get("texture"), f"{source} texture")
    return Spec(limits, roi, exclusions, rule, name, narrowest, texture, given)


def load_spec(path) -> Spec:
    """Read and check ``spec.json``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Spec

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        Not valid JSON, or a bad specification (:func:`parse_spec`).
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"--spec: file {p} does not exist")
    try:
        text = p.read_text()
    except UnicodeDecodeError as exc:
        raise InputError(f"spec {p}: not valid JSON ({exc})") from None
    return parse_spec(loads_unique(text, f"spec {p}"), f"spec {p.name}")


def _raster(polygon: np.ndarray, x0: float, y0: float, pixel: float, shape) -> np.ndarray:
    """Pixels of an (H, W) grid whose centres a polygon (mm) covers (OpenCV scan conversion, 1/256 px)."""
    import cv2

    cols = (polygon[:, 0] - x0) / pixel
    rows = (y0 - polygon[:, 1]) / pixel
    pts = np.clip(np.round(np.stack([cols, rows], axis=1) * 256.0), -2**30, 2**30).astype(np.int32)
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=8)
    return mask.astype(bool)


def check_spec_field(spec: Spec, image_size, pixel_size_mm: float, *, blur_px: float = 0.0) -> None:
    """Check the spec's regions against the camera's field of view before any part is measured.

    Parameters
    ----------
    spec : Spec
    image_size : (H, W)
        The rig's image size, pixels.
    pixel_size_mm : float
        Pixel size on the reference plane, mm (the rig camera's nominal pixel).
    blur_px : float
        The images' blur (Gaussian standard deviation, pixels), for ``min_width_mm``.

    Raises
    ------
    InputError
        ``min_width_mm`` is below two pixels across: its depth is not resolved
        (:func:`photometric.resolution.require_resolution`, which warns with a
        :class:`photometric.resolution.ResolutionWarning` where it reads markedly shallow).
        ``roi_mm`` or an exclusion zone lies wholly outside the field of view (every part would
        pass, nothing of it being inspected), or the exclusion zones cover the whole inspected
        region. The message gives the field of view in mm (x right, y up, pixel centres on
        :data:`surfaces.grid.GRID_CONVENTION`).

    Examples
    --------
    >>> check_spec_field(parse_spec({"max_count": 0, "roi_mm": [[-1, -1], [1, -1], [1, 1]]}), (100, 100), 0.1)
    >>> check_spec_field(parse_spec({"max_count": 0, "roi_mm": [[50, 50], [60, 50], [60, 60]]}), (100, 100), 0.1)
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: spec roi_mm: lies wholly outside the field of view (x -4.95..4.95 mm, \
y -4.95..4.95 mm); nothing of a part would be inspected
    """
    if spec.min_width_mm is not None:
        from photometric.resolution import require_resolution

        require_resolution(spec.min_width_mm, pixel_size_mm, blur_px=blur_px, where="spec min_width_mm")
    if spec.roi is None and not spec.exclusions:
        return
    shape = (int(image_size[0]), int(image_size[1]))
    # a coarser grid over the same field for large images: the check needs coverage, not detail
    step = max(1, -(-max(shape) // 2048))
    xs, ys = pixel_axes(shape, pixel_size_mm)
    grid = (-(-shape[0] // step), -(-shape[1] // step))
    field = (f"x {xs[0]:.4g}..{xs[-1]:.4g} mm, y {ys[-1]:.4g}..{ys[0]:.4g} mm")

    def cover(poly):
        return _raster(poly, float(xs[0]), float(ys[0]), float(pixel_size_mm) * step, grid)

    inspected = np.ones(grid, bool)
    if spec.roi is not None:
        inspected = cover(spec.roi)
        if not inspected.any():
            raise InputError(f"spec roi_mm: lies wholly outside the field of view ({field}); nothing of a part "
                             "would be inspected")
    for k, zone in enumerate(spec.exclusions):
        covered = cover(zone)
        if not covered.any():
            raise InputError(f"spec exclusion_zones_mm[{k}]: lies wholly outside the field of view ({field})")
        inspected &= ~covered
    if not inspected.any():
        raise InputError(f"spec exclusion_zones_mm: the exclusion zones cover the whole inspected region "
                         f"({'roi_mm' if spec.roi is not None else 'the field of view'}, {field}); no part could "
                         "fail")
