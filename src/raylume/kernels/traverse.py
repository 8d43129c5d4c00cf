"""BVH traversal: closest hit (nearer child first) and any hit (for shadow rays).

Both take the scene's Geometry view. Infinite planes cannot live in a bounding volume
hierarchy; they are few and tested first. Leaf loops are written inline: a helper call per
leaf costs more than the intersection tests it makes.
"""

import numpy as np
from numba import njit

from .intersect import INF, intersect_box, intersect_plane, intersect_sphere, intersect_triangle, ray_shear, slab_ray
from .layout import HIT_NONE, HIT_PLANE, HIT_SPHERE, HIT_TRIANGLE, PRIM_SPHERE, SCRATCH_PAD, TRAVERSAL_STACK
from .vec import KERNEL, row3

# Shear constants for rays in scenes without triangles, and slab constants for a root leaf
# (never used, but typed alike).
_NO_SHEAR = (0, 1, 2, 0.0, 0.0, 1.0)
_NO_SLAB = ((0.0, 0.0, 0.0), (0, 0, 0))


@njit(cache=True)
def traversal_stacks():
    """One thread's (node_stack, t_stack) for closest_hit and any_hit."""
    return scratch_array(TRAVERSAL_STACK, np.int32), scratch_array(TRAVERSAL_STACK, np.float64)


@njit(cache=True)
def scratch_array(n, dtype):
    """An array of n elements for one thread's scratch, with SCRATCH_PAD unused elements on
    either side against false sharing: see layout.py."""
    return np.empty(n + 2 * SCRATCH_PAD, dtype=dtype)[SCRATCH_PAD:SCRATCH_PAD + n]


@njit(**KERNEL, inline="always")
def closest_hit(G, o, d, tmin, tmax, node_stack, t_stack):
    """Nearest hit in (tmin, tmax): (t, kind, index, b1, b2); kind HIT_NONE when nothing.
    b1, b2 are the barycentric weights of a triangle's second and third vertices."""
    best_t = tmax
    kind = HIT_NONE
    index = -1
    b1 = 0.0
    b2 = 0.0
    for p in range(G.planes.shape[0]):
        t = intersect_plane(o, d, row3(G.planes, p, 0), row3(G.planes, p, 3), tmin, best_t)
        if t < best_t:
            best_t, kind, index = t, HIT_PLANE, p

    nodes = G.node_index
    bounds = G.node_bounds
    shear = ray_shear(d) if G.triangles.shape[0] > 0 else _NO_SHEAR
    # A root leaf (small scenes) needs neither box tests nor the inverse direction.
    slab = _NO_SLAB
    if nodes[0, 1] == 0:
        if nodes[0, 0] == 0:
            return best_t, kind, index, b1, b2  # empty scene
        slab = slab_ray(d)
        if intersect_box(bounds, 0, o, slab, best_t) == INF:
            return best_t, kind, index, b1, b2
    node = 0
    top = 0
    while True:
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            for k in range(first, first + count):
                pid = G.prim_id[k]
                if G.prim_type[k] == PRIM_SPHERE:
                    t = intersect_sphere(o, d, row3(G.spheres, pid, 0), G.spheres[pid, 3], tmin, best_t)
                    if t < best_t:
                        best_t, kind, index = t, HIT_SPHERE, pid
                else:
                    t, u, v = intersect_triangle(o, shear, G.triangles, pid, tmin, best_t)
                    if t < best_t:
                        best_t, kind, index, b1, b2 = t, HIT_TRIANGLE, pid, u, v
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
    return best_t, kind, index, b1, b2


@njit(**KERNEL, inline="always")
def any_hit(G, o, d, tmin, tmax, node_stack):
    """True when anything lies in (tmin, tmax): stops at the first blocker found."""
    for p in range(G.planes.shape[0]):
        if intersect_plane(o, d, row3(G.planes, p, 0), row3(G.planes, p, 3), tmin, tmax) < INF:
            return True
    nodes = G.node_index
    bounds = G.node_bounds
    if nodes[0, 1] == 0 and nodes[0, 0] == 0:
        return False  # empty scene
    shear = ray_shear(d) if G.triangles.shape[0] > 0 else _NO_SHEAR
    slab = slab_ray(d) if nodes[0, 1] == 0 else _NO_SLAB
    node_stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            for k in range(first, first + count):
                pid = G.prim_id[k]
                if G.prim_type[k] == PRIM_SPHERE:
                    if intersect_sphere(o, d, row3(G.spheres, pid, 0), G.spheres[pid, 3], tmin, tmax) < INF:
                        return True
                elif intersect_triangle(o, shear, G.triangles, pid, tmin, tmax)[0] < INF:
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
