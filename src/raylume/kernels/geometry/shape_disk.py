"""Disk: a centre, a unit normal and a radius (two-sided). Row: centre (3), unit normal (3),
radius, then the unit tangent e1 (3) that UVs measure angles from."""

import math

import numpy as np

from ..film.sampler import concentric_disk
from ..vec import cross, dot, inline_function, kernel_function, length, madd, row3, sub
from .shape_plane import intersect_plane
from .transform import transform_point, transform_unit_normal, uniform_scale

INF = math.inf
CENTER = 0
NORMAL = 3
RADIUS = 6
TANGENT = 7
BOUNDED = True


def pack(obj, m: np.ndarray) -> list[float]:
    """The disk's row, its transform m (4x4, object to world) applied."""
    from .shape_sphere import basis

    n = transform_unit_normal(m, obj.normal)
    e1, _ = basis(n)
    return [*transform_point(m, obj.center), *n, obj.radius * uniform_scale(m), *e1]


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact boxes: along axis k a disk reaches radius * sqrt(1 - n_k^2) from its centre."""
    n = rows[:, NORMAL : NORMAL + 3]
    reach = rows[:, RADIUS : RADIUS + 1] * np.sqrt(np.clip(1.0 - n * n, 0.0, 1.0))
    c = rows[:, CENTER : CENTER + 3]
    return c - reach, c + reach


@kernel_function
def intersect(rows, i, o, d, tmin, tmax):
    """The supporting plane's hit, kept when it lies within the radius."""
    c = row3(rows, i, CENTER)
    t = intersect_plane(o, d, c, row3(rows, i, NORMAL), tmin, tmax)
    if t == INF:
        return INF
    rel = sub(madd(o, d, t), c)
    r = rows[i, RADIUS]
    if dot(rel, rel) > r * r:
        return INF
    return t


@inline_function
def normal(rows, i, p):
    return row3(rows, i, NORMAL)


@kernel_function
def uv(rows, i, p):
    """u: the angle around the normal from the tangent, over 2 pi (0..1); v: the distance from
    the centre over the radius (0 at the centre, 1 on the rim)."""
    rel = sub(p, row3(rows, i, CENTER))
    e1 = row3(rows, i, TANGENT)
    e2 = cross(row3(rows, i, NORMAL), e1)
    phi = math.atan2(dot(rel, e2), dot(rel, e1))
    if phi < 0.0:
        phi += 2.0 * math.pi
    return phi * (0.5 / math.pi), min(length(rel) / rows[i, RADIUS], 1.0)


# --- rasterizer tessellation ------------------------------------------------------------------

TOLERANCE_PX = 0.1
SEGMENTS = (24, 4096)


def circle_segments(radius: float, nearest: float, px_per_rad: float) -> int:
    """Segments of a polygon whose chords stray less than TOLERANCE_PX from a circle of this
    radius seen from `nearest` away: the sagitta r (1 - cos(pi / n)) on screen."""
    radius_px = radius * px_per_rad / max(nearest, 1e-300)
    sag = TOLERANCE_PX / max(radius_px, 1e-300)
    if sag >= 2.0:
        return SEGMENTS[0]
    return int(np.clip(math.ceil(math.pi / math.acos(1.0 - sag)), *SEGMENTS))


def ring(center, e1, e2, radius: float, segments: int) -> np.ndarray:
    """(segments, 3) points on the circle; polygon vertices lie on the circle, so the polygon
    is inside it by at most the sagitta."""
    phi = 2.0 * math.pi * np.arange(segments) / segments
    return center + radius * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)


def fan(center, points: np.ndarray) -> np.ndarray:
    """(n, 9) triangles from `center` to consecutive points of a closed ring."""
    nxt = np.roll(np.arange(len(points)), -1)
    return np.concatenate([np.broadcast_to(center, points.shape), points, points[nxt]], axis=1)


def nearest_distance(center, normal, radius: float, eye) -> float:
    """Distance from the eye to the nearest point of the disk."""
    rel = np.asarray(eye, dtype=np.float64) - center
    height = float(np.dot(rel, normal))
    radial = float(np.linalg.norm(rel - height * normal))
    return math.hypot(height, max(radial - radius, 0.0))


def tessellate(row: np.ndarray, view) -> np.ndarray:
    center = np.asarray(row[CENTER : CENTER + 3], dtype=np.float64)
    n = np.asarray(row[NORMAL : NORMAL + 3], dtype=np.float64)
    e1 = np.asarray(row[TANGENT : TANGENT + 3], dtype=np.float64)
    radius = float(row[RADIUS])
    segments = circle_segments(radius, nearest_distance(center, n, radius, view.eye), view.px_per_rad)
    return fan(center, ring(center, e1, np.cross(n, e1), radius, segments))


# --- emission (path mode samples emissive shapes) ---------------------------------------------


@kernel_function
def sample(rows, i, u1, u2):
    """A uniform point on disk i for (u1, u2) in [0, 1)^2 (concentric map), and the normal."""
    n = row3(rows, i, NORMAL)
    e1 = row3(rows, i, TANGENT)
    e2 = cross(n, e1)
    a, b = concentric_disk(u1, u2)
    r = rows[i, RADIUS]
    return madd(madd(row3(rows, i, CENTER), e1, a * r), e2, b * r), n


def area(rows: np.ndarray) -> np.ndarray:
    return math.pi * rows[:, RADIUS] ** 2
