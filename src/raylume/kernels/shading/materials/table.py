"""The material table: float64 (M, MAT_WIDTH), one row per material, its kind in MAT_KIND (a kind
module's KIND, registry.py). Columns every kind shares (colour, texture, emission) and the
columns some kinds read; which kind reads which, and how, is in the kinds' modules. The phong
columns (MAT_SPECULAR, MAT_REFLECTIVE, MAT_TRANSPARENCY, MAT_IOR) also hold every other kind's
trace-mode approximation (each module's `trace_approximation`): trace and cast modes read only
them. Also here: the colour at a hit (texture lookup) and Beer-Lambert absorption."""

import math

from ...vec import inline_function, row3
from ..textures import texture_at

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
# 1 + the normal map's row in the texture table, 0 for none (so that a row of zeros has none)
MAT_NORMAL_MAP = 23
MAT_NORMAL_STRENGTH = 24  # multiplies the map's x and y (glTF's normalTexture.scale)
MAT_BUMP_MAP = 25  # 1 + the bump (height) map's row in the texture table, 0 for none
MAT_BUMP_HEIGHT = 26  # the displacement of a white texel, in scene units
MAT_ALPHA_MAP = 27  # 1 + the cut-out mask's row in the texture table, 0 for none
MAT_ALPHA_CUTOFF = 28  # below this coverage the surface has a hole
MAT_WIDTH = 29


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
