"""Textures: a table of their own that materials point into (MAT_TEXTURE), and the lookups.

Table: float64 (X, TEX_WIDTH). Checker: a 3D checkerboard in world space with cells of side
TEX_CELL alternating TEX_COLOR_A and TEX_COLOR_B. Image: texels in the scene's texel atlas
(float32 (N, 3), linear RGB, row by row from TEX_OFFSET), looked up bilinearly by the
surface's UVs times (TEX_SCALE_U, TEX_SCALE_V), repeating; TEX_COLOR_A holds its mean colour.
"""

import math

import numpy as np
from numba import njit

from .shapes import uv
from .vec import KERNEL, row3

TEX_KIND = 0
TEX_COLOR_A = 1  # 3 columns
TEX_COLOR_B = 4  # 3 columns
TEX_CELL = 7
TEX_OFFSET = 8
TEX_WIDTH_PX = 9
TEX_HEIGHT_PX = 10
TEX_SCALE_U = 11
TEX_SCALE_V = 12
TEX_WIDTH = 13

CHECKER = 0
IMAGE = 1


@njit(**KERNEL, inline="always")
def checker(textures, x, p):
    # A tiny bias keeps a plane through a cell boundary (y = 0) inside one cell.
    inv = 1.0 / textures[x, TEX_CELL]
    parity = (math.floor(p[0] * inv + 1e-9) + math.floor(p[1] * inv + 1e-9) + math.floor(p[2] * inv + 1e-9)) % 2
    if parity == 0:
        return row3(textures, x, TEX_COLOR_A)
    return row3(textures, x, TEX_COLOR_B)


@njit(**KERNEL, inline="always")
def texture_at(G, F, X, x, prim, b1, b2, p):
    """Colour of texture x at a hit on primitive `prim` at p."""
    tex = F.textures
    if tex[x, TEX_KIND] == CHECKER:
        return checker(tex, x, p)
    if X is None:  # never: such scenes have no image textures (shapes.features)
        return row3(tex, x, TEX_COLOR_A)
    # explicit int64: call sites after inlined traversal may type the primitive as a literal,
    # which would compile shapes.uv once per literal
    u, v = uv(G, X, np.int64(prim), b1, b2, p)
    return texture_lookup(
        F.texels,
        int(tex[x, TEX_OFFSET]),
        int(tex[x, TEX_WIDTH_PX]),
        int(tex[x, TEX_HEIGHT_PX]),
        u * tex[x, TEX_SCALE_U],
        v * tex[x, TEX_SCALE_V],
    )


@njit(**KERNEL)
def texture_lookup(texels, offset, width, height, u, v):
    """Bilinear lookup of an image texture at (u, v), wrapping (repeating) in both directions.

    The image's top row is v = 1 and its left column u = 0 (OBJ/glTF convention); texel
    (x, y), y counted from the top, has its centre at ((x + 0.5) / width, 1 - (y + 0.5) / height)
    and there the lookup returns exactly that texel."""
    if not (u == u and v == v):  # NaN
        u = 0.0
        v = 0.0
    u -= math.floor(u)
    v -= math.floor(v)
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
