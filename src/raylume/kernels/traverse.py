"""BVH traversal: closest hit (nearer child first) and any hit (for shadow rays).

Both take the scene's Geometry view and test primitives through one leaf loop
(`intersect_range`) over the primitive table (shapes.py). Unbounded primitives (planes) follow
the bounded ones in that table and are tested before traversal.

BVH layout (accel/bvh.py): depth-first; inner node m has its left child at m + 1 and its right
child in node_index[m, 0]; a leaf holds (first, count) into the primitive table.
"""

import math

import numpy as np
from numba import njit

from .shape_triangle import NO_SHEAR, ray_shear
from .shapes import NO_HIT, intersect
from .vec import KERNEL

INF = math.inf

# Size of per-thread traversal stacks; a BVH deeper than this is rejected at build time.
TRAVERSAL_STACK = 128
# Unused elements on either side of each thread's scratch arrays (at least 256 bytes: beyond a
# cache line and its prefetched neighbour). Small arrays allocated by two threads can lie back
# to back: without the gap one thread's stack ended in the cache line where another's began,
# and their writes fought over it (false sharing: the seed scene took 85 instead of 45 ms on
# 2 threads).
SCRATCH_PAD = 1024

# Slab constants for a root leaf (never used, but typed alike).
_NO_SLAB = ((0.0, 0.0, 0.0), (0, 0, 0))


@njit(cache=True)
def traversal_stacks():
    """One thread's (node_stack, t_stack) for closest_hit and any_hit."""
    return scratch_array(TRAVERSAL_STACK, np.int32), scratch_array(TRAVERSAL_STACK, np.float64)


@njit(cache=True)
def scratch_array(n, dtype):
    """An array of n elements for one thread's scratch, with SCRATCH_PAD unused elements on
    either side against false sharing."""
    return np.empty(n + 2 * SCRATCH_PAD, dtype=dtype)[SCRATCH_PAD : SCRATCH_PAD + n]


@njit(**KERNEL, inline="always")
def intersect_box(bounds, n, o, slab, tmax):
    """Slab test against node n of bounds (float32 (M, 6)); entry distance or +inf. `slab` is
    the ray's `slab_ray(d)`: 1/d and, per axis, the column of the near plane. Picking the near
    and far plane by the direction's sign gives exactly the min/max of the two slab distances
    (rounding is monotonic) with six fewer comparisons: traversal ~9% faster."""
    inv, near = slab
    nx, ny, nz = near
    tnx = (bounds[n, nx] - o[0]) * inv[0]
    tfx = (bounds[n, 3 - nx] - o[0]) * inv[0]
    tny = (bounds[n, 1 + ny] - o[1]) * inv[1]
    tfy = (bounds[n, 4 - ny] - o[1]) * inv[1]
    tnz = (bounds[n, 2 + nz] - o[2]) * inv[2]
    tfz = (bounds[n, 5 - nz] - o[2]) * inv[2]
    tnear = max(tnx, tny, tnz, 0.0)
    # Widen the far side by a few ulps so rounding never culls a box the ray touches.
    tfar = min(tfx, tfy, tfz, tmax) * 1.0000000000000004
    if tnear <= tfar:
        return tnear
    return INF


@njit(**KERNEL)
def slab_ray(d):
    """Per-ray constants of the slab test: (1/d, near-plane columns), see intersect_box."""
    inv = safe_inverse(d)
    return inv, (0 if inv[0] >= 0.0 else 3, 0 if inv[1] >= 0.0 else 3, 0 if inv[2] >= 0.0 else 3)


@njit(**KERNEL)
def safe_inverse(d):
    """1/d with zero components replaced by a huge finite value (no inf * 0 = NaN in slabs)."""
    out0 = 1.0 / d[0] if d[0] != 0.0 else 1e200
    out1 = 1.0 / d[1] if d[1] != 0.0 else 1e200
    out2 = 1.0 / d[2] if d[2] != 0.0 else 1e200
    return (out0, out1, out2)


@njit(**KERNEL, inline="always")
def intersect_range(G, X, first, end, o, d, shear, tmin, best_t, prim, b1, b2, stop_at_first):
    """The leaf loop: primitives first..end-1 against the ray, nearest hit before best_t.
    Returns the updated (best_t, prim, b1, b2); with stop_at_first, returns at the first hit
    (any-hit queries)."""
    for k in range(first, end):
        t, u, v = intersect(G, X, k, o, d, shear, tmin, best_t)
        if t < best_t:
            best_t, prim, b1, b2 = t, k, u, v
            if stop_at_first:
                break
    return best_t, prim, b1, b2


