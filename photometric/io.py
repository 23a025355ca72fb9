"""Reading photometric-stereo inputs: images, masks, light files and DiLiGenT-style folders.

Light files: :func:`load_lights` (directions, or slant and azimuth), :func:`load_intensities`
and :func:`load_light_positions` (LEDs, mm); each checks what it reads once.

A DiLiGenT-style folder holds ``filenames.txt`` (image files in light order),
``light_directions.txt`` (``x y z`` per row), optionally ``light_intensities.txt``
(``r g b`` per row), ``mask.png``, ``normal_gt.npy`` (or DiLiGenT's ``Normal_gt.mat``)
and ``triad.txt`` (three of the file names). A near-field folder (the rig contract of
:mod:`photometric.rig`) adds ``light_positions.txt`` (``x y z`` in mm per image),
``flat_001.png ...`` (flat-field images, one per light; named in ``scene.json``
``flat_field.files`` or found as ``flat_*.png``) and, in ``scene.json``, ``lights`` (``model:
"point"``, ``axes``, ``mu``), ``camera`` and ``flat_field.albedo``. The RobustPhotometricStereo layout
(``imageNNN.npy`` files, ``lights.npy`` whose row NNN is image NNN's light,
``gt_normal.npy``) is read too; its lights are in the same frame as DiLiGenT's (checked on
the shared ``rps_bunny``: of the eight axis-sign choices only the identity makes least
squares reproduce ``gt_normal``, to 3e-6 deg median; flipping y gives about 35 deg).
Images are 8/16-bit PNG/TIFF (read with OpenCV ``IMREAD_UNCHANGED``, so 16 bits survive,
and converted BGR -> RGB) or ``.npy``.
"""

from __future__ import annotations

import json
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from photometric.camera import Camera, camera_from_dict
from photometric.leds import PointLights, point_lights
from photometric.lights import as_intensities, lights_from_angles, validate_lights
from surfaces.validate import InputError, reads_file

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
    point_lights : photometric.leds.PointLights or None
        LED positions (``light_positions.txt``) with the axes and lobe exponents of
        ``scene.json`` when it states them (near-field folders).
    flat_images : numpy.ndarray or None, shape like ``images``
        Flat-field images in light order.
    flat_albedo : float or None
        The flat target's albedo (``scene.json`` ``flat_field.albedo``).
    camera : photometric.camera.Orthographic, Perspective or None
        ``scene.json`` ``camera``.
    full_scale : float or None
        The value at which the sensor saturates: 1 for integer image files (8/16-bit
        PNG/TIFF/...), None for float files and arrays (no saturation level known).
    """

    images: np.ndarray
    lights: np.ndarray
    intensities: np.ndarray
    mask: np.ndarray
    normal_gt: np.ndarray | None
    names: tuple[str, ...]
    point_lights: PointLights | None = None
    flat_images: np.ndarray | None = None
    flat_albedo: float | None = None
    camera: Camera | None = None
    full_scale: float | None = None

    def subset(self, keep) -> PhotometricData:
        """The same data with only the images ``keep`` selects (and their lights).

        Parameters
        ----------
        keep : array_like, shape (N,), bool
            Images to keep, in light order.

        Returns
        -------
        PhotometricData
            Images, lights, intensities, names, LED positions and flat-field images
            reduced to the kept ones; mask, ground truth and camera shared.
        """
        k = np.flatnonzero(np.asarray(keep, bool))
        pl = self.point_lights
        if pl is not None:
            pl = pl.subset(k)
        return replace(
            self, images=self.images[k], lights=self.lights[k], intensities=self.intensities[k],
            names=tuple(self.names[i] for i in k), point_lights=pl,
            flat_images=None if self.flat_images is None else self.flat_images[k])


def _read_array(path, name: str) -> np.ndarray:
    """A ``.npy`` array or an image file read by OpenCV with all its bits (BGR order)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: file {p} does not exist")
    if p.suffix.lower() == ".npy":
        return np.load(p, allow_pickle=False)
    arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if arr is None:
        raise InputError(f"{name}: OpenCV cannot read {p}")
    return arr


#: Image files that hold floats: no saturation level is known for them.
FLOAT_SUFFIXES = (".npy", ".exr")


