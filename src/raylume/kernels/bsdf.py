"""BSDFs for path tracing: one evaluation and one sampling routine over the material kinds of
materials.py, following Mitsuba 3's plugins (DESIGN.md section 6).

    bsdf_eval(mat, m, color, wo, wi) -> ((fr, fg, fb), pdf)
    bsdf_sample(mat, m, color, wo, u0, u1, u2) -> (wi, (wr, wg, wb), pdf, delta)

`mat` is the material table, `m` the row, `color` the material's colour at the hit (textures
already looked up). Directions are unit vectors in the local shading frame, z the shading
normal; wo points towards the viewer (the previous path vertex), wi towards the next vertex or
the light. f is the BSDF without the cosine factor; pdf is the solid-angle density with which
bsdf_sample returns wi, lobe-selection probabilities included. Smooth (delta) lobes add nothing
to bsdf_eval; bsdf_sample returns them with delta = True, pdf = the probability of choosing
them and weight = their reflectance (transmittance) / that probability. Any other sample's
weight is f |cos wi| / pdf with the f and pdf of bsdf_eval (all lobes). A failed sample
(grazing wo, a direction below the surface) has weight (0, 0, 0) and pdf 0: end the path.
u0 picks the lobe, (u1, u2) the direction; all three uniform in [0, 1).

Transport is radiance: light refracted from index n_i (wi's side) to n_o (wo's side) is scaled by
(n_o / n_i)^2, as pbrt-v4 (TransportMode::Radiance) and Mitsuba 3 do. Beer-Lambert absorption
is the integrator's.

Sides. DIELECTRIC (and PHONG's transparent part) uses the true side: +z is outside (index 1),
-z inside (index MAT_IOR), wo.z of either sign. Everything else is two-sided, like Mitsuba's
`twosided` adapter: it acts on wo's side (a caller may flip the frame so that wo.z > 0, or not)
and f = 0 when wi is on the other side. wo.z == 0 gives f = 0 and failed samples.

Kinds (Mitsuba 3's plugins in brackets). Roughness is the GGX alpha: 0 selects the smooth
plugin, anything else is clamped to >= 1e-4 as Mitsuba does.
- DIFFUSE [diffuse]: color / pi, cosine-weighted sampling.
- CONDUCTOR [conductor, roughconductor]: color times the conductor Fresnel of eta + i k per
  channel when MAT_HAS_ETA is 1, else times 1 (material "none"). Rough: GGX with
  G = G1(wi) G1(wo), visible normals sampled (Heitz 2018).
- DIELECTRIC [dielectric, roughdielectric]: index MAT_IOR inside, color = specular
  transmittance (reflection untinted). Smooth: reflect with the Fresnel probability, else
  refract. Rough: Walter et al. 2007 with GGX; a normal visible from wo's side, then
  reflection with probability F(wo.m), else refraction.
- PLASTIC [plastic, roughplastic; nonlinear = false, specular_reflectance 1]: diffuse
  reflectance `color` under a dielectric coating of index eta = MAT_IOR clamped to [1, 3]:
  f = coating lobe + color / (1 - Fdr) / eta^2 * T(wo) T(wi) / pi, where smooth: the coating
  is a mirror of Fresnel reflectance (delta), T = 1 - Fresnel, Fdr = Mitsuba's fit of the
  diffuse Fresnel reflectance at 1 / eta; rough: the coating is GGX reflection F D G /
  (4 cos cos), T = the energy its rough interface transmits (the transmission lobe's albedo)
  and Fdr its hemispherical reflectance from inside (Mitsuba precomputes both per material;
  here they are tables over alpha, eta and cos). The
  coating lobe is chosen with probability (1 - T(wo)) w / ((1 - T(wo)) w + T(wo) (1 - w)),
  w = 1 / (1 + mean(color)) (Mitsuba's specular_sampling_weight, from the colour at the hit).
- PHONG, the seed's material, as an energy-conserving BSDF. With T = MAT_TRANSPARENCY,
  r = MAT_REFLECTIVE, s = MAT_SPECULAR (-1: no highlight), ks = 0.04 if s > 0 else 0 and
  kl = (1 - T)(1 - r), its lobes are
    (1) Lambert with reflectance kl * color * (1 - ks);
    (2) if s > 0, the normalized Phong lobe kl * color * ks * (s + 2) / (2 pi) * max(0, cos a)^s,
        a the angle between wi and the mirror direction of wo (sampled with density
        (s + 1) / (2 pi) cos^s a about that direction; powers under e^-50 count as 0);
    (3) a smooth white mirror of reflectance (1 - T) r (delta);
    (4) a smooth dielectric of index MAT_IOR with weight T (delta: Fresnel reflection, untinted
        refraction with the radiance factor, as DIELECTRIC).
  Lobes are chosen in proportion to their luminance weights kl (1 - ks) Y, kl ks Y, (1 - T) r
  and T, Y the colour's Rec. 709 luminance. (1)-(3) are two-sided, (4) uses the true side.
"""