# Inlined: with a call, every ray of a scene with planes passed the Geometry view by value
# (glass example: trace 10%, cast 30% slower). Scenes without unbounded shapes compile none of
# it (X is None, see shapes.features). Any-hit queries use it too, without stopping early (a
# few planes).
@njit(**KERNEL, inline="always")
def _unbounded_hit(G, X, o, d, shear, tmin, tmax):
    """The nearest of the unbounded primitives (after the BVH's) hit by the ray."""
    return intersect_range(G, X, G.n_bounded, G.prims.shape[0], o, d, shear, tmin, tmax, NO_HIT, 0.0, 0.0, False)


@njit(**KERNEL, inline="always")
def closest_hit(G, X, o, d, tmin, tmax, node_stack, t_stack):
    """Nearest hit in (tmin, tmax): (t, primitive, b1, b2); primitive NO_HIT when nothing.
    b1, b2 are the barycentric weights of a triangle's second and third vertices."""
    shear = ray_shear(d) if G.triangles.shape[0] > 0 else NO_SHEAR
    best_t, prim, b1, b2 = tmax, NO_HIT, 0.0, 0.0
    if X is not None:
        if G.n_bounded < G.prims.shape[0]:
            best_t, prim, b1, b2 = _unbounded_hit(G, X, o, d, shear, tmin, tmax)
    nodes = G.node_index
    bounds = G.node_bounds
    # A root leaf (small scenes) needs neither box tests nor the inverse direction.
    slab = _NO_SLAB
    if nodes[0, 1] == 0:
        if nodes[0, 0] == 0:
            return best_t, prim, b1, b2  # empty scene
        slab = slab_ray(d)
        if intersect_box(bounds, 0, o, slab, best_t) == INF:
            return best_t, prim, b1, b2
    node = 0
    top = 0
    while True:
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            best_t, prim, b1, b2 = intersect_range(
                G, X, first, first + count, o, d, shear, tmin, best_t, prim, b1, b2, False
            )
        else:
            left = node + 1
            right = nodes[node, 0]
            t_left = intersect_box(bounds, left, o, slab, best_t)
            t_right = intersect_box(bounds, right, o, slab, best_t)
            if t_left != INF and t_right != INF:
                if t_right < t_left:
                    left, right = right, left
                    t_left, t_right = t_right, t_left
                node_stack[top] = right
                t_stack[top] = t_right
                top += 1
                node = left
                continue
            if t_left != INF:
                node = left
                continue
            if t_right != INF:
                node = right
                continue
        # pop the next subtree still nearer than the best hit so far
        found = False
        while top > 0:
            top -= 1
            if t_stack[top] < best_t:
                node = node_stack[top]
                found = True
                break
        if not found:
            break
    return best_t, prim, b1, b2


@njit(**KERNEL, inline="always")
def any_hit(G, X, o, d, tmin, tmax, node_stack):
    """True when anything lies in (tmin, tmax): stops at the first blocker found."""
    shear = ray_shear(d) if G.triangles.shape[0] > 0 else NO_SHEAR
    if X is not None:
        if G.n_bounded < G.prims.shape[0] and _unbounded_hit(G, X, o, d, shear, tmin, tmax)[1] >= 0:
            return True
    nodes = G.node_index
    bounds = G.node_bounds
    if nodes[0, 1] == 0 and nodes[0, 0] == 0:
        return False  # empty scene
    slab = slab_ray(d) if nodes[0, 1] == 0 else _NO_SLAB
    node_stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            if intersect_range(G, X, first, first + count, o, d, shear, tmin, tmax, NO_HIT, 0.0, 0.0, True)[1] >= 0:
                return True
        else:
            # test children before pushing them, so the stack holds only boxes the ray enters
            right = nodes[node, 0]
            if intersect_box(bounds, right, o, slab, tmax) != INF:
                node_stack[top] = right
                top += 1
            if intersect_box(bounds, node + 1, o, slab, tmax) != INF:
                node_stack[top] = node + 1
                top += 1
    return False
