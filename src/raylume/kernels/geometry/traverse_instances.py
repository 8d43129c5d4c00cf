"""Two-level traversal: the top-level BVH over instances, and each instanced mesh's own BVH.

X (an Instances, kernels/scene.py) holds one node array: the top-level BVH (TLAS, root node 0)
over the instances' world boxes, then the bottom-level BVH (BLAS) of every instanced mesh, each
rooted at the node its instances name. Both are the wide BVH of accel/wide.py. At a top-level
leaf the ray is moved into the instance's object space by the inverse matrix, direction *not*
normalised, so distances along it are the world ray's t: the best hit so far prunes the BLAS as
it is, and a BLAS hit's t needs no conversion. The watertight test's shear constants and the
box test's per-ray constants are those of the object-space ray.

BLASes hold triangles alone (instanced meshes), so their leaves are tested by the triangle tests
directly. A BLAS traversal runs on the same stacks, above the top-level entries still pending
(compile/geometry.py checks that both depths fit TRAVERSAL_STACK).

These functions are calls, not inlined: only scenes with instances run them, each call passes
the views by value once per ray, and inlining them into every traversal site would grow every
kernel's compile time.
"""

import numpy as np

from ..vec import inline_function, kernel_function
from .shape_triangle import intersect_triangle, intersect_triangle_block, ray_shear
from .shapes import INSTANCE_SHIFT, NO_HIT, PRIM_ROW
from .wide_nodes import box_ray, leaf_count, leaf_first, pop_nearer, push_children, traceable


@inline_function
def _to_object(inv, i, o, d):
    """The world ray (o, d) in instance i's object space (d not normalised)."""
    oo = (
        inv[i, 0] * o[0] + inv[i, 1] * o[1] + inv[i, 2] * o[2] + inv[i, 3],
        inv[i, 4] * o[0] + inv[i, 5] * o[1] + inv[i, 6] * o[2] + inv[i, 7],
        inv[i, 8] * o[0] + inv[i, 9] * o[1] + inv[i, 10] * o[2] + inv[i, 11],
    )
    dd = (
        inv[i, 0] * d[0] + inv[i, 1] * d[1] + inv[i, 2] * d[2],
        inv[i, 4] * d[0] + inv[i, 5] * d[1] + inv[i, 6] * d[2],
        inv[i, 8] * d[0] + inv[i, 9] * d[1] + inv[i, 10] * d[2],
    )
    return oo, dd


@inline_function
def _leaf_triangles(prims, tris, cols, leaf, o, shear, tmin, best_t):
    """The nearest hit in the BLAS leaf whose reference is `leaf`: (t, primitive or NO_HIT, b1, b2)."""
    first = leaf_first(leaf)
    count = leaf_count(leaf)
    if count < 0:  # 2 to 4 triangles in consecutive rows, tested together
        row = np.int64(prims[first, PRIM_ROW])
        t, j, u, v = intersect_triangle_block(o, shear, tris, cols, row, -count, tmin, best_t)
        if t < best_t:
            return t, np.int64(first + j), u, v
        return best_t, np.int64(NO_HIT), 0.0, 0.0
    prim, b1, b2 = np.int64(NO_HIT), 0.0, 0.0
    for k in range(first, first + count):
        t, u, v = intersect_triangle(o, shear, tris, np.int64(prims[k, PRIM_ROW]), tmin, best_t)
        if t < best_t:
            best_t, prim, b1, b2 = t, np.int64(k), u, v
    return best_t, prim, b1, b2


@inline_function
def _blas_hit(prims, tris, cols, bounds, index, root, o, d, tmin, best_t, node_stack, t_stack, base, stop_at_first):
    """Nearest hit of the object-space ray in the BLAS rooted at `root`, nearer than best_t,
    using the stacks from `base` up: (t, primitive or NO_HIT, b1, b2). With stop_at_first, the
    first leaf's hit (any-hit queries), children nearest first as in traverse._bvh_hit."""
    prim, b1, b2 = np.int64(NO_HIT), 0.0, 0.0
    if not traceable(o, d):
        return best_t, prim, b1, b2
    shear = ray_shear(d)
    rf, rows = box_ray(o, d)
    ref = np.int64(root)
    top = base
    while True:
        if ref >= 0:
            k, nearest = push_children(
                bounds, index, prims, ref, rf, rows, best_t, node_stack, t_stack, top, prims, False
            )
            if k > 0:
                top += k - 1
                ref = np.int64(nearest)
                continue
        else:
            t, j, u, v = _leaf_triangles(prims, tris, cols, ref, o, shear, tmin, best_t)
            if j != NO_HIT:
                best_t, prim, b1, b2 = t, j, u, v
                if stop_at_first:
                    break
        found, top, entry = pop_nearer(node_stack, t_stack, top, base, best_t)
        ref = np.int64(entry)
        if not found:
            break
    return best_t, prim, b1, b2


@kernel_function
def instances_hit(G, X, o, d, tmin, best_t, hit, b1, b2, node_stack, t_stack, stop_at_first):
    """The nearest instance hit nearer than best_t, else (best_t, hit, b1, b2) unchanged; with
    stop_at_first, the first one found (any-hit queries). A hit is `(instance + 1) <<
    INSTANCE_SHIFT | primitive` (shapes.split_hit)."""
    if X.inverse.shape[0] == 0 or not traceable(o, d):
        return best_t, hit, b1, b2
    bounds = X.node_bounds
    index = X.node_index
    inv = X.inverse
    rf, rows = box_ray(o, d)
    ref = np.int64(0)
    top = 0
    while True:
        if ref >= 0:
            k, nearest = push_children(bounds, index, inv, ref, rf, rows, best_t, node_stack, t_stack, top, inv, False)
            if k > 0:
                top += k - 1
                ref = np.int64(nearest)
                continue
        else:
            first = leaf_first(ref)
            for i in range(first, first + abs(leaf_count(ref))):
                oo, dd = _to_object(inv, i, o, d)
                root = X.index[i, 0]
                t, j, u, v = _blas_hit(
                    G.prims, G.triangles, G.triangle_columns, bounds, index, root, oo, dd, tmin, best_t, node_stack,
                    t_stack, top, stop_at_first,
                )  # fmt: skip
                if j != NO_HIT:
                    best_t, b1, b2 = t, u, v
                    hit = ((np.int64(i) + 1) << INSTANCE_SHIFT) | j
                    if stop_at_first:
                        return best_t, hit, b1, b2
        found, top, entry = pop_nearer(node_stack, t_stack, top, 0, best_t)
        ref = np.int64(entry)
        if not found:
            break
    return best_t, hit, b1, b2
