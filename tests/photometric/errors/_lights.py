"""Light sets shared by the tests of photometric.errors."""

from __future__ import annotations

import numpy as np

from photometric.errors import derivative_square
from photometric.lights import lights_from_angles, ring_lights

TRIAD45 = ring_lights(3, 45.0)
TRIAD60 = ring_lights(3, 60.0, azimuth0_deg=10.0)
# an irregular triad (DiLiGenT bear's, rounded) and four lights, to avoid symmetric special cases
BEAR = np.array([[0.6033, -0.2726, 0.7495], [-0.5644, 0.3956, 0.7245], [-0.5094, -0.3824, 0.7709]])
BEAR = BEAR / np.linalg.norm(BEAR, axis=1, keepdims=True)
FOUR = lights_from_angles([40.0, 35.0, 50.0, 45.0], [0.0, 100.0, 190.0, 280.0])
CONFIGS = {"triad45": TRIAD45, "triad60": TRIAD60, "bear": BEAR, "four": FOUR}


def square(D=1.0, n=21):
    """The derivative square |p|, |q| <= D on an n x n grid."""
    return derivative_square(D, n)
