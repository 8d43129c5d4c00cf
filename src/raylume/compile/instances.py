"""Compile stage (of geometry.py): instanced meshes -> the two-level structure
(kernels/geometry/traverse_instances.py).

Each instanced mesh is stored once, in its own space: its triangles and primitive-table rows
(after the world's), and its own wide BVH (a BLAS). The instances of every mesh share one
top-level wide BVH (the TLAS) over their world boxes. All BLASes follow the TLAS in one node
array; the TLAS's leaves are ranges of the instance arrays, reordered into its leaf order.

What an instance costs: its inverse matrix (3 x 4 float32, 48 bytes), its BLAS root and its
index within its object (int32 x 2, 8 bytes), and its share of the TLAS's nodes (256 bytes per
node; leaves of up to TLAS_MAX_LEAF instances). The inverse is rounded to float32 once, here,
and rays are moved with it in float64: every ray, primary or secondary, sees the same instance,
placed by the rounded matrix (geometry moved by ~1e-7 of its coordinates), so a hit point and
the shadow ray leaving it agree about where the surface is. A float64 inverse (96 bytes) would
put an instance over the 128 bytes it may cost.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..accel.bvh import build_bvh
from ..accel.tlas import build_tlas
from ..accel.wide import (
    NODE_REF,
    WideBVH,
    collapse,
    mark_triangle_leaves,
    single_leaf,
    wide_depth,
    wide_nbytes,
)
from ..kernels.geometry.layout import LEAF_SHIFT, line_aligned
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
from ..kernels.geometry.wide_nodes import BVH_WIDTH, stack_needed
from ..scene.instances import inverse_rows

# BLASes are built as the world BVH is (geometry.py's constants). The TLAS (accel/tlas.py): binned SAH with
# leaves of up to 8 instances and a node visit weighed as 4 instance tests, collapsed so that
# every leaf lane holds one instance (_collapse_tlas): a leaf of 4 or more instances that does
# not fit its parent's free lanes becomes a node of its own. With leaves of up to 4 instances
# tested one after another (the previous TLAS) a camera ray entered 1.8 instances per ray on
# bench_instances' 10 000 copies, 1.2 of them for nothing (it missed the instance's own box);
# one lane per instance: 0.63 and 0.04, 11% less CPU time per frame (512 x 384, A/B medians).
# Per instance it costs 35-50 bytes of nodes (20 before; 10 000 scattered, rotated instances:
# 104 bytes with the record, under the 128 allowed). Leaves of one instance straight from the
# SAH build left the collapsed nodes 3.6/8 full (98 bytes of nodes per instance).
# World boxes: the union of the BLAS's level-2 boxes (up to 64) through the matrix
# (BOX_LEVELS), tighter than the object box's for rotated instances (-30% instances entered on
# randomly turned copies, -5% frame time; level 3 bought nothing more).
BLAS_MAX_LEAF = 4
BLAS_TRAVERSAL_COST = 2.0
BLAS_LEAF_BLOCK = TRIANGLES_PER_TEST  # as the world BVH's (geometry.py BVH_LEAF_BLOCK)
SMALL_BLAS = 8
BOX_LEVELS = 2


class InstanceArrays(NamedTuple):
    prims: np.ndarray  # int32 (P, PRIM_WIDTH): instanced meshes' rows, PRIM_ROW into `triangles`
    triangles: np.ndarray  # float32 (T, 9), object space, each mesh in its BLAS's leaf order
    normals: np.ndarray | None  # float32 (T, 9), None when no instanced mesh is smooth
    smooth: np.ndarray  # bool (T,)
    uvs: np.ndarray | None  # float32 (T, 6), None when none needs UVs
    node_bounds: np.ndarray  # float32 (M, NODE_ROWS, W) node records: the TLAS (root 0), then every BLAS
    node_index: np.ndarray  # the same records as int32 (wide.py); BLAS leaves' first rows relative to `prims`
    blas_leaf: np.ndarray  # bool (M, W): lanes of node_index[:, NODE_REF] that are BLAS leaves
    inverse: np.ndarray  # float32 (N, 12): world-to-object matrices, TLAS leaf order
    index: np.ndarray  # int32 (N, 2): BLAS root node, index within its object
    meshes: np.ndarray  # int64 (K, 3): each instanced mesh's first row of `prims`, rows, BLAS root
    extent: float  # largest world coordinate of the instances' boxes
    box: np.ndarray  # float64 (2, 3): the instances' world box, lo then hi (+inf, -inf where none)
    stack: int  # traversal stack entries a TLAS walk with a BLAS walk on top can need
    node_bytes: int  # the node arrays and the primitive table's kind and row columns
    stats: dict


def empty_instances() -> InstanceArrays:
    tlas = single_leaf(np.zeros((0, 3)), np.zeros((0, 3)), BVH_WIDTH)
    return InstanceArrays(
        prims=np.zeros((0, PRIM_WIDTH), np.int32),
        triangles=np.zeros((0, 9), np.float32),
        normals=None,
        smooth=np.zeros(0, bool),
        uvs=None,
        node_bounds=tlas.node_bounds,
        node_index=tlas.node_index,
        blas_leaf=np.zeros((1, BVH_WIDTH), bool),
        inverse=np.zeros((0, 12), np.float32),
        index=np.zeros((0, 2), np.int32),
        meshes=np.zeros((0, 3), np.int64),
        extent=0.0,
        box=np.array([[np.inf] * 3, [-np.inf] * 3]),
        stack=0,
        node_bytes=0,
        stats={"instances": 0},
    )


def _wide(lo, hi, accelerate, small, max_leaf, c_trav, leaf_block):
    if accelerate and len(lo) > small:
        bvh = build_bvh(lo, hi, max_leaf_size=max_leaf, c_trav=c_trav, leaf_block=leaf_block)
        return collapse(bvh, BVH_WIDTH)
    return single_leaf(lo, hi, BVH_WIDTH)


def blas_boxes(blas: WideBVH, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """Boxes (K, 3) that together hold a BLAS's triangles: its root's child boxes, those of
    inner children replaced by their own children's, `levels` levels down (1: the root's
    children, at most BVH_WIDTH boxes; 2: at most BVH_WIDTH**2)."""
    b, idx = blas.node_bounds, blas.node_index
    nodes = [0]
    lo, hi = [], []
    for level in range(levels):
        deeper = []
        for m in nodes:
            for lane in range(BVH_WIDTH):
                if not b[m, 0, lane] <= b[m, 3, lane]:
                    continue  # an unused lane
                if idx[m, NODE_REF, lane] >= 0 and level + 1 < levels:
                    deeper.append(int(idx[m, NODE_REF, lane]))
                else:
                    lo.append(b[m, :3, lane])
                    hi.append(b[m, 3:6, lane])
        nodes = deeper
    return np.array(lo, np.float64).reshape(-1, 3), np.array(hi, np.float64).reshape(-1, 3)


@nb.njit(cache=True)
def _world_boxes(lo, hi, matrices, out_lo, out_hi):
    for n in range(matrices.shape[0]):
        a = matrices[n]
        for i in range(3):
            out_lo[n, i] = np.inf
            out_hi[n, i] = -np.inf
        for k in range(lo.shape[0]):
            for i in range(3):
                c = a[i, 3]
                e = 0.0
                for j in range(3):
                    c += a[i, j] * (0.5 * (lo[k, j] + hi[k, j]))
                    e += abs(a[i, j]) * (0.5 * (hi[k, j] - lo[k, j]))
                out_lo[n, i] = min(out_lo[n, i], c - e)
                out_hi[n, i] = max(out_hi[n, i], c + e)


def world_boxes(lo: np.ndarray, hi: np.ndarray, matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The world boxes (N, 3) of the object boxes (K, 3) (lo, hi) placed by each (3, 4) matrix:
    the union of each box's exact transformed box (centre moved, half-extent by |A|). Several
    boxes (blas_boxes) bound a rotated instance more tightly than its one object box would."""
    n = len(matrices)
    out_lo, out_hi = np.empty((n, 3)), np.empty((n, 3))
    _world_boxes(
        np.ascontiguousarray(lo, np.float64),
        np.ascontiguousarray(hi, np.float64),
        np.ascontiguousarray(matrices, np.float64),
        out_lo,
        out_hi,
    )
    return out_lo, out_hi


