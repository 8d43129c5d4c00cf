"""Cylinder: the centres p0 and p1 of its ends and a radius; `capped` closes both ends with
disks, otherwise it is an open tube (two-sided). Row: p0 (3), p1 (3), radius, capped (0/1),
unit axis (3) from p0 to p1, height |p1 - p0|, unit tangent e1 (3) for UVs.

A hit reports which part it struck in its first barycentric slot (PART_SIDE, PART_BOTTOM at
p0, PART_TOP at p1), so the surface normal needs no guess at the rim."""

import math

import numpy as np

from ..vec import cross, dot, inline_function, kernel_function, madd, mul, normalize, row3, sub
from .transform import transform_point, uniform_scale

INF = math.inf
P0 = 0
P1 = 3
RADIUS = 6
CAPPED = 7
AXIS = 8
HEIGHT = 11
TANGENT = 12
BOUNDED = True
PART_SIDE = 0.0
PART_BOTTOM = 1.0
PART_TOP = 2.0


def pack(obj, m: np.ndarray) -> list[float]:
    """The cylinder's row, its transform m (4x4, object to world) applied."""
    from .shape_sphere import basis

    p0 = transform_point(m, obj.p0)
    p1 = transform_point(m, obj.p1)
    axis = p1 - p0
    height = float(np.linalg.norm(axis))
    axis = axis / height
    e1, _ = basis(axis)
    return [*p0, *p1, obj.radius * uniform_scale(m), 1.0 if obj.capped else 0.0, *axis, height, *e1]


def solid(row) -> tuple | None:
    """A capped cylinder as a solid (compile/media.py): (point -> inside?, a point of its
    surface, its volume); None when it is an open tube, which has no inside."""
    if row[CAPPED] == 0.0:
        return None
    p0, axis = np.asarray(row[P0 : P0 + 3]), np.asarray(row[AXIS : AXIS + 3])
    radius, height = float(row[RADIUS]), float(row[HEIGHT])

    def inside(p) -> bool:
        s = float((np.asarray(p) - p0) @ axis)
        return 0.0 < s < height and float(np.sum((np.asarray(p) - p0 - s * axis) ** 2)) < radius * radius

    side = np.asarray(row[TANGENT : TANGENT + 3])
    return inside, p0 + axis * height / 2 + radius * side, np.pi * radius * radius * height


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact boxes: the union of the two end circles' boxes."""
    a = rows[:, AXIS : AXIS + 3]
    reach = rows[:, RADIUS : RADIUS + 1] * np.sqrt(np.clip(1.0 - a * a, 0.0, 1.0))
    p0, p1 = rows[:, P0 : P0 + 3], rows[:, P1 : P1 + 3]
    return np.minimum(p0, p1) - reach, np.maximum(p0, p1) + reach


@kernel_function
def intersect(rows, i, o, d, tmin, tmax):
    """Nearest of the side's two roots within the height and, when capped, the end disks.
    Returns (t, part). The side's quadratic is solved as the sphere's is: from the ray's
    closest approach to the axis and by Vieta, free of cancellation for distant rays."""
    p0 = row3(rows, i, P0)
    a = row3(rows, i, AXIS)
    r = rows[i, RADIUS]
    h = rows[i, HEIGHT]
    rel = sub(o, p0)
    oz = dot(rel, a)
    dz = dot(d, a)
    op = madd(rel, a, -oz)  # origin and direction across the axis
    dp = madd(d, a, -dz)
    best = tmax
    part = PART_SIDE
    aa = dot(dp, dp)
    if aa > 0.0:
        b = dot(op, dp)
        closest = madd(op, dp, -b / aa)
        disc = r * r - dot(closest, closest)
        if disc >= 0.0:
            q = -b - math.copysign(math.sqrt(aa * disc), b)
            if q != 0.0:
                t0 = q / aa
                t1 = (dot(op, op) - r * r) / q
                if t0 > t1:
                    t0, t1 = t1, t0
                for t in (t0, t1):
                    if t > tmin and t < best:
                        z = oz + t * dz
                        if z >= 0.0 and z <= h:
                            best = t
                            break
    if rows[i, CAPPED] > 0.0 and dz != 0.0:
        for cap in range(2):
            t = ((h if cap == 1 else 0.0) - oz) / dz
            if t > tmin and t < best:
                s = madd(op, dp, t)
                if dot(s, s) <= r * r:
                    best = t
                    part = PART_TOP if cap == 1 else PART_BOTTOM
    if best < tmax:
        return best, part
    return INF, part


@inline_function
def normal(rows, i, p, part):
    a = row3(rows, i, AXIS)
    if part == PART_TOP:
        return a
    if part == PART_BOTTOM:
        return mul(a, -1.0)
    rel = sub(p, row3(rows, i, P0))
    return normalize(madd(rel, a, -dot(rel, a)))


@kernel_function
def uv(rows, i, p, part):
    """u: the angle around the axis from the tangent, over 2 pi; v: on the side the height
    from p0 over the length (0 at p0, 1 at p1), on the caps the distance from the axis over
    the radius."""
    a = row3(rows, i, AXIS)
    rel = sub(p, row3(rows, i, P0))
    z = dot(rel, a)
    across = madd(rel, a, -z)
    e1 = row3(rows, i, TANGENT)
    phi = math.atan2(dot(across, cross(a, e1)), dot(across, e1))
    if phi < 0.0:
        phi += 2.0 * math.pi
    u = phi * (0.5 / math.pi)
    if part == PART_SIDE:
        return u, min(max(z / rows[i, HEIGHT], 0.0), 1.0)
    return u, min(math.sqrt(dot(across, across)) / rows[i, RADIUS], 1.0)


def tessellate(row: np.ndarray, view) -> tuple[np.ndarray, np.ndarray]:
    """(triangles, the part of each): the side as a band of quads between the end circles (and the caps as fans), with
    enough segments that chords stay within the disks' tolerance on screen."""
    from .shape_disk import circle_segments, fan, nearest_distance, ring

    row = np.asarray(row, dtype=np.float64)
    p0, p1 = row[P0 : P0 + 3], row[P1 : P1 + 3]
    a, e1 = row[AXIS : AXIS + 3], row[TANGENT : TANGENT + 3]
    e2 = np.cross(a, e1)
    r = float(row[RADIUS])
    nearest = min(
        nearest_distance(p0, a, r, view.eye),
        nearest_distance(p1, a, r, view.eye),
        _side_distance(p0, a, float(row[HEIGHT]), r, view.eye),
    )
    segments = circle_segments(r, nearest, view.px_per_rad)
    bottom, top = ring(p0, e1, e2, r, segments), ring(p1, e1, e2, r, segments)
    nxt = np.roll(np.arange(segments), -1)
    side = np.concatenate(
        [np.concatenate([bottom, top, top[nxt]], axis=1), np.concatenate([bottom, top[nxt], bottom[nxt]], axis=1)]
    )
    parts = [np.full(len(side), PART_SIDE)]
    if row[CAPPED] > 0.0:
        side = np.concatenate([side, fan(p0, bottom), fan(p1, top)])
        parts += [np.full(segments, PART_BOTTOM), np.full(segments, PART_TOP)]
    return side, np.concatenate(parts)


def _side_distance(p0, axis, height: float, radius: float, eye) -> float:
    rel = np.asarray(eye, dtype=np.float64) - p0
    z = float(np.dot(rel, axis))
    radial = float(np.linalg.norm(rel - z * axis))
    dz = max(-z, z - height, 0.0)
    return math.hypot(dz, abs(radial - radius))
