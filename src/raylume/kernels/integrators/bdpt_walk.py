"""Bidirectional path tracing's subpaths: the random walk from the camera (radiance) or from a
light (importance), as pbrt-v4's GenerateCameraSubpath, GenerateLightSubpath and RandomWalk.

Each vertex records its forward density (area measure; solid angle towards a light at infinity)
and, once the walk leaves it, the reverse density of the vertex before it. The walk shades as
path mode does (path.py): the same shading frame, two-sided rules, Beer-Lambert absorption
inside dielectrics, area lights (quad, sphere lights) that end a ray, and Russian roulette from
segment RR_DEPTH on (its 1 / q is in the throughput, not in the MIS densities: the weights stay a
partition of unity, each strategy stays unbiased). Participating media as path mode renders them:
the walk carries the medium its ray travels in, each segment's free flight may end in a medium
vertex (the phase function samples the next direction), null boundaries are passed without a
vertex, and a transmission changes the medium by the interface table. Random numbers: the camera
walk's BSDF and phase samples from path mode's BSDF dimension, the light walk's from a dimension
of its own, both keyed by the vertex's number along its subpath; free flights from
DIM_WALK_MEDIUM, keyed by the vertex and the null boundaries passed."""

import math

import numpy as np

from ..film.camera import CAM_FORWARD, camera_importance
from ..film.sampler import DIM_BSDF, dimension_key, key_uniform2, ld_uniform2, sub_key
from ..geometry.shapes import NO_HIT, PRIM_LIGHT, offset_epsilon, split_hit, surface
from ..geometry.traverse import any_hit_leaving, closest_hit_leaving
from ..shading.alpha_map import in_hole
from ..shading.frame import shading_frame, to_local, to_world
from ..shading.lights import at_infinity, hit_area_lights, is_delta, pick_emitter, sample_emission
from ..shading.materials import (
    MAT_EMISSION,
    albedo,
    beer_lambert,
    bsdf_eval,
    bsdf_sample,
    importance_delta_weight,
    index_matched,
    radiance_factor,
    two_sided,
)
from ..shading.media import MED_G, free_flight, hg_sample, medium_beyond, medium_leaving
from ..shading.media import homogeneous as homogeneous_medium
from ..shading.media.table import MED_KIND
from ..shading.media.tracking import ABSORBED, SCATTERED
from ..shading.normal_map import mapped_normal
from ..vec import dot, hadamard, inline_function, kernel_function, madd, mul, row3
from .bdpt_vertex import (
    CAMERA,
    F_DELTA_LIGHT,
    F_EMISSIVE,
    F_INFINITE,
    F_ON_SURFACE,
    LIGHT,
    SURFACE,
    UNION,
    V_DELTA,
    V_DIR,
    V_MED,
    V_NG,
    V_OBJ,
    V_PDF_FWD,
    V_PDF_REV,
    convert_density,
    infinite_density,
    put_medium_vertex,
    put_vertex,
    shading_correction,
)

INF = math.inf
RR_DEPTH = 5  # as path mode: Russian roulette from this many segments on
DIM_EMIT = np.uint64(0xE3177E47)  # the light subpath's emitter, point and direction
DIM_LIGHT_WALK = np.uint64(0x11647A1C)  # its BSDF samples
DIM_WALK_ROULETTE = np.uint64(0x2077E11E)
DIM_WALK_LOBE = np.uint64(0x10BE0000)  # ^ dim: which lobe of the BSDF a vertex samples
DIM_WALK_MEDIUM = np.uint64(0x3ED1A11E)  # free flights: per vertex and null boundary passed (^ dim)
FIRST_HIT = -2  # random_walk's medium: the one around the first surface the ray meets
MAX_CROSSINGS = 1024  # null boundaries one subpath passes at most (as path mode)
ZERO = (0.0, 0.0, 0.0)
ONE = (1.0, 1.0, 1.0)


@inline_function
def _roulette(key, dim, i, beta, walk):
    """Russian roulette after vertex i from RR_DEPTH on, by the walk's own throughput: (the walk
    goes on, beta, walk)."""
    if i < RR_DEPTH:
        return True, beta, walk
    q = min(walk, 0.95)
    u_rr, _ = key_uniform2(dimension_key(key, DIM_WALK_ROULETTE ^ dim, i))
    if not (u_rr < q):
        return False, beta, walk
    return True, mul(beta, 1.0 / q), walk / q


