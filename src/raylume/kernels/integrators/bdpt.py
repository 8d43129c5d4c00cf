"""Bidirectional path tracing (`integrator = "bdpt"`): Veach's thesis, chapter 10, as pbrt-v4's
BDPTIntegrator computes it.

Every camera sample traces a camera subpath and a light subpath (bdpt_walk.py) and connects
them by every strategy (s light vertices, t camera vertices) with s + t - 1 segments up to
max_depth: s = 0 (the camera subpath meets a light by itself), s = 1 (a point on a light picked
by power, a shadow ray), t = 1 (the light subpath's vertices seen by the camera: a splat on the
film wherever they land, splat.py) and the connections between the two. Each is weighted by the
balance heuristic over the strategies that could have made the same path (bdpt_mis.py), so the
estimate is unbiased and converges to path mode's image.

Participating media as pbrt-v3's BDPT renders them: subpaths scatter in media (medium vertices,
the phase function for a BSDF; bdpt_walk.py), pass null boundaries without a vertex and track
the medium they travel in as path mode does; every connection multiplies in the transmittance
of the media and null boundaries it passes (shadow.py's, path mode's shadow rays), from the
medium on its starting vertex's side. The MIS densities leave out the free flights' distance
sampling and the transmittance, the same for every strategy (pbrt-v3), so the weights still sum
to one over the strategies that can make a path.

max_depth counts segments, as path mode (-1: unlimited, Russian roulette from segment 5, at most
MAX_SEGMENTS). A strategy switch (RAYLUME_BDPT_STRATEGY="s,t", with or without MIS) renders one
strategy alone, for tests."""

import math

import numpy as np

from ..film.camera import CAM_FORWARD, camera_importance, lens_area, lens_point
from ..film.sampler import dimension_key, key_uniform2, ld_uniform2, sub_key
from ..film.splat import splat
from ..geometry import shape_sphere
from ..geometry.shapes import NO_HIT, PRIM_KIND, PRIM_ROW, SPHERE, offset_epsilon, split_hit
from ..geometry.traverse import any_hit_leaving
from ..shading.lights import (
    LIGHT_INTENSITY,
    SHADOW_SHORTEN,
    area_light_blocks,
    at_infinity,
    emission_pdf,
    environment_light,
    is_delta,
    pick_emitter,
    sample_emission,
)
from ..shading.lights.registry import hides_own_point
from ..shading.materials import MAT_EMISSION, beer_lambert, two_sided
from ..vec import add, any_positive, dot, hadamard, inline_function, kernel_function, mul, row3, sub
from .bdpt_glint import GLINT_COUNT, glint_sample, pixel_weight, through_delta_only
from .bdpt_mis import mis_weight
from .bdpt_vertex import (
    CAMERA,
    F_DELTA_LIGHT,
    F_EMISSIVE,
    F_INFINITE,
    F_ON_SURFACE,
    LIGHT,
    SURFACE,
    V_BETA,
    V_DIR,
    V_E,
    V_HIT,
    V_M,
    V_NG,
    V_P,
    V_PDF_FWD,
    V_WIDTH,
    connectible,
    cosine_at,
    has_flag,
    is_light,
    kind_of,
    medium_towards,
    pdf_light_origin,
    put_vertex,
    toward,
    vertex_f,
)
from .bdpt_walk import camera_subpath, light_subpath
from .shadow import shadow_ray, shadow_transmittance

INF = math.inf
MAX_SEGMENTS = 64  # unlimited max_depth: subpaths end by Russian roulette, or here
GLINT_ONLY = -2  # the strategy switch's s for the glint strategy alone (bdpt_setup.strategy_switch)
NO_GLINT = -3  # ... and for every strategy but the glint strategy
DIM_CONNECT_LIGHT = np.uint64(0x5A3D11E1)  # s = 1: the light point of each camera vertex
DIM_CONNECT_LENS = np.uint64(0x1E25C0DE)  # t = 1: the lens point of each light vertex
DIM_CONNECT_MEDIUM = np.uint64(0x5AD0B1D1)  # ratio tracking along each strategy's connection
ZERO = (0.0, 0.0, 0.0)
ONE = (1.0, 1.0, 1.0)
SAVED = 0  # the scratch row where a subpath's vertex waits while a sampled one takes its place


