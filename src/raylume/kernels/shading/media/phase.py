"""The Henyey-Greenstein phase function [pbrt-v4 11.3.1; Mitsuba 3: hg]. Directions are the
ways light travels: cos_theta = dot(d_in, d_out), so g > 0 scatters forward (d_out near d_in)."""

import math

from ...vec import inline_function, turn
from ..lights.sampling import basis

INV_4PI = 0.25 / math.pi


@inline_function
def hg_eval(g, cos_theta):
    """Value (and pdf: the sampling below is exact) of the phase function for cos_theta."""
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_4PI * (1.0 - g * g) / (denom * math.sqrt(denom))


@inline_function
def hg_sample(g, d, u1, u2):
    """A direction scattered from the travel direction d for uniforms (u1, u2) in [0, 1), and its
    pdf (the phase function's value: the sample's weight is 1)."""
    if abs(g) < 1e-3:
        cos_theta = 1.0 - 2.0 * u1
    else:
        s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1)
        cos_theta = min(1.0, max(-1.0, (1.0 + g * g - s * s) / (2.0 * g)))
    sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    c, s = turn(u2)
    a, b = basis(d)
    x, y = sin_theta * c, sin_theta * s
    w = (
        a[0] * x + b[0] * y + d[0] * cos_theta,
        a[1] * x + b[1] * y + d[1] * cos_theta,
        a[2] * x + b[2] * y + d[2] * cos_theta,
    )
    return w, hg_eval(g, cos_theta)
