"""The `ambient` light: light from everywhere. Trace mode (the seed's): `intensity` added to
every surface's light, unshadowed, one light after another in the scene's order. Path mode: a
uniform environment of radiance `intensity`; the scene's ambient lights are summed into one row
(the light table's ambient row), sampled uniformly over the sphere."""

import math

import numpy as np

from ...film.sampler import uniform_sphere
from ...vec import inline_function, mul, row3
from .sampling import disk_density, disk_origin
from .table import LIGHT_INTENSITY, mean_intensity, scene_light_row

NAME = "ambient"
KIND = 0
DELTA = False
INFINITE = True
VISIBLE = False  # seen by rays that leave the scene, through the table's ambient row
FALLOFF = False
EVERYWHERE = True  # trace mode: added unshadowed, no point to sample
INF = math.inf


def pack(light) -> np.ndarray:
    """The model light's row of the light table (table.py): its intensity, nothing else."""
    return scene_light_row(light)


def power(row: np.ndarray, radius: float) -> float:
    """Power of the summed row: its radiance over the scene's bounding sphere (radius, roughly)."""
    return 4 * math.pi * math.pi * radius**2 * mean_intensity(row)


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: a direction uniform over the sphere, its radiance, pdf 1 / 4 pi."""
    return uniform_sphere(u1, u2), INF, row3(Em.data, e, LIGHT_INTENSITY), 0.25 / math.pi, False


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return 0.25 / math.pi


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a direction towards the light uniform over the sphere, the ray from the
    disk of the scene's bounding sphere facing it (pbrt): (origin, -, direction of travel,
    radiance, 1 / (pi R^2), 1 / (4 pi), -1)."""
    to_light = uniform_sphere(u1, u2)
    p, pdf_pos = disk_origin(B, to_light, u3, u4)
    return p, (0.0, 0.0, 0.0), mul(to_light, -1.0), row3(Em.data, e, LIGHT_INTENSITY), pdf_pos, 0.25 / math.pi, -1


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    return row3(Em.data, e, LIGHT_INTENSITY), disk_density(B), 0.25 / math.pi