@kernel_function
def _transmitted(C, A, i, w, d2, key, node_stack, t_stack):
    """The fraction of light (RGB) that passes the segment from A[i] along unit w (squared
    length d2, inf: to infinity): 0 or 1 by any_hit, or where the scene has media or null
    boundaries, their transmittance (path mode's shadow rays, shadow.py) from the medium the
    segment starts in. Offsets from surfaces as path mode's shadow rays; the far end shortened
    by SHADOW_SHORTEN."""
    o = row3(A, i, V_P)
    dist = math.sqrt(d2) if d2 < INF else INF
    leaving = np.int64(NO_HIT)  # the surface the segment leaves, offset towards w (traverse.py)
    if kind_of(A, i) == SURFACE or has_flag(A, i, F_ON_SURFACE):
        ng = row3(A, i, V_NG)
        eps = offset_epsilon(C.F.epsilon_floor, o)
        # aimed from the offset point at the far end (shadow.shadow_ray: aimed from the vertex, a
        # grazing segment crossed the far end's surface before its shortened end)
        o, w, tmax = shadow_ray(o, ng, eps if dot(w, ng) > 0.0 else -eps, w, dist)
        leaving = np.int64(A[i, V_HIT])
    else:
        tmax = dist * (1.0 - SHADOW_SHORTEN)  # inf for inf
    # quad and sphere lights (not in the BVH) stop the segment, as they stop path mode's rays,
    # its shadow rays and the subpaths (bdpt_walk.py): light behind a sphere light does not
    # pass it (the segment's ends are shortened off the light it may end on)
    if area_light_blocks(C.Em, -1, o, w, tmax):
        return ZERO
    Md = C.Md
    if Md.pass_through:
        med = medium_towards(C, A, i, w)
        return shadow_transmittance(C.G, C.F, C.X, Md, o, w, tmax, med, key, node_stack, t_stack)
    if any_hit_leaving(C.G, C.X, o, w, 0.0, tmax, leaving, node_stack, t_stack):
        return ZERO
    return ONE


@inline_function
def _connection_key(key, s, t):
    """Ratio tracking's random numbers along strategy (s, t)'s connection."""
    return sub_key(dimension_key(key, DIM_CONNECT_MEDIUM, s), t)


@kernel_function
def _self_hidden(C, A, i, e, n, w):
    """Does area light e, which is not in the BVH (quad and sphere lights), hide its own point of
    normal n seen along w from A[i] (the far side of a sphere light)?"""
    if e >= C.Em.n_area:
        return False
    return hides_own_point(C.Em, e, row3(A, i, V_P), n, w)


@kernel_function
def _own_sphere_hides(C, hit, q, p, near):
    """Does the sphere that a connection's far end q lies on (`hit`: its primitive; NO_HIT, the
    near end's own primitive `near` or another shape: no) hide q from the near end p, as a
    sphere light hides its far side (shape_sphere.sphere_hides_point)? The segment stops
    SHADOW_SHORTEN of its length short of q, so a sphere smaller than that is not met on its
    near side: its far side, and the light subpaths' vertices inside an emissive sphere, shone
    through it (a white emissive sphere of radius 1e-5, half a unit above a floor: the floor 10x
    path mode's)."""
    if hit == NO_HIT or hit == near:
        return False
    G = C.G
    k, inst = split_hit(C.X, hit)
    if inst >= 0 or G.prims[k, PRIM_KIND] != SPHERE:
        return False
    row = np.int64(G.prims[k, PRIM_ROW])
    centre = row3(G.shapes, row, shape_sphere.CENTER)
    return shape_sphere.sphere_hides_point(centre, G.shapes[row, shape_sphere.RADIUS], p, sub(q, centre), sub(q, p))


