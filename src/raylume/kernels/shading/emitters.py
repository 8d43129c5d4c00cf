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
* emissive instanced meshes, one row each (INSTANCED): a sample picks one of the mesh's
  instances (from a distribution over them), then a triangle in proportion to its area in the
  mesh's own space, then a uniform point on it, taken to world space by the instance's matrix
  (`instanced_area`: the pdf accounts for what the matrix does to the triangle's area); every
  triangle of the mesh points back here through PRIM_LIGHT;
* the environment, when the scene has one (one row; environment.py samples it).

Ambient lights are a uniform environment in path mode: their radiances summed in one row
(kind lights.AMBIENT), sampled uniformly over the sphere.
`sample_emitter` returns a direction, its distance, the arriving radiance (or intensity over
r^2 for the delta lights) and the solid-angle pdf; `emitter_pdf` is that pdf for a direction
that a BSDF sample happened to find, for multiple importance sampling.
"""

import math

import numpy as np

from ..film.sampler import key_uniform2, sub_key, uniform_sphere
from ..geometry import shape_sphere
from ..geometry.shape_plane import intersect_plane
from ..geometry.shape_sphere import intersect_sphere
from ..geometry.shapes import PRIM_KIND, PRIM_ROW, sample_surface, split_hit
from ..geometry.shapes import SPHERE as SHAPE_SPHERE
from ..vec import cross, dot, inline_function, kernel_function, length, madd, mul, normalize, row3, sub
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

INF = math.inf

PRIMITIVE = 6  # an emissive primitive of the scene's geometry
ENVIRONMENT = 7
INSTANCED = 8  # an emissive instanced mesh: all its instances' triangles

EMIT_PRIM = LIGHT_WIDTH  # PRIMITIVE rows: the primitive's index in the primitive table
EMIT_AREA = LIGHT_WIDTH + 1  # its area
EMIT_WIDTH = LIGHT_WIDTH + 2
# INSTANCED rows (beside the radiance in LIGHT_INTENSITY): where the mesh's distributions lie
# in the emitter distributions array (Emitters.dist, float64): its instances' cdf (count + 1
# values, unnormalised) followed by those instances' rows of the instance table (as floats),
# and its triangles' cdf (by area in object space, count + 1 values); EMIT_PRIM is the mesh's
# first primitive row (its triangles' rows are consecutive), EMIT_AREA its object-space area.
INST_CDF = 0
INST_COUNT = 1
TRI_CDF = 2
TRI_COUNT = 6

# Shadow rays towards a sampled point stop this fraction short of it (the emitter itself
# must not count as a blocker).
SHADOW_SHORTEN = 1e-5


@kernel_function
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


@inline_function
def pick_probability(cdf, e):
    return (cdf[e + 1] - cdf[e]) / cdf[cdf.shape[0] - 1]


@kernel_function
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


@kernel_function
def _sphere_cone_pdf(centre, radius, p, wi, dist):
    to_c = sub(centre, p)
    dist2 = dot(to_c, to_c)
    if dist2 <= radius * radius * (1.0 + 1e-9):
        q = madd(p, wi, dist)
        return _area_pdf(p, q, normalize(sub(q, centre)), 4.0 * math.pi * radius * radius)
    cos_max = math.sqrt(max(0.0, 1.0 - radius * radius / dist2))
    return 1.0 / (2.0 * math.pi * (1.0 - cos_max))


@inline_function
def _area_pdf(p, q, n, area):
    """Solid-angle pdf at p of a point q (normal n) sampled uniformly on a surface of `area`."""
    to_q = sub(q, p)
    dist2 = dot(to_q, to_q)
    cos_l = abs(dot(n, to_q)) / math.sqrt(dist2) if dist2 > 0.0 else 0.0
    if cos_l <= 0.0 or area <= 0.0:
        return 0.0
    return dist2 / (area * cos_l)


@inline_function
def _pick(dist, first, n, u):
    """Index in [0, n) whose share of the cdf dist[first : first + n + 1] holds u."""
    lo = 0
    hi = n
    total = dist[first + n]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if dist[first + mid] <= u * total:
            lo = mid
        else:
            hi = mid
    return lo


@inline_function
def _inverse_det(inv, i):
    """det B of instance i's stored world-to-object matrix B (float32, taken in float64)."""
    return (
        inv[i, 0] * (np.float64(inv[i, 5]) * inv[i, 10] - np.float64(inv[i, 6]) * inv[i, 9])
        - inv[i, 1] * (np.float64(inv[i, 4]) * inv[i, 10] - np.float64(inv[i, 6]) * inv[i, 8])
        + inv[i, 2] * (np.float64(inv[i, 4]) * inv[i, 9] - np.float64(inv[i, 5]) * inv[i, 8])
    )


@inline_function
def instance_weight(det):
    """The weight of an instance in its mesh's instance distribution, from det B: |det A|^(2/3)
    of its object-to-world matrix A = B^-1 (the scale of areas under a similarity;
    emitters_table.instance_weights computes the same at compile time)."""
    return abs(det) ** (-2.0 / 3.0)


@kernel_function
def instanced_area(dist, data, e, inv, i, tris, r):
    """1 / (area density) of the points INSTANCED row e samples, at triangle row r of instance
    i: P(instance) P(triangle) / (the triangle's world area). The world area is the object
    area times |B^T n| / |det B| (B the world-to-object matrix, n the unit object normal)."""
    n_inst = int(data[e, INST_COUNT])
    first = int(data[e, INST_CDF])
    det = _inverse_det(inv, i)
    p_inst = instance_weight(det) / dist[first + n_inst]
    v0 = row3(tris, r, 0)
    n = normalize(cross(sub(row3(tris, r, 3), v0), sub(row3(tris, r, 6), v0)))
    bn = (
        inv[i, 0] * n[0] + inv[i, 4] * n[1] + inv[i, 8] * n[2],
        inv[i, 1] * n[0] + inv[i, 5] * n[1] + inv[i, 9] * n[2],
        inv[i, 2] * n[0] + inv[i, 6] * n[1] + inv[i, 10] * n[2],
    )
    # P(triangle) = area / total object area; the triangle's own object area cancels
    return data[e, EMIT_AREA] * length(bn) / (abs(det) * p_inst)


# Not inlined: only instanced emitters take this branch, and the path kernel's compile stays as
# it was. Arrays by value, no views of the scene.
@kernel_function
def _sample_instanced(dist, data, e, inv, prims, tris, u1, u2, u3, u4):
    """A point of INSTANCED row e: (world point, unit world normal, 1 / area density)."""
    n_inst = int(data[e, INST_COUNT])
    first = int(data[e, INST_CDF])
    i = int(dist[first + n_inst + 1 + _pick(dist, first, n_inst, u3)])
    k = int(data[e, EMIT_PRIM]) + _pick(dist, int(data[e, TRI_CDF]), int(data[e, TRI_COUNT]), u4)
    r = np.int64(prims[k, PRIM_ROW])
    s = math.sqrt(u1)
    v0 = row3(tris, r, 0)
    e1 = sub(row3(tris, r, 3), v0)
    e2 = sub(row3(tris, r, 6), v0)
    q = sub(madd(madd(v0, e1, 1.0 - s), e2, u2 * s), (inv[i, 3], inv[i, 7], inv[i, 11]))
    # world point: B^-1 (q - b), by the adjugate; world normal: B^T n (the inverse transpose)
    a00, a01, a02 = np.float64(inv[i, 0]), np.float64(inv[i, 1]), np.float64(inv[i, 2])
    a10, a11, a12 = np.float64(inv[i, 4]), np.float64(inv[i, 5]), np.float64(inv[i, 6])
    a20, a21, a22 = np.float64(inv[i, 8]), np.float64(inv[i, 9]), np.float64(inv[i, 10])
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    c10 = a02 * a21 - a01 * a22
    c11 = a00 * a22 - a02 * a20
    c12 = a01 * a20 - a00 * a21
    c20 = a01 * a12 - a02 * a11
    c21 = a02 * a10 - a00 * a12
    c22 = a00 * a11 - a01 * a10
    p = (
        (c00 * q[0] + c10 * q[1] + c20 * q[2]) / det,
        (c01 * q[0] + c11 * q[1] + c21 * q[2]) / det,
        (c02 * q[0] + c12 * q[1] + c22 * q[2]) / det,
    )
    n = cross(e1, e2)
    nw = normalize(
        (
            a00 * n[0] + a10 * n[1] + a20 * n[2],
            a01 * n[0] + a11 * n[1] + a21 * n[2],
            a02 * n[0] + a12 * n[1] + a22 * n[2],
        )
    )
    return p, nw, instanced_area(dist, data, e, inv, i, tris, r)


# Inlined (one call site): a call passed the Geometry, Emitters and Environment views by value,
# which cost more than the sampling (148 vs 84 ns on the Cornell box's light).
@inline_function
def sample_emitter(G, X, Em, Env, e, p, u1, u2, key):
    """Emitter row e seen from p: (unit direction wi, distance (inf: at infinity), radiance
    arriving along wi (delta lights: intensity / r^2 or irradiance), solid-angle pdf (0: no
    sample), delta). `key`: the light sample's key (instanced emitters draw two more uniforms
    from it); X: the scene's Instances (kernels/scene.py)."""
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
    elif kind == INSTANCED:
        u3, u4 = key_uniform2(sub_key(key, 2))
        q, n, area = _sample_instanced(Em.dist, data, e, X.inverse, G.prims, G.triangles, u1, u2, u3, u4)
    else:
        q, n = sample_surface(G, int(data[e, EMIT_PRIM]), u1, u2)
        area = data[e, EMIT_AREA]
    to_q = sub(q, p)
    dist = length(to_q)
    if dist <= 0.0:
        return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, False
    wi = mul(to_q, 1.0 / dist)
    return wi, dist, radiance, _area_pdf(p, q, n, area), False


@kernel_function
def emitter_pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    """The solid-angle pdf with which sample_emitter(e, p) gives the direction wi that met the
    emitter at distance dist (normal n_hit there; `hit`: the primitive hit, as closest_hit
    gives it, for instanced emitters); 0 for delta lights."""
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
    elif kind == INSTANCED:
        k, i = split_hit(X, hit)
        area = instanced_area(Em.dist, data, e, X.inverse, i, G.triangles, np.int64(G.prims[k, PRIM_ROW]))
    else:
        area = data[e, EMIT_AREA]
    return _area_pdf(p, madd(p, wi, dist), n_hit, area)


@kernel_function
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


@inline_function
def environment_light(Env, d):
    """Radiance of the environment along d (zero without one)."""
    if Env.present:
        return environment_radiance(Env, d)
    return (0.0, 0.0, 0.0)
