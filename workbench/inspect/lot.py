"""Rendered production lots for inspection tests and benchmarks (truth known, no file is precomputed).

A lot is a near-field rig (LEDs on a ring about 200 mm away, an orthographic camera over
the part) and parts rendered with :func:`datasets_synthetic.nearfield.render_near_field`:
clean plates and plates with one scratch, crack or dent
(:func:`datasets_synthetic.heightfields.inspection_part`) of known depth around the
limit, image noise, and a different albedo texture and brightness per part; one exposure
for the whole lot, so the flat field stays valid. :func:`render_lot` writes::

    OUT/rig/flat_001.png ...      flat-field images (the calibration target), 16 bit
    OUT/rig/light_positions.txt   LED positions, mm
    OUT/parts/<id>/001.png ...    one 16-bit image per light, with filenames.txt
    OUT/truth.json                per part: defect kind, depth, width, length (mm)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from surfaces.io import atomic_write_text, write_json, write_png
from surfaces.validate import InputError

__all__ = ["LotPart", "lot_plan", "render_lot"]


@dataclass(frozen=True)
class LotPart:
    """One part of a lot.

    Attributes
    ----------
    id : str
        Folder name.
    defect : str or None
        ``scratch``, ``crack``, ``dent`` or None (a clean part).
    depth_mm : float
        True defect depth (0 for a clean part).
    albedo_scale : float
        Brightness of this part's albedo texture relative to the lot's.
    seed : int
        Seed of its texture and noise.
    """

    id: str
    defect: str | None
    depth_mm: float
    albedo_scale: float
    seed: int


def lot_plan(n_parts: int = 40, limit_mm: float = 0.10, seed: int = 0) -> list[LotPart]:
    """A production lot around a depth limit: clean, clearly under, borderline and clearly over.

    Parameters
    ----------
    n_parts : int
        Parts in the lot (at least 4).
    limit_mm : float
        The depth limit the defects are sized around.
    seed : int

    Returns
    -------
    list of LotPart
        About 30 % clean, 25 % at 0.3-0.6 x the limit, 20 % at 0.93-1.07 x (borderline)
        and 25 % at 1.5-2.2 x (clearly over); defect kinds cycle scratch, crack, dent.
    """
    if int(n_parts) < 4:
        raise InputError(f"n_parts: a lot needs at least 4 parts, got {n_parts}")
    rng = np.random.default_rng(seed)
    n = int(n_parts)
    n_clean, n_under, n_border = round(0.3 * n), round(0.25 * n), round(0.2 * n)
    n_over = n - n_clean - n_under - n_border
    factors = ([0.0] * n_clean + list(rng.uniform(0.3, 0.6, n_under)) + list(rng.uniform(0.93, 1.07, n_border))
               + list(rng.uniform(1.5, 2.2, n_over)))
    order = rng.permutation(n)
    kinds = ("scratch", "crack", "dent")
    parts = []
    for k, i in enumerate(order):
        f = factors[i]
        parts.append(LotPart(f"part_{k + 1:03d}", kinds[k % 3] if f > 0 else None, float(f * limit_mm),
                             float(rng.uniform(0.85, 1.1)), int(seed * 1000 + k)))
    return parts


def render_lot(out, parts, *, size=256, field_mm: float = 20.0, n_lights: int = 4, light_distance_mm: float = 200.0,
               slant_deg: float = 40.0, noise: float = 0.003, seed: int = 0) -> dict:
    """Render a lot's flat field and parts into ``out`` (layout in the module docstring).

    Parameters
    ----------
    out : str or Path
    parts : list of LotPart
    size : int or (H, W)
        Image size, pixels.
    field_mm : float
        Width of the field of view, mm (the pixel size is ``field_mm / W``).
    n_lights : int
    light_distance_mm, slant_deg : float
        The LED ring: distance from the origin (mm) and slant (degrees).
    noise : float
        Gaussian image noise, full-scale units.
    seed : int
        Seed of the flat field's noise.

    Returns
    -------
    dict
        The content of ``truth.json``: ``pixel_size_mm``, ``image_size``, ``lights``,
        ``exposure``, ``noise`` and ``parts`` (id, defect, depth_mm, width_mm, length_mm,
        albedo_scale).
    """
    from datasets_synthetic.cameras import orthographic_camera
    from datasets_synthetic.heightfields import AnalyticSurface, inspection_part
    from datasets_synthetic.nearfield import render_near_field
    from datasets_synthetic.point_lights import ring_point_lights
    from datasets_synthetic.render import texture_albedo
    from surfaces.grid import image_shape

    root = Path(out)
    h, w = image_shape(size)
    ps = float(field_mm) / w
    cam = orthographic_camera((h, w), ps)
    lights = ring_point_lights(int(n_lights), slant_deg, light_distance_mm)
    # one exposure for the lot, with head room for the brightest part
    first = render_near_field(AnalyticSurface(), cam, lights, 0.9, flat_albedo=0.8, seed=seed)
    exposure = 0.8 * first.exposure
    flats = render_near_field(AnalyticSurface(), cam, lights, 0.9, exposure=exposure, flat_albedo=0.8, noise=noise,
                              bit_depth=16, seed=seed).flats
    rig = root / "rig"
    for k, img in enumerate(flats):
        write_png(rig / f"flat_{k + 1:03d}.png", _u16(img))
    atomic_write_text(rig / "light_positions.txt", "".join(f"{x:.10f} {y:.10f} {z:.10f}\n"
                                                            for x, y, z in lights.positions))
    records = []
    for part in parts:
        if part.defect is None:
            scene, truth = AnalyticSurface(), {"width_mm": 0.0, "length_mm": 0.0}
        else:
            scene = inspection_part((h, w), ps, part.defect, depth_mm=part.depth_mm)
            d = scene.defects[0]
            truth = {"width_mm": float(d["width_mm"]), "length_mm": float(d["length_mm"])}
        rho = np.clip(part.albedo_scale * texture_albedo((h, w), 0.6, 0.9, max(4.0, w / 24), part.seed), 0.05, 1.0)
        images = render_near_field(scene, cam, lights, rho, exposure=exposure, flat_albedo=0.8, noise=noise,
                                   bit_depth=16, seed=part.seed).images
        folder = root / "parts" / part.id
        names = [f"{k + 1:03d}.png" for k in range(len(images))]
        for name, img in zip(names, images):
            write_png(folder / name, _u16(img))
        atomic_write_text(folder / "filenames.txt", "\n".join(names) + "\n")
        records.append({**asdict(part), **truth})
    content = {"pixel_size_mm": ps, "image_size": [h, w], "light_positions_mm": lights.positions.tolist(),
               "flat_albedo": 0.8, "exposure": exposure, "noise": noise, "parts": records}
    write_json(root / "truth.json", content)
    return content


def _u16(img: np.ndarray) -> np.ndarray:
    return np.round(np.clip(img, 0.0, 1.0) * 65535.0).astype(np.uint16)
