"""`--mode raster`: a Z-buffer rasterizer over the scene's triangles, with the ray caster's camera.

Rasterization projects every triangle and fills the pixel centres it covers, keeping the
nearest under a Z-buffer: its cost grows linearly with the number of triangles, where ray
casting through a BVH grows about logarithmically. Both modes use the same camera (pixel
centres, DESIGN.md), the same AOVs, and the same local lighting as `trace` (ambient,
diffuse, specular) -- but the rasterizer has no shadows, reflection or refraction.

The kernels and the details of scan conversion (2D homogeneous edge functions,
perspective-correct depth and barycentrics, near-plane clipping, the top-left fill rule,
deterministic banded parallelism) are in `kernels/raster/raster_kernel.py`. Analytic shapes are drawn
as triangles from their own module's `tessellate` (kernels/shape_*.py: spheres as the cap the
camera sees, within a tenth of a pixel; planes as a huge square around the camera; disks,
quads and cylinders as polygons within the same tolerance). Shading uses each shape's exact
normal at the rasterized point; that point lies on a flat facet, a little inside a curved
shape, so a sphere's silhouette moves by less than that tolerance, but its depth (up to ~3%
at the silhouette, ~0.5% inside it), normal, texture lookup and shading (~1-2% in a
highlight) differ a little from the ray caster's too; flat shapes agree with it. These
triangles carry their primitive, so AOVs report the shape's object and prim 0, as the ray
caster does.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from .accel.wide import NODE_REF, leaf_count, leaf_first
from .kernels.film.camera import CAM_POSITION, CAM_UP
from .kernels.film.image_pass import Aovs
from .kernels.frame_stack import roomy_frame_stack
from .kernels.geometry.shape_triangle import triangle_tables
from .kernels.geometry.shapes import PRIM_KIND, PRIM_ROW, Shape
from .kernels.geometry.shapes import tessellate as tessellate_shape
from .kernels.raster.raster_kernel import Parts, rasterize_arrays

NEAR_FRACTION = 1e-30  # near plane distance, as a fraction of the scene's extent


class RasterView(NamedTuple):
    """What tessellation needs to know of the camera."""

    eye: np.ndarray
    px_per_rad: float  # pixels per radian at the image centre
    scale: float  # the scene's size


def rasterize(
    S,
    cam: np.ndarray,
    width: int,
    height: int,
    background,
    progress: Callable[[int, int], None] | None = None,
    aovs: bool = True,
):
    """Render the kernel scene S through the camera array by rasterization, one sample at each
    pixel centre (spp does not apply). Returns (rgb, aovs, kernel_seconds, rays=0); `aovs` is
    empty when not wanted."""
    W, H = width, height
    cam = np.asarray(cam, dtype=np.float64)
    S, prim_instance = flatten_instances(S)
    extra, extra_prim, extra_part = tessellate(S, cam, W, H)
    triangle_prim = triangle_primitives(S)
    near = near_distance(S)
    background = np.asarray(background, dtype=np.float64)

    # every pixel is written by the kernels: no need to initialise
    rgb = np.empty((H, W, 3), dtype=np.float32)
    A = (H, W) if aovs else (1, 1)
    arrays = {
        "depth": np.empty(A, dtype=np.float32),
        "normal": np.empty((*A, 3), dtype=np.float32),
        "object": np.empty(A, dtype=np.int32),
        "prim": np.empty(A, dtype=np.int32),
        "albedo": np.empty((*A, 3), dtype=np.float32),
        "instance": np.empty(A, dtype=np.int32),
    }
    _warm_up(S, cam, near, background)
    start = time.perf_counter()
    parts = Parts(triangle_prim, extra, extra_prim, extra_part, prim_instance)
    rasterize_arrays(S, cam, W, H, near, parts, background, rgb, Aovs(**arrays), aovs)
    kernel_seconds = time.perf_counter() - start
    if progress is not None:
        progress(H, H)
    return rgb, (arrays if aovs else {}), kernel_seconds, 0


@roomy_frame_stack  # (frame_stack.py)
def _warm_up(S, cam, near, background):
    """Compile the kernels (or load them from the cache) on empty input, outside the timing."""
    empty = S._replace(triangles=S.triangles[:0], **triangle_tables(S.triangles[:0]), sweep=S.sweep[:, :0])
    rgb = np.zeros((1, 1, 3), np.float32)
    none = np.zeros(0, np.int32)
    parts = Parts(none, np.zeros((0, 9)), none, np.zeros(0), np.zeros(len(S.prims), np.int32))
    one = np.zeros((1, 1), np.float32), np.zeros((1, 1, 3), np.float32), np.zeros((1, 1), np.int32)
    aovs = Aovs(
        depth=one[0], normal=one[1], object=one[2], prim=one[2].copy(), albedo=one[1].copy(), instance=one[2].copy()
    )
    rasterize_arrays(empty, cam, 1, 1, near, parts, background, rgb, aovs, True)


# Instances are drawn as plain triangles, each instance's copy of its mesh; beyond this many
# the copies would not fit in memory (ray modes trace any number).
MAX_FLAT_TRIANGLES = 50_000_000


def flatten_instances(S):
    """(S with every instance drawn as world-space triangles, int32 per primitive: its
    `instance` AOV). A scene without instances comes back as it is (AOV 0 everywhere)."""
    n_inst = len(S.instance_inverse)
    if n_inst == 0:
        return S, np.zeros(len(S.prims), np.int32)
    from .errors import RaylumeError

    roots = np.unique(S.instance_index[:, 0])
    index = S.inst_node_index
    # each BLAS's nodes run from its root to the next root; its leaves cover its rows
    ranges = {}
    ends = [*roots[1:], len(index)]
    for r, e in zip(roots, ends, strict=True):
        refs = index[r:e, NODE_REF, :]
        leaves = refs[(refs < 0) & (leaf_count(refs) != 0)]
        first = leaf_first(leaves).astype(np.int64)
        last = first + np.abs(leaf_count(leaves))
        ranges[int(r)] = (int(first.min()), int(last.max()))
    n_world = min(a for a, _ in ranges.values())
    n_bounded = max(b for _, b in ranges.values())
    sizes = np.array([ranges[int(r)][1] - ranges[int(r)][0] for r in S.instance_index[:, 0]])
    if sizes.sum() > MAX_FLAT_TRIANGLES:
        raise RaylumeError(
            f"raster mode draws every instance's triangles: {int(sizes.sum())} here, more than "
            f"{MAX_FLAT_TRIANGLES}; render this scene in cast, trace or path mode"
        )
    world_tris = int(S.prims[n_world:n_bounded, PRIM_ROW].min())
    tris, normals, uvs, rows, ids = [], [], [], [], []
    smooth_any = len(S.triangle_normals) == len(S.triangles)
    uv_any = len(S.triangle_uvs) == len(S.triangles)
    for i in range(n_inst):
        a, b = ranges[int(S.instance_index[i, 0])]
        inv = S.instance_inverse[i].reshape(3, 4)
        m = np.linalg.inv(inv[:, :3])  # object to world, linear part
        t = -m @ inv[:, 3]
        src = S.prims[a:b, PRIM_ROW].astype(np.int64)
        v = S.triangles[src].astype(np.float64).reshape(-1, 3, 3) @ m.T + t
        mirror = np.linalg.det(m) < 0
        order = [0, 2, 1] if mirror else [0, 1, 2]  # keep the winding's normal outward
        tris.append(v[:, order].reshape(-1, 9))
        if smooth_any:
            n = S.triangle_normals[src].astype(np.float64).reshape(-1, 3, 3) @ np.linalg.inv(m)
            n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-300)
            normals.append(n[:, order].reshape(-1, 9))
        if uv_any:
            uvs.append(S.triangle_uvs[src].reshape(-1, 3, 2)[:, order].reshape(-1, 6))
        rows.append(S.prims[a:b])
        ids.append(np.full(b - a, S.instance_index[i, 1], np.int32))
    flat = np.concatenate(rows).copy()
    flat_src = flat[:, PRIM_ROW].astype(np.int64)  # each flat triangle's stored (object-space) row
    flat[:, PRIM_ROW] = world_tris + np.arange(len(flat), dtype=np.int32)
    prims = np.concatenate([S.prims[:n_world], flat, S.prims[n_bounded:]])
    smooth = np.concatenate([S.triangle_smooth[:world_tris], S.triangle_smooth[flat_src]])
    flat_s = S._replace(
        prims=prims,
        n_bounded=n_world + len(flat),
        triangles=np.concatenate([S.triangles[:world_tris], np.concatenate(tris).astype(np.float32)]),
        triangle_normals=np.concatenate([S.triangle_normals[:world_tris], np.concatenate(normals).astype(np.float32)])
        if smooth_any
        else S.triangle_normals,
        triangle_smooth=smooth,
        triangle_uvs=np.concatenate([S.triangle_uvs[:world_tris], np.concatenate(uvs).astype(np.float32)])
        if uv_any
        else S.triangle_uvs,
        instance_inverse=S.instance_inverse[:0],
        instance_index=S.instance_index[:0],
    )
    # the flattened triangles are no longer the sweep table's (geometry/sweep.py): the BVH walk
    flat_s = flat_s._replace(**triangle_tables(flat_s.triangles), sweep=S.sweep[:, :0])
    prim_instance = np.zeros(len(prims), np.int32)
    prim_instance[n_world : n_world + len(flat)] = np.concatenate(ids)
    return flat_s, prim_instance


def scene_scale(S) -> float:
    """The scene's size: the largest coordinate magnitude of its shapes and camera."""
    return max(float(S.epsilon_floor) * 1e3, 1e-30)


