"""The environment as a light (`[environment]`): path mode samples it in proportion to its
radiance (kernels/shading/environment.py has the lookup and the sampling), one row at infinity.
Trace mode sees it only as what rays that hit nothing meet."""

import math

import numpy as np

from ...vec import inline_function, mul
from ..environment import environment_pdf, environment_radiance_pdf, sample_environment
from .sampling import disk_density, disk_origin

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
    return 4 * math.pi * math.pi * radius**2 * float(image.mean(dtype=np.float64))  # float32 sums overflow


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    wi, radiance, pdf_ = sample_environment(Env, u1, u2)
    return wi, INF, radiance, pdf_, False


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    return environment_pdf(Env, wi)


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a direction towards the light sampled as `sample` does, the ray from the
    disk of the scene's bounding sphere facing it (pbrt)."""
    to_light, radiance, pdf_dir = sample_environment(Env, u1, u2)
    p, pdf_pos = disk_origin(B, to_light, u3, u4)
    return p, (0.0, 0.0, 0.0), mul(to_light, -1.0), radiance, pdf_pos, pdf_dir, -1


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    radiance, pdf_dir = environment_radiance_pdf(Env, mul(w, -1.0))
    return radiance, disk_density(B), pdf_dir