import math
import sys

import numpy as np
from numba import njit

from .materials import (
    CONDUCTOR,
    DIELECTRIC,
    DIFFUSE,
    MAT_ETA,
    MAT_HAS_ETA,
    MAT_IOR,
    MAT_K,
    MAT_KIND,
    MAT_REFLECTIVE,
    MAT_ROUGHNESS,
    MAT_SPECULAR,
    MAT_TRANSPARENCY,
    PLASTIC,
)
from .optics import fresnel_dielectric
from .vec import add, cross, dot, inline_function, kernel_function, madd, mul, normalize

INV_PI = 1.0 / math.pi
ALPHA_MIN = 1e-4  # Mitsuba's clamp of GGX alpha
PLASTIC_ETA_MAX = 3.0  # plastic's index is clamped to [1, PLASTIC_ETA_MAX], the tables' range
PHONG_KS = 0.04  # the share of a Phong material's colour in its highlight lobe

_ZERO = (0.0, 0.0, 0.0)
_ONE = (1.0, 1.0, 1.0)
_UP = (0.0, 0.0, 1.0)
_FAILED = (_UP, _ZERO, 0.0, False)  # (wi, weight, pdf, delta) of a failed sample
# A per-kind sampler's pdf meaning "a non-delta direction: bsdf_sample weighs it with bsdf_eval"
_EVALUATE = -1.0


@kernel_function
def _same_side(a, b):
    """a and b (z components) strictly on the same side (signs, not a product that can underflow)."""
    return (a > 0.0 and b > 0.0) or (a < 0.0 and b < 0.0)


@kernel_function
def _side(v, s):
    """v with its z times s = +-1: the two-sided kinds work with wo's side as +z."""
    return (v[0], v[1], v[2] * s)


@kernel_function
def _mirror(v):
    """The mirror direction of v about the normal z."""
    return (-v[0], -v[1], v[2])


@kernel_function
def _reflect(v, m):
    """v mirrored about the unit (micro)normal m: 2 (v.m) m - v."""
    return madd(mul(v, -1.0), m, 2.0 * dot(v, m))


@kernel_function
def _cosine_hemisphere(u1, u2):
    """A direction about +z with density cos / pi."""
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    return (r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u1)))


@kernel_function
def _grid(x, n):
    """Cell and weight of x in [0, 1] on n equally spaced nodes (n a float: one compilation)."""
    t = min(max(x, 0.0), 1.0) * (n - 1.0)
    i = min(int(t), int(n) - 2)
    return i, t - i


# --- Fresnel ---------------------------------------------------------------------------------
# (the dielectric one is optics.fresnel_dielectric: cos_i >= 0, eta = n_incident / n_transmitted)


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
def fresnel_diffuse_reflectance(eta):
    """Fdr: the dielectric Fresnel reflectance averaged over cosine-weighted incident light,
    eta = n_transmitted / n_incident. Mitsuba's choice of fits: Egan and Hilgeman 1973 below 1,
    d'Eon and Irving 2011 above (both within 0.1 % for common indices)."""
    if eta < 1.0:
        return -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    x = 1.0 / eta
    return 0.919317 + x * (-3.4793 + x * (6.75335 + x * (-7.80989 + x * (4.98554 - 1.36881 * x))))


