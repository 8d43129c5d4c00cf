"""BVH traversal: closest hit (nearer child first) and any hit (for shadow rays).

Infinite planes cannot live in a bounding volume hierarchy; they are few and tested first.
"""

from numba import njit

from .intersect import INF, intersect_box, intersect_plane, intersect_sphere, intersect_triangle, ray_shear, safe_inverse
from .layout import HIT_NONE, HIT_PLANE, HIT_SPHERE, HIT_TRIANGLE, PRIM_SPHERE
from .vec import FAST, row3


@njit(fastmath=FAST)
def closest_hit(S, o, d, tmin, tmax, node_stack, t_stack):
    """Nearest hit in (tmin, tmax): (t, kind, index, b1, b2); kind HIT_NONE when nothing."""
    best_t = tmax
    kind = HIT_NONE
    index = -1
    b1 = 0.0
    b2 = 0.0
    for p in range(S.planes.shape[0]):
        t = intersect_plane(o, d, row3(S.planes, p, 0), row3(S.planes, p, 3), tmin, best_t)
        if t < best_t:
            best_t, kind, index = t, HIT_PLANE, p

    inv_d = safe_inverse(d)
    shear = ray_shear(d)
    bounds = S.node_bounds
    nodes = S.node_index
    if intersect_box(bounds, 0, o, inv_d, best_t) == INF:
        return best_t, kind, index, b1, b2
    node = 0
    top = 0
    while True:
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            for k in range(first, first + count):
                pid = S.prim_id[k]
                if S.prim_type[k] == PRIM_SPHERE:
                    t = intersect_sphere(o, d, row3(S.spheres, pid, 0), S.spheres[pid, 3], tmin, best_t)
                    if t < best_t:
                        best_t, kind, index = t, HIT_SPHERE, pid
                else:
                    t, u, v = intersect_triangle(o, shear, S.triangles, pid, tmin, best_t)
                    if t < best_t:
                        best_t, kind, index, b1, b2 = t, HIT_TRIANGLE, pid, u, v
        elif nodes[node, 0] > node:  # inner node (an empty root leaf has count 0 and index 0)
            left = node + 1
            right = nodes[node, 0]
            t_left = intersect_box(bounds, left, o, inv_d, best_t)
            t_right = intersect_box(bounds, right, o, inv_d, best_t)
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


@njit(fastmath=FAST)
def any_hit(S, o, d, tmin, tmax, node_stack):
    """True when anything lies in (tmin, tmax): stops at the first blocker found."""
    for p in range(S.planes.shape[0]):
        if intersect_plane(o, d, row3(S.planes, p, 0), row3(S.planes, p, 3), tmin, tmax) < INF:
            return True
    inv_d = safe_inverse(d)
    shear = ray_shear(d)
    bounds = S.node_bounds
    nodes = S.node_index
    top = 0
    node_stack[top] = 0
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        if intersect_box(bounds, node, o, inv_d, tmax) == INF:
            continue
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            for k in range(first, first + count):
                pid = S.prim_id[k]
                if S.prim_type[k] == PRIM_SPHERE:
                    if intersect_sphere(o, d, row3(S.spheres, pid, 0), S.spheres[pid, 3], tmin, tmax) < INF:
                        return True
                elif intersect_triangle(o, shear, S.triangles, pid, tmin, tmax)[0] < INF:
                    return True
        elif nodes[node, 0] > node:
            node_stack[top] = nodes[node, 0]
            node_stack[top + 1] = node + 1
            top += 2
    return False
