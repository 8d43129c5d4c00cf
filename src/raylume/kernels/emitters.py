"""Emitters: what path mode samples as light, in radiometric units (DESIGN.md section 6).

One table, float64 (E, EMIT_WIDTH), with a kind per row (int32 (E,)) and a cumulative
distribution (float64 (E + 1,)) that picks a row in proportion to its power. Rows, in order:

* area lights (`quad`, `sphere` lights): surfaces of radiance `intensity`, emitting on both
  sides, visible to rays (`hit_area_lights` tests them beside the BVH: trace mode does not see
  them) — first, so the ray test loops over rows 0..n_area-1 only;
* point and spot lights (radiant intensity, W/sr, 1/r^2 falloff) and directional lights
  (irradiance on a surface facing them): the lights.py columns, copied;
* emissive primitives: triangles, spheres, quads and disks whose material has `emission`
  (the primitive table's PRIM_LIGHT column points back here, for MIS when a ray hits them);
* the environment, when the scene has one (one row; environment.py samples it).

Ambient lights are a uniform environment in path mode: their radiances summed in one row
(kind lights.AMBIENT), sampled uniformly over the sphere.
`sample_emitter` returns a direction, its distance, the arriving radiance (or intensity over
r^2 for the delta lights) and the solid-angle pdf; `emitter_pdf` is that pdf for a direction
that a BSDF sample happened to find, for multiple importance sampling.
"""

import math

import numpy as np
from numba import njit

from . import shape_sphere
from .environment import environment_pdf, environment_radiance, sample_environment
from .lights import (
    AMBIENT,
    DIRECTIONAL,
    LIGHT_INTENSITY,
    LIGHT_POSITION,
    LIGHT_RADIUS,
    LIGHT_U,
    LIGHT_V,
    LIGHT_WIDTH,
    POINT,
    QUAD,
    SPHERE,
    SPOT,
    basis,
    spot_falloff,
)
from .sampler import uniform_sphere
from .shape_plane import intersect_plane
from .shape_sphere import intersect_sphere
from .shapes import PRIM_KIND, PRIM_ROW, sample_surface
from .shapes import SPHERE as SHAPE_SPHERE
from .vec import KERNEL, cross, dot, length, madd, mul, normalize, row3, sub

INF = math.inf

PRIMITIVE = 6  # an emissive primitive of the scene's geometry
ENVIRONMENT = 7

EMIT_PRIM = LIGHT_WIDTH  # PRIMITIVE rows: the primitive's index in the primitive table
EMIT_AREA = LIGHT_WIDTH + 1  # its area
EMIT_WIDTH = LIGHT_WIDTH + 2

# Shadow rays towards a sampled point stop this fraction short of it (the emitter itself
# must not count as a blocker).
SHADOW_SHORTEN = 1e-5


@njit(**KERNEL)
def pick_emitter(cdf, u):
    """The row whose share of the cdf holds u, and the probability of picking it."""
    n = cdf.shape[0] - 1
    lo = 0
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[mid] <= u * cdf[n]:
            lo = mid
        else:
            hi = mid
    return lo, (cdf[lo + 1] - cdf[lo]) / cdf[n]


@njit(**KERNEL, inline="always")
def pick_probability(cdf, e):
    return (cdf[e + 1] - cdf[e]) / cdf[cdf.shape[0] - 1]


