"""Wide BVH: the binned-SAH binary tree (bvh.py) collapsed into nodes of up to W children.

Each wide node stores its children's boxes structure-of-arrays, one float32 lane per child, so
that traversal tests all of them with one vector instruction per plane (kernels/traverse.py):

* ``node_bounds[m]``  float32 ``(6, W)``: rows lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, one column
                      per child. Unused lanes hold the empty box (lo = +inf, hi = -inf), which
                      no ray can enter (its entry distance is +inf or NaN on every axis).
* ``node_index[m]``   int32 ``(2, W)``: row 0 the child's wide node (inner child) or its first
                      primitive (leaf child); row 1 the leaf's primitive count, 0 for an inner
                      child (and for unused lanes), negated for a leaf of 2 to 4 triangles that
                      traversal tests together (mark_triangle_leaves).

Children come after their parent (node 0 is the root), and siblings' nodes are consecutive.
Leaves are the binary tree's leaves, unchanged: ranges of the primitive table. A root that is
a leaf (small scenes) becomes a root node with one leaf lane.

The collapse is the classic greedy one (Wald et al. 2008, "Getting rid of packets"; Embree's
BVH8 builder): a wide node starts from a binary node's two children and repeatedly opens the
inner child of largest surface area into its two children until it has W children or only
leaves.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba as nb
import numpy as np

from .bvh import BVH

__all__ = ["WideBVH", "collapse", "mark_triangle_leaves", "single_leaf", "wide_depth", "wide_nbytes"]

_F32_MAX = float(np.finfo(np.float32).max)


class WideBVH(NamedTuple):
    node_bounds: np.ndarray  # (M, 6, W) float32
    node_index: np.ndarray  # (M, 2, W) int32
    prim_order: np.ndarray  # (N,) int32, as the binary tree's


@nb.njit(cache=True, nogil=True)
def _area(b, c):
    ex = max(min(np.float64(b[c, 3]), _F32_MAX) - max(np.float64(b[c, 0]), -_F32_MAX), 0.0)
    ey = max(min(np.float64(b[c, 4]), _F32_MAX) - max(np.float64(b[c, 1]), -_F32_MAX), 0.0)
    ez = max(min(np.float64(b[c, 5]), _F32_MAX) - max(np.float64(b[c, 2]), -_F32_MAX), 0.0)
    return ex * ey + ey * ez + ez * ex


_NOGIL = {"cache": True, "nogil": True}


@nb.njit(**_NOGIL)
def _grown(a, n):
    b = np.empty(2 * a.shape[0] + n, a.dtype)
    b[: a.shape[0]] = a
    return b


@nb.njit(**_NOGIL)
def _walk(nbounds, nindex, naxis, width, b0, w0, n0, wb, wi, bsize, limit, desc):
    """Collapse the binary subtree of inner node ``b0`` into wide row ``w0``, numbering new
    wide nodes from ``n0``: depth-first, a node's inner children consecutive, the first
    child's subtree first. With ``limit`` >= 0, an inner node other than ``b0`` whose binary
    subtree has at most ``limit`` nodes is an item, collapsed apart: the walk leaves its row
    unwritten and skips ``desc[k]`` rows (the k-th item's descendants, 0 when not known yet)
    right where it would have numbered them, so that the result is the serial walk's. Returns
    (next free row, the items: binary node, root row, first descendant row)."""
    work_b = np.empty(64, np.int64)
    work_w = np.empty(64, np.int64)
    item_b = np.empty(16, np.int64)
    item_w = np.empty(16, np.int64)
    item_base = np.empty(16, np.int64)
    kids = np.empty(width, np.int64)
    work_b[0] = b0
    work_w[0] = w0
    sp = 1
    n_wide = n0
    n_items = 0
    while sp > 0:
        sp -= 1
        b = work_b[sp]
        w = work_w[sp]
        if limit >= 0 and b != b0 and bsize[b] <= limit:
            if n_items == item_b.shape[0]:
                item_b, item_w, item_base = _grown(item_b, 1), _grown(item_w, 1), _grown(item_base, 1)
            item_b[n_items] = b
            item_w[n_items] = w
            item_base[n_items] = n_wide
            n_wide += desc[n_items] if n_items < desc.shape[0] else 0
            n_items += 1
            continue
        kids[0] = b + 1
        kids[1] = nindex[b, 0]
        nk = 2
        while nk < width:
            best = -1
            best_area = -1.0
            for i in range(nk):
                c = kids[i]
                if naxis[c] >= 0:
                    a = _area(nbounds, c)
                    if a > best_area:
                        best_area = a
                        best = i
            if best < 0:
                break
            c = kids[best]
            kids[best] = c + 1
            kids[nk] = nindex[c, 0]
            nk += 1
        if sp + nk > work_b.shape[0]:
            work_b, work_w = _grown(work_b, nk), _grown(work_w, nk)
        first = n_wide
        for i in range(nk):
            c = kids[i]
            for d in range(6):
                wb[w, d, i] = nbounds[c, d]
            if naxis[c] < 0:
                wi[w, 0, i] = nindex[c, 0]
                wi[w, 1, i] = nindex[c, 1]
            else:
                wi[w, 0, i] = n_wide
                wi[w, 1, i] = 0
                n_wide += 1
        for i in range(nk, width):
            for d in range(3):
                wb[w, d, i] = np.inf
                wb[w, 3 + d, i] = -np.inf
            wi[w, 0, i] = 0
            wi[w, 1, i] = 0
        # pushed in reverse: the first child's subtree is collapsed (and numbered) first
        child = n_wide
        for i in range(nk - 1, -1, -1):
            if naxis[kids[i]] >= 0:
                child -= 1
                work_b[sp] = kids[i]
                work_w[sp] = child
                sp += 1
        n_wide = max(n_wide, first)
    return n_wide, item_b[:n_items], item_w[:n_items], item_base[:n_items]


@nb.njit(**_NOGIL)
def _subtree_sizes(nindex, naxis):
    # Children come after their parent: one backward pass.
    size = np.ones(naxis.shape[0], np.int64)
    for m in range(naxis.shape[0] - 1, -1, -1):
        if naxis[m] >= 0:
            size[m] = 1 + size[m + 1] + size[nindex[m, 0]]
    return size


@nb.njit(**_NOGIL)
def _collapse_items(nbounds, nindex, naxis, width, item_b, j0, j1, swb, swi, desc):
    """Items j0 .. j1 - 1 collapsed on their own into scratch rows from b // 2 (a subtree of s
    binary nodes has at most s // 2 inner ones, hence as many wide nodes: the items' rows never
    overlap); each one's number of descendant rows into ``desc``."""
    none = np.empty(0, np.int64)
    for j in range(j0, j1):
        r0 = item_b[j] // 2
        end, _, _, _ = _walk(nbounds, nindex, naxis, width, item_b[j], r0, r0 + 1, swb, swi, none, -1, none)
        desc[j] = end - r0 - 1