def full_scale_of(paths: Sequence) -> float | None:
    """1.0 when every file is an integer image format (scaled to full scale 1 when read), else None.

    Parameters
    ----------
    paths : sequence of str or Path
        Image files.

    Returns
    -------
    float or None
    """
    return None if any(Path(p).suffix.lower() in FLOAT_SUFFIXES for p in paths) else 1.0


@reads_file("image")
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
    arr = _read_raw(p)
    return _scaled(arr, p, np.empty(arr.shape, np.float32))


def _read_raw(p: Path) -> np.ndarray:
    """The stored pixels of one image file in RGB order, (H, W) or (H, W, 3), any dtype."""
    arr = _read_array(p, "image")
    if arr.ndim == 3 and p.suffix.lower() != ".npy":
        arr = arr[..., :3][..., ::-1]  # OpenCV's BGR(A) to RGB
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] != 3):
        raise InputError(f"image: {p} has unsupported shape {arr.shape}")
    return arr


def _scaled(arr: np.ndarray, p: Path, out: np.ndarray) -> np.ndarray:
    """``arr`` as float32 into ``out`` (integers divided by their type's maximum), checked finite.

    One pass straight from the stored type into ``out``: no float32 or float64
    temporaries of the image (the values equal ``arr.astype(float32) / float32(max)``).
    """
    if np.issubdtype(arr.dtype, np.integer):
        np.divide(arr, np.float32(np.iinfo(arr.dtype).max), out=out, dtype=np.float32)
        return out
    np.copyto(out, arr, casting="unsafe")
    # a float64 sum of float32 values cannot overflow: it is finite exactly when every value is
    if not np.isfinite(np.sum(out, dtype=np.float64)):
        raise InputError(f"image: {p} contains NaN or infinite values")
    return out


#: Bayer mosaic layouts (``--bayer``): the colours of the sensor's top-left 2 x 2 cell, row by row.
BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
# OpenCV names a mosaic by the cell one pixel down and right of the top-left: the sensor's RGGB is
# OpenCV's "BG" (checked in tests/photometric/test_capture.py by a red image's mosaic coming back red)
_CV_BAYER = {"RGGB": cv2.COLOR_BayerBG2RGB, "BGGR": cv2.COLOR_BayerRG2RGB, "GRBG": cv2.COLOR_BayerGB2RGB,
             "GBRG": cv2.COLOR_BayerGR2RGB}
#: A capture whose brightest observations (99.9th percentile in the mask, over the images) stay below
#: this fraction of full scale gets a warning (:func:`exposure_note`).
DARK_PEAK = 0.5


def demosaic(raw: np.ndarray, pattern: str, name: str = "image") -> np.ndarray:
    """RGB image of a single-channel Bayer mosaic (OpenCV's bilinear demosaicing, full resolution).

    Parameters
    ----------
    raw : numpy.ndarray, shape (H, W), uint8 or uint16
        The sensor's values, not demosaiced.
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
        Colours of the top-left 2 x 2 cell, row by row.
    name : str, optional
        For messages.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), same dtype, RGB order

    Examples
    --------
    >>> mosaic = np.zeros((6, 6), np.uint8)
    >>> mosaic[0::2, 0::2] = 200  # red sites of an RGGB sensor under red light
    >>> demosaic(mosaic, "RGGB")[3, 3].tolist()
    [200, 0, 0]
    """
    if pattern not in _CV_BAYER:
        raise InputError(f"bayer: expected one of {BAYER_PATTERNS}, got {pattern!r}")
    if raw.ndim != 2:
        raise InputError(f"{name}: a Bayer mosaic has one channel, got shape {raw.shape} (already demosaiced?)")
    if raw.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{name}: a Bayer mosaic must be 8 or 16 bit integers, got {raw.dtype}")
    return cv2.cvtColor(np.ascontiguousarray(raw), _CV_BAYER[pattern])


