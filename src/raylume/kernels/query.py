"""Batch ray queries over a compiled scene: closest hits for arrays of rays (benchmarks, tests,
and users who want raylume as a ray-intersection library)."""

from numba import njit, prange

from .intersect import INF
from .layout import HIT_NONE, HIT_PLANE, HIT_SPHERE
from .scene import geometry_of
from .traverse import closest_hit, traversal_stacks
from .vec import FAST


@njit(parallel=True, fastmath=FAST, cache=True, error_model="numpy")
def intersect_rays(S, origins, directions, t_out, object_out, prim_out, lanes):
    """Closest hit of each ray (unit directions). t = inf, object = prim = -1 for misses.
    `lanes`: parallel iterations, one per thread (numba.get_num_threads(); passed in because
    calling it here would keep Numba from caching the function)."""
    n = origins.shape[0]
    chunk = 256
    for lane in prange(lanes):
        G = geometry_of(S)  # made inside the parallel loop: parfor cannot capture it from outside
        node_stack, t_stack = traversal_stacks()
        # interleaved chunks: neighbouring rays cost alike, distant ones may not (see frame.py)
        for c in range(lane, (n + chunk - 1) // chunk, lanes):
            for k in range(c * chunk, min(n, (c + 1) * chunk)):
                o = (float(origins[k, 0]), float(origins[k, 1]), float(origins[k, 2]))
                d = (float(directions[k, 0]), float(directions[k, 1]), float(directions[k, 2]))
                t, kind, index, b1, b2 = closest_hit(G, o, d, 0.0, INF, node_stack, t_stack)
                t_out[k] = t
                if kind == HIT_NONE:
                    object_out[k] = -1
                    prim_out[k] = -1
                elif kind == HIT_SPHERE:
                    object_out[k] = S.sphere_object[index]
                    prim_out[k] = 0
                elif kind == HIT_PLANE:
                    object_out[k] = S.plane_object[index]
                    prim_out[k] = 0
                else:
                    object_out[k] = S.triangle_object[index]
                    prim_out[k] = S.triangle_prim[index]