def build_instances(meshes: list, accelerate: bool = True) -> InstanceArrays:
    """The two-level structure of objects.py's instanced meshes (_InstancedMesh)."""
    if not meshes:
        return empty_instances()
    prims, tris, normals, smooth, uvs = [], [], [], [], []
    blas_records = []
    box_lo, box_hi, roots, ids, inverses, firsts = [], [], [], [], [], []
    prim_base = 0
    node_base = 0  # nodes of the BLASes before this one (the TLAS's are added below)
    blas_depth = 1
    drawn = 0
    any_smooth = any(m.normals is not None for m in meshes)
    any_uvs = any(m.uvs is not None for m in meshes)
    for mesh in meshes:
        corners = mesh.triangles.reshape(-1, 3, 3)
        lo = corners.min(axis=1).astype(np.float64)
        hi = corners.max(axis=1).astype(np.float64)
        del corners
        blas = _wide(lo, hi, accelerate, SMALL_BLAS, BLAS_MAX_LEAF, BLAS_TRAVERSAL_COST, BLAS_LEAF_BLOCK)
        order = blas.prim_order.astype(np.int64)
        n = len(order)
        mark_triangle_leaves(blas, np.ones(n, bool))
        blas_depth = max(blas_depth, wide_depth(blas) if accelerate else 1)
        rows = np.zeros((n, PRIM_WIDTH), np.int32)
        rows[:, PRIM_KIND] = Shape.TRIANGLE
        rows[:, PRIM_ROW] = prim_base + np.arange(n, dtype=np.int32)
        rows[:, PRIM_MATERIAL] = mesh.material
        rows[:, PRIM_OBJECT] = mesh.obj
        rows[:, PRIM_FACE] = mesh.first_face + order
        rows[:, PRIM_LIGHT] = -1
        prims.append(rows)
        tris.append(mesh.triangles[order])
        normals.append(mesh.normals[order] if mesh.normals is not None else None)
        smooth.append(np.full(n, mesh.normals is not None))
        uvs.append(mesh.uvs[order] if mesh.uvs is not None else None)
        records = blas.node_bounds.copy()
        index = records.view(np.int32)
        # leaves' first primitives moved by prim_base, inner children by node_base (layout.py)
        refs = index[:, NODE_REF, :]
        refs += np.where(refs < 0, -(prim_base << LEAF_SHIFT), node_base).astype(np.int32)
        blas_records.append(records)
        # the instances of this mesh: world boxes of the mesh's box
        if BOX_LEVELS and accelerate and len(lo) > SMALL_BLAS:
            wlo, whi = world_boxes(*blas_boxes(blas, BOX_LEVELS), mesh.matrices)
        else:
            wlo, whi = world_boxes(lo.min(axis=0, keepdims=True), hi.max(axis=0, keepdims=True), mesh.matrices)
        box_lo.append(wlo)
        box_hi.append(whi)
        roots.append(np.full(len(mesh.matrices), node_base, np.int64))
        firsts.append((prim_base, n))
        ids.append(mesh.ids)
        inverses.append(inverse_rows(mesh.matrices))
        drawn += n * len(mesh.matrices)
        prim_base += n
        node_base += len(index)

    lo, hi = np.concatenate(box_lo), np.concatenate(box_hi)
    tlas = build_tlas(lo, hi, accelerate)
    tlas_depth = wide_depth(tlas) if accelerate else 1
    order = tlas.prim_order.astype(np.int64)
    n_tlas = len(tlas.node_index)
    records = [tlas.node_bounds, *blas_records]
    node_bounds = line_aligned((sum(len(r) for r in records), *tlas.node_bounds.shape[1:]), np.float32)
    np.concatenate(records, out=node_bounds)
    node_index = node_bounds.view(np.int32)
    blas_leaf = node_index[:, NODE_REF, :] < 0
    blas_leaf[:n_tlas] = False
    node_index[n_tlas:, NODE_REF, :] += np.where(blas_leaf[n_tlas:], 0, n_tlas).astype(np.int32)
    index = np.empty((len(order), 2), np.int32)
    index[:, 0] = (np.concatenate(roots) + n_tlas)[order]
    index[:, 1] = np.concatenate(ids)[order]
    inverse = np.ascontiguousarray(np.concatenate(inverses)[order])
    n_inst = len(order)
    all_prims = np.concatenate(prims)
    node_bytes = int(node_bounds.nbytes + 8 * len(all_prims))
    record = int(inverse.nbytes + index.nbytes)
    tlas_bytes = wide_nbytes(tlas)
    return InstanceArrays(
        prims=all_prims,
        triangles=np.concatenate(tris),
        normals=np.concatenate(
            [nm if nm is not None else np.zeros((len(t), 9), np.float32) for nm, t in zip(normals, tris)]
        )
        if any_smooth
        else None,
        smooth=np.concatenate(smooth),
        uvs=np.concatenate([u if u is not None else np.zeros((len(t), 6), np.float32) for u, t in zip(uvs, tris)])
        if any_uvs
        else None,
        node_bounds=node_bounds,
        node_index=node_index,
        blas_leaf=blas_leaf,
        inverse=inverse,
        index=index,
        meshes=np.array([(f, n, r[0] + n_tlas) for (f, n), r in zip(firsts, roots)], np.int64).reshape(-1, 3),
        extent=float(max(np.abs(lo).max(), np.abs(hi).max())),
        box=np.array([lo.min(axis=0), hi.max(axis=0)], dtype=np.float64),
        stack=stack_needed(tlas_depth) + stack_needed(blas_depth),
        node_bytes=node_bytes,
        stats={
            "instances": n_inst,
            "instanced_meshes": len(meshes),
            "instanced_triangles": int(drawn),  # triangles the instances draw (each mesh stored once)
            "stored_instanced_triangles": int(prim_base),
            # per instance: inverse matrix, indices and the top-level BVH's nodes
            "instance_bytes": record + tlas_bytes,
            "bytes_per_instance": (record + tlas_bytes) / n_inst,
            "tlas_nodes": int(n_tlas),
            "tlas_depth": int(tlas_depth),
        },
    )