def subtract_ambient(images: np.ndarray, ambient) -> np.ndarray:
    """Images minus a dark (ambient) frame, clipped at 0, in place.

    Parameters
    ----------
    images : numpy.ndarray, shape (N, H, W) or (N, H, W, 3), float32
        Linear images (full scale 1).
    ambient : array_like, shape (H, W[, 3]) or (N, H, W[, 3])
        One frame for every image, or one per image (all LEDs off, same exposure).

    Returns
    -------
    numpy.ndarray
        ``images`` itself.

    Examples
    --------
    >>> imgs = np.full((3, 2, 2), 0.5, np.float32)
    >>> round(float(subtract_ambient(imgs, np.full((2, 2), 0.1, np.float32))[0, 0, 0]), 3)
    0.4
    """
    amb = np.asarray(ambient, np.float32)
    hw = images.shape[1:3]
    per_image = amb.ndim >= 3 and amb.shape[0] == images.shape[0] and amb.shape[1:3] == hw
    frame = amb.shape[1:] if per_image else amb.shape
    if frame[:2] != hw or len(frame) > 3 or (len(frame) == 3 and frame[2] != 3):
        raise InputError(f"ambient: shape {amb.shape} fits neither one image {images.shape[1:]} nor the stack "
                         f"{images.shape}")
    if len(frame) == 3 and images.ndim == 3:  # a colour dark frame for grey images: its grey
        amb = amb.mean(axis=-1)
    elif len(frame) == 2 and images.ndim == 4:  # a grey dark frame for colour images: every channel
        amb = amb[..., None]
    if not np.all(np.isfinite(amb)) or np.any(amb < 0):
        raise InputError("ambient: the dark frame must be finite and non-negative")
    np.subtract(images, amb, out=images)
    np.maximum(images, 0.0, out=images)
    return images


