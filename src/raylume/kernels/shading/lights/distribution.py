"""Path mode's choice among lights: a cdf over the light table's rows in proportion to power
(compile/lights.py builds it), and the area lights that rays see beside the BVH."""

import math

from ...vec import inline_function, kernel_function, last_at_most
from ..environment import environment_radiance, environment_radiance_pdf
from .registry import visible_hit

INF = math.inf


@kernel_function
def pick_emitter(cdf, u):
    """The row whose share of the cdf holds u, and the probability of picking it."""
    n = cdf.shape[0] - 1
    lo = last_at_most(cdf, 0, n, u * cdf[n])
    return lo, (cdf[lo + 1] - cdf[lo]) / cdf[n]


@inline_function
def pick_probability(cdf, e):
    """The probability of picking row e: 0 when nothing emits (a black environment alone: its
    row's share was 0 / 0, and every path that met it a NaN sample)."""
    total = cdf[cdf.shape[0] - 1]
    return (cdf[e + 1] - cdf[e]) / total if total > 0.0 else 0.0


@kernel_function
def hit_area_lights(Em, o, d, tmax):
    """The nearest area light (rows 0..n_area-1, the VISIBLE kinds) along the ray before tmax:
    (t, row, normal), row -1 when none."""
    best = tmax
    hit = -1
    normal = (0.0, 0.0, 1.0)
    for e in range(Em.n_area):
        t, n = visible_hit(Em, e, o, d, best)
        if t < best:
            best = t
            hit = e
            normal = n
    return best, hit, normal


@inline_function
def area_light_blocks(Em, target, o, d, tmax):
    """Whether an area light other than row `target` (-1: any) lies on the shadow ray before
    tmax. Area lights (quads, spheres) are not in the BVH, so any_hit does not see them; they stop
    shadow rays as they stop every other ray (a light behind another is in its shadow, as in
    Mitsuba, where emitters are shapes). A scene's one area light never blocks the rays aimed
    at it: the loop is then empty."""
    for e in range(Em.n_area):
        if e != target:
            t, _ = visible_hit(Em, e, o, d, tmax)
            if t < tmax:
                return True
    return False


@inline_function
def environment_light(Env, d):
    """Radiance of the environment along d (zero without one)."""
    if Env.present:
        return environment_radiance(Env, d)
    return (0.0, 0.0, 0.0)


@inline_function
def environment_arrival(Em, Env, d):
    """What a ray that leaves the scene along d meets of the environment: (its radiance, the
    density with which next-event estimation picks and samples that direction), one lookup of
    d's image coordinates for both. Zero and 0 without an environment."""
    if not Env.present:
        return (0.0, 0.0, 0.0), 0.0
    rgb, pdf = environment_radiance_pdf(Env, d)
    return rgb, pick_probability(Em.cdf, Em.environment_row) * pdf
