"""The `sphere` light: a ball of `radius` at `position`. Trace mode (the seed's units): the seed's
point light spread over the disk the sphere shows to the shading point (its silhouette as seen
from afar), the average over `samples` stratified points; rays do not see it. Path mode: a
surface of radiance `intensity`, seen by rays, sampled by the cone it subtends (pbrt)."""

import math

import numpy as np

from ...film.sampler import concentric_disk, uniform_sphere
from ...geometry.shape_sphere import intersect_sphere, sphere_hides_point
from ...vec import inline_function, kernel_function, length, madd, normalize, row3, sub
from .sampling import basis, cosine_two_sided, sphere_cone, sphere_cone_pdf, two_sided_pdf
from .table import (
    AREA_SHADOW_SHORTEN,
    LIGHT_INTENSITY,
    LIGHT_POSITION,
    LIGHT_RADIUS,
    mean_intensity,
    scene_light_row,
)

NAME = "sphere"
KIND = 4
DELTA = False
INFINITE = False
VISIBLE = True
FALLOFF = False
EVERYWHERE = False
INF = math.inf


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py)."""
    row = scene_light_row(light)
    row[LIGHT_POSITION : LIGHT_POSITION + 3] = light.position
    row[LIGHT_RADIUS] = light.radius
    return row


def power(row: np.ndarray, radius: float) -> float:
    """Emitted power: radiance over its surface, pi per unit area."""
    return math.pi * 4 * math.pi * row[LIGHT_RADIUS] ** 2 * mean_intensity(row)


@kernel_function
def trace_sample(L, k, p, u1, u2):
    """Trace mode: the point (u1, u2) of the disk facing p: (vector from p to the point, shadow
    ray length, a little short of it)."""
    centre = row3(L.data, k, LIGHT_POSITION)
    e1, e2 = basis(normalize(sub(centre, p)))
    a, b = concentric_disk(u1, u2)
    r = L.data[k, LIGHT_RADIUS]
    q = madd(madd(centre, e1, a * r), e2, b * r)
    to_light = sub(q, p)
    return to_light, length(to_light) * (1.0 - AREA_SHADOW_SHORTEN)


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: a direction uniform over the cone it subtends from p."""
    wi, dist, pdf_ = sphere_cone(row3(Em.data, e, LIGHT_POSITION), Em.data[e, LIGHT_RADIUS], p, u1, u2)
    return wi, dist, row3(Em.data, e, LIGHT_INTENSITY), pdf_, False


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return sphere_cone_pdf(row3(Em.data, e, LIGHT_POSITION), Em.data[e, LIGHT_RADIUS], p, wi, dist)


@inline_function
def hit(Em, e, o, d, tmax):
    """The ray (o, d) against sphere row e before tmax: (t, unit normal), t = inf for a miss."""
    data = Em.data
    c = row3(data, e, LIGHT_POSITION)
    t = intersect_sphere(o, d, c, data[e, LIGHT_RADIUS], 0.0, tmax)
    if t < tmax:
        return t, normalize(sub(madd(o, d, t), c))
    return INF, (0.0, 0.0, 1.0)


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a point uniform over the sphere, a cosine direction on either side (path
    mode's rays see it from inside too)."""
    n = uniform_sphere(u1, u2)
    r = Em.data[e, LIGHT_RADIUS]
    q = madd(row3(Em.data, e, LIGHT_POSITION), n, r)
    w = cosine_two_sided(n, u3, u4)
    return q, n, w, row3(Em.data, e, LIGHT_INTENSITY), 1.0 / (4.0 * math.pi * r * r), two_sided_pdf(n, w), -1


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    r = Em.data[e, LIGHT_RADIUS]
    return row3(Em.data, e, LIGHT_INTENSITY), 1.0 / (4.0 * math.pi * r * r), two_sided_pdf(n, w)


@inline_function
def hides(Em, e, p, n, w):
    """Does the sphere hide its own point of outward normal n from p, which looks at it along w?
    A convex body hides the points that face away, unless p is inside it. (A ray test with the
    far end shortened by a fraction of the distance took points near the silhouette of a sphere
    smaller than that fraction as seen: bdpt's light sampling was 30% too bright at r = 1e-6.)"""
    return sphere_hides_point(row3(Em.data, e, LIGHT_POSITION), Em.data[e, LIGHT_RADIUS], p, n, w)


def bounds(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners of the box around the sphere (bidirectional path tracing's bounding sphere)."""
    c = row[LIGHT_POSITION : LIGHT_POSITION + 3]
    return c - row[LIGHT_RADIUS], c + row[LIGHT_RADIUS]
