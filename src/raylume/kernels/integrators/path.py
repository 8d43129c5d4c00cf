"""Path tracing: unbiased Monte Carlo light transport in radiometric units, as Mitsuba 3's
`path` integrator computes it.

Each camera sample follows one path. At every surface it adds the surface's emission, a
next-event estimate (one light picked in proportion to power, lights/distribution.py, a point on it,
a shadow ray) and continues in a direction sampled from the BSDF (materials/registry.py). Emission found by
a BSDF-sampled direction and light found by next-event estimation are weighted by the power
heuristic (Veach's multiple importance sampling), so each light path is counted once;
delta lights and smooth (delta) BSDF lobes take the one strategy that can find them.

Depth counts path segments as Mitsuba does: the camera ray is segment 1, so max_depth 1 shows
only emitters seen directly, 2 is direct lighting and 0 is black; -1 is unlimited, with Russian roulette
from segment RR_DEPTH on. Random numbers come from the sampler's named dimensions keyed by
(seed, pixel, sample, segment), so an image depends only on the scene, seed and spp.
"""

import math

import numpy as np

from ..film.sampler import DIM_BSDF, DIM_LIGHT, dimension_key, key_uniform2, ld_uniform2, sub_key
from ..geometry.shapes import NO_HIT, PRIM_LIGHT, offset_epsilon, split_hit, surface
from ..geometry.traverse import any_hit_between, closest_hit_leaving
from ..shading.alpha_map import in_hole
from ..shading.environment import environment_cell, prefetch_environment
from ..shading.frame import facing_normals, to_local, to_world
from ..shading.lights import (
    LIGHT_INTENSITY,
    SHADOW_SHORTEN,
    area_light_blocks,
    environment_arrival,
    hit_area_lights,
    light_pdf,
    light_point,
    light_primitive,
    pick_emitter,
    pick_probability,
    sample_light,
)
from ..shading.lights.sampling import basis
from ..shading.materials import (
    MAT_EMISSION,
    albedo,
    beer_lambert,
    bsdf_eval,
    bsdf_sample,
    delta_only,
    index_matched,
    is_diffuse,
    radiance_factor,
    two_sided,
)
from ..shading.media import MED_G, free_flight, hg_eval, hg_sample, medium_beyond, medium_leaving
from ..shading.media.tracking import ABSORBED, SCATTERED
from ..shading.normal_map import mapped_normal
from ..vec import dot, hadamard, inline_function, madd, mul, row3
from .shadow import scale_free_shadows, shadow_ray, shadow_segment, shadow_transmittance

INF = math.inf
RR_DEPTH = 5  # Mitsuba's rr_depth: Russian roulette from this many segments on
# Strategies (a debugging and testing switch, RAYLUME_PATH_STRATEGY): both combined by MIS,
# light sampling alone (emitters found by BSDF samples count only after delta bounces), BSDF
# sampling alone (next-event estimation only for delta lights, which nothing else can find).
MIS = 0
LIGHT_ONLY = 1
BSDF_ONLY = 2
DIM_ROULETTE = np.uint64(0x2077E77E)
DIM_BSDF_LOBE = np.uint64(0xB5DF10BE)  # which lobe of the BSDF a bounce samples
DIM_MEDIUM = np.uint64(0x3ED1A3ED)  # free flights through media: per segment and boundary crossed
DIM_SHADOW_MEDIUM = np.uint64(0x5AD0BEEF)  # ratio tracking along shadow rays
MAX_CROSSINGS = 1024  # null boundaries one path passes at most (a guard against endless rounding)


@inline_function
def power_heuristic(a, b):
    """Veach's power heuristic (beta 2) weight of the strategy with pdf a against pdf b."""
    a2 = a * a
    return a2 / (a2 + b * b) if a2 > 0.0 else 0.0


@inline_function
def _light_weight(pdf_l, pdf_b, weighed):
    """A light sample's MIS weight over its density pdf_l: the power heuristic against the BSDF's
    pdf_b when `weighed`, else 1, divided by pdf_l; one division (w / a = a / (a^2 + b^2))."""
    if weighed:
        return pdf_l / (pdf_l * pdf_l + pdf_b * pdf_b)
    return 1.0 / pdf_l


