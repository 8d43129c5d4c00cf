"""The `quad` light: a parallelogram, centre `position` +- u/2 +- v/2. Trace mode (the seed's
units): the seed's point light spread over the quad, the average over `samples` stratified
points of a point light of intensity `intensity` there; rays do not see it. Path mode: a
surface of radiance `intensity` emitting on both sides, seen by rays (area lights lead the
table: path.py tests rows 0..n_area-1 beside the BVH)."""

import math

import numpy as np

from ...geometry.shape_plane import intersect_plane
from ...vec import cross, dot, inline_function, kernel_function, length, madd, mul, row3, sub
from .sampling import area_pdf, cosine_two_sided, towards_point, two_sided_pdf
from .table import (
    AREA_SHADOW_SHORTEN,
    LIGHT_INTENSITY,
    LIGHT_POSITION,
    LIGHT_U,
    LIGHT_V,
    mean_intensity,
    scene_light_row,
)

NAME = "quad"
KIND = 3
DELTA = False
INFINITE = False
VISIBLE = True  # rays see it (path mode)
FALLOFF = False
EVERYWHERE = False
INF = math.inf


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py)."""
    row = scene_light_row(light)
    row[LIGHT_POSITION : LIGHT_POSITION + 3] = light.position
    row[LIGHT_U : LIGHT_U + 3] = light.u
    row[LIGHT_V : LIGHT_V + 3] = light.v
    return row


def power(row: np.ndarray, radius: float) -> float:
    """Emitted power: radiance over both sides of its area, pi per side."""
    area = float(np.linalg.norm(np.cross(row[LIGHT_U : LIGHT_U + 3], row[LIGHT_V : LIGHT_V + 3])))
    return 2 * math.pi * area * mean_intensity(row)


@kernel_function
def trace_sample(L, k, p, u1, u2):
    """Trace mode: the point (u1, u2) in [0, 1)^2 of the quad seen from p: (vector from p to
    the point, shadow ray length, a little short of it)."""
    centre = row3(L.data, k, LIGHT_POSITION)
    q = madd(madd(centre, row3(L.data, k, LIGHT_U), u1 - 0.5), row3(L.data, k, LIGHT_V), u2 - 0.5)
    to_light = sub(q, p)
    return to_light, length(to_light) * (1.0 - AREA_SHADOW_SHORTEN)


@inline_function
def surface_point(G, X, Em, e, u1, u2):
    """A point uniform over its area: (True, the point, the unit normal, the area, radiance)."""
    data = Em.data
    u = row3(data, e, LIGHT_U)
    v = row3(data, e, LIGHT_V)
    q = madd(madd(row3(data, e, LIGHT_POSITION), u, u1 - 0.5), v, u2 - 0.5)
    n = cross(u, v)
    area = length(n)
    return True, q, mul(n, 1.0 / area), area, row3(data, e, LIGHT_INTENSITY)


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: a point uniform over its area, seen from p."""
    _, q, n, area, radiance = surface_point(G, X, Em, e, u1, u2)
    return towards_point(p, q, n, area, radiance)


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    """The solid-angle pdf of sample's point met along wi at dist (normal n_hit there)."""
    area = length(cross(row3(Em.data, e, LIGHT_U), row3(Em.data, e, LIGHT_V)))
    return area_pdf(p, madd(p, wi, dist), n_hit, area)


@inline_function
def hit(Em, e, o, d, tmax):
    """The ray (o, d) against quad row e before tmax: (t, unit normal), t = inf for a miss."""
    data = Em.data
    c = row3(data, e, LIGHT_POSITION)
    u = row3(data, e, LIGHT_U)
    v = row3(data, e, LIGHT_V)
    n = cross(u, v)
    t = intersect_plane(o, d, c, n, 0.0, tmax)
    if t == INF:
        return INF, (0.0, 0.0, 1.0)
    rel = sub(madd(o, d, t), c)
    # coordinates along u and v (dual basis: n x v / |n|^2, u x n / |n|^2)
    nn = dot(n, n)
    a = dot(cross(v, n), rel) / nn
    b = dot(cross(n, u), rel) / nn
    if abs(a) <= 0.5 and abs(b) <= 0.5:
        return t, mul(n, 1.0 / math.sqrt(nn))
    return INF, (0.0, 0.0, 1.0)


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a point uniform over the area, a cosine direction on either side."""
    data = Em.data
    u = row3(data, e, LIGHT_U)
    v = row3(data, e, LIGHT_V)
    q = madd(madd(row3(data, e, LIGHT_POSITION), u, u1 - 0.5), v, u2 - 0.5)
    n = cross(u, v)
    area = length(n)
    n = mul(n, 1.0 / area)
    w = cosine_two_sided(n, u3, u4)
    return q, n, w, row3(data, e, LIGHT_INTENSITY), 1.0 / area, two_sided_pdf(n, w), -1


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    area = length(cross(row3(Em.data, e, LIGHT_U), row3(Em.data, e, LIGHT_V)))
    return row3(Em.data, e, LIGHT_INTENSITY), 1.0 / area, two_sided_pdf(n, w)


def bounds(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners of the box around the quad (bidirectional path tracing's bounding sphere)."""
    c = row[LIGHT_POSITION : LIGHT_POSITION + 3]
    half = 0.5 * (np.abs(row[LIGHT_U : LIGHT_U + 3]) + np.abs(row[LIGHT_V : LIGHT_V + 3]))
    return c - half, c + half