def read_ambient(paths, images: np.ndarray, bayer: str | None = None) -> np.ndarray:
    """Read dark frame(s) and subtract them from ``images`` (:func:`subtract_ambient`).

    Parameters
    ----------
    paths : str, Path or sequence of them
        One file for every image or one per image (light order).
    images : numpy.ndarray, shape (N, H, W[, 3]), float32
    bayer : str, optional
        The mosaic layout when the frames are mosaics like the images.

    Returns
    -------
    numpy.ndarray
        ``images``, ambient subtracted.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = list(paths)
    if len(paths) not in (1, images.shape[0]):
        raise InputError(f"ambient: {len(paths)} dark frames for {images.shape[0]} images (give one, or one per image)")
    frames = read_images(paths, bayer=bayer)
    return subtract_ambient(images, frames[0] if len(paths) == 1 else frames)


def exposure_note(images: np.ndarray, mask=None, full_scale: float | None = 1.0,
                  bits: int | None = None) -> str | None:
    """A warning for a dark or low-bit capture: its brightest observations far below full scale.

    Parameters
    ----------
    images : numpy.ndarray, shape (N, H, W[, 3])
        Images, full scale 1.
    mask : array_like, shape (H, W), optional
    full_scale : float or None, optional
        None (float input): nothing is said.
    bits : int, optional
        The files' bit depth, for the message (8 or 16).

    Returns
    -------
    str or None
        Set when the 99.9th percentile over the images and the mask uses fewer grey levels
        than :data:`DARK_PEAK` of an 8-bit range (below 128 DN of an 8-bit file, 128 of 65535 of a
        16-bit one): the quantisation step is then a larger part of every value (noise, banding
        in the normals). ``bits`` None: 8 when the values are multiples of 1/255, else 16.

    Examples
    --------
    >>> imgs = np.full((3, 4, 4), 100 / 255, np.float32)
    >>> exposure_note(imgs, bits=8)[:58]
    'images: dark capture: the brightest observations reach 100'
    """
    if full_scale is None:
        return None
    m = np.ones(images.shape[1:3], bool) if mask is None else np.asarray(mask, bool)
    # a strided sample of at most about 2 million values: no copy of the whole stack (the solve's memory)
    s = max(1, int(np.ceil(np.sqrt(images.size / 2_000_000))))
    vals = images[:, ::s, ::s][:, m[::s, ::s]]
    if vals.size == 0:
        return None
    peak = float(np.percentile(vals, 99.9))
    if bits is None:
        # 8-bit files read as multiples of 1/255; anything finer is taken as 16 bits
        bits = 8 if np.allclose(vals * 255.0, np.round(vals * 255.0), atol=1e-3) else 16
    # the grey levels the brightest observations use: a 16-bit capture at 14 % of full scale still has
    # ~9,000 of them (no warning); an 8-bit one below half of full scale has fewer than 128
    if peak * (2**bits - 1) >= DARK_PEAK * 255 * full_scale:
        return None
    dn = f" of {2**bits - 1} DN" if bits else ""
    value = f"{peak * (2**bits - 1):.0f}{dn}" if bits else f"{peak:.3f}"
    return (f"images: dark capture: the brightest observations reach {value} ({100 * peak:.0f} % of full scale, "
            f"99.9th percentile): each value carries a larger quantisation and noise share; expose longer or "
            "use more bits")


def read_images(paths: Sequence, bayer: str | None = None) -> np.ndarray:
    """Read several images of one size into a stack.

    Parameters
    ----------
    paths : sequence of str or Path
        Image files (see :func:`read_image`).
    bayer : {"RGGB", "BGGR", "GRBG", "GBRG"}, optional
        The files are single-channel Bayer mosaics of this layout: each is demosaiced to
        RGB (:func:`demosaic`) before scaling.

    Returns
    -------
    numpy.ndarray, shape (N, H, W) or (N, H, W, 3), float32
    """
    if len(paths) == 0:
        raise InputError("images: no image files given")
    if bayer is not None:
        if bayer not in _CV_BAYER:
            raise InputError(f"bayer: expected one of {BAYER_PATTERNS}, got {bayer!r}")
        first = demosaic(_read_raw(Path(paths[0])), bayer, str(paths[0]))
        out = np.empty((len(paths),) + first.shape, np.float32)
        _scaled(first, Path(paths[0]), out[0])
        for k, path in enumerate(paths[1:], start=1):
            img = demosaic(_read_raw(Path(path)), bayer, str(path))
            if img.shape != out.shape[1:]:
                raise InputError(f"images: {path} has shape {img.shape}, {paths[0]} has {out.shape[1:]}")
            _scaled(img, Path(path), out[k])
        return out
    # each file is converted straight into its plane of the stack: the peak is the stack
    # plus one stored (e.g. uint16) image, not a float copy per image
    first = _read_raw(Path(paths[0]))
    out = np.empty((len(paths),) + first.shape, np.float32)
    _scaled(first, Path(paths[0]), out[0])
    dtypes = {first.dtype.str: [Path(paths[0]).name]}
    del first
    for k, path in enumerate(paths[1:], start=1):
        img = _read_raw(Path(path))
        if img.shape != out.shape[1:]:
            raise InputError(f"images: {path} has shape {img.shape}, {paths[0]} has {out.shape[1:]}")
        dtypes.setdefault(img.dtype.str, []).append(Path(path).name)
        _scaled(img, Path(path), out[k])
    if len(dtypes) > 1:  # 8-bit and 16-bit frames: not one camera setting (each is scaled by its own full scale)
        groups = "; ".join(f"{np.dtype(t).name} {', '.join(names[:3])}{' ...' if len(names) > 3 else ''}"
                           for t, names in dtypes.items())
        warnings.warn(f"images: mixed bit depths ({groups}); each is scaled to its own full scale", UserWarning,
                      stacklevel=2)
    return out


@reads_file("mask image")
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
        raise InputError(f"mask: {p} has shape {mask.shape}, the images are {tuple(shape)}")
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
        raise InputError(f"normal_gt: shape {gt.shape} does not match the images {shape}")
    return gt


@reads_file("photometric folder")
def read_folder(folder, select: str | Sequence[str] | None = None, bayer: str | None = None) -> PhotometricData:
    """Read a DiLiGenT-style (or RobustPhotometricStereo-style) folder.

    Parameters
    ----------
    folder : str or Path
        The folder (layouts in the module docstring).
    select : None, "triad" or sequence of str, optional
        ``"triad"``: only the images named in ``triad.txt``; a sequence: only these
        image names (in the given order); ``None``: all images.
    bayer : {"RGGB", "BGGR", "GRBG", "GBRG"}, optional
        The images are Bayer mosaics of this layout (:func:`read_images`).

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
            raise InputError(
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
            raise InputError(f"folder: lights.npy shape {table.shape} lacks rows {rows}")
        lights = validate_lights(table[rows])
    else:
        raise FileNotFoundError(
            f"folder: {d} has neither filenames.txt + light_directions.txt nor lights.npy"
        )
    all_names = list(names)
    intens_file = d / "light_intensities.txt"
    intens = load_intensities(intens_file, len(names)) if intens_file.is_file() else np.ones((len(names), 3))

    if select is not None:
        if isinstance(select, str):
            if select != "triad":
                raise InputError(f"select: expected 'triad' or a list of names, got {select!r}")
            if not (d / "triad.txt").is_file():
                raise FileNotFoundError(f"select: {d / 'triad.txt'} is missing")
            wanted = _read_names(d / "triad.txt")
        else:
            wanted = [str(s) for s in select]
        missing = [w for w in wanted if w not in names]
        if missing:
            raise InputError(f"select: {missing} are not among the folder's images")
        order = [names.index(w) for w in wanted]
        names, lights, intens = wanted, lights[order], intens[order]
        lights = validate_lights(lights, "lights (selected)")

    images = read_images([d / n for n in names], bayer=bayer)
    shape = images.shape[1:3]
    mask = read_mask(d / "mask.png", shape) if (d / "mask.png").is_file() else np.ones(shape, bool)
    near = _read_nearfield(d, all_names, names, images.shape)
    return PhotometricData(
        images=images,
        lights=lights,
        intensities=intens,
        mask=mask,
        normal_gt=_read_normal_gt(d, shape),
        names=tuple(names),
        **near,
        full_scale=full_scale_of(names),
    )


@reads_file("scene folder")
def read_scene(folder) -> dict:
    """A folder's ``scene.json`` as a dict (empty when there is none).

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    dict
    """
    path = Path(folder) / "scene.json"
    if not path.is_file():
        return {}
    try:
        scene = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"input: {path} is not valid JSON ({exc})") from None
    return scene if isinstance(scene, dict) else {}