@njit(**KERNEL)
def _sphere_cone(centre, radius, p, u1, u2):
    """A direction towards the sphere, uniform over the cone it subtends from p (pbrt), its
    distance and pdf; from inside, a uniform point on the sphere (pdf converted)."""
    to_c = sub(centre, p)
    dist2 = dot(to_c, to_c)
    if dist2 <= radius * radius * (1.0 + 1e-9):
        n = uniform_sphere(u1, u2)
        q = madd(centre, n, radius)
        to_q = sub(q, p)
        dist = length(to_q)
        if dist <= 0.0:
            return (0.0, 0.0, 1.0), 0.0, 0.0
        return mul(to_q, 1.0 / dist), dist, _area_pdf(p, q, n, 4.0 * math.pi * radius * radius)
    dc = math.sqrt(dist2)
    w = mul(to_c, 1.0 / dc)
    sin2_max = radius * radius / dist2
    cos_max = math.sqrt(max(0.0, 1.0 - sin2_max))
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * math.pi * u2
    e1, e2 = basis(w)
    wi = normalize(madd(madd(mul(w, cos_t), e1, sin_t * math.cos(phi)), e2, sin_t * math.sin(phi)))
    dist = intersect_sphere(p, wi, centre, radius, 0.0, INF)
    if dist == INF:  # a direction on the cone's rim, missed by rounding: the tangent point
        dist = dot(wi, to_c)
    return wi, dist, 1.0 / (2.0 * math.pi * (1.0 - cos_max))


@njit(**KERNEL)
def _sphere_cone_pdf(centre, radius, p, wi, dist):
    to_c = sub(centre, p)
    dist2 = dot(to_c, to_c)
    if dist2 <= radius * radius * (1.0 + 1e-9):
        q = madd(p, wi, dist)
        return _area_pdf(p, q, normalize(sub(q, centre)), 4.0 * math.pi * radius * radius)
    cos_max = math.sqrt(max(0.0, 1.0 - radius * radius / dist2))
    return 1.0 / (2.0 * math.pi * (1.0 - cos_max))


@njit(**KERNEL, inline="always")
def _area_pdf(p, q, n, area):
    """Solid-angle pdf at p of a point q (normal n) sampled uniformly on a surface of `area`."""
    to_q = sub(q, p)
    dist2 = dot(to_q, to_q)
    cos_l = abs(dot(n, to_q)) / math.sqrt(dist2) if dist2 > 0.0 else 0.0
    if cos_l <= 0.0 or area <= 0.0:
        return 0.0
    return dist2 / (area * cos_l)


# Inlined (one call site): a call passed the Geometry, Emitters and Environment views by value,
# which cost more than the sampling (148 vs 84 ns on the Cornell box's light).
@njit(**KERNEL, inline="always")
def sample_emitter(G, Em, Env, e, p, u1, u2):
    """Emitter row e seen from p: (unit direction wi, distance (inf: at infinity), radiance
    arriving along wi (delta lights: intensity / r^2 or irradiance), solid-angle pdf (0: no
    sample), delta)."""
    kind = Em.kind[e]
    data = Em.data
    if kind == POINT or kind == SPOT:
        to_l = sub(row3(data, e, LIGHT_POSITION), p)
        dist = length(to_l)
        if dist <= 0.0:
            return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, True
        wi = mul(to_l, 1.0 / dist)
        scale = 1.0 / (dist * dist)
        if kind == SPOT:
            scale *= spot_falloff(data, e, wi)
        return wi, dist, mul(row3(data, e, LIGHT_INTENSITY), scale), 1.0, True
    if kind == DIRECTIONAL:
        return row3(data, e, LIGHT_POSITION), INF, row3(data, e, LIGHT_INTENSITY), 1.0, True
    if kind == ENVIRONMENT:
        wi, radiance, pdf = sample_environment(Env, u1, u2)
        return wi, INF, radiance, pdf, False
    if kind == AMBIENT:
        return uniform_sphere(u1, u2), INF, row3(data, e, LIGHT_INTENSITY), 0.25 / math.pi, False
    radiance = row3(data, e, LIGHT_INTENSITY)
    if kind == SPHERE or (kind == PRIMITIVE and G.prims[int(data[e, EMIT_PRIM]), PRIM_KIND] == SHAPE_SPHERE):
        if kind == SPHERE:
            centre = row3(data, e, LIGHT_POSITION)
            radius = data[e, LIGHT_RADIUS]
        else:
            row = np.int64(G.prims[int(data[e, EMIT_PRIM]), PRIM_ROW])
            centre = row3(G.shapes, row, shape_sphere.CENTER)
            radius = G.shapes[row, shape_sphere.RADIUS]
        wi, dist, pdf = _sphere_cone(centre, radius, p, u1, u2)
        return wi, dist, radiance, pdf, False
    if kind == QUAD:
        u = row3(data, e, LIGHT_U)
        v = row3(data, e, LIGHT_V)
        q = madd(madd(row3(data, e, LIGHT_POSITION), u, u1 - 0.5), v, u2 - 0.5)
        n = cross(u, v)
        area = length(n)
        n = mul(n, 1.0 / area)
    else:
        q, n = sample_surface(G, int(data[e, EMIT_PRIM]), u1, u2)
        area = data[e, EMIT_AREA]
    to_q = sub(q, p)
    dist = length(to_q)
    if dist <= 0.0:
        return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, False
    wi = mul(to_q, 1.0 / dist)
    return wi, dist, radiance, _area_pdf(p, q, n, area), False


