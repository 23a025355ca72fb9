"""Frame checks: is each image of a capture fit to measure (exposure, dark, saturated, size, bit depth)?

A photometric capture is one image per light. A failed LED gives a dark frame, a wrong
exposure a saturated one; a solve that leaves such frames out (:func:`photometric.stereo.screen_images`
does, per pixel) still returns a surface, from fewer lights than the rig was calibrated for,
and an inspection would decide a part on it. :func:`check_frames` looks at every frame
before the solve and names what is wrong with each, with the same black floor and
saturation level as the screen (one definition of "black" and "saturated"):

- **dark**: at least :data:`DARK_FRACTION` of the pixels are black (below
  :data:`photometric.stereo.BLACK_FLOOR`), or its bright level (99th percentile) is below
  :data:`RELATIVE_DARK` of the median bright level of the part's frames (an LED that did
  not fire, with some ambient light);
- **saturated**: at least :data:`SATURATED_FRACTION` of the pixels at or above the
  saturation level (integer images only: float images have no known full scale);
- **wrong size**: not the size the rig was calibrated for;
- **wrong bit depth** (when one is expected) and **mixed bit depths** within one part
  (8-bit and 16-bit frames do not come from one camera setting).

Pure functions over images and their stored bit depths; :func:`read_frames` reads a
part's files one at a time for them (no stack is kept).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photometric.stereo import BLACK_FLOOR, SATURATED, screen_images
from surfaces.validate import InputError

__all__ = ["DARK_FRACTION", "SATURATED_FRACTION", "RELATIVE_DARK", "FrameReport", "check_frames", "read_frames",
           "stored_bit_depth"]

#: a frame with at least this fraction of black pixels is dark
DARK_FRACTION = 0.9
#: a frame with at least this fraction of saturated pixels is saturated
SATURATED_FRACTION = 0.5
#: a frame whose 99th-percentile level is below this fraction of the part's median one is dark
RELATIVE_DARK = 0.1


@dataclass(frozen=True)
class FrameReport:
    """What :func:`check_frames` found, per frame.

    Attributes
    ----------
    names : tuple of str
        Frame names (file names), in light order.
    shapes : tuple of (int, int)
        Each frame's (H, W), pixels.
    bit_depths : tuple of int or None
        Stored bits per channel (8, 16, ...; None for float data).
    dark_fraction, saturated_fraction : numpy.ndarray, shape (N,)
        Fraction of the counted pixels that are black / saturated.
    exposure : numpy.ndarray, shape (N,)
        Median level of the counted pixels relative to full scale (0..1).
    bright : numpy.ndarray, shape (N,)
        99th-percentile level relative to full scale.
    reasons : tuple of str
        One sentence per problem (empty: every frame is fit to measure).
    """

    names: tuple
    shapes: tuple
    bit_depths: tuple
    dark_fraction: np.ndarray
    saturated_fraction: np.ndarray
    exposure: np.ndarray
    bright: np.ndarray
    reasons: tuple

    @property
    def ok(self) -> bool:
        """True when no frame has a problem."""
        return not self.reasons

    def to_dict(self) -> dict:
        """JSON-ready: per frame name, size, bit depth, dark and saturated fractions, exposure; the reasons."""
        return {
            "frames": [{"name": n, "shape": list(s), "bit_depth": b, "dark_fraction": round(float(d), 4),
                        "saturated_fraction": round(float(t), 4), "exposure": round(float(e), 4)}
                       for n, s, b, d, t, e in zip(self.names, self.shapes, self.bit_depths, self.dark_fraction,
                                                   self.saturated_fraction, self.exposure)],
            "reasons": list(self.reasons),
        }


def stored_bit_depth(array: np.ndarray) -> int | None:
    """Bits per channel of stored pixels: 8 for uint8, 16 for uint16, ...; None for floats.

    Parameters
    ----------
    array : numpy.ndarray
        Pixels as stored in the file (before scaling).

    Returns
    -------
    int or None

    Examples
    --------
    >>> stored_bit_depth(np.zeros(2, np.uint16)), stored_bit_depth(np.zeros(2, np.float32))
    (16, None)
    """
    return int(np.iinfo(array.dtype).bits) if np.issubdtype(array.dtype, np.integer) else None


def _levels(image: np.ndarray, mask) -> tuple[float, float]:
    top = image.max(axis=2) if image.ndim == 3 else image
    values = top[mask] if mask is not None and mask.shape == top.shape else top.ravel()
    if values.size == 0:
        return 0.0, 0.0
    med, p99 = np.percentile(values, [50.0, 99.0])
    return float(med), float(p99)


def _size_reasons(names, shapes, expected_shape) -> list[str]:
    """Frames of another size than the rig's: one sentence when they share one size, else one per frame."""
    want = tuple(int(v) for v in expected_shape)
    wrong = [(n, s) for n, s in zip(names, shapes) if tuple(s) != want]
    if not wrong:
        return []
    if len(wrong) == len(names) and len({tuple(s) for _, s in wrong}) == 1:
        h, w = wrong[0][1]
        return [f"rig: calibrated for {want[0]} x {want[1]} px images, the images are {h} x {w} px"]
    return [f"{n!r} is {s[0]} x {s[1]} px, the rig's images are {want[0]} x {want[1]} px" for n, s in wrong]


