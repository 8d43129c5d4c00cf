"""GGX (Trowbridge-Reitz) microfacets, isotropic: the distribution, Smith's masking, and the
sampling of visible normals. Roughness is the GGX alpha, as Mitsuba's rough plugins take it."""

import math

from ...vec import add, cross, dot, kernel_function, mul, normalize, turn
from .lobes import INV_PI, same_side


@kernel_function
def ggx_d(m, alpha):
    """GGX (Trowbridge-Reitz) density of unit microfacet normals m, isotropic alpha."""
    if m[2] <= 0.0:
        return 0.0
    a2 = alpha * alpha
    t = (m[0] * m[0] + m[1] * m[1]) / a2 + m[2] * m[2]
    return INV_PI / (a2 * t * t)


@kernel_function
def smith_g1(v, m, alpha):
    """Smith's GGX masking 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_v)), written with |v.z| instead
    of the tangent so that grazing v gives 0 (not inf / inf); 0 where v sees m's back side."""
    if not same_side(dot(v, m), v[2]):
        return 0.0
    z = abs(v[2])
    return 2.0 * z / (z + math.sqrt(z * z + alpha * alpha * (v[0] * v[0] + v[1] * v[1])))


@kernel_function
def sample_vndf(v, alpha, u1, u2):
    """A GGX normal m visible from v (v.z >= 0), density G1(v) max(0, v.m) D(m) / v.z (Heitz
    2018): stretch v to alpha = 1, pick a point of the hemisphere's projection seen from v,
    unstretch. The degenerate result (0, 0, 0) has D = 0, so it fails downstream."""
    vh = normalize((alpha * v[0], alpha * v[1], v[2]))
    lensq = vh[0] * vh[0] + vh[1] * vh[1]
    if lensq > 0.0:
        inv = 1.0 / math.sqrt(lensq)
        t1 = (-vh[1] * inv, vh[0] * inv, 0.0)
    else:
        t1 = (1.0, 0.0, 0.0)
    t2 = cross(vh, t1)
    r = math.sqrt(u1)
    cos_phi, sin_phi = turn(u2)
    p1 = r * cos_phi
    s = 0.5 * (1.0 + vh[2])  # squeeze the disk's far half to the visible part
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * r * sin_phi
    p3 = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = add(add(mul(t1, p1), mul(t2, p2)), mul(vh, p3))
    return normalize((alpha * nh[0], alpha * nh[1], max(0.0, nh[2])))
