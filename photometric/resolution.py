"""What a pixel size resolves: checks of the narrowest imperfection of interest against the rig.

A groove a few pixels wide is sampled too coarsely for its depth: the deepest pixel centre
misses a V's bottom by up to half a pixel and the slope's step at the rim integrates with a
first-order error, so it reads shallow (a V-scratch 6 px wide about 14 %, 12 px wide about
9 %, more under blur: 0.6 px of blur takes the 6 px one to about 21 %). Below two pixels
across, the footprint is a line of one or two pixels: its depth is not resolved at all (a
hairline crack a third of a pixel wide is a dark line in the images, not a groove in the
height). :func:`check_resolution` predicts that reading from the groove model of the
uncertainty budget (:func:`photometric.uncertainty.defects._groove_depth_errors`) and says
whether a specification's narrowest imperfection is resolved, resolved with a warning, or
must be refused; :func:`require_resolution` raises on the last.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from surfaces.validate import InputError, positive

__all__ = ["DEPTH_BIAS_WARN", "MIN_PIXELS_ACROSS", "ResolutionCheck", "ResolutionWarning", "check_resolution",
           "require_resolution"]

#: Pixels across the narrowest imperfection below which its depth is not resolved (refused).
MIN_PIXELS_ACROSS = 2.0
#: Predicted relative shortfall of a V-groove's depth (worst sub-pixel place, axis along the
#: grid) above which the check warns.
DEPTH_BIAS_WARN = 0.10


class ResolutionWarning(UserWarning):
    """The narrowest imperfection of interest is resolved, but its depth reads markedly shallow."""


@dataclass(frozen=True)
class ResolutionCheck:
    """The verdict of :func:`check_resolution`.

    Attributes
    ----------
    narrowest_mm, pixel_size_mm : float
        The narrowest imperfection of interest (its width, mm) and the pixel size (mm).
    pixels_across : float
        ``narrowest_mm / pixel_size_mm``.
    blur_px : float
        The images' blur assumed (Gaussian standard deviation, pixels).
    depth_shortfall : float or None
        Predicted relative shortfall of the measured depth of a V-groove that wide (0.14:
        reads 14 % shallow) at the worst sub-pixel place of an axis along the grid; None
        when not resolved (nothing to predict).
    status : {"ok", "warn", "refuse"}
    message : str
        One line saying why (empty when ``ok``).
    """

    narrowest_mm: float
    pixel_size_mm: float
    pixels_across: float
    blur_px: float
    depth_shortfall: float | None
    status: str
    message: str

    def to_dict(self) -> dict:
        """The check as a JSON-ready dict."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


def _v_groove_shortfall(width_px: float, blur_px: float, pixel_area: bool = False) -> float:
    """Relative depth shortfall of a long V-groove ``width_px`` wide along the grid's rows, its
    bottom between two rows or a quarter of a pixel off one (the worse), on the groove model."""
    from photometric.uncertainty.defects import _groove_depth_errors

    offsets = np.array([[0.3, 0.5, 0.0, 0.0], [0.3, 0.25, 0.0, 0.0]])
    depth, h = 1.0, 1.0  # the error is linear in the depth and scales with the pixel
    length = max(8.0 * width_px, 40.0)
    errors = _groove_depth_errors(depth, width_px, length, 0.0, h, offsets, "dct", 1.0, blur_px, pixel_area)
    return float(max(-errors.min(), 0.0) / depth)


def check_resolution(narrowest_mm: float, pixel_size_mm: float, *, blur_px: float = 0.0, pixel_area: bool = False,
                     min_pixels: float = MIN_PIXELS_ACROSS, warn_shortfall: float = DEPTH_BIAS_WARN
                     ) -> ResolutionCheck:
    """Check the narrowest imperfection of interest against what the pixel size resolves.

    Parameters
    ----------
    narrowest_mm : float
        Width of the narrowest imperfection the inspection must judge, mm (> 0).
    pixel_size_mm : float
        Pixel size on the part, mm (> 0).
    blur_px : float
        Gaussian standard deviation of the images' blur, pixels (>= 0).
    pixel_area : bool
        Whether the pixels integrate their area (a camera) rather than sample their centre.
    min_pixels : float
        Pixels across below which the depth is not resolved: ``refuse``.
    warn_shortfall : float
        Predicted relative depth shortfall (V-groove, worst place) above which: ``warn``.

    Returns
    -------
    ResolutionCheck

    Examples
    --------
    >>> check_resolution(0.6, 0.05).status
    'ok'
    >>> c = check_resolution(0.3, 0.05)
    >>> c.status, round(c.pixels_across, 1), 0.10 < c.depth_shortfall < 0.2
    ('warn', 6.0, True)
    >>> check_resolution(0.035, 0.1).status
    'refuse'
    """
    w = positive(narrowest_mm, "narrowest_mm")
    h = positive(pixel_size_mm, "pixel_size_mm")
    blur = positive(blur_px, "blur_px", allow_zero=True)
    n = w / h
    if n < min_pixels:
        return ResolutionCheck(w, h, n, blur, None, "refuse",
                               f"the narrowest imperfection of interest ({w:g} mm) is {n:.2g} px across at "
                               f"{h:g} mm pixels, below {min_pixels:g} px: its depth is not resolved")
    shortfall = _v_groove_shortfall(n, blur, bool(pixel_area))
    if shortfall > warn_shortfall:
        return ResolutionCheck(w, h, n, blur, shortfall, "warn",
                               f"the narrowest imperfection of interest ({w:g} mm) is {n:.3g} px across at {h:g} mm "
                               f"pixels{f' with {blur:g} px blur' if blur else ''}: a V-groove that narrow reads up "
                               f"to {100 * shortfall:.0f} % shallow (stated in its uncertainty, not corrected)")
    return ResolutionCheck(w, h, n, blur, shortfall, "ok", "")


def require_resolution(narrowest_mm: float, pixel_size_mm: float, *, blur_px: float = 0.0,
                       where: str = "narrowest_mm", **limits) -> ResolutionCheck:
    """:func:`check_resolution`, raising on ``refuse`` and warning (:class:`ResolutionWarning`) on ``warn``.

    Parameters
    ----------
    narrowest_mm, pixel_size_mm, blur_px :
        As :func:`check_resolution`.
    where : str
        Name of the input for the message (e.g. ``"spec min_width_mm"``).
    **limits :
        ``min_pixels``, ``warn_shortfall`` of :func:`check_resolution`.

    Returns
    -------
    ResolutionCheck

    Raises
    ------
    InputError
        The narrowest imperfection is below ``min_pixels`` across.
    """
    check = check_resolution(narrowest_mm, pixel_size_mm, blur_px=blur_px, **limits)
    if check.status == "refuse":
        finer = check.narrowest_mm / MIN_PIXELS_ACROSS if "min_pixels" not in limits else None
        hint = f"; pixels of at most {finer:.3g} mm would resolve it" if finer and math.isfinite(finer) else ""
        raise InputError(f"{where}: {check.message}{hint}")
    if check.status == "warn":
        warnings.warn(f"{where}: {check.message}", ResolutionWarning, stacklevel=2)
    return check
