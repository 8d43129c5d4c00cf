"""What the kinds' BSDFs share: the conventions of the local shading frame, results, and the
smooth dielectric interface (the dielectric kind's and phong's transparent part).

Directions are unit vectors in the local shading frame, z the shading normal; wo points towards
the viewer (the previous path vertex), wi towards the next vertex or the light. f is the BSDF
without the cosine factor; pdf the solid-angle density with which the kind's `sample` returns
wi, lobe-selection probabilities included. A kind's `sample` returns (wi, weight, pdf, delta):
for a delta lobe or a failure the weight and pdf themselves; for any other direction pdf =
EVALUATE, and registry.bsdf_sample then weighs wi with the kind's `evaluate` (all lobes), unless
the kind has one lobe whose weight f cos / pdf it knows in closed form (diffuse: its colour),
which it returns with its pdf (the same value `evaluate` gives: the chi-square tests check it).
A failed sample (grazing wo, a direction below the surface) has weight (0, 0, 0) and pdf 0.

Sides. A two-sided kind acts on wo's side, like Mitsuba's `twosided` adapter: it samples on the
+z side (`side(wo, s)`, s the sign of wo.z) and flips the direction back, and f = 0 when wi is
on the other side. The dielectric (and phong's transparent part) uses the true side: +z is
outside (index 1), -z inside (index MAT_IOR).

Transport is radiance: light refracted from index n_i (wi's side) to n_o (wo's side) is scaled
by (n_o / n_i)^2, as pbrt-v4 (TransportMode::Radiance) and Mitsuba 3 do."""

import math

from ...vec import dot, kernel_function, madd, mul, turn
from ..optics import fresnel_dielectric

INV_PI = 1.0 / math.pi
ALPHA_MIN = 1e-4  # Mitsuba's clamp of GGX alpha

ZERO = (0.0, 0.0, 0.0)
ONE = (1.0, 1.0, 1.0)
UP = (0.0, 0.0, 1.0)
FAILED = (UP, ZERO, 0.0, False)  # (wi, weight, pdf, delta) of a failed sample
# A kind's sample pdf meaning "a non-delta direction: bsdf_sample weighs it with evaluate"
EVALUATE = -1.0


@kernel_function
def same_side(a, b):
    """a and b (z components) strictly on the same side (signs, not a product that can underflow)."""
    return (a > 0.0 and b > 0.0) or (a < 0.0 and b < 0.0)


@kernel_function
def side(v, s):
    """v with its z times s = +-1: the two-sided kinds work with wo's side as +z."""
    return (v[0], v[1], v[2] * s)


@kernel_function
def mirror(v):
    """The mirror direction of v about the normal z."""
    return (-v[0], -v[1], v[2])


@kernel_function
def reflect(v, m):
    """v mirrored about the unit (micro)normal m: 2 (v.m) m - v."""
    return madd(mul(v, -1.0), m, 2.0 * dot(v, m))


@kernel_function
def cosine_hemisphere(u1, u2):
    """A direction about +z with density cos / pi."""
    r = math.sqrt(u1)
    c, s = turn(u2)
    return (r * c, r * s, math.sqrt(max(0.0, 1.0 - u1)))


@kernel_function
def smooth_dielectric(ior, tint, wo, u):
    """Fresnel choice between mirror reflection and refraction; the refracted weight carries
    the tint and the radiance factor (n_wo / n_wi)^2."""
    ratio = 1.0 / ior if wo[2] > 0.0 else ior  # n on wo's side / n on the other side
    f, cos_t = fresnel_dielectric(abs(wo[2]), ratio)
    if u < f or f >= 1.0:
        return mirror(wo), ONE, f, True
    wi = (-ratio * wo[0], -ratio * wo[1], -math.copysign(cos_t, wo[2]))
    return wi, mul(tint, ratio * ratio), 1.0 - f, True