# --- GGX microfacets -------------------------------------------------------------------------


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
    if not _same_side(dot(v, m), v[2]):
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
    phi = 2.0 * math.pi * u2
    p1 = r * math.cos(phi)
    s = 0.5 * (1.0 + vh[2])  # squeeze the disk's far half to the visible part
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * r * math.sin(phi)
    p3 = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = add(add(mul(t1, p1), mul(t2, p2)), mul(vh, p3))
    return normalize((alpha * nh[0], alpha * nh[1], max(0.0, nh[2])))


# --- Rough plastic's coating tables ----------------------------------------------------------
# T(alpha, eta, mu): the energy that the GGX coating transmits (its transmission lobe's
# albedo, masking included) of light arriving at cos mu from outside, and R_int(alpha, eta):
# its reflectance for diffuse light from inside (Mitsuba's roughplastic computes both per
# material, with eval_transmittance and eval_reflectance; R_int is stored divided by the smooth
# interface's, which varies less with eta). Tabulated over sqrt(alpha),
# sqrt((eta - 1) / (PLASTIC_ETA_MAX - 1)) and mu (the square roots put nodes where the functions
# change fastest), read with linear interpolation. The tables are built on first access of
# COAT_TRANSMITTANCE / COAT_INTERNAL (module __getattr__, under a second): the kernels read
# them through `_tables`, the module itself, so the build runs when a kernel that needs them
# is compiled, and Numba freezes them into its machine code (cached kernels never rebuild).

_NA, _NE, _NM = 17, 17, 33
_tables = sys.modules[__name__]


@kernel_function
def coat_quadrature(alpha, eta_ratio, mu, transmitted, r_nodes, r_weights):
    """Albedo of a GGX dielectric's reflection lobe (E[F(wo.m) G1(wi, m)] over the normals m
    visible from wo, Mitsuba's eval_reflectance) or transmission lobe (E[(1 - F) G1(wt, m)],
    eval_transmittance, energy: no radiance factor) for light arriving at cos mu from the side
    of relative index eta_ratio = n_incident / n_transmitted. Gauss-Legendre in the radius of
    sample_vndf's disk point, the midpoint rule in its angle, over the half disk p1 < 0 (the
    lobes are symmetric about the plane of incidence; p1 -> -p1 mirrors m across it), as many
    angles as radii."""
    wo = (math.sqrt(max(0.0, 1.0 - mu * mu)), 0.0, mu)
    n_phi = r_nodes.shape[0]
    total = 0.0
    for i in range(r_nodes.shape[0]):
        u1 = r_nodes[i] * r_nodes[i]
        for j in range(n_phi):
            m = sample_vndf(wo, alpha, u1, 0.25 + 0.5 * (j + 0.5) / n_phi)
            dwo = dot(wo, m)
            fr, cos_t = fresnel_dielectric(abs(dwo), eta_ratio)
            if transmitted:
                wi = madd(mul(wo, -eta_ratio), m, eta_ratio * dwo - cos_t)
                if wi[2] < 0.0:
                    total += r_weights[i] * (1.0 - fr) * smith_g1(wi, m, alpha)
            else:
                wi = _reflect(wo, m)
                if wi[2] > 0.0:
                    total += r_weights[i] * fr * smith_g1(wi, m, alpha)
    return total / n_phi