@kernel_function
def random_walk(C, V, start, o, d, beta, pdf_dir, most, importance, key, dim, spread, med, node_stack, t_stack):
    """Extend subpath V (vertex start - 1 made, the ray (o, d) leaving it with solid-angle
    density pdf_dir, in medium med: -1 none, FIRST_HIT the one the first surface met lies in)
    by at most `most` vertices. Returns (vertices made, rays traced, the camera ray left the
    scene with no light at infinity to meet: the backdrop)."""
    G, F, X, Em, Env, Md = C.G, C.F, C.X, C.Em, C.Env, C.Md
    mat = F.materials
    pdf_fwd = pdf_dir
    made = 0
    rays = 0
    walk = 1.0  # the walk's own throughput (BSDF weights), for Russian roulette
    cone = 0.0
    crossings = 0  # null boundaries passed
    infinite_lights = Em.ambient_row >= 0 or Env.present
    leaving = np.int64(NO_HIT)  # the surface o lies on, offset towards d (path mode's rule)
    while made < most:
        i = start + made
        prev = i - 1
        t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, INF, leaving, node_stack, t_stack)
        rays += 1
        tl, el, nl = INF, -1, d
        if Em.n_area > 0:
            tl, el, nl = hit_area_lights(Em, o, d, t)
        if med == FIRST_HIT:
            med, traced = _medium_ahead(G, X, F, Md, o, d, t, prim, b1, b2, node_stack, t_stack)
            rays += traced
        if med >= 0:
            # the medium along the segment (path mode's free flight): a scattering before its end
            # is a medium vertex, where the phase function samples the next direction
            flight_key = sub_key(dimension_key(key, DIM_WALK_MEDIUM ^ dim, i), crossings)
            status, ts, beta = free_flight(Md, med, o, d, tl if el >= 0 else t, flight_key, beta)
            if status == ABSORBED:
                break
            if status == SCATTERED:
                p = madd(o, d, ts)
                g = Md.data[med, MED_G]
                put_medium_vertex(V, i, p, mul(d, -1.0), beta, med, g)
                V[i, V_PDF_FWD] = convert_density(pdf_fwd, V, prev, V, i)
                made += 1
                if made >= most:
                    break
                u_a, u_b = ld_uniform2(key, dim, i)
                wi_w, phase = hg_sample(g, d, u_a, u_b)
                pdf_fwd = phase  # HG is symmetric: the reverse density is the same
                V[prev, V_PDF_REV] = convert_density(phase, V, i, V, prev)
                cone += spread * ts
                o = p
                leaving = np.int64(NO_HIT)
                d = wi_w
                going, beta, walk = _roulette(key, dim, i, beta, walk)
                if not going:
                    break
                continue
        if el >= 0:  # an area light ends the ray; a camera subpath keeps it as a light vertex
            if not importance:
                put_vertex(
                    V, i, LIGHT, madd(o, d, tl), nl, nl, mul(d, -1.0), beta, 0.0, -1, el, ZERO, NO_HIT, F_ON_SURFACE
                )
                V[i, V_PDF_FWD] = convert_density(pdf_fwd, V, prev, V, i)
                made += 1
            break
        if prim == NO_HIT:
            if importance:
                break
            if not infinite_lights:
                return made, rays, i == 1
            put_vertex(V, i, LIGHT, o, d, d, mul(d, -1.0), beta, pdf_fwd, -1, UNION, ZERO, NO_HIT, F_INFINITE)
            for c in range(3):
                V[i, V_DIR + c] = d[c]
            made += 1
            break
        p = madd(o, d, t)
        ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
        ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
        entering = dot(ng, d) < 0.0
        if Md.pass_through and (index_matched(mat, m) or in_hole(G, F, X, m, prim, b1, b2, p)):
            # a null boundary: the ray goes on unchanged into the medium beyond, no vertex (path
            # mode's rule); the next vertex's density still converts from the vertex before. A
            # hole in an alpha map the same (a null patch of the object's boundary)
            if Md.present:
                med = medium_beyond(Md, obj, d, ng)
            eps = offset_epsilon(F.epsilon_floor, p)
            o = madd(p, ng, -eps if entering else eps)
            leaving = prim
            cone += spread * t
            crossings += 1
            if crossings > MAX_CROSSINGS:
                break
            continue
        if not entering:
            beta = beer_lambert(mat, m, beta, t)
        cone += spread * t
        colour = albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone)
        flags = 0
        e = -1
        if not importance:
            emission = row3(mat, m, MAT_EMISSION)
            if emission[0] > 0.0 or emission[1] > 0.0 or emission[2] > 0.0:
                k, _ = split_hit(X, prim)
                flags = F_EMISSIVE
                e = np.int64(G.prims[k, PRIM_LIGHT])
        put_vertex(V, i, SURFACE, p, ng, ns, mul(d, -1.0), beta, 0.0, m, e, colour, prim, flags)
        V[i, V_PDF_FWD] = convert_density(pdf_fwd, V, prev, V, i)
        if Md.present:
            V[i, V_MED] = med
            V[i, V_OBJ] = obj
        made += 1
        if made >= most:
            break
        n_geo = ng  # outward: which side is inside, for the media
        two = two_sided(mat, m)
        ng, ns, s_axis, t_axis = shading_frame(two, not entering, ng, ns)
        wo_w = mul(d, -1.0)
        wo = to_local(wo_w, s_axis, t_axis, ns)
        u0, _ = key_uniform2(dimension_key(key, dim ^ DIM_WALK_LOBE, i))
        u1, u2 = ld_uniform2(key, dim, i)
        wi, weight, pdf, delta = bsdf_sample(mat, m, colour, wo, u0, u1, u2)
        if not (pdf > 0.0) or not (weight[0] > 0.0 or weight[1] > 0.0 or weight[2] > 0.0):
            break
        wi_w = to_world(wi, s_axis, t_axis, ns)
        up = dot(wi_w, ng) > 0.0
        if two and not up:
            break  # a shading normal sent the path through the surface
        med = medium_leaving(Md, med, obj, d, n_geo, wi_w)  # transmitted: into the medium beyond
        if delta:
            pdf_fwd = 0.0
            pdf_rev = 0.0
            V[i, V_DELTA] = 1.0
            if importance:
                weight = importance_delta_weight(mat, m, wo, wi, weight)
        else:
            pdf_fwd = pdf
            f_rev, pdf_rev = bsdf_eval(mat, m, colour, wi, wo)
            if importance:  # the adjoint BSDF: light goes on from wo's side to wi's
                weight = mul(f_rev, abs(wi[2]) / pdf)
        if importance:
            weight = mul(weight, shading_correction(ng, ns, wo_w, wi_w))
        beta = hadamard(beta, weight)
        walk *= max(weight[0], weight[1], weight[2])
        if not importance:  # without a camera subpath's radiance factors (path._roulette's eta2)
            walk /= radiance_factor(mat, m, wo, wi)
        V[prev, V_PDF_REV] = convert_density(pdf_rev, V, i, V, prev)
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, ng, eps if up else -eps)
        leaving = prim
        d = wi_w
        going, beta, walk = _roulette(key, dim, i, beta, walk)
        if not going:
            break
    return made, rays, False


