"""Fuzzing the public readers: random bytes and truncated or damaged copies of every input format.

Each reader must either read the file or fail with a clean error of the
ValueError family (what ``workbench`` prints as one line with exit code 2),
never with a traceback from inside a library (``AttributeError``, ``KeyError``,
``IndexError``, ``struct.error``, ``zipfile.BadZipFile``, ...).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from workbench.cli import INPUT_ERRORS

EXAMPLES = settings(max_examples=25, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _png() -> bytes:
    ramp = (np.arange(64, dtype=np.uint16).reshape(8, 8) * 1000).astype(np.uint16)
    return cv2.imencode(".png", ramp)[1].tobytes()


def _mesh(suffix: str) -> bytes:
    from surfaces.io import write_mesh
    from surfaces.mesh import TriangleMesh

    tetra = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return _bytes_of(lambda path: write_mesh(tetra, path), suffix)


def _patches() -> bytes:
    from surfaces.coons import from_grid
    from surfaces.io import save_patches

    x, y = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0], indexing="ij")
    return _bytes_of(lambda path: save_patches(from_grid(np.stack([x, y, x * y], -1)), path), ".npz")


def _bytes_of(write, suffix: str) -> bytes:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"f{suffix}"
        write(path)
        return path.read_bytes()


@pytest.fixture(scope="module")
def phantom(tmp_path_factory):
    """A small CT series with its RT Structure Set and contour JSON (datasets_synthetic)."""
    from datasets_synthetic.phantoms import make_phantom, write_phantom

    folder = tmp_path_factory.mktemp("phantom")
    write_phantom(folder, make_phantom("ellipsoid", a=6.0, b=5.0, c=5.0), spacing=2.5, pixel=1.0, fmt="rtstruct",
                  n_points=24, n_surface=200)
    return folder


def _read_then_check(read, path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        read(path)
    except INPUT_ERRORS:
        pass


def _readers():
    from photometric.io import read_image, read_mask
    from photometric.io import load_lights
    from slices.io import list_rois, read_contour_json, read_rtstruct
    from surfaces.io import load_patches, read_mesh
    from workbench.batch import read_manifest

    return {
        "png image": (".png", read_image),
        "png mask": (".png", read_mask),
        "ply": (".ply", read_mesh),
        "stl": (".stl", read_mesh),
        "obj": (".obj", read_mesh),
        "npz patches": (".npz", load_patches),
        "contour json": (".json", read_contour_json),
        "rtstruct rois": (".dcm", list_rois),
        "rtstruct roi": (".dcm", lambda p: read_rtstruct(p, 1)),
        "lights text": (".txt", load_lights),
        "lights json": (".json", load_lights),
        "manifest csv": (".csv", lambda p: read_manifest(p, "slices")),
        "manifest jsonl": (".jsonl", lambda p: read_manifest(p, "photometric")),
    }


SAMPLES = {
    "png image": _png,
    "png mask": _png,
    "ply": lambda: _mesh(".ply"),
    "stl": lambda: _mesh(".stl"),
    "obj": lambda: _mesh(".obj"),
    "npz patches": _patches,
    "lights text": lambda: b"0 0 1\n0.5 0 0.866\n0 0.5 0.866\n",
    "lights json": lambda: json.dumps({"lights": [[0, 0, 1], [0.5, 0, 0.866], [0, 0.5, 0.866]]}).encode(),
    "manifest csv": lambda: b"id,input,roi,rays\na,cases/rtstruct.dcm,Heart;Lung,32\n",
    "manifest jsonl": lambda: (json.dumps({"images": "a.png;b.png;c.png", "lights": "L.txt", "select": "triad"})
                               + "\n").encode(),
}


def _sample(name: str, phantom_folder: Path) -> bytes:
    if name == "contour json":
        return (phantom_folder / "contours.json").read_bytes()
    if name.startswith("rtstruct"):
        return (phantom_folder / "rtstruct.dcm").read_bytes()
    return SAMPLES[name]()


NAMES = sorted(_readers())


@pytest.mark.parametrize("name", NAMES)
def test_valid_samples_are_read(name, phantom, tmp_path):
    """The seeds of the fuzzing are valid files: the readers accept them."""
    suffix, read = _readers()[name]
    path = tmp_path / f"in{suffix}"
    path.write_bytes(_sample(name, phantom))
    read(path)


@pytest.mark.parametrize("name", NAMES)
@EXAMPLES
@given(data=st.binary(max_size=2048))
def test_random_bytes_give_a_clean_error(name, phantom, tmp_path, data):
    suffix, read = _readers()[name]
    _read_then_check(read, tmp_path / f"random{suffix}", data)


@pytest.mark.parametrize("name", NAMES)
@EXAMPLES
@given(cut=st.floats(0.0, 1.0, exclude_max=True), flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True),
                                                                           st.integers(0, 255)), max_size=4))
def test_truncated_or_damaged_copies_give_a_clean_error(name, phantom, tmp_path, cut, flips):
    suffix, read = _readers()[name]
    sample = bytearray(_sample(name, phantom))
    for where, value in flips:  # a few damaged bytes, then the file cut short
        sample[int(where * len(sample))] = value
    _read_then_check(read, tmp_path / f"cut{suffix}", bytes(sample[: int(cut * len(sample))]))


@EXAMPLES
@given(cut=st.floats(0.0, 1.0, exclude_max=True), which=st.integers(0, 100))
def test_ct_series_with_a_truncated_slice_gives_a_clean_error(phantom, tmp_path, cut, which):
    from slices.io import read_ct_series

    series = tmp_path / "ct"
    shutil.rmtree(series, ignore_errors=True)
    shutil.copytree(phantom / "ct", series)
    files = sorted(series.iterdir())
    victim = files[which % len(files)]
    victim.write_bytes(victim.read_bytes()[: int(cut * victim.stat().st_size)])
    try:
        read_ct_series(series, hu_min=100)
    except INPUT_ERRORS:
        pass
