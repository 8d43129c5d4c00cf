"""Wide BVH: the binned-SAH binary tree (bvh.py) collapsed into nodes of up to W children.

Each wide node is one record of NODE_ROWS rows of W 32-bit lanes, one lane per child (224
bytes for W = 8; Embree's BVH8 node is 256), its children's boxes structure-of-arrays so that
traversal tests all of them with one vector instruction per plane (kernels/geometry/traverse.py):

* rows 0-5, float32: lo_x, lo_y, lo_z, hi_x, hi_y, hi_z. Unused lanes hold the empty box
  (lo = +inf, hi = -inf), which no ray can enter (its entry distance is +inf or NaN on every
  axis).
* row NODE_REF, int32: the child's reference (kernels/geometry/layout.py): its wide node (an
  inner child, >= 0; 0 in unused lanes), or a leaf's first primitive and count field in one
  negative number (leaf_ref), the count negated for a leaf of 2 to 4 triangles that traversal
  tests together (mark_triangle_leaves). Leaves hold at most 15 primitives, and a BVH at most
  LEAF_FIRST_LIMIT (2**26).

``node_bounds`` (float32) and ``node_index`` (int32) are two views of the same records: a node's
child indices lie in the cache line after its boxes, not in a second array (docs/architecture.md:
bumpy 4M frames on a Zen 3 3-11% faster in each of 4 alternating runs).

Children come after their parent (node 0 is the root), and siblings' nodes are consecutive.
Leaves are the binary tree's leaves, unchanged: ranges of the primitive table. A root that is
a leaf (small scenes) becomes a root node with one leaf lane.

The collapse is the optimal one of Ylitie, Karras and Laine 2017 ("Efficient incoherent ray
traversal on GPUs through compressed wide BVHs", section 3.1): of all the ways to keep some of
the binary nodes as wide nodes (each with at most W lanes), the one of least summed surface
area, the SAH cost of its node visits (plus a small cost per node, NODE_COST, for memory),
found by dynamic programming over the binary tree. The
greedy collapse it replaced (Wald et al. 2008; Embree's BVH8 builder: open the inner child of
largest area until W children or only leaves) left the nodes 4.0 of 8 lanes full on average
(bumpy 4M: 357,885 nodes) against 6.1 (209,560), and a hit ray visited 8.9 nodes against 8.4.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from ..kernels.geometry.layout import (
    LEAF_COUNTS,
    LEAF_FIRST_LIMIT,
    NODE_REF,
    NODE_ROWS,
    SPHERE_BLOCK,
    leaf_count,
    leaf_first,
    leaf_ref,
    line_aligned,
)
from ..kernels.vec import kernel_function
from .bvh import BVH

__all__ = [
    "NODE_REF",
    "NODE_ROWS",
    "WideBVH",
    "collapse",
    "leaf_count",
    "leaf_first",
    "leaf_ref",
    "mark_triangle_leaves",
    "node_records",
    "outward_f32",
    "single_leaf",
    "wide_depth",
    "wide_nbytes",
]

_F32_MAX = float(np.finfo(np.float32).max)
# What a wide node costs the optimal collapse beside its area: NODE_COST / leaves of the root's
# area, so that a node is kept only where it saves the visits of that many leaves' share of the
# tree. The nodes, and their memory, shrink with it (bumpy 40k 2176 -> 2038, 1M 52,164 ->
# 49,852, 4M 209,565 -> 199,070) while the summed area, the SAH's visits, grows 0.1%; bumpy hit
# rays the same (1M packets 42.7 / 42.5 -> 42.1 / 44.7 ms, single rays 53.9 / 55.5 -> 52.9 /
# 52.3, 40k 23.3 / 23.6 -> 23.6 / 23.2, alternating). 8 or 16 save 1-2% more nodes for 0.2-0.4%.
NODE_COST = 4.0
compiled_leaf_ref = nb.njit(leaf_ref)  # for the compiled collapses (here and tlas.py)


class WideBVH(NamedTuple):
    node_bounds: np.ndarray  # (M, NODE_ROWS, W) float32: the node records
    node_index: np.ndarray  # (M, NODE_ROWS, W) int32: the same records (node_records)
    prim_order: np.ndarray  # (N,) int32, as the binary tree's


def node_records(m: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Uninitialised records of m wide nodes, as (node_bounds, node_index): float32 and int32
    views of one array."""
    bounds = line_aligned((m, NODE_ROWS, width), np.float32)
    return bounds, bounds.view(np.int32)


