"""The phantoms by name: :data:`SHAPES` and :func:`make_phantom`."""

from __future__ import annotations

from datasets_synthetic.phantoms.base import Phantom
from datasets_synthetic.phantoms.cylinder import TiltedCylinder
from datasets_synthetic.phantoms.lobes import Lobes
from datasets_synthetic.phantoms.ring import Ring
from datasets_synthetic.phantoms.scaled import Ellipsoid, Kidney
from surfaces.validate import InputError

_CLASSES = {"ellipsoid": Ellipsoid, "kidney": Kidney, "ring": Ring, "lobes": Lobes,
            "tilted_cylinder": TiltedCylinder}

#: Names of the phantom shapes.
SHAPES = tuple(_CLASSES)

#: Small organs at risk as named shapes (mm): a lens (about 0.11 cc, 9 x 3.6 x 7 mm; planning systems
#: report 0.100-0.130 cc for a left lens) and an optic chiasm (about 0.35 cc, 14 x 8 x 6 mm); both are
#: cut into 1-5 contours at CT slice spacings of 2-3 mm (issue 19, small structures).
PRESETS = {
    "lens": ("ellipsoid", {"a": 4.0, "b": 1.8, "c": 3.5}),
    "chiasm": ("ellipsoid", {"a": 7.0, "b": 4.0, "c": 3.0}),
}


def make_phantom(shape: str, **params) -> Phantom:
    """Build a phantom by name.

    Parameters
    ----------
    shape : str
        ``"ellipsoid"``, ``"kidney"``, ``"ring"``, ``"lobes"`` or ``"tilted_cylinder"``,
        or a preset of :data:`PRESETS` (``"lens"``, ``"chiasm"``).
    **params
        Keyword arguments of the class (:class:`Ellipsoid`, :class:`Kidney`,
        :class:`Ring`, :class:`Lobes`, :class:`TiltedCylinder`), all in mm/degrees;
        they override a preset's.

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
    >>> round(make_phantom("lens").volume_mm3, 1)  # 4/3 pi 4 x 1.8 x 3.5
    105.6
    >>> make_phantom("cube")
    Traceback (most recent call last):
    ...
    surfaces.validate.InputError: shape: unknown phantom 'cube'; expected one of ellipsoid, kidney, ring, lobes, ...
    """
    if shape in PRESETS:
        shape, base = PRESETS[shape]
        params = {**base, **params}
    if shape not in _CLASSES:
        raise InputError(f"shape: unknown phantom {shape!r}; expected one of {', '.join(SHAPES)}")
    try:
        return _CLASSES[shape](**params)
    except TypeError as exc:
        raise InputError(f"params: {exc}") from None
