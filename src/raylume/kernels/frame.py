"""The image loop: rows on threads, samples per pixel into the film, primary-hit AOVs.

Each pixel gathers its own `spp` camera samples: positions in the pixel from the sampler
(stratified, jittered), warped through the pixel filter (film.py) and, with an aperture, paired
with a stratified point on the lens. One sample per pixel is the pinhole ray through the pixel
centre. Samples are added to the film's running sums; samples first..first+spp-1 of a pass
continue from whatever earlier passes left there."""

import numpy as np
from numba import njit

from .camera import CAM_LENS_RADIUS, camera_ray, thin_lens_ray
from .film import add_sample, filter_sample, pixel_sums, store_sums
from .materials import albedo
from .sampler import lens_sample, pixel_sample, sample_key
from .scene import geometry_of, lights_of, surfaces_of
from .shapes import NO_HIT, surface
from .trace import RAY_WIDTH, stack_rows, trace_ray
from .traverse import closest_hit, scratch_array, traversal_stacks
from .vec import FAST, KERNEL, dot, madd, mul

INF = np.inf


@njit(**KERNEL, inline="always")
def _cast_ray(G, F, o, d, background, node_stack, t_stack):
    t, prim, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
    if prim == NO_HIT:
        return background
    p = madd(o, d, t)
    ng, ns, m, obj, face = surface(G, prim, b1, b2, p)
    return albedo(G, F, m, prim, b1, b2, p)


@njit(**KERNEL, inline="always")
def camera_sample(cam, filt, seed, i, j, s, total_spp, width, height):
    """Camera sample s (of total_spp per pixel) of pixel (i, j): (origin, direction, filter
    weight, random key)."""
    key = sample_key(seed, j * width + i, s)
    weight = 1.0
    if total_spp == 1:
        x = i + 0.5
        y = j + 0.5
    else:
        ux, uy = pixel_sample(key, s, total_spp)
        x, y, weight = filter_sample(filt, i, j, ux, uy)
    o, d = camera_ray(cam, x, y, width, height)
    if cam[CAM_LENS_RADIUS] > 0.0:
        lu, lv = lens_sample(key, s, total_spp)
        o, d = thin_lens_ray(cam, o, d, lu, lv)
    return o, d, weight, key


# Entry points, one per kind of work, so a render compiles only what it runs. Each renders one
# lane: every lanes-th row of [row_begin, row_end), starting at row_begin + lane. The Session
# runs the lanes on threads (the kernels release the GIL). Rows differ widely in cost (sky
# against floor); interleaving them balances the threads, where contiguous blocks of rows left
# one thread the sky and two threads were only 1.4x faster than one on the seed scene.
# `samples` is (first, count, total): this pass adds samples first..first+count-1 of total.
# Every lane counts the rows it finished in rows_done[lane * PROGRESS_STRIDE] (counters a cache
# line apart, against false sharing) and checks stop[0] before each row: the waiting thread
# shows progress from the counters and stops a render within a row's time.
LANE = dict(nogil=True, cache=True, fastmath=FAST, error_model="numpy")
PROGRESS_STRIDE = 16