@kernel_function()  # linked into _lane_table, its one caller (kernels/vec.py)
def _area(b, c):
    ex = max(min(np.float64(b[c, 3]), _F32_MAX) - max(np.float64(b[c, 0]), -_F32_MAX), 0.0)
    ey = max(min(np.float64(b[c, 4]), _F32_MAX) - max(np.float64(b[c, 1]), -_F32_MAX), 0.0)
    ez = max(min(np.float64(b[c, 5]), _F32_MAX) - max(np.float64(b[c, 2]), -_F32_MAX), 0.0)
    return ex * ey + ey * ez + ez * ex


@nb.njit(cache=True, nogil=True, _nrt=False)
def _lane_table(nbounds, nindex, naxis, width, split, stack, pair, pair_k, node_share):
    """The optimal collapse's choices, bottom up over the binary nodes, into `split` (int8
    (nodes, width)). The cost of a binary node's subtree given at most i lanes of its wide
    parent is the least summed surface area of the wide nodes below it (leaves are the same in
    every collapse, so their cost is left out), each wide node counted as `node_share` of the
    root's area more (NODE_COST); split[n, i - 1] says how it is reached: 0, node n takes one
    lane (a leaf, or a wide node of its own: its area and cost plus its two subtrees' cost in
    `width` lanes); k > 0, n's left subtree takes at most k lanes and its right i - k.

    Nodes come parent first, left subtree, right subtree, so in reverse order each node comes
    right after its left subtree, which came right after its right subtree: the costs wait on
    `stack` (float64 (K, width), K above the tree's depth), the node's two children's rows on
    top. `pair`, `pair_k`: (width + 1,) scratch. It allocates nothing: without reference
    counting, less to compile in a cold build."""
    node_cost = node_share * _area(nbounds, 0)
    sp = 0
    for n in range(naxis.shape[0] - 1, -1, -1):
        if naxis[n] < 0:
            for i in range(width):
                split[n, i] = 0
                stack[sp, i] = 0.0
            sp += 1
            continue
        left, right = sp - 1, sp - 2  # rows of n + 1's and nindex[n, 0]'s costs
        for i in range(2, width + 1):  # the two subtrees side by side in at most i lanes
            pair[i] = np.inf
            for k in range(1, i):
                c = stack[left, k - 1] + stack[right, i - k - 1]
                if c < pair[i]:
                    pair[i] = c
                    pair_k[i] = k
        own = _area(nbounds, n) + node_cost + pair[width]
        sp -= 1  # n's row replaces its children's
        stack[sp - 1, 0] = own
        split[n, 0] = 0
        for i in range(2, width + 1):
            if pair[i] <= own:  # on a tie, lanes of the parent: fewer nodes
                stack[sp - 1, i - 1] = pair[i]
                split[n, i - 1] = pair_k[i]
            else:
                stack[sp - 1, i - 1] = own
                split[n, i - 1] = 0


