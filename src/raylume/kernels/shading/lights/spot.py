"""The `spot` light: a point light whose intensity falls from full inside its inner cone
(`inner_angle`) to 0 at its outer cone (`angle`), pbrt's smooth step in the cosine, shining
along `direction`. Units as the point light's."""

import math

import numpy as np

from ...geometry.transform import unit_vector
from ...vec import dot, inline_function, length, mul, row3, sub
from . import point
from .sampling import about
from .table import (
    LIGHT_AXIS,
    LIGHT_COS_INNER,
    LIGHT_COS_OUTER,
    LIGHT_INTENSITY,
    LIGHT_POSITION,
    mean_intensity,
    scene_light_row,
)

NAME = "spot"
KIND = 5
DELTA = True
INFINITE = False
VISIBLE = False
FALLOFF = True  # its intensity depends on the direction it leaves in (`falloff`)
EVERYWHERE = False


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py)."""
    row = scene_light_row(light)
    row[LIGHT_POSITION : LIGHT_POSITION + 3] = light.position
    row[LIGHT_AXIS : LIGHT_AXIS + 3] = unit_vector(light.direction)
    row[LIGHT_COS_OUTER] = math.cos(math.radians(light.angle))
    row[LIGHT_COS_INNER] = math.cos(math.radians(light.inner))
    return row


def power(row: np.ndarray, radius: float) -> float:
    """Emitted power: the point light's over the solid angle of its cones (the falloff's mean)."""
    intensity = mean_intensity(row)
    return 2 * math.pi * intensity * (1 - 0.5 * (row[LIGHT_COS_INNER] + row[LIGHT_COS_OUTER]))


@inline_function
def falloff(data, k, l):
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
def trace_falloff(L, k, l):
    """Trace mode: falloff of spot light k of the table view L towards the unit direction l."""
    return falloff(L.data, k, l)


# trace mode finds a spot light as the point light it is (the integrator adds trace_falloff)
trace_sample = point.trace_sample


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: (wi, distance, intensity x falloff / r^2 arriving, pdf 1, delta)."""
    data = Em.data
    to_l = sub(row3(data, e, LIGHT_POSITION), p)
    dist = length(to_l)
    if dist <= 0.0:
        return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, True
    wi = mul(to_l, 1.0 / dist)
    scale = 1.0 / (dist * dist)
    scale *= falloff(data, e, wi)
    return wi, dist, mul(row3(data, e, LIGHT_INTENSITY), scale), 1.0, True


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return 0.0


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a direction uniform in the outer cone, the intensity times the falloff."""
    data = Em.data
    axis = row3(data, e, LIGHT_AXIS)
    cos_outer = data[e, LIGHT_COS_OUTER]
    cos_t = 1.0 - u1 * (1.0 - cos_outer)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    w = about(axis, cos_t, sin_t, u2)
    le = mul(row3(data, e, LIGHT_INTENSITY), falloff(data, e, mul(w, -1.0)))
    return row3(data, e, LIGHT_POSITION), (0.0, 0.0, 0.0), w, le, 1.0, _cone_pdf(cos_outer), -1


@inline_function
def _cone_pdf(cos_outer):
    return 1.0 / (2.0 * math.pi * max(1.0 - cos_outer, 1e-12))


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    data = Em.data
    cos_t = dot(w, row3(data, e, LIGHT_AXIS))
    if cos_t < data[e, LIGHT_COS_OUTER]:
        return (0.0, 0.0, 0.0), 1.0, 0.0
    le = mul(row3(data, e, LIGHT_INTENSITY), falloff(data, e, mul(w, -1.0)))
    return le, 1.0, _cone_pdf(data[e, LIGHT_COS_OUTER])
