"""Direct lighting, the seed's ComputeLighting: for every light of the scene, in its order, points
sampled on it (each light kind's trace_sample, shading/lights/), the material's response towards
the viewer (materials/seed_response.py) and a shadow ray.

Shadow rays in opaque scenes are any-hit queries. With transparent materials they walk from
hit to hit: each transparent surface lets `transparency` through, and the path inside a medium
(between entering and leaving it) is attenuated by Beer-Lambert absorption.
"""

import math

import numpy as np

from ..film.sampler import light_sample
from ..geometry.shapes import offset_epsilon, surface
from ..geometry.traverse import any_hit, closest_hit
from ..shading.alpha_map import MAX_HOLES, in_hole
from ..shading.lights import (
    LIGHT_INTENSITY,
    LIGHT_SAMPLES,
    has_falloff,
    is_delta,
    is_everywhere,
    trace_area,
    trace_delta,
    trace_falloff,
)
from ..shading.materials import MAT_SPECULAR, MAT_TRANSPARENCY, beer_lambert
from ..shading.materials.seed_response import phong_response
from ..vec import dot, inline_function, kernel_function, madd, mul, normalize, row3

INF = math.inf


@inline_function
def direct_lighting(G, F, L, X, p, o, n, view, m, shadows, node_stack, t_stack, key, event):
    """Ambient + diffuse + specular intensity (RGB) at surface point p from every light, and the
    shadow rays traced. n faces the viewer; the shadow rays start at o, p offset off the surface
    (the directions to the lights are p's: the offset grows with the distance from the origin, a
    unit at 1e7, and lighting taken from it changed with where the scene sits). Area lights take their
    `samples` stratified points from the camera sample's `key` at its `event`-th shaded surface
    (sampler.py); key 0 gives a fixed pattern."""
    specular = F.materials[m, MAT_SPECULAR]
    ir = 0.0
    ig = 0.0
    ib = 0.0
    rays = 0
    for j in range(L.order.shape[0]):
        k = L.order[j]
        kind = L.kind[k]
        intensity = row3(L.data, k, LIGHT_INTENSITY)
        if is_everywhere(kind):  # the seed's ambient light
            ir += intensity[0]
            ig += intensity[1]
            ib += intensity[2]
            continue
        # Every sample of every light goes through one shadow-ray call site (each inlined copy
        # of the traversal costs seconds of JIT time). Area lights are sampled by a call, so
        # that the point-light path keeps its registers (live values across the shadow ray
        # slow the traversal).
        delta = is_delta(kind)
        count = 1 if delta else int(L.data[k, LIGHT_SAMPLES])
        remaining = count
        while remaining > 0:
            remaining -= 1
            if delta:
                to_light, tmax = trace_delta(L, k, p, 0.0, 0.0)
            elif X is not None:  # area lights (none in scenes whose X is None)
                u1, u2 = light_sample(key, event, j, remaining, count)
                to_light, tmax = trace_area(L, k, p, u1, u2)
            else:
                to_light, tmax = (0.0, 0.0, 1.0), 0.0
            l = normalize(to_light)
            scale = phong_response(n, l, view, specular)
            if has_falloff(kind):
                scale *= trace_falloff(L, k, l)
            if scale <= 0.0:
                continue  # nothing to add: skip the shadow ray
            if shadows:
                tr, used = shadow_transmittance(G, F, X, o, l, tmax, node_stack, t_stack)
                rays += used
            else:
                tr = (1.0, 1.0, 1.0)
            if not delta:
                scale = scale / count
            ir += intensity[0] * scale * tr[0]
            ig += intensity[1] * scale * tr[1]
            ib += intensity[2] * scale * tr[2]
    return (ir, ig, ib), rays


@inline_function
def shadow_transmittance(G, F, X, o, d, tmax, node_stack, t_stack):
    """Fraction (RGB) of light reaching o from distance tmax along d, and the rays used."""
    if X is not None:
        if F.has_transparency:
            return _transparent_shadow(G, F, X, o, d, tmax, node_stack, t_stack)
    if any_hit(G, X, o, d, 0.0, tmax, node_stack, t_stack):
        return (0.0, 0.0, 0.0), 1
    return (1.0, 1.0, 1.0), 1


# A call, not inlined: a walk through transparent surfaces costs several traversals anyway, and
# one more inlined copy of the traversal costs seconds of compile time in every trace kernel.
@kernel_function
def _transparent_shadow(G, F, X, o, d, tmax, node_stack, t_stack):
    tr = (1.0, 1.0, 1.0)
    origin = o
    remaining = tmax
    rays = 0
    for _ in range(MAX_HOLES):  # as many surfaces as a camera ray passes holes
        t, prim, b1, b2 = closest_hit(G, X, origin, d, 0.0, remaining, node_stack, t_stack)
        rays += 1
        if t == INF or t >= remaining:
            return tr, rays
        p = madd(origin, d, t)
        ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
        leaving = dot(ng, d) > 0.0
        if not in_hole(G, F, X, m, prim, b1, b2, p):  # a hole in an alpha map lets all through
            transparency = F.materials[m, MAT_TRANSPARENCY]
            if transparency <= 0.0:
                return (0.0, 0.0, 0.0), rays
            tr = mul(tr, transparency)
        if leaving:  # the segment just travelled lay inside this medium (a hole's too)
            tr = beer_lambert(F.materials, m, tr, t)
        if max(tr[0], tr[1], tr[2]) < 1e-4:
            return (0.0, 0.0, 0.0), rays
        eps = offset_epsilon(F.epsilon_floor, p)
        origin = madd(p, ng, eps if leaving else -eps)
        remaining -= t
    return (0.0, 0.0, 0.0), rays


@inline_function
def unshadowed_lighting(G, F, L, X, p, n, view, m, node_stack, t_stack):
    """direct_lighting without shadow rays and with the fixed area-light pattern (the
    rasterizer's lighting)."""
    return direct_lighting(G, F, L, X, p, p, n, view, m, False, node_stack, t_stack, np.uint64(0), 0)
