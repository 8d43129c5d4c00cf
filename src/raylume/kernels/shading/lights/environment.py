"""The environment as a light (`[environment]`): path mode samples it in proportion to its
radiance (kernels/shading/environment.py has the lookup and the sampling), one row at infinity.
Trace mode sees it only as what rays that hit nothing meet."""

import math

from ...vec import inline_function
from ..environment import environment_pdf, sample_environment

NAME = "environment"
KIND = 7
DELTA = False
INFINITE = True
VISIBLE = False  # seen by rays that leave the scene (path.py looks it up)
FALLOFF = False
EVERYWHERE = False
INF = math.inf


def power(image, radius: float) -> float:
    """Power of an environment of this (mean) radiance image around a scene of `radius`."""
    return 4 * math.pi * math.pi * radius**2 * float(image.mean())


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    wi, radiance, pdf_ = sample_environment(Env, u1, u2)
    return wi, INF, radiance, pdf_, False


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return environment_pdf(Env, wi)
