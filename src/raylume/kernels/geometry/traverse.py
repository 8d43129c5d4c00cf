"""BVH traversal: closest hit (nearest children first) and any hit (for shadow rays).

The BVH is wide (accel/wide.py): each node holds up to BVH_WIDTH children, their boxes stored
structure-of-arrays (a record of rows of W lanes per node: one row per slab plane, then the
children's indices; one lane per child).
`box_hits` tests a ray against all W boxes of a node at once, in explicit LLVM vector code
(one ymm register per plane row on AVX2: vsubps, vmulps, vmaxps, vminps, vcmpps), so it
vectorises whatever Numba's SLP vectoriser setting, and the on-disk cache cannot hold a scalar
version of it. The hit children are pushed onto the stack sorted by entry distance (nearest on
top); popped entries beyond the best hit so far are skipped. Any-hit queries take the same
path and stop at the first leaf with a hit.

Primitives are tested through one leaf loop (`intersect_range`) over the primitive table
(shapes.py); leaves are ranges of it. Unbounded primitives (planes) follow the bounded ones in
that table and are tested before traversal.

Stack entries are lanes' references (layout.py): an inner node's index (>= 0), or a leaf's
first primitive and count field in one negative int32 (leaf_first, leaf_count).
"""

import numpy as np
from numba.extending import overload

from ..scene import is_instances
from ..vec import INLINE_OVERLOAD, inline_function
from .layout import NODE_REF, SPHERE_BLOCK
from .shape_sphere import intersect_spheres
from .shape_triangle import NO_SHEAR, intersect_triangle_block, ray_shear
from .shapes import NO_HIT, PRIM_LAST, PRIM_ROW, intersect, split_hit
from .sweep import sweep_hit
from .wide_nodes import (
    box_ray,
    leaf_count,
    leaf_first,
    pop_nearer,
    prefetch_cells,
    prefetch_neighbours,
    prefetch_row,
    push_children,
    traceable,
)

# --- leaves -----------------------------------------------------------------------------------


@inline_function
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


@inline_function
def rows_in_leaf_order(G):
    """Whether every bounded primitive is a triangle: compile/geometry.py then numbers the triangle rows
    in leaf order, so a leaf's first primitive is its first triangle row."""
    return G.triangles.shape[0] == G.n_bounded


@inline_function
def prefetch_surface(G, X, hit):
    """Start loading what shapes.surface reads for a hit (not NO_HIT): its row of the primitive
    table and, where that row's triangle is its own row (rows_in_leaf_order), the triangle's
    vertex normals and smooth flag. The traversal reads the triangles alone, so on a large mesh
    each of these is a cache miss of its own at shading; a renderer that traces several rays
    before it shades them asks for them as each hit is found."""
    k = split_hit(X, hit)[0]
    prefetch_cells(G.prims, k, 0, PRIM_LAST)
    if rows_in_leaf_order(G):
        prefetch_row(G.triangle_smooth, k)
        if k < G.triangle_normals.shape[0]:  # (one row when no mesh is smooth)
            prefetch_cells(G.triangle_normals, k, 0, 8)


@inline_function
def block_row(G, first):
    """The first triangle row of a block leaf whose first primitive is `first`: read straight
    from it where rows_in_leaf_order, so that the triangles' load need not wait for the
    primitive table's (a cache miss of its own on a large mesh: bumpy 4M single-ray hit rays
    on a Zen 3 187.5 -> 139.4 ms, alternating; 40k 52.9 -> 50.3)."""
    return np.int64(first) if rows_in_leaf_order(G) else np.int64(G.prims[first, PRIM_ROW])


@inline_function
def intersect_leaf(G, X, first, count, o, d, shear, tmin, best_t, prim, b1, b2, stop_at_first):
    """A leaf (its count field decoded as accel/wide.py says): blocks of 2 to 4 triangles or of 2
    to 8 spheres tested four at a time, other leaves primitive by primitive (with stop_at_first, up to the
    first hit: any-hit queries). Returns the updated (best_t, prim, b1, b2)."""
    if count < -SPHERE_BLOCK:
        n = -count - SPHERE_BLOCK
        P = G.prims
        r0 = P[first, PRIM_ROW]
        rows = (
            r0,
            P[first + 1, PRIM_ROW],
            P[first + 2, PRIM_ROW] if n > 2 else r0,
            P[first + 3, PRIM_ROW] if n > 3 else r0,
        )
        t, j = intersect_spheres(G.shapes, rows, min(n, 4), o, d, tmin, best_t)
        if n > 4:  # a root leaf of 5 to 8 spheres (mark_sphere_leaves): the next four, nearer only
            r4 = P[first + 4, PRIM_ROW]
            rows = (
                r4,
                P[first + 5, PRIM_ROW] if n > 5 else r4,
                P[first + 6, PRIM_ROW] if n > 6 else r4,
                P[first + 7, PRIM_ROW] if n > 7 else r4,
            )
            t4, j4 = intersect_spheres(G.shapes, rows, n - 4, o, d, tmin, min(t, best_t))
            if t4 < t:
                t, j = t4, j4 + 4
        if t < best_t:
            return t, first + j, 0.0, 0.0
        return best_t, prim, b1, b2
    if count < 0:  # -count triangles in consecutive rows
        row = block_row(G, first)
        t, j, u, v = intersect_triangle_block(o, shear, G.triangles, G.triangle_columns, row, -count, tmin, best_t)
        if t < best_t:
            return t, first + j, u, v
        return best_t, prim, b1, b2
    return intersect_range(G, X, first, first + count, o, d, shear, tmin, best_t, prim, b1, b2, stop_at_first)


