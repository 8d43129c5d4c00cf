"""Binned-SAH bounding volume hierarchy builder.

The builder follows Wald 2007 ("On fast construction of SAH-based bounding
volume hierarchies") as used by pbrt's ``BVHAccel`` with ``SplitMethod::SAH``:
centroids are binned along all three axes, the SAH cost of every bin boundary
is evaluated with two sweeps and the cheapest plane wins.

Layout of the result (flat arrays, depth-first, no Python objects per node):

* ``node_bounds[m]``   float32 ``[lo_x, lo_y, lo_z, hi_x, hi_y, hi_z]``
* ``node_index[m]``    inner: ``(right_child, 0)``, the left child is ``m + 1``;
                       leaf:  ``(first, count)`` into ``prim_order``
* ``node_axis[m]``     split axis of inner nodes, ``-1`` for leaves
* ``prim_order``       permutation of the primitive ids

Node boxes are conservative: every primitive box is rounded *outward* to
float32 once, up front, and node boxes are exact unions (min/max) of those
float32 boxes.  So each node box contains the float64 input box of every
primitive below it, with no extra padding beyond one float32 rounding.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ..kernels.vec import kernel_function

__all__ = ["BVH", "build_bvh", "bvh_nbytes", "bvh_depth", "sah_cost", "triangle_bounds"]

# Largest finite float32.  Primitive coordinates beyond float32 range become
# +-inf after outward rounding (still conservative); clamping to this value
# wherever we do arithmetic keeps centroids and areas finite.
_F32_MAX = float(np.finfo(np.float32).max)

# Relative padding added to every box extent when computing SAH areas.  It
# keeps the heuristic meaningful for boxes that are degenerate in two or three
# dimensions (points, axis-aligned segments), whose true area is zero and would
# make every split look free.  Relative to the node size, so negligible
# otherwise.
_AREA_EPS = 1e-6


class BVH(NamedTuple):
    node_bounds: np.ndarray  # (M, 6) float32
    node_index: np.ndarray  # (M, 2) int32
    node_axis: np.ndarray  # (M,) int8
    prim_order: np.ndarray  # (N,) int32


# ---------------------------------------------------------------------------
# Numba kernels.  fastmath stays off: the code relies on +-inf sentinels and
# on the bin index of a primitive being computed bit-identically in the
# binning pass and the partition pass.  Every kernel is nogil: the parallel
# build runs them on Python threads (a parallel=True parfor would add seconds
# of cold compile time).
# ---------------------------------------------------------------------------

_JIT = {"cache": True, "nogil": True}
# The kernels that allocate nothing run without Numba's reference counting
# (``_nrt=False``): with it, each call of a per-node helper with array
# arguments (_surely_leaf, _choose, ...) paid atomic increfs and decrefs that
# Numba's pruning pass left in (a tenth of the kernels' profile samples at
# bumpy 4M; the build's CPU time -3%).
_NO_RC = {**_JIT, "_nrt": False}
# Helpers that only the kernels call are KernelFunctions (kernels/vec.py). Their code is linked
# into the kernels that call them, with no Python wrapper or machine code of their own: a cold
# build compiled in 3.1 s instead of 4.3 s (one measurement each). Their options are the
# kernels' own (no fast-math).
_HELPER = {}
_HELPER_RC = {"_nrt": False}


@nb.njit(**_NO_RC)
def _prepare(lo, hi, box, cen, ids, cbounds, start, end):
    """Round primitive boxes [start, end) outward to float32 into ``box``
    (N, 6), their centroids into ``cen`` (N, 3), their ids into ``ids``
    (here, on the threads: np.arange was 0.03 s on the main one at 4 M), and
    return the centroid bounds in ``cbounds`` (6,).  Returns the index of the
    first invalid primitive (NaN or lo > hi), or -1."""
    neg_inf = np.float32(-np.inf)
    pos_inf = np.float32(np.inf)
    for i in range(start, end):
        for k in range(3):
            a = lo[i, k]
            b = hi[i, k]
            if not (a <= b):  # also catches NaN
                return i
            fa = np.float32(a)
            if fa > a:
                fa = np.nextafter(fa, neg_inf)
            fb = np.float32(b)
            if fb < b:
                fb = np.nextafter(fb, pos_inf)
            box[i, k] = fa
            box[i, 3 + k] = fb
            cen[i, k] = _centroid(fa, fb)
        ids[i] = i
    _cen_bounds(cen, start, end, cbounds)
    return -1


@kernel_function(**_HELPER)
def _centroid(a, b):
    # The centroid, float32 (computed once, in _prepare: binning and
    # partitioning read it).  Clamping keeps it finite for boxes that reach
    # past the float32 range.
    a = min(max(np.float64(a), -_F32_MAX), _F32_MAX)
    b = min(max(np.float64(b), -_F32_MAX), _F32_MAX)
    return np.float32(0.5 * (a + b))


@kernel_function(**_HELPER_RC)
def _scaled_area(nodebox):
    """(1 / the node's largest extent, its half area in those units): the scale its children's
    and bins' areas are measured in."""
    size = 0.0
    for d in range(3):
        e = min(nodebox[3 + d], _F32_MAX) - max(nodebox[d], -_F32_MAX)
        if e > size:
            size = e
    inv = 1.0 / size if size > 0.0 else 1.0
    return inv, _half_area(nodebox[0], nodebox[1], nodebox[2], nodebox[3], nodebox[4], nodebox[5], inv)


@kernel_function(**_HELPER)
def _half_area(lx, ly, lz, hx, hy, hz, inv):
    # Surface area / 2 of a box, extents scaled by ``inv`` (1 / node size) so
    # huge or tiny scenes neither overflow nor underflow, then padded.
    ex = (min(hx, _F32_MAX) - max(lx, -_F32_MAX)) * inv + _AREA_EPS
    ey = (min(hy, _F32_MAX) - max(ly, -_F32_MAX)) * inv + _AREA_EPS
    ez = (min(hz, _F32_MAX) - max(lz, -_F32_MAX)) * inv + _AREA_EPS
    return ex * ey + ey * ez + ez * ex


@kernel_function(**_HELPER)
def _bins_area(lx, ly, lz, nx, ny, nz, inv):
    """_half_area of a running box of bins, kept as float32 lo and -hi."""
    return _half_area(
        np.float64(lx), np.float64(ly), np.float64(lz), -np.float64(nx), -np.float64(ny), -np.float64(nz), inv
    )


@kernel_function(**_HELPER)
def _bin_of(c, cmin, scale, n_bins):
    # Must be evaluated identically in binning and partitioning.
    t = (c - cmin) * scale
    if t < n_bins:
        return int(t)
    return n_bins - 1


@kernel_function(**_HELPER_RC)
def _set_empty(b):
    for d in range(3):
        b[d] = np.inf
        b[3 + d] = -np.inf


@nb.njit(**_NO_RC)
def _cen_bounds(cen, start, end, cbnd):
    """Centroid bounds of primitives [start, end) into ``cbnd`` (6,); an
    empty range gives the empty bounds."""
    l0 = l1 = l2 = np.float32(np.inf)
    h0 = h1 = h2 = np.float32(-np.inf)
    for i in range(start, end):
        c0, c1, c2 = cen[i, 0], cen[i, 1], cen[i, 2]
        l0, l1, l2 = _min32(l0, c0), _min32(l1, c1), _min32(l2, c2)
        h0, h1, h2 = _max32(h0, c0), _max32(h1, c1), _max32(h2, c2)
    cbnd[0], cbnd[1], cbnd[2], cbnd[3], cbnd[4], cbnd[5] = l0, l1, l2, h0, h1, h2


# Bins: ``bcnt`` (3, n_bins) primitive counts and ``bbox`` (3, n_bins, 8)
# float32 box bounds per axis and bin, as (lo_x, lo_y, lo_z, +inf, -hi_x,
# -hi_y, -hi_z, +inf): one 8-lane min grows a bin by a box (_grow3).  Empty
# bins are all +inf.


@nb.njit(**_NO_RC)
def _clear_bins(bcnt, bbox, n_bins):
    for k in range(3):
        for b in range(n_bins):
            bcnt[k, b] = 0
            for d in range(8):
                bbox[k, b, d] = np.inf


@kernel_function(**_HELPER_RC)
def _union_bin(acc, bbox, k, b):
    for d in range(3):
        v = np.float64(bbox[k, b, d])
        if v < acc[d]:
            acc[d] = v
        v = -np.float64(bbox[k, b, 4 + d])
        if v > acc[3 + d]:
            acc[3 + d] = v


@intrinsic
def _grow3(typingctx, bbox, b0, b1, b2, l0, l1, l2, h0, h1, h2):
    """Grow bins (0, b0), (1, b1), (2, b2) of ``bbox`` by the box (l, h):
    one 8-lane vector min each.  Numba leaves LLVM's SLP vectoriser off, and
    the six scalar min/max per bin made binning twice as slow."""
    sig = types.void(bbox, b0, b1, b2, l0, l1, l2, h0, h1, h2)

    def codegen(context, builder, sig, args):
        f32 = ir.FloatType()
        i64 = ir.IntType(64)
        vt = ir.VectorType(f32, 8)
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        n_bins = cgutils.unpack_tuple(builder, arr.shape, 3)[1]
        vmin = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vt, [vt, vt]), "llvm.minnum.v8f32")
        v = ir.Constant(vt, [float("inf")] * 8)
        for lane, x, t in zip((0, 1, 2, 4, 5, 6), args[4:], sig.args[4:], strict=True):
            x = context.cast(builder, x, t, types.float32)
            if lane >= 4:
                x = builder.fsub(ir.Constant(f32, -0.0), x)  # exact negation
            v = builder.insert_element(v, x, ir.Constant(ir.IntType(32), lane))
        for k in range(3):
            b = context.cast(builder, args[1 + k], sig.args[1 + k], types.int64)
            row = builder.add(builder.mul(ir.Constant(i64, k), n_bins), b)
            p = builder.gep(arr.data, [builder.mul(row, ir.Constant(i64, 8))], inbounds=True)
            vp = builder.bitcast(p, vt.as_pointer())
            old = builder.load(vp, align=4)
            # minnum, not a compare and select: LLVM turned that into a masked
            # store (vmaskmovps), microcoded on AMD and slower than scalar code.
            # No NaN reaches the bins (inputs are checked), hence nnan.
            builder.store(builder.call(vmin, [v, old], fastmath=("nnan",)), vp, align=4)
        return context.get_dummy_value()

    return sig, codegen


