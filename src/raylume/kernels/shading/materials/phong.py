"""The `phong` material, the seed's model and the default: `color` (or a texture), a Phong
exponent `specular` (none: matte), mirror reflectivity `reflective`, `transparency` with an
index of refraction `ior` and Beer-Lambert `absorption` inside.

Trace and cast modes: the seed's response to a light (seed_response.py: diffuse N.L plus the
highlight (R.V)^s), mirror reflection and Fresnel refraction (integrators/trace.py). Every other
kind is shown in trace mode through the same columns (its module's `trace_approximation`).

Path mode: the same material as an energy-conserving BSDF. With T = transparency, r =
reflective, s = specular (-1: no highlight), ks = 0.04 if s > 0 else 0 and kl = (1 - T)(1 - r),
its lobes are
  (1) Lambert with reflectance kl * color * (1 - ks);
  (2) if s > 0, the normalized Phong lobe kl * color * ks * (s + 2) / (2 pi) * max(0, cos a)^s,
      a the angle between wi and the mirror direction of wo (sampled with density
      (s + 1) / (2 pi) cos^s a about that direction; powers under e^-50 count as 0);
  (3) a smooth white mirror of reflectance (1 - T) r (delta);
  (4) a smooth dielectric of index ior with weight T (delta: Fresnel reflection, untinted
      refraction with the radiance factor, as the dielectric kind).
Lobes are chosen in proportion to their luminance weights kl (1 - ks) Y, kl ks Y, (1 - T) r and
T, Y the colour's Rec. 709 luminance. (1)-(3) are two-sided, (4) uses the true side: a
transparent phong material is not two-sided."""

import math

import numpy as np

from ...vec import dot, inline_function, kernel_function, madd, mul, turn
from .lobes import EVALUATE, FAILED, INV_PI, ONE, ZERO, cosine_hemisphere, mirror, same_side, side, smooth_dielectric
from .table import MAT_ABSORPTION, MAT_IOR, MAT_REFLECTIVE, MAT_SPECULAR, MAT_TRANSPARENCY

NAME = "phong"
KIND = 0
SOLID = False  # compile/media.py: no inside of its own (filled with the medium around it)
PHONG_KS = 0.04  # the share of a Phong material's colour in its highlight lobe


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    row[MAT_IOR] = mat.ior
    row[MAT_ABSORPTION : MAT_ABSORPTION + 3] = mat.absorption


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency): the material's own."""
    return (mat.specular if mat.specular is not None else -1.0), mat.reflective, mat.transparency


def phong_exponent(roughness: float) -> float:
    """The Phong exponent whose lobe is about as wide as GGX of this alpha (2 / alpha^2 - 2,
    Walter et al. 2007), a sharp 1000 for smooth surfaces: the other kinds' highlights in trace
    mode."""
    return 1000.0 if roughness < 0.0447 else max(2.0 / roughness**2 - 2.0, 1.0)


@kernel_function
def _weights(mat, m, color):
    """The lobes' luminance weights: Lambert, highlight, mirror, dielectric; and ks."""
    t = mat[m, MAT_TRANSPARENCY]
    r = mat[m, MAT_REFLECTIVE]
    ks = PHONG_KS if mat[m, MAT_SPECULAR] > 0.0 else 0.0
    kl = (1.0 - t) * (1.0 - r)
    y = 0.2126 * color[0] + 0.7152 * color[1] + 0.0722 * color[2]
    return kl * (1.0 - ks) * y, kl * ks * y, (1.0 - t) * r, t, ks


@kernel_function
def evaluate(mat, m, color, wo, wi):
    wd, wp, wm, wt, ks = _weights(mat, m, color)
    total = wd + wp + wm + wt
    if not (total > 0.0) or not same_side(wo[2], wi[2]):
        return ZERO, 0.0
    s = math.copysign(1.0, wo[2])
    wo = side(wo, s)
    wi = side(wi, s)
    n = mat[m, MAT_SPECULAR]
    kl = (1.0 - mat[m, MAT_TRANSPARENCY]) * (1.0 - mat[m, MAT_REFLECTIVE])
    # max(0, cos a)^n / (2 pi), 0 under e^-50 (a slow subnormal number otherwise)
    cos_a = dot(wi, mirror(wo))
    lobe = 0.0
    if n > 0.0 and cos_a > 0.0 and cos_a > 1.0 - 50.0 / n:
        lobe = cos_a**n * 0.5 * INV_PI
    f = mul(color, kl * ((1.0 - ks) * INV_PI + ks * (n + 2.0) * lobe))
    return f, (wd * wi[2] * INV_PI + wp * (n + 1.0) * lobe) / total


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    wd, wp, wm, wt, ks = _weights(mat, m, color)
    total = wd + wp + wm + wt
    if not (total > 0.0):
        return FAILED
    s = math.copysign(1.0, wo[2])
    x = u0 * total
    if x < wd:
        return side(cosine_hemisphere(u1, u2), s), ZERO, EVALUATE, False
    if x < wd + wp:
        # about the mirror direction r, density (n + 1) / (2 pi) cos^n of the angle to r;
        # tangents b1, b2 complete r to a basis (Duff et al. 2017)
        r = mirror(side(wo, s))
        sign = math.copysign(1.0, r[2])
        a = -1.0 / (sign + r[2])
        b = r[0] * r[1] * a
        b1 = (1.0 + sign * r[0] * r[0] * a, sign * b, -sign * r[0])
        b2 = (b, sign + r[1] * r[1] * a, -r[1])
        cos_a = u1 ** (1.0 / (mat[m, MAT_SPECULAR] + 1.0))
        sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
        cos_phi, sin_phi = turn(u2)
        wi = madd(madd(mul(r, cos_a), b1, sin_a * cos_phi), b2, sin_a * sin_phi)
        return side(wi, s), ZERO, EVALUATE, False
    x -= wd + wp
    if x < wm or not (wt > 0.0):
        if not (wm > 0.0):
            return FAILED
        # reflectance (1 - T) r = wm over the probability wm / total
        return mirror(wo), (total, total, total), wm / total, True
    # the dielectric lobe, weight T, chosen with probability wt / total = T / total
    wi, w, p, delta = smooth_dielectric(mat[m, MAT_IOR], ONE, wo, min((x - wm) / wt, 1.0))
    return wi, mul(w, total), p * wt / total, delta


@inline_function
def delta_only(mat, m):
    """No diffuse part left: a pure mirror and/or glass."""
    return (1.0 - mat[m, MAT_TRANSPARENCY]) * (1.0 - mat[m, MAT_REFLECTIVE]) == 0.0 and mat[m, MAT_SPECULAR] <= 0.0


@inline_function
def two_sided(mat, m):
    return not (mat[m, MAT_TRANSPARENCY] > 0.0)


@inline_function
def aov_albedo(mat, m, color):
    """The `albedo` AOV and the denoiser's guide: the colour at the hit."""
    return color