@nb.njit(**_NOGIL)
def _place_items(item_b, item_w, item_base, desc, j0, j1, swb, swi, wb, wi):
    """Items j0 .. j1 - 1 from scratch to their rows: the root to its row, its descendants from
    its first row on, their child links moved with them."""
    width = wb.shape[2]
    for j in range(j0, j1):
        r0 = item_b[j] // 2
        shift = item_base[j] - (r0 + 1)
        for r in range(desc[j] + 1):
            src = r0 + r
            dst = item_w[j] if r == 0 else item_base[j] + r - 1
            for d in range(6):
                for lane in range(width):
                    wb[dst, d, lane] = swb[src, d, lane]
            for lane in range(width):
                v = swi[src, 0, lane]
                if swi[src, 1, lane] == 0 and v != 0:  # an inner child (empty lanes hold 0, 0)
                    v += shift
                wi[dst, 0, lane] = v
                wi[dst, 1, lane] = swi[src, 1, lane]


# Binary subtrees of at most this many nodes are collapsed apart, on threads, when the tree has
# more than 4 times as many (the result is the serial collapse's, whatever the threshold).
_ITEM = 1 << 14


def _collapse(nbounds, nindex, naxis, width, threads):
    m_bin = naxis.shape[0]
    if naxis[0] < 0:  # the root is a leaf
        wb = np.empty((1, 6, width), np.float32)
        wb[0, :3], wb[0, 3:] = np.inf, -np.inf
        wb[0, :, 0] = nbounds[0]
        wi = np.zeros((1, 2, width), np.int32)
        wi[0, :, 0] = nindex[0]
        return wb, wi
    none = np.empty(0, np.int64)
    if threads <= 1 or m_bin <= 4 * _ITEM:
        cap = int(np.count_nonzero(naxis >= 0))  # each wide node consumes a binary inner node
        wb = np.empty((cap, 6, width), np.float32)
        wi = np.empty((cap, 2, width), np.int32)
        m, _, _, _ = _walk(nbounds, nindex, naxis, width, 0, 0, 1, wb, wi, none, -1, none)
        return wb[:m].copy(), wi[:m].copy()
    bsize = _subtree_sizes(nindex, naxis)
    # The top of the wide tree walked first without the items' descendants (rows written to
    # scratch, only to find the items), the items collapsed apart on threads (largest first),
    # then the top walked again with their sizes known, into the final rows, and the items
    # moved under it.
    swb = np.empty((m_bin // 2 + 1, 6, width), np.float32)
    swi = np.empty((m_bin // 2 + 1, 2, width), np.int32)
    n1, item_b, _, _ = _walk(nbounds, nindex, naxis, width, 0, 0, 1, swb, swi, bsize, _ITEM, none)
    desc = np.empty(len(item_b), np.int64)
    jobs = np.argsort(-bsize[item_b], kind="stable").tolist()
    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(lambda j: _collapse_items(nbounds, nindex, naxis, width, item_b, j, j + 1, swb, swi, desc), jobs))
        m = int(n1 + desc.sum())
        wb = np.empty((m, 6, width), np.float32)
        wi = np.empty((m, 2, width), np.int32)
        end, _, item_w, item_base = _walk(nbounds, nindex, naxis, width, 0, 0, 1, wb, wi, bsize, _ITEM, desc)
        assert end == m
        list(pool.map(lambda j: _place_items(item_b, item_w, item_base, desc, j, j + 1, swb, swi, wb, wi), jobs))
    return wb, wi


def collapse(bvh: BVH, width: int = 8) -> WideBVH:
    """The binary BVH as a BVH of ``width``-wide nodes (same leaves, same primitive order).
    Large trees are collapsed on ``numba.get_num_threads()`` threads; the result does not depend
    on the thread count."""
    if not 2 <= width <= 32:
        raise ValueError("width must be in 2..32")
    wb, wi = _collapse(bvh.node_bounds, bvh.node_index, bvh.node_axis, int(width), nb.get_num_threads())
    return WideBVH(wb, wi, bvh.prim_order)


@nb.njit(cache=True)
def _wide_depths(node_index):
    depth = np.ones(node_index.shape[0], np.int64)
    for m in range(node_index.shape[0]):
        for lane in range(node_index.shape[2]):
            if node_index[m, 1, lane] == 0:
                c = node_index[m, 0, lane]
                if c > m:  # inner child (unused lanes point at node 0)
                    depth[c] = depth[m] + 1
    return depth


def wide_depth(wide: WideBVH) -> int:
    """Levels of wide nodes (a root with only leaves has depth 1)."""
    return int(_wide_depths(wide.node_index).max())


def wide_nbytes(wide: WideBVH) -> int:
    """Bytes of the node arrays (what traversal reads beside the primitive table)."""
    return int(wide.node_bounds.nbytes + wide.node_index.nbytes)


def single_leaf(lo: np.ndarray, hi: np.ndarray, width: int = 8) -> WideBVH:
    """A root node with one leaf lane holding every primitive (small scenes, and modes that
    never trace rays); its box is rounded outward to float32. Pure numpy: small scenes need no
    BVH code compiled."""
    n = len(lo)
    bounds = np.empty((1, 6, width), np.float32)
    bounds[:, :3] = np.inf
    bounds[:, 3:] = -np.inf
    if n:
        lo64, hi64 = np.asarray(lo, np.float64).min(axis=0), np.asarray(hi, np.float64).max(axis=0)
        lo32, hi32 = lo64.astype(np.float32), hi64.astype(np.float32)
        lo32 = np.where(lo32 > lo64, np.nextafter(lo32, np.float32(-np.inf)), lo32)
        hi32 = np.where(hi32 < hi64, np.nextafter(hi32, np.float32(np.inf)), hi32)
        bounds[0, :3, 0] = lo32
        bounds[0, 3:, 0] = hi32
    index = np.zeros((1, 2, width), np.int32)
    index[0, 1, 0] = n
    return WideBVH(bounds, index, np.arange(n, dtype=np.int32))


# A leaf's count field tells how traversal tests it: count > 0, primitives first .. first +
# count - 1 one by one; -4 .. -2, that many triangles at once (mark_triangle_leaves); below
# -SPHERE_BLOCK, -count - SPHERE_BLOCK spheres at once (mark_sphere_leaves).
SPHERE_BLOCK = 8


def _leaves_of_one_kind(wide: WideBVH, of_kind: np.ndarray, most: int) -> np.ndarray:
    """bool (N, W): the lanes whose leaf holds 2 .. `most` primitives, all of the kind
    (`of_kind`: bool per primitive-table row, in leaf order)."""
    count = wide.node_index[:, 1, :]
    first = wide.node_index[:, 0, :]
    prefix = np.concatenate([[0], np.cumsum(of_kind, dtype=np.int64)])
    leaf = (count >= 2) & (count <= most)
    end = np.where(leaf, first.astype(np.int64) + count, 0)
    start = np.where(leaf, first, 0)
    return leaf & (prefix[end] - prefix[start] == count)


def mark_triangle_leaves(wide: WideBVH, is_triangle: np.ndarray, most: int = 4) -> None:
    """Leaves of 2 .. `most` primitives that are all triangles get their count negated in place:
    traversal tests them together (shape_triangle.intersect_triangles), reading consecutive
    rows of the triangle table. `is_triangle`: bool per primitive-table row, in leaf order."""
    count = wide.node_index[:, 1, :]
    block = _leaves_of_one_kind(wide, is_triangle, most)
    count[block] = -count[block]


def mark_sphere_leaves(wide: WideBVH, is_sphere: np.ndarray, most: int = 4) -> None:
    """Leaves of 2 .. `most` primitives that are all spheres get the count -(SPHERE_BLOCK +
    count) in place: traversal tests them together (shape_sphere.intersect_spheres). The seed
    scene's four spheres are one such leaf. `is_sphere`: bool per primitive-table row, in leaf
    order."""
    count = wide.node_index[:, 1, :]
    block = _leaves_of_one_kind(wide, is_sphere, most)
    count[block] = -(SPHERE_BLOCK + count[block])
