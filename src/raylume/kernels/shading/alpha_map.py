"""Alpha maps: a material's cut-out mask. Where its coverage (the image's alpha, or its grey,
as stored: compile/materials.py keeps it in all three channels) at the hit's UVs is below the
material's cutoff, the surface has a hole, and every ray passes it as if nothing were there:
path mode and bdpt step through it as through a null boundary (their shadow rays too: the
scene's pass_through), into the medium beyond, so a closed object keeps its inside filled;
trace mode's rays go on and its shadow rays walk through it (the scene's has_transparency),
with the absorption of the segment inside; cast mode and the AOVs show what lies behind.
Shadow rays pass as many holes as camera rays do (MAX_HOLES, shadow.MAX_CROSSINGS). The lookup
is bilinear at full size (glTF's alphaMode MASK against alphaCutoff; pbrt-v4 and Mitsuba 3 read
fractional alpha stochastically, which a cutoff of 0.5 approximates for masks that are mostly 0
or 1). The geometry queries (raylume.intersect, occluded) see masked surfaces whole.
"""

import math

import numpy as np

from ..geometry.shapes import NO_HIT, PRIM_MATERIAL, offset_epsilon, split_hit, surface, uv
from ..geometry.traverse import closest_hit
from ..vec import dot, inline_function, kernel_function, madd, sub
from .materials import MAT_ALPHA_CUTOFF, MAT_ALPHA_MAP
from .textures import full_size_lookup

# holes one ray passes at most (a guard against endless rounding): the hit beyond counts as solid
MAX_HOLES = 1024


@inline_function
def in_hole(G, F, X, m, prim, b1, b2, p):
    """Whether the hit at p on primitive `prim` of material m falls in a hole of its alpha map.
    Basic scenes (X None) have no image textures, so no holes: their kernels compile none of it."""
    if X is None:
        return False
    x = np.int64(F.materials[m, MAT_ALPHA_MAP]) - 1
    if x < 0:
        return False
    return _coverage(G, F, X, x, np.int64(prim), b1, b2, p) < F.materials[m, MAT_ALPHA_CUTOFF]


@kernel_function
def _coverage(G, F, X, x, k, b1, b2, p):
    u, v = uv(G, X, k, b1, b2, p)
    return full_size_lookup(F, x, u, v)[0]


@inline_function
def past_holes(G, F, X, o, d, t, prim, b1, b2, node_stack, t_stack):
    """The first hit (t, prim, b1, b2) along the unit ray (o, d) that is not in a hole, from its
    closest hit (t, prim, b1, b2): itself where its material has no alpha map (a load or two;
    none where no material lets light through: has_transparency, which alpha maps set), else
    found by tracing on from each hole's far side (t from o, to within the offsets)."""
    if X is None or prim == NO_HIT or not F.has_transparency:
        return t, prim, b1, b2
    k, _ = split_hit(X, prim)
    if not (F.materials[G.prims[k, PRIM_MATERIAL], MAT_ALPHA_MAP] > 0.0):
        return t, prim, b1, b2
    return _past_holes(G, F, X, o, d, t, prim, b1, b2, node_stack, t_stack)


@kernel_function
def _past_holes(G, F, X, o, d, t, prim, b1, b2, node_stack, t_stack):
    origin = o
    for _ in range(MAX_HOLES):
        if prim == NO_HIT:
            return math.inf, prim, b1, b2
        p = madd(origin, d, t)
        ng, _, m, _, _ = surface(G, X, prim, b1, b2, p)
        if not in_hole(G, F, X, m, prim, b1, b2, p):
            return dot(sub(p, o), d), prim, b1, b2
        eps = offset_epsilon(F.epsilon_floor, p)
        origin = madd(p, ng, -eps if dot(ng, d) < 0.0 else eps)
        t, prim, b1, b2 = closest_hit(G, X, origin, d, 0.0, math.inf, node_stack, t_stack)
    return dot(sub(madd(origin, d, t), o), d), prim, b1, b2