@nb.njit(cache=True, nogil=True, _nrt=False)
def _walk(nbounds, nindex, naxis, width, split, wb, wi, stack, kids, parts):
    """The collapse from the root into the records ``wb``, ``wi`` (node_records), numbering wide
    nodes depth-first, a node's inner children consecutive, the first child's subtree first.
    The wide node made from binary node b holds the lanes that split (_lane_table) gives b's
    two subtrees in `width` lanes, in tree order. ``stack`` (K, 2): work rows, K above the
    number of inner nodes (each is pushed once); ``kids`` (width,) and ``parts`` (width + 1, 2)
    int64 scratch: a node's children, and the (binary node, lanes it may take) still to place.
    Returns the number of rows written."""
    stack[0, 0] = 0
    stack[0, 1] = 0
    sp = 1
    n_wide = 1
    while sp > 0:
        sp -= 1
        b = stack[sp, 0]
        w = stack[sp, 1]
        # b in `width` lanes: an inner node there always splits (its own lane would cost its
        # area on top), so the loop starts with its two subtrees
        parts[0, 0] = b
        parts[0, 1] = width
        n_parts = 1
        nk = 0
        while n_parts > 0:
            n_parts -= 1
            c = parts[n_parts, 0]
            i = parts[n_parts, 1]
            j = split[c, i - 1]
            if j == 0:
                kids[nk] = c
                nk += 1
            else:  # the right part below the left: the leftmost is placed first
                parts[n_parts, 0] = nindex[c, 0]
                parts[n_parts, 1] = i - j
                parts[n_parts + 1, 0] = c + 1
                parts[n_parts + 1, 1] = j
                n_parts += 2
        for i in range(nk):
            c = kids[i]
            for d in range(6):
                wb[w, d, i] = nbounds[c, d]
            if naxis[c] < 0:
                wi[w, NODE_REF, i] = compiled_leaf_ref(nindex[c, 0], nindex[c, 1])
            else:
                wi[w, NODE_REF, i] = n_wide
                n_wide += 1
        # Rows are filled when made (lanes past the children: the empty box), so rows never
        # made are never touched.
        for i in range(nk, width):
            for d in range(3):
                wb[w, d, i] = np.inf
                wb[w, 3 + d, i] = -np.inf
            wi[w, NODE_REF, i] = 0
        # pushed in reverse: the first child's subtree is collapsed (and numbered) first
        child = n_wide
        for i in range(nk - 1, -1, -1):
            if naxis[kids[i]] >= 0:
                child -= 1
                stack[sp, 0] = kids[i]
                stack[sp, 1] = child
                sp += 1
    return n_wide


def collapse(bvh: BVH, width: int = 8) -> WideBVH:
    """The binary BVH as a BVH of ``width``-wide nodes (same leaves, same primitive order)."""
    if not 2 <= width <= 32:
        raise ValueError("width must be in 2..32")
    nbounds, nindex, naxis = bvh.node_bounds, bvh.node_index, bvh.node_axis
    check_leaves(len(bvh.prim_order), nindex[naxis < 0, 1])
    if naxis[0] < 0:  # the root is a leaf
        wb, wi = node_records(1, width)
        wb[0, :3], wb[0, 3:6] = np.inf, -np.inf
        wb[0, :6, 0] = nbounds[0]
        wi[0, NODE_REF] = 0
        wi[0, NODE_REF, 0] = leaf_ref(nindex[0, 0], nindex[0, 1])
        return WideBVH(wb, wi, bvh.prim_order)
    # Bounds, not counts: the wide nodes, the inner nodes (each consumes one) and the stacks
    # are at most half the binary nodes; np.empty's untouched rows cost no memory. (Before,
    # a row per binary inner node was initialised, then the result trimmed: 2x slower.)
    cap = naxis.shape[0] // 2 + 2
    split = np.empty((naxis.shape[0], width), np.int8)
    pair, pair_k = np.empty(width + 1), np.empty(width + 1, np.int64)
    node_share = NODE_COST / max(1, int(np.count_nonzero(naxis < 0)))
    _lane_table(nbounds, nindex, naxis, int(width), split, np.empty((cap, width)), pair, pair_k, node_share)
    wb, wi = node_records(cap, width)
    kids, parts = np.empty(width, np.int64), np.empty((width + 1, 2), np.int64)
    m = _walk(nbounds, nindex, naxis, int(width), split, wb, wi, np.empty((cap, 2), np.int64), kids, parts)
    # The rows written, as views: no copy (it cost a fifth of the collapse at bumpy 4M, and
    # its memory), and the rows past m were never touched, so they take none.
    return WideBVH(wb[:m], wi[:m], bvh.prim_order)