@nb.njit(**_NO_RC)
def _bin_prims(box, cen, start, end, cb, scale, n_bins, bcnt, bbox):
    """Add primitives [start, end) to per-axis bins (count, box bounds);
    the bins are float32 like the boxes, so unions stay exact."""
    c0, c1, c2 = cb[0], cb[1], cb[2]
    s0, s1, s2 = scale[0], scale[1], scale[2]
    for i in range(start, end):
        l0, l1, l2 = box[i, 0], box[i, 1], box[i, 2]
        h0, h1, h2 = box[i, 3], box[i, 4], box[i, 5]
        b0 = _bin_of(cen[i, 0], c0, s0, n_bins)
        b1 = _bin_of(cen[i, 1], c1, s1, n_bins)
        b2 = _bin_of(cen[i, 2], c2, s2, n_bins)
        bcnt[0, b0] += 1
        bcnt[1, b1] += 1
        bcnt[2, b2] += 1
        _grow3(bbox, b0, b1, b2, l0, l1, l2, h0, h1, h2)


@kernel_function(**_HELPER_RC)
def _best_split(bcnt, bbox, n_bins, scale, inv, node_area, c_trav, c_isect, block, r_area, r_cnt):
    """SAH sweep over all bin boundaries.  Returns (cost, axis, plane); plane
    p sends bins [0, p) left.  axis is -1 when no plane has primitives on
    both sides.  Costs are not divided by the node area, so zero-area nodes
    need no special case.  The running boxes are local scalars (through an
    array, every bin's union went through memory: ~2x slower).  An empty bin
    (all +inf) changes neither the running box nor the count, so its area is
    the one before, not computed again: small nodes have many."""
    best_cost = np.inf
    best_axis = -1
    best_plane = -1
    for k in range(3):
        if scale[k] == 0.0:
            continue
        # Right-to-left: area and count of bins [b, n_bins).
        lx = ly = lz = np.float32(np.inf)
        nx = ny = nz = np.float32(np.inf)  # -hi
        cnt = 0
        area = np.inf  # read only where r_cnt > 0
        for b in range(n_bins - 1, 0, -1):
            c = bcnt[k, b]
            if c != 0:
                cnt += c
                lx, ly, lz = _min32(lx, bbox[k, b, 0]), _min32(ly, bbox[k, b, 1]), _min32(lz, bbox[k, b, 2])
                nx, ny, nz = _min32(nx, bbox[k, b, 4]), _min32(ny, bbox[k, b, 5]), _min32(nz, bbox[k, b, 6])
                area = _bins_area(lx, ly, lz, nx, ny, nz, inv)
            r_cnt[b] = cnt
            r_area[b] = area
        # Left-to-right: combine with bins [0, p).
        lx = ly = lz = np.float32(np.inf)
        nx = ny = nz = np.float32(np.inf)
        cnt = 0
        l_area = np.inf
        grown = False  # since l_area was computed
        for p in range(1, n_bins):
            c = bcnt[k, p - 1]
            if c != 0:
                cnt += c
                lx, ly, lz = _min32(lx, bbox[k, p - 1, 0]), _min32(ly, bbox[k, p - 1, 1]), _min32(lz, bbox[k, p - 1, 2])
                nx, ny, nz = _min32(nx, bbox[k, p - 1, 4]), _min32(ny, bbox[k, p - 1, 5]), _min32(nz, bbox[k, p - 1, 6])
                grown = True
            if cnt == 0 or r_cnt[p] == 0:
                continue
            if grown:
                l_area = _bins_area(lx, ly, lz, nx, ny, nz, inv)
                grown = False
            cost = c_trav * node_area + c_isect * (_blocks(cnt, block) * l_area + _blocks(r_cnt[p], block) * r_area[p])
            if cost < best_cost:
                best_cost = cost
                best_axis = k
                best_plane = p
    return best_cost, best_axis, best_plane


