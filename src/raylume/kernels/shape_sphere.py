"""Sphere: centre and radius. Row of the analytic shape table: centre (3), radius."""

import math

import numpy as np
from numba import njit

from .vec import KERNEL, dot, normalize, row3, sub

INF = math.inf
CENTER = 0
RADIUS = 3
BOUNDED = True


def pack(obj) -> list[float]:
    return [*obj.center, obj.radius]


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return rows[:, CENTER : CENTER + 3] - rows[:, RADIUS : RADIUS + 1], rows[:, CENTER : CENTER + 3] + rows[
        :, RADIUS : RADIUS + 1
    ]


@njit(**KERNEL)
def intersect_sphere(o, d, center, radius, tmin, tmax):
    """The seed's quadratic in a stable form (Ray Tracing Gems ch. 7): the discriminant is
    computed from the ray's closest approach, and the second root via Vieta, so neither a
    radius-5000 sphere nor a grazing ray loses precision to cancellation. Unit d; the hit
    distance in (tmin, tmax) or +inf."""
    co = sub(o, center)
    b = dot(co, d)  # half the seed's b, with a = dot(D, D) = 1
    c = dot(co, co) - radius * radius
    if c > 0.0 and b > 0.0:
        return INF  # outside, moving away: both roots are negative (tmin >= 0 always)
    px = co[0] - b * d[0]
    py = co[1] - b * d[1]
    pz = co[2] - b * d[2]
    disc = radius * radius - (px * px + py * py + pz * pz)
    if disc < 0.0:
        return INF
    q = -b - math.copysign(math.sqrt(disc), b)
    if q == 0.0:
        return INF
    t0 = c / q
    t1 = q
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tmin and t0 < tmax:
        return t0
    if t1 > tmin and t1 < tmax:
        return t1
    return INF


@njit(**KERNEL, inline="always")
def intersect(rows, i, o, d, tmin, tmax):
    return intersect_sphere(o, d, row3(rows, i, CENTER), rows[i, RADIUS], tmin, tmax)


@njit(**KERNEL, inline="always")
def normal(rows, i, p):
    return normalize(sub(p, row3(rows, i, CENTER)))


@njit(**KERNEL)
def uv(rows, i, p):
    """u = 0.5 + atan2(n.x, -n.z) / 2pi (0.5 faces -z, the default camera; the seam is at the
    back, +z), v = 0.5 + asin(n.y) / pi (0 at the south pole, 1 at the north)."""
    n = normal(rows, i, p)
    u = 0.5 + math.atan2(n[0], -n[2]) * (0.5 / math.pi)
    v = 0.5 + math.asin(min(1.0, max(-1.0, n[1]))) / math.pi
    return u, v


# --- rasterizer tessellation ------------------------------------------------------------------

TOLERANCE_PX = 0.1
RINGS = (8, 1024)
SEGMENTS = (24, 2048)


def basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vector `axis` to an orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def tessellate(row: np.ndarray, view) -> np.ndarray:
    return sphere_cap(row[CENTER : CENTER + 3], float(row[RADIUS]), view.eye, view.px_per_rad)


def sphere_cap(center, radius: float, eye, px_per_rad: float) -> np.ndarray:
    """float64 (N, 9): the part of the sphere visible from `eye`.

    Tessellated around the axis from the centre towards the eye: a fan at the pole nearest the
    eye, then rings out to the silhouette (polar angle acos(r / D) for an eye at distance
    D > r; the whole sphere when the eye is inside). Rings are spaced by the angle a ring step
    subtends *at the eye* (an eye just above a huge sphere, like the seed's ground, gets fine
    rings under it and coarse ones far away); ring and segment counts keep every chord within
    TOLERANCE_PX of the true sphere on screen, clamped to RINGS and SEGMENTS."""
    center = np.asarray(center, dtype=np.float64)
    to_eye = np.asarray(eye, dtype=np.float64) - center
    dist = float(np.linalg.norm(to_eye))
    axis = to_eye / dist if dist > 1e-12 * radius else np.array([0.0, 1.0, 0.0])
    inside = dist <= radius
    theta_max = math.pi if inside else math.acos(radius / dist)

    # Eye-to-surface distance along the meridian, and u(theta) = integral of r dtheta / that:
    # the angle a meridian step subtends at the eye. Rings are spaced evenly in u.
    theta = np.linspace(0.0, theta_max, 4097)
    # |eye - point|^2 = (D - r)^2 + 4 D r sin^2(theta / 2): no cancellation when D ~ r
    reach = np.sqrt((dist - radius) ** 2 + 4.0 * dist * radius * np.sin(0.5 * theta) ** 2)
    reach = np.maximum(reach, 1e-9 * radius)
    du = radius / reach
    u = np.concatenate([[0.0], np.cumsum(0.5 * (du[1:] + du[:-1]) * np.diff(theta))])
    far = float(reach.max())
    # A chord over a step of theta strays radius * dtheta^2 / 8 from the sphere; seen from up
    # to `far` away that is (du^2 * far / (8 radius)) radians on screen.
    step_u = math.sqrt(8.0 * TOLERANCE_PX * radius / (far * px_per_rad))
    rings = int(np.clip(math.ceil(u[-1] / step_u), *RINGS))
    ring_theta = np.interp(np.linspace(0.0, u[-1], rings + 1)[1:], u, theta)
    if inside:
        ring_theta = ring_theta[:-1]  # the last "ring" is the antipode: a pole, below
    # Segments: the widest ring (the silhouette) must be polygonal by less than the tolerance.
    widest = float((np.sin(ring_theta) * radius / np.interp(ring_theta, theta, reach)).max())
    sag = TOLERANCE_PX / max(widest * px_per_rad, 1e-300)  # allowed 1 - cos(pi / n)
    segments = int(np.clip(math.ceil(math.pi / math.acos(max(1.0 - sag, -1.0))) if sag < 2 else 0, *SEGMENTS))

    e1, e2 = basis(axis)
    phi = 2.0 * math.pi * np.arange(segments) / segments
    st, ct = np.sin(ring_theta)[:, None, None], np.cos(ring_theta)[:, None, None]
    ring_dirs = ct * axis + st * (np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2)
    ring_pts = center + radius * ring_dirs  # (rings, segments, 3)
    pole = center + radius * axis
    nxt = np.roll(np.arange(segments), -1)
    tris = [np.stack([np.broadcast_to(pole, (segments, 3)), ring_pts[0], ring_pts[0, nxt]], axis=1)]
    if len(ring_pts) > 1:
        a, b = ring_pts[:-1], ring_pts[:-1, nxt]
        c, d = ring_pts[1:], ring_pts[1:, nxt]
        tris.append(np.stack([a, c, b], axis=2).reshape(-1, 3, 3))
        tris.append(np.stack([b, c, d], axis=2).reshape(-1, 3, 3))
    if inside:
        antipode = center - radius * axis
        last = ring_pts[-1]
        tris.append(np.stack([last, np.broadcast_to(antipode, (segments, 3)), last[nxt]], axis=1))
    return np.concatenate(tris).reshape(-1, 9)


def area(rows: np.ndarray) -> np.ndarray:
    """Surface areas (emission: path mode samples a sphere by the cone it subtends, emitters.py)."""
    return 4.0 * math.pi * rows[:, RADIUS] ** 2