@kernel_function
def _into(C, A, i, w, d2):
    """Does a connection leave surface vertex A[i] along w into a dielectric's inside?"""
    if kind_of(A, i) != SURFACE or not (d2 < INF):
        return False
    return not two_sided(C.F.materials, int(A[i, V_M])) and dot(w, row3(A, i, V_NG)) < 0.0


@kernel_function
def _absorbed(C, A, i, w, d2, value):
    """value attenuated over a connection that leaves A[i] along w into a dielectric's inside
    (Beer-Lambert, as path mode's segments inside one)."""
    if not _into(C, A, i, w, d2):
        return value
    return beer_lambert(C.F.materials, int(A[i, V_M]), value, math.sqrt(d2))


@kernel_function
def _emitted(C, Vc, pt):
    """Radiance that camera vertex Vc[pt], a light, sends back along its subpath (s = 0)."""
    if kind_of(Vc, pt) == LIGHT:
        if has_flag(Vc, pt, F_INFINITE):
            d = row3(Vc, pt, V_DIR)
            le = environment_light(C.Env, d)
            if C.Em.ambient_row >= 0:
                le = add(le, row3(C.Em.data, C.Em.ambient_row, LIGHT_INTENSITY))
            return le
        return row3(C.Em.data, int(Vc[pt, V_E]), LIGHT_INTENSITY)
    if has_flag(Vc, pt, F_EMISSIVE):
        return row3(C.F.materials, int(Vc[pt, V_M]), MAT_EMISSION)
    return ZERO


@kernel_function
def _copy_row(A, i, B, k):
    for c in range(V_WIDTH):
        B[k, c] = A[i, c]


@kernel_function
def connect(C, Vc, Vl, saved, s, t, key, mis, node_stack, t_stack):
    """Strategy (s, t >= 2): (radiance for the pixel, rays traced)."""
    pt = t - 1
    if s > 0 and kind_of(Vc, pt) == LIGHT:
        return ZERO, 0
    beta_c = row3(Vc, pt, V_BETA)
    if s == 0:
        if not is_light(Vc, pt):
            return ZERO, 0
        value = hadamard(beta_c, _emitted(C, Vc, pt))
        if not any_positive(value):
            return ZERO, 0
        if not mis:
            return value, 0
        if kind_of(Vc, pt) == SURFACE and Vc[pt, V_E] < 0:
            return value, 0  # an emitter no light strategy samples: only s = 0 finds it
        return mul(value, mis_weight(C, Vc, Vl, 0, t)), 0
    if not connectible(C.F, Vc, pt):
        return ZERO, 0
    if s == 1:
        return _connect_light(C, Vc, Vl, saved, t, key, mis, node_stack, t_stack)
    qs = s - 1
    if not connectible(C.F, Vl, qs):
        return ZERO, 0
    w, d2 = toward(Vc, pt, Vl, qs)
    if not (d2 > 0.0):
        return ZERO, 0
    f_c = vertex_f(C.F, Vc, pt, w, False)
    if not any_positive(f_c):
        return ZERO, 0
    f_l = vertex_f(C.F, Vl, qs, mul(w, -1.0), True)
    g = cosine_at(Vc, pt, w) * cosine_at(Vl, qs, w) / d2
    value = mul(hadamard(hadamard(beta_c, f_c), hadamard(f_l, row3(Vl, qs, V_BETA))), g)
    if not any_positive(value):
        return ZERO, 0
    if _own_sphere_hides(C, np.int64(Vl[qs, V_HIT]), row3(Vl, qs, V_P), row3(Vc, pt, V_P), np.int64(Vc[pt, V_HIT])):
        return ZERO, 0
    tr = _transmitted(C, Vc, pt, w, d2, _connection_key(key, s, t), node_stack, t_stack)
    if not any_positive(tr):
        return ZERO, 1
    value = hadamard(value, tr)
    # a segment inside a dielectric: both its ends are on the inside; absorb once
    if _into(C, Vl, qs, mul(w, -1.0), d2):
        value = _absorbed(C, Vl, qs, mul(w, -1.0), d2, value)
    else:
        value = _absorbed(C, Vc, pt, w, d2, value)
    if mis:
        value = mul(value, mis_weight(C, Vc, Vl, s, t))
    return value, 1


