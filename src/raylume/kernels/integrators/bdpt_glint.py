"""Glints: camera paths that see an emitter through delta surfaces alone (camera - lens - lens -
mirror - bulb), a strategy of bidirectional path tracing beside Veach's (s, t).

Every vertex of such a path but the emitter is a mirror or glass, so no light subpath or
connection can make it: only s = 0 does, by a pixel's own samples meeting the emitter's image.
Where that image is smaller than a pixel (a head lamp's bulb in its reflector, seen from the
side) one sample in many finds it, worth many times the pixel's mean: fireflies that the other
strategies cannot lower, path mode's noise at bdpt's cost a sample. This strategy samples the
film where a guide says such paths are, instead of only pixel by pixel:

* **The guide** (`glint_guide`, once per image): a few pilot camera samples per pixel follow
  the camera ray through delta surfaces; each delta vertex scores how nearly its outgoing ray
  heads for a point sampled on an emitter (a cone of COS_RELAX, weighted by the throughput and
  the emitter's radiance), and an emitter met after a delta vertex scores its radiance. Per
  pixel the scores sum to the guide: a density q over the film (per unit pixel area), made of
  its own random numbers, the same on any threads or machines. It only steers where the
  strategy samples: any guide leaves the image unbiased.
* **The strategy** (`glint_sample`): each camera sample of every pixel also takes one film
  point x from the guide (its pixel by the guide's cdf, uniform inside it) and follows its ray
  through delta surfaces as the camera subpath would (the same shading, absorption, offsets and
  cone; no Russian roulette). An emitter met after at least one delta vertex is splatted to the
  pixels j around x: f_j(x) L / (f_j(x) + R q(x)), f_j the density at x of pixel j's own sample
  positions (`fis_density`) and R = width x height (the strategy's samples per sample per
  pixel).
* **The weights.** A pixel's own sample at x whose camera subpath is such a path (s = 0 through
  delta, non-emissive vertices, ending on an emitter that is not at infinity) takes the weight
  f_j(x) / (f_j(x) + R q(x)). With the strategy's, the two sum to one for every path of the
  class (the balance heuristic of the pixel's samples and the strategy's, counted per unit film
  area), so the image converges to the same as without it.

Scenes with media or null boundaries, images of 1 sample per pixel (a pixel's centre, not its
filtered area), filters with negative lobes, and the strategy switch's unweighted strategies
and "noglint" take no guide (bdpt_setup.glint_cdf): their images are those of bdpt without this
strategy, bit for bit. `RAYLUME_BDPT_STRATEGY=glint` renders its share alone."""

import math

import numpy as np

from ..film.camera import CAM_CONE_SPREAD, CAM_LENS_RADIUS, camera_importance, camera_ray, obliquity, thin_lens_ray
from ..film.film import FILTER_BOX, FILTER_KIND, FILTER_TABLE, FILTER_TABLE_SIZE
from ..film.sampler import dimension_key, key_uniform2, sample_key, sub_key
from ..film.splat import splat_finite, splat_pixel
from ..geometry.shapes import NO_HIT, offset_epsilon, surface
from ..geometry.traverse import closest_hit_leaving
from ..shading.frame import shading_frame, to_local, to_world
from ..shading.lights import LIGHT_INTENSITY, at_infinity, hit_area_lights, is_delta, pick_emitter
from ..shading.materials import MAT_EMISSION, albedo, beer_lambert, bsdf_sample, two_sided
from ..shading.normal_map import mapped_normal
from ..vec import any_positive, dot, hadamard, kernel_function, last_at_most, madd, mul, row3, sub
from .bdpt_vertex import F_EMISSIVE, F_INFINITE, V_DELTA, V_FLAGS, V_P
from .bdpt_walk import emitter_sample

INF = math.inf
DIM_GLINT = np.uint64(0x611E7C0D)  # the strategy's film point (and lens point)
DIM_GLINT_WALK = np.uint64(0x611E7A1C)  # its delta samples, per vertex
DIM_PILOT = np.uint64(0x91107)  # a pilot sample's film point
GUIDE_SEED = np.uint64(0x6A1DE5EED)  # the pilot samples' keys: sample_key(seed ^ this, pixel, k)
DIM_GUIDE_LIGHT = np.uint64(0x6A1DE11E)  # a pilot's point on an emitter
PILOTS = 16  # pilot samples per pixel
PILOTS_FIRST = 4  # ... of which a pixel without delta surfaces takes these
COS_RELAX = math.cos(0.5)  # a delta vertex scores when its ray passes this near the light point
GLINT_COUNT = (0, 0)  # the strategy counts' slot of this strategy (no (s, t) has t = 0)
ONE = (1.0, 1.0, 1.0)
ZERO = (0.0, 0.0, 0.0)


