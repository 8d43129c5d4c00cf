"""Quad: a parallelogram with centre `position` and edge vectors u and v, spanning
position +- u/2 +- v/2 (as the quad light). Two-sided; its normal is u x v, normalised.
Row: centre (3), u (3), v (3), unit normal (3), w = (u x v) / |u x v|^2 (3): the dual vector
that gives a point's (a, b) in p - centre = a u + b v."""

import math

import numpy as np

from ..vec import cross, dot, inline_function, kernel_function, madd, row3, sub
from .shape_plane import intersect_plane
from .transform import transform_point, transform_vector, unit_vector

INF = math.inf
CENTER = 0
U = 3
V = 6
NORMAL = 9
DUAL = 12
BOUNDED = True


def pack(obj, m: np.ndarray) -> list[float]:
    """The quad's row, its transform m (4x4, object to world) applied."""
    u = transform_vector(m, obj.u)
    v = transform_vector(m, obj.v)
    n = np.cross(u, v)
    return [*transform_point(m, obj.position), *u, *v, *unit_vector(n), *(n / np.dot(n, n))]


def corners(rows: np.ndarray) -> np.ndarray:
    """(N, 4, 3): c - u/2 - v/2, c + u/2 - v/2, c + u/2 + v/2, c - u/2 + v/2."""
    c, u, v = rows[:, None, CENTER : CENTER + 3], rows[:, None, U : U + 3], rows[:, None, V : V + 3]
    a = np.array([-0.5, 0.5, 0.5, -0.5])[None, :, None]
    b = np.array([-0.5, -0.5, 0.5, 0.5])[None, :, None]
    return c + a * u + b * v


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    k = corners(rows)
    return k.min(axis=1), k.max(axis=1)


@kernel_function
def local(rows, i, p):
    """(a, b) with p - centre = a u + b v, for p in the quad's plane; |a|, |b| <= 1/2 inside."""
    rel = sub(p, row3(rows, i, CENTER))
    w = row3(rows, i, DUAL)
    return dot(w, cross(rel, row3(rows, i, V))), dot(w, cross(row3(rows, i, U), rel))


@kernel_function
def intersect(rows, i, o, d, tmin, tmax):
    """The supporting plane's hit, kept when it lies within the parallelogram."""
    t = intersect_plane(o, d, row3(rows, i, CENTER), row3(rows, i, NORMAL), tmin, tmax)
    if t == INF:
        return INF
    a, b = local(rows, i, madd(o, d, t))
    if abs(a) > 0.5 or abs(b) > 0.5:
        return INF
    return t


@inline_function
def normal(rows, i, p):
    return row3(rows, i, NORMAL)


@kernel_function
def uv(rows, i, p):
    """(0, 0) at centre - u/2 - v/2, (1, 0) at centre + u/2 - v/2, (0, 1) at centre - u/2 + v/2."""
    a, b = local(rows, i, p)
    return min(max(a + 0.5, 0.0), 1.0), min(max(b + 0.5, 0.0), 1.0)


# tessellate's triangles are exactly the parallelogram: a small scene's sweep filters rays with
# them (shapes.exact_triangles, sweep.py)
TESSELLATION_IS_EXACT = True


def tessellate(row: np.ndarray, view) -> np.ndarray:
    """Two triangles: exactly the parallelogram."""
    k = corners(np.asarray(row, dtype=np.float64)[None, :])[0]
    return np.array([np.concatenate([k[0], k[1], k[2]]), np.concatenate([k[0], k[2], k[3]])])


# --- emission (path mode samples emissive shapes) ---------------------------------------------


@kernel_function
def sample(rows, i, u1, u2):
    """A uniform point on quad i for (u1, u2) in [0, 1)^2, and the normal there."""
    c = madd(madd(row3(rows, i, CENTER), row3(rows, i, U), u1 - 0.5), row3(rows, i, V), u2 - 0.5)
    return c, row3(rows, i, NORMAL)


def area(rows: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.cross(rows[:, U : U + 3], rows[:, V : V + 3]), axis=1)
