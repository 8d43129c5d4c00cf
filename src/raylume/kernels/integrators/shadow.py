"""Shadow rays: where they start and end (`shadow_ray`: path mode's next-event estimation and
bdpt's connections), and, where light may pass things on its way, their transmittance: through
index-matched (null) boundaries and participating media, whose transmittance it multiplies in
(Mitsuba 3's volpath does the same). Scenes with neither take any_hit instead (path.py)."""

import math

from ..film.sampler import sub_key
from ..geometry.shapes import NO_HIT, offset_epsilon, surface
from ..geometry.sweep import SWEEP_OTHER
from ..geometry.traverse import closest_hit
from ..shading.alpha_map import in_hole
from ..shading.lights import SHADOW_SHORTEN
from ..shading.materials import index_matched
from ..shading.media import medium_beyond, transmittance
from ..vec import dot, hadamard, inline_function, length, madd, mul, sub

ZERO3 = (0.0, 0.0, 0.0)
# Boundaries one shadow ray passes at most (a guard: a ray grazing a mesh could otherwise
# cross and re-cross it by rounding without end)
MAX_CROSSINGS = 1024  # as path mode's (a camera ray's): a ray that passes them sees what a shadow ray does
INF = math.inf


@inline_function
def shadow_segment(p, n, offset, wi, dist):
    """(origin, direction, tmax) of the shadow ray from surface point p towards the point at
    `dist` along unit wi (inf: a direction, then wi itself and tmax inf): from p offset along n,
    its direction the whole segment from there to that point and tmax 1 - SHADOW_SHORTEN, short
    of it, as pbrt spawns rays to a point. Aimed from p itself, the offset origin's ray crossed
    the target's own surface before its shortened end wherever it met it at a grazing angle
    (offset / sin > SHADOW_SHORTEN x dist), and the light blocked itself. Unnormalized: for
    scenes where scale_free_shadows (the normalization, a square root and a division in a chain,
    was ~4% of the Cornell box's path time in a cpu-clock profile); shadow_ray elsewhere."""
    origin = madd(p, n, offset)
    if not dist < INF:
        return origin, wi, INF
    return origin, sub(madd(p, wi, dist), origin), 1.0 - SHADOW_SHORTEN


@inline_function
def shadow_ray(p, n, offset, wi, dist):
    """shadow_segment's ray with a unit direction, tmax SHADOW_SHORTEN of its length short of the
    point (a sphere's test and distances through media want unit directions)."""
    origin, to, tmax = shadow_segment(p, n, offset, wi, dist)
    if not dist < INF:
        return origin, to, tmax
    span = length(to)
    return origin, mul(to, 1.0 / span), span * (1.0 - SHADOW_SHORTEN)


@inline_function
def scale_free_shadows(G, Em, Md):
    """Whether every test a shadow ray meets in this scene takes a direction of any length, its
    distances in units of that length: a swept scene (geometry/sweep.py: triangles and flat
    polygons, whose mask and exact tests scale with the direction) without other bounded
    primitives (a sphere's test assumes a unit direction), unbounded ones, area lights beside
    the primitives (area_light_blocks) or media (distances along the ray)."""
    return (
        G.sweep.shape[1] > 0
        and G.sweep[SWEEP_OTHER, 0] < 0.0
        and G.n_bounded == G.prims.shape[0]
        and Em.n_area == 0
        and not Md.pass_through
    )


@inline_function
def shadow_transmittance(G, F, X, Md, o, d, tmax, med, key, node_stack, t_stack):
    """The fraction of light (RGB) that travels from o along d over (0, tmax) through the media
    and null boundaries in between, starting in medium med; 0 when anything else blocks it."""
    tr = (1.0, 1.0, 1.0)
    for crossing in range(MAX_CROSSINGS):
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, tmax, node_stack, t_stack)
        if med >= 0:
            tr = hadamard(tr, transmittance(Md, med, o, d, t if prim != NO_HIT else tmax, sub_key(key, crossing)))
            if tr[0] == 0.0 and tr[1] == 0.0 and tr[2] == 0.0:
                return tr
        if prim == NO_HIT:
            return tr
        p = madd(o, d, t)
        ng, _, m, obj, _ = surface(G, X, prim, b1, b2, p)
        if not (index_matched(F.materials, m) or in_hole(G, F, X, m, prim, b1, b2, p)):
            return ZERO3
        if Md.present:
            med = medium_beyond(Md, obj, d, ng)
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, ng, eps if dot(d, ng) > 0.0 else -eps)
        tmax -= t
    return ZERO3