def place_instanced(inst: InstanceArrays, n_world: int, n_world_tris: int) -> None:
    """Point the instanced rows at their final places, in place: BLAS leaves at primitive rows
    after the world's n_world, PRIM_ROW at triangle rows after the world's n_world_tris (and
    `meshes`' first rows at the primitive table's)."""
    inst.node_index[:, NODE_REF, :][inst.blas_leaf] -= np.int32(n_world << LEAF_SHIFT)
    inst.prims[:, PRIM_ROW] += np.int32(n_world_tris)
    inst.meshes[:, 0] += n_world


def join_triangles(world: tuple, inst: tuple) -> tuple:
    """(triangles, normals, smooth, uvs) of the world's triangles followed by the instanced
    meshes'. Normals and UVs are (1, k) placeholders when no triangle has them."""
    tri, tri_n, tri_smooth, tri_uv = world
    i_tri, i_n, i_smooth, i_uv = inst
    n = len(tri)
    out_tri = np.concatenate([tri, i_tri])
    full_n = len(tri_n) == n and n > 0
    if full_n or i_n is not None:
        out_n = np.concatenate(
            [tri_n if full_n else np.zeros((n, 9), np.float32), i_n if i_n is not None else np.zeros_like(i_tri)]
        )
    else:
        out_n = tri_n
    full_uv = len(tri_uv) == n and n > 0
    if full_uv or i_uv is not None:
        out_uv = np.concatenate(
            [
                tri_uv if full_uv else np.zeros((n, 6), np.float32),
                i_uv if i_uv is not None else np.zeros((len(i_tri), 6), np.float32),
            ]
        )
    else:
        out_uv = tri_uv
    return out_tri, out_n, np.concatenate([tri_smooth, i_smooth]), out_uv