@kernel_function
def glint_walk(C, o, d, spread, most, key, target, le_target, node_stack, t_stack):
    """The camera ray (o, d) followed through delta surfaces, at most `most` segments: (the
    radiance of the emitter it meets after at least one delta vertex, or 0; the guide's score
    towards the light point `target` with radiance le_target (0 for none); rays traced)."""
    G, F, X, Em = C.G, C.F, C.X, C.Em
    mat = F.materials
    beta = ONE
    score = 0.0
    cone = 0.0
    rays = 0
    leaving = np.int64(NO_HIT)
    aim = any_positive(le_target)
    for i in range(1, most + 1):  # vertex i of the camera subpath
        t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, INF, leaving, node_stack, t_stack)
        rays += 1
        el = -1
        if Em.n_area > 0:
            _, el, _ = hit_area_lights(Em, o, d, t)
        if el >= 0:  # an area light ends the ray
            if i > 1:
                return hadamard(beta, row3(Em.data, el, LIGHT_INTENSITY)), score, rays
            break
        if prim == NO_HIT:
            break
        p = madd(o, d, t)
        ng, ns, m, _, _ = surface(G, X, prim, b1, b2, p)
        ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
        entering = dot(ng, d) < 0.0
        if not entering:
            beta = beer_lambert(mat, m, beta, t)
        cone += spread * t
        emission = row3(mat, m, MAT_EMISSION)
        if any_positive(emission):  # the path ends at its first emitter (an emitter is no delta vertex here)
            if i > 1:
                return hadamard(beta, emission), score, rays
            break
        colour = albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone)
        two = two_sided(mat, m)
        ng, ns, s_axis, t_axis = shading_frame(two, not entering, ng, ns)
        wo = to_local(mul(d, -1.0), s_axis, t_axis, ns)
        k2 = dimension_key(key, DIM_GLINT_WALK, i)
        u0, u1 = key_uniform2(k2)
        u2, _ = key_uniform2(sub_key(k2, 1))
        wi, weight, pdf, delta = bsdf_sample(mat, m, colour, wo, u0, u1, u2)
        if not delta or not (pdf > 0.0) or not any_positive(weight):
            break
        wi_w = to_world(wi, s_axis, t_axis, ns)
        up = dot(wi_w, ng) > 0.0
        if two and not up:
            break
        beta = hadamard(beta, weight)
        if aim:
            w = sub(target, p)
            dist = math.sqrt(dot(w, w))
            if dist > 0.0:
                c = dot(wi_w, w) / dist
                if c > COS_RELAX:
                    near = (c - COS_RELAX) / (1.0 - COS_RELAX)
                    glow = hadamard(beta, le_target)
                    score += near * (glow[0] + glow[1] + glow[2])
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, ng, eps if up else -eps)
        leaving = prim
        d = wi_w
    return ZERO, score, rays


@kernel_function
def film_ray(cam, x, y, width, height, u1, u2):
    """The camera ray through image point (x, y), from the lens point of (u1, u2) with an
    aperture: as camera_sample makes it."""
    o, d = camera_ray(cam, x, y, width, height)
    if cam[CAM_LENS_RADIUS] > 0.0:
        o, d = thin_lens_ray(cam, o, d, u1, u2)
    return o, d


@kernel_function
def _pilot_light(C, key):
    """A point on an emitter with a surface (area lights, emissive shapes) and its radiance, for
    a pilot sample; radiance 0 when the pick is another kind."""
    Em = C.Em
    if not (Em.cdf[Em.cdf.shape[0] - 1] > 0.0):
        return ZERO, ZERO
    e, _, p, _, _, le, pdf_pos, _, _ = emitter_sample(C, key, DIM_GUIDE_LIGHT)
    kind = Em.kind[e]
    if at_infinity(kind) or is_delta(kind) or not (pdf_pos > 0.0):
        return ZERO, ZERO
    return p, le


@kernel_function
def glint_guide(C, seed, most, guide, rows, node_stack, t_stack):
    """Fill rows rows[0] .. rows[1] - 1 of guide (float64 (height, width)) with each pixel's
    score (module docstring); returns the rays traced. A pixel whose first PILOTS_FIRST pilots
    all stop at their first hit (no delta surface there) takes no more: the 3 x 3 spread of the
    guide (bdpt_setup) covers a glint at its edge, and most pixels of most scenes cost a quarter."""
    cam = C.cam
    width, height = C.width, C.height
    spread = cam[CAM_CONE_SPREAD]
    rays = 0
    for j in range(rows[0], rows[1]):
        for i in range(width):
            total = 0.0
            deltas = False
            for s in range(PILOTS):
                if s == PILOTS_FIRST and not deltas:
                    break
                key = sample_key(np.uint64(seed) ^ GUIDE_SEED, j * width + i, s)
                ux, uy = key_uniform2(dimension_key(key, DIM_PILOT, 0))
                u1, u2 = key_uniform2(sub_key(key, 1))
                o, d = film_ray(cam, i + ux, j + uy, width, height, u1, u2)
                target, le = _pilot_light(C, key)
                value, score, used = glint_walk(
                    C, o, d, spread * obliquity(cam, d), most, key, target, le, node_stack, t_stack
                )
                rays += used
                deltas = deltas or used > 1
                total += score + value[0] + value[1] + value[2]
            guide[j, i] = total
    return rays


