"""The image loop: rows in parallel, samples per pixel, primary-hit AOVs."""

import numpy as np
from numba import njit, prange

from .camera import camera_ray
from .intersect import INF
from .layout import HIT_NONE, MODE_CAST, TRAVERSAL_STACK
from .sampling import stratified_offset
from .scene import geometry_of, lights_of, surfaces_of
from .shade import albedo as albedo_of
from .shade import surface
from .trace import trace_ray
from .traverse import closest_hit
from .vec import FAST, KERNEL, dot, madd, mul


@njit(**KERNEL)
def _cast_ray(G, F, o, d, background, node_stack, t_stack):
    t, kind, index, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
    if kind == HIT_NONE:
        return background
    p = madd(o, d, t)
    ng, ns, m, obj, prim = surface(G, F, kind, index, b1, b2, p)
    return albedo_of(F.materials, m, p)


@njit(**KERNEL)
def _primary_aovs(G, F, cam, i, j, width, height, node_stack, t_stack, depth, normal, obj_id, prim_id, albedo):
    """Depth, normal, object, prim and albedo of the ray through the pixel centre."""
    o, d = camera_ray(cam, i + 0.5, j + 0.5, width, height)
    t, kind, index, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
    if kind == HIT_NONE:
        depth[j, i] = INF
        obj_id[j, i] = -1
        prim_id[j, i] = -1
        for c in range(3):
            normal[j, i, c] = 0.0
            albedo[j, i, c] = 0.0
    else:
        p = madd(o, d, t)
        ng, ns, m, obj, prim = surface(G, F, kind, index, b1, b2, p)
        if dot(ns, d) > 0.0:
            ns = mul(ns, -1.0)
        a = albedo_of(F.materials, m, p)
        depth[j, i] = t
        obj_id[j, i] = obj
        prim_id[j, i] = prim
        for c in range(3):
            normal[j, i, c] = ns[c]
            albedo[j, i, c] = a[c]
    return 1


@njit(parallel=True, fastmath=FAST, cache=True, error_model="numpy")
def render_rows(S, cam, width, height, row_begin, row_end, spp, seed, mode, max_depth,
                background, want_aovs, rgb, depth, normal, obj_id, prim_id, albedo, rays_per_row):
    """Render rows [row_begin, row_end) into the output arrays (all indexed by absolute row)."""
    bg = (background[0], background[1], background[2])
    for j in prange(row_begin, row_end):
        # Views made per row inside the parallel loop (parfor cannot capture them from outside).
        G = geometry_of(S)
        F = surfaces_of(S)
        L = lights_of(S)
        node_stack = np.empty(TRAVERSAL_STACK, dtype=np.int32)
        t_stack = np.empty(TRAVERSAL_STACK, dtype=np.float64)
        work = np.empty((2 * max_depth + 4, 10), dtype=np.float64)
        rays = 0
        inv_spp = 1.0 / spp
        for i in range(width):
            pixel = j * width + i
            if want_aovs:
                rays += _primary_aovs(G, F, cam, i, j, width, height, node_stack, t_stack,
                                      depth, normal, obj_id, prim_id, albedo)
            sr = 0.0
            sg = 0.0
            sb = 0.0
            for s in range(spp):
                fx, fy = stratified_offset(seed, pixel, s, spp)
                o, d = camera_ray(cam, i + fx, j + fy, width, height)
                if mode == MODE_CAST:
                    col = _cast_ray(G, F, o, d, bg, node_stack, t_stack)
                    rays += 1
                else:
                    col, used = trace_ray(G, F, L, o, d, max_depth, bg, work, node_stack, t_stack)
                    rays += used
                sr += col[0]
                sg += col[1]
                sb += col[2]
            rgb[j, i, 0] = sr * inv_spp
            rgb[j, i, 1] = sg * inv_spp
            rgb[j, i, 2] = sb * inv_spp
        rays_per_row[j] = rays