def check_leaves(n: int, counts: np.ndarray | None = None) -> None:
    """A leaf's reference holds its first primitive below LEAF_FIRST_LIMIT (n primitives) and its
    count in LEAF_COUNTS (`counts`, the leaves' sizes; None: not checked) (kernels/geometry/layout.py)."""
    if n > LEAF_FIRST_LIMIT:
        raise ValueError(f"{n} primitives in one BVH: at most {LEAF_FIRST_LIMIT} (use instances)")
    if counts is not None and len(counts) and counts.max() > LEAF_COUNTS[-1]:
        raise ValueError(f"a leaf of {int(counts.max())} primitives: wide BVHs hold at most {LEAF_COUNTS[-1]}")


def wide_depth(wide: WideBVH) -> int:
    """Levels of wide nodes (a root with only leaves has depth 1). Level by level in numpy
    (a few array operations a level): a compiled loop cost a cold build ~0.25 s of JIT."""
    refs = wide.node_index[:, NODE_REF, :]
    level = np.zeros(1, np.int64)  # the root
    depth = 0
    while level.size:
        depth += 1
        children = refs[level]
        level = children[children > 0]  # leaves are < 0; node 0 is the root, no one's child (unused lanes)
    return depth


def wide_nbytes(wide: WideBVH) -> int:
    """Bytes of the node records (what traversal reads beside the primitive table)."""
    return int(wide.node_bounds.nbytes)


def single_leaf(lo: np.ndarray, hi: np.ndarray, width: int = 8) -> WideBVH:
    """A root node with one leaf lane holding every primitive (small scenes, and modes that
    never trace rays); its box is rounded outward to float32. More primitives than a leaf holds
    (LEAF_COUNTS: modes that never trace rays) become leaves of consecutive primitives under
    nodes in the same order (flat_tree). Pure numpy: small scenes need no BVH code compiled."""
    n = len(lo)
    if n > LEAF_COUNTS[-1]:
        return flat_tree(lo, hi, width)
    bounds, index = node_records(1, width)
    bounds[:, :3] = np.inf
    bounds[:, 3:6] = -np.inf
    if n:
        bounds[0, :6, 0] = outward_f32(np.asarray(lo, np.float64).min(axis=0), np.asarray(hi, np.float64).max(axis=0))
    index[:, NODE_REF] = 0
    index[0, NODE_REF, 0] = leaf_ref(0, n)
    return WideBVH(bounds, index, np.arange(n, dtype=np.int32))


