"""Camera options against the camera an input folder or rig states (issue 37: say it, never silently).

A rounded ``--pixel-size 0.0586`` for a folder rendered at 0.05859375 mm scales
every length in mm (a calibrated LED 200 mm away moves by about 0.2 mm), and a
``--camera perspective`` applied to an orthographic folder gives wrong heights
without any error. :func:`camera_conflicts` lists such contradictions;
:func:`warn_camera_conflicts` turns each into one ``workbench: warning:`` line.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

#: relative difference of two pixel sizes (or focal lengths, heights) taken as a disagreement
RELATIVE_TOLERANCE = 1e-6


def _stated_camera(folder: Path) -> tuple[dict | None, str]:
    """The camera a folder's scene.json states (``model`` and its numbers), and where it says so."""
    path = folder / "scene.json"
    if not path.is_file():
        return None, ""
    try:
        scene = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        return None, ""  # the readers refuse it with the reason
    if not isinstance(scene, dict):
        return None, ""
    cam = scene.get("camera")
    if isinstance(cam, dict) and cam.get("model") in ("orthographic", "perspective"):
        return cam, str(path)
    if isinstance(scene.get("pixel_size_mm"), (int, float)):
        return {"model": "orthographic", "pixel_size_mm": float(scene["pixel_size_mm"])}, str(path)
    return None, ""


def _rig_camera(rig: str | Path) -> tuple[dict | None, str]:
    path = Path(rig)
    try:
        cam = json.loads(path.read_text()).get("camera")
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, AttributeError):
        return None, ""  # the rig reader refuses it with the reason
    return (cam, str(path)) if isinstance(cam, dict) and "model" in cam else (None, "")


def _led_distance(folders: Iterable[Path]) -> float | None:
    for folder in folders:
        path = folder / "light_positions.txt"
        if path.is_file():
            try:
                return float(np.linalg.norm(np.loadtxt(path, ndmin=2), axis=1).max())
            except ValueError:
                return None
    return None


def camera_conflicts(folders: Iterable[str | Path] = (), *, rig: str | Path | None = None,
                     pixel_size: float | None = None, camera: str | None = None,
                     focal_length_px: float | None = None, camera_height_mm: float | None = None) -> list[str]:
    """The camera options that contradict the camera stated by the input folders or the rig.

    Parameters
    ----------
    folders : iterable of path-like
        Input folders; each one's ``scene.json`` (``camera``, or ``pixel_size_mm``) is read
        when present. Folders without one are skipped.
    rig : path-like, optional
        A ``rig.json`` whose ``camera`` is compared too.
    pixel_size : float, optional
        ``--pixel-size`` (mm).
    camera : {"orthographic", "perspective"}, optional
        ``--camera``; ``focal_length_px`` or ``camera_height_mm`` imply perspective.
    focal_length_px, camera_height_mm : float, optional
        ``--focal-length-px``, ``--camera-height``.

    Returns
    -------
    list of str
        One sentence per contradiction (distinct), naming the option, both values and the
        consequence; empty when the options agree or none is given.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     scene = {"camera": {"model": "orthographic", "pixel_size_mm": 0.05859375}}
    ...     _ = (Path(d) / "scene.json").write_text(json.dumps(scene))
    ...     (message,) = camera_conflicts([d], pixel_size=0.0586)
    ...     same = camera_conflicts([d], pixel_size=0.05859375)
    ...     perspective = camera_conflicts([d], camera="perspective", focal_length_px=4000, camera_height_mm=400)
    >>> message.startswith("--pixel-size 0.0586 differs"), "by +0.0107 %" in message, same
    (True, True, [])
    >>> perspective[0].startswith("--camera perspective contradicts the orthographic camera")
    True
    """
    model = camera or ("perspective" if focal_length_px is not None or camera_height_mm is not None else None)
    folders = [Path(f) for f in folders]
    stated = [_stated_camera(f) for f in folders]
    if rig is not None:
        stated.append(_rig_camera(rig))
    distance = _led_distance(folders)
    out: list[str] = []
    for cam, where in stated:
        if cam is None:
            continue
        where = "..." + where[-40:] if len(where) > 43 else where
        if model is not None and model != cam["model"]:
            out.append(f"--camera {model} contradicts the {cam['model']} camera of {where}: the heights and "
                       "positions in mm follow the camera given, so they are wrong unless the images really "
                       f"come from a {model} camera (leave the camera options out to use the stated one)")
            continue
        checks = [("--pixel-size", pixel_size, cam.get("pixel_size_mm"), "pixel size", "mm"),
                  ("--focal-length-px", focal_length_px, cam.get("focal_length_px"), "focal length", "px"),
                  ("--camera-height", camera_height_mm, cam.get("camera_height_mm"), "camera height", "mm")]
        for option, given, own, what, unit in checks:
            if given is None or not isinstance(own, (int, float)) or own == 0:
                continue
            rel = float(given) / float(own) - 1.0
            if abs(rel) <= RELATIVE_TOLERANCE:
                continue
            text = (f"{option} {given:.8g} differs from the camera of {where} ({what} {own:.8g} {unit}) by "
                    f"{100 * rel:+.3g} %: every length in mm scales with it")
            if distance is not None and option == "--pixel-size":
                text += (f" (LEDs {distance:.0f} mm away move by about {abs(rel) * distance:.2g} mm, more when "
                         "triangulated from mirror spheres)")
            out.append(text)
    return list(dict.fromkeys(out))


def warn_camera_conflicts(folders: Iterable[str | Path] = (), **options) -> list[str]:
    """Warn (``UserWarning``, one ``workbench: warning:`` line each) about :func:`camera_conflicts`.

    Parameters
    ----------
    folders : iterable of path-like
    **options
        As :func:`camera_conflicts`.

    Returns
    -------
    list of str
        The messages warned.
    """
    messages = camera_conflicts(folders, **options)
    for message in messages:
        warnings.warn(message, UserWarning, stacklevel=2)
    return messages
