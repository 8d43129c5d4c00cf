"""The `homogeneous` medium [Mitsuba 3: homogeneous; pbrt-v4: homogeneous]: the same sigma_a and
sigma_s everywhere. Its majorant is its largest channel of sigma_t over the whole ray, and its
transmittance has a closed form (Beer-Lambert), so shadow rays through it need no tracking."""

import math

import numpy as np

from ...vec import inline_function
from .table import MED_G, MED_SIGMA_A, MED_SIGMA_S, MED_SIGMA_T_MAX

NAME = "homogeneous"
KIND = 0


def pack(medium, row: np.ndarray) -> None:
    row[MED_SIGMA_A : MED_SIGMA_A + 3] = medium.sigma_a
    row[MED_SIGMA_S : MED_SIGMA_S + 3] = medium.sigma_s
    row[MED_G] = medium.g
    row[MED_SIGMA_T_MAX] = max(a + s for a, s in zip(medium.sigma_a, medium.sigma_s))


@inline_function
def exact_transmittance(data, k, distance):
    """exp(-sigma_t distance) per channel (1 where sigma_t is 0, even at infinite distance)."""
    t0 = data[k, MED_SIGMA_A] + data[k, MED_SIGMA_S]
    t1 = data[k, MED_SIGMA_A + 1] + data[k, MED_SIGMA_S + 1]
    t2 = data[k, MED_SIGMA_A + 2] + data[k, MED_SIGMA_S + 2]
    return (
        math.exp(-t0 * distance) if t0 > 0.0 else 1.0,
        math.exp(-t1 * distance) if t1 > 0.0 else 1.0,
        math.exp(-t2 * distance) if t2 > 0.0 else 1.0,
    )