@njit(cache=True, _nrt=False)
def _fill_coat_tables(transmittance, internal, t_rule, r_rule, mu_rule):
    # (no allocation in here: the build may run inside the compilation of a kernel, whose
    # flags say no reference counting)
    for i in range(_NA):
        alpha = max((i / (_NA - 1)) ** 2, ALPHA_MIN)
        for j in range(_NE):
            eta = 1.0 + (PLASTIC_ETA_MAX - 1.0) * (j / (_NE - 1)) ** 2
            for k in range(_NM):
                mu = max(k / (_NM - 1), 1e-6)
                transmittance[i, j, k] = coat_quadrature(alpha, 1.0 / eta, mu, True, t_rule[0], t_rule[1])
            # the integral of R_inside(mu) 2 mu dmu, by Gauss-Legendre on either side of the
            # critical angle's cosine (total internal reflection below it: a kink) ...
            mu_c = math.sqrt(1.0 - 1.0 / (eta * eta))
            acc = 0.0
            for lo, hi in ((0.0, mu_c), (mu_c, 1.0)):
                for k in range(mu_rule[0].shape[0]):
                    mu = lo + (hi - lo) * mu_rule[0][k]
                    r = coat_quadrature(alpha, eta, mu, False, r_rule[0], r_rule[1])
                    acc += (hi - lo) * mu_rule[1][k] * 2.0 * mu * r
            # ... made like Mitsuba's value, the mean of 2 mu R(mu) over 64 equally spaced mu
            # from 0 to 1: 63/64 of its trapezoid rule plus 2 R(1) / 128 (~1.5 % less than the
            # integral). Not that mean itself: it jumps as the kink crosses its points, so it
            # cannot be interpolated in eta (Mitsuba computes it for each material's eta) ...
            r1 = coat_quadrature(alpha, eta, 1.0, False, r_rule[0], r_rule[1])
            # ... and stored over the smooth interface's (Mitsuba's fit): a ratio that changes
            # slowly with eta, so that interpolation between the nodes stays accurate
            internal[i, j] = (63.0 / 64.0 * acc + r1 / 64.0) / fresnel_diffuse_reflectance(1.0 / eta)
        internal[i, 0] = internal[i, 1]  # (eta = 1: both are 0)


def _gauss_radii(n):
    """Gauss-Legendre nodes and weights for the disk radius r in [0, 1], u1 = r^2 (du1 = 2r dr)."""
    x, w = np.polynomial.legendre.leggauss(n)
    r = 0.5 * (x + 1.0)
    return r, w * r


