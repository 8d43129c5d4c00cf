"""The `diffuse` material [Mitsuba 3: diffuse]: Lambertian reflection of reflectance `color`,
two-sided, sampled by the cosine. Trace mode shows it matte."""

import math

import numpy as np

from ...vec import inline_function, kernel_function, mul, turn_in_lanes
from .lobes import INV_PI, ZERO, cosine_hemisphere, same_side, side

NAME = "diffuse"
KIND = 1
SOLID = False  # compile/media.py: no inside of its own (filled with the medium around it)


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    # a diffuse material has no column of its own


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency) of trace mode: matte."""
    return -1.0, 0.0, 0.0


@kernel_function
def evaluate(mat, m, color, wo, wi):
    if not same_side(wo[2], wi[2]):
        return ZERO, 0.0
    return mul(color, INV_PI), abs(wi[2]) * INV_PI


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    """The cosine's direction, weighed f cos / pdf = the colour itself, with evaluate's pdf:
    no second dispatch to evaluate (lobes.py); cos > 0, as sqrt(1 - u1) is for u1 < 1."""
    wi = side(cosine_hemisphere(u1, u2), math.copysign(1.0, wo[2]))
    return wi, color, abs(wi[2]) * INV_PI, False


@inline_function
def lane_sample(wo_z, u1, u2):
    """`sample`'s direction and pdf for a vector loop over paths (path_wavefront.py), from wo's z
    alone: the same cosine (up to turn's rounding), the side picked by a select, not copysign."""
    r = math.sqrt(u1)
    c, s = turn_in_lanes(u2)
    z = math.sqrt(max(0.0, 1.0 - u1))
    return (r * c, r * s, z if wo_z >= 0.0 else -z), z * INV_PI


@inline_function
def delta_only(mat, m):
    return False


@inline_function
def two_sided(mat, m):
    return True


@inline_function
def aov_albedo(mat, m, color):
    """The `albedo` AOV and the denoiser's guide: the colour at the hit."""
    return color