def check_frames(images: Sequence, names: Sequence[str], bit_depths: Sequence | None = None, *,
                 expected_shape=None, expected_bit_depth: int | None = None, mask=None,
                 saturation: float = SATURATED, floor: float = BLACK_FLOOR) -> FrameReport:
    """Check each frame of a capture: dark, saturated, wrong size, wrong or mixed bit depth.

    Parameters
    ----------
    images : sequence of numpy.ndarray, each (H, W) or (H, W, 3)
        The frames scaled to full scale 1 (:func:`photometric.io.read_image`), in light
        order; they may differ in size (that is one of the checks).
    names : sequence of str
        Their names, for the reasons.
    bit_depths : sequence of int or None, optional
        Stored bits per channel of each (:func:`stored_bit_depth`); None: not checked.
    expected_shape : (H, W), optional
        The size the rig was calibrated for.
    expected_bit_depth : int, optional
        The bit depth the capture must have.
    mask : numpy.ndarray (H, W) bool, optional
        Pixels that count (for frames of that size).
    saturation : float
        Saturation level (``inf`` for float frames: not tested); as
        :func:`photometric.stereo.screen_images`.
    floor : float
        Black floor; as :func:`photometric.stereo.screen_images`.

    Returns
    -------
    FrameReport

    Examples
    --------
    >>> ok = np.full((8, 8), 0.5, np.float32)
    >>> r = check_frames([ok, np.zeros((8, 8), np.float32), ok, np.ones((8, 8), np.float32)], "abcd", [16] * 4)
    >>> r.reasons
    ("'b' is dark (100 % of its pixels black)", "'d' is saturated (100 % of its pixels at full scale)")
    >>> check_frames([ok, ok, ok], "abc", [8, 16, 16]).reasons
    ('mixed bit depths in one part: 8-bit a; 16-bit b, c',)
    """
    names = [str(n) for n in names]
    if len(names) != len(images):
        raise InputError(f"frames: {len(images)} images for {len(names)} names")
    n = len(images)
    depths = tuple(bit_depths) if bit_depths is not None else (None,) * n
    shapes = tuple(tuple(int(v) for v in np.shape(img)[:2]) for img in images)
    dark, sat, expo, bright = (np.zeros(n) for _ in range(4))
    m = None if mask is None else np.asarray(mask, bool)
    for k, img in enumerate(images):
        a = np.asarray(img)
        own = m if m is not None and m.shape == a.shape[:2] and m.any() else None
        screen = screen_images(a[None], own, saturation, floor)  # one definition of black and saturated
        dark[k], sat[k] = float(screen.black[0]), float(screen.saturated[0])
        expo[k], bright[k] = _levels(a, own)
    reasons = []
    if expected_shape is not None:
        reasons += _size_reasons(names, shapes, expected_shape)
    known = sorted({d for d in depths if d is not None})
    if len(known) > 1:
        groups = "; ".join(f"{d}-bit " + ", ".join(names[k] for k in range(n) if depths[k] == d) for d in known)
        reasons.append(f"mixed bit depths in one part: {groups}")
    elif expected_bit_depth is not None and known and known[0] != expected_bit_depth:
        reasons.append(f"the frames are {known[0]}-bit, the capture must be {expected_bit_depth}-bit")
    typical = float(np.median(bright)) if n >= 3 else 0.0
    for k in range(n):
        if dark[k] >= DARK_FRACTION:
            reasons.append(f"{names[k]!r} is dark ({100 * dark[k]:.0f} % of its pixels black)")
        elif typical > 0 and bright[k] < RELATIVE_DARK * typical:
            reasons.append(f"{names[k]!r} is dark (its bright level {bright[k]:.3g} of full scale is below "
                           f"{RELATIVE_DARK:g} x the part's typical {typical:.3g}: did its light fire?)")
        if sat[k] >= SATURATED_FRACTION:
            reasons.append(f"{names[k]!r} is saturated ({100 * sat[k]:.0f} % of its pixels at full scale)")
    return FrameReport(tuple(names), shapes, depths, dark, sat, expo, bright, tuple(reasons))


def read_frames(paths: Sequence, *, expected_shape=None, expected_bit_depth: int | None = None,
                mask=None) -> FrameReport:
    """Read a capture's files one at a time and :func:`check_frames` them.

    Parameters
    ----------
    paths : sequence of str or Path
        Image files in light order (PNG/TIFF 8 or 16 bit, or ``.npy``).
    expected_shape, expected_bit_depth, mask
        As :func:`check_frames`.

    Returns
    -------
    FrameReport

    Notes
    -----
    Every second pixel in each direction is looked at (fractions and levels of a quarter of
    the pixels); one stored image is held at a time.
    """
    from photometric.io import FLOAT_SUFFIXES, _read_raw, _scaled

    images, depths, full = [], [], []
    m = None if mask is None else np.asarray(mask, bool)[::2, ::2]
    for path in paths:
        p = Path(path)
        raw = _read_raw(p)
        depths.append(stored_bit_depth(raw))
        full.append((int(raw.shape[0]), int(raw.shape[1])))
        sub = raw[::2, ::2]
        images.append(_scaled(sub, p, np.empty(sub.shape, np.float32)))
        del raw
    floats = any(Path(p).suffix.lower() in FLOAT_SUFFIXES for p in paths)
    report = check_frames(images, [Path(p).name for p in paths], depths, expected_bit_depth=expected_bit_depth,
                          mask=m, saturation=np.inf if floats else SATURATED)
    reasons = list(report.reasons)
    if expected_shape is not None:
        reasons = _size_reasons(report.names, full, expected_shape) + reasons
    return FrameReport(report.names, tuple(full), report.bit_depths, report.dark_fraction,
                       report.saturated_fraction, report.exposure, report.bright, tuple(reasons))

