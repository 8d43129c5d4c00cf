"""The `dielectric` material [Mitsuba 3: dielectric, roughdielectric]: glass, water. Index `ior`
inside (outside is 1), `color` the specular transmittance (reflection untinted), `absorption`
the Beer-Lambert coefficient inside (the integrators apply it). Smooth (`roughness` 0):
reflection with the Fresnel probability, else refraction (delta lobes). Rough: Walter et al.
2007 with GGX; a normal visible from wo's side, then reflection with probability F(wo.m), else
refraction. Not two-sided: +z is outside. Trace mode shows it fully transparent with Fresnel."""

import math

import numpy as np

from ...vec import add, dot, inline_function, kernel_function, madd, mul, normalize
from ..optics import fresnel_dielectric
from .lobes import ALPHA_MIN, EVALUATE, FAILED, ZERO, reflect, same_side, smooth_dielectric
from .microfacet import ggx_d, sample_vndf, smith_g1
from .phong import phong_exponent
from .table import (
    MAT_ABSORPTION,
    MAT_IOR,
    MAT_ROUGHNESS,
)

NAME = "dielectric"
KIND = 3
SOLID = True  # compile/media.py: a solid, clear inside unless it has an interior medium


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    row[MAT_IOR] = mat.ior
    row[MAT_ABSORPTION : MAT_ABSORPTION + 3] = mat.absorption
    # An interface of index 1 bends nothing, rough or not: smooth, as it renders (the rough
    # lobes' half vector of a straight-through pair is zero, and they had rendered black)
    row[MAT_ROUGHNESS] = 0.0 if mat.ior == 1.0 else mat.roughness


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency) of trace mode: transparent, with Fresnel."""
    return phong_exponent(mat.roughness), 0.0, 1.0


@kernel_function
def evaluate(mat, m, color, wo, wi):
    co = wo[2]
    ci = wi[2]
    if mat[m, MAT_ROUGHNESS] <= 0.0 or co == 0.0 or ci == 0.0:
        return ZERO, 0.0
    alpha = max(mat[m, MAT_ROUGHNESS], ALPHA_MIN)
    ior = mat[m, MAT_IOR]
    reflect_ = same_side(co, ci)
    eta = ior if co > 0.0 else 1.0 / ior  # n on the other side / n on wo's side
    # the (generalised) half-vector, turned to +z
    h = normalize(add(wo, wi) if reflect_ else madd(wo, wi, eta))
    if h[2] < 0.0:
        h = mul(h, -1.0)
    dwo = dot(wo, h)
    dwi = dot(wi, h)
    if h[2] == 0.0 or not same_side(dwo, co) or not same_side(dwi, ci):
        return ZERO, 0.0
    d = ggx_d(h, alpha)
    g1o = smith_g1(wo, h, alpha)
    g = g1o * smith_g1(wi, h, alpha)
    fr = fresnel_dielectric(abs(dwo), 1.0 / eta)[0]
    pdf_h = g1o * abs(dwo) * d / abs(co)  # normals visible from wo's side
    if reflect_:
        v = fr * d * g / (4.0 * abs(co) * abs(ci))
        return (v, v, v), pdf_h * fr / (4.0 * abs(dwi))
    denom = (dwo + eta * dwi) ** 2
    if not (denom > 0.0):
        return ZERO, 0.0
    # Walter et al.'s BTDF times the radiance factor 1 / eta^2, which cancels its eta^2
    v = (1.0 - fr) * d * g * abs(dwo) * abs(dwi) / (abs(co) * abs(ci) * denom)
    return mul(color, v), pdf_h * (1.0 - fr) * eta * eta * abs(dwi) / denom


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    if mat[m, MAT_ROUGHNESS] <= 0.0:
        return smooth_dielectric(mat[m, MAT_IOR], color, wo, u0)
    co = wo[2]
    ior = mat[m, MAT_IOR]
    # a normal visible from wo's side (seen from -wo when wo is inside), on the +z side
    h = sample_vndf(wo if co > 0.0 else mul(wo, -1.0), max(mat[m, MAT_ROUGHNESS], ALPHA_MIN), u1, u2)
    dwo = dot(wo, h)
    ratio = 1.0 / ior if co > 0.0 else ior  # n on wo's side / n on the other side
    fr, cos_t = fresnel_dielectric(abs(dwo), ratio)
    if u0 < fr or fr >= 1.0:
        wi = reflect(wo, h)
        ok = same_side(wi[2], co)
    else:
        wi = madd(mul(wo, -ratio), h, ratio * dwo - math.copysign(cos_t, dwo))
        ok = same_side(wi[2], -co)
    if not ok:
        return FAILED
    return wi, ZERO, EVALUATE, False


@inline_function
def delta_only(mat, m):
    return mat[m, MAT_ROUGHNESS] == 0.0


@inline_function
def two_sided(mat, m):
    return False


@inline_function
def aov_albedo(mat, m, color):
    """The `albedo` AOV and the denoiser's guide: the colour at the hit."""
    return color
