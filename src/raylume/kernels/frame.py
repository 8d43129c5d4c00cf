"""The image loop: rows in parallel, samples per pixel, primary-hit AOVs.

Each pixel gathers its own `spp` camera samples (see sampling.py): stratified positions in the
unit square, jittered, warped through the pixel filter (box: the pixel itself; gaussian and
mitchell: a wider footprint centred on the pixel) and, with an aperture, paired with a
stratified point on the lens. One sample per pixel is the pinhole ray through the pixel
centre. The pixel's value is the filter-weighted mean of its samples."""

import numpy as np
from numba import njit

from .camera import camera_ray, thin_lens_ray
from .intersect import INF
from .layout import (
    CAM_FILTER,
    CAM_FILTER_NEGATIVE,
    CAM_FILTER_TABLE,
    CAM_LENS_RADIUS,
    FILTER_BOX,
    HIT_NONE,
)
from .sampling import filter_offset, key_uniform2, lens_sample, sample_key, stratum
from .scene import geometry_of, lights_of, surfaces_of
from .shade import surface, surface_albedo
from .trace import trace_ray
from .traverse import closest_hit, scratch_array, traversal_stacks
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


# Entry points, one per kind of work, so a render compiles only what it runs. Each renders one
# lane: every lanes-th row of [row_begin, row_end), starting at row_begin + lane. render.py runs
# the lanes on threads (the kernels release the GIL). Rows differ widely in cost (sky against
# floor); interleaving them balances the threads, where contiguous blocks of rows left one
# thread the sky and two threads were only 1.4x faster than one on the seed scene.
LANE = dict(nogil=True, cache=True, fastmath=FAST, error_model="numpy")


@njit(**LANE)
def trace_lane(S, cam, width, height, row_begin, row_end, lane, lanes, spp, seed, max_depth, background,
               rgb, rays_per_row):
    """Whitted-traced colour of the lane's rows into rgb; rays traced per row into rays_per_row."""
    node_stack, t_stack = traversal_stacks()
    slots = 2 * max_depth + 4  # a ray's reflection and refraction at each level, and spare
    work = scratch_array(slots * 10, np.float64).reshape((slots, 10))
    bg = (background[0], background[1], background[2])
    G, F, L = geometry_of(S), surfaces_of(S), lights_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        rays_per_row[j] += _trace_row(G, F, L, cam, j, width, height, spp, seed, max_depth, bg, rgb,
                                      work, node_stack, t_stack)


@njit(**LANE)
def cast_lane(S, cam, width, height, row_begin, row_end, lane, lanes, spp, seed, background, rgb, rays_per_row):
    """Ray-cast colour (the closest hit's albedo) of the lane's rows."""
    node_stack, t_stack = traversal_stacks()
    bg = (background[0], background[1], background[2])
    G, F = geometry_of(S), surfaces_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        rays_per_row[j] += _cast_row(G, F, cam, j, width, height, spp, seed, bg, rgb, node_stack, t_stack)


@njit(**LANE)
def aov_lane(S, cam, width, height, row_begin, row_end, lane, lanes, depth, normal, obj_id, prim_id, albedo,
             rays_per_row):
    """Primary-hit AOVs (depth, normal, object, prim, albedo) of the lane's rows."""
    node_stack, t_stack = traversal_stacks()
    G, F = geometry_of(S), surfaces_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        rays_per_row[j] += _primary_aovs_row(G, F, cam, j, width, height, node_stack, t_stack,
                                             depth, normal, obj_id, prim_id, albedo)


# The row loops below are two copies of one skeleton on purpose: each holds its per-ray work
# inlined. A call per ray passes the scene's views (two dozen array descriptors, ~200 machine
# words): that cost ~40 ns per pixel, a fifth of the seed scene's time.


@njit(**KERNEL)
def _cast_row(G, F, cam, j, width, height, spp, seed, bg, rgb, node_stack, t_stack):
    for i in range(width):
        total = (0.0, 0.0, 0.0, 0.0)
        for s in range(spp):
            o, d, w, key = camera_sample(cam, seed, i, j, s, spp, width, height)
            total = _add_sample(total, _cast_ray(G, F, o, d, bg, node_stack, t_stack), w)
        _store_pixel(rgb, j, i, total, spp)
    return width * spp


@njit(**KERNEL)
def _trace_row(G, F, L, cam, j, width, height, spp, seed, max_depth, bg, rgb, work, node_stack, t_stack):
    rays = 0
    for i in range(width):
        total = (0.0, 0.0, 0.0, 0.0)
        for s in range(spp):
            o, d, w, key = camera_sample(cam, seed, i, j, s, spp, width, height)
            col, used = trace_ray(G, F, L, o, d, max_depth, bg, work, node_stack, t_stack, key)
            rays += used
            total = _add_sample(total, col, w)
        _store_pixel(rgb, j, i, total, spp)
    return rays


@njit(**KERNEL, inline="always")
def _add_sample(total, col, w):
    """Running (r, g, b, weight) of a pixel plus one sample of filter weight w = +-1."""
    if w > 0.0:
        return (total[0] + col[0], total[1] + col[1], total[2] + col[2], total[3] + w)
    # a negative lobe of the pixel filter
    return (total[0] - col[0], total[1] - col[1], total[2] - col[2], total[3] + w)


@njit(**KERNEL, inline="always")
def _store_pixel(rgb, j, i, total, spp):
    # Weights are +-1, so a pixel's sum is spp when the filter is positive (box,
    # gaussian). A Mitchell pixel whose weights cancel (possible at a few spp) is divided
    # by spp instead; negative results of its lobes are clipped to 0.
    weights = total[3]
    if weights < 0.5:
        weights = spp
    inv = 1.0 / weights
    rgb[j, i, 0] = max(total[0] * inv, 0.0)
    rgb[j, i, 1] = max(total[1] * inv, 0.0)
    rgb[j, i, 2] = max(total[2] * inv, 0.0)


@njit(**KERNEL)
def _primary_aovs_row(G, F, cam, j, width, height, node_stack, t_stack, depth, normal, obj_id, prim_id, albedo):
    """Depth, normal, object, prim and albedo of the (pinhole) rays through the row's pixel
    centres. Returns rays traced."""
    for i in range(width):
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
    return width
