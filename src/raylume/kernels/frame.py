"""The image loop: rows in parallel, samples per pixel, primary-hit AOVs.

Each pixel gathers its own `spp` camera samples (see sampling.py): stratified positions in the
unit square, jittered, warped through the pixel filter (box: the pixel itself; gaussian and
mitchell: a wider footprint centred on the pixel) and, with an aperture, paired with a
stratified point on the lens. One sample per pixel is the pinhole ray through the pixel
centre. The pixel's value is the filter-weighted mean of its samples."""

import numpy as np
from numba import njit, prange

from .camera import camera_ray, thin_lens_ray
from .intersect import INF
from .layout import (
    CAM_FILTER,
    CAM_FILTER_NEGATIVE,
    CAM_FILTER_TABLE,
    CAM_LENS_RADIUS,
    FILTER_BOX,
    HIT_NONE,
    MODE_CAST,
    SCRATCH_PAD,
    TRAVERSAL_STACK,
)
from .sampling import filter_offset, key_uniform2, lens_sample, sample_key, stratum
from .scene import geometry_of, lights_of, surfaces_of
from .shade import surface, surface_albedo
from .trace import trace_ray
from .traverse import closest_hit
from .vec import FAST, KERNEL, dot, madd, mul


@njit(**KERNEL, inline="always")
def _cast_ray(G, F, o, d, background, node_stack, t_stack):
    t, kind, index, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
    if kind == HIT_NONE:
        return background
    p = madd(o, d, t)
    ng, ns, m, obj, prim = surface(G, F, kind, index, b1, b2, p)
    return surface_albedo(G, F, kind, index, b1, b2, p, m)


@njit(**KERNEL)
def _primary_aovs(G, F, cam, i, j, width, height, node_stack, t_stack, depth, normal, obj_id, prim_id, albedo):
    """Depth, normal, object, prim and albedo of the (pinhole) ray through the pixel centre."""
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
        a = surface_albedo(G, F, kind, index, b1, b2, p, m)
        depth[j, i] = t
        obj_id[j, i] = obj
        prim_id[j, i] = prim
        for c in range(3):
            normal[j, i, c] = ns[c]
            albedo[j, i, c] = a[c]
    return 1


@njit(**KERNEL)
def camera_sample(cam, seed, i, j, s, spp, width, height):
    """Camera sample s of pixel (i, j): (origin, direction, filter weight, random key)."""
    key = sample_key(seed, j * width + i, s)
    weight = 1.0
    if spp == 1:
        x = i + 0.5
        y = j + 0.5
    else:
        jx, jy = key_uniform2(key)
        ux, uy = stratum(s, spp, jx, jy)
        if cam[CAM_FILTER] == FILTER_BOX:
            x = i + ux
            y = j + uy
        else:
            dx = filter_offset(cam, CAM_FILTER_TABLE, ux)
            dy = filter_offset(cam, CAM_FILTER_TABLE, uy)
            x = i + 0.5 + dx
            y = j + 0.5 + dy
            if abs(dx) > cam[CAM_FILTER_NEGATIVE]:
                weight = -weight
            if abs(dy) > cam[CAM_FILTER_NEGATIVE]:
                weight = -weight
    o, d = camera_ray(cam, x, y, width, height)
    if cam[CAM_LENS_RADIUS] > 0.0:
        lu, lv = lens_sample(key, s, spp)
        o, d = thin_lens_ray(cam, o, d, lu, lv)
    return o, d, weight, key


@njit(parallel=True, fastmath=FAST, cache=True, error_model="numpy")
def render_rows(S, cam, width, height, row_begin, row_end, lanes, spp, seed, mode, max_depth,
                background, want_aovs, rgb, depth, normal, obj_id, prim_id, albedo, rays_per_row):
    """Render rows [row_begin, row_end) into the output arrays (all indexed by absolute row).

    Each of the `lanes` parallel iterations (one per thread) takes every lanes-th row. Rows
    differ widely in cost (sky against floor), and a parallel loop over the rows themselves
    hands each thread one contiguous block: on the seed scene one thread got the sky, the
    other the floor, and two threads were only 1.4x faster than one. Interleaved, 1.85x."""
    for lane in prange(lanes):
        # Views and scratch stacks made inside the parallel loop (a parfor cannot capture a
        # namedtuple built outside it); a row is one call, so the views are passed once per
        # row rather than once per ray. The stacks are padded against false sharing.
        node_stack = np.empty(TRAVERSAL_STACK + SCRATCH_PAD, dtype=np.int32)
        t_stack = np.empty(TRAVERSAL_STACK + SCRATCH_PAD, dtype=np.float64)
        work = np.empty((2 * max_depth + 4 + SCRATCH_PAD // 10, 10), dtype=np.float64)
        for j in range(row_begin + lane, row_end, lanes):
            rays_per_row[j] = _render_row(
                geometry_of(S), surfaces_of(S), lights_of(S), cam, j, width, height, spp, seed, mode, max_depth,
                background, want_aovs, rgb, depth, normal, obj_id, prim_id, albedo, node_stack, t_stack, work,
            )


@njit(**KERNEL)
def _render_row(G, F, L, cam, j, width, height, spp, seed, mode, max_depth, background, want_aovs,
                rgb, depth, normal, obj_id, prim_id, albedo, node_stack, t_stack, work):
    """One image row: samples per pixel, the pixel filter's weights, AOVs. Returns rays traced."""
    bg = (background[0], background[1], background[2])
    rays = 0
    for i in range(width):
        if want_aovs:
            rays += _primary_aovs(G, F, cam, i, j, width, height, node_stack, t_stack,
                                  depth, normal, obj_id, prim_id, albedo)
        sr = 0.0
        sg = 0.0
        sb = 0.0
        weights = 0.0
        for s in range(spp):
            o, d, w, key = camera_sample(cam, seed, i, j, s, spp, width, height)
            if mode == MODE_CAST:
                col = _cast_ray(G, F, o, d, bg, node_stack, t_stack)
                rays += 1
            else:
                col, used = trace_ray(G, F, L, o, d, max_depth, bg, work, node_stack, t_stack, key)
                rays += used
            if w > 0.0:
                sr += col[0]
                sg += col[1]
                sb += col[2]
            else:  # a negative lobe of the pixel filter
                sr -= col[0]
                sg -= col[1]
                sb -= col[2]
            weights += w
        # Weights are +-1, so a pixel's sum is spp when the filter is positive (box,
        # gaussian). A Mitchell pixel whose weights cancel (possible at a few spp) is divided
        # by spp instead; negative results of its lobes are clipped to 0.
        if weights < 0.5:
            weights = spp
        inv = 1.0 / weights
        rgb[j, i, 0] = max(sr * inv, 0.0)
        rgb[j, i, 1] = max(sg * inv, 0.0)
        rgb[j, i, 2] = max(sb * inv, 0.0)
    return rays
