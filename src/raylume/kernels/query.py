"""Batch ray queries over a compiled scene: closest hits for arrays of rays (benchmarks, tests,
and users who want raylume as a ray-intersection library)."""

import numpy as np
from numba import njit

from ..lanes import lane_pool
from .packet import PACKET, packet_hit, packet_scratch, packet_trace, root_box, scene_extent, uses_packets
from .scene import geometry_of
from .shapes import NO_HIT, PRIM_FACE, PRIM_OBJECT, instance_id, split_hit
from .traverse import INF, closest_hit, prefetch_row, scratch_array, traversal_stacks
from .vec import FAST, inline_function, kernel_function


# A call per chunk of rays, compiled without reference counting (KERNEL), as the frame kernels'
# row functions are: inlined into the lane's loop (then a parfor's), the traversal took and
# dropped references to the BVH arrays for every ray (4 calls with atomic operations a ray).
@kernel_function
def _intersect_chunk(G, X, origins, directions, outputs, start, end, stacks, packets, hits):
    """Rays start .. end - 1 (at most CHUNK) into the outputs: traced first, their distances
    stored and their hits kept in `hits` (one per ray of the chunk), then their ids looked up.
    A hit's object and face ids lie in its row of the primitive table, a cache miss of its own
    on a large mesh; the row is prefetched when the hit is found and read after the whole
    chunk is traced, when it has long arrived (bumpy 4M hit rays on a Zen 3 71.4 -> 67.5 ms, 1M
    56.5 -> 50.0, against the eight rows requested together after each packet)."""
    extent = scene_extent(G)
    root = root_box(G)
    packets_here = uses_packets(G, X)
    t_out = outputs[0]
    k = start
    while k < end:
        n = min(PACKET, end - k)
        if not (
            packets_here
            and _packet_hits(G, X, origins, directions, k, n, extent, root, t_out, hits, start, stacks, packets)
        ):
            # one call site: the single-ray traversal is inlined once (a second copy cost ~1.5 s
            # of cold compile)
            _closest_hits_singly(G, X, origins, directions, k, k + n, t_out, hits, start, stacks)
        k += n
    store_ids(G, X, start, end, hits, outputs)


@inline_function
def _packet_hits(G, X, origins, directions, k, n, extent, root, t_out, hits, start, stacks, packets):
    """Rays k .. k + n - 1 traced as a packet: distances into t_out, hits into hits[k - start
    ...] (extent: scene_extent(G), root: root_box(G)); False when they are refused, and nothing
    written."""
    node_stack, t_stack = stacks
    _, lane, prim_lane, _ = packets
    coherent = packet_trace(G, X, root, origins, directions, k, n, extent, packets, node_stack, t_stack)
    if coherent:
        for i in range(n):
            t, prim, _, _ = packet_hit(lane, prim_lane, i)
            _keep_hit(G, X, k + i, t, prim, t_out, hits, start)
    return coherent


@inline_function
def _closest_hits_singly(G, X, origins, directions, first, end, t_out, hits, start, stacks):
    """Rays first .. end - 1 ray by ray (closest_hit): distances into t_out, hits into
    hits[k - start]."""
    node_stack, t_stack = stacks
    for k in range(first, end):
        o = (float(origins[k, 0]), float(origins[k, 1]), float(origins[k, 2]))
        d = (float(directions[k, 0]), float(directions[k, 1]), float(directions[k, 2]))
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        _keep_hit(G, X, k, t, prim, t_out, hits, start)


@inline_function
def _keep_hit(G, X, k, t, prim, t_out, hits, start):
    t_out[k] = t
    hits[k - start] = prim
    if prim != NO_HIT:
        prefetch_row(G.prims, split_hit(X, prim)[0])


@inline_function
def store_ids(G, X, start, end, hits, outputs):
    """The object, face and instance ids of rays start .. end - 1 from their hits (hits[k -
    start]; -1 for a miss)."""
    _, object_out, prim_out, instance_out = outputs
    for k in range(start, end):
        prim = hits[k - start]
        if prim == NO_HIT:
            object_out[k] = -1
            prim_out[k] = -1
            instance_out[k] = -1
        else:
            row, _ = split_hit(X, prim)
            object_out[k] = G.prims[row, PRIM_OBJECT]
            prim_out[k] = G.prims[row, PRIM_FACE]
            instance_out[k] = instance_id(X, prim)


@inline_function
def intersect_singly(G, X, origins, directions, outputs, start, end, stacks, hits):
    """intersect_lane's work for rays start .. end - 1 (at most CHUNK) without packets: the
    single-ray traversal alone (benchmarks/bench_hits.py)."""
    _closest_hits_singly(G, X, origins, directions, start, end, outputs[0], hits, start, stacks)
    store_ids(G, X, start, end, hits, outputs)


# Rays per chunk: a lane takes every lanes-th chunk (neighbouring rays cost alike, distant ones
# may not; see frame.py).
CHUNK = 256


@njit(nogil=True, fastmath=FAST, cache=True, error_model="numpy")
def intersect_lane(S, X, origins, directions, t_out, object_out, prim_out, instance_out, lane, lanes):
    """Closest hits of lane `lane` of `lanes`: chunks lane, lane + lanes, ... of the rays."""
    n = origins.shape[0]
    G = geometry_of(S)
    stacks = traversal_stacks()
    packets = packet_scratch()
    hits = scratch_array(CHUNK, np.int64)
    outputs = (t_out, object_out, prim_out, instance_out)
    for c in range(lane, (n + CHUNK - 1) // CHUNK, lanes):
        _intersect_chunk(G, X, origins, directions, outputs, c * CHUNK, min(n, (c + 1) * CHUNK), stacks, packets, hits)


def intersect_rays(S, X, origins, directions, t_out, object_out, prim_out, instance_out, lanes: int) -> None:
    """Closest hit of each ray (unit directions) into the outputs: t = inf, object = prim =
    instance = -1 for misses; instance is the instance's index within its object, 0 off
    instances. X: the scene's `features(S)` (shapes.py). The rays' chunks are shared among
    `lanes` threads, each running the nogil intersect_lane, as a render runs its lanes: a
    parfor (prange) did the same and cost ~1.7 s of cold compile."""
    args = (S, X, origins, directions, t_out, object_out, prim_out, instance_out)
    lanes = max(1, min(lanes, (origins.shape[0] + CHUNK - 1) // CHUNK))
    if lanes == 1:
        intersect_lane(*args, 0, 1)
        return
    pool = lane_pool(lanes - 1)
    futures = [pool.submit(intersect_lane, *args, lane, lanes) for lane in range(1, lanes)]
    intersect_lane(*args, 0, lanes)
    for f in futures:
        f.result()