@kernel_function
def _connect_light(C, Vc, Vl, saved, t, key, mis, node_stack, t_stack):
    """Strategy (1, t): a point on a light (picked by power, placed as a light subpath's first
    vertex would be: each kind's `emit`) joined to camera vertex t - 1."""
    G, F, X, Em, Env = C.G, C.F, C.X, C.Em, C.Env
    if not (Em.cdf[Em.cdf.shape[0] - 1] > 0.0):
        return ZERO, 0
    pt = t - 1
    k = dimension_key(key, DIM_CONNECT_LIGHT, t)
    u_pick, _ = key_uniform2(k)
    u1, u2 = ld_uniform2(key, DIM_CONNECT_LIGHT, t)
    u3, u4 = key_uniform2(sub_key(k, 2))
    e, p_pick = pick_emitter(Em.cdf, u_pick)
    p, n, w_emit, le, pdf_pos, pdf_dir, hit = sample_emission(G, X, Em, Env, e, u1, u2, u3, u4, k, C.B)
    kind = Em.kind[e]
    infinite = at_infinity(kind)
    delta = is_delta(kind)
    surface_point = not infinite and not delta
    flags = (F_INFINITE if infinite else 0) | (F_DELTA_LIGHT if delta else 0) | (F_ON_SURFACE if surface_point else 0)
    _copy_row(Vl, 0, saved, SAVED)
    put_vertex(Vl, 0, LIGHT, p, n, n, w_emit, le, 0.0, -1, e, ZERO, hit, flags)
    if infinite:
        for c in range(3):
            Vl[0, V_DIR + c] = -w_emit[c]
    value = ZERO
    rays = 0
    w, d2 = toward(Vc, pt, Vl, 0)
    if infinite:
        ok = pdf_dir > 0.0 and p_pick > 0.0
        light = mul(le, 1.0 / (p_pick * pdf_dir)) if ok else ZERO
    else:
        ok = d2 > 0.0 and pdf_pos > 0.0 and p_pick > 0.0
        light = ZERO
        if ok:
            le, _, _ = emission_pdf(G, X, Em, Env, e, p, n, mul(w, -1.0), hit, C.B)
            cos_l = abs(dot(n, w)) if surface_point else 1.0
            light = mul(le, cos_l / (p_pick * pdf_pos * d2))
    if ok and any_positive(light):
        f = vertex_f(F, Vc, pt, w, False)
        value = hadamard(hadamard(row3(Vc, pt, V_BETA), f), mul(light, cosine_at(Vc, pt, w)))
        if any_positive(value):
            rays = 1
            tr = _transmitted(C, Vc, pt, w, d2, _connection_key(key, 1, t), node_stack, t_stack)
            hidden = _self_hidden(C, Vc, pt, e, n, w) or _own_sphere_hides(
                C, hit, p, row3(Vc, pt, V_P), np.int64(Vc[pt, V_HIT])
            )
            if any_positive(tr) and not hidden:
                value = _absorbed(C, Vc, pt, w, d2, hadamard(value, tr))
                if mis:
                    Vl[0, V_PDF_FWD] = pdf_light_origin(C, Vl, 0, Vc, pt)
                    value = mul(value, mis_weight(C, Vc, Vl, 1, t))
            else:
                value = ZERO
    _copy_row(saved, SAVED, Vl, 0)
    return value, rays


