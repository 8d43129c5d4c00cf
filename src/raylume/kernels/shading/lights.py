"""Lights: each kind's sampling (a point on the light as seen from a shading point) and its
data, in a table the Python side fills (`pack_light`).

Table: int32 kinds (L,) and float64 (L, LIGHT_WIDTH). Ambient light arrives from everywhere
unshadowed. Point and directional lights are single points (directional: at infinity, the
column LIGHT_DIRECTION holding the unit vector towards it). Area lights (quad, sphere) are the
seed's point light spread over a shape: their contribution is the average, over `samples`
stratified points on the shape, of a point light of the same intensity at that point. A quad
is sampled uniformly over its area; a sphere over its disk facing the shading point (its
silhouette as seen from afar). A spot light is a point light whose intensity falls from full
inside its inner cone to 0 at its outer cone (pbrt's smooth step in the cosine). In trace
mode lights are not geometry: camera rays and reflections do not see them (path mode's view
of the same lights, in radiometric units, is emitters.py).
"""

import math

import numpy as np

from ..film.sampler import concentric_disk
from ..geometry.transform import unit_vector
from ..vec import inline_function, kernel_function, length, madd, normalize, row3, sub

INF = math.inf

AMBIENT = 0
POINT = 1
DIRECTIONAL = 2
QUAD = 3  # centre +- u/2 +- v/2
SPHERE = 4
SPOT = 5

LIGHT_POSITION = 0  # 3 columns: a point light's position, a quad's or sphere's centre
LIGHT_DIRECTION = 0  # 3 columns: a directional light's unit vector towards the light
LIGHT_INTENSITY = 3  # 3 columns, RGB
LIGHT_U = 6  # quad edge vectors (3 columns each)
LIGHT_V = 9
LIGHT_AXIS = 6  # 3 columns: a spot light's unit direction (the way it shines)
LIGHT_COS_OUTER = 9  # cos of a spot's outer half-angle (0 beyond it)
LIGHT_COS_INNER = 10  # cos of its inner half-angle (full intensity inside)
LIGHT_RADIUS = 12  # sphere
LIGHT_SAMPLES = 13  # shadow samples per shading point (area lights; 1 for the others)
LIGHT_WIDTH = 14

# Shadow rays towards a point on an area light stop this fraction short of it, so a light
# placed on a surface (a lamp on a ceiling) is not shadowed by that surface.
AREA_SHADOW_SHORTEN = 1e-6

KINDS = {"ambient": AMBIENT, "point": POINT, "directional": DIRECTIONAL, "quad": QUAD, "sphere": SPHERE, "spot": SPOT}


def pack_light(light) -> tuple[int, np.ndarray]:
    """(kind, row) of a model light."""
    row = np.zeros(LIGHT_WIDTH, dtype=np.float64)
    kind = KINDS[light.type]
    row[LIGHT_INTENSITY : LIGHT_INTENSITY + 3] = light.intensity
    row[LIGHT_SAMPLES] = getattr(light, "samples", 1)
    if kind == DIRECTIONAL:
        row[LIGHT_DIRECTION : LIGHT_DIRECTION + 3] = unit_vector(light.direction)
    elif kind != AMBIENT:
        row[LIGHT_POSITION : LIGHT_POSITION + 3] = light.position
    if kind == QUAD:
        row[LIGHT_U : LIGHT_U + 3] = light.u
        row[LIGHT_V : LIGHT_V + 3] = light.v
    elif kind == SPHERE:
        row[LIGHT_RADIUS] = light.radius
    elif kind == SPOT:
        row[LIGHT_AXIS : LIGHT_AXIS + 3] = unit_vector(light.direction)
        row[LIGHT_COS_OUTER] = math.cos(math.radians(light.angle))
        row[LIGHT_COS_INNER] = math.cos(math.radians(light.inner))
    return kind, row


@inline_function
def is_delta(kind):
    """A light of a single point (one sample, no random numbers)."""
    return kind == POINT or kind == DIRECTIONAL or kind == SPOT


@inline_function
def spot_falloff(data, k, l):
    """The share of spot light k's intensity sent along -l (l: unit, from the lit point towards
    the light): 1 inside the inner cone, 0 outside the outer one, a smooth step between."""
    cos_t = -(l[0] * data[k, LIGHT_AXIS] + l[1] * data[k, LIGHT_AXIS + 1] + l[2] * data[k, LIGHT_AXIS + 2])
    lo = data[k, LIGHT_COS_OUTER]
    hi = data[k, LIGHT_COS_INNER]
    if cos_t <= lo:
        return 0.0
    if cos_t >= hi:
        return 1.0
    x = (cos_t - lo) / (hi - lo)
    return x * x * (3.0 - 2.0 * x)


@inline_function
def sample_delta(L, k, p):
    """Point, spot or directional light k seen from p: (vector from p towards it, shadow ray
    length)."""
    if L.kind[k] != DIRECTIONAL:
        to_light = sub(row3(L.data, k, LIGHT_POSITION), p)
        return to_light, length(to_light)
    return row3(L.data, k, LIGHT_DIRECTION), INF


@kernel_function
def sample_area(L, k, p, u1, u2):
    """The point (u1, u2) in [0, 1)^2 of area light k as seen from p: (vector from p to the
    point, shadow ray length)."""
    centre = row3(L.data, k, LIGHT_POSITION)
    if L.kind[k] == QUAD:
        q = madd(madd(centre, row3(L.data, k, LIGHT_U), u1 - 0.5), row3(L.data, k, LIGHT_V), u2 - 0.5)
    else:
        e1, e2 = basis(normalize(sub(centre, p)))
        a, b = concentric_disk(u1, u2)
        r = L.data[k, LIGHT_RADIUS]
        q = madd(madd(centre, e1, a * r), e2, b * r)
    to_light = sub(q, p)
    return to_light, length(to_light) * (1.0 - AREA_SHADOW_SHORTEN)


@kernel_function
def basis(w):
    """Two unit vectors completing the unit w to an orthonormal basis (Duff et al. 2017)."""
    sign = 1.0 if w[2] >= 0.0 else -1.0
    a = -1.0 / (sign + w[2])
    b = w[0] * w[1] * a
    return (1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]), (b, sign + w[1] * w[1] * a, -w[1])
