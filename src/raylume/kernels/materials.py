"""Materials: a table with a kind tag per row, and each kind's response to light.

Table: float64 (M, MAT_WIDTH). Kind PHONG is the seed's model: colour (or a texture), a Phong
exponent, mirror reflectivity, transparency with an index of refraction, and Beer-Lambert
absorption inside. Evaluation (how much of a light's intensity a surface sends towards the
viewer) is here; choosing points on lights is in lights.py; the loop that joins them, with
shadow rays, is direct.py.
"""

import math

from .textures import texture_at
from .vec import dot, inline_function, mul, row3, sub

MAT_KIND = 0
MAT_COLOR = 1  # 3 columns, linear RGB
MAT_SPECULAR = 4  # Phong exponent, -1 for a matte surface
MAT_REFLECTIVE = 5
MAT_TRANSPARENCY = 6
MAT_IOR = 7  # dielectric, plastic and phong: index of refraction of the inside (outside is 1)
MAT_ABSORPTION = 8  # 3 columns, Beer-Lambert coefficient per unit length
MAT_TEXTURE = 11  # row in the texture table, -1 for none
MAT_ROUGHNESS = 12  # GGX alpha; 0 is perfectly smooth
MAT_ETA = 13  # 3 columns: a conductor's complex index of refraction, real part (RGB)
MAT_K = 16  # 3 columns: its imaginary part
MAT_HAS_ETA = 19  # 1 when a conductor has eta and k (Fresnel), 0 for a perfect mirror times color
MAT_EMISSION = 20  # 3 columns: emitted radiance (path mode: the surface is a light)
MAT_WIDTH = 23

# Kinds (MAT_KIND), the scene's material `type`s.
PHONG = 0
DIFFUSE = 1
CONDUCTOR = 2
DIELECTRIC = 3
PLASTIC = 4


@inline_function
def highlight(cos_rv, specular):
    """cos_rv ** specular, the Phong highlight, by repeated squaring where the exponent is a
    whole number up to 2**16 (the seed's 10, 500 and 1000): libm's pow took ~7% of the seed's
    trace kernel. Callers skip cos_rv <= 1 - 50 / specular, so no square underflows."""
    n = int(specular)
    if n != specular or n > 65536:
        return cos_rv**specular
    result = 1.0
    base = cos_rv
    while n > 0:
        if n & 1:
            result *= base
        base *= base
        n >>= 1
    return result


@inline_function
def phong(n, l, view, specular):
    """The seed's diffuse + specular factor for the unit direction l towards a light (n and
    view unit too; specular <= 0 for a matte surface)."""
    n_dot_l = dot(n, l)
    scale = max(n_dot_l, 0.0)
    if specular > 0.0:
        # the seed adds the highlight whatever the sign of N.L (R and V decide)
        r = sub(mul(n, 2.0 * n_dot_l), l)
        cos_rv = dot(r, view)  # the seed divides by |R| |V|: both are 1 here
        if cos_rv > 0.0:
            # Below 1 - 50/s the highlight is under e^-50 (about 2e-22): skip the power, whose
            # result would otherwise often be a slow subnormal number.
            if cos_rv > 1.0 - 50.0 / specular:
                scale += highlight(cos_rv, specular)
    return scale


@inline_function
def albedo(G, F, X, m, prim, b1, b2, p, d, n, radius):
    """The material's colour at a hit: its plain colour or its texture's, filtered over the
    footprint of a ray cone of `radius` along d at the surface of normal n (textures.py)."""
    x = int(F.materials[m, MAT_TEXTURE])
    if x < 0:
        return row3(F.materials, m, MAT_COLOR)
    return texture_at(G, F, X, x, prim, b1, b2, p, d, n, radius)


@inline_function
def beer_lambert(materials, m, w, distance):
    """w attenuated by the material's absorption over `distance` inside it."""
    return (
        w[0] * math.exp(-materials[m, MAT_ABSORPTION] * distance),
        w[1] * math.exp(-materials[m, MAT_ABSORPTION + 1] * distance),
        w[2] * math.exp(-materials[m, MAT_ABSORPTION + 2] * distance),
    )
