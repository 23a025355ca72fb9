"""A CT structure end to end: a synthetic phantom's contour stack -> one closed solid, volume vs exact.

``datasets_synthetic`` cuts an ellipsoid and a kidney-shaped phantom into planar
contours 2.5 mm apart (unequal point counts per slice, as a planning system draws
them); ``slices`` turns each stack into one interpolating surface with caps
(seed 000), a mesh, a volume and an area.

What a metrologist checks, against the phantoms' exact volume and area:

* the relative volume and area errors of the reconstructed solid (caps ``half``:
  the end slices' half slab, the convention of treatment-planning systems);
* the planning systems' slab count for comparison (area of each contour x spacing);
* that the surface passes through every contour point (its largest deviation).

Run: ``python examples/ct_structure_phantom.py [out_folder]``; writes ``ct_structure_phantom.png``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from datasets_synthetic.phantoms import make_phantom  # noqa: E402
from slices import Contour, reconstruct_contours  # noqa: E402

SPACING_MM = 2.5


def main(out: Path) -> dict:
    rows = {}
    fig = plt.figure(figsize=(11, 4.8))
    for k, (shape, params) in enumerate((("ellipsoid", {"a": 30.0, "b": 20.0, "c": 15.0}), ("kidney", {}))):
        phantom = make_phantom(shape, **params)
        stack = [Contour(c["z"], c["points"]) for c in phantom.contours(SPACING_MM, n_points=96, seed=k)]
        rec = reconstruct_contours(stack, spacing=SPACING_MM, caps="half", mesh=True)
        rows[shape] = {
            "contours": len(stack),
            "points": int(sum(len(c.points) for c in stack)),
            "volume_mm3": rec.volume_mm3,
            "exact_volume_mm3": phantom.volume_mm3,
            "volume_rel_error": rec.volume_mm3 / phantom.volume_mm3 - 1,
            "slab_volume_rel_error": rec.slab_volume_mm3 / phantom.volume_mm3 - 1,
            "area_rel_error": rec.area_mm2 / phantom.area_mm2 - 1,
            "max_deviation_mm": rec.max_deviation_mm,
        }
        mesh = rec.bodies[0].mesh
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.plot_trisurf(*mesh.vertices.T, triangles=mesh.triangles, color="0.8", alpha=0.35, linewidth=0)
        for c in stack:
            closed = np.vstack([c.points, c.points[:1]])
            ax.plot(closed[:, 0], closed[:, 1], np.full(len(closed), c.z), color="tab:blue", lw=0.7)
        ax.set_box_aspect(np.ptp(mesh.vertices, axis=0))
        ax.set_title(f"{shape}: volume {100 * rows[shape]['volume_rel_error']:+.2f} % vs exact", fontsize=9)

    print(f"{'':>10} {'contours':>8} {'volume mm3':>11} {'exact':>11} {'dV/V':>9} {'slab dV/V':>10} {'dA/A':>9} "
          f"{'max dev mm':>10}")
    for shape, r in rows.items():
        print(f"{shape:>10} {r['contours']:>8} {r['volume_mm3']:>11.1f} {r['exact_volume_mm3']:>11.1f} "
              f"{r['volume_rel_error']:>+9.2%} {r['slab_volume_rel_error']:>+10.2%} {r['area_rel_error']:>+9.2%} "
              f"{r['max_deviation_mm']:>10.1e}")
    fig.savefig(out / "ct_structure_phantom.png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return rows


if __name__ == "__main__":
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="ct_structure_"))
    folder.mkdir(parents=True, exist_ok=True)
    result = main(folder)
    for r in result.values():
        assert abs(r["volume_rel_error"]) < 0.03 and r["max_deviation_mm"] < 1e-6
    print(f"figure: {folder / 'ct_structure_phantom.png'}")
