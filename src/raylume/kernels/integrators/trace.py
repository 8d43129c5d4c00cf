"""Whitted ray tracing: local lighting with shadows, mirror reflection and refraction.

The seed's recursive TraceRay becomes an explicit stack of weighted rays: each hit adds its
weighted local colour and may push a reflected and a transmitted ray. A surface with
reflectivity r and transparency T contributes (1 - T)(1 - r) local, reflects (1 - T) r + T F
and transmits T (1 - F), F being the Fresnel reflectance. With T = 0 this is exactly the seed's
local * (1 - r) + reflected * r. At depth 0 the surface returns its local colour, as the seed does.
"""

import math

from ..geometry.shapes import offset_epsilon, surface
from ..geometry.traverse import closest_hit
from ..shading.alpha_map import MAX_HOLES, in_hole
from ..shading.environment import environment_radiance
from ..shading.materials import MAT_EMISSION, MAT_IOR, MAT_REFLECTIVE, MAT_TRANSPARENCY, albedo, beer_lambert
from ..shading.normal_map import mapped_normal
from ..shading.optics import fresnel_dielectric, reflect, refract
from ..vec import add, dot, hadamard, inline_function, kernel_function, madd, mul, row3
from .direct import direct_lighting

INF = math.inf
# Branches whose weight falls below this cannot change an 8-bit pixel.
MIN_WEIGHT = 1e-4

# Columns of the stack of rays waiting to be traced (float64 (K, RAY_WIDTH)).
RAY_ORIGIN = 0  # 3 columns
RAY_DIRECTION = 3  # 3 columns
RAY_WEIGHT = 6  # 3 columns, RGB
RAY_DEPTH = 9  # bounces left
RAY_CONE = 10  # the ray cone's radius at the origin (texture filtering)
RAY_WIDTH = 11


@kernel_function
def stack_rows(max_depth):
    """Rows of the ray stack: a reflection waiting beside a refraction at every level, and spare."""
    return 2 * max_depth + 4


# Inlined into the row loop (frame.py): a call per camera ray passed the scene views by value.
@inline_function
def trace_ray(G, F, L, X, Env, o, d, spread, max_depth, background, rays, node_stack, t_stack, key):
    """Colour seen along the ray (o, d). `rays` is the stack of rays waiting to be traced;
    `key` the camera sample's random key (area lights). Textures are filtered over a ray cone
    from the eye whose radius grows by `spread` per unit distance, along reflections and
    refractions too (as if every surface were flat: curvature's widening is left out). Rays
    that hit nothing see the environment Env when the scene has one, else the background.
    Returns (rgb, rays traced)."""
    cr = 0.0
    cg = 0.0
    cb = 0.0
    count = 0
    shaded = 0  # surfaces shaded so far: the sampler's event counter
    top = 0
    # The next ray is kept in (o, d, w, depth) while `pending`; only a second branch (a
    # reflection beside a refraction) waits on the stack.
    w = (1.0, 1.0, 1.0)
    depth = max_depth
    cone = 0.0  # the cone's radius at o
    pending = True
    crossings = 0  # holes passed (alpha maps), all rays of the sample together: at most MAX_HOLES
    while True:
        if not pending:
            if top == 0:
                break
            top -= 1
            o = (rays[top, RAY_ORIGIN], rays[top, RAY_ORIGIN + 1], rays[top, RAY_ORIGIN + 2])
            d = (rays[top, RAY_DIRECTION], rays[top, RAY_DIRECTION + 1], rays[top, RAY_DIRECTION + 2])
            w = (rays[top, RAY_WEIGHT], rays[top, RAY_WEIGHT + 1], rays[top, RAY_WEIGHT + 2])
            depth = int(rays[top, RAY_DEPTH])
            cone = rays[top, RAY_CONE]
        pending = False
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        count += 1
        if t == INF:
            sky = environment_radiance(Env, d) if Env.present else background
            cr += w[0] * sky[0]
            cg += w[1] * sky[1]
            cb += w[2] * sky[2]
            continue
        p = madd(o, d, t)
        ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
        mat = F.materials
        entering = dot(ng, d) < 0.0
        if not entering:
            # The segment just travelled lay inside this surface's medium.
            w = beer_lambert(mat, m, w, t)
        if crossings < MAX_HOLES and in_hole(G, F, X, m, prim, b1, b2, p):
            # a hole in an alpha map: the ray goes on from the far side, as if nothing were there
            crossings += 1
            cone += spread * t
            eps = offset_epsilon(F.epsilon_floor, p)
            o, pending = madd(p, ng, -eps if entering else eps), True
            continue
        ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
        if not entering:
            ng = mul(ng, -1.0)
            ns = mul(ns, -1.0)
        # ng, ns now face the incoming ray; a shading normal bent past the horizon is clamped.
        if dot(ns, d) >= 0.0:
            ns = ng
        eps = offset_epsilon(F.epsilon_floor, p)
        outside = madd(p, ng, eps)
        view = mul(d, -1.0)
        light, shadow_rays = direct_lighting(
            G, F, L, X, p, outside, ns, view, m, True, node_stack, t_stack, key, shaded
        )
        shaded += 1
        count += shadow_rays
        cone += spread * t
        # the seed's local colour, and any emission (a glowing surface shows its radiance)
        local = add(hadamard(albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone), light), row3(mat, m, MAT_EMISSION))
        if depth <= 0:
            cr += w[0] * local[0]
            cg += w[1] * local[1]
            cb += w[2] * local[2]
            continue
        r = mat[m, MAT_REFLECTIVE]
        transparency = mat[m, MAT_TRANSPARENCY]
        fresnel = 0.0
        cos_i = -dot(ns, d)
        cos_t = 0.0
        eta = 1.0
        if transparency > 0.0:
            ior = mat[m, MAT_IOR]
            eta = 1.0 / ior if entering else ior
            fresnel, cos_t = fresnel_dielectric(cos_i, eta)
        k_local = (1.0 - transparency) * (1.0 - r)
        cr += w[0] * k_local * local[0]
        cg += w[1] * k_local * local[1]
        cb += w[2] * k_local * local[2]
        w_reflect = mul(w, (1.0 - transparency) * r + transparency * fresnel)
        w_transmit = mul(w, transparency * (1.0 - fresnel))
        reflects = max(w_reflect[0], w_reflect[1], w_reflect[2]) > MIN_WEIGHT
        transmits = max(w_transmit[0], w_transmit[1], w_transmit[2]) > MIN_WEIGHT
        # The refracted ray is traced next and the reflected one waits on the stack (the order
        # a stack of both would give).
        if transmits:
            if reflects and top < rays.shape[0]:
                _push(rays, top, outside, reflect(d, ns), w_reflect, depth - 1, cone)
                top += 1
            o, d, w, depth, pending = madd(p, ng, -eps), refract(d, ns, eta, cos_i, cos_t), w_transmit, depth - 1, True
        elif reflects:
            o, d, w, depth, pending = outside, reflect(d, ns), w_reflect, depth - 1, True
    return (cr, cg, cb), count


@kernel_function
def _push(rays, top, o, d, w, depth, cone):
    for c in range(3):
        rays[top, RAY_ORIGIN + c] = o[c]
        rays[top, RAY_DIRECTION + c] = d[c]
        rays[top, RAY_WEIGHT + c] = w[c]
    rays[top, RAY_DEPTH] = depth
    rays[top, RAY_CONE] = cone
