"""Emissive instanced meshes: one row per mesh whose material has `emission` (path mode only). A
sample picks one of the mesh's instances (from a distribution over them), then a triangle in
proportion to its area in the mesh's own space, then a uniform point on it, taken to world space
by the instance's matrix (`instanced_area`: the pdf accounts for what the matrix does to the
triangle's area). Every triangle of the mesh points back to the row through PRIM_LIGHT. The
distributions lie in the light table's distributions array (table.py: INST_CDF ...)."""

import math

import numpy as np

from ...film.sampler import key_uniform2, sub_key
from ...geometry.shapes import INSTANCE_SHIFT, PRIM_ROW, split_hit
from ...vec import cross, inline_function, kernel_function, last_at_most, length, madd, normalize, row3, sub
from .sampling import area_pdf, cosine_two_sided, towards_point, two_sided_pdf
from .table import EMIT_AREA, EMIT_PRIM, INST_CDF, INST_COUNT, LIGHT_INTENSITY, TRI_CDF, TRI_COUNT

NAME = "instanced"
KIND = 8
DELTA = False
INFINITE = False
VISIBLE = False  # seen as the instances' triangles (the BVH finds them)
FALLOFF = False
EVERYWHERE = False


def power(object_area: float, instance_weight_sum: float, radiance: np.ndarray) -> float:
    """Both sides of every instance's triangles (exact for similarities: |det A|^(2/3) is the
    area scale; only the choice between emitters depends on it)."""
    return 2 * math.pi * object_area * instance_weight_sum * float(radiance.mean())


@inline_function
def _pick(dist, first, n, u):
    """Index in [0, n) whose share of the cdf dist[first : first + n + 1] holds u."""
    return last_at_most(dist, first, n, u * dist[first + n])


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
    compile/lights.py instance_weights computes the same at compile time)."""
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
def sample_point(dist, data, e, inv, prims, tris, u1, u2, u3, u4):
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


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: a point of one of the mesh's instances (two more uniforms from `key`)."""
    u3, u4 = key_uniform2(sub_key(key, 2))
    q, n, area = sample_point(Em.dist, Em.data, e, X.inverse, G.prims, G.triangles, u1, u2, u3, u4)
    return towards_point(p, q, n, area, row3(Em.data, e, LIGHT_INTENSITY))


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    k, i = split_hit(X, hit)
    area = instanced_area(Em.dist, Em.data, e, X.inverse, i, G.triangles, np.int64(G.prims[k, PRIM_ROW]))
    return area_pdf(p, madd(p, wi, dist), n_hit, area)


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a point of one of the mesh's instances, as `sample` picks it, and a
    cosine direction on either side (two more uniforms from `key`)."""
    q, n, inv_density = sample_point(Em.dist, Em.data, e, X.inverse, G.prims, G.triangles, u1, u2, u3, u4)
    v1, v2 = key_uniform2(sub_key(key, 3))
    w = cosine_two_sided(n, v1, v2)
    # the hit of the point: its instance and triangle, for emit_pdf (as a ray finds them)
    hit = _sampled_hit(Em.dist, Em.data, e, u3, u4)
    return q, n, w, row3(Em.data, e, LIGHT_INTENSITY), 1.0 / inv_density, two_sided_pdf(n, w), hit


@kernel_function
def _sampled_hit(dist, data, e, u3, u4):
    """The hit id (instance + 1) << 32 | primitive of sample_point's choice for u3, u4."""
    n_inst = int(data[e, INST_COUNT])
    first = int(data[e, INST_CDF])
    slot = _pick(dist, first, n_inst, u3)
    i = int(dist[first + n_inst + 1 + slot])
    k = int(data[e, EMIT_PRIM]) + _pick(dist, int(data[e, TRI_CDF]), int(data[e, TRI_COUNT]), u4)
    return ((np.int64(i) + 1) << INSTANCE_SHIFT) | np.int64(k)


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    k, i = split_hit(X, hit)
    area = instanced_area(Em.dist, Em.data, e, X.inverse, i, G.triangles, np.int64(G.prims[k, PRIM_ROW]))
    return row3(Em.data, e, LIGHT_INTENSITY), 1.0 / area, two_sided_pdf(n, w)
