"""Cameras for ray-cast pictures: pinhole or orthographic, standard views fitted to a box.

Conventions
-----------
World coordinates are those of the geometry (mm for CT and height fields).
Standard views assume z is "up" for the front/side views; "top" looks down the
z axis, which is the camera view of a photometric height field (x right, y up,
z towards the camera). Images are ``(H, W)``; pixel ``(row, col)`` has its
centre at ``col + 0.5``, ``row + 0.5``; row 0 is the top row. The camera frame
is x right, y up, z towards the viewer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from surfaces.validate import as_array, InputError, positive

__all__ = ["STANDARD_VIEWS", "Camera", "fit_camera"]

# view name -> (direction from the target towards the eye, camera up vector)
STANDARD_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "top": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "bottom": ((0.0, 0.0, -1.0), (0.0, -1.0, 0.0)),
    "iso": ((1.0, -1.0, 1.0), (0.0, 0.0, 1.0)),
}

@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera.

    Attributes
    ----------
    eye, target, up : (3,) float64
        Camera position, the point it looks at, and the approximate up direction
        (world units). ``up`` need not be orthogonal to the viewing direction.
    fov_deg : float or None
        Vertical field of view in degrees for a perspective camera; ``None``
        for an orthographic camera.
    ortho_height : float
        Height of the orthographic view window in world units (ignored for a
        perspective camera).
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float | None = None
    ortho_height: float = 2.0

    def __post_init__(self) -> None:
        for name in ("eye", "target", "up"):
            object.__setattr__(self, name, as_array(getattr(self, name), name, shape=(3,)))
        if np.linalg.norm(self.target - self.eye) == 0:
            raise InputError("camera: eye and target coincide")
        if self.fov_deg is not None and not 0.0 < float(self.fov_deg) < 180.0:
            raise InputError(f"fov_deg: must lie in (0, 180) degrees, got {self.fov_deg}")
        positive(self.ortho_height, "ortho_height")
        forward = self.target - self.eye
        if np.linalg.norm(np.cross(forward, self.up)) <= 1e-12 * np.linalg.norm(forward):
            raise InputError("camera: up is parallel to the viewing direction")

    @property
    def perspective(self) -> bool:
        """True for a perspective camera."""
        return self.fov_deg is not None

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal camera frame.

        Returns
        -------
        right, up, back : (3,) float64
            Image x (right), image y (up) and the direction towards the viewer
            (``back = -forward``), a right-handed frame.
        """
        back = self.eye - self.target
        back = back / np.linalg.norm(back)
        right = np.cross(self.up, back)
        right /= np.linalg.norm(right)
        return right, np.cross(back, right), back

    def _half_extent(self, width: int, height: int) -> tuple[float, float]:
        """Half width and half height of the image plane at unit distance (or ortho window)."""
        aspect = width / height
        if self.perspective:
            half_h = float(np.tan(np.radians(self.fov_deg) / 2.0))
        else:
            half_h = self.ortho_height / 2.0
        return half_h * aspect, half_h

    def rays(self, width: int, height: int) -> np.ndarray:
        """Camera rays through every pixel centre.

        Parameters
        ----------
        width, height : int
            Image size in pixels.

        Returns
        -------
        (height, width, 6) float32
            Origin (3) and direction (3) per pixel, in the RaycastingScene
            layout. Perspective directions are unit vectors; orthographic rays
            start on the image plane through ``eye`` and share the viewing
            direction.
        """
        right, up, back = self.basis()
        half_w, half_h = self._half_extent(width, height)
        x = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * half_w
        y = (1.0 - (np.arange(height) + 0.5) / height * 2.0) * half_h
        rays = np.empty((height, width, 6), np.float32)
        plane = x[None, :, None] * right + y[:, None, None] * up
        if self.perspective:
            direction = plane - back
            direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
            rays[..., :3] = self.eye
            rays[..., 3:] = direction
        else:
            rays[..., :3] = self.eye + plane
            rays[..., 3:] = -back
        return rays

    def project(self, points: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Project world points into the image.

        Parameters
        ----------
        points : (N, 3) array_like
            World points.
        width, height : int
            Image size in pixels.

        Returns
        -------
        pixels : (N, 2) float64
            ``(col, row)`` image coordinates (continuous; pixel centres at +0.5).
        depth : (N,) float64
            Distance in front of the camera along the viewing direction
            (negative behind it).
        """
        pts = as_array(points, "points", shape=(None, 3))
        right, up, back = self.basis()
        rel = pts - self.eye
        xc, yc, depth = rel @ right, rel @ up, -(rel @ back)
        if self.perspective:
            safe = np.where(np.abs(depth) > 1e-12, depth, 1e-12)
            xc, yc = xc / safe, yc / safe
        half_w, half_h = self._half_extent(width, height)
        col = (xc / half_w + 1.0) * width / 2.0
        row = (1.0 - yc / half_h) * height / 2.0
        return np.stack([col, row], axis=1), depth


def fit_camera(
    bounds: np.ndarray,
    view: str | Sequence[float] = "iso",
    aspect: float = 4.0 / 3.0,
    *,
    fov_deg: float | None = None,
    margin: float = 1.08,
    up: Sequence[float] | None = None,
    points: np.ndarray | None = None,
) -> Camera:
    """Camera that frames an axis-aligned box from a standard or given direction.

    Parameters
    ----------
    bounds : (2, 3) array_like
        Box minimum and maximum corners (world units).
    view : str or (3,) array_like
        A name from :data:`STANDARD_VIEWS` (``front``, ``back``, ``side``,
        ``left``, ``top``, ``bottom``, ``iso``) or a direction from the box
        centre towards the eye.
    aspect : float
        Image width / height.
    fov_deg : float, optional
        Vertical field of view for a perspective camera; orthographic when None.
    margin : float
        Extra room around the box (1 = tight).
    up : (3,) array_like, optional
        Up vector; defaults to the standard view's (z, or y for top/bottom).
    points : (N, 3) array_like, optional
        Points to frame tightly (for example the mesh vertices, which must lie in
        the box); the box corners are framed when omitted.

    Returns
    -------
    Camera
        The fitted camera: the box's eight corners project inside the image.

    Examples
    --------
    >>> cam = fit_camera(np.array([[0.0, 0.0, 0.0], [2.0, 1.0, 1.0]]), "top", 4 / 3)
    >>> pixels, depth = cam.project(np.array([[1.0, 0.5, 1.0]]), 400, 300)
    >>> pixels.round(6).tolist()  # the box centre lands in the picture centre
    [[200.0, 150.0]]
    """
    box = as_array(bounds, "bounds", shape=(2, 3))
    positive(aspect, "aspect")
    positive(margin, "margin")
    if isinstance(view, str):
        if view not in STANDARD_VIEWS:
            raise InputError(f"view: unknown view {view!r}; choose from {', '.join(STANDARD_VIEWS)}")
        direction, default_up = STANDARD_VIEWS[view]
    else:
        direction = as_array(view, "view", shape=(3,))
        default_up = (0.0, 0.0, 1.0)
        if abs(direction[2]) > 0.99 * np.linalg.norm(direction):
            default_up = (0.0, 1.0, 0.0)
    d = np.asarray(direction, float)
    if np.linalg.norm(d) == 0:
        raise InputError("view: direction is the zero vector")
    d /= np.linalg.norm(d)
    up_vec = as_array(default_up if up is None else up, "up", shape=(3,))
    centre = box.mean(axis=0)
    radius = max(float(np.linalg.norm(box[1] - box[0])) / 2.0, 1e-9)
    corners = np.array(np.meshgrid(*box.T, indexing="ij")).reshape(3, -1).T
    probe = Camera(centre + d * radius * 4.0, centre, up_vec)
    right, cam_up, back = probe.basis()
    rel = (corners if points is None else as_array(points, "points", shape=(None, 3))) - centre
    ext_x = float(np.abs(rel @ right).max())
    ext_y = float(np.abs(rel @ cam_up).max())
    half_h = max(ext_y, ext_x / aspect, 1e-9) * margin
    if fov_deg is None:
        # the eye sits outside the box so that no corner lies behind the image plane
        return Camera(centre + d * radius * 3.0, centre, up_vec, None, 2.0 * half_h)
    tan_half = np.tan(np.radians(fov_deg) / 2.0)
    distance = half_h / tan_half + radius
    return Camera(centre + d * distance, centre, up_vec, float(fov_deg))
