"""Reading photometric-stereo inputs: images, masks and DiLiGenT-style folders.

A DiLiGenT-style folder holds ``filenames.txt`` (image files in light order),
``light_directions.txt`` (``x y z`` per row), optionally ``light_intensities.txt``
(``r g b`` per row), ``mask.png``, ``normal_gt.npy`` (or DiLiGenT's ``Normal_gt.mat``)
and ``triad.txt`` (three of the file names). The RobustPhotometricStereo layout
(``imageNNN.npy`` files, ``lights.npy`` whose row NNN is image NNN's light,
``gt_normal.npy``) is read too; its lights are in the same frame as DiLiGenT's (checked on
the shared ``rps_bunny``: of the eight axis-sign choices only the identity makes least
squares reproduce ``gt_normal``, to 3e-6 deg median; flipping y gives about 35 deg).
Images are 8/16-bit PNG/TIFF (read with OpenCV ``IMREAD_UNCHANGED``, so 16 bits survive,
and converted BGR -> RGB) or ``.npy``.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from photometric.lights import load_intensities, load_lights, validate_lights

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg", ".npy", ".exr")


@dataclass(frozen=True)
class PhotometricData:
    """Everything a photometric-stereo solve needs, as read from disk.

    Attributes
    ----------
    images : numpy.ndarray, shape (N, H, W) or (N, H, W, 3), float32
        Linear images scaled to [0, 1] by their integer type's maximum (float files
        are kept as they are); RGB order.
    lights : numpy.ndarray, shape (N, 3), float64
        Unit light directions (:data:`photometric.lights.CONVENTION`).
    intensities : numpy.ndarray, shape (N, 3), float64
        Per-light RGB intensities (ones when the folder has none).
    mask : numpy.ndarray, shape (H, W), bool
        Object mask (all True when the folder has none).
    normal_gt : numpy.ndarray or None, shape (H, W, 3), float32
        Ground-truth normals when the folder has them.
    names : tuple of str
        Image file names, in light order.
    """

    images: np.ndarray
    lights: np.ndarray
    intensities: np.ndarray
    mask: np.ndarray
    normal_gt: np.ndarray | None
    names: tuple[str, ...]


def _read_array(path, name: str) -> np.ndarray:
    """A ``.npy`` array or an image file read by OpenCV with all its bits (BGR order)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: file {p} does not exist")
    if p.suffix.lower() == ".npy":
        return np.load(p, allow_pickle=False)
    arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if arr is None:
        raise ValueError(f"{name}: OpenCV cannot read {p}")
    return arr


def read_image(path) -> np.ndarray:
    """Read one image as float32 in [0, 1] (integer types scaled by their maximum).

    Parameters
    ----------
    path : str or Path
        PNG/TIFF/BMP/JPEG (OpenCV, ``IMREAD_UNCHANGED``: 16 bits kept, BGR -> RGB,
        alpha dropped) or ``.npy`` (kept as stored).

    Returns
    -------
    numpy.ndarray, shape (H, W) or (H, W, 3), float32
    """
    p = Path(path)
    arr = _read_array(p, "image")
    if arr.ndim == 3 and p.suffix.lower() != ".npy":
        arr = arr[..., :3][..., ::-1]  # OpenCV's BGR(A) to RGB
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3):
        raise ValueError(f"image: {p} has unsupported shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.integer):
        return (arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)).astype(np.float32)
    out = np.ascontiguousarray(arr, dtype=np.float32)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"image: {p} contains NaN or infinite values")
    return out


def read_images(paths: Sequence) -> np.ndarray:
    """Read several images of one size into a stack.

    Parameters
    ----------
    paths : sequence of str or Path
        Image files (see :func:`read_image`).

    Returns
    -------
    numpy.ndarray, shape (N, H, W) or (N, H, W, 3), float32
    """
    if len(paths) == 0:
        raise ValueError("images: no image files given")
    first = read_image(paths[0])
    out = np.empty((len(paths),) + first.shape, np.float32)
    out[0] = first
    for k, path in enumerate(paths[1:], start=1):
        img = read_image(path)
        if img.shape != first.shape:
            raise ValueError(f"images: {path} has shape {img.shape}, {paths[0]} has {first.shape}")
        out[k] = img
    return out


