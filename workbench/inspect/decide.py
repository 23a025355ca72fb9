"""Verdicts: each imperfection and each part against a :class:`~workbench.inspect.spec.Spec`.

Two decision rules (``spec.decision_rule``):

``simple``
    A quantity conforms when its value is within the limit (``value <= limit``; for the
    lower limit ``min_distance_mm``, ``value >= limit``).
``guard_band``
    ISO 14253-1: with the expanded uncertainty ``U`` (k = 2) of the measured value, a
    quantity fails only when ``value - U > limit`` (non-conformance proven), passes only
    when ``value + U < limit`` (conformance proven), and is ``uncertain`` between the two.
    An exact quantity (``U = 0``, the count) passes at ``value <= limit``. ``U`` is read
    from each imperfection's ``uncertainty_k2`` (what ``photometric`` states with the
    measurement); a quantity without one makes ``guard_band`` refuse with a ``ValueError``
    (a U is never invented).

Part quantities: ``count`` (imperfections that decide: centre inside ``roi_mm`` and outside
every exclusion zone), ``total_area_mm2`` (their summed area; ``U`` the sum of their area
``U`` s, since the light and pixel-size errors behind them are shared, fully correlated)
and ``min_distance_mm`` (the smallest gap between two imperfection outlines, each outline
the rectangle of its length along its axis by its maximum width; ``U`` propagated from the
two outlines' extents: half of each one's larger length or width ``U``).

Texture (ISO 25178-2): the spec's texture limits (:data:`workbench.runs.texture.TEXTURE_LIMITS`)
are checked against the part's texture parameters with the same rules
(:func:`workbench.runs.texture.judge_texture`; the noise-bias corrected value and its U when
the texture has an uncertainty).

A part's verdict is the worst of all its checks (imperfections, part, texture): ``fail`` over
``uncertain`` over ``pass``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from surfaces.grid import pixel_axes
from workbench.inspect.spec import IMPERFECTION_LIMITS, Spec
from workbench.runs.texture import TEXTURE_LIMITS, judge_texture
from surfaces.validate import InputError

__all__ = ["VERDICTS", "Decision", "decide_value", "center_mm", "outline_mm", "inside_polygon", "outline_gap",
           "judge"]

#: verdicts from best to worst
VERDICTS = ("pass", "uncertain", "fail")


def _worst(verdicts) -> str:
    return max(verdicts, key=VERDICTS.index, default="pass")


def decide_value(value: float, U: float | None, limit: float, rule: str, lower: bool = False) -> str:
    """Verdict of one measured quantity against one limit.

    Parameters
    ----------
    value : float
        Measured value.
    U : float or None
        Its expanded uncertainty (k = 2); required by ``guard_band``.
    limit : float
        Upper limit (or lower limit with ``lower``).
    rule : {"simple", "guard_band"}
    lower : bool, optional
        ``limit`` is a lower limit (the value must reach it).

    Returns
    -------
    {"pass", "uncertain", "fail"}

    Raises
    ------
    ValueError
        ``guard_band`` without ``U``, a negative ``U``, or an unknown rule.

    Examples
    --------
    >>> decide_value(0.12, 0.01, 0.10, "guard_band"), decide_value(0.105, 0.01, 0.10, "guard_band")
    ('fail', 'uncertain')
    >>> decide_value(0.105, None, 0.10, "simple"), decide_value(0.08, 0.01, 0.10, "guard_band")
    ('fail', 'pass')
    """
    sign = -1.0 if lower else 1.0
    v, lim = sign * float(value), sign * float(limit)
    if rule == "simple":
        return "pass" if v <= lim else "fail"
    if rule != "guard_band":
        raise InputError(f"decision_rule: expected 'simple' or 'guard_band', got {rule!r}")
    if U is None:
        raise InputError("guard_band: the measured value has no expanded uncertainty U")
    u = float(U)
    if not np.isfinite(u) or u < 0:
        raise InputError(f"guard_band: U must be a finite non-negative number, got {U!r}")
    if v - u > lim:
        return "fail"
    if v + u < lim or (u == 0.0 and v <= lim):
        return "pass"
    return "uncertain"


def center_mm(defect: dict, shape, pixel_size: float) -> np.ndarray:
    """Centre ``(x, y)`` of an imperfection in mm (rig frame).

    Parameters
    ----------
    defect : dict
        A record of :func:`photometric.defects.measure_defects` (its ``center_mm`` when
        present, else ``center_px`` on the grid of :data:`surfaces.grid.GRID_CONVENTION`).
    shape : (H, W)
        Image size, pixels.
    pixel_size : float
        Pixel size, mm.

    Returns
    -------
    numpy.ndarray, shape (2,)
    """
    if defect.get("center_mm") is not None:
        return np.asarray(defect["center_mm"], float)
    xs, ys = pixel_axes(shape, pixel_size)
    row, col = defect["center_px"]
    return np.array([xs[0] + col * pixel_size, ys[0] - row * pixel_size])


def outline_mm(defect: dict, center) -> np.ndarray:
    """Corners (4, 2) of an imperfection's outline in mm: length along its axis by its maximum width.

    Parameters
    ----------
    defect : dict
        ``length_mm``, ``max_width_mm`` and ``axis_deg`` (from +x towards +y).
    center : array_like, shape (2,)
        Its centre, mm (:func:`center_mm`).

    Returns
    -------
    numpy.ndarray, shape (4, 2)
    """
    a = np.radians(float(defect["axis_deg"]))
    u = np.array([np.cos(a), np.sin(a)]) * 0.5 * float(defect["length_mm"])
    v = np.array([-np.sin(a), np.cos(a)]) * 0.5 * float(defect["max_width_mm"])
    c = np.asarray(center, float)
    return np.stack([c - u - v, c + u - v, c + u + v, c - u + v])


def inside_polygon(points, polygon) -> np.ndarray:
    """Even-odd test: which points lie inside a polygon.

    Parameters
    ----------
    points : array_like, shape (M, 2)
    polygon : array_like, shape (V, 2)

    Returns
    -------
    numpy.ndarray, shape (M,), bool

    Examples
    --------
    >>> inside_polygon([[0.5, 0.5], [2, 0.5]], [[0, 0], [1, 0], [1, 1], [0, 1]]).tolist()
    [True, False]
    """
    p = np.atleast_2d(np.asarray(points, float))
    q = np.asarray(polygon, float)
    x, y = p[:, :1], p[:, 1:2]
    x1, y1 = q[:, 0], q[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    spans = (y1 > y) != (y2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
    return (np.count_nonzero(spans & (x < x_cross), axis=1) % 2) == 1


def _separated(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(0) < pb.min(0)) | (pb.max(0) < pa.min(0))):
            return True
    return False


def _point_segment(points: np.ndarray, poly: np.ndarray) -> float:
    """Smallest distance from points (M, 2) to the edges of a polygon (V, 2)."""
    a = poly[None, :, :]
    d = np.roll(poly, -1, axis=0)[None] - a
    t = np.clip(np.sum((points[:, None, :] - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-300), 0, 1)
    nearest = a + t[..., None] * d
    return float(np.min(np.linalg.norm(points[:, None, :] - nearest, axis=2)))


def outline_gap(a, b) -> float:
    """Gap (mm) between two convex outlines: 0 when they touch or overlap.

    Parameters
    ----------
    a, b : array_like, shape (V, 2)
        Convex polygons (:func:`outline_mm`).

    Returns
    -------
    float

    Examples
    --------
    >>> sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> outline_gap(sq, sq + [3, 0]), outline_gap(sq, sq + [0.5, 0.5])
    (2.0, 0.0)
    """
    pa, pb = np.asarray(a, float), np.asarray(b, float)
    if not _separated(pa, pb):
        return 0.0
    return min(_point_segment(pa, pb), _point_segment(pb, pa))


@dataclass(frozen=True)
class Decision:
    """What :func:`judge` decided for one part.

    Attributes
    ----------
    verdict : {"pass", "fail", "uncertain"}
    rule : {"simple", "guard_band"}
    imperfections : list of dict
        One record per imperfection: ``id``, ``kind``, ``region`` (``inspected``,
        ``outside_roi`` or ``excluded``), ``verdict`` (None when it does not decide),
        ``center_mm``, ``outline_mm`` (4 corners), ``axis_deg``, ``values`` (quantity ->
        ``{"value", "U"}``, mm or mm^2, ``U`` expanded k = 2 or None) and ``checks``.
    part_checks : list of dict
        The part quantities checked.
    decided_by : list of str
        The checks that gave the verdict (empty for a pass: every check passed).
    texture_checks : list of dict
        The texture parameters checked (:func:`workbench.runs.texture.judge_texture`: each
        also with ``limit_key`` and ``unit``); empty when the spec limits none.

    Each check is ``{"quantity", "value", "U", "limit", "limit_kind" ("max" or "min"),
    "rule", "verdict"}``.
    """

    verdict: str
    rule: str
    imperfections: list
    part_checks: list
    decided_by: list
    texture_checks: list = field(default_factory=list)


#: imperfection quantities recorded in result.json (value and U), whether limited or not
RECORDED = ("max_depth_mm", "length_mm", "mean_width_mm", "max_width_mm", "area_mm2", "volume_mm3")


def _u(defect: dict, quantity: str) -> float | None:
    unc = defect.get("uncertainty_k2") or {}
    value = unc.get(quantity) if isinstance(unc, dict) else None
    return None if value is None else float(value)


def _check(quantity, value, U, limit, rule, lower=False, where="") -> dict:
    if rule == "guard_band" and U is None:
        raise InputError(f"guard_band: {where}{quantity} has no expanded uncertainty U (measure with "
                         "uncertainty, or use decision_rule 'simple')")
    return {"quantity": quantity, "value": value, "U": U, "limit": limit, "limit_kind": "min" if lower else "max",
            "rule": rule, "verdict": decide_value(value, U, limit, rule, lower)}


def judge(defects, spec: Spec, shape, pixel_size: float, texture: dict | None = None) -> Decision:
    """Decide one part: every imperfection and the part quantities against the spec.

    Parameters
    ----------
    defects : list of dict
        Records of :func:`photometric.defects.measure_defects`, each optionally with
        ``uncertainty_k2`` (quantity -> expanded uncertainty, k = 2).
    spec : Spec
    shape : (H, W)
        Image size, pixels (centres from ``center_px``).
    pixel_size : float
        Pixel size, mm.
    texture : dict, optional
        The part's texture (what ``texture.json`` holds); required when the spec limits a
        texture parameter.

    Returns
    -------
    Decision

    Raises
    ------
    ValueError
        ``guard_band`` and an imperfection quantity or texture parameter the spec limits has
        no ``U``; a texture limit without a texture.
    """
    rule = spec.decision_rule
    records = []
    for d in defects:
        c = center_mm(d, shape, pixel_size)
        region = "inspected"
        if spec.roi is not None and not inside_polygon(c[None], spec.roi)[0]:
            region = "outside_roi"
        elif any(inside_polygon(c[None], z)[0] for z in spec.exclusions):
            region = "excluded"
        values = {q: {"value": float(d[q]), "U": _u(d, q)} for q in RECORDED if q in d}
        checks = []
        if region == "inspected":
            for key, q in IMPERFECTION_LIMITS.items():
                if key in spec.limits:
                    checks.append(_check(q, values[q]["value"], values[q]["U"], spec.limits[key], rule,
                                         where=f"imperfection {d['id']} "))
        records.append({
            "id": int(d["id"]), "kind": d.get("kind", "depression"), "region": region,
            "verdict": _worst(c["verdict"] for c in checks) if region == "inspected" else None,
            "center_mm": c.tolist(), "outline_mm": outline_mm(d, c).tolist(),
            "axis_deg": float(d["axis_deg"]), "values": values, "checks": checks,
        })
    counted = [(r, d) for r, d in zip(records, defects) if r["region"] == "inspected"]
    part = []
    if "max_count" in spec.limits:
        part.append(_check("count", len(counted), 0.0, spec.limits["max_count"], rule))
    if "max_total_area_mm2" in spec.limits:
        areas = [r["values"]["area_mm2"] for r, _ in counted]
        us = [a["U"] for a in areas]
        U = None if any(u is None for u in us) else float(sum(us))
        part.append(_check("total_area_mm2", float(sum(a["value"] for a in areas)), U,
                           spec.limits["max_total_area_mm2"], rule, where="part "))
    if "min_distance_mm" in spec.limits and len(counted) >= 2:
        best, U = np.inf, None
        for i in range(len(counted)):
            for j in range(i + 1, len(counted)):
                gap = outline_gap(counted[i][0]["outline_mm"], counted[j][0]["outline_mm"])
                if gap < best:
                    ext = [[_u(d, "length_mm"), _u(d, "mean_width_mm")] for d in (counted[i][1], counted[j][1])]
                    flat = [u for pair in ext for u in pair]
                    U = None if any(u is None for u in flat) else 0.5 * (max(ext[0]) + max(ext[1]))
                    best = gap
        part.append(_check("min_distance_mm", float(best), U, spec.limits["min_distance_mm"], rule, lower=True,
                           where="part "))
    texture_checks = []
    if any(k in TEXTURE_LIMITS for k in spec.limits):
        if texture is None:
            raise InputError("spec: limits a texture parameter, but the part's texture was not measured")
        texture_checks = judge_texture(texture, spec.limits, rule)
    verdicts = [r["verdict"] for r, _ in counted] + [c["verdict"] for c in part + texture_checks]
    verdict = _worst(verdicts)
    decided_by = []
    if verdict != "pass":
        for r, _ in counted:
            decided_by += [f"imperfection {r['id']} {c['quantity']}" for c in r["checks"] if c["verdict"] == verdict]
        decided_by += [f"part {c['quantity']}" for c in part if c["verdict"] == verdict]
        decided_by += [f"texture {c['quantity']}" for c in texture_checks if c["verdict"] == verdict]
    return Decision(verdict, rule, records, part, decided_by, texture_checks)