# Inlined: with a call, every ray of a scene with planes passed the Geometry view by value
# (glass example: trace 10%, cast 30% slower). Scenes without unbounded shapes compile none of
# it (X is None, see variants.features). Any-hit queries use it too, without stopping early (a
# few planes).
@inline_function
def _unbounded_hit(G, X, o, d, shear, tmin, tmax):
    """The nearest of the unbounded primitives (after the BVH's) hit by the ray."""
    return intersect_range(G, X, G.n_bounded, G.prims.shape[0], o, d, shear, tmin, tmax, NO_HIT, 0.0, 0.0, False)


# --- instances ---------------------------------------------------------------------------------
# Scenes with instances (X an Instances) test them beside the unbounded primitives, before the
# world BVH (traverse_instances.py); every other variant compiles nothing for them.


def _instances_hit(G, X, o, d, tmin, best_t, prim, b1, b2, node_stack, t_stack, stop_at_first):
    raise NotImplementedError("a Numba overload")


@overload(_instances_hit, jit_options=INLINE_OVERLOAD)
def _instances_hit_impl(G, X, o, d, tmin, best_t, prim, b1, b2, node_stack, t_stack, stop_at_first):
    if is_instances(X):
        from .traverse_instances import instances_hit

        # The empty test inlined, before the call: path mode passes Instances for every scene,
        # and a call per ray passing the views slowed Cornell path mode (1.85 -> 2.24 s). The primitive as
        # int64 and distances as floats: a literal (NO_HIT) at some call sites would compile
        # the function once more per literal.
        def impl(G, X, o, d, tmin, best_t, prim, b1, b2, node_stack, t_stack, stop_at_first):
            if X.inverse.shape[0] == 0:
                return float(best_t), np.int64(prim), float(b1), float(b2)
            return instances_hit(
                G, X, o, d, float(tmin), float(best_t), np.int64(prim), float(b1), float(b2), node_stack, t_stack,
                bool(stop_at_first),
            )  # fmt: skip

        return impl
    return lambda G, X, o, d, tmin, best_t, prim, b1, b2, node_stack, t_stack, stop_at_first: (best_t, prim, b1, b2)


# --- traversal --------------------------------------------------------------------------------


@inline_function
def _root_is_a_leaf(index):
    """A root node with one leaf lane (small scenes; one node has no inner children, so an
    unused lane 1 means lane 0 alone)."""
    return index.shape[0] == 1 and index[0, NODE_REF, 1] >= 0


@inline_function
def _lazy_shear(G, X):
    """Whether a ray's shear (the exact triangle test's constants) waits until a triangle is to be
    tested: without planes or instances, which test before the BVH. A swept scene without planes
    (its instances are none) computes it only for a ray with candidates (sweep.py)."""
    if G.triangles.shape[0] == 0:
        return False
    return X is None or (G.sweep.shape[1] > 0 and G.n_bounded == G.prims.shape[0])


@inline_function
def closest_hit(G, X, o, d, tmin, tmax, node_stack, t_stack):
    """Nearest hit in (tmin, tmax): (t, primitive, b1, b2); primitive NO_HIT when nothing.
    b1, b2 are the barycentric weights of a triangle's second and third vertices."""
    return closest_hit_leaving(G, X, o, d, tmin, tmax, NO_HIT, node_stack, t_stack)


@inline_function
def closest_hit_leaving(G, X, o, d, tmin, tmax, leaving, node_stack, t_stack):
    """closest_hit for a ray leaving primitive `leaving` (NO_HIT: none), its origin offset from
    the surface to the side it goes to: the same hit, which small scenes find faster knowing
    that (sweep.py)."""
    # Without planes or instances the shear is computed at the first leaf, not before the
    # traversal: a ray that misses every box never computes it, and the others do not hold it
    # through the first node visits (bunny and bumpy 10k-1M frames ~8% less time, their hit
    # rays ~3%; benchmarks/bench_hits.py, alternating builds). Planes and instances need it
    # before the traversal.
    lazy_shear = _lazy_shear(G, X)
    shear = ray_shear(d) if G.triangles.shape[0] > 0 and not lazy_shear else NO_SHEAR
    best_t, prim, b1, b2 = tmax, NO_HIT, 0.0, 0.0
    if X is not None:
        if G.n_bounded < G.prims.shape[0]:
            best_t, prim, b1, b2 = _unbounded_hit(G, X, o, d, shear, tmin, tmax)
        best_t, prim, b1, b2 = _instances_hit(G, X, o, d, tmin, best_t, prim, b1, b2, node_stack, t_stack, False)
    return _bvh_hit(
        G, X, o, d, shear, lazy_shear, tmin, best_t, prim, b1, b2, node_stack, t_stack, False, leaving, NO_HIT
    )