@kernel_function
def glint_sample(C, key, most, splats, window, node_stack, t_stack):
    """The strategy's sample of one camera sample: a film point from the guide's cdf (C.glint),
    its ray through delta surfaces, what it finds splatted (module docstring). Returns (rays
    traced, 1 if it added a splat, 1 if a splat was refused as not finite)."""
    cdf = C.glint
    cam = C.cam
    width, height = C.width, C.height
    k = dimension_key(key, DIM_GLINT, 0)
    u_pick, u_x = key_uniform2(k)
    u_y, u_1 = key_uniform2(sub_key(k, 1))
    u_2, _ = key_uniform2(sub_key(k, 2))
    pix, share = pick_emitter(cdf, u_pick)
    x = pix % width + u_x
    y = pix // width + u_y
    o, d = film_ray(cam, x, y, width, height, u_1, u_2)
    spread = cam[CAM_CONE_SPREAD] * obliquity(cam, d)
    value, _, rays = glint_walk(C, o, d, spread, most, k, ZERO, ZERO, node_stack, t_stack)
    if not any_positive(value):
        return rays, 0, 0
    if not splat_finite(value):
        return rays, 0, 1
    # to each pixel whose samples could land at (x, y): its density there over the sum of the
    # two strategies' (the balance heuristic), times the radiance over the strategy's density
    rq = width * height * share
    x0, y0, x1, y1 = window
    r = -C.pixel_filter[FILTER_TABLE]  # the filter's radius (the table's first offset)
    for py in range(max(int(math.floor(y - r)), y0), min(int(math.floor(y + r)) + 1, y1)):
        fy = fis_density(C.pixel_filter, y - (py + 0.5))
        if fy == 0.0:
            continue
        for px in range(max(int(math.floor(x - r)), x0), min(int(math.floor(x + r)) + 1, x1)):
            f = fy * fis_density(C.pixel_filter, x - (px + 0.5))
            if f > 0.0:
                splat_pixel(splats, window, px, py, value, f / (f + rq))
    return rays, 1, 0


@kernel_function
def fis_density(filt, d):
    """The density of a pixel's sample offsets along one axis at offset d from its centre, as
    film.filter_sample places them: uniform for the box, else the tabulated inverse cdf's
    (piecewise constant). The weights need the density the pixel's samples really have: the
    filter's own curve differs from it where the table is coarse (a gaussian's tails)."""
    if filt[FILTER_KIND] == FILTER_BOX:
        return 1.0 if d >= -0.5 and d < 0.5 else 0.0
    n = FILTER_TABLE_SIZE
    if not (d >= filt[FILTER_TABLE] and d < filt[FILTER_TABLE + n - 1]):
        return 0.0
    k = last_at_most(filt, FILTER_TABLE, n, d)
    width = filt[FILTER_TABLE + k + 1] - filt[FILTER_TABLE + k]
    return 1.0 / ((n - 1) * width) if width > 0.0 else 0.0


@kernel_function
def through_delta_only(Vc, pt):
    """Whether camera vertices 1 .. pt - 1 (pt >= 2) are all delta and none emits, and vertex pt
    is not a light at infinity: the class of paths this strategy samples too, when vertex pt
    emits (s = 0). Asked only where the image has a guide (bdpt_sample)."""
    if pt < 2 or (int(Vc[pt, V_FLAGS]) & F_INFINITE) != 0:
        return False
    for i in range(1, pt):
        if Vc[i, V_DELTA] == 0.0 or (int(Vc[i, V_FLAGS]) & F_EMISSIVE) != 0:
            return False
    return True


@kernel_function
def pixel_weight(C, Vc, px, py):
    """The balance heuristic's weight of pixel (px, py)'s own sample for a path this strategy
    could make: |f(x)| / (|f(x)| + R q(x)), x the image point of its camera ray (Vc[0] to
    Vc[1])."""
    cdf = C.glint
    width, height = C.width, C.height
    w = sub(row3(Vc, 1, V_P), row3(Vc, 0, V_P))
    n = math.sqrt(dot(w, w))
    if not (n > 0.0):
        return 1.0
    _, _, x, y = camera_importance(C.cam, width, height, row3(Vc, 0, V_P), mul(w, 1.0 / n))
    if not (x >= 0.0 and y >= 0.0 and x < width and y < height):
        return 1.0
    pix = int(y) * width + int(x)
    rq = width * height * (cdf[pix + 1] - cdf[pix]) / cdf[cdf.shape[0] - 1]
    f = fis_density(C.pixel_filter, x - (px + 0.5)) * fis_density(C.pixel_filter, y - (py + 0.5))
    if not (f + rq > 0.0):
        return 1.0
    return f / (f + rq)
