"""The top-level BVH over instances (compile/instances.py): binned SAH over the instances' world
boxes with leaves of up to TLAS_MAX_LEAF, collapsed into BVH_WIDTH-wide nodes whose leaves are
opened into one lane per instance where the node has room (beside the world BVH's collapse,
wide.py)."""

from __future__ import annotations

import numba as nb
import numpy as np

from ..kernels.geometry.layout import NODE_REF
from ..kernels.geometry.wide_nodes import BVH_WIDTH
from .bvh import build_bvh
from .wide import WideBVH, check_leaves, compiled_leaf_ref, node_records, outward_f32, single_leaf

TLAS_MAX_LEAF = 8
TLAS_TRAVERSAL_COST = 4.0
TLAS_SPLIT_MIN = 4


@nb.njit(cache=True)
def _area(b, c):
    ex = max(np.float64(b[c, 3]) - np.float64(b[c, 0]), 0.0)
    ey = max(np.float64(b[c, 4]) - np.float64(b[c, 1]), 0.0)
    ez = max(np.float64(b[c, 5]) - np.float64(b[c, 2]), 0.0)
    return ex * ey + ey * ez + ez * ex


@nb.njit(cache=True)
def _collapse_tlas(nbounds, nindex, naxis, box, width, split_min, wb, wi):
    """The binary TLAS as wide nodes whose leaf lanes hold one instance each where there is
    room: a wide node opens its largest child, inner node (one more lane) or leaf of k
    instances (k - 1 more lanes, when they fit), until it is full. Leaves that do not fit stay
    ranges of instances, or, with split_min instances or more, nodes of their own with one lane
    each. `box`: float32 (N, 6) instance boxes (rounded outward), in leaf order. Into the node
    records (wb, wi) = wide.node_records(binary nodes, width); returns how many it made."""
    cap = naxis.shape[0]
    for m in range(cap):
        for lane in range(width):
            for d in range(3):
                wb[m, d, lane] = np.inf
                wb[m, 3 + d, lane] = -np.inf
            wi[m, NODE_REF, lane] = 0
    work_b = np.empty(cap, np.int64)
    work_w = np.empty(cap, np.int64)
    kids = np.empty(width, np.int64)  # binary node c >= 0, or -1 - i for instance i alone
    work_b[0] = 0
    work_w[0] = 0
    sp = 1
    n_wide = 1
    while sp > 0:
        sp -= 1
        b = work_b[sp]
        w = work_w[sp]
        if naxis[b] < 0:  # a root that is a leaf
            kids[0] = b
            nk = 1
        else:
            kids[0] = b + 1
            kids[1] = nindex[b, 0]
            nk = 2
        while nk < width:
            best = -1
            best_area = -1.0
            for i in range(nk):
                c = kids[i]
                if c < 0:
                    continue
                if naxis[c] >= 0 or (nindex[c, 1] > 1 and nk + nindex[c, 1] - 1 <= width):
                    a = _area(nbounds, c)
                    if a > best_area:
                        best_area = a
                        best = i
            if best < 0:
                break
            c = kids[best]
            if naxis[c] >= 0:
                kids[best] = c + 1
                kids[nk] = nindex[c, 0]
                nk += 1
            else:
                first = nindex[c, 0]
                kids[best] = -1 - first
                for j in range(1, nindex[c, 1]):
                    kids[nk] = -1 - (first + j)
                    nk += 1
        for i in range(nk):
            c = kids[i]
            if c < 0:
                for d in range(6):
                    wb[w, d, i] = box[-1 - c, d]
                wi[w, NODE_REF, i] = compiled_leaf_ref(-1 - c, 1)
                continue
            for d in range(6):
                wb[w, d, i] = nbounds[c, d]
            if naxis[c] < 0 and nindex[c, 1] >= split_min:
                # a leaf of several instances: a node of its own, one lane each
                wi[w, NODE_REF, i] = n_wide
                first = nindex[c, 0]
                for j in range(nindex[c, 1]):
                    for d in range(6):
                        wb[n_wide, d, j] = box[first + j, d]
                    wi[n_wide, NODE_REF, j] = compiled_leaf_ref(first + j, 1)
                n_wide += 1
            elif naxis[c] < 0:
                wi[w, NODE_REF, i] = compiled_leaf_ref(nindex[c, 0], nindex[c, 1])
            else:
                wi[w, NODE_REF, i] = n_wide
                n_wide += 1
        for i in range(nk - 1, -1, -1):
            c = kids[i]
            if c >= 0 and naxis[c] >= 0:
                work_b[sp] = c
                work_w[sp] = wi[w, NODE_REF, i]
                sp += 1
    return n_wide


def build_tlas(lo: np.ndarray, hi: np.ndarray, accelerate: bool = True) -> WideBVH:
    """The TLAS over instance world boxes (N, 3): binned SAH with leaves of up to TLAS_MAX_LEAF,
    collapsed into BVH_WIDTH-wide nodes whose leaves are opened into one lane per instance where
    the node has room (_collapse_tlas)."""
    if not accelerate or len(lo) <= 1:
        return single_leaf(lo, hi, BVH_WIDTH)
    bvh = build_bvh(lo, hi, max_leaf_size=TLAS_MAX_LEAF, c_trav=TLAS_TRAVERSAL_COST)
    check_leaves(len(lo), bvh.node_index[bvh.node_axis < 0, 1])
    order = bvh.prim_order.astype(np.int64)
    box = outward_f32(np.asarray(lo, np.float64)[order], np.asarray(hi, np.float64)[order])
    wb, wi = node_records(len(bvh.node_axis), BVH_WIDTH)
    n = _collapse_tlas(bvh.node_bounds, bvh.node_index, bvh.node_axis, box, BVH_WIDTH, TLAS_SPLIT_MIN, wb, wi)
    records = wb[:n].copy()  # the rows written (the binary node count bounds them)
    return WideBVH(records, records.view(np.int32), bvh.prim_order)
