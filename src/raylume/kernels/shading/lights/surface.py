"""Emissive surfaces: every primitive (triangle, sphere, quad, disk) whose material has
`emission`, one row each, radiance the emission on both sides (path mode only: trace mode shows
the emission as the surface's own colour, no light). The primitive table's PRIM_LIGHT column
points back to the row, so that a BSDF-sampled ray that hits the primitive finds the pdf with
which next-event estimation would have chosen the point (MIS). Spheres are sampled by the cone
they subtend, the others uniformly over their area (shapes.sample_surface)."""

import math

import numpy as np

from ...film.sampler import uniform_sphere
from ...geometry import shape_sphere
from ...geometry.shapes import PRIM_KIND, PRIM_ROW, sample_surface
from ...geometry.shapes import SPHERE as SHAPE_SPHERE
from ...vec import inline_function, madd, row3
from .sampling import (
    area_pdf,
    cosine_two_sided,
    sphere_cone,
    sphere_cone_pdf,
    towards_point,
    two_sided_pdf,
)
from .table import EMIT_AREA, EMIT_PRIM, LIGHT_INTENSITY

NAME = "surface"
KIND = 6
DELTA = False
INFINITE = False
VISIBLE = False  # seen as the primitive it is (the BVH finds it)
FALLOFF = False
EVERYWHERE = False


def power(area: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """Emitted power of primitives of one-sided `area` (P,) and radiance (P, 3): both sides."""
    return 2 * math.pi * area * radiance.mean(axis=1)


@inline_function
def surface_point(G, X, Em, e, u1, u2):
    """A point uniform over the primitive: (True, the point, its unit normal, the area,
    radiance); (False, ...) for a sphere, which `sample` samples by its cone instead."""
    data = Em.data
    radiance = row3(data, e, LIGHT_INTENSITY)
    k = int(data[e, EMIT_PRIM])
    if G.prims[k, PRIM_KIND] == SHAPE_SPHERE:
        return False, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0, radiance
    q, n = sample_surface(G, k, u1, u2)
    return True, q, n, data[e, EMIT_AREA], radiance


@inline_function
def sample(G, X, Em, Env, e, p, u1, u2, key):
    """Path mode: a point of the primitive seen from p (a sphere: a direction in its cone)."""
    on_surface, q, n, area, radiance = surface_point(G, X, Em, e, u1, u2)
    if on_surface:
        return towards_point(p, q, n, area, radiance)
    data = Em.data
    row = np.int64(G.prims[int(data[e, EMIT_PRIM]), PRIM_ROW])
    centre = row3(G.shapes, row, shape_sphere.CENTER)
    radius = G.shapes[row, shape_sphere.RADIUS]
    wi, dist, pdf_ = sphere_cone(centre, radius, p, u1, u2)
    return wi, dist, radiance, pdf_, False


@inline_function
def primitive(Em, e):
    """The primitive this light's points lie on: what a shadow ray towards it ends short of
    (traverse.any_hit_between's `arriving`)."""
    return np.int64(Em.data[e, EMIT_PRIM])


@inline_function
def pdf(G, X, Em, Env, e, p, wi, dist, n_hit, hit):
    data = Em.data
    k = int(data[e, EMIT_PRIM])
    if G.prims[k, PRIM_KIND] == SHAPE_SPHERE:
        row = np.int64(G.prims[k, PRIM_ROW])
        return sphere_cone_pdf(
            row3(G.shapes, row, shape_sphere.CENTER), G.shapes[row, shape_sphere.RADIUS], p, wi, dist
        )
    return area_pdf(p, madd(p, wi, dist), n_hit, data[e, EMIT_AREA])


@inline_function
def emit(G, X, Em, Env, e, u1, u2, u3, u4, key, B):
    """Bidirectional: a point uniform over the primitive and a cosine direction on either side
    (spheres too: path mode sees their emission from inside as well)."""
    data = Em.data
    k = int(data[e, EMIT_PRIM])
    radiance = row3(data, e, LIGHT_INTENSITY)
    pdf_pos = 1.0 / data[e, EMIT_AREA]
    if G.prims[k, PRIM_KIND] == SHAPE_SPHERE:
        row = np.int64(G.prims[k, PRIM_ROW])
        n = uniform_sphere(u1, u2)
        q = madd(row3(G.shapes, row, shape_sphere.CENTER), n, G.shapes[row, shape_sphere.RADIUS])
        w = cosine_two_sided(n, u3, u4)
        return q, n, w, radiance, pdf_pos, two_sided_pdf(n, w), np.int64(k)
    q, n = sample_surface(G, k, u1, u2)
    w = cosine_two_sided(n, u3, u4)
    return q, n, w, radiance, pdf_pos, two_sided_pdf(n, w), np.int64(k)


@inline_function
def emit_pdf(G, X, Em, Env, e, p, n, w, hit, B):
    data = Em.data
    pdf_pos = 1.0 / data[e, EMIT_AREA]
    return row3(data, e, LIGHT_INTENSITY), pdf_pos, two_sided_pdf(n, w)
