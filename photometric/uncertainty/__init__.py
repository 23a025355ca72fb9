"""Measurement uncertainty of photometric stereo (GUM, ISO/IEC Guide 98-3): per-pixel slope and
height uncertainty and the budget of every defect figure.

Sources (:class:`Tolerances`, standard uncertainties):

* image noise ``sigma`` (full scale 0-1; with N >= 4 lights estimated from the residuals);
* each light's direction (``light_tolerance_deg``, isotropic: each of the two tangent
  components of the unit light vector has standard uncertainty ``sigma_l``);
* each light's intensity (``intensity_tolerance``, relative);
* each LED's position (``light_position_tolerance_mm``, near-field rigs: each of x, y, z);
* the pixel size (``pixel_size_tolerance``, relative).

Linear propagation (the default)
--------------------------------
The far-field solve is ``m = C x`` with ``C = L^+`` (3, N), ``x_k = I_k / E_k`` and
``m = rho n``; the slopes are ``p = -m_x / m_z``, ``q = -m_y / m_z``, so
``d(p, q) = G dm / m_z`` with ``G = [[-1, 0, -p], [0, -1, -q]]`` and
``m_z = rho / sqrt(1 + p^2 + q^2)``.

* Noise: ``Cov(dm) = sigma^2 C diag(1 / E_k^2) C^T``, hence per pixel
  ``Cov(p, q) = sigma^2 (1 + p^2 + q^2) / rho^2 G C W C^T G^T`` (closed form, vectorised).
* A light parameter ``theta_j`` moving light ``k`` by ``dl_k`` gives
  ``d(p, q) = G c_k (n . dl_k)`` with ``n = (-p, -q, 1)`` (:mod:`photometric.errors.model`);
  an intensity error ``delta_k`` gives ``G c_k (n . l_k) delta_k``. These errors are
  systematic: the same parameter moves every pixel, so each parameter's slope field is
  integrated once (the integration is linear) and ``u_z^2 = sum_j (dz/dtheta_j)^2 u_j^2``.
* The noise part is white in the slopes but not after integration. For the free-boundary
  least-squares (DCT) integrator the covariance of the height is diagonal in the DCT-II
  basis: with ``s_k^2 = 4 sin^2(pi k / 2H)`` and ``c_k^2 = cos^2(pi k / 2H)`` (rows, ``l``
  and ``W`` for columns) the mode variance is
  ``T_kl = h^2 (sigma_p^2 s_l^2 c_l^2 + sigma_q^2 s_k^2 c_k^2) / (s_k^2 + s_l^2)^2``
  (derived here: ``z = (A^T A)^+ A^T M g`` with the edge difference ``A`` and the
  trapezoidal average ``M``, and ``A^T M M^T A`` is diagonal in the same basis). The
  per-pixel variance ``sum_kl a_k(r)^2 b_l(c)^2 T_kl`` takes one DCT-III per axis
  (``cos^2 = (1 + cos 2x) / 2``), and the variance of any linear figure ``w . z`` (a depth
  against a fitted background, a volume) is ``sum_kl T_kl DCT(w)_kl^2``. ``sigma_p``,
  ``sigma_q`` are the mean slope variances over the valid pixels (stationary model).
* Point lights (near-field rigs, orthographic or perspective camera): per pixel the light
  vectors ``s_k(X)`` at the solved points give ``m = M^-1 sum_k x_k s_k`` (``M = sum_k s_k s_k^T``);
  an LED coordinate moves the slopes by ``G c_k (n . ds_k/dP)`` with ``c_k = M^-1 s_k``
  (:class:`PointLightModel`); the noise covariance is ``sum_k w_k c_k c_k^T``. A perspective
  camera's points ``X`` are the solve's ``xy`` and heights; its slope fields are integrated
  on the pixel grid with the reference-plane pixel (the pixels' footprints differ from it
  by ``z / H_c``, second order in a height error).
* Images above 0.26 MP integrate the systematic fields on blocks of ``r x r`` pixels (the
  far-field fields are linear in ``1, p, q, p^2, pq, q^2``, so the block means are exact;
  the blocks must resolve the narrowest defect) and the noise figures on block sums
  plus the peak pixel's own fine-scale variance.
* Defect depth and volume are linear in the height after a least-squares background fit:
  each systematic field's effect is taken on the *measured depth* (field minus its
  background fit), so a light error that only tilts the plate adds nothing.
* Width, length and area depend on the segmentation: their budget holds the pixel size
  and the pixel quantisation of the outline, from the same measures over the measured
  outline, a stadium, rasterised at random sub-pixel offsets, widths and lengths. Those
  errors are bounded, flat-topped and skewed, not normal, and for one defect they are not
  random: its place on the grid (the phase) is fixed, so an axis-aligned outline whose rim
  lies between two pixel rows reads the same error at every trial. U must hold at every
  phase: it is the 95 % half-width of ``Normal(max |e|, others)``, the largest error of the
  model's placements (random ones plus the grid's symmetry points) with the Gaussian of the
  other terms (``defects._every_phase_half_width``; a uniform error of half-range ``a``
  alone gives ``a``), stated as the ``discretisation`` term's effective
  standard uncertainty: the ``u_q`` for which ``2 sqrt(u_q^2 + sum of the others' u^2)``
  is that half-width, so the budget still sums with k = 2. Over random phases it covers
  more than 95 % (benchmarks/results/uncertainty.md, "Every orientation and sub-pixel place").
  A stated image blur (``Tolerances.blur_px``) or pixels that integrate their area
  (``Tolerances.pixel_area``, a camera) widen the slope footprint by a known amount
  (``defects._blur_widening``): the model rasterises the narrower outline and the widening
  is added to its errors as a bias. The length is measured to a
  sub-pixel (:func:`photometric.defects._stadium_length`), so it carries no known bias to
  correct.
  The volume gets the place of its outline.
* The depth's pixel-grid error comes from a model of the defect: a parabolic-section
  groove of the measured depth, width, length and axis whose exact slopes at the pixel
  centres are integrated and measured like the solve, at random sub-pixel placements
  (``defects._groove_depth_errors``). The slope's step at the rim integrates with a
  first-order error that depends on where the rim falls between two pixel centres; it
  wanders along the groove and the deepest pixel picks its largest excursion (a bias that
  depends on the axis, largest near 45 deg), and the deepest centre misses the bottom by
  up to half a pixel. The spread is the depth's ``discretisation``; the bias is stated,
  not corrected (the section is an assumption), as ``method_bias``: the ``u_b`` whose
  k = 2 interval, with every other term, holds 95 % at the placement of the largest error
  (GUM F.2.4.5; the defect's phase is fixed, so the mean error is not enough: an
  axis-aligned V whose bottom lies between two rows reads its largest shortfall at every
  trial). With ``Tolerances.blur_px`` the model blurs its slopes (a 6 px V reads ~21 %
  shallow under 0.6 px blur) on the groove's width, the footprint's widening taken off;
  with ``Tolerances.pixel_area`` it averages them over each pixel, and as the images are
  not linear in steep slopes, also runs the centre's slopes under the box's variance: both
  linearisations' errors count.
  :mod:`photometric.resolution` predicts the same shortfall before any part is measured.

Monte Carlo (``method="montecarlo"``) repeats the fast solve (normals, integration,
defects) with perturbed lights, intensities and noise added to the images, and reports
the spread; the quantisation terms are added as in the linear method (the pixel grid is
the same in every repetition).

Layout: :mod:`~photometric.uncertainty.budget` (sources, figures, tolerances, the result,
``format_value``), :mod:`~photometric.uncertainty.slopes`,
:mod:`~photometric.uncertainty.heights`, :mod:`~photometric.uncertainty.defects` and
:mod:`~photometric.uncertainty.propagation` (:func:`propagate`, Monte Carlo); every public
name is importable from ``photometric.uncertainty``.
"""

from __future__ import annotations

from photometric.uncertainty.budget import (
    COVERAGE_FACTOR,
    FIGURES,
    MC_PIXEL_SAMPLES_LIMIT,
    METHODS,
    SOURCES,
    Tolerances,
    UncertaintyResult,
    check_monte_carlo_size,
    format_value,
)
from photometric.uncertainty.heights import height_noise_variance, linear_variance
from photometric.uncertainty.propagation import propagate
from photometric.uncertainty.slopes import (
    PointLightModel,
    estimate_noise_sigma,
    slope_noise_covariance,
    slope_sensitivities,
    slope_systematic_variance,
)

__all__ = [
    "METHODS",
    "SOURCES",
    "FIGURES",
    "COVERAGE_FACTOR",
    "MC_PIXEL_SAMPLES_LIMIT",
    "Tolerances",
    "UncertaintyResult",
    "PointLightModel",
    "estimate_noise_sigma",
    "slope_noise_covariance",
    "slope_sensitivities",
    "slope_systematic_variance",
    "height_noise_variance",
    "linear_variance",
    "propagate",
    "format_value",
    "check_monte_carlo_size",
]