@njit(**LANE)
def trace_lane(
    S,
    cam,
    filt,
    width,
    height,
    row_begin,
    row_end,
    lane,
    lanes,
    samples,
    seed,
    max_depth,
    background,
    film,
    rays_per_row,
    rows_done,
    stop,
):
    """Whitted-traced samples of the lane's rows into the film; rays traced per row into rays_per_row."""
    node_stack, t_stack = traversal_stacks()
    slots = stack_rows(max_depth)
    work = scratch_array(slots * RAY_WIDTH, np.float64).reshape((slots, RAY_WIDTH))
    bg = (background[0], background[1], background[2])
    G, F, L = geometry_of(S), surfaces_of(S), lights_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        if stop[0] != 0:
            break
        rays_per_row[j] += _trace_row(
            G, F, L, cam, filt, j, width, height, samples, seed, max_depth, bg, film, work, node_stack, t_stack
        )
        rows_done[lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def cast_lane(
    S,
    cam,
    filt,
    width,
    height,
    row_begin,
    row_end,
    lane,
    lanes,
    samples,
    seed,
    background,
    film,
    rays_per_row,
    rows_done,
    stop,
):
    """Ray-cast samples (the closest hit's albedo) of the lane's rows into the film."""
    node_stack, t_stack = traversal_stacks()
    bg = (background[0], background[1], background[2])
    G, F = geometry_of(S), surfaces_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        if stop[0] != 0:
            break
        rays_per_row[j] += _cast_row(G, F, cam, filt, j, width, height, samples, seed, bg, film, node_stack, t_stack)
        rows_done[lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def aov_lane(
    S,
    cam,
    width,
    height,
    row_begin,
    row_end,
    lane,
    lanes,
    depth,
    normal,
    obj_id,
    prim_id,
    albedo_out,
    rays_per_row,
    rows_done,
    stop,
):
    """Primary-hit AOVs (depth, normal, object, prim, albedo) of the lane's rows."""
    node_stack, t_stack = traversal_stacks()
    G, F = geometry_of(S), surfaces_of(S)
    for j in range(row_begin + lane, row_end, lanes):
        if stop[0] != 0:
            break
        rays_per_row[j] += _primary_aovs_row(
            G, F, cam, j, width, height, node_stack, t_stack, depth, normal, obj_id, prim_id, albedo_out
        )
        rows_done[lane * PROGRESS_STRIDE] += 1


# The row loops below are two copies of one skeleton on purpose: each holds its per-ray work
# inlined. A call per ray passes the scene's views (two dozen array descriptors, ~200 machine
# words): that cost ~40 ns per pixel, a fifth of the seed scene's time.


@njit(**KERNEL)
def _cast_row(G, F, cam, filt, j, width, height, samples, seed, bg, film, node_stack, t_stack):
    first, count, total_spp = samples
    for i in range(width):
        total = pixel_sums(film, j, i)
        for s in range(first, first + count):
            o, d, w, key = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
            total = add_sample(total, _cast_ray(G, F, o, d, bg, node_stack, t_stack), w)
        store_sums(film, j, i, total)
    return width * count


@njit(**KERNEL)
def _trace_row(G, F, L, cam, filt, j, width, height, samples, seed, max_depth, bg, film, work, node_stack, t_stack):
    first, count, total_spp = samples
    rays = 0
    for i in range(width):
        total = pixel_sums(film, j, i)
        for s in range(first, first + count):
            o, d, w, key = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
            col, used = trace_ray(G, F, L, o, d, max_depth, bg, work, node_stack, t_stack, key)
            rays += used
            total = add_sample(total, col, w)
        store_sums(film, j, i, total)
    return rays


@njit(**KERNEL)
def _primary_aovs_row(G, F, cam, j, width, height, node_stack, t_stack, depth, normal, obj_id, prim_id, albedo_out):
    """Depth, normal, object, prim and albedo of the (pinhole) rays through the row's pixel
    centres. Returns rays traced."""
    for i in range(width):
        o, d = camera_ray(cam, i + 0.5, j + 0.5, width, height)
        t, prim, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
        if prim == NO_HIT:
            depth[j, i] = INF
            obj_id[j, i] = -1
            prim_id[j, i] = -1
            for c in range(3):
                normal[j, i, c] = 0.0
                albedo_out[j, i, c] = 0.0
        else:
            p = madd(o, d, t)
            ng, ns, m, obj, face = surface(G, prim, b1, b2, p)
            if dot(ns, d) > 0.0:
                ns = mul(ns, -1.0)
            a = albedo(G, F, m, prim, b1, b2, p)
            depth[j, i] = t
            obj_id[j, i] = obj
            prim_id[j, i] = face
            for c in range(3):
                normal[j, i, c] = ns[c]
                albedo_out[j, i, c] = a[c]
    return width
