"""Textures: a table of their own that materials point into (MAT_TEXTURE), and the lookups.

Table: float64 (X, TEX_WIDTH). Checker: a 3D checkerboard in world space with cells of side
TEX_CELL alternating TEX_COLOR_A and TEX_COLOR_B. Image: texels in the scene's texel atlas
(float32 (N, 3), linear RGB, row by row from TEX_OFFSET), looked up by the surface's UVs times
(TEX_SCALE_U, TEX_SCALE_V), repeating; TEX_COLOR_A holds its mean colour. The atlas holds
each image's mip-map: TEX_LEVELS levels, each half the size of the one before (at least 1
texel), one after the other from TEX_OFFSET.

Filtering (ray cones, Akenine-Moller et al. 2021): a lookup may carry the footprint of the
pixel at the hit, a cone of radius `radius` around the ray direction d cut by the surface of
normal n: an ellipse with semi-axes radius / |cos| along d's projection and radius across
it. The checker is box-filtered over that ellipse's bounding box in closed form; an image is
read trilinearly from the mip level whose texels match the ellipse's major axis. radius 0
is a point lookup (exactly the unfiltered texture).
"""

import math

import numpy as np

from ..geometry.shapes import uv, uv_differentials
from ..vec import cross, dot, inline_function, kernel_function, mul, row3

TEX_KIND = 0
TEX_COLOR_A = 1  # 3 columns
TEX_COLOR_B = 4  # 3 columns
TEX_CELL = 7
TEX_OFFSET = 8
TEX_WIDTH_PX = 9
TEX_HEIGHT_PX = 10
TEX_SCALE_U = 11
TEX_SCALE_V = 12
TEX_LEVELS = 13
TEX_WIDTH = 14

CHECKER = 0
IMAGE = 1


@inline_function
def checker(textures, x, p):
    # A tiny bias keeps a plane through a cell boundary (y = 0) inside one cell.
    inv = 1.0 / textures[x, TEX_CELL]
    parity = (math.floor(p[0] * inv + 1e-9) + math.floor(p[1] * inv + 1e-9) + math.floor(p[2] * inv + 1e-9)) % 2
    if parity == 0:
        return row3(textures, x, TEX_COLOR_A)
    return row3(textures, x, TEX_COLOR_B)


# Grazing footprints are capped at this many cone radii: beyond it the checker is grey and
# the image at its coarsest level anyway.
MAX_ELONGATION = 100.0


@kernel_function
def footprint(d, n, radius):
    """Semi-axes (a1, a2) of the ellipse a cone of `radius` along the unit direction d cuts
    from the plane of unit normal n: a1 along d's projection (radius / |cos|), a2 across."""
    c = max(abs(dot(d, n)), 1.0 / MAX_ELONGATION)
    across = cross(n, d)
    s = math.sqrt(dot(across, across))
    if s < 1e-9:  # looking straight at the surface: a circle, any axes will do
        helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
        across = cross(n, helper)
        s = math.sqrt(dot(across, across))
    t2 = mul(across, 1.0 / s)
    t1 = cross(t2, n)
    return mul(t1, radius / c), mul(t2, radius)


@inline_function
def _square_wave_integral(x):
    """Integral from 0 to x of the wave that is +1 on [0, 1), -1 on [1, 2), period 2."""
    f = x - 2.0 * math.floor(0.5 * x)
    return 1.0 - abs(f - 1.0)


@inline_function
def _filtered_wave(x, width):
    """That wave averaged over [x - width/2, x + width/2] (the value at x when width is 0)."""
    if width < 1e-6:
        return 1.0 if (math.floor(x) % 2) == 0 else -1.0
    h = 0.5 * width
    return (_square_wave_integral(x + h) - _square_wave_integral(x - h)) / width


@kernel_function
def filtered_checker(textures, x, p, a1, a2):
    """The checker averaged over the bounding box of the footprint ellipse (a1, a2) at p.

    The checker is A where the product of one square wave per axis is +1 and B where it is -1;
    a box's average of a product of functions of one axis each is the product of their
    averages, each in closed form."""
    inv = 1.0 / textures[x, TEX_CELL]
    product = 1.0
    for k in range(3):
        width = 2.0 * math.sqrt(a1[k] * a1[k] + a2[k] * a2[k]) * inv
        product *= _filtered_wave(p[k] * inv + 1e-9, width)
    wa = 0.5 * (1.0 + product)
    wb = 1.0 - wa
    return (
        wa * textures[x, TEX_COLOR_A] + wb * textures[x, TEX_COLOR_B],
        wa * textures[x, TEX_COLOR_A + 1] + wb * textures[x, TEX_COLOR_B + 1],
        wa * textures[x, TEX_COLOR_A + 2] + wb * textures[x, TEX_COLOR_B + 2],
    )


