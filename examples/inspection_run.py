"""A tiny inspection lot through the public API: calibrate a rig once, then measure and decide each part.

Four parts of a 20 mm plate (clean, a scratch clearly over the 0.10 mm depth limit, a dent
clearly under it, a crack at the limit) are rendered on a near-field rig (4 LEDs 200 mm
away, orthographic camera, 0.3 % noise, a flat field); the rig is calibrated from the flat
field (:func:`workbench.runs.photometric.calibrate_to_rig`) and every part goes through
:func:`workbench.inspect.part.inspect_part` under the ``guard_band`` rule: the stated
uncertainty of the LED positions gives each depth its expanded uncertainty U (k = 2), and a
depth within U of the limit is ``uncertain``, not passed or failed.

Prints, per part, the true and measured depth with U and the verdict, and writes the parts'
``overlay.png`` side by side as ``inspection_run.png`` into the folder given as the first
argument (default: a new temporary folder).

Run: ``python examples/inspection_run.py [OUT_DIR]``
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from photometric.camera import make_camera  # noqa: E402
from workbench.inspect.lot import LotPart, render_lot  # noqa: E402
from workbench.inspect.part import inspect_part  # noqa: E402
from workbench.inspect.spec import parse_spec  # noqa: E402
from workbench.runs.photometric import calibrate_to_rig  # noqa: E402

LIMIT_MM = 0.10
PARTS = (LotPart("clean", None, 0.0, 1.0, 11), LotPart("scratch_over", "scratch", 0.16, 0.9, 12),
         LotPart("dent_under", "dent", 0.04, 1.08, 13), LotPart("crack_limit", "crack", 0.10, 0.95, 14))
#: stated standard uncertainty of each LED coordinate (the image noise is estimated from the 4 lights' residuals)
UNCERTAINTY = {"method": "linear", "light_position_u_mm": 0.2}


def main(out_dir: Path) -> list:
    work = Path(tempfile.mkdtemp(prefix="inspection_lot_"))
    truth = render_lot(work, PARTS, size=224, field_mm=20.0)
    flats = sorted(str(p) for p in (work / "rig").glob("flat_*.png"))
    rig = work / "rig.json"
    calibrate_to_rig(rig, light_positions=work / "rig" / "light_positions.txt",
                     camera=make_camera("orthographic", pixel_size_mm=truth["pixel_size_mm"]), flat_field=flats,
                     flat_albedo=truth["flat_albedo"])
    spec = parse_spec({"max_depth_mm": LIMIT_MM, "decision_rule": "guard_band"})
    print(f"rig: {rig.name}, {truth['pixel_size_mm']:.4f} mm per pixel; limit {LIMIT_MM} mm, rule guard_band")
    rows = []
    for part in PARTS:
        figures = inspect_part(work / "parts" / part.id, out_dir / part.id, rig, spec, uncertainty=UNCERTAINTY)
        measured, u = figures["max_depth_mm"], figures["max_depth_U_mm"]
        rows.append((part.id, part.depth_mm, measured, u, figures["verdict"]))
        shown = f"{measured:.4f} mm" + ("" if u is None else f" ± {u:.4f} mm (k = 2)")
        print(f"{part.id:>13}: true depth {part.depth_mm:.3f} mm, measured {shown}, verdict {figures['verdict']}")
    fig, axes = plt.subplots(1, len(PARTS), figsize=(3.2 * len(PARTS), 3.4))
    for ax, (pid, depth, _, _, verdict) in zip(axes, rows, strict=True):
        ax.imshow(plt.imread(out_dir / pid / "overlay.png"))
        ax.set_title(f"{pid}\n{depth:.2f} mm: {verdict}", fontsize=9)
        ax.set_axis_off()
    path = out_dir / "inspection_run.png"
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)
    missed = [pid for pid, depth, measured, u, _ in rows if u is not None and abs(measured - depth) > u]
    print("parts whose measured depth misses the true one by more than its U: "
          + (", ".join(missed) if missed else "none")
          + " (U holds the image noise, the LED positions and the pixel grid of the stated model)")
    result = json.loads((out_dir / PARTS[1].id / "result.json").read_text())
    print(f"result.json of {PARTS[1].id}: verdict {result['verdict']}, decided by {result['decided_by']}")
    print(f"wrote {path}")
    return rows


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="inspection_run_")))
