"""Synthetic inputs for the batch tests: image triads and CT phantom structure sets."""

from __future__ import annotations

from pathlib import Path

SIZE = 64
PHANTOMS = (
    ("ellipsoid", {}),
    ("kidney", {}),
    ("ring", {}),
    ("lobes", {}),
    ("ellipsoid", {"a": 18.0, "b": 12.0, "c": 15.0}),
    ("lobes", {"radii_mm": (18.0, 12.0)}),
)


def make_triads(root: Path, n: int, size: int = SIZE) -> list[Path]:
    """Write ``n`` DiLiGenT-style triad folders ``root/line<i // 6>/triad_<i>``; return them."""
    from datasets_synthetic.render import make_triad_folder

    scenes = ("plate", "crack", "dent", "scratch", "bumps", "sphere")
    folders = []
    for i in range(n):
        folder = root / f"line{i // 6}" / f"triad_{i:02d}"
        make_triad_folder(folder, scene=scenes[i % len(scenes)], size=size, seed=i)
        folders.append(folder)
    return folders


def make_phantoms(root: Path, n: int) -> list[Path]:
    """Write ``n`` phantom folders ``root/patient_<i>`` with an RT Structure Set each; return them."""
    from datasets_synthetic.phantoms import make_phantom, write_phantom

    folders = []
    for i in range(n):
        shape, params = PHANTOMS[i % len(PHANTOMS)]
        folder = root / f"patient_{i:02d}"
        write_phantom(folder, make_phantom(shape, **params), 4.0, 1.5, fmt="rtstruct", n_points=48)
        folders.append(folder)
    return folders
