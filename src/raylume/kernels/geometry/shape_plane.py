"""Infinite plane: a point on it and its unit normal. Unbounded: it lives outside the BVH and
is tested before traversal. Row: point (3), unit normal (3)."""

import math

import numpy as np

from ..vec import cross, dot, inline_function, kernel_function, normalize, row3, sub
from .transform import transform_point, transform_unit_normal, unit_vector

INF = math.inf
POINT = 0
NORMAL = 3
BOUNDED = False
# Rasterizer: half-side of the square drawn for a plane, in units of the scene's size.
RASTER_EXTENT = 1e5


def pack(obj, m: np.ndarray) -> list[float]:
    """The plane's row, its transform m (4x4, object to world) applied."""
    if np.array_equal(m, np.eye(4)):  # as written, to the bit (a -0.0 kept: it orients the UVs' basis)
        return [*obj.point, *unit_vector(obj.normal)]
    return [*transform_point(m, obj.point), *transform_unit_normal(m, obj.normal)]


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.full((len(rows), 3), -np.inf), np.full((len(rows), 3), np.inf)


@kernel_function
def intersect_plane(o, d, point, normal, tmin, tmax):
    denom = dot(d, normal)
    if denom == 0.0:
        return INF
    t = dot(sub(point, o), normal) / denom
    if t > tmin and t < tmax:
        return t
    return INF


@inline_function
def intersect(rows, i, o, d, tmin, tmax):
    return intersect_plane(o, d, row3(rows, i, POINT), row3(rows, i, NORMAL), tmin, tmax)


@inline_function
def normal(rows, i, p):
    return row3(rows, i, NORMAL)


@kernel_function
def uv(rows, i, p):
    """World units along two axes of the plane: right and up of a wall facing -z; x and z on
    a floor."""
    n = row3(rows, i, NORMAL)
    hint = (0.0, 0.0, 1.0) if abs(n[1]) > 0.999 else (0.0, 1.0, 0.0)
    t1 = normalize(cross(n, hint))
    t2 = cross(t1, n)
    rel = sub(p, row3(rows, i, POINT))
    return dot(rel, t1), dot(rel, t2)


def tessellate(row: np.ndarray, view) -> np.ndarray:
    """float64 (8, 9): a square of the plane centred on the eye's foot point, 2 x 2 quads, of
    half-side RASTER_EXTENT times the scene's size (its extent, the eye's height above the
    plane, at least 1). Perspective needs no finer split: depth and attributes come from each
    triangle's exact plane, and triangles passing behind the eye are clipped at the near
    plane. The far edge lies about 1e-5 radians below the true horizon."""
    from .shape_sphere import basis

    point = np.asarray(row[POINT : POINT + 3], dtype=np.float64)
    n = np.asarray(row[NORMAL : NORMAL + 3], dtype=np.float64)
    n = n / np.linalg.norm(n)
    eye = np.asarray(view.eye, dtype=np.float64)
    height = float(np.dot(eye - point, n))
    foot = eye - height * n
    half = RASTER_EXTENT * max(view.scale, abs(height), 1.0)
    e1, e2 = basis(n)
    s = np.array([-half, 0.0, half])
    grid = foot + s[:, None, None] * e1 + s[None, :, None] * e2  # (3, 3, 3)
    quads = []
    for a in range(2):
        for b in range(2):
            p00, p10, p01, p11 = grid[a, b], grid[a + 1, b], grid[a, b + 1], grid[a + 1, b + 1]
            quads += [np.concatenate([p00, p10, p11]), np.concatenate([p00, p11, p01])]
    return np.asarray(quads)
