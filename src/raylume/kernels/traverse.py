"""BVH traversal: closest hit (nearer child first) and any hit (for shadow rays).

Infinite planes cannot live in a bounding volume hierarchy; they are few and tested first.
Per-ray setup (inverse direction, watertight shear) is skipped where a scene does not need it:
small scenes have a single leaf as root, and sphere-only scenes never need the shear.
"""

from numba import njit

from .intersect import INF, intersect_box, intersect_plane, intersect_sphere, intersect_triangle, ray_shear, safe_inverse
from .layout import HIT_NONE, HIT_PLANE, HIT_SPHERE, HIT_TRIANGLE, PRIM_SPHERE
from .vec import FAST, row3


@njit(fastmath=FAST)
def _nearest_plane(S, o, d, tmin, tmax):
    best_t = tmax
    index = -1
    for p in range(S.planes.shape[0]):
        t = intersect_plane(o, d, row3(S.planes, p, 0), row3(S.planes, p, 3), tmin, best_t)
        if t < best_t:
            best_t, index = t, p
    return best_t, index


@njit(fastmath=FAST)
def _leaf_closest(S, k0, k1, o, d, shear, tmin, best_t, kind, index, b1, b2):
    for k in range(k0, k1):
        pid = S.prim_id[k]
        if S.prim_type[k] == PRIM_SPHERE:
            t = intersect_sphere(o, d, row3(S.spheres, pid, 0), S.spheres[pid, 3], tmin, best_t)
            if t < best_t:
                best_t, kind, index = t, HIT_SPHERE, pid
        else:
            t, u, v = intersect_triangle(o, shear, S.triangles, pid, tmin, best_t)
            if t < best_t:
                best_t, kind, index, b1, b2 = t, HIT_TRIANGLE, pid, u, v
    return best_t, kind, index, b1, b2


@njit(fastmath=FAST)
def closest_hit(S, o, d, tmin, tmax, node_stack, t_stack):
    """Nearest hit in (tmin, tmax): (t, kind, index, b1, b2); kind HIT_NONE when nothing."""
    best_t, index = _nearest_plane(S, o, d, tmin, tmax)
    kind = HIT_PLANE if index >= 0 else HIT_NONE
    b1 = 0.0
    b2 = 0.0
    nodes = S.node_index
    shear = ray_shear(d) if S.triangles.shape[0] > 0 else (0, 1, 2, 0.0, 0.0, 1.0)
    if nodes[0, 1] > 0:  # the root is a leaf: test its primitives directly
        return _leaf_closest(S, nodes[0, 0], nodes[0, 0] + nodes[0, 1], o, d, shear, tmin, best_t, kind, index, b1, b2)
    inv_d = safe_inverse(d)
    bounds = S.node_bounds
    if nodes[0, 0] == 0 or intersect_box(bounds, 0, o, inv_d, best_t) == INF:
        return best_t, kind, index, b1, b2  # empty scene, or the ray misses everything
    node = 0
    top = 0
    while True:
        count = nodes[node, 1]
        if count > 0:
            first = nodes[node, 0]
            best_t, kind, index, b1, b2 = _leaf_closest(S, first, first + count, o, d, shear, tmin, best_t, kind, index, b1, b2)
        else:
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
def _leaf_any(S, k0, k1, o, d, shear, tmin, tmax):
    for k in range(k0, k1):
        pid = S.prim_id[k]
        if S.prim_type[k] == PRIM_SPHERE:
            if intersect_sphere(o, d, row3(S.spheres, pid, 0), S.spheres[pid, 3], tmin, tmax) < INF:
                return True
        elif intersect_triangle(o, shear, S.triangles, pid, tmin, tmax)[0] < INF:
            return True
    return False


@njit(fastmath=FAST)
def any_hit(S, o, d, tmin, tmax, node_stack):
    """True when anything lies in (tmin, tmax): stops at the first blocker found."""
    if _nearest_plane(S, o, d, tmin, tmax)[1] >= 0:
        return True
    nodes = S.node_index
    shear = ray_shear(d) if S.triangles.shape[0] > 0 else (0, 1, 2, 0.0, 0.0, 1.0)
    if nodes[0, 1] > 0:
        return _leaf_any(S, nodes[0, 0], nodes[0, 0] + nodes[0, 1], o, d, shear, tmin, tmax)
    if nodes[0, 0] == 0:
        return False  # empty scene
    inv_d = safe_inverse(d)
    bounds = S.node_bounds
    node_stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = node_stack[top]
        if intersect_box(bounds, node, o, inv_d, tmax) == INF:
            continue
        count = nodes[node, 1]
        if count > 0:
            if _leaf_any(S, nodes[node, 0], nodes[node, 0] + count, o, d, shear, tmin, tmax):
                return True
        else:
            node_stack[top] = nodes[node, 0]
            node_stack[top + 1] = node + 1
            top += 2
    return False