def near_distance(S) -> float:
    return NEAR_FRACTION * scene_scale(S)


def triangle_primitives(S) -> np.ndarray:
    """int32 (T,): the primitive of each row of the triangle table."""
    out = np.zeros(len(S.triangles), dtype=np.int32)
    is_tri = S.prims[:, PRIM_KIND] == Shape.TRIANGLE
    out[S.prims[is_tri, PRIM_ROW]] = np.flatnonzero(is_tri).astype(np.int32)
    return out


def tessellate(S, cam: np.ndarray, width: int, height: int):
    """Triangles drawing the kernel scene's analytic shapes: (float64 (E, 9), primitive (E,),
    part (E,), see shapes.tessellate)."""
    # pixels per radian at the image centre (the same horizontally and vertically)
    up = cam[CAM_UP : CAM_UP + 3]
    view = RasterView(
        cam[CAM_POSITION : CAM_POSITION + 3], 0.5 * height / max(float(np.linalg.norm(up)), 1e-300), scene_scale(S)
    )
    parts, prims, which = [], [], []
    for k in np.flatnonzero(S.prims[:, PRIM_KIND] != Shape.TRIANGLE):
        kind = Shape(int(S.prims[k, PRIM_KIND]))
        tris, part = tessellate_shape(kind, S.shapes[S.prims[k, PRIM_ROW]], view)
        parts.append(tris)
        prims.append(np.full(len(tris), k, np.int32))
        which.append(np.asarray(part, dtype=np.float64))
    if not parts:
        return np.zeros((0, 9)), np.zeros(0, np.int32), np.zeros(0)
    return np.ascontiguousarray(np.concatenate(parts)), np.concatenate(prims), np.concatenate(which)