@kernel_function
def connect_camera(C, Vc, Vl, saved, s, key, mis, node_stack, t_stack):
    """Strategy (s >= 2, 1): light vertex s - 1 seen from a point on the lens. Returns (the
    value to splat, image x, y, rays traced); value 0 when it reaches no pixel."""
    qs = s - 1
    if not connectible(C.F, Vl, qs):
        return ZERO, -1.0, -1.0, 0
    cam = C.cam
    u1, u2 = ld_uniform2(key, DIM_CONNECT_LENS, s)
    pl = lens_point(cam, u1, u2)
    f_axis = (cam[CAM_FORWARD], cam[CAM_FORWARD + 1], cam[CAM_FORWARD + 2])
    _copy_row(Vc, 0, saved, SAVED)
    put_vertex(Vc, 0, CAMERA, pl, f_axis, f_axis, f_axis, (1.0, 1.0, 1.0), 1.0, -1, -1, ZERO, -1, 0)
    w, d2 = toward(Vl, qs, Vc, 0)  # from the light vertex towards the lens
    value = ZERO
    x = -1.0
    y = -1.0
    rays = 0
    if d2 > 0.0:
        we, _, x, y = camera_importance(cam, C.width, C.height, pl, mul(w, -1.0))
        cos_lens = abs(dot(f_axis, w))
        if we > 0.0 and cos_lens > 0.0:
            # the lens point's solid-angle density seen from the vertex: d2 / (cos lens_area)
            beta_cam = we * cos_lens * lens_area(cam) / d2
            f = vertex_f(C.F, Vl, qs, w, True)
            value = mul(hadamard(row3(Vl, qs, V_BETA), f), cosine_at(Vl, qs, w) * beta_cam)
            if any_positive(value):
                rays = 1
                for c in range(3):
                    Vc[0, V_BETA + c] = beta_cam
                tr = _transmitted(C, Vl, qs, w, d2, _connection_key(key, s, 1), node_stack, t_stack)
                if any_positive(tr):
                    value = _absorbed(C, Vl, qs, w, d2, hadamard(value, tr))
                    if mis:
                        value = mul(value, mis_weight(C, Vc, Vl, s, 1))
                else:
                    value = ZERO
    _copy_row(saved, SAVED, Vc, 0)
    return value, x, y, rays


@kernel_function
def bdpt_sample(
    C, Vc, Vl, saved, o, d, spread, key, inside, depth, strategy, splats, window, filt, counts, px, py,
    node_stack, t_stack,
):  # fmt: skip
    """One camera sample of pixel (px, py): its light subpath, splatted where the camera sees it
    (t = 1), the glint strategy's sample (splatted, bdpt_glint.py), and when the pixel is in the
    window (`inside`) its camera subpath and every other strategy. Returns (radiance for the
    pixel, rays traced, splats refused as not finite)."""
    most = depth if depth >= 0 else MAX_SEGMENTS
    s_only, t_only, mis_flag = strategy
    mis = mis_flag != 0
    rays = 0
    refused = 0
    glints = C.glint.shape[0] > 1
    if glints and (s_only == -1 or s_only == GLINT_ONLY):
        used, added, bad = glint_sample(C, key, most, splats, window, node_stack, t_stack)
        rays += used
        refused += bad
        counts[GLINT_COUNT] += added
    if s_only == GLINT_ONLY:
        return ZERO, rays, refused
    n_light, used = light_subpath(C, Vl, most, key, node_stack, t_stack)
    rays += used
    for s in range(2, min(n_light, most) + 1):
        if s_only >= 0 and not (s == s_only and t_only == 1):
            continue
        value, x, y, used = connect_camera(C, Vc, Vl, saved, s, key, mis, node_stack, t_stack)
        rays += used
        if any_positive(value):
            if splat(splats, window, filt, x, y, value):
                counts[s, 1] += 1
            else:
                refused += 1
    L = ZERO
    if not inside:
        return L, rays, refused
    n_camera, used, backdrop = camera_subpath(C, Vc, most, o, d, spread, key, node_stack, t_stack)
    rays += used
    if backdrop and (s_only < 0 or (s_only == 0 and t_only == 2)):
        L = C.background
    for t in range(2, n_camera + 1):
        for s in range(0, n_light + 1):
            segments = s + t - 1
            if segments > most:
                break
            if s_only >= 0 and not (s == s_only and t == t_only):
                continue
            value, used = connect(C, Vc, Vl, saved, s, t, key, mis, node_stack, t_stack)
            rays += used
            if s == 0 and mis and glints and any_positive(value) and through_delta_only(Vc, t - 1):
                value = mul(value, pixel_weight(C, Vc, px, py))  # shared with the glint strategy
            if any_positive(value):
                counts[s, t] += 1
                L = add(L, value)
    return L, rays, refused