def outward_f32(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """float32 (..., 6) boxes holding the float64 boxes (lo, hi) (..., 3)."""
    lo32, hi32 = lo.astype(np.float32), hi.astype(np.float32)
    lo32 = np.where(lo32 > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32 < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return np.ascontiguousarray(np.concatenate([lo32, hi32], axis=-1))


def flat_tree(lo: np.ndarray, hi: np.ndarray, width: int = 8) -> WideBVH:
    """A wide BVH of the primitives in their order, without sorting them: leaves of
    LEAF_COUNTS' most consecutive primitives, `width` consecutive leaves or nodes a node, level
    by level up to the root. As slow to trace as no BVH, but a valid one, made in a few numpy
    operations, for modes that never trace rays (single_leaf)."""
    n = len(lo)
    check_leaves(n)
    per = LEAF_COUNTS[-1]
    starts = np.arange(0, n, per)
    lo64, hi64 = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    boxes = outward_f32(np.minimum.reduceat(lo64, starts), np.maximum.reduceat(hi64, starts))
    levels = [boxes]  # the boxes of each level's children, the leaves first
    while len(levels[-1]) > width:
        b = levels[-1]
        groups = np.arange(0, len(b), width)
        levels.append(np.concatenate([np.minimum.reduceat(b[:, :3], groups), np.maximum.reduceat(b[:, 3:], groups)], 1))
    levels.reverse()  # the root's children first
    sizes = [-(-len(b) // width) for b in levels]  # nodes of each level
    bounds, index = node_records(sum(sizes), width)
    bounds[:, :3] = np.inf
    bounds[:, 3:6] = -np.inf
    index[:, NODE_REF] = 0
    base = 0
    for depth, b in enumerate(levels):
        k = np.arange(len(b))
        node, lane = base + k // width, k % width
        bounds[node, :6, lane] = b
        if depth + 1 < len(levels):  # children: the next level's nodes, in order
            index[node, NODE_REF, lane] = base + sizes[depth] + k
        else:
            index[node, NODE_REF, lane] = leaf_ref(starts, np.minimum(per, n - starts))
        base += sizes[depth]
    return WideBVH(bounds, index, np.arange(n, dtype=np.int32))


def _leaves_of_one_kind(wide: WideBVH, of_kind: np.ndarray, most: int) -> np.ndarray:
    """bool (N, W): the lanes whose leaf holds 2 .. `most` primitives (count field), all of the
    kind (`of_kind`: bool per primitive-table row, in leaf order)."""
    ref = wide.node_index[:, NODE_REF, :]
    if not of_kind.any():  # (a mesh's scene has no spheres: 0.1 s at 4M triangles)
        return np.zeros(ref.shape, dtype=bool)
    count = np.where(ref < 0, leaf_count(ref), 0)
    leaf = (count >= 2) & (count <= most)
    if of_kind.all():  # every leaf is of the kind (a scene of triangles alone)
        return leaf
    first = np.where(ref < 0, leaf_first(ref), 0)
    prefix = np.concatenate([[0], np.cumsum(of_kind, dtype=np.int64)])
    end = np.where(leaf, first.astype(np.int64) + count, 0)
    start = np.where(leaf, first, 0)
    return leaf & (prefix[end] - prefix[start] == count)


def _set_counts(wide: WideBVH, lanes: np.ndarray, count: np.ndarray) -> None:
    """The leaves in `lanes` (bool (N, W)) get the count fields `count` (one per lane), in place."""
    ref = wide.node_index[:, NODE_REF, :]
    ref[lanes] = leaf_ref(leaf_first(ref[lanes]), count)


def mark_triangle_leaves(wide: WideBVH, is_triangle: np.ndarray, most: int = 4) -> None:
    """Leaves of 2 .. `most` primitives that are all triangles get their count negated in place:
    traversal tests them together (shape_triangle.intersect_triangles), reading consecutive
    rows of the triangle table. `is_triangle`: bool per primitive-table row, in leaf order."""
    block = _leaves_of_one_kind(wide, is_triangle, most)
    _set_counts(wide, block, -leaf_count(wide.node_index[:, NODE_REF, :][block]))


def mark_sphere_leaves(wide: WideBVH, is_sphere: np.ndarray, most: int = 8) -> None:
    """Leaves of 2 .. `most` primitives that are all spheres get the count -(SPHERE_BLOCK +
    count) in place: traversal tests them four at a time (shape_sphere.intersect_spheres). The
    seed scene's four spheres are one such leaf; examples/materials.toml's six (a root leaf of
    up to 8 primitives) another: one by one, through the shape dispatch, their tests had been
    ~12% of its path-mode time. `is_sphere`: bool per primitive-table row, in leaf
    order."""
    block = _leaves_of_one_kind(wide, is_sphere, most)
    _set_counts(wide, block, -(SPHERE_BLOCK + leaf_count(wide.node_index[:, NODE_REF, :][block])))
