"""Mirror reflection, Snell refraction and the exact dielectric Fresnel equations."""

import math

from ..vec import dot, kernel_function, madd, mul


@kernel_function
def reflect(d, n):
    """Mirror d about the unit normal n: d - 2 (d.n) n (the seed's 2N(N.L) - L with L = -d)."""
    return madd(d, n, -2.0 * dot(d, n))


@kernel_function
def fresnel_dielectric(cos_i, eta):
    """Unpolarised reflectance of a dielectric interface (exact Fresnel equations).

    cos_i: cosine of the incidence angle (> 0), eta = n_incident / n_transmitted.
    Returns (reflectance, cos_t); reflectance 1 and cos_t 0 under total internal reflection."""
    sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i)
    if sin2_t >= 1.0:
        return 1.0, 0.0
    cos_t = math.sqrt(1.0 - sin2_t)
    r_s = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    r_p = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    return 0.5 * (r_s * r_s + r_p * r_p), cos_t


@kernel_function
def refract(d, n, eta, cos_i, cos_t):
    """Snell's law: d refracted through the unit normal n facing against d."""
    return madd(mul(d, eta), n, eta * cos_i - cos_t)