@inline_function
def _add_light(L, beta, le, w):
    """L plus radiance le arriving through path throughput beta, with MIS weight w."""
    return (L[0] + beta[0] * le[0] * w, L[1] + beta[1] * le[1] * w, L[2] + beta[2] * le[2] * w)


@inline_function
def _emitter_weight(G, X, Em, Env, e, hit, prev_p, d, t, n_hit, prev_pdf, prev_delta, strategy):
    """MIS weight of emission met by a BSDF-sampled ray (against next-event estimation); `hit`:
    the primitive met (NO_HIT for lights that are not primitives)."""
    if prev_delta or e < 0 or strategy == BSDF_ONLY:
        return 1.0
    if strategy == LIGHT_ONLY:
        return 0.0
    pdf_l = pick_probability(Em.cdf, e) * light_pdf(G, X, Em, Env, e, prev_p, d, t, n_hit, hit)
    return power_heuristic(prev_pdf, pdf_l)


@inline_function
def _weight_against(pdf_l, e, prev_pdf, prev_delta, strategy):
    """_emitter_weight with the light's density (pick probability included) already known."""
    if prev_delta or e < 0 or strategy == BSDF_ONLY:
        return 1.0
    if strategy == LIGHT_ONLY:
        return 0.0
    return power_heuristic(prev_pdf, pdf_l)


@inline_function
def _roulette(beta, eta2, key, depth):
    """Russian roulette from segment RR_DEPTH on: (the path goes on, its throughput). The
    survival probability follows beta without the refractions' radiance factors (eta2, as pbrt's
    etaScale and Mitsuba's eta^2): inside glass of index 100 beta is 1e-4 of what leaves it, and
    a path there survived each step with that probability, its light in rare huge samples (a
    white furnace's glass sphere read 0.966 at 64 spp)."""
    if depth < RR_DEPTH:
        return True, beta
    q = min(max(beta[0], beta[1], beta[2]) * eta2, 0.95)
    u_rr, _ = key_uniform2(dimension_key(key, DIM_ROULETTE, depth))
    if u_rr >= q:
        return False, beta
    return True, mul(beta, 1.0 / q)


@inline_function
def _shadow(G, F, X, Em, Md, origin, wi, tmax, med, target, key, depth, leaving, node_stack, t_stack):
    """Transmittance (RGB) of a shadow ray towards light row `target`: 0 where another area
    light is in the way, else through media and null boundaries where the scene has them
    (shadow.py), else 0 or 1 by any_hit. `leaving`: the primitive it leaves from (NO_HIT: a
    point in a medium), and the target's primitive (lights.light_primitive), which it ends
    short of, as traverse.any_hit_between takes them."""
    if area_light_blocks(Em, target, origin, wi, tmax):
        return (0.0, 0.0, 0.0)
    if Md.pass_through:
        return shadow_transmittance(
            G, F, X, Md, origin, wi, tmax, med, dimension_key(key, DIM_SHADOW_MEDIUM, depth), node_stack, t_stack
        )
    if any_hit_between(G, X, origin, wi, 0.0, tmax, leaving, light_primitive(Em, target), node_stack, t_stack):
        return (0.0, 0.0, 0.0)
    return (1.0, 1.0, 1.0)


# What path_segment says of the path it advanced
GO = 0  # the path goes on: its state holds its next ray
DONE = 1  # the path has ended: its state's L is its radiance
DEFERRED = 2  # at a diffuse surface whose shading the caller does (path_wavefront.py)
ZERO3 = (0.0, 0.0, 0.0)
# path_segment's deferred surface when there is none
NOTHING_DEFERRED = (ZERO3, ZERO3, ZERO3, ZERO3, 0.0, 0, ZERO3, ZERO3, 0.0, 0.0, ZERO3, 0.0, False, 0.0, 0.0,
                    np.int64(-1))  # fmt: skip