def _read_nearfield(d: Path, all_names: list[str], names: list[str], image_shape) -> dict:
    """The near-field parts of a folder, in the (selected) light order of ``names``."""
    scene = read_scene(d)
    order = [all_names.index(n) for n in names]
    out: dict = {}
    if isinstance(scene.get("camera"), dict):
        out["camera"] = camera_from_dict(scene["camera"], f"camera ({d / 'scene.json'})")
    pos_file = d / "light_positions.txt"
    if pos_file.is_file():
        positions = load_light_positions(pos_file)
        if positions.shape[0] != len(all_names):
            raise InputError(f"folder: {pos_file.name} has {positions.shape[0]} rows for {len(all_names)} images")
        lights = scene.get("lights")
        axes = mu = None
        if isinstance(lights, dict) and lights.get("model") == "point":
            if lights.get("axes") is not None:
                axes = np.asarray(lights["axes"], float)
            if lights.get("mu") is not None:
                mu = np.broadcast_to(np.asarray(lights["mu"], float), (len(all_names),))
        for value, what in ((axes, "lights.axes"), (mu, "lights.mu")):
            if value is not None and len(value) != len(all_names):
                raise InputError(f"folder: scene.json {what} has {len(value)} entries for {len(all_names)} images")
        out["point_lights"] = point_lights(positions[order], None if axes is None else axes[order],
                                           None if mu is None else mu[order], name=f"light_positions ({pos_file})")
    flat = scene.get("flat_field") if isinstance(scene.get("flat_field"), dict) else {}
    if flat.get("files"):
        flat_names = [str(f) for f in flat["files"]]
    else:
        flat_names = sorted(f.name for f in d.glob("flat_*.png"))
    if flat_names:
        if len(flat_names) != len(all_names):
            raise InputError(f"flat_field: {d} has {len(flat_names)} flat-field image(s) for {len(all_names)} "
                             "images (one per light)")
        flats = read_images([d / flat_names[k] for k in order])
        if flats.shape != tuple(image_shape):
            raise InputError(f"flat_field: flat-field images of {d} are {flats.shape[1:]}, the images "
                             f"{tuple(image_shape[1:])}")
        out["flat_images"] = flats
        if flat.get("albedo") is not None:
            out["flat_albedo"] = float(flat["albedo"])
    return out


# ----------------------------------------------------------------------------- light files


