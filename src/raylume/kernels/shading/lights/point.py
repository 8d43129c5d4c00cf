"""The `point` light: all its light leaves one point. Trace mode (the seed's units): intensity
`intensity` at every distance, one shadow ray up to the light. Path mode: radiant intensity
(W/sr), falling off as 1 / r^2; a delta light, found only by next-event estimation."""

import math

import numpy as np

from ...film.sampler import uniform_sphere
from ...vec import inline_function, length, mul, row3, sub
from .table import LIGHT_INTENSITY, LIGHT_POSITION, mean_intensity, scene_light_row

NAME = "point"
KIND = 1
DELTA = True  # a single point: no random numbers, no MIS
INFINITE = False  # at a finite distance
VISIBLE = False  # rays do not see it
FALLOFF = False  # no angular falloff in trace mode
EVERYWHERE = False  # not the seed's ambient light


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py)."""
    row = scene_light_row(light)
    row[LIGHT_POSITION : LIGHT_POSITION + 3] = light.position
    return row


def power(row: np.ndarray, radius: float) -> float:
    """Emitted power, for path mode's light distribution: 4 pi I (the channels' mean)."""
    return 4 * math.pi * mean_intensity(row)


@inline_function
def trace_sample(L, k, p, u1, u2):
    """Trace mode: (the vector from p to the light, the shadow ray's length)."""
    to_light = sub(row3(L.data, k, LIGHT_POSITION), p)
    return to_light, length(to_light)


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: (wi, distance, intensity / r^2 arriving, pdf 1, delta)."""
    to_l = sub(row3(Em.data, e, LIGHT_POSITION), p)
    dist = length(to_l)
    if dist <= 0.0:
        return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, True
    wi = mul(to_l, 1.0 / dist)
    return wi, dist, mul(row3(Em.data, e, LIGHT_INTENSITY), 1.0 / (dist * dist)), 1.0, True


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    """No direction a BSDF samples meets a point."""
    return 0.0


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: light leaving the point, a direction uniform over the sphere: (point,
    normal (none), direction, intensity, position pdf 1 (a delta), direction pdf, hit -1)."""
    w = uniform_sphere(u1, u2)
    return (
        row3(Em.data, e, LIGHT_POSITION),
        (0.0, 0.0, 0.0),
        w,
        row3(Em.data, e, LIGHT_INTENSITY),
        1.0,
        0.25 / math.pi,
        -1,
    )


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    """(intensity along w, position pdf, direction pdf) of emit's light along w."""
    return row3(Em.data, e, LIGHT_INTENSITY), 1.0, 0.25 / math.pi
