"""`--mode raster`: a Z-buffer rasterizer over the scene's triangles, with the ray caster's camera.

Rasterization projects every triangle and fills the pixel centres it covers, keeping the
nearest under a Z-buffer: its cost grows linearly with the number of triangles, where ray
casting through a BVH grows about logarithmically. Both modes use the same camera (pixel
centres, DESIGN.md), the same AOVs, and the same local lighting as `trace` (ambient,
diffuse, specular) -- but the rasterizer has no shadows, reflection or refraction.

The kernels and the details of scan conversion (2D homogeneous edge functions,
perspective-correct depth and barycentrics, near-plane clipping, the top-left fill rule,
deterministic banded parallelism) are in `kernels/raster_kernel.py`. This module turns the
non-triangle shapes into triangles:

* Spheres become the cap that the camera can see, tessellated around the axis from the
  sphere's centre towards the camera: a fan at the pole nearest the camera, then rings out
  to the silhouette (the horizon circle, polar angle acos(r / D) for a camera at distance
  D > r; the whole sphere when the camera is inside). Ring spacing keeps each ring step a
  roughly constant angle *as seen from the camera* (so a camera just above a huge sphere,
  like the seed scene's ground, gets fine rings under it and coarse ones far away), and
  ring and segment counts are chosen so that no chord strays more than SPHERE_TOLERANCE_PX
  (a tenth of a pixel) from the true sphere on screen, clamped to SPHERE_RINGS and
  SPHERE_SEGMENTS. Shading uses the analytic sphere normal at the rasterized point, so only
  the silhouette and the depth differ from the ray caster, by less than that tolerance.
* Planes become a square of half-side PLANE_EXTENT times the scene's size (its extent, the
  camera's height above the plane, at least 1), centred on the camera's foot point on the
  plane, in 2 x 2 quads (8 triangles). Perspective needs no further splitting, because depth
  and attributes come from the exact plane of each triangle, and triangles passing under or
  behind the camera are clipped against the near plane. The far edge lies 1e-5 radians
  below the true horizon as seen from the camera's height (a fraction of a pixel below 4k).

All these triangles carry their shape's object index and prim 0, as the ray caster reports.
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

from .kernels.layout import HIT_PLANE, HIT_SPHERE
from .kernels.raster_kernel import rasterize_arrays

SPHERE_TOLERANCE_PX = 0.1
SPHERE_RINGS = (8, 1024)
SPHERE_SEGMENTS = (24, 2048)
PLANE_EXTENT = 1e5
NEAR_FRACTION = 1e-30  # near plane distance, as a fraction of the scene's extent


def rasterize(scene, compiled, progress: Callable[[int, int], None] | None = None, aovs: bool = True):
    """Render `scene` by rasterization, one sample at each pixel centre (spp does not apply).
    Returns (rgb, aovs, kernel_seconds, rays=0); `aovs` is empty when not wanted."""
    settings = scene.render
    W, H = settings.width, settings.height
    S = compiled.kernel
    cam = np.asarray(compiled.camera, dtype=np.float64)
    extra, extra_kind, extra_index = tessellate(S, cam, W, H)
    near = near_distance(S)
    background = np.asarray(settings.background, dtype=np.float64)

    # every pixel is written by the kernels: no need to initialise
    rgb = np.empty((H, W, 3), dtype=np.float32)
    A = (H, W) if aovs else (1, 1)
    arrays = {
        "depth": np.empty(A, dtype=np.float32),
        "normal": np.empty((*A, 3), dtype=np.float32),
        "object": np.empty(A, dtype=np.int32),
        "prim": np.empty(A, dtype=np.int32),
        "albedo": np.empty((*A, 3), dtype=np.float32),
    }
    _warm_up(S, cam, near, background)
    start = time.perf_counter()
    rasterize_arrays(S, cam, W, H, near, extra, extra_kind, extra_index, background, aovs,
                     rgb, arrays["depth"], arrays["normal"], arrays["object"], arrays["prim"], arrays["albedo"])
    kernel_seconds = time.perf_counter() - start
    if progress is not None:
        progress(H, H)
    return rgb, (arrays if aovs else {}), kernel_seconds, 0


def _warm_up(S, cam, near, background):
    """Compile the kernels (or load them from the cache) on empty input, outside the timing."""
    empty = S._replace(triangles=S.triangles[:0])
    rgb = np.zeros((1, 1, 3), np.float32)
    rasterize_arrays(empty, cam, 1, 1, near, np.zeros((0, 9)), np.zeros(0, np.int32), np.zeros(0, np.int32),
                     background, True, rgb, np.zeros((1, 1), np.float32), np.zeros((1, 1, 3), np.float32),
                     np.zeros((1, 1), np.int32), np.zeros((1, 1), np.int32), np.zeros((1, 1, 3), np.float32))


def scene_scale(S) -> float:
    """The scene's size: the largest coordinate magnitude of its shapes and camera."""
    return max(float(S.epsilon_floor) * 1e3, 1e-30)