@inline_function
def texture_at(G, F, X, x, prim, b1, b2, p, d, n, radius):
    """Colour of texture x at a hit on primitive `prim` at p, seen along d (unit) on a surface
    of unit normal n, filtered over a cone footprint of `radius` (0: a point lookup)."""
    tex = F.textures
    if tex[x, TEX_KIND] == CHECKER:
        if radius > 0.0:
            a1, a2 = footprint(d, n, radius)
            return filtered_checker(tex, x, p, a1, a2)
        return checker(tex, x, p)
    if X is None:  # never: such scenes have no image textures (variants.features)
        return row3(tex, x, TEX_COLOR_A)
    # explicit int64: call sites after inlined traversal may type the primitive as a literal,
    # which would compile shapes.uv once per literal
    k = np.int64(prim)
    u, v = uv(G, X, k, b1, b2, p)
    su = tex[x, TEX_SCALE_U]
    sv = tex[x, TEX_SCALE_V]
    width = int(tex[x, TEX_WIDTH_PX])
    height = int(tex[x, TEX_HEIGHT_PX])
    level = 0.0
    if radius > 0.0:
        a1, a2 = footprint(d, n, radius)
        du1, dv1, du2, dv2 = uv_differentials(G, X, k, b1, b2, p, u, v, a1, a2)
        # the footprint's longer axis in texels of level 0
        l1 = math.hypot(du1 * su * width, dv1 * sv * height)
        l2 = math.hypot(du2 * su * width, dv2 * sv * height)
        texels = 2.0 * max(l1, l2)
        if texels > 1.0:
            level = math.log2(texels)
    return mip_lookup(F.texels, int(tex[x, TEX_OFFSET]), width, height, int(tex[x, TEX_LEVELS]), u * su, v * sv, level)


@inline_function
def full_size_lookup(F, x, u, v):
    """Image texture x's texel at the surface's (u, v) times its scale: bilinear on its
    full-size level, repeating (the normal, bump and alpha maps' lookup, as pbrt-v4 reads them)."""
    tex = F.textures
    return texture_lookup(
        F.texels,
        int(tex[x, TEX_OFFSET]),
        int(tex[x, TEX_WIDTH_PX]),
        int(tex[x, TEX_HEIGHT_PX]),
        u * tex[x, TEX_SCALE_U],
        v * tex[x, TEX_SCALE_V],
    )


@kernel_function
def mip_lookup(texels, offset, width, height, levels, u, v, level):
    """Trilinear lookup: bilinear in the two mip levels around `level`, blended."""
    if not (level > 0.0):  # also NaN
        return texture_lookup(texels, offset, width, height, u, v)
    top = levels - 1
    if level >= top:
        level = float(top)
    lower = int(level)
    t = level - lower
    for _ in range(lower):
        offset += width * height
        width = max(1, width // 2)
        height = max(1, height // 2)
    a = texture_lookup(texels, offset, width, height, u, v)
    if t == 0.0 or lower == top:
        return a
    b = texture_lookup(texels, offset + width * height, max(1, width // 2), max(1, height // 2), u, v)
    return (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t)


@kernel_function
def texture_lookup(texels, offset, width, height, u, v):
    """Bilinear lookup of an image texture at (u, v), wrapping (repeating) in both directions.

    The image's top row is v = 1 and its left column u = 0 (OBJ/glTF convention); texel
    (x, y), y counted from the top, has its centre at ((x + 0.5) / width, 1 - (y + 0.5) / height)
    and there the lookup returns exactly that texel."""
    u -= math.floor(u)
    v -= math.floor(v)
    # NaN or inf (inf - inf), or a huge u whose wrap rounds badly: (0, 0). An index from NaN
    # is undefined, and such UVs had read memory outside the texture.
    if not (0.0 <= u <= 1.0 and 0.0 <= v <= 1.0):
        u = 0.0
        v = 0.0
    fx = u * width - 0.5
    fy = (1.0 - v) * height - 0.5
    x0f = math.floor(fx)
    y0f = math.floor(fy)
    tx = fx - x0f
    ty = fy - y0f
    x0 = int(x0f) % width
    y0 = int(y0f) % height
    x1 = (x0 + 1) % width
    y1 = (y0 + 1) % height
    top = offset + y0 * width
    bottom = offset + y1 * width
    w00 = (1.0 - tx) * (1.0 - ty)
    w10 = tx * (1.0 - ty)
    w01 = (1.0 - tx) * ty
    w11 = tx * ty
    t = texels
    return (
        t[top + x0, 0] * w00 + t[top + x1, 0] * w10 + t[bottom + x0, 0] * w01 + t[bottom + x1, 0] * w11,
        t[top + x0, 1] * w00 + t[top + x1, 1] * w10 + t[bottom + x0, 1] * w01 + t[bottom + x1, 1] * w11,
        t[top + x0, 2] * w00 + t[top + x1, 2] * w10 + t[bottom + x0, 2] * w01 + t[bottom + x1, 2] * w11,
    )