@kernel_function
def _medium_ahead(G, X, F, Md, o, d, t, prim, b1, b2, node_stack, t_stack):
    """The medium a ray from a light lies in, by the first surface it meets that has different
    media on its two sides (hit from outside: the medium around that object, from inside: its
    inside); the scene's outer medium when it meets none. Lights are not objects: they sit in
    whatever encloses them. A surface with one medium on both sides is passed: an open one (a
    plane, a quad) has no inside, and the medium "around" it, found from one of its points, need
    not be the one around the point the ray meets (a floor through a sphere of fog). Returns
    (the medium, the rays traced beyond the first hit)."""
    if not Md.present:
        return -1, 0
    for traced in range(MAX_CROSSINGS):
        if prim == NO_HIT:
            return Md.camera, traced
        p = madd(o, d, t)
        ng, _, _, obj, _ = surface(G, X, prim, b1, b2, p)
        entering = dot(d, ng) < 0.0
        if Md.interface[obj, 0] != Md.interface[obj, 1]:
            return (Md.interface[obj, 1] if entering else Md.interface[obj, 0]), traced
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, ng, -eps if entering else eps)
        t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, INF, prim, node_stack, t_stack)
    return Md.camera, MAX_CROSSINGS


@kernel_function
def camera_subpath(C, Vc, most, o, d, spread, key, node_stack, t_stack):
    """The camera subpath of the camera ray (o, d): the lens point, then at most `most`
    vertices. Returns (vertices, rays, backdrop)."""
    cam = C.cam
    f = (cam[CAM_FORWARD], cam[CAM_FORWARD + 1], cam[CAM_FORWARD + 2])
    put_vertex(Vc, 0, CAMERA, o, f, f, f, ONE, 1.0, -1, -1, ZERO, NO_HIT, 0)
    _, pdf_dir, _, _ = camera_importance(cam, C.width, C.height, o, d)
    made, rays, backdrop = random_walk(
        C, Vc, 1, o, d, ONE, pdf_dir, most, False, key, DIM_BSDF, spread, C.Md.camera, node_stack, t_stack
    )
    return made + 1, rays, backdrop


