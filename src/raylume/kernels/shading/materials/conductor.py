"""The `conductor` material [Mitsuba 3: conductor, roughconductor]: a metal. Its reflectance is
`color` times the conductor Fresnel of eta + i k per channel when the material has `eta` and
`k` (MAT_HAS_ETA 1), else `color` itself (Mitsuba's material "none"). `roughness` is the GGX
alpha: 0 a smooth mirror (a delta lobe), anything else GGX with G = G1(wi) G1(wo), visible
normals sampled (Heitz 2018), alpha clamped to >= 1e-4 as Mitsuba does. Two-sided. Trace mode
shows it as a tinted mirror: reflective 1 - alpha, its colour on the rest, a highlight as wide
as the GGX lobe."""

import math

import numpy as np

from ...vec import add, dot, inline_function, kernel_function, mul, normalize
from .lobes import ALPHA_MIN, EVALUATE, ZERO, mirror, reflect, same_side, side
from .microfacet import ggx_d, sample_vndf, smith_g1
from .phong import phong_exponent
from .table import (
    MAT_ETA,
    MAT_HAS_ETA,
    MAT_K,
    MAT_ROUGHNESS,
)

NAME = "conductor"
KIND = 2
SOLID = False  # compile/media.py: no inside of its own (filled with the medium around it)


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    row[MAT_ROUGHNESS] = mat.roughness
    if mat.eta is not None and mat.k is not None:
        row[MAT_ETA : MAT_ETA + 3] = mat.eta
        row[MAT_K : MAT_K + 3] = mat.k
        row[MAT_HAS_ETA] = 1.0


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency) of trace mode: a tinted mirror."""
    return phong_exponent(mat.roughness), max(0.0, 1.0 - mat.roughness), 0.0


@kernel_function
def fresnel_conductor(cos_i, eta, k):
    """Unpolarised reflectance of a conductor of complex index eta + i k lit from index 1 at
    cos_i in [0, 1] (the closed form Mitsuba takes from Moeller's "Optics")."""
    c2 = cos_i * cos_i
    s2 = 1.0 - c2
    t0 = eta * eta - k * k - s2
    a2b2 = math.sqrt(max(0.0, t0 * t0 + 4.0 * eta * eta * k * k))  # a^2 + b^2
    a = math.sqrt(max(0.0, 0.5 * (a2b2 + t0)))
    t1 = a2b2 + c2
    t2 = 2.0 * cos_i * a
    r_s = (t1 - t2) / max(t1 + t2, 1e-300)
    t3 = a2b2 * c2 + s2 * s2
    t4 = t2 * s2
    r_p = r_s * (t3 - t4) / max(t3 + t4, 1e-300)
    return 0.5 * (r_s + r_p)


@kernel_function
def _reflectance(mat, m, color, cos_i):
    if mat[m, MAT_HAS_ETA] < 0.5:
        return color
    return (
        color[0] * fresnel_conductor(cos_i, mat[m, MAT_ETA], mat[m, MAT_K]),
        color[1] * fresnel_conductor(cos_i, mat[m, MAT_ETA + 1], mat[m, MAT_K + 1]),
        color[2] * fresnel_conductor(cos_i, mat[m, MAT_ETA + 2], mat[m, MAT_K + 2]),
    )


@kernel_function
def evaluate(mat, m, color, wo, wi):
    if mat[m, MAT_ROUGHNESS] <= 0.0 or not same_side(wo[2], wi[2]):
        return ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = side(wo, s)
    wi = side(wi, s)
    alpha = max(mat[m, MAT_ROUGHNESS], ALPHA_MIN)
    h = normalize(add(wo, wi))
    d = ggx_d(h, alpha)
    g1o = smith_g1(wo, h, alpha)
    k = d * g1o * smith_g1(wi, h, alpha) / (4.0 * wo[2] * wi[2])
    # pdf: the visible-normal density G1(wo) (wo.h) D / wo.z times the Jacobian 1 / (4 wo.h)
    return mul(_reflectance(mat, m, color, dot(wo, h)), k), g1o * d / (4.0 * wo[2])


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    s = math.copysign(1.0, wo[2])
    up = side(wo, s)
    if mat[m, MAT_ROUGHNESS] <= 0.0:
        return mirror(wo), _reflectance(mat, m, color, up[2]), 1.0, True
    wi = reflect(up, sample_vndf(up, max(mat[m, MAT_ROUGHNESS], ALPHA_MIN), u1, u2))
    return side(wi, s), ZERO, EVALUATE, False


@inline_function
def delta_only(mat, m):
    return mat[m, MAT_ROUGHNESS] == 0.0


@inline_function
def two_sided(mat, m):
    return True


@inline_function
def aov_albedo(mat, m, color):
    """The `albedo` AOV and the denoiser's guide: the colour at the hit."""
    return color