@inline_function
def path_start(Md, o, d):
    """The state of a path leaving the camera along (o, d): (o, d, beta, L, rays, depth,
    prev_pdf, prev_delta, cone, med, mis_o, mis_t, crossings, leaving, eta2), as path_segment takes it.
    MIS weighs emission met by a sampled direction with the light's pdf seen from the vertex
    that sampled it, mis_o, mis_t before o along d (null boundaries pass a ray unchanged);
    `eta2` undoes the radiance factors (n_wo / n_wi)^2 that refractions put in beta, for Russian
    roulette (_roulette);
    `leaving` is the surface o lies on, offset towards d (none for the camera); `cone` the ray
    cone's radius at o; `med` the medium the ray travels in (-1: none); the camera ray sees
    emitters at full weight (prev_delta)."""
    return (o, d, (1.0, 1.0, 1.0), ZERO3, 0, 0, 0.0, True, 0.0, Md.camera, o, 0.0, 0, np.int64(NO_HIT), 1.0)


@inline_function
def _ended(st, L, rays):
    """The state of a path that ended with radiance L after `rays` rays (all that is read of it)."""
    return (st[0], st[1], st[2], L, rays, st[5], st[6], st[7], st[8], st[9], st[10], st[11], st[12], st[13], st[14])


# How a deferred surface's light sample is given (path_segment, _partial_light)
GIVEN = 0  # the direction, its distance, radiance and density (pick included)
SURFACE_POINT = 1  # a point uniform over a surface: the point, its unit normal, the area, radiance
ENVIRONMENT_CELL = 2  # the environment's choice (environment.environment_cell): (cos theta, u, 0)


@inline_function
def _partial_light(G, X, Em, Env, le, u1, u2):
    """Light row le's sample where path_segment defers it: (form, the point or cell, the point's
    unit normal, the surface's area or the cell's pdf, radiance). A SURFACE_POINT's caller
    finishes it as sampling.towards_point would; an ENVIRONMENT_CELL's as
    environment.sample_environment would, looking its radiance up only once the shadow ray is
    known to arrive (here (1, 1, 1)); the other kinds are GIVEN: sampled whole (sample_light)."""
    if le == Em.environment_row:
        pdf_cell, cos_theta, u = environment_cell(Env, u1, u2)
        lit = 1.0 if pdf_cell > 0.0 else 0.0
        return ENVIRONMENT_CELL, (cos_theta, u, 0.0), ZERO3, pdf_cell, (lit, lit, lit)
    on_surface, q, n_l, area, li = light_point(G, X, Em, le, u1, u2)
    return (SURFACE_POINT if on_surface else GIVEN), q, n_l, area, li


@inline_function
def path_ray(G, F, X, Em, Env, Md, o, d, spread, max_depth, background, key, node_stack, t_stack, strategy):
    """Radiance along the camera ray (o, d) by one path; textures are filtered over a ray cone
    growing by `spread` per unit distance (as trace_ray's). Returns (rgb, rays traced)."""
    st = path_start(Md, o, d)
    unnormalized_shadows = scale_free_shadows(G, Em, Md)
    while True:
        status, st, _ = path_segment(
            G, F, X, Em, Env, Md, st, spread, max_depth, background, key, node_stack, t_stack, strategy,
            unnormalized_shadows, False,
        )  # fmt: skip
        if status == DONE:
            return st[3], st[4]


