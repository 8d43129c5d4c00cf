"""Plastic's coating: a dielectric layer of index eta over a diffuse base. The smooth coating's
terms are Fresnel's; the rough (GGX) coating's are tables built here, read by coat_terms.
Also the diffuse Fresnel reflectance Fdr, the smooth coating's internal reflection."""

import math
import sys

import numpy as np
from numba import njit

from ...vec import dot, kernel_function, madd, mul
from ..optics import fresnel_dielectric
from .lobes import ALPHA_MIN, reflect
from .microfacet import sample_vndf, smith_g1

PLASTIC_ETA_MAX = 3.0  # plastic's index is clamped to [1, PLASTIC_ETA_MAX], the tables' range


@kernel_function
def _grid(x, n):
    """Cell and weight of x in [0, 1] on n equally spaced nodes (n a float: one compilation)."""
    t = min(max(x, 0.0), 1.0) * (n - 1.0)
    i = min(int(t), int(n) - 2)
    return i, t - i


@kernel_function
def fresnel_diffuse_reflectance(eta):
    """Fdr: the dielectric Fresnel reflectance averaged over cosine-weighted incident light,
    eta = n_transmitted / n_incident. Mitsuba's choice of fits: Egan and Hilgeman 1973 below 1,
    d'Eon and Irving 2011 above (both within 0.1 % for common indices)."""
    if eta < 1.0:
        return -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    x = 1.0 / eta
    return 0.919317 + x * (-3.4793 + x * (6.75335 + x * (-7.80989 + x * (4.98554 - 1.36881 * x))))


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
                wi = reflect(wo, m)
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