@inline_function
def any_hit(G, X, o, d, tmin, tmax, node_stack, t_stack):
    """True when anything lies in (tmin, tmax): stops at the first blocker found."""
    return any_hit_between(G, X, o, d, tmin, tmax, NO_HIT, NO_HIT, node_stack, t_stack)


@inline_function
def any_hit_leaving(G, X, o, d, tmin, tmax, leaving, node_stack, t_stack):
    """any_hit for a ray leaving primitive `leaving`, as closest_hit_leaving."""
    return any_hit_between(G, X, o, d, tmin, tmax, leaving, NO_HIT, node_stack, t_stack)


@inline_function
def any_hit_between(G, X, o, d, tmin, tmax, leaving, arriving, node_stack, t_stack):
    """any_hit for a shadow ray leaving primitive `leaving` (as closest_hit_leaving) and aimed at
    a point of primitive `arriving` (NO_HIT: none), ending short of it (shadow.shadow_ray): the
    exact test cannot hit a flat one there either, which small scenes use (sweep.py)."""
    lazy_shear = _lazy_shear(G, X)  # as in closest_hit
    shear = ray_shear(d) if G.triangles.shape[0] > 0 and not lazy_shear else NO_SHEAR
    if X is not None:
        if G.n_bounded < G.prims.shape[0] and _unbounded_hit(G, X, o, d, shear, tmin, tmax)[1] >= 0:
            return True
        if _instances_hit(G, X, o, d, tmin, tmax, NO_HIT, 0.0, 0.0, node_stack, t_stack, True)[1] != NO_HIT:
            return True
    hit = _bvh_hit(
        G, X, o, d, shear, lazy_shear, tmin, tmax, NO_HIT, 0.0, 0.0, node_stack, t_stack, True, leaving, arriving
    )
    return hit[1] != NO_HIT


@inline_function
def _bvh_hit(
    G, X, o, d, shear, lazy_shear, tmin, best_t, prim, b1, b2, node_stack, t_stack, stop_at_first, leaving, arriving
):
    """The nearest hit in the BVH in (tmin, best_t), or (best_t, prim, b1, b2) unchanged; with
    stop_at_first, the first hit of the first leaf that has one (any_hit). Both visit the
    children nearest first: a shadow ray that a surface blocks near its origin (its own
    surface, facing away from the light) finds it in the first leaves instead of wherever the
    lane order leads (bench_shadows.py's rays one by one: bumpy 4M 10-15% less time, 40k 2-3%,
    than with the unsorted stack any-hit had; alternating builds in one process)."""
    if G.sweep.shape[1] > 0:  # a small scene: every triangle at once (sweep.py)
        return sweep_hit(G, X, o, d, shear, lazy_shear, tmin, best_t, prim, b1, b2, stop_at_first, leaving, arriving)
    index = G.node_index
    bounds = G.node_bounds
    if _root_is_a_leaf(index):
        # its one leaf, with no box test and before the per-ray box constants exist: through
        # the node, or with the constants live across the traversal loop, the seed's trace
        # kernel was 20-60% slower (1 thread)
        if lazy_shear:
            shear = ray_shear(d)
        first, count = leaf_first(index[0, NODE_REF, 0]), leaf_count(index[0, NODE_REF, 0])
        return intersect_leaf(G, X, first, count, o, d, shear, tmin, best_t, prim, b1, b2, stop_at_first)
    if not traceable(o, d):
        return best_t, prim, b1, b2
    rf, rows = box_ray(o, d)
    tri = G.triangles
    direct = rows_in_leaf_order(G)
    ref = 0
    top = 0
    while True:
        if ref >= 0:
            k, nearest = push_children(
                bounds, index, G.prims, ref, rf, rows, best_t, node_stack, t_stack, top, tri, direct
            )
            if k > 0:  # descend into the nearest
                top += k - 1
                ref = nearest
                continue
        else:
            if lazy_shear:
                shear = ray_shear(d)
                lazy_shear = False
            first, count = leaf_first(ref), leaf_count(ref)
            if direct:  # rows in leaf order: a block leaf (count < 0) or one triangle
                prefetch_neighbours(tri, first, first + abs(count))
            best_t, prim, b1, b2 = intersect_leaf(
                G, X, first, count, o, d, shear, tmin, best_t, prim, b1, b2, stop_at_first
            )
            if stop_at_first and prim != NO_HIT:
                break
        found, top, ref = pop_nearer(node_stack, t_stack, top, 0, best_t)
        if not found:
            break
    return best_t, prim, b1, b2