def __getattr__(name):
    """Builds the coating tables on first access (see above)."""
    if name not in ("COAT_TRANSMITTANCE", "COAT_INTERNAL"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    transmittance, internal = np.empty((_NA, _NE, _NM)), np.empty((_NA, _NE))
    # T: 12 x 12 points per value (within 0.15 %); R_int: 24 x 24 (total internal reflection
    # puts a kink in its integrand) at 2 x 8 + 1 cosines
    x, w = np.polynomial.legendre.leggauss(8)
    _fill_coat_tables(transmittance, internal, _gauss_radii(12), _gauss_radii(24), (0.5 * (x + 1.0), 0.5 * w))
    globals().update(COAT_TRANSMITTANCE=transmittance, COAT_INTERNAL=internal)
    return globals()[name]


@kernel_function
def coat_terms(alpha, eta, mu):
    """(T(alpha, eta, mu), R_int(alpha, eta)), interpolated in the tables."""
    i, a = _grid(math.sqrt(alpha), float(_NA))
    j, b = _grid(math.sqrt((eta - 1.0) / (PLASTIC_ETA_MAX - 1.0)), float(_NE))
    k, c = _grid(mu, float(_NM))
    transmittance = _tables.COAT_TRANSMITTANCE
    internal = _tables.COAT_INTERNAL
    t = 0.0
    r_int = 0.0
    for di in range(2):
        for dj in range(2):
            w = (a if di else 1.0 - a) * (b if dj else 1.0 - b)
            r_int += w * internal[i + di, j + dj]
            t += w * ((1.0 - c) * transmittance[i + di, j + dj, k] + c * transmittance[i + di, j + dj, k + 1])
    return t, r_int * fresnel_diffuse_reflectance(1.0 / eta)


# --- Evaluation, per kind -------------------------------------------------------------------


@kernel_function
def _diffuse_eval(color, wo, wi):
    if not _same_side(wo[2], wi[2]):
        return _ZERO, 0.0
    return mul(color, INV_PI), abs(wi[2]) * INV_PI


@kernel_function
def _conductor_reflectance(mat, m, color, cos_i):
    if mat[m, MAT_HAS_ETA] < 0.5:
        return color
    return (
        color[0] * fresnel_conductor(cos_i, mat[m, MAT_ETA], mat[m, MAT_K]),
        color[1] * fresnel_conductor(cos_i, mat[m, MAT_ETA + 1], mat[m, MAT_K + 1]),
        color[2] * fresnel_conductor(cos_i, mat[m, MAT_ETA + 2], mat[m, MAT_K + 2]),
    )


@kernel_function
def _conductor_eval(mat, m, color, wo, wi):
    if mat[m, MAT_ROUGHNESS] <= 0.0 or not _same_side(wo[2], wi[2]):
        return _ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = _side(wo, s)
    wi = _side(wi, s)
    alpha = max(mat[m, MAT_ROUGHNESS], ALPHA_MIN)
    h = normalize(add(wo, wi))
    d = ggx_d(h, alpha)
    g1o = smith_g1(wo, h, alpha)
    k = d * g1o * smith_g1(wi, h, alpha) / (4.0 * wo[2] * wi[2])
    # pdf: the visible-normal density G1(wo) (wo.h) D / wo.z times the Jacobian 1 / (4 wo.h)
    return mul(_conductor_reflectance(mat, m, color, dot(wo, h)), k), g1o * d / (4.0 * wo[2])


@kernel_function
def _dielectric_eval(mat, m, color, wo, wi):
    co = wo[2]
    ci = wi[2]
    if mat[m, MAT_ROUGHNESS] <= 0.0 or co == 0.0 or ci == 0.0:
        return _ZERO, 0.0
    alpha = max(mat[m, MAT_ROUGHNESS], ALPHA_MIN)
    ior = mat[m, MAT_IOR]
    reflect = _same_side(co, ci)
    eta = ior if co > 0.0 else 1.0 / ior  # n on the other side / n on wo's side
    # the (generalised) half-vector, turned to +z
    h = normalize(add(wo, wi) if reflect else madd(wo, wi, eta))
    if h[2] < 0.0:
        h = mul(h, -1.0)
    dwo = dot(wo, h)
    dwi = dot(wi, h)
    if h[2] == 0.0 or not _same_side(dwo, co) or not _same_side(dwi, ci):
        return _ZERO, 0.0
    d = ggx_d(h, alpha)
    g1o = smith_g1(wo, h, alpha)
    g = g1o * smith_g1(wi, h, alpha)
    fr = fresnel_dielectric(abs(dwo), 1.0 / eta)[0]
    pdf_h = g1o * abs(dwo) * d / abs(co)  # normals visible from wo's side
    if reflect:
        v = fr * d * g / (4.0 * abs(co) * abs(ci))
        return (v, v, v), pdf_h * fr / (4.0 * abs(dwi))
    denom = (dwo + eta * dwi) ** 2
    if not (denom > 0.0):
        return _ZERO, 0.0
    # Walter et al.'s BTDF times the radiance factor 1 / eta^2, which cancels its eta^2
    v = (1.0 - fr) * d * g * abs(dwo) * abs(dwi) / (abs(co) * abs(ci) * denom)
    return mul(color, v), pdf_h * (1.0 - fr) * eta * eta * abs(dwi) / denom


@kernel_function
def _plastic_terms(mat, m, color, wo):
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
def _plastic_eval(mat, m, color, wo, wi):
    if not _same_side(wo[2], wi[2]):
        return _ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = _side(wo, s)
    wi = _side(wi, s)
    eta, alpha, t_o, diffuse, p_spec = _plastic_terms(mat, m, color, wo)
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
def _phong_weights(mat, m, color):
    """The lobes' luminance weights: Lambert, highlight, mirror, dielectric; and ks."""
    t = mat[m, MAT_TRANSPARENCY]
    r = mat[m, MAT_REFLECTIVE]
    ks = PHONG_KS if mat[m, MAT_SPECULAR] > 0.0 else 0.0
    kl = (1.0 - t) * (1.0 - r)
    y = 0.2126 * color[0] + 0.7152 * color[1] + 0.0722 * color[2]
    return kl * (1.0 - ks) * y, kl * ks * y, (1.0 - t) * r, t, ks


@kernel_function
def _phong_eval(mat, m, color, wo, wi):
    wd, wp, wm, wt, ks = _phong_weights(mat, m, color)
    total = wd + wp + wm + wt
    if not (total > 0.0) or not _same_side(wo[2], wi[2]):
        return _ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = _side(wo, s)
    wi = _side(wi, s)
    n = mat[m, MAT_SPECULAR]
    kl = (1.0 - mat[m, MAT_TRANSPARENCY]) * (1.0 - mat[m, MAT_REFLECTIVE])
    # max(0, cos a)^n / (2 pi), 0 under e^-50 (a slow subnormal number otherwise)
    cos_a = dot(wi, _mirror(wo))
    lobe = 0.0
    if n > 0.0 and cos_a > 0.0 and cos_a > 1.0 - 50.0 / n:
        lobe = cos_a**n * 0.5 * INV_PI
    f = mul(color, kl * ((1.0 - ks) * INV_PI + ks * (n + 2.0) * lobe))
    return f, (wd * wi[2] * INV_PI + wp * (n + 1.0) * lobe) / total


@kernel_function
def bsdf_eval(mat, m, color, wo, wi):
    """(f, pdf) of material row m for the unit local directions wo, wi (module docstring)."""
    kind = int(mat[m, MAT_KIND])
    if kind == DIFFUSE:
        return _diffuse_eval(color, wo, wi)
    if kind == CONDUCTOR:
        return _conductor_eval(mat, m, color, wo, wi)
    if kind == DIELECTRIC:
        return _dielectric_eval(mat, m, color, wo, wi)
    if kind == PLASTIC:
        return _plastic_eval(mat, m, color, wo, wi)
    return _phong_eval(mat, m, color, wo, wi)


# --- Sampling, per kind ---------------------------------------------------------------------
# Each returns (wi, weight, pdf, delta) for a delta lobe or a failure, and pdf = _EVALUATE for
# a non-delta direction (on the +z side for the two-sided kinds, flipped back by the caller),
# which bsdf_sample weighs with bsdf_eval (all lobes' f and pdf).


@kernel_function
def _smooth_dielectric(ior, tint, wo, u):
    """Fresnel choice between mirror reflection and refraction; the refracted weight carries
    the tint and the radiance factor (n_wo / n_wi)^2."""
    ratio = 1.0 / ior if wo[2] > 0.0 else ior  # n on wo's side / n on the other side
    f, cos_t = fresnel_dielectric(abs(wo[2]), ratio)
    if u < f or f >= 1.0:
        return _mirror(wo), _ONE, f, True
    wi = (-ratio * wo[0], -ratio * wo[1], -math.copysign(cos_t, wo[2]))
    return wi, mul(tint, ratio * ratio), 1.0 - f, True


@kernel_function
def _conductor_sample(mat, m, color, wo, up, u1, u2):
    if mat[m, MAT_ROUGHNESS] <= 0.0:
        return _mirror(wo), _conductor_reflectance(mat, m, color, up[2]), 1.0, True
    return _reflect(up, sample_vndf(up, max(mat[m, MAT_ROUGHNESS], ALPHA_MIN), u1, u2)), _ZERO, _EVALUATE, False


@kernel_function
def _dielectric_sample(mat, m, color, wo, u0, u1, u2):
    if mat[m, MAT_ROUGHNESS] <= 0.0:
        return _smooth_dielectric(mat[m, MAT_IOR], color, wo, u0)
    co = wo[2]
    ior = mat[m, MAT_IOR]
    # a normal visible from wo's side (seen from -wo when wo is inside), on the +z side
    h = sample_vndf(wo if co > 0.0 else mul(wo, -1.0), max(mat[m, MAT_ROUGHNESS], ALPHA_MIN), u1, u2)
    dwo = dot(wo, h)
    ratio = 1.0 / ior if co > 0.0 else ior  # n on wo's side / n on the other side
    fr, cos_t = fresnel_dielectric(abs(dwo), ratio)
    if u0 < fr or fr >= 1.0:
        wi = _reflect(wo, h)
        ok = _same_side(wi[2], co)
    else:
        wi = madd(mul(wo, -ratio), h, ratio * dwo - math.copysign(cos_t, dwo))
        ok = _same_side(wi[2], -co)
    if not ok:
        return _FAILED
    return wi, _ZERO, _EVALUATE, False


@kernel_function
def _plastic_sample(mat, m, color, wo, up, u0, u1, u2):
    eta, alpha, t_o, diffuse, p_spec = _plastic_terms(mat, m, color, up)
    if u0 >= p_spec:
        return _cosine_hemisphere(u1, u2), _ZERO, _EVALUATE, False
    if alpha == 0.0:
        r = (1.0 - t_o) / p_spec
        return _mirror(wo), (r, r, r), p_spec, True
    return _reflect(up, sample_vndf(up, alpha, u1, u2)), _ZERO, _EVALUATE, False


@kernel_function
def _phong_sample(mat, m, color, wo, up, u0, u1, u2):
    wd, wp, wm, wt, ks = _phong_weights(mat, m, color)
    total = wd + wp + wm + wt
    if not (total > 0.0):
        return _FAILED
    x = u0 * total
    if x < wd:
        return _cosine_hemisphere(u1, u2), _ZERO, _EVALUATE, False
    if x < wd + wp:
        # about the mirror direction r, density (n + 1) / (2 pi) cos^n of the angle to r;
        # tangents b1, b2 complete r to a basis (Duff et al. 2017)
        r = _mirror(up)
        sign = math.copysign(1.0, r[2])
        a = -1.0 / (sign + r[2])
        b = r[0] * r[1] * a
        b1 = (1.0 + sign * r[0] * r[0] * a, sign * b, -sign * r[0])
        b2 = (b, sign + r[1] * r[1] * a, -r[1])
        cos_a = u1 ** (1.0 / (mat[m, MAT_SPECULAR] + 1.0))
        sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
        phi = 2.0 * math.pi * u2
        wi = madd(madd(mul(r, cos_a), b1, sin_a * math.cos(phi)), b2, sin_a * math.sin(phi))
        return wi, _ZERO, _EVALUATE, False
    x -= wd + wp
    if x < wm or not (wt > 0.0):
        if not (wm > 0.0):
            return _FAILED
        # reflectance (1 - T) r = wm over the probability wm / total
        return _mirror(wo), (total, total, total), wm / total, True
    # the dielectric lobe, weight T, chosen with probability wt / total = T / total
    wi, w, p, delta = _smooth_dielectric(mat[m, MAT_IOR], _ONE, wo, min((x - wm) / wt, 1.0))
    return wi, mul(w, total), p * wt / total, delta


@inline_function  # one call site (path.py); a call cost ~25 ns a bounce
def bsdf_sample(mat, m, color, wo, u0, u1, u2):
    """(wi, weight, pdf, delta) of material row m for wo, from uniforms u0 (the lobe), u1, u2
    (the direction) in [0, 1) (module docstring)."""
    if wo[2] == 0.0:
        return _FAILED
    kind = int(mat[m, MAT_KIND])
    s = math.copysign(1.0, wo[2])
    up = _side(wo, s)  # two-sided kinds sample on +z, then flip back
    if kind == DIELECTRIC:
        wi, w, pdf, delta = _dielectric_sample(mat, m, color, wo, u0, u1, u2)
    elif kind == DIFFUSE:
        wi, w, pdf, delta = _cosine_hemisphere(u1, u2), _ZERO, _EVALUATE, False
    elif kind == CONDUCTOR:
        wi, w, pdf, delta = _conductor_sample(mat, m, color, wo, up, u1, u2)
    elif kind == PLASTIC:
        wi, w, pdf, delta = _plastic_sample(mat, m, color, wo, up, u0, u1, u2)
    else:
        wi, w, pdf, delta = _phong_sample(mat, m, color, wo, up, u0, u1, u2)
    if pdf != _EVALUATE:
        return wi, w, pdf, delta
    if kind != DIELECTRIC:
        wi = _side(wi, s)  # (a direction that left wo's side gets f = pdf = 0 below)
    f, pdf = bsdf_eval(mat, m, color, wo, wi)
    if not (pdf > 0.0 and pdf - pdf == 0.0):  # 0, inf or NaN (x - x is NaN for inf)
        return _FAILED
    w = mul(f, abs(wi[2]) / pdf)
    if not (w[0] - w[0] == 0.0 and w[1] - w[1] == 0.0 and w[2] - w[2] == 0.0):
        return _FAILED
    return wi, w, pdf, False
