"""Compile stage: geometry and BVH. The gathered geometry becomes the primitive table in BVH leaf
order (kernels/geometry/shapes.py), the triangles reordered to match, the world's wide BVH
(accel/: binned SAH, collapsed to BVH_WIDTH-wide nodes) and the instanced meshes' two levels
(instances.py)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..accel.bvh import build_bvh, triangle_bounds
from ..accel.wide import WideBVH, collapse, mark_sphere_leaves, mark_triangle_leaves, single_leaf, wide_depth
from ..errors import SceneError
from ..kernels.geometry.layout import LEAF_FIRST_LIMIT
from ..kernels.geometry.shape_triangle import TRIANGLES_PER_TEST
from ..kernels.geometry.shapes import (
    PRIM_FACE,
    PRIM_KIND,
    PRIM_LIGHT,
    PRIM_MATERIAL,
    PRIM_OBJECT,
    PRIM_ROW,
    PRIM_WIDTH,
    Shape,
)
from ..kernels.geometry.wide_nodes import BVH_WIDTH, TRAVERSAL_STACK, stack_needed
from .instances import InstanceArrays, build_instances, join_triangles, place_instanced
from .objects import SceneGeometry, _Analytic

# BVH shape, measured on the seed scene and the bunny (benchmarks/bench_bvh.py): visiting a node
# (two box tests) costs about as much as two primitive tests, and scenes of a few primitives
# are fastest as a single leaf, with no box test at all.
BVH_MAX_LEAF = 4
BVH_TRAVERSAL_COST = 2.0
# A leaf of up to 4 triangles or spheres is one vector test (kernels/geometry/traverse.py intersect_leaf),
# so the heuristic counts a leaf's cost in blocks of 4: a leaf of 1 costs as much as one of 4.
# Hit rays on a 1M-triangle mesh ~3% faster, the bunny ~1.5% (benchmarks/bench_hits.py).
BVH_LEAF_BLOCK = TRIANGLES_PER_TEST
BVH_OPTIONS = {"max_leaf_size": BVH_MAX_LEAF, "c_trav": BVH_TRAVERSAL_COST, "leaf_block": BVH_LEAF_BLOCK}
SMALL_SCENE = 8


class BuiltGeometry(NamedTuple):
    """The geometry as the kernels read it (KernelScene's fields of the same names), the BVHs,
    and what the other stages need: the primitive table's world rows, the scene's extent."""

    prims: np.ndarray  # int32 (P, PRIM_WIDTH); PRIM_LIGHT -1 until the lights stage
    n_world: int  # prims[:n_world]: the world BVH's, in leaf order; then the instanced meshes'
    n_bounded: int
    shapes: np.ndarray
    triangles: np.ndarray
    triangle_normals: np.ndarray
    triangle_smooth: np.ndarray
    triangle_uvs: np.ndarray
    bvh: WideBVH
    depth: int
    instances: InstanceArrays
    extent: float  # the largest coordinate magnitude of the geometry (for ray offsets)
    radius: float  # the bounded geometry's bounding radius, half its box's diagonal (for light powers)


def build_geometry(geometry: SceneGeometry, accelerate: bool, source: str) -> BuiltGeometry:
    """The primitive table, triangles and BVHs of the gathered geometry. `accelerate=False`
    skips the BVH (the rasterizer needs none: at 4M triangles that saves about 9 s)."""
    analytic, soup = geometry.analytic, geometry.soup
    shapes = analytic.table()
    bounded = analytic.bounded()
    in_bvh = np.flatnonzero(bounded)  # analytic rows in the BVH, in object order
    unbounded = np.flatnonzero(~bounded)
    tri, tri_n, tri_smooth, tri_mat, tri_obj, tri_face = soup.arrays()
    tri_uv = soup.uv_array()
    n_analytic, n_tris = len(in_bvh), len(tri)
    stored = n_analytic + n_tris + sum(len(m.triangles) for m in geometry.instanced)
    if stored > LEAF_FIRST_LIMIT:  # what a BVH leaf's reference can point at (kernels/geometry/layout.py)
        raise SceneError(
            f"{source}: {stored:,} primitives, more than the {LEAF_FIRST_LIMIT:,} a scene holds; "
            "place repeated meshes as instances"
        )
    copies = sum(len(m.matrices) for m in geometry.instanced)
    if copies > LEAF_FIRST_LIMIT:  # the top-level BVH's leaves point at instances
        raise SceneError(f"{source}: {copies:,} instances, more than the {LEAF_FIRST_LIMIT:,} a scene holds")
    inst = build_instances(geometry.instanced, accelerate)

    # Bounds of every BVH primitive: bounded analytic shapes first, then triangles (of the
    # float32 vertices the kernels intersect, so the boxes are exact).
    lo = np.empty((n_analytic + n_tris, 3), dtype=np.float64)
    hi = np.empty_like(lo)
    lo[:n_analytic], hi[:n_analytic] = analytic.bounds(shapes, in_bvh)
    if n_tris:
        triangle_bounds(tri, lo[n_analytic:], hi[n_analytic:])
    if accelerate and len(lo) > SMALL_SCENE:
        # the binned-SAH binary tree, collapsed into BVH_WIDTH-wide nodes (accel/wide.py)
        bvh = collapse(build_bvh(lo, hi, **BVH_OPTIONS), BVH_WIDTH)
        depth = wide_depth(bvh)
    else:
        bvh = single_leaf(lo, hi, BVH_WIDTH)
        depth = 1
    if stack_needed(depth) > TRAVERSAL_STACK:  # traversal stacks are fixed-size (no allocation per ray)
        raise SceneError(
            f"{source}: the BVH is {depth} levels deep, more than the traversal supports; "
            "the scene's primitives are pathologically arranged"
        )

    # Reorder so that leaves read consecutive triangles (cache-friendly traversal).
    order = bvh.prim_order.astype(np.int64)
    is_tri = order >= n_analytic
    tri_perm = order[is_tri] - n_analytic
    # (np.take: rows copied whole, ~4x faster than indexing for the (T, 9) tables: 0.09 s
    # against 0.36 s at 4M triangles)
    if n_tris:
        tri, tri_smooth, tri_mat, tri_obj, tri_face = (
            np.take(a, tri_perm, axis=0) for a in (tri, tri_smooth, tri_mat, tri_obj, tri_face)
        )
        if len(tri_n) == n_tris:
            tri_n = np.take(tri_n, tri_perm, axis=0)
        if len(tri_uv) == n_tris:
            tri_uv = np.take(tri_uv, tri_perm, axis=0)

    # The primitive table: the world BVH's primitives in leaf order, the instanced meshes'
    # (each in its BLAS's leaf order), then the unbounded shapes.
    n_world = len(order)
    n_bounded = n_world + len(inst.prims)
    prims = np.zeros((n_bounded + len(unbounded), PRIM_WIDTH), dtype=np.int32)
    prims[:, PRIM_LIGHT] = -1  # no primitive emits light yet (path tracing's emitters will)
    shape_rows = np.concatenate([in_bvh[order[~is_tri]], unbounded])
    shape_slots = np.concatenate([np.flatnonzero(~is_tri), np.arange(n_bounded, len(prims))])
    _fill_prims(prims, shape_slots, shape_rows, analytic)
    # a slice where every world primitive is a triangle (a mesh's scene): indexed, the five
    # strided columns took 0.2 s at 4M triangles
    tri_slots = slice(0, n_tris) if n_tris == n_world else np.flatnonzero(is_tri)
    prims[tri_slots, PRIM_KIND] = Shape.TRIANGLE
    prims[tri_slots, PRIM_ROW] = np.arange(n_tris, dtype=np.int32)
    prims[tri_slots, PRIM_MATERIAL] = tri_mat
    prims[tri_slots, PRIM_OBJECT] = tri_obj
    prims[tri_slots, PRIM_FACE] = tri_face
    if accelerate and n_tris:
        mark_triangle_leaves(bvh, is_tri)  # leaves of triangles alone are tested 4 at a time
    mark_sphere_leaves(bvh, prims[:n_world, PRIM_KIND] == Shape.SPHERE)  # and of spheres alone
    if len(inst.prims):  # the instanced meshes' rows and triangles follow the world's
        place_instanced(inst, n_world, n_tris)
        prims[n_world:n_bounded] = inst.prims
        tri, tri_n, tri_smooth, tri_uv = join_triangles(
            (tri, tri_n, tri_smooth, tri_uv), (inst.triangles, inst.normals, inst.smooth, inst.uvs)
        )
    if inst.stack > TRAVERSAL_STACK:  # a BLAS walk runs on the stack above the TLAS walk's
        raise SceneError(
            f"{source}: the instances' BVHs are too deep together for the traversal; "
            "the instances or an instanced mesh are pathologically arranged"
        )

    # per axis, the least and largest of the boxes' corners (no np.abs (N, 3) temporaries: 0.3 s
    # at 4M triangles), for the largest coordinate's size and the geometry's box
    box_lo, box_hi = inst.box[0], inst.box[1]
    extent = [inst.extent]
    if len(lo):
        lo_min, lo_max, hi_min, hi_max = lo.min(axis=0), lo.max(axis=0), hi.min(axis=0), hi.max(axis=0)
        extent.append(max(-lo_min.min(), lo_max.max(), -hi_min.min(), hi_max.max()))
        box_lo, box_hi = np.minimum(box_lo, lo_min), np.maximum(box_hi, hi_max)
    for r in unbounded:  # an unbounded shape's size is that of its defining point
        extent.append(np.abs(shapes[r, :3]).max())
    return BuiltGeometry(
        prims, n_world, n_bounded, shapes, np.ascontiguousarray(tri), np.ascontiguousarray(tri_n), tri_smooth,
        np.ascontiguousarray(tri_uv), bvh, depth, inst, float(max(extent)), _radius(box_lo, box_hi, max(extent)),
    )  # fmt: skip


def _radius(box_lo: np.ndarray, box_hi: np.ndarray, extent: float) -> float:
    """Half the diagonal of the bounded geometry's box: how far light from an infinite source
    (ambient, environment, directional) falls on the scene, for the lights' sampling weights.
    The largest coordinate magnitude would grow with the scene's distance from the origin: moved
    1000 units away, a small scene's ambient light outweighed its point light 10^5 times, and
    path mode all but never sampled the point light. Scenes of unbounded shapes alone: `extent`."""
    if not (box_lo <= box_hi).all():
        return float(extent)
    return float(0.5 * np.linalg.norm(box_hi - box_lo))


def _fill_prims(prims: np.ndarray, slots: np.ndarray, rows: np.ndarray, analytic: _Analytic) -> None:
    """Primitive-table rows `slots` for the analytic shapes of `rows`."""
    for column, values in (
        (PRIM_KIND, analytic.kinds),
        (PRIM_MATERIAL, analytic.materials),
        (PRIM_OBJECT, analytic.objects),
    ):
        prims[slots, column] = np.asarray(values, dtype=np.int32)[rows] if len(rows) else 0
    prims[slots, PRIM_ROW] = rows  # PRIM_FACE stays 0: an analytic shape is one face
