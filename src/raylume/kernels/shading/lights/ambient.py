"""The `ambient` light: light from everywhere. Trace mode (the seed's): `intensity` added to
every surface's light, unshadowed, one light after another in the scene's order. Path mode: a
uniform environment of radiance `intensity`; the scene's ambient lights are summed into one row
(the light table's ambient row), sampled uniformly over the sphere."""

import math

import numpy as np

from ...film.sampler import uniform_sphere
from ...vec import inline_function, row3
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