@kernel_function(**_HELPER)
def _min32(a, b):
    return a if a < b else b


@kernel_function(**_HELPER)
def _max32(a, b):
    return a if a > b else b


@kernel_function(**_HELPER)
def _blocks(count, block):
    """Intersection tests a leaf of ``count`` primitives costs: one per block."""
    return (count + block - 1) // block


@nb.njit(**_NO_RC)
def _set_scale(cb, count, n_bins, scale):
    # Fewer bins for smaller nodes (6 + count / 8, at most one per
    # primitive): the bins' sweep dominated the build at the bottom of the
    # tree (bumpy 1M: ~10% faster, SAH +0.05%).  Embree's 4 + count / 20
    # was faster still but cost SAH +0.5% and a level of depth.
    nbe = min(n_bins, count, 6 + count // 8)
    for k in range(3):
        ext = cb[3 + k] - cb[k]
        # A zero-width axis puts everything into bin 0, leaving no valid
        # plane on it; no special case needed.
        scale[k] = nbe / ext if ext > 0.0 else 0.0
    return nbe


@nb.njit(**_NO_RC)
def _choose(bcnt, bbox, nbe, scale, count, max_leaf, c_trav, c_isect, block, nodebox, r_area, r_cnt):
    """The node box (into ``nodebox``) and the split of a binned node:
    returns (axis, plane); axis -2 makes a leaf, -1 halves the range (all
    centroids coincide)."""
    # Node box = union of the bins of any one axis.
    _set_empty(nodebox)
    for b in range(nbe):
        _union_bin(nodebox, bbox, 0, b)
    inv, node_area = _scaled_area(nodebox)
    cost, axis, plane = _best_split(bcnt, bbox, nbe, scale, inv, node_area, c_trav, c_isect, block, r_area, r_cnt)
    if count <= max_leaf and (axis < 0 or c_isect * _blocks(count, block) * node_area <= cost):
        return -2, 0
    return axis, plane


@kernel_function(**_HELPER_RC)
def _threshold(cmin, scale, plane, n_bins):
    """The least float32 centroid whose bin is ``plane`` or above: since
    _bin_of is monotone, bin < plane exactly when the centroid is below it
    (one compare a primitive in the partition instead of the bin's
    arithmetic on its critical path).  ``cmin`` is the node's least
    centroid (bin 0); every centroid is at most the largest float32."""
    inf = np.float32(np.inf)
    # Nearly always within an ulp or two of the plane's position.
    x = np.float32(cmin + plane / scale)
    for _ in range(4):
        if _bin_of(x, cmin, scale, n_bins) < plane:
            y = np.nextafter(x, inf)
            if _bin_of(y, cmin, scale, n_bins) >= plane:
                return y
        else:
            y = np.nextafter(x, -inf)
            if _bin_of(y, cmin, scale, n_bins) < plane:
                return x
        x = y
    # Otherwise (bins far wider than the float32 spacing near the plane, e.g.
    # around 0 in a node spanning 1e30: a flat run of billions of floats)
    # bisection, keeping bin(lo) < plane <= bin(hi).
    lo = np.float32(cmin)
    hi = np.float32(_F32_MAX)
    while np.nextafter(lo, inf) < hi:
        m = np.float32(0.5 * (np.float64(lo) + np.float64(hi)))
        if m <= lo or m >= hi:
            m = np.nextafter(lo, inf)
        if _bin_of(m, cmin, scale, n_bins) >= plane:
            hi = m
        else:
            lo = m
    return hi


@nb.njit(**_NO_RC)
def _partition(box, cen, ids, start, end, k, cmin, scale, plane, n_bins, cb_l, cb_r):
    """Hoare partition of [start, end) by bin < plane on axis k; collects
    the centroid bounds of both sides on the way (in locals: through the
    arrays, every primitive's update went through memory).  Returns the
    split index."""
    inf = np.float32(np.inf)
    la0 = la1 = la2 = inf
    lb0 = lb1 = lb2 = -inf
    ra0 = ra1 = ra2 = inf
    rb0 = rb1 = rb2 = -inf
    thr = _threshold(cmin, scale, plane, n_bins)
    i = start
    j = end - 1
    while True:
        while i <= j and cen[i, k] < thr:
            c0, c1, c2 = cen[i, 0], cen[i, 1], cen[i, 2]
            la0, la1, la2 = _min32(la0, c0), _min32(la1, c1), _min32(la2, c2)
            lb0, lb1, lb2 = _max32(lb0, c0), _max32(lb1, c1), _max32(lb2, c2)
            i += 1
        while i <= j and not cen[j, k] < thr:
            c0, c1, c2 = cen[j, 0], cen[j, 1], cen[j, 2]
            ra0, ra1, ra2 = _min32(ra0, c0), _min32(ra1, c1), _min32(ra2, c2)
            rb0, rb1, rb2 = _max32(rb0, c0), _max32(rb1, c1), _max32(rb2, c2)
            j -= 1
        if i >= j:
            break
        for d in range(6):
            t = box[i, d]
            box[i, d] = box[j, d]
            box[j, d] = t
        for d in range(3):
            t = cen[i, d]
            cen[i, d] = cen[j, d]
            cen[j, d] = t
        t_id = ids[i]
        ids[i] = ids[j]
        ids[j] = t_id
    cb_l[0], cb_l[1], cb_l[2], cb_l[3], cb_l[4], cb_l[5] = la0, la1, la2, lb0, lb1, lb2
    cb_r[0], cb_r[1], cb_r[2], cb_r[3], cb_r[4], cb_r[5] = ra0, ra1, ra2, rb0, rb1, rb2
    return i


@kernel_function(**_HELPER_RC)
def _surely_leaf(box, start, end, c_trav, c_isect, block, nodebox):
    """Whether a node of at most max_leaf primitives is a leaf whatever its
    bins say (then its box is in ``nodebox``), without binning it.  Any
    split costs at least c_trav A + c_isect (the sum of the primitives'
    areas), since each side's box holds each of its primitives' boxes (and
    areas computed as _choose does are monotone): a leaf costing no more
    than that bound (less a margin for rounding) is what _choose decides
    too.  With c_trav = 2, the leaves of 2 always, most of 3 and many of 4.
    With blocks of several primitives a side costs at least its box's area
    once, so the bound is c_trav A + c_isect (the largest primitive's area);
    with c_isect <= c_trav every node of one block is a leaf."""
    count = end - start
    for d in range(3):
        lo = box[start, d]
        hi = box[start, 3 + d]
        for i in range(start + 1, end):
            lo = _min32(lo, box[i, d])
            hi = _max32(hi, box[i, 3 + d])
        nodebox[d] = lo
        nodebox[3 + d] = hi
    if _blocks(count, block) * c_isect <= c_trav:  # a split costs more than c_trav A alone
        return True
    inv, node_area = _scaled_area(nodebox)
    prims = 0.0
    largest = 0.0
    for i in range(start, end):
        a = _half_area(
            np.float64(box[i, 0]),
            np.float64(box[i, 1]),
            np.float64(box[i, 2]),
            np.float64(box[i, 3]),
            np.float64(box[i, 4]),
            np.float64(box[i, 5]),
            inv,
        )
        prims += a
        largest = max(largest, a)
    if block > 1:
        prims = largest
    return c_isect * _blocks(count, block) * node_area <= (c_trav * node_area + c_isect * prims) * (1.0 - 1e-9)


@nb.njit(**_JIT)
def _build_range(
    box, cen, ids, start0, end0, root_cb, max_leaf, n_bins, c_trav, c_isect, block, nbounds, nindex, naxis, base
):
    """Serial build of the subtree over primitives [start0, end0) into node
    rows base, base + 1, ... (depth-first; child links and leaf ranges are
    absolute).  Returns the number of nodes written (at most 2 count - 1)."""
    bcnt = np.empty((3, n_bins), np.int64)
    bbox = np.empty((3, n_bins, 8), np.float32)
    r_area = np.empty(n_bins, np.float64)
    r_cnt = np.empty(n_bins, np.int64)
    scale = np.empty(3, np.float64)
    cb = np.empty(6, np.float64)
    nodebox = np.empty(6, np.float64)
    cb_l = np.empty(6, np.float64)
    cb_r = np.empty(6, np.float64)

    # Work stack rows: start, end, node whose right-child slot to patch (or
    # -1), then the centroid bounds of the range -- all as float64 (indices
    # are exact far beyond 2**31).  Grows on demand: a pathological SAH tree
    # can be deeper than any fixed bound.
    stack = np.empty((64, 9), np.float64)
    stack[0, 0] = start0
    stack[0, 1] = end0
    stack[0, 2] = -1
    for d in range(6):
        stack[0, 3 + d] = root_cb[d]
    sp = 1
    n_nodes = 0

    while sp > 0:
        sp -= 1
        start = int(stack[sp, 0])
        end = int(stack[sp, 1])
        patch = int(stack[sp, 2])
        for d in range(6):
            cb[d] = stack[sp, 3 + d]
        m = base + n_nodes
        n_nodes += 1
        if patch >= 0:
            nindex[patch, 0] = m
        count = end - start

        if count <= max_leaf and _surely_leaf(box, start, end, c_trav, c_isect, block, nodebox):
            for d in range(6):
                nbounds[m, d] = nodebox[d]
            nindex[m, 0] = start
            nindex[m, 1] = count
            naxis[m] = -1
            continue
        if count == 1:
            for d in range(6):
                nbounds[m, d] = box[start, d]
            nindex[m, 0] = start
            nindex[m, 1] = 1
            naxis[m] = -1
            continue

        nbe = _set_scale(cb, count, n_bins, scale)
        _clear_bins(bcnt, bbox, nbe)
        _bin_prims(box, cen, start, end, cb, scale, nbe, bcnt, bbox)
        axis, plane = _choose(bcnt, bbox, nbe, scale, count, max_leaf, c_trav, c_isect, block, nodebox, r_area, r_cnt)
        for d in range(6):
            nbounds[m, d] = nodebox[d]
        if axis == -2:
            nindex[m, 0] = start
            nindex[m, 1] = count
            naxis[m] = -1
            continue

        if axis >= 0:
            mid = _partition(box, cen, ids, start, end, axis, cb[axis], scale[axis], plane, nbe, cb_l, cb_r)
        else:
            # All centroids coincide: nothing to bin, so halve the range to
            # keep leaves within max_leaf.
            mid = start + count // 2
            _cen_bounds(cen, start, mid, cb_l)
            _cen_bounds(cen, mid, end, cb_r)
            axis = 0
        naxis[m] = axis
        nindex[m, 1] = 0  # nindex[m, 0] is patched when the right job pops

        if sp + 2 > stack.shape[0]:
            bigger = np.empty((2 * stack.shape[0], 9), np.float64)
            for r in range(sp):
                for d in range(9):
                    bigger[r, d] = stack[r, d]
            stack = bigger
        # Right job below the left one, so the left child pops next and is
        # written right after its parent; the right one patches nindex[m, 0]
        # when popped.
        stack[sp, 0] = mid
        stack[sp, 1] = end
        stack[sp, 2] = m
        stack[sp + 1, 0] = start
        stack[sp + 1, 1] = mid
        stack[sp + 1, 2] = -1
        for d in range(6):
            stack[sp, 3 + d] = cb_r[d]
            stack[sp + 1, 3 + d] = cb_l[d]
        sp += 2

    return n_nodes


# --- The top of the tree: one node at a time, each pass split over threads --


# These two call the kernels that _build_range calls, with the same types, from
# Python (the kernels release the GIL): no kernel of their own to compile.


def _bin_piece(box, cen, start, end, cb, scale, nbe, bcnt, bbox):
    _clear_bins(bcnt, bbox, nbe)
    _bin_prims(box, cen, start, end, cb, scale, nbe, bcnt, bbox)


def _partition_blocks(box, cen, ids, start, end, block, j0, j1, k, cmin, scale, plane, nbe, half, n_left, pcb):
    """Partition blocks j0 .. j1 - 1 of [start, end) (``block`` primitives
    each) in place, each on its own; per block: the primitives going left
    (``n_left[j]``) and both sides' centroid bounds (``pcb[j]``).  Blocks
    are fixed, not one per thread, so the order does not depend on the
    thread count.  k < 0: halve by position (before ``half`` go left)."""
    for j in range(j0, j1):
        a = start + j * block
        b = min(end, a + block)
        if k >= 0:
            m = _partition(box, cen, ids, a, b, k, cmin, scale, plane, nbe, pcb[j, 0], pcb[j, 1])
        else:
            m = min(max(half, a), b)
            _cen_bounds(cen, a, m, pcb[j, 0])
            _cen_bounds(cen, m, b, pcb[j, 1])
        n_left[j] = m - a


# Nodes above this many primitives are split with their binning and
# partition passes spread over threads; smaller ones are whole subtrees,
# built serially, one per thread at a time.  Fixed (not derived from the
# thread count), so the tree and the primitive order never depend on it.
_TOP = 1 << 15
# Top nodes are partitioned in blocks of this many primitives (each in
# place, then the blocks' parts moved together): fixed for the same reason.
_BLOCK = 1 << 14


class _Runner:
    """Runs a nogil kernel over argument tuples, on ``threads`` threads."""

    def __init__(self, threads: int):
        self.pool = ThreadPoolExecutor(threads) if threads > 1 else None

    def map(self, fn, argsets):
        if self.pool is None:
            return [fn(*a) for a in argsets]
        return list(self.pool.map(lambda a: fn(*a), argsets))

    def close(self):
        if self.pool is not None:
            self.pool.shutdown()


def _misplaced(start, end, mid, n_left):
    """After the blocks' partition: the pairs of equal ranges (right-part primitives before
    ``mid``, left-part ones from ``mid`` on, both in position order) to swap so that
    [start, mid) holds the left part. Returns (to_right, to_left, length) arrays."""
    a = start + _BLOCK * np.arange(len(n_left))
    b = np.minimum(a + _BLOCK, end)
    m = a + n_left
    r_lo, r_hi = m, np.minimum(b, mid)  # right parts sitting left of mid
    l_lo, l_hi = np.maximum(a, mid), m  # left parts sitting right of mid
    r = r_hi > r_lo
    lft = l_hi > l_lo
    r_lo, r_len = r_lo[r], (r_hi - r_lo)[r]
    l_lo, l_len = l_lo[lft], (l_hi - l_lo)[lft]
    # Both lists cover as many primitives: cut them at each other's boundaries.
    cuts = np.union1d(np.cumsum(r_len), np.cumsum(l_len))
    cuts = np.concatenate([[0], cuts])
    length = np.diff(cuts)
    at = cuts[:-1]
    ri = np.searchsorted(np.cumsum(r_len), at, side="right")
    li = np.searchsorted(np.cumsum(l_len), at, side="right")
    r_off = at - (np.cumsum(r_len) - r_len)[ri]
    l_off = at - (np.cumsum(l_len) - l_len)[li]
    return r_lo[ri] + r_off, l_lo[li] + l_off, length


def _swap(arrays, x, y, length, j0, j1):
    """Swap ranges x[j], y[j] of ``length[j]`` rows in each of ``arrays``, j in j0 .. j1 - 1."""
    for j in range(j0, j1):
        p, q, k = int(x[j]), int(y[j]), int(length[j])
        for arr in arrays:
            t = arr[p : p + k].copy()
            arr[p : p + k] = arr[q : q + k]
            arr[q : q + k] = t


def _place(snb, sni, sna, src, count, nbounds, nindex, naxis, dst):
    """Copy a subtree's ``count`` nodes from row ``src`` of the subtrees'
    rows to row ``dst``; its child links (numbered from 0) move with it."""
    nbounds[dst : dst + count] = snb[src : src + count]
    naxis[dst : dst + count] = a = sna[src : src + count]
    nindex[dst : dst + count] = sni[src : src + count]
    nindex[dst : dst + count, 0] += np.where(a >= 0, dst, 0).astype(np.int32)


def _subtree(box, cen, ids, a, b, cb, max_leaf, n_bins, c_trav, c_isect, block, scratch, out):
    """The subtree over primitives [a, b), built serially into this thread's scratch (up to
    2 (b - a) - 1 rows; ``scratch``: a threading.local), its node rows numbered from 0, then
    copied to the next free rows of ``out`` (bounds, index, axis, a lock, [next free row]);
    returns (first row in out, rows).  So the rows of ``out`` are touched from the start, only
    as far as they are used, and freed at once with it.  Before, a shared scratch of 2 N rows
    written at 2 a ... had its pages touched all over (0.26 GB at bumpy 4M; its page faults
    were a tenth of the build's CPU time); arrays of 2 (b - a) - 1 rows per subtree, kept,
    raised the 10 M render's peak memory by 2%, and so did copies of each subtree (the
    allocator kept the freed copies)."""
    cap = 2 * (b - a) - 1
    if getattr(scratch, "cap", 0) < cap:
        scratch.cap = cap
        scratch.arrays = (np.empty((cap, 6), np.float32), np.empty((cap, 2), np.int32), np.empty(cap, np.int8))
    snb, sni, sna = scratch.arrays
    m = _build_range(box, cen, ids, a, b, cb, max_leaf, n_bins, c_trav, c_isect, block, snb, sni, sna, 0)
    onb, oni, ona, lock, free = out
    with lock:
        at = free[0]
        free[0] += m
    onb[at : at + m] = snb[:m]
    oni[at : at + m] = sni[:m]
    ona[at : at + m] = sna[:m]
    return at, m


def _reuse(buf, rows, cols, dtype):
    """A (rows, cols) ``dtype`` array in the memory of ``buf`` (C-contiguous, 4-byte
    items) if it fits, else a new one."""
    flat = buf.reshape(-1).view(dtype)
    if rows * cols <= flat.size:
        return flat[: rows * cols].reshape(rows, cols)
    return np.empty((rows, cols), dtype)


def _pieces(start: int, end: int, parts: int) -> list[tuple[int, int]]:
    cuts = [start + (end - start) * j // parts for j in range(parts + 1)]
    return [(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True) if b > a]


def _build(box, cen, ids, root_cb, max_leaf, n_bins, c_trav, c_isect, block, threads):
    """The tree over the prepared primitives; reorders ``ids`` (and uses
    ``box``, ``cen`` as scratch).  Returns (node_bounds, node_index, node_axis)."""
    n = box.shape[0]
    run = _Runner(threads)
    try:
        # Top of the tree, in depth-first order: ["node", box, axis, right entry]
        # or ["task", start, end, centroid bounds] for a subtree built later.
        entries: list[list] = []
        stack = [(0, n, root_cb, -1)]
        scale = np.empty(3, np.float64)
        while stack:
            start, end, cb, parent = stack.pop()
            if parent >= 0:
                entries[parent][3] = len(entries)
            count = end - start
            if count <= max(_TOP, max_leaf):  # so that a top node is never a leaf
                entries.append(["task", start, end, cb])
                continue
            pieces = _pieces(start, end, threads)
            nbe = _set_scale(cb, count, n_bins, scale)
            pcnt = np.empty((len(pieces), 3, n_bins), np.int64)
            pbox = np.empty((len(pieces), 3, n_bins, 8), np.float32)
            run.map(_bin_piece, [(box, cen, a, b, cb, scale, nbe, pcnt[j], pbox[j]) for j, (a, b) in enumerate(pieces)])
            # The pieces' bins reduced exactly (counts, min), so the result
            # does not depend on how the range was cut.
            nodebox = np.empty(6, np.float64)
            bcnt, bbox = pcnt[:, :, :nbe].sum(axis=0), pbox[:, :, :nbe].min(axis=0)
            r_area, r_cnt = np.empty(n_bins, np.float64), np.empty(n_bins, np.int64)
            axis, plane = _choose(
                bcnt, bbox, nbe, scale, count, max_leaf, c_trav, c_isect, block, nodebox, r_area, r_cnt
            )
            k = int(axis)
            cmin, sk = (float(cb[k]), float(scale[k])) if k >= 0 else (0.0, 0.0)
            half = start + count // 2
            n_blocks = -(-count // _BLOCK)
            groups = _pieces(0, n_blocks, threads)
            n_left = np.empty(n_blocks, np.int64)
            pcb = np.empty((n_blocks, 2, 6), np.float64)
            args = (k, cmin, sk, plane, nbe, half, n_left, pcb)
            run.map(_partition_blocks, [(box, cen, ids, start, end, _BLOCK, j0, j1, *args) for j0, j1 in groups])
            mid = start + int(n_left.sum())
            # Then the right parts left of mid swapped with the left parts right
            # of it, in place (only misplaced primitives move; blocks that went
            # wholly to their side stay): numpy copies, which release the GIL,
            # so no Numba kernel to compile for them.
            x, y, length = _misplaced(start, end, mid, n_left)
            cut = np.searchsorted(np.cumsum(length), np.sum(length) * np.arange(1, threads) / threads)
            spans = [(int(p), int(q)) for p, q in zip(np.r_[0, cut], np.r_[cut, len(length)], strict=True) if q > p]
            run.map(_swap, [((box, cen, ids), x, y, length, j0, j1) for j0, j1 in spans])
            cb_l = np.concatenate([pcb[:, 0, :3].min(axis=0), pcb[:, 0, 3:].max(axis=0)])
            cb_r = np.concatenate([pcb[:, 1, :3].min(axis=0), pcb[:, 1, 3:].max(axis=0)])
            entries.append(["node", nodebox.astype(np.float32), max(k, 0), -1])
            stack.append((mid, end, cb_r, len(entries) - 1))
            stack.append((start, mid, cb_l, -1))

        # Subtrees built whole, largest first for balance, each into its
        # thread's scratch, then copied into the rows of `out` in the order
        # they finish (see _subtree).
        tasks = [e for e in entries if e[0] == "task"]
        cap = 2 * n - 1
        out = (np.empty((cap, 6), np.float32), np.empty((cap, 2), np.int32), np.empty(cap, np.int8))
        scratch, lock, free = threading.local(), threading.Lock(), [0]
        order = sorted(range(len(tasks)), key=lambda t: tasks[t][1] - tasks[t][2])
        built = run.map(
            _subtree,
            [
                (box, cen, ids, a, b, cb, max_leaf, n_bins, c_trav, c_isect, block, scratch, (*out, lock, free))
                for _, a, b, cb in (tasks[t] for t in order)
            ],
        )
        sub = dict(zip(order, built, strict=True))
        size_of = {t: sub[t][1] for t in sub}
        if len(entries) == 1:  # one subtree: the tree
            return tuple(x[: size_of[0]].copy() for x in out)

        # Depth-first numbering of the whole tree: a subtree's nodes follow
        # its place in the top part.
        at = []
        m = 0
        t = 0
        for e in entries:
            at.append(m)
            if e[0] == "node":
                m += 1
            else:
                m += size_of[t]
                t += 1
        # The result in the memory of `box` and `cen`, when it fits (leaves of
        # several primitives: about 0.7 N nodes): their pages are in already
        # (fresh arrays' page faults: placing took 0.18 s, now 0.03 at 4 M), they are not
        # read any more, and the peak does not grow by the tree.
        nbounds = _reuse(box, m, 6, np.float32)
        nindex = _reuse(cen, m, 2, np.int32)
        naxis = np.empty(m, np.int8)
        jobs = []
        t = 0
        for e, row in zip(entries, at, strict=True):
            if e[0] == "task":
                jobs.append((*out, sub[t][0], size_of[t], nbounds, nindex, naxis, row))
                t += 1
        run.map(_place, jobs)
        # The top nodes' rows after the subtrees': their first writes, scattered
        # over fresh arrays, faulted in most of the pages on this thread alone
        # (0.1 s at bumpy 4M) when they came first.
        for e, row in zip(entries, at, strict=True):
            if e[0] == "node":
                nbounds[row] = e[1]
                nindex[row] = (at[e[3]], 0)
                naxis[row] = e[2]
        return nbounds, nindex, naxis
    finally:
        run.close()


# ---------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------


def build_bvh(
    lo, hi, max_leaf_size: int = 4, n_bins: int = 16, *, c_trav: float = 1.0, c_isect: float = 1.0, leaf_block: int = 1
) -> BVH:
    """Build a binned-SAH BVH over N primitive boxes ``lo``/``hi`` (N, 3).

    ``c_trav`` / ``c_isect`` are the relative costs of a node traversal and
    of a primitive intersection used by the heuristic; ``leaf_block``
    primitives are tested as one (a leaf of n costs ceil(n / leaf_block)
    intersections: traversal tests blocks of 4 triangles with one vector
    test, so a leaf of 1 costs as much as one of 4).  Large inputs are
    built on ``numba.get_num_threads()`` threads; the result does not depend
    on the thread count.
    """
    lo = np.ascontiguousarray(lo, dtype=np.float64)
    hi = np.ascontiguousarray(hi, dtype=np.float64)
    if lo.ndim != 2 or lo.shape[1] != 3 or lo.shape != hi.shape:
        raise ValueError(f"lo and hi must both have shape (N, 3), got {lo.shape} and {hi.shape}")
    if max_leaf_size < 1:
        raise ValueError("max_leaf_size must be >= 1")
    if n_bins < 2:
        raise ValueError("n_bins must be >= 2")
    if leaf_block < 1:
        raise ValueError("leaf_block must be >= 1")
    n = lo.shape[0]
    if n >= 2**30:
        raise ValueError("too many primitives for int32 indices")

    if n == 0:
        bounds = np.array([[np.inf] * 3 + [-np.inf] * 3], dtype=np.float32)
        return BVH(bounds, np.zeros((1, 2), np.int32), np.full(1, -1, np.int8), np.zeros(0, np.int32))

    threads = max(1, min(nb.get_num_threads(), n // _TOP))
    box = np.empty((n, 6), np.float32)
    cen = np.empty((n, 3), np.float32)
    ids = np.empty(n, np.int32)
    pieces = _pieces(0, n, threads)
    pcb = np.empty((len(pieces), 6), np.float64)
    run = _Runner(threads)
    try:
        bad = run.map(_prepare, [(lo, hi, box, cen, ids, pcb[j], a, b) for j, (a, b) in enumerate(pieces)])
    finally:
        run.close()
    bad = [b for b in bad if b >= 0]
    if bad:
        i = min(bad)
        raise ValueError(f"primitive {i} has an invalid box (NaN or lo > hi): lo={lo[i]}, hi={hi[i]}")
    root_cb = np.concatenate([pcb[:, :3].min(axis=0), pcb[:, 3:].max(axis=0)])
    nbounds, nindex, naxis = _build(
        box, cen, ids, root_cb, int(max_leaf_size), int(n_bins), float(c_trav), float(c_isect), int(leaf_block), threads
    )
    return BVH(nbounds, nindex, naxis, ids)


@nb.njit(**_JIT)
def _triangle_bounds(tri, lo, hi, start, end):
    for i in range(start, end):
        for d in range(3):
            a, b, c = tri[i, d], tri[i, 3 + d], tri[i, 6 + d]
            if a != a or b != b or c != c:  # NaN, as numpy's min gives (build_bvh rejects it)
                lo[i, d] = hi[i, d] = np.nan
            else:
                lo[i, d] = min(a, b, c)
                hi[i, d] = max(a, b, c)


# Triangle counts above which triangle_bounds runs its kernel.
_TRI_KERNEL = 1 << 18


def triangle_bounds(tri: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """The boxes of triangles ``tri`` (T, 9) float32 (three corners) into ``lo``, ``hi`` (T, 3)
    float64; above _TRI_KERNEL triangles in a kernel on ``numba.get_num_threads()`` threads
    (numpy's min over the corner axis took 1.6-3 s at 4 M triangles, the kernel 0.06 s; below,
    numpy's elementwise minimum, a few times faster than that min, and no kernel to compile:
    ~0.3 s cold)."""
    n = len(tri)
    if n <= _TRI_KERNEL:  # numpy (exact as well): smaller scenes compile no kernel for it
        np.minimum(np.minimum(tri[:, 0:3], tri[:, 3:6]), tri[:, 6:9], out=lo)
        np.maximum(np.maximum(tri[:, 0:3], tri[:, 3:6]), tri[:, 6:9], out=hi)
        return
    tri = np.ascontiguousarray(tri, np.float32)
    threads = max(1, min(nb.get_num_threads(), n // _TOP))
    run = _Runner(threads)
    try:
        run.map(_triangle_bounds, [(tri, lo, hi, a, b) for a, b in _pieces(0, n, threads)])
    finally:
        run.close()


def bvh_nbytes(bvh: BVH) -> int:
    """Total bytes held by the BVH arrays."""
    return int(sum(a.nbytes for a in bvh))


@nb.njit(cache=True)
def _depths(node_index, node_axis):
    # Children always come after their parent, so one forward pass works.
    depth = np.ones(node_axis.shape[0], np.int64)
    for m in range(node_axis.shape[0]):
        if node_axis[m] >= 0:
            depth[m + 1] = depth[m] + 1
            depth[node_index[m, 0]] = depth[m] + 1
    return depth


def bvh_depth(bvh: BVH) -> int:
    """Number of levels (a single leaf has depth 1).  A traversal stack of
    ``bvh_depth(bvh)`` entries is always enough."""
    return int(_depths(bvh.node_index, bvh.node_axis).max())


def _areas(bounds: np.ndarray) -> np.ndarray:
    b = np.clip(bounds.astype(np.float64), -_F32_MAX, _F32_MAX)
    e = np.maximum(b[:, 3:] - b[:, :3], 0.0)
    return 2.0 * (e[:, 0] * e[:, 1] + e[:, 1] * e[:, 2] + e[:, 2] * e[:, 0])


def sah_cost(bvh: BVH, c_trav: float = 1.0, c_isect: float = 1.0, leaf_block: int = 1) -> float:
    """Expected cost of a random ray that hits the root box:
    sum over inner nodes of ``c_trav * A(n)/A(root)`` plus sum over leaves of
    ``c_isect * ceil(count / leaf_block) * A(n)/A(root)`` (as build_bvh counts)."""
    area = _areas(bvh.node_bounds)
    leaf = bvh.node_axis < 0
    blocks = -(-bvh.node_index[:, 1].astype(np.int64) // leaf_block)
    weight = np.where(leaf, c_isect * blocks, c_trav)
    root = area[0]
    if not root > 0.0:
        # Degenerate scene (points or a segment): all ratios tend to 1.
        return float(weight.sum())
    return float((weight * area).sum() / root)
