"""The phantoms by name: :data:`SHAPES` and :func:`make_phantom`."""

from __future__ import annotations

from datasets_synthetic.phantoms.base import Phantom
from datasets_synthetic.phantoms.cylinder import TiltedCylinder
from datasets_synthetic.phantoms.lobes import Lobes
from datasets_synthetic.phantoms.ring import Ring
from datasets_synthetic.phantoms.scaled import Ellipsoid, Kidney

_CLASSES = {"ellipsoid": Ellipsoid, "kidney": Kidney, "ring": Ring, "lobes": Lobes,
            "tilted_cylinder": TiltedCylinder}

#: Names of the phantom shapes.
SHAPES = tuple(_CLASSES)


def make_phantom(shape: str, **params) -> Phantom:
    """Build a phantom by name.

    Parameters
    ----------
    shape : str
        ``"ellipsoid"``, ``"kidney"``, ``"ring"``, ``"lobes"`` or ``"tilted_cylinder"``.
    **params
        Keyword arguments of the class (:class:`Ellipsoid`, :class:`Kidney`,
        :class:`Ring`, :class:`Lobes`, :class:`TiltedCylinder`), all in mm/degrees.

    Returns
    -------
    Phantom

    Examples
    --------
    A cylinder of radius 10 mm and length 50 mm, leaning 30 degrees: ``V = pi r^2 L``
    and ``S = 2 pi r (L + r)`` whatever the tilt:

    >>> import numpy as np
    >>> ph = make_phantom("tilted_cylinder", radius_mm=10.0, length_mm=50.0, tilt_deg=30.0)
    >>> round(ph.volume_mm3 / np.pi, 9), round(ph.area_mm2 / np.pi, 9)
    (5000.0, 1200.0)
    >>> round(make_phantom("ellipsoid", a=3.0, b=2.0, c=1.0).volume_mm3 / np.pi, 12)  # 4/3 pi a b c
    8.0
    >>> make_phantom("cube")
    Traceback (most recent call last):
    ...
    ValueError: shape: unknown phantom 'cube'; expected one of ellipsoid, kidney, ring, lobes, tilted_cylinder
    """
    if shape not in _CLASSES:
        raise ValueError(f"shape: unknown phantom {shape!r}; expected one of {', '.join(SHAPES)}")
    try:
        return _CLASSES[shape](**params)
    except TypeError as exc:
        raise ValueError(f"params: {exc}") from None