@kernel_function
def emitter_sample(C, key, dim):
    """A light picked by power and a point and direction leaving it (each kind's `emit`), from
    the camera sample of `key`'s numbers of dimension `dim` (the point and the direction
    low-discrepancy): (light, its pick probability, point, normal, direction, radiance, position
    density, direction density, primitive hit). The light subpath's first vertex, and the glint
    guide's pilots' light points (bdpt_glint.py)."""
    k = dimension_key(key, dim, 0)
    u_pick, _ = key_uniform2(k)
    u1, u2 = ld_uniform2(key, dim, 1)
    u3, u4 = ld_uniform2(key, dim, 2)
    e, p_pick = pick_emitter(C.Em.cdf, u_pick)
    p, n, w, le, pdf_pos, pdf_dir, hit = sample_emission(C.G, C.X, C.Em, C.Env, e, u1, u2, u3, u4, k, C.B)
    return e, p_pick, p, n, w, le, pdf_pos, pdf_dir, hit


@kernel_function
def light_subpath(C, Vl, most, key, node_stack, t_stack):
    """The light subpath of a camera sample: a point on a light picked by power and a direction
    leaving it (each kind's `emit`), then at most most - 1 more vertices. Returns (vertices, rays)."""
    F, Em = C.F, C.Em
    if most < 1 or not (Em.cdf[Em.cdf.shape[0] - 1] > 0.0):
        return 0, 0
    e, p_pick, p, n, w, le, pdf_pos, pdf_dir, hit = emitter_sample(C, key, DIM_EMIT)
    if not (pdf_pos > 0.0 and pdf_dir > 0.0 and p_pick > 0.0) or not (le[0] > 0.0 or le[1] > 0.0 or le[2] > 0.0):
        return 0, 0
    kind = Em.kind[e]
    infinite = at_infinity(kind)
    delta = is_delta(kind)
    flags = (F_INFINITE if infinite else 0) | (F_DELTA_LIGHT if delta else 0)
    surface_point = not infinite and not delta
    if surface_point:
        flags |= F_ON_SURFACE
    put_vertex(Vl, 0, LIGHT, p, n, n, w, le, p_pick * pdf_pos, -1, e, ZERO, hit, flags)
    cos_l = 1.0
    if infinite:
        for c in range(3):
            Vl[0, V_DIR + c] = -w[c]
    elif surface_point:
        cos_l = abs(dot(n, w))
    beta = mul(le, cos_l / (p_pick * pdf_pos * pdf_dir))
    o = p
    if (
        infinite
        and C.G.n_bounded < C.G.prims.shape[0]
        and any_hit_leaving(C.G, C.X, p, mul(w, -1.0), 0.0, INF, np.int64(NO_HIT), node_stack, t_stack)
    ):
        # The disk lies outside the bounded geometry's sphere, not beyond an infinite plane: light
        # from this side of one does not reach the disk's point, so the subpath carries nothing
        # (the light vertex stays, for the strategies that sample the light anew).
        return 1, 1
    if surface_point:
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, n, eps if dot(n, w) > 0.0 else -eps)
    Md = C.Md
    med = FIRST_HIT if Md.present else -1
    if infinite and Md.present:
        # from the bounding sphere's disk, which lies in the outer medium: a homogeneous one lets
        # nothing through from infinitely far (a grid's box lies inside the sphere, bdpt_setup.py)
        med = Md.camera
        if med >= 0 and int(Md.data[med, MED_KIND]) == homogeneous_medium.KIND:
            beta = hadamard(beta, homogeneous_medium.exact_transmittance(Md.data, med, INF))
    made, rays, _ = random_walk(
        C, Vl, 1, o, w, beta, pdf_dir, most - 1, True, key, DIM_LIGHT_WALK, 0.0, med, node_stack, t_stack
    )
    if infinite:
        # the first vertex's density is the disk's (planar), the light's own its direction's
        if made > 0:
            Vl[1, V_PDF_FWD] = pdf_pos * abs(dot(w, row3(Vl, 1, V_NG)))
        Vl[0, V_PDF_FWD] = infinite_density(C, mul(w, -1.0))
    return made + 1, rays
