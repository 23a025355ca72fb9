"""Accuracy of photometric stereo against deviated light directions (seed 002(a)).

Seed 002(a) reconstructs a surface from a triad of images under three known light
directions (Lambertian model ``I_k = rho * (l_k . n)``, so ``rho n = L^-1 I``) and asks
how much the reconstructed derivatives ``p``, ``q`` suffer when the real light
directions deviate from the nominal ones, and which deviations keep the error below a
tolerance over a range of derivatives.

Modules, one idea each (every public name is also here, ``errors.sensitivity``):

* :mod:`~photometric.errors.model`: the exact error ``m = L^+ L' n`` and its first-order
  form (sensitivity, covariance, RMS angle);
* :mod:`~photometric.errors.maps`: error maps over two deviations, error curves;
* :mod:`~photometric.errors.tolerances`: worst case and its inversion into operating limits;
* :mod:`~photometric.errors.montecarlo`: random deviations against the first order;
* :mod:`~photometric.errors.configuration`: conditioning of light rings, image noise;
* :mod:`~photometric.errors.surface`: the errors of a given height field.

Light geometry (angles, deviations, rotations) lives in :mod:`photometric.lights`;
studies that render scenes and write reports live in ``workbench.studies``.
"""

from photometric.errors.configuration import OPTIMAL_SLANT_DEG, noise_propagation, ring_conditioning
from photometric.errors.maps import ErrorMap, error_curves, error_map
from photometric.errors.model import (
    DerivativeError,
    derivative_square,
    exact_error,
    first_order_angle_rms,
    first_order_covariance,
    first_order_error,
    lit_normals,
    reconstruction_matrix,
    sensitivity,
)
from photometric.errors.montecarlo import MonteCarloResult, exceedance_probability, monte_carlo, random_deviations
from photometric.errors.surface import height_error, surface_derivatives
from photometric.errors.tolerances import (
    MODES,
    Tolerance,
    max_derivative_range,
    max_deviation,
    recommendation_table,
    worst_case_error,
)

__all__ = [
    "DerivativeError",
    "ErrorMap",
    "MODES",
    "MonteCarloResult",
    "OPTIMAL_SLANT_DEG",
    "Tolerance",
    "derivative_square",
    "error_curves",
    "error_map",
    "exact_error",
    "exceedance_probability",
    "first_order_angle_rms",
    "first_order_covariance",
    "first_order_error",
    "height_error",
    "lit_normals",
    "max_derivative_range",
    "max_deviation",
    "monte_carlo",
    "noise_propagation",
    "random_deviations",
    "recommendation_table",
    "reconstruction_matrix",
    "ring_conditioning",
    "sensitivity",
    "surface_derivatives",
    "worst_case_error",
]
