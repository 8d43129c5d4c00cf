"""The `directional` light: parallel light from a direction (a light at infinity). Trace mode:
intensity `intensity`, shadow rays to infinity. Path mode: irradiance on a surface facing it."""

import math

import numpy as np

from ...geometry.transform import unit_vector
from ...vec import inline_function, mul, row3
from .sampling import disk_density, disk_origin
from .table import (
    LIGHT_DIRECTION,
    LIGHT_INTENSITY,
    LIGHT_POSITION,
    mean_intensity,
    scene_light_row,
)

NAME = "directional"
KIND = 2
DELTA = True
INFINITE = True  # at infinity: its column LIGHT_DIRECTION holds the unit vector towards it
VISIBLE = False
FALLOFF = False
EVERYWHERE = False
INF = math.inf


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py)."""
    row = scene_light_row(light)
    row[LIGHT_DIRECTION : LIGHT_DIRECTION + 3] = unit_vector(light.direction)
    return row


def power(row: np.ndarray, radius: float) -> float:
    """Emitted power: its irradiance over the scene's cross-section (radius: its bounding
    radius, roughly)."""
    return math.pi * radius**2 * mean_intensity(row)


@inline_function
def trace_sample(L, k, p, u1, u2):
    """Trace mode: (the unit vector towards the light, an endless shadow ray)."""
    return row3(L.data, k, LIGHT_DIRECTION), INF


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: (the direction towards it, at infinity, its irradiance, pdf 1, delta)."""
    return row3(Em.data, e, LIGHT_POSITION), INF, row3(Em.data, e, LIGHT_INTENSITY), 1.0, True


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return 0.0


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: parallel rays from the disk of the scene's bounding sphere facing the
    light (pbrt): (origin, -, direction of travel, irradiance, 1 / (pi R^2), 1 (a delta), -1)."""
    to_light = row3(Em.data, e, LIGHT_DIRECTION)
    p, pdf_pos = disk_origin(B, to_light, u1, u2)
    return p, (0.0, 0.0, 0.0), mul(to_light, -1.0), row3(Em.data, e, LIGHT_INTENSITY), pdf_pos, 1.0, -1


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    """No direction but its own: direction pdf 0 (a delta), as pbrt's PDF_Le."""
    return row3(Em.data, e, LIGHT_INTENSITY), disk_density(B), 0.0