def near_distance(S) -> float:
    return NEAR_FRACTION * scene_scale(S)


def tessellate(S, cam: np.ndarray, width: int, height: int):
    """Triangles for the kernel scene's spheres and planes: (float64 (E, 9), kind (E,) as
    HIT_SPHERE / HIT_PLANE, index (E,) into S.spheres or S.planes)."""
    origin = cam[0:3]
    # pixels per radian at the image centre (the same horizontally and vertically)
    px_per_rad = 0.5 * height / max(float(np.linalg.norm(cam[9:12])), 1e-300)
    parts, kinds, indices = [], [], []
    for k in range(len(S.spheres)):
        tris = sphere_cap(S.spheres[k, :3], float(S.spheres[k, 3]), origin, px_per_rad)
        parts.append(tris)
        kinds.append(np.full(len(tris), HIT_SPHERE, np.int32))
        indices.append(np.full(len(tris), k, np.int32))
    for k in range(len(S.planes)):
        tris = plane_square(S.planes[k, :3], S.planes[k, 3:6], origin, scene_scale(S))
        parts.append(tris)
        kinds.append(np.full(len(tris), HIT_PLANE, np.int32))
        indices.append(np.full(len(tris), k, np.int32))
    if not parts:
        return np.zeros((0, 9)), np.zeros(0, np.int32), np.zeros(0, np.int32)
    return np.ascontiguousarray(np.concatenate(parts)), np.concatenate(kinds), np.concatenate(indices)


def _basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vector `axis` to an orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def sphere_cap(center, radius: float, eye, px_per_rad: float) -> np.ndarray:
    """float64 (N, 9): the part of the sphere visible from `eye`, see the module docstring."""
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
    step_u = math.sqrt(8.0 * SPHERE_TOLERANCE_PX * radius / (far * px_per_rad))
    rings = int(np.clip(math.ceil(u[-1] / step_u), *SPHERE_RINGS))
    ring_theta = np.interp(np.linspace(0.0, u[-1], rings + 1)[1:], u, theta)
    if inside:
        ring_theta = ring_theta[:-1]  # the last "ring" is the antipode: a pole, below
    # Segments: the widest ring (the silhouette) must be polygonal by less than the tolerance.
    widest = float((np.sin(ring_theta) * radius / np.interp(ring_theta, theta, reach)).max())
    sag = SPHERE_TOLERANCE_PX / max(widest * px_per_rad, 1e-300)  # allowed 1 - cos(pi / n)
    segments = int(np.clip(math.ceil(math.pi / math.acos(max(1.0 - sag, -1.0))) if sag < 2 else 0,
                           *SPHERE_SEGMENTS))

    e1, e2 = _basis(axis)
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


def plane_square(point, normal, eye, scale: float) -> np.ndarray:
    """float64 (8, 9): a square of the plane centred on the eye's foot point, 2 x 2 quads."""
    point = np.asarray(point, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    eye = np.asarray(eye, dtype=np.float64)
    height = float(np.dot(eye - point, n))
    foot = eye - height * n
    half = PLANE_EXTENT * max(scale, abs(height), 1.0)
    e1, e2 = _basis(n)
    s = np.array([-half, 0.0, half])
    grid = foot + s[:, None, None] * e1 + s[None, :, None] * e2  # (3, 3, 3)
    quads = []
    for a in range(2):
        for b in range(2):
            p00, p10, p01, p11 = grid[a, b], grid[a + 1, b], grid[a, b + 1], grid[a + 1, b + 1]
            quads += [np.concatenate([p00, p10, p11]), np.concatenate([p00, p11, p01])]
    return np.asarray(quads)