@njit(**KERNEL)
def emitter_pdf(G, Em, Env, e, p, wi, dist, n_hit):
    """The solid-angle pdf with which sample_emitter(e, p) gives the direction wi that met the
    emitter at distance dist (normal n_hit there); 0 for delta lights."""
    kind = Em.kind[e]
    data = Em.data
    if kind == POINT or kind == SPOT or kind == DIRECTIONAL:
        return 0.0
    if kind == ENVIRONMENT:
        return environment_pdf(Env, wi)
    if kind == AMBIENT:
        return 0.25 / math.pi
    if kind == SPHERE:
        return _sphere_cone_pdf(row3(data, e, LIGHT_POSITION), data[e, LIGHT_RADIUS], p, wi, dist)
    if kind == PRIMITIVE and G.prims[int(data[e, EMIT_PRIM]), PRIM_KIND] == SHAPE_SPHERE:
        row = np.int64(G.prims[int(data[e, EMIT_PRIM]), PRIM_ROW])
        return _sphere_cone_pdf(
            row3(G.shapes, row, shape_sphere.CENTER), G.shapes[row, shape_sphere.RADIUS], p, wi, dist
        )
    if kind == QUAD:
        area = length(cross(row3(data, e, LIGHT_U), row3(data, e, LIGHT_V)))
    else:
        area = data[e, EMIT_AREA]
    return _area_pdf(p, madd(p, wi, dist), n_hit, area)


@njit(**KERNEL)
def hit_area_lights(Em, o, d, tmax):
    """The nearest area light (rows 0..n_area-1) along the ray before tmax: (t, row, normal),
    row -1 when none."""
    best = tmax
    hit = -1
    normal = (0.0, 0.0, 1.0)
    data = Em.data
    for e in range(Em.n_area):
        c = row3(data, e, LIGHT_POSITION)
        if Em.kind[e] == QUAD:
            u = row3(data, e, LIGHT_U)
            v = row3(data, e, LIGHT_V)
            n = cross(u, v)
            t = intersect_plane(o, d, c, n, 0.0, best)
            if t == INF:
                continue
            rel = sub(madd(o, d, t), c)
            # coordinates along u and v (dual basis: n x v / |n|^2, u x n / |n|^2)
            nn = dot(n, n)
            a = dot(cross(v, n), rel) / nn
            b = dot(cross(n, u), rel) / nn
            if abs(a) <= 0.5 and abs(b) <= 0.5:
                best = t
                hit = e
                normal = mul(n, 1.0 / math.sqrt(nn))
        else:
            t = intersect_sphere(o, d, c, data[e, LIGHT_RADIUS], 0.0, best)
            if t < best:
                best = t
                hit = e
                normal = normalize(sub(madd(o, d, t), c))
    return best, hit, normal


@njit(**KERNEL, inline="always")
def environment_light(Env, d):
    """Radiance of the environment along d (zero without one)."""
    if Env.present:
        return environment_radiance(Env, d)
    return (0.0, 0.0, 0.0)
