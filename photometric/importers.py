"""Calibration files of other near-field tools, read into the workbench's rig (``rig.json``).

Two formats carry the same content (LED positions, axes, intensities, lobes; the camera's
intrinsics), both in the **camera frame** of computer vision: origin at the camera centre,
x right, y down (image rows), z forward (along the optical axis), millimetres.

* **Quéau** (Y. Quéau's near-field photometric stereo code, ``yqueau/near_ps``):
  ``light.mat`` holds ``S`` (N, 3) LED positions, ``Dir`` (N, 3) LED axes (from the LED
  into the scene), ``Phi`` (N, 1) or (N, 3) radiant intensities (per colour) and ``mu``
  (N, 1) lobe exponents; ``camera.mat`` holds ``K``, stored transposed
  (``[[fx, 0, 0], [0, fy, 0], [cx, cy, 1]]``; transposed back when ``K[0, 2] == 0``, as his
  code does) with a 1-based principal point (MATLAB's pixel (1, 1) is the top-left centre).
* **Text** (LUCES-style: the same content as text tables, one row per LED): in one folder,
  positions ``led_positions.txt`` (or ``S.txt``), axes ``led_directions.txt`` (or
  ``Dir.txt``, optional), intensities ``led_intensities.txt`` / ``light_intensities.txt``
  (or ``Phi.txt``, optional), lobes ``led_mu.txt`` (or ``mu.txt``, optional), and ``K.txt``
  (3 x 3, either orientation as above). Its principal point is taken as 1-based too
  unless ``k_origin=0`` says otherwise.

The workbench's rig frame (:mod:`photometric.camera`) has its origin on the optical axis
in the reference plane, x right, y up, z towards the camera, and a 0-based principal
point. With the camera ``H`` above the reference plane (the working distance, which these
files do not hold), a camera-frame point ``(x, y, z)`` is ``(x, -y, H - z)`` in the rig
frame, an axis ``(a, b, c)`` is ``(a, -b, -c)``, and the principal point is ``(cx - 1,
cy - 1)``. The intensities become the rig's ``e_k = Phi_k / d0_k^2`` (irradiance at the
reference distance ``d0_k = |P_k|``, :mod:`photometric.leds`; the model
``E = Phi (-l . a)^mu / |P - X|^2`` of both formats), scaled so the largest is 1 (the
files' absolute scale depends on their images' units; the albedo is then relative).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photometric.camera import make_camera
from photometric.leds import point_lights
from photometric.rig import Rig
from surfaces.validate import as_array, InputError, positive

__all__ = ["CameraFrameCalibration", "read_queau", "read_text_calibration", "read_calibration", "to_rig",
           "camera_to_rig_points", "camera_to_rig_axes", "load_axes", "TEXT_NAMES"]


@dataclass(frozen=True)
class CameraFrameCalibration:
    """A near-field calibration as the files state it, in the camera frame (x right, y down, z forward).

    Attributes
    ----------
    positions_mm : numpy.ndarray, shape (N, 3)
        LED positions, mm, from the camera centre.
    axes : numpy.ndarray or None, shape (N, 3)
        Unit LED axes (from the LED into the scene).
    phi : numpy.ndarray or None, shape (N, 3)
        Radiant intensities per colour (the files' units).
    mu : numpy.ndarray or None, shape (N,)
        Lobe exponents.
    focal_length_px : (float, float)
        ``(fx, fy)``, pixels.
    principal_point_px : (float, float)
        ``(cx, cy)`` (column, row), **0-based** (already shifted from the file's origin).
    source : dict
        The files read and their format.
    """

    positions_mm: np.ndarray
    axes: np.ndarray | None
    phi: np.ndarray | None
    mu: np.ndarray | None
    focal_length_px: tuple[float, float]
    principal_point_px: tuple[float, float]
    source: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.positions_mm.shape[0])


def camera_to_rig_points(points, camera_height_mm: float) -> np.ndarray:
    """Camera-frame points (x right, y down, z forward; mm) in the rig frame (x right, y up, z up).

    Parameters
    ----------
    points : array_like, shape (N, 3)
    camera_height_mm : float
        Camera centre's height above the reference plane, mm.

    Returns
    -------
    numpy.ndarray, shape (N, 3)

    Examples
    --------
    >>> camera_to_rig_points([[10.0, -20.0, 75.0]], 200.0).tolist()
    [[10.0, 20.0, 125.0]]
    """
    p = as_array(points, "points", ndim=2)
    return np.stack([p[:, 0], -p[:, 1], positive(camera_height_mm, "camera_height_mm") - p[:, 2]], axis=1)


def camera_to_rig_axes(axes) -> np.ndarray:
    """Camera-frame directions in the rig frame (y and z flip), normalised.

    Examples
    --------
    >>> camera_to_rig_axes([[0.0, 0.6, 0.8]]).tolist()
    [[0.0, -0.6, -0.8]]
    """
    a = as_array(axes, "axes", ndim=2) * np.array([1.0, -1.0, -1.0])
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def _intrinsics(K, name: str, k_origin: int) -> tuple[tuple[float, float], tuple[float, float], bool]:
    K = as_array(K, name, shape=(3, 3))
    transposed = bool(K[0, 2] == 0 and K[1, 2] == 0 and (K[2, 0] != 0 or K[2, 1] != 0))
    if transposed:
        K = K.T
    if K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
        raise InputError(f"{name}: expected intrinsics [[fx, s, cx], [0, fy, cy], [0, 0, 1]] (or its transpose), "
                         f"got {K.tolist()}")
    if abs(K[0, 1]) > 1e-9 * abs(K[0, 0]):
        raise InputError(f"{name}: a skewed camera (K[0, 1] = {K[0, 1]}) is not supported")
    if k_origin not in (0, 1):
        raise InputError(f"k_origin: the principal point's origin is 0 or 1, got {k_origin!r}")
    fx, fy = positive(K[0, 0], f"{name} fx"), positive(K[1, 1], f"{name} fy")
    return (fx, fy), (float(K[0, 2]) - k_origin, float(K[1, 2]) - k_origin), transposed


def _rows(value, n: int | None, name: str, width: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[1] not in width or (n is not None and a.shape[0] != n):
        raise InputError(f"{name}: expected {n if n is not None else 'N'} rows of {' or '.join(map(str, width))} "
                         f"value(s), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name}: values must be finite")
    return a


def _assemble(S, Dir, Phi, mu, K, names: dict, k_origin: int, fmt: str) -> CameraFrameCalibration:
    pos = _rows(S, None, names["S"], (3,))
    n = pos.shape[0]
    if np.any(pos[:, 2] <= 0):
        raise InputError(f"{names['S']}: LED(s) {np.flatnonzero(pos[:, 2] <= 0).tolist()} are not in front of the "
                         "camera (z forward must be > 0 in the camera frame)")
    axes = None
    if Dir is not None:
        axes = _rows(Dir, n, names["Dir"], (3,))
        norm = np.linalg.norm(axes, axis=1)
        if np.any(norm == 0):
            raise InputError(f"{names['Dir']}: zero-length LED axis")
        axes = axes / norm[:, None]
    phi = None
    if Phi is not None:
        phi = _rows(Phi, n, names["Phi"], (1, 3))
        if np.any(phi <= 0):
            raise InputError(f"{names['Phi']}: intensities must be positive")
        phi = np.repeat(phi, 3, axis=1) if phi.shape[1] == 1 else phi
    m = None
    if mu is not None:
        m = _rows(mu, n, names["mu"], (1,))[:, 0]
        if np.any(m < 0):
            raise InputError(f"{names['mu']}: lobe exponents must be >= 0")
    f, pp, transposed = _intrinsics(K, names["K"], k_origin)
    source = {"format": fmt, "files": {k: str(v) for k, v in names.items()}, "k_transposed": transposed,
              "principal_point_origin_in_file": k_origin}
    return CameraFrameCalibration(pos, axes, phi, m, f, pp, source)


def _loadmat(path: Path, keys: tuple[str, ...], required: tuple[str, ...]) -> dict:
    from scipy.io import loadmat

    if not path.is_file():
        raise FileNotFoundError(f"calibration: file {path} does not exist")
    try:
        doc = loadmat(str(path))
    # scipy raises NotImplementedError for MATLAB v7.3 files (HDF5): a file it cannot read, not unfinished code
    except (ValueError, OSError, NotImplementedError) as exc:
        raise InputError(f"calibration: {path} is not a MATLAB .mat file scipy can read ({exc})") from None
    missing = [k for k in required if k not in doc]
    if missing:
        has = sorted(k for k in doc if not k.startswith("__"))
        raise InputError(f"calibration: {path} lacks {missing} (has {has})")
    return {k: doc.get(k) for k in keys}


def read_queau(light_mat, camera_mat, *, k_origin: int = 1) -> CameraFrameCalibration:
    """Read Quéau-format ``light.mat`` and ``camera.mat`` (see the module docstring).

    Parameters
    ----------
    light_mat, camera_mat : str or Path
        The two files.
    k_origin : {1, 0}, optional
        Origin of the principal point in ``K`` (1: MATLAB, the format's).

    Returns
    -------
    CameraFrameCalibration

    Raises
    ------
    FileNotFoundError, InputError
    """
    lp, cp = Path(light_mat), Path(camera_mat)
    light = _loadmat(lp, ("S", "Dir", "Phi", "mu"), ("S",))
    cam = _loadmat(cp, ("K",), ("K",))
    names = {"S": f"{lp.name} S", "Dir": f"{lp.name} Dir", "Phi": f"{lp.name} Phi", "mu": f"{lp.name} mu",
             "K": f"{cp.name} K"}
    cal = _assemble(light["S"], light["Dir"], light["Phi"], light["mu"], cam["K"], names, k_origin, "queau")
    return CameraFrameCalibration(**{**cal.__dict__, "source": {**cal.source, "light": str(lp), "camera": str(cp)}})


#: Accepted names of the text format's files, first found wins (see the module docstring).
TEXT_NAMES = {"S": ("led_positions.txt", "S.txt"), "Dir": ("led_directions.txt", "Dir.txt"),
              "Phi": ("led_intensities.txt", "light_intensities.txt", "Phi.txt"), "mu": ("led_mu.txt", "mu.txt"),
              "K": ("K.txt", "intrinsics.txt")}


def read_text_calibration(folder, *, k_origin: int = 1) -> CameraFrameCalibration:
    """Read the text form of the same calibration (LUCES-style tables, see the module docstring).

    Parameters
    ----------
    folder : str or Path
        The folder with the tables.
    k_origin : {1, 0}, optional
        Origin of the principal point in ``K.txt``.

    Returns
    -------
    CameraFrameCalibration
    """
    d = Path(folder)
    if not d.is_dir():
        raise NotADirectoryError(f"calibration: {d} is not a folder")
    found, values = {}, {}
    for key, candidates in TEXT_NAMES.items():
        path = next((d / c for c in candidates if (d / c).is_file()), None)
        if path is None:
            if key in ("S", "K"):
                raise FileNotFoundError(f"calibration: {d} has none of {list(candidates)}")
            values[key] = None
            found[key] = key
            continue
        try:
            values[key] = np.loadtxt(path, ndmin=2, delimiter=None if "," not in path.read_text() else ",")
        except ValueError as exc:
            raise InputError(f"calibration: {path} is not a table of numbers ({exc})") from None
        found[key] = path.name
    return _assemble(values["S"], values["Dir"], values["Phi"],
                     None if values["mu"] is None else values["mu"].ravel(), values["K"], found, k_origin, "text")


def load_axes(path) -> np.ndarray:
    """LED axes from a text file, ``x y z`` per LED (``--led-axes``; any length, normalised by :func:`to_rig`).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    numpy.ndarray, shape (N, 3)
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"led axes: file {p} does not exist")
    try:
        a = np.loadtxt(p, ndmin=2, delimiter="," if "," in p.read_text() else None)
    except ValueError as exc:
        raise InputError(f"led axes: {p} is not a table of numbers ({exc})") from None
    return _rows(a, None, f"led axes ({p.name})", (3,))


def read_calibration(path, camera_mat=None, *, k_origin: int = 1) -> CameraFrameCalibration:
    """Read either format: a ``light.mat`` (with ``camera.mat`` beside it unless given) or a text folder.

    Parameters
    ----------
    path : str or Path
        ``light.mat``, or a folder holding ``light.mat`` + ``camera.mat`` or the text tables.
    camera_mat : str or Path, optional
        ``camera.mat`` (default: beside ``light.mat``).
    k_origin : {1, 0}, optional

    Returns
    -------
    CameraFrameCalibration
    """
    p = Path(path)
    if p.is_dir() and (p / "light.mat").is_file():
        p = p / "light.mat"
    if p.suffix.lower() == ".mat":
        return read_queau(p, camera_mat if camera_mat is not None else p.parent / "camera.mat", k_origin=k_origin)
    if p.is_dir():
        return read_text_calibration(p, k_origin=k_origin)
    if not p.exists():
        raise FileNotFoundError(f"calibration: {p} does not exist")
    raise InputError(f"calibration: {p} is neither a .mat file nor a folder of text tables")


def to_rig(cal: CameraFrameCalibration, camera_height_mm: float, image_size, *, axes=None,
           focal_length_px=None, principal_point_px=None) -> Rig:
    """The workbench rig of a camera-frame calibration, with the camera ``camera_height_mm`` above the plane.

    Parameters
    ----------
    cal : CameraFrameCalibration
    camera_height_mm : float
        Working distance: the camera centre's height above the reference plane, mm (the
        files do not hold it; :func:`photometric.distance.estimate_camera_height` estimates it
        from the images).
    image_size : (H, W)
        The images' size, pixels.
    axes : array_like, shape (N, 3), optional
        LED axes in the camera frame, replacing the file's (``--led-axes``).
    focal_length_px : float or (float, float), optional
        Replaces the file's ``(fx, fy)``.
    principal_point_px : (float, float), optional
        Replaces the file's principal point; 0-based.

    Returns
    -------
    Rig
        Positions, axes and lobes in the rig frame, the perspective camera, the relative
        intensities; ``calibration`` records the source and the conversion.

    Examples
    --------
    >>> cal = CameraFrameCalibration(np.array([[10.0, -20.0, 75.0], [-10.0, -20.0, 75.0], [0.0, 20.0, 75.0]]),
    ...                              np.array([[0.0, 0.6, 0.8]] * 3), None, np.ones(3), (3000.0, 3010.0),
    ...                              (960.0, 600.0))
    >>> rig = to_rig(cal, 200.0, (1200, 1920))
    >>> rig.lights.positions[0].tolist(), rig.lights.axes[0].round(3).tolist(), rig.camera.fy
    ([10.0, 20.0, 125.0], [0.0, -0.6, -0.8], 3010.0)
    """
    h = positive(camera_height_mm, "camera_height_mm")
    n = len(cal)
    ax = cal.axes if axes is None else _rows(axes, n, "led_axes", (3,))
    pos = camera_to_rig_points(cal.positions_mm, h)
    if np.any(pos[:, 2] <= 0):
        raise InputError(f"camera_height_mm: at {h:g} mm LED(s) {np.flatnonzero(pos[:, 2] <= 0).tolist()} are at "
                         "or below the reference plane (the working distance must exceed the LEDs' depth "
                         f"{float(cal.positions_mm[:, 2].max()):g} mm)")
    rig_axes = None if ax is None else camera_to_rig_axes(ax)
    mu = cal.mu if rig_axes is not None else None
    if rig_axes is not None and mu is None:
        raise InputError("led axes: the LED axes need lobe exponents mu (the file has none; give --led-mu)")
    lights = point_lights(pos, rig_axes, mu, name="calibration S")
    intens = None
    if cal.phi is not None:
        e = cal.phi / np.sum(pos**2, axis=1)[:, None]
        intens = e / e.max()
    f = cal.focal_length_px if focal_length_px is None else focal_length_px
    pp = cal.principal_point_px if principal_point_px is None else principal_point_px
    camera = make_camera("perspective", focal_length_px=f, camera_height_mm=h, principal_point_px=pp)
    hw = as_array(image_size, "image_size", shape=(2,))
    calibration = {
        "method": f"imported ({cal.source.get('format', '?')} camera-frame calibration)",
        "source": cal.source,
        "conversion": "rig = (x, -y, H - z) of the camera frame (x right, y down, z forward); axes (a, -b, -c); "
                      "principal point 0-based; intensities Phi / |P|^2 scaled to a largest of 1",
        "camera_frame": {"positions_mm": cal.positions_mm.tolist(),
                         "axes": None if ax is None else np.asarray(ax).tolist(),
                         "phi": None if cal.phi is None else cal.phi.tolist()},
        "camera_height_mm": h,
    }
    return Rig(lights, camera, (int(hw[0]), int(hw[1])), intens, calibration=calibration)