def read_mask(path, shape: tuple[int, int] | None = None) -> np.ndarray:
    """Read a binary mask (any non-zero pixel is inside).

    Parameters
    ----------
    path : str or Path
        Image (``.png`` etc.) or ``.npy`` file.
    shape : tuple of int, optional
        Required (H, W).

    Returns
    -------
    numpy.ndarray, shape (H, W), bool
    """
    p = Path(path)
    arr = _read_array(p, "mask")
    if arr.ndim == 3:
        arr = arr.max(axis=2)
    mask = np.asarray(arr) > 0
    if shape is not None and mask.shape != tuple(shape):
        raise ValueError(f"mask: {p} has shape {mask.shape}, the images are {tuple(shape)}")
    return mask


def _read_names(path: Path) -> list[str]:
    return [line.strip() for line in path.read_text().splitlines() if line.strip()]


def _read_normal_gt(folder: Path, shape: tuple[int, int]) -> np.ndarray | None:
    for name in ("normal_gt.npy", "gt_normal.npy"):
        if (folder / name).is_file():
            gt = np.load(folder / name, allow_pickle=False).astype(np.float32)
            break
    else:
        if not (folder / "Normal_gt.mat").is_file():
            return None
        from scipy.io import loadmat

        gt = np.asarray(loadmat(folder / "Normal_gt.mat")["Normal_gt"], np.float32)
    if gt.shape != shape + (3,):
        raise ValueError(f"normal_gt: shape {gt.shape} does not match the images {shape}")
    return gt


def read_folder(folder, select: str | Sequence[str] | None = None) -> PhotometricData:
    """Read a DiLiGenT-style (or RobustPhotometricStereo-style) folder.

    Parameters
    ----------
    folder : str or Path
        The folder (layouts in the module docstring).
    select : None, "triad" or sequence of str, optional
        ``"triad"``: only the images named in ``triad.txt``; a sequence: only these
        image names (in the given order); ``None``: all images.

    Returns
    -------
    PhotometricData
    """
    d = Path(folder)
    if not d.is_dir():
        raise NotADirectoryError(f"folder: {d} is not a directory")
    if (d / "filenames.txt").is_file():
        names = _read_names(d / "filenames.txt")
        lights_file = d / "light_directions.txt"
        if not lights_file.is_file():
            raise FileNotFoundError(f"folder: {lights_file} is missing")
        lights = load_lights(lights_file)
        if lights.shape[0] != len(names):
            raise ValueError(
                f"folder: {lights_file.name} has {lights.shape[0]} rows for {len(names)} images"
            )
    elif (d / "lights.npy").is_file():
        # RobustPhotometricStereo layout: row NNN of lights.npy belongs to imageNNN.
        names = sorted(f.name for f in d.iterdir() if re.fullmatch(r"image\d+\.npy", f.name))
        if not names:
            raise FileNotFoundError(f"folder: {d} has lights.npy but no imageNNN.npy files")
        table = np.load(d / "lights.npy", allow_pickle=False)
        rows = [int(re.findall(r"\d+", n)[0]) for n in names]
        if table.ndim != 2 or max(rows) >= table.shape[0]:
            raise ValueError(f"folder: lights.npy shape {table.shape} lacks rows {rows}")
        lights = validate_lights(table[rows])
    else:
        raise FileNotFoundError(
            f"folder: {d} has neither filenames.txt + light_directions.txt nor lights.npy"
        )
    intens_file = d / "light_intensities.txt"
    intens = load_intensities(intens_file, len(names)) if intens_file.is_file() else np.ones((len(names), 3))

    if select is not None:
        if isinstance(select, str):
            if select != "triad":
                raise ValueError(f"select: expected 'triad' or a list of names, got {select!r}")
            if not (d / "triad.txt").is_file():
                raise FileNotFoundError(f"select: {d / 'triad.txt'} is missing")
            wanted = _read_names(d / "triad.txt")
        else:
            wanted = [str(s) for s in select]
        missing = [w for w in wanted if w not in names]
        if missing:
            raise ValueError(f"select: {missing} are not among the folder's images")
        order = [names.index(w) for w in wanted]
        names, lights, intens = wanted, lights[order], intens[order]
        lights = validate_lights(lights, "lights (selected)")

    images = read_images([d / n for n in names])
    shape = images.shape[1:3]
    mask = read_mask(d / "mask.png", shape) if (d / "mask.png").is_file() else np.ones(shape, bool)
    return PhotometricData(
        images=images,
        lights=lights,
        intensities=intens,
        mask=mask,
        normal_gt=_read_normal_gt(d, shape),
        names=tuple(names),
    )
