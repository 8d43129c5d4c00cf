"""The `plastic` material [Mitsuba 3: plastic, roughplastic; nonlinear = false,
specular_reflectance 1]: diffuse reflectance `color` under a dielectric coating of index eta =
`ior` clamped to [1, 3]:

    f = coating lobe + color / (1 - Fdr) / eta^2 * T(wo) T(wi) / pi

Smooth (`roughness` 0): the coating is a mirror of Fresnel reflectance (a delta lobe), T = 1 -
Fresnel, Fdr = Mitsuba's fit of the diffuse Fresnel reflectance at 1 / eta. Rough: the coating
is GGX reflection F D G / (4 cos cos), T = the energy its rough interface transmits and Fdr its
hemispherical reflectance from inside (coating.py's tables over alpha, eta and cos; Mitsuba
precomputes both per material). The coating lobe is chosen with probability (1 - T(wo)) w /
((1 - T(wo)) w + T(wo) (1 - w)), w = 1 / (1 + mean(color)) (Mitsuba's
specular_sampling_weight, from the colour at the hit). Two-sided. Trace mode shows it matte
with a highlight, and the coating's normal-incidence reflectance as a mirror when smooth."""

import math

import numpy as np

from ...vec import add, dot, inline_function, kernel_function, madd, mul, normalize
from ..optics import fresnel_dielectric
from .coating import PLASTIC_ETA_MAX, coat_terms, fresnel_diffuse_reflectance
from .lobes import ALPHA_MIN, EVALUATE, INV_PI, ZERO, cosine_hemisphere, mirror, reflect, same_side, side
from .microfacet import ggx_d, sample_vndf, smith_g1
from .phong import phong_exponent
from .table import MAT_IOR, MAT_ROUGHNESS

NAME = "plastic"
KIND = 4
SOLID = False  # compile/media.py: no inside of its own (filled with the medium around it)


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    row[MAT_IOR] = mat.ior
    row[MAT_ROUGHNESS] = mat.roughness


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency) of trace mode: a highlight, and the
    coating's normal-incidence reflectance as a mirror when it is smooth."""
    f0 = ((mat.ior - 1.0) / (mat.ior + 1.0)) ** 2
    return phong_exponent(mat.roughness), f0 if mat.roughness < 0.0447 else 0.0, 0.0


@kernel_function
def _terms(mat, m, color, wo):
    """(eta, alpha (0: smooth), T(wo), color / (1 - Fdr) / eta^2, probability of the coating
    lobe) for wo on the +z side."""
    eta = min(max(mat[m, MAT_IOR], 1.0), PLASTIC_ETA_MAX)
    alpha = max(mat[m, MAT_ROUGHNESS], ALPHA_MIN) if mat[m, MAT_ROUGHNESS] > 0.0 else 0.0
    if alpha > 0.0:
        t_o, fdr = coat_terms(alpha, eta, wo[2])
    else:
        t_o = 1.0 - fresnel_dielectric(wo[2], 1.0 / eta)[0]
        fdr = fresnel_diffuse_reflectance(1.0 / eta)
    w = 1.0 / (1.0 + (color[0] + color[1] + color[2]) / 3.0)
    ps = (1.0 - t_o) * w
    pd = t_o * (1.0 - w)
    p_spec = ps / (ps + pd) if ps + pd > 0.0 else 1.0
    return eta, alpha, t_o, mul(color, 1.0 / ((1.0 - fdr) * eta * eta)), p_spec


@kernel_function
def evaluate(mat, m, color, wo, wi):
    if not same_side(wo[2], wi[2]):
        return ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = side(wo, s)
    wi = side(wi, s)
    eta, alpha, t_o, diffuse, p_spec = _terms(mat, m, color, wo)
    pdf = (1.0 - p_spec) * wi[2] * INV_PI
    if alpha == 0.0:
        t_i = 1.0 - fresnel_dielectric(wi[2], 1.0 / eta)[0]
        return mul(diffuse, t_o * t_i * INV_PI), pdf
    t_i = coat_terms(alpha, eta, wi[2])[0]
    h = normalize(add(wo, wi))
    d = ggx_d(h, alpha)
    g1o = smith_g1(wo, h, alpha)
    spec = fresnel_dielectric(dot(wo, h), 1.0 / eta)[0] * d * g1o * smith_g1(wi, h, alpha) / (4.0 * wo[2] * wi[2])
    return madd((spec, spec, spec), diffuse, t_o * t_i * INV_PI), pdf + p_spec * g1o * d / (4.0 * wo[2])


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    s = math.copysign(1.0, wo[2])
    up = side(wo, s)
    eta, alpha, t_o, diffuse, p_spec = _terms(mat, m, color, up)
    if u0 >= p_spec:
        return side(cosine_hemisphere(u1, u2), s), ZERO, EVALUATE, False
    if alpha == 0.0:
        r = (1.0 - t_o) / p_spec
        return mirror(wo), (r, r, r), p_spec, True
    return side(reflect(up, sample_vndf(up, alpha, u1, u2)), s), ZERO, EVALUATE, False


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