def _read_table(path: Path, name: str) -> np.ndarray:
    """Numbers from a text or .npy file."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return np.load(path, allow_pickle=False)
    try:
        return np.loadtxt(path, ndmin=2, delimiter="," if suffix == ".csv" else None)
    except ValueError as exc:
        raise InputError(f"{name}: {path} is not a table of numbers ({exc})") from None


def _read_json(path: Path, name: str):
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"{name}: {path} is not valid JSON ({exc})") from None


def _existing(path, name: str) -> Path:
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: file {p} does not exist")
    return p


@reads_file("light file")
def load_lights(path) -> np.ndarray:
    """Read light directions from a file.

    Parameters
    ----------
    path : str or Path
        One of

        * text (``.txt``, ``.csv``, ...): one ``x y z`` row per light (DiLiGenT
          ``light_directions.txt``), or two columns ``slant azimuth`` in degrees (the
          "slant tilt" form of vision software: tilt is the azimuth);
        * ``.npy``: an ``(N, 3)`` array;
        * ``.json``: a list of ``[x, y, z]``, or an object with ``"lights"``
          (list of ``[x, y, z]``) or ``"slant_deg"`` and ``"azimuth_deg"`` lists
          (``"tilt_deg"`` is accepted for ``"azimuth_deg"``).

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Unit light directions, validated once by :func:`validate_lights`.

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        Unreadable content or invalid lights.
    """
    p = _existing(path, "lights")
    name = f"lights ({p.name})"
    if p.suffix.lower() == ".json":
        data = _read_json(p, "lights")
        if isinstance(data, dict):
            if "lights" in data:
                data = data["lights"]
            elif "slant_deg" in data and ("azimuth_deg" in data or "tilt_deg" in data):
                data = lights_from_angles(data["slant_deg"], data.get("azimuth_deg"), tilt_deg=data.get("tilt_deg"))
            else:
                raise InputError(f"lights: {p} needs a 'lights' list or 'slant_deg' and 'azimuth_deg' (or 'tilt_deg')")
        return validate_lights(data, name)
    table = _read_table(p, "lights")
    if table.ndim == 2 and table.shape[1] == 2:
        table = lights_from_angles(table[:, 0], table[:, 1])
    return validate_lights(table, name)


@reads_file("light intensity file")
def load_intensities(path, n: int) -> np.ndarray:
    """Read per-light intensities (DiLiGenT ``light_intensities.txt``: ``r g b`` per row).

    Parameters
    ----------
    path : str or Path
        Text (one value or one ``r g b`` row per light), ``.npy`` or ``.json`` (a list,
        or an object with an ``"intensities"`` list).
    n : int
        Number of lights the file must describe.

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        See :func:`as_intensities`.
    """
    p = _existing(path, "intensities")
    if p.suffix.lower() == ".json":
        data = _read_json(p, "intensities")
        if isinstance(data, dict):
            data = data.get("intensities")
            if data is None:
                raise InputError(f"intensities: {p} needs an 'intensities' list")
        return as_intensities(data, n, f"intensities ({p.name})")
    table = _read_table(p, "intensities")
    if table.ndim == 2 and table.shape[0] == 1 and n != 1:
        table = table.reshape(-1)
    return as_intensities(table, n, f"intensities ({p.name})")


@reads_file("light position file")
def load_light_positions(path) -> np.ndarray:
    """Read LED positions (``light_positions.txt``: one ``x y z`` row in mm per image).

    Parameters
    ----------
    path : str or Path
        Text (whitespace or ``.csv`` comma separated), ``.npy`` ``(N, 3)`` or ``.json``
        (a list of ``[x, y, z]`` or an object with ``"positions_mm"``).

    Returns
    -------
    numpy.ndarray, shape (N, 3), float64
        Positions in mm, checked by :func:`point_lights`.
    """
    p = _existing(path, "light_positions")
    if p.suffix.lower() == ".json":
        data = _read_json(p, "light_positions")
        if isinstance(data, dict):
            data = data.get("positions_mm")
            if data is None:
                raise InputError(f"light_positions: {p} needs a 'positions_mm' list")
    else:
        data = _read_table(p, "light_positions")
    return point_lights(data, name=f"light_positions ({p.name})").positions