@inline_function
def path_segment(
    G, F, X, Em, Env, Md, st, spread, max_depth, background, key, node_stack, t_stack, strategy, unnormalized_shadows,
    defer,
):  # fmt: skip
    """One segment of the path in state st (path_start): its ray to the next vertex, the light
    met there and the next ray. Returns (GO or DONE, the new state, the deferred surface). With
    `defer`, a diffuse surface whose light sample next-event estimation may use is left
    unshaded (DEFERRED): the state's beta and L as they reach it, and the surface to shade, (p,
    ng, ns, colour, eps, *light sample, u1, u2, light row): the normals turned to face the ray
    (shading_frame's), the light sample (its form, the direction, point or cell, the point's
    normal, the area or the cell's pdf, distance, radiance, density with the pick's: for a point
    only the pick's; 0: no light to add; whether MIS weighs it), the BSDF's two uniforms.
    The shadow ray of a diffuse surface's light leaves on the incoming ray's side: in its
    medium."""
    o, d, beta, L, rays, depth, prev_pdf, prev_delta, cone, med, mis_o, mis_t, crossings, leaving, eta2 = st
    mat = F.materials
    nothing = NOTHING_DEFERRED
    if max_depth == 0:  # no segment at all: black, as Mitsuba's max_depth 0 and bdpt's
        return DONE, st, nothing
    # Next-event estimation's numbers for the surface this segment may reach, drawn before
    # its traversal so that the environment's alias slot (a cache miss: ~11% of
    # materials.toml's time waited for it) arrives meanwhile.
    light_key = dimension_key(key, DIM_LIGHT, depth + 1)
    u_pick, _ = key_uniform2(light_key)
    u1, u2 = ld_uniform2(key, DIM_LIGHT, depth + 1)
    if Env.present:
        prefetch_environment(Env, u1)
    t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, INF, leaving, node_stack, t_stack)
    rays += 1
    depth += 1
    tl, e, nl = INF, -1, d
    if Em.n_area > 0:
        tl, e, nl = hit_area_lights(Em, o, d, t)
    if med >= 0:
        # the medium along the segment: a scattering before its end makes a path vertex there
        flight_key = sub_key(dimension_key(key, DIM_MEDIUM, depth), crossings)
        status, ts, beta = free_flight(Md, med, o, d, tl if e >= 0 else t, flight_key, beta)
        if status == ABSORBED:
            return DONE, _ended(st, L, rays), nothing
        if status == SCATTERED:
            if max_depth >= 0 and depth >= max_depth:
                return DONE, _ended(st, L, rays), nothing
            p = madd(o, d, ts)
            g = Md.data[med, MED_G]
            if Em.cdf[Em.cdf.shape[0] - 1] > 0.0:
                le, p_pick = pick_emitter(Em.cdf, u_pick)
                wi, dist, li, pdf_l, delta_l = sample_light(G, X, Em, Env, le, p, u1, u2, light_key)
                if pdf_l > 0.0 and (li[0] > 0.0 or li[1] > 0.0 or li[2] > 0.0) and (delta_l or strategy != BSDF_ONLY):
                    phase = hg_eval(g, dot(d, wi))
                    tmax = dist * (1.0 - SHADOW_SHORTEN) if dist < INF else INF
                    rays += 1
                    tr = _shadow(
                        G, F, X, Em, Md, p, wi, tmax, med, le, key, depth, np.int64(NO_HIT), node_stack, t_stack
                    )
                    if tr[0] > 0.0 or tr[1] > 0.0 or tr[2] > 0.0:
                        weighed = not delta_l and strategy != LIGHT_ONLY
                        L = _add_light(L, hadamard(beta, tr), li, phase * _light_weight(p_pick * pdf_l, phase, weighed))
            u_a, u_b = ld_uniform2(key, DIM_BSDF, depth)
            wi, phase = hg_sample(g, d, u_a, u_b)
            going, beta = _roulette(beta, eta2, key, depth)
            st = (
                p,
                wi,
                beta,
                L,
                rays,
                depth,
                phase,
                False,
                cone + spread * ts,
                med,
                p,
                0.0,
                crossings,
                np.int64(NO_HIT),
                eta2,
            )
            return (GO if going else DONE), st, nothing
    if e >= 0:
        w = _emitter_weight(
            G, X, Em, Env, e, np.int64(NO_HIT), mis_o, d, mis_t + tl, nl, prev_pdf, prev_delta, strategy
        )
        L = _add_light(L, beta, row3(Em.data, e, LIGHT_INTENSITY), w)
        return DONE, _ended(st, L, rays), nothing
    if prim == NO_HIT:
        if Em.ambient_row >= 0:
            w = _emitter_weight(
                G, X, Em, Env, Em.ambient_row, np.int64(NO_HIT), mis_o, d, INF, d, prev_pdf, prev_delta, strategy
            )
            L = _add_light(L, beta, row3(Em.data, Em.ambient_row, LIGHT_INTENSITY), w)
        if Env.present:
            le_env, pdf_env = environment_arrival(Em, Env, d)  # one lookup of d for both
            w = _weight_against(pdf_env, Em.environment_row, prev_pdf, prev_delta, strategy)
            L = _add_light(L, beta, le_env, w)
        elif depth == 1 and Em.ambient_row < 0:  # the background: a backdrop, not a light
            L = _add_light(L, (1.0, 1.0, 1.0), background, 1.0)
        return DONE, _ended(st, L, rays), nothing
    p = madd(o, d, t)
    ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
    ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
    entering = dot(ng, d) < 0.0
    eps = offset_epsilon(F.epsilon_floor, p)
    # (alpha maps make pass_through: in scenes without, no hole is looked for)
    if index_matched(mat, m) or (Md.pass_through and in_hole(G, F, X, m, prim, b1, b2, p)):
        # an index-matched boundary: the ray goes on unchanged into the medium beyond, and
        # the segment does not count as one (Mitsuba's volpath); a hole in an alpha map the
        # same (the object's inside stays filled: a hole is a null patch of its boundary)
        if Md.present:
            med = medium_beyond(Md, obj, d, ng)
        st = (madd(p, ng, -eps if entering else eps), d, beta, L, rays, depth - 1, prev_pdf, prev_delta,
              cone + spread * t, med, mis_o, mis_t + t, crossings + 1, prim, eta2)  # fmt: skip
        return (DONE if crossings + 1 > MAX_CROSSINGS else GO), st, nothing
    if not entering:
        # the segment just travelled lay inside this surface's medium
        beta = beer_lambert(mat, m, beta, t)
    emission = row3(mat, m, MAT_EMISSION)
    if emission[0] > 0.0 or emission[1] > 0.0 or emission[2] > 0.0:
        k, _ = split_hit(X, prim)
        # the light row as int64, as at the other call sites: one compilation of the MIS
        # weight and of every light kind's pdf, not a second one for an int32 row
        w = _emitter_weight(
            G,
            X,
            Em,
            Env,
            np.int64(G.prims[k, PRIM_LIGHT]),
            prim,
            mis_o,
            d,
            mis_t + t,
            ng,
            prev_pdf,
            prev_delta,
            strategy,
        )
        L = _add_light(L, beta, emission, w)
    if max_depth >= 0 and depth >= max_depth:
        return DONE, _ended(st, L, rays), nothing
    n_geo = ng  # outward: which side is inside, for the media
    two_sided_here = two_sided(mat, m)
    ng, ns = facing_normals(two_sided_here, not entering, ng, ns)
    cone += spread * t
    colour = albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone)
    lights = Em.cdf[Em.cdf.shape[0] - 1] > 0.0 and not delta_only(mat, m)
    deferring = defer and is_diffuse(mat, m)
    # next-event estimation's light sample: where the shading is deferred, a point on a surface
    # or an environment cell for the caller to finish, else the kind's whole sample (one call
    # site of sample_light, which inlines every kind's)
    form, aim, n_l, area, li = GIVEN, ZERO3, ZERO3, 0.0, ZERO3
    le, p_pick = np.int64(-1), 0.0
    wi, dist, pdf_l, delta_l = ZERO3, 0.0, 0.0, False
    if lights:
        le, p_pick = pick_emitter(Em.cdf, u_pick)
        if deferring:
            form, aim, n_l, area, li = _partial_light(G, X, Em, Env, le, u1, u2)
        if form == GIVEN:
            wi, dist, li, pdf_l, delta_l = sample_light(G, X, Em, Env, le, p, u1, u2, light_key)
    lit = li[0] > 0.0 or li[1] > 0.0 or li[2] > 0.0
    usable = lights and pdf_l > 0.0 and lit and (delta_l or strategy != BSDF_ONLY)
    if deferring:
        # the facing normals and the light sample, for the caller's SIMD stage
        weighed = not delta_l and strategy != LIGHT_ONLY
        if form == GIVEN:
            aim, density = wi, p_pick * pdf_l if usable else 0.0
        else:  # its density is the pick's (a point) or the cell's with the pick's
            density = p_pick * area if form == ENVIRONMENT_CELL else p_pick
            density = density if lights and lit and strategy != BSDF_ONLY else 0.0
            dist = INF if form == ENVIRONMENT_CELL else 0.0
        b_u1, b_u2 = ld_uniform2(key, DIM_BSDF, depth)
        deferred = (p, ng, ns, colour, eps, form, aim, n_l, area, dist, li, density, weighed, b_u1, b_u2, np.int64(le))
        st = (o, d, beta, L, rays, depth, prev_pdf, prev_delta, cone, med, mis_o, mis_t, crossings, prim, eta2)
        return DEFERRED, st, deferred
    s_axis, t_axis = basis(ns)
    wo = to_local(mul(d, -1.0), s_axis, t_axis, ns)

    # next-event estimation
    if usable:
        wi_local = to_local(wi, s_axis, t_axis, ns)
        up = dot(wi, ng) > 0.0
        # two-sided reflection: light from below the geometric surface cannot arrive
        if up or not two_sided_here:
            f, pdf_b = bsdf_eval(mat, m, colour, wo, wi_local)
            if f[0] > 0.0 or f[1] > 0.0 or f[2] > 0.0:
                if unnormalized_shadows:
                    origin, aim, tmax = shadow_segment(p, ng, eps if up else -eps, wi, dist)
                else:
                    origin, aim, tmax = shadow_ray(p, ng, eps if up else -eps, wi, dist)
                rays += 1
                # the shadow ray leaves on the side of the incoming ray, or crosses
                shadow_med = medium_leaving(Md, med, obj, d, n_geo, wi)
                tr = _shadow(G, F, X, Em, Md, origin, aim, tmax, shadow_med, le, key, depth, prim, node_stack, t_stack)
                if tr[0] > 0.0 or tr[1] > 0.0 or tr[2] > 0.0:
                    weighed = not delta_l and strategy != LIGHT_ONLY
                    scale = abs(wi_local[2]) * _light_weight(p_pick * pdf_l, pdf_b, weighed)
                    L = _add_light(L, hadamard(hadamard(beta, f), tr), li, scale)

    # continue the path
    u0, _ = key_uniform2(dimension_key(key, DIM_BSDF_LOBE, depth))
    u1, u2 = ld_uniform2(key, DIM_BSDF, depth)
    wi_local, weight, pdf, delta = bsdf_sample(mat, m, colour, wo, u0, u1, u2)
    if not (pdf > 0.0) or not (weight[0] > 0.0 or weight[1] > 0.0 or weight[2] > 0.0):
        return DONE, _ended(st, L, rays), nothing
    wi = to_world(wi_local, s_axis, t_axis, ns)
    up = dot(wi, ng) > 0.0
    if two_sided_here and not up:
        # a shading normal sent the path through the surface
        return DONE, _ended(st, L, rays), nothing
    med = medium_leaving(Md, med, obj, d, n_geo, wi)  # transmitted: into the medium beyond
    beta = hadamard(beta, weight)
    eta2 /= radiance_factor(mat, m, wo, wi_local)
    o = madd(p, ng, eps if up else -eps)
    going, beta = _roulette(beta, eta2, key, depth)
    st = (o, wi, beta, L, rays, depth, pdf, delta, cone, med, o, 0.0, crossings, prim, eta2)
    return (GO if going else DONE), st, nothing


@inline_function
def finite_sample(c):
    """A sample fit for the film: finite and not negative."""
    return (
        c[0] == c[0]
        and c[1] == c[1]
        and c[2] == c[2]
        and abs(c[0]) < INF
        and abs(c[1]) < INF
        and abs(c[2]) < INF
        and c[0] >= 0.0
        and c[1] >= 0.0
        and c[2] >= 0.0
    )
