"""Ray packets: eight coherent rays traced through the wide BVH together (SIMD across rays).

Single-ray traversal (traverse.py) tests one ray against a node's eight child boxes in one
vector instruction per plane. A packet turns that around: eight rays that start close together
and point the same way (neighbouring camera pixels) visit nearly the same nodes, so one pass
over the tree serves all eight. A node's boxes, its child list and a leaf's triangles are
loaded once for eight rays rather than once each, the stack pushed and popped once for eight
(Wald, Slusallek, Benthin and Wagner 2001, "Interactive rendering with coherent ray tracing";
Embree's packet kernels). Each triangle of a leaf is tested against the eight rays at once; a
node's eight boxes are tested against each of the rays that reached it in turn, the single-ray
test with the node's box rows held in registers, so a node that two rays reach costs two tests,
not eight.

A leaf that one to six of the packet's rays reach is tested ray by ray with the single-ray
block test's arithmetic (four triangles per vector, the block gathered once for those rays:
packet_triangles_each) rather than eight float64 lanes at once; so is every leaf of a shadow
packet, whose rays leave it as they are blocked.

Each ray's result is the single-ray traversal's to the last bit: the triangle test is the same
watertight test (shape_triangle.py) operation for operation, one ray per lane in float64, and
the box test widens every slab as the single-ray one does, so no box a ray enters is culled.
Only which of two triangles hit at exactly the same distance is reported can differ (a ray
through a shared edge): the first one found, and the packet finds them in another order.

A packet is taken only when it pays and is safe (`packet_setup`): every ray finite, every
direction in one octant with one dominant axis (so the slab rows and the watertight test's axis
order are the packet's, not each ray's), the directions within 10 degrees of the first ray's
and the origins within 1% of the scene's extent of its origin; and only in scenes whose root
is no leaf and that have no instances. Cast mode takes packets in the kernels' basic variant
(spheres and triangles alone: variants.features gives X None); the batch query in every scene
without instances, testing planes ray by ray first (`packet_unbounded`). Where a run of rays
turns part way (the next row of compacted hit rays, another octant), its leading rays go as a
smaller packet when there are two or more. Anything else is traced ray by ray, by the caller.

Packet state lives in one thread's scratch arrays (`packet_scratch`):

* ``box`` float32 (BOX_ROWS, 8): per lane, box_ray's near offsets x, y, z, far offsets, 1 / d;
  then packet_node's rows (the best hits in float32, a table of the rays' bits).
* ``lane`` float64 (LANE_ROWS, 8): per lane the sheared-test constants, the best hit so far and
  the ray itself (rows below).
* ``prim`` int64 (8,): per lane the primitive of the best hit (NO_HIT when none).
* the mask stack, int32 (TRAVERSAL_STACK,): beside traverse.py's node and distance stacks, each
  entry's mask of rays.
"""

import contextlib
import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import inline_function, kernel_function
from .layout import NODE_REF, SPHERE_BLOCK
from .shape_triangle import (
    EXACT,
    EXACT_DIVISION,
    TRIANGLES_PER_TEST,
    block_columns,
    block_test,
    exact_ops,
    shear_axes,
    watertight_distance,
    watertight_edges,
)
from .shapes import NO_HIT
from .traverse import _root_is_a_leaf, _unbounded_hit, block_row, intersect_leaf, rows_in_leaf_order
from .wide_nodes import (
    _F32_MAX,
    _NEAR_SCALE,
    BVH_WIDTH,
    TRAVERSAL_STACK,
    leaf_count,
    leaf_first,
    lowest_bit,
    node_planes,
    prefetch_child,
    prefetch_child_rows,
    prefetch_neighbours,
    prefetch_row,
    ray_axis_ir,
    scratch_array,
    select_max,
    select_min,
    slab_test,
    trailing_zeros,
)

PACKET = 8  # rays per packet: eight float32 lanes in one AVX2 register
assert PACKET == BVH_WIDTH  # a node's child mask and a child's ray mask are both one byte

# Rows of the `box` scratch (float32, one column per ray): box_ray's nine constants (near offsets
# x, y, z, far offsets, 1 / d), then packet_node's: the rays' best hits in float32 (BOX_BEST),
# and each ray's bit in every lane (BOX_BITS + r: 1 << r as int32, written by packet_load), read
# by the node test's loop as broadcasts and memory operands
BOX_BEST = 9
BOX_BITS = 10
BOX_ROWS = BOX_BITS + PACKET

# Rows of the `lane` scratch (float64, one column per ray)
OX, OY, OZ = 0, 1, 2  # the origin's components along the shear axes kx, ky, kz
SX, SY, SZ = 3, 4, 5  # the watertight test's shear constants
TMIN = 6
BEST_T, BEST_V, BEST_W, BEST_DET = 7, 8, 9, 10  # the best hit: t and its unnormalised barycentrics
RAY_O, RAY_D = 11, 14  # the ray as given (x, y, z rows), for leaves tested ray by ray
LANE_ROWS = 17

# How close a packet's rays must be to be traced together. Neighbouring pixels of any camera
# at any usual resolution differ by far less than this; rays of a path tracer's bounces, or
# random rays, fail it and take the single-ray path, where a packet would only visit the union
# of eight unrelated traversals.
_MIN_COS = 0.985  # directions within 10 degrees of the first ray's
_ORIGIN_SPREAD = 0.01  # origins within this fraction of the scene's extent of the first ray's
# Shadow rays of neighbouring pixels start on the surface a few pixels' width apart (bunny at
# 600 x 600: eight pixels span ~5% of its size) but run side by side to one light: their
# traversals overlap as a camera packet's do.
_SHADOW_ORIGIN_SPREAD = 0.1
# The fewest leading rays of a refused run that are still traced as a packet (one goes alone:
# the single-ray traversal is faster for one ray).
_MIN_TAKEN = 2


@kernel_function(_nrt=True)
def packet_scratch():
    """One thread's packet state: (box, lane, prim, mask stack) as the module docstring says."""
    return (
        scratch_array(BOX_ROWS * PACKET, np.float32).reshape((BOX_ROWS, PACKET)),
        scratch_array(LANE_ROWS * PACKET, np.float64).reshape((LANE_ROWS, PACKET)),
        scratch_array(PACKET, np.int64),
        scratch_array(TRAVERSAL_STACK, np.int32),
    )


# --- LLVM IR helpers ------------------------------------------------------------------------------

_f32, _f64, _i1 = ir.FloatType(), ir.DoubleType(), ir.IntType(1)
_i8, _i32, _i64 = ir.IntType(8), ir.IntType(32), ir.IntType(64)
_V8F = ir.VectorType(_f32, PACKET)
_V8D = ir.VectorType(_f64, PACKET)
_V8I64 = ir.VectorType(_i64, PACKET)


def _splat(builder, x, vt):
    undef = ir.Constant(vt, ir.Undefined)
    zeros = ir.Constant(ir.VectorType(_i32, vt.count), [0] * vt.count)
    return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(_i32, 0)), undef, zeros)


def _row_pointer(builder, data, row, vt):
    """Pointer to row `row` (an i64) of a C-contiguous (R, PACKET) array, as a vector."""
    p = builder.gep(data, [builder.mul(row, ir.Constant(_i64, PACKET))], inbounds=True)
    return builder.bitcast(p, vt.as_pointer())


def _align(vt):
    """The element's alignment: numpy guarantees no more for a scratch row."""
    return 4 if vt.element == _f32 else 8


def _load_row(builder, data, row, vt):
    return builder.load(_row_pointer(builder, data, ir.Constant(_i64, row), vt), align=_align(vt))


def _store_row(builder, value, data, row, vt):
    builder.store(value, _row_pointer(builder, data, ir.Constant(_i64, row), vt), align=_align(vt))


def _lane_pointer(builder, data, row, i):
    """Pointer to element (row, i) of a C-contiguous (R, PACKET) array; i an i64."""
    return builder.gep(data, [builder.add(i, ir.Constant(_i64, row * PACKET))], inbounds=True)


def _load_lane(builder, data, row, i):
    return builder.load(_lane_pointer(builder, data, row, i))


@contextlib.contextmanager
def _each_ray(builder, mask, name):
    """A loop over the set bits of the i64 `mask` (at most the low PACKET), lowest first, none
    when it is 0: the code emitted in the with block is its body, and the bit's index (an i64)
    is what the with statement binds. Not unrolled, so that LLVM schedules one ray at a time."""
    left_slot = cgutils.alloca_once_value(builder, mask)
    loop = builder.append_basic_block(f"{name}.ray")
    done = builder.append_basic_block(f"{name}.done")
    builder.cbranch(builder.icmp_unsigned("!=", mask, ir.Constant(_i64, 0)), loop, done)
    builder.position_at_end(loop)
    left = builder.load(left_slot)
    builder.store(builder.and_(left, builder.sub(left, ir.Constant(_i64, 1))), left_slot)
    yield trailing_zeros(builder, left)
    builder.cbranch(builder.icmp_unsigned("!=", builder.load(left_slot), ir.Constant(_i64, 0)), loop, done)
    builder.position_at_end(done)


def _mask_vector(builder, mask):
    """The low PACKET bits of the i64 `mask` as a <PACKET x i1> vector (bit i: lane i), made by
    a vector compare of the splatted mask with each lane's bit: a bitcast of an i8 to <8 x i1>
    is taken apart byte by byte by LLVM's x86 backend and its result packed and unpacked around
    every use (six instructions a child in packet_node)."""
    vi = ir.VectorType(_i32, PACKET)
    bits = ir.Constant(vi, [1 << i for i in range(PACKET)])
    lanes = builder.and_(_splat(builder, builder.trunc(mask, _i32), vi), bits)
    return builder.icmp_unsigned("!=", lanes, ir.Constant(vi, [0] * PACKET))


def _mask_bits(builder, vec):
    """A <PACKET x i1> vector as the low bits of an i64."""
    return builder.zext(builder.bitcast(vec, ir.IntType(PACKET)), _i64)


def _reduce(builder, v, pick):
    """A horizontal reduction of the vector v by pick(builder, a, b) (a shuffle tree)."""
    n = v.type.count
    undef = ir.Constant(v.type, ir.Undefined)
    while n > 1:
        n //= 2
        hi = builder.shuffle_vector(
            v,
            undef,
            ir.Constant(ir.VectorType(_i32, v.type.count), [n + i for i in range(n)] + [0] * (v.type.count - n)),
        )
        v = pick(builder, v, hi)
    return builder.extract_element(v, ir.Constant(_i32, 0))


def _array_data(context, builder, ty, value):
    return context.make_array(ty)(context, builder, value).data


def _check_array(name, a, dtype, ndim):
    if not (isinstance(a, types.Array) and a.dtype == dtype and a.ndim == ndim and a.layout == "C"):
        raise TypingError(f"{name}: a C-contiguous {dtype} array of {ndim} dimensions")


# --- a node: its eight child boxes against the packet ----------------------------------------------


def _check_node_arrays(name, bounds, box, lane, t_out):
    _check_array(name, bounds, types.float32, 3)
    _check_array(name, box, types.float32, 2)
    _check_array(name, lane, types.float64, 2)
    _check_array(name, t_out, types.float32, 1)


def _node_operands(context, builder, sig, args, t_out_at):
    """packet_node's and packet_node_full's operands, (bounds, node, box, rows, lane) first and
    (t_out, at) at args[t_out_at:]: (node records, node as an i64, box scratch, the near rows as
    i64s, lane scratch, a pointer to t_out[at])."""
    b = _array_data(context, builder, sig.args[0], args[0])
    n = context.cast(builder, args[1], sig.args[1], types.int64)
    bx = _array_data(context, builder, sig.args[2], args[2])
    rows = [
        context.cast(builder, r, t, types.int64)
        for r, t in zip(cgutils.unpack_tuple(builder, args[3], 3), sig.args[3], strict=True)
    ]
    ln = _array_data(context, builder, sig.args[4], args[4])
    out = builder.gep(
        _array_data(context, builder, sig.args[t_out_at], args[t_out_at]),
        [context.cast(builder, args[t_out_at + 1], sig.args[t_out_at + 1], types.int64)],
        inbounds=True,
    )
    return b, n, bx, rows, ln, out


@intrinsic
def packet_node(typingctx, bounds, node, box, rows, lane, active, t_out, at):
    """The packet's rays (box: box_ray's constants per lane; rows: the packet's near-plane rows)
    against the BVH_WIDTH child boxes of wide node `node`, each ray up to its best hit so far
    (lane[BEST_T]): an i64 of BVH_WIDTH bytes, byte c the mask of the `active` rays that enter
    child c; t_out[at + c] (float32) the nearest entry distance over those rays (+inf for none).
    The slab test is box_hits' (wide_nodes.slab_test): no ray's entered box is culled."""
    _check_node_arrays("packet_node", bounds, box, lane, t_out)

    def codegen(context, builder, sig, args):
        b, n, bx, rows, ln, out = _node_operands(context, builder, sig, args, t_out_at=6)
        active = builder.and_(context.cast(builder, args[5], sig.args[5], types.int64), ir.Constant(_i64, 0xFF))
        # Rays outer, children in the lanes: each active ray against the node's eight boxes is
        # box_hits' test, its nine constants broadcast from the scratch, and the node's six
        # plane rows stay in registers for all of them. A loop over the active rays, not
        # unrolled: unrolled, LLVM hoisted every ray's multiply-adds to the top and spilled them.
        near, far = node_planes(builder, b, n, rows)
        vi = ir.VectorType(_i32, PACKET)
        inf = ir.Constant(_V8F, [math.inf] * PACKET)
        # the rays' best hits in float32 once a visit, each ray's then one broadcast load (in the
        # scratch, not a local: LLVM would forward the store into the loop as a conversion a ray)
        _store_row(builder, builder.fptrunc(_load_row(builder, ln, BEST_T, _V8D), _V8F), bx, BOX_BEST, _V8F)
        bits = builder.bitcast(bx, vi.as_pointer())
        rays_slot = cgutils.alloca_once_value(builder, ir.Constant(vi, [0] * PACKET))  # lane c: rays entering c
        minima_slot = cgutils.alloca_once_value(builder, inf)  # lane c: their nearest entry
        with _each_ray(builder, active, "packet_node") as r:
            rf = [_splat(builder, _load_lane(builder, bx, k, r), _V8F) for k in range(9)]
            best = _load_lane(builder, bx, BOX_BEST, r)
            tnear, hit = slab_test(builder, near, far, rf, _splat(builder, best, _V8F))
            bit = builder.load(builder.gep(bits, [builder.add(r, ir.Constant(_i64, BOX_BITS))], inbounds=True), align=4)
            builder.store(builder.or_(builder.load(rays_slot), builder.and_(builder.sext(hit, vi), bit)), rays_slot)
            builder.store(select_min(builder, builder.load(minima_slot), builder.select(hit, tnear, inf)), minima_slot)
        minima = builder.load(minima_slot)
        rays = builder.load(rays_slot)
        # hit entries are never NaN, so the minimum does not depend on the order of the rays;
        # scaled once here rather than in each slab test (a product rounded to nearest is
        # monotone, so the minimum of the scaled entries is the scaled minimum)
        minima = builder.fmul(minima, ir.Constant(_V8F, [_NEAR_SCALE] * PACKET))
        builder.store(minima, builder.bitcast(out, _V8F.as_pointer()), align=4)
        result = builder.bitcast(builder.trunc(rays, ir.VectorType(_i8, PACKET)), _i64)
        return result

    return types.int64(bounds, node, box, rows, lane, active, t_out, at), codegen


def _lane_minima(builder, vectors):
    """The minimum of each of eight <8 x float> vectors, as one vector (lane c: vectors[c]'s):
    the eight reductions share their shuffles, three levels of halving pairs of vectors, seven
    minima instead of twenty-four."""
    level = list(vectors)
    half = PACKET // 2
    while len(level) > 1:
        # each vector holds groups of 2 * half partial minima, one group per original vector;
        # the minimum of each group's two halves, the first vector's groups then the second's
        starts = range(0, PACKET, 2 * half)
        lo_c = ir.Constant(
            ir.VectorType(_i32, PACKET), [v + g + i for v in (0, PACKET) for g in starts for i in range(half)]
        )
        hi_c = ir.Constant(
            ir.VectorType(_i32, PACKET), [v + g + half + i for v in (0, PACKET) for g in starts for i in range(half)]
        )
        level = [
            select_min(builder, builder.shuffle_vector(a, b, lo_c), builder.shuffle_vector(a, b, hi_c))
            for a, b in zip(level[0::2], level[1::2], strict=True)
        ]
        half //= 2
    return level[0]


@intrinsic
def packet_node_full(typingctx, bounds, node, box, rows, lane, t_out, at):
    """packet_node for a packet whose eight rays are all active, the other way round: children
    outer, the rays in the lanes, each child's planes broadcast against the rays' constants (the
    same multiply-adds a pair, so the same masks and entries to the bit). Eight rays cost eight
    child tests and one shuffle tree of minima instead of eight ray tests with their loop."""
    _check_node_arrays("packet_node_full", bounds, box, lane, t_out)

    def codegen(context, builder, sig, args):
        b, n, bx, rows, ln, out = _node_operands(context, builder, sig, args, t_out_at=5)
        near, far = node_planes(builder, b, n, rows)
        rf = [_load_row(builder, bx, k, _V8F) for k in range(9)]
        best = builder.fptrunc(_load_row(builder, ln, BEST_T, _V8D), _V8F)
        inf = ir.Constant(_V8F, [math.inf] * PACKET)
        undef = ir.Constant(_V8F, ir.Undefined)
        result = ir.Constant(_i64, 0)
        entries = []  # per child: each ray's entry distance, +inf where it misses
        for c in range(BVH_WIDTH):
            lane_c = ir.Constant(ir.VectorType(_i32, PACKET), [c] * PACKET)
            lo = [builder.shuffle_vector(near[k], undef, lane_c) for k in range(3)]
            hi = [builder.shuffle_vector(far[k], undef, lane_c) for k in range(3)]
            tnear, hit = slab_test(builder, lo, hi, rf, best)
            entries.append(builder.select(hit, tnear, inf))
            result = builder.or_(result, builder.shl(_mask_bits(builder, hit), ir.Constant(_i64, 8 * c)))
        # scaled once, as packet_node scales them (a product rounded to nearest is monotone)
        minima = builder.fmul(_lane_minima(builder, entries), ir.Constant(_V8F, [_NEAR_SCALE] * PACKET))
        builder.store(minima, builder.bitcast(out, _V8F.as_pointer()), align=4)
        return result

    return types.int64(bounds, node, box, rows, lane, t_out, at), codegen


@intrinsic
def packet_box(typingctx, planes, box, lane, active):
    """The `active` rays of the packet that enter one box, given by its planes in the packet's
    row order (near x, y, z, far x, y, z; float32): the bit mask, by packet_node's slab test."""
    _check_array("packet_box", box, types.float32, 2)
    _check_array("packet_box", lane, types.float64, 2)

    def codegen(context, builder, sig, args):
        values = cgutils.unpack_tuple(builder, args[0], 6)
        bx = _array_data(context, builder, sig.args[1], args[1])
        ln = _array_data(context, builder, sig.args[2], args[2])
        act = _mask_vector(builder, context.cast(builder, args[3], sig.args[3], types.int64))
        near = [_load_row(builder, bx, k, _V8F) for k in range(3)]
        far = [_load_row(builder, bx, 3 + k, _V8F) for k in range(3)]
        inv = [_load_row(builder, bx, 6 + k, _V8F) for k in range(3)]
        tmax = builder.fptrunc(_load_row(builder, ln, BEST_T, _V8D), _V8F)
        lo = [_splat(builder, values[k], _V8F) for k in range(3)]
        hi = [_splat(builder, values[3 + k], _V8F) for k in range(3)]
        _, hit = slab_test(builder, lo, hi, near + far + inv, tmax)
        return _mask_bits(builder, builder.and_(hit, act))

    return types.int64(planes, box, lane, active), codegen


@inline_function
def root_box(G):
    """The box around the root's children (float32 lo x, y, z, hi x, y, z; empty lanes are
    +inf to -inf and leave it alone): a packet whose rays all miss it skips the root's eight
    child tests."""
    b = G.node_bounds
    x0, y0, z0 = b[0, 0, 0], b[0, 1, 0], b[0, 2, 0]
    x1, y1, z1 = b[0, 3, 0], b[0, 4, 0], b[0, 5, 0]
    for c in range(1, BVH_WIDTH):
        x0, y0, z0 = min(x0, b[0, 0, c]), min(y0, b[0, 1, c]), min(z0, b[0, 2, c])
        x1, y1, z1 = max(x1, b[0, 3, c]), max(y1, b[0, 4, c]), max(z1, b[0, 5, c])
    return (x0, y0, z0, x1, y1, z1)


@intrinsic
def packet_farthest(typingctx, lane, mask):
    """The farthest best hit so far (lane[BEST_T]) among the rays of `mask`."""
    _check_array("packet_farthest", lane, types.float64, 2)

    def codegen(context, builder, sig, args):
        ln = _array_data(context, builder, sig.args[0], args[0])
        m = _mask_vector(builder, context.cast(builder, args[1], sig.args[1], types.int64))
        best = _load_row(builder, ln, BEST_T, _V8D)
        return _reduce(builder, builder.select(m, best, ir.Constant(_V8D, [-math.inf] * PACKET)), select_max)

    return types.float64(lane, mask), codegen


# --- a leaf of triangles against the packet ----------------------------------------------------------


@intrinsic
def packet_triangles(typingctx, tri, row, count, first, axes, lane, prim, active):
    """Triangles row .. row + count - 1 of tri (float32 (T, 9)) against the `active` rays of the
    packet, one ray per float64 lane: shape_triangle.intersect_triangle's arithmetic operation
    for operation (IEEE, no FMA contraction), with the packet's shear axes `axes` (kx, ky, kz)
    and each lane's origin and shear constants. A hit nearer than a ray's best replaces it in
    lane[BEST_*] and prim (first + the triangle's place in the leaf): as the single-ray test,
    the first of equal hits is kept. Camera packets' leaves that seven or eight rays reach; shadow
    packets test every leaf ray by ray (packet_closest)."""
    _check_array("packet_triangles", tri, types.float32, 2)
    _check_array("packet_triangles", lane, types.float64, 2)
    _check_array("packet_triangles", prim, types.int64, 1)

    def codegen(context, builder, sig, args):
        t_data = _array_data(context, builder, sig.args[0], args[0])
        row0 = context.cast(builder, args[1], sig.args[1], types.int64)
        n = context.cast(builder, args[2], sig.args[2], types.int64)
        first = context.cast(builder, args[3], sig.args[3], types.int64)
        kx, ky, kz = (
            context.cast(builder, a, t, types.int64)
            for a, t in zip(cgutils.unpack_tuple(builder, args[4], 3), sig.args[4], strict=True)
        )
        ln = _array_data(context, builder, sig.args[5], args[5])
        pr = _array_data(context, builder, sig.args[6], args[6])
        act = _mask_vector(builder, context.cast(builder, args[7], sig.args[7], types.int64))
        _, fsub, _, _ = exact_ops(builder)
        ox, oy, oz = (_load_row(builder, ln, r, _V8D) for r in (OX, OY, OZ))
        sx, sy, sz = (_load_row(builder, ln, r, _V8D) for r in (SX, SY, SZ))
        tmin = _load_row(builder, ln, TMIN, _V8D)
        prim_ptr = builder.bitcast(pr, _V8I64.as_pointer())
        c3, c6 = ir.Constant(_i64, 3), ir.Constant(_i64, 6)
        cols = (kx, ky, kz, builder.add(kx, c3), builder.add(ky, c3), builder.add(kz, c3))
        cols += (builder.add(kx, c6), builder.add(ky, c6), builder.add(kz, c6))
        # The best hits are carried through the leaf in registers (stack slots that LLVM
        # promotes) and stored once after it, with plain stores. Stored back triangle by
        # triangle, each `store(select(ok, new, load(row)), row)` became a masked store
        # (vmaskmovpd) on AVX2, which AMD's Zen 3 runs microcoded at tens of cycles: the
        # packet traversal took 3-4x its time there (an AVX-512 machine's masked stores
        # are cheap, which is why it went unseen).
        rows = (BEST_T, BEST_V, BEST_W, BEST_DET)
        best_slots = {r: cgutils.alloca_once_value(builder, _load_row(builder, ln, r, _V8D)) for r in rows}
        prim_slot = cgutils.alloca_once_value(builder, builder.load(prim_ptr, align=8))
        with cgutils.for_range(builder, n) as loop:
            r = builder.add(row0, loop.index)
            base = builder.mul(r, ir.Constant(_i64, 9))

            def vertex(c):  # tri[r, c] as a float64 splat
                x = builder.load(builder.gep(t_data, [builder.add(base, c)], inbounds=True), align=4)
                return _splat(builder, builder.fpext(x, _f64), _V8D)

            ax, ay, az = fsub(vertex(cols[0]), ox), fsub(vertex(cols[1]), oy), fsub(vertex(cols[2]), oz)
            bx, by, bz = fsub(vertex(cols[3]), ox), fsub(vertex(cols[4]), oy), fsub(vertex(cols[5]), oz)
            cx, cy, cz = fsub(vertex(cols[6]), ox), fsub(vertex(cols[7]), oy), fsub(vertex(cols[8]), oz)
            _, v, w, det, num, inside = watertight_edges(builder, (ax, ay, az, bx, by, bz, cx, cy, cz), sx, sy)
            inside = builder.and_(inside, act)
            best = builder.load(best_slots[BEST_T])
            t, ok = watertight_distance(builder, num, det, inside, sz, tmin, best)
            for dest, value in ((BEST_T, t), (BEST_V, v), (BEST_W, w), (BEST_DET, det)):
                slot = best_slots[dest]
                builder.store(builder.select(ok, value, builder.load(slot)), slot)
            here = _splat(builder, builder.add(first, loop.index), _V8I64)
            builder.store(builder.select(ok, here, builder.load(prim_slot)), prim_slot)
        for r in rows:
            _store_row(builder, builder.load(best_slots[r]), ln, r, _V8D)
        builder.store(builder.load(prim_slot), prim_ptr, align=8)
        return context.get_dummy_value()

    return types.void(tri, row, count, first, axes, lane, prim, active), codegen


@intrinsic
def packet_triangles_each(typingctx, tri, row, count, first, axes, lane, prim, active):
    """Triangles row .. row + count - 1 (a block leaf, count <= 4) against each `active` ray of
    the packet in turn, four triangles per vector (shape_triangle.block_test, the single-ray
    block test's arithmetic): for a leaf that few of the packet's rays reach, the same results
    as packet_triangles, to the bit. The block's vertex columns are gathered once for all the
    rays, and each ray's origin is read in the shear's axis order (packet_shear's rows): ray by
    ray through intersect_triangles, each ray gathered the rows again and picked its origin's
    components by the axes. A hit keeps its barycentrics undivided (v, w and det, as
    packet_triangles keeps them), for packet_finish to divide once: divided at every hit, as the
    single-ray test does, their two scalar divisions were a wait in every leaf that found one
    (bumpy hit rays, `benchmarks/ab_queries.py`, pinned: 1M 4-5% and 4M 6% faster, 10M 3%, the
    bunny 3%, 40k the same; the same bits)."""
    _check_array("packet_triangles_each", tri, types.float32, 2)
    _check_array("packet_triangles_each", lane, types.float64, 2)
    _check_array("packet_triangles_each", prim, types.int64, 1)

    def codegen(context, builder, sig, args):
        table = context.make_array(sig.args[0])(context, builder, args[0])
        row0, n, first = (context.cast(builder, args[i], sig.args[i], types.int64) for i in (1, 2, 3))
        axes = [
            context.cast(builder, a, t, types.int64)
            for a, t in zip(cgutils.unpack_tuple(builder, args[4], 3), sig.args[4], strict=True)
        ]
        ln = _array_data(context, builder, sig.args[5], args[5])
        pr = _array_data(context, builder, sig.args[6], args[6])
        active = builder.and_(context.cast(builder, args[7], sig.args[7], types.int64), ir.Constant(_i64, 0xFF))
        cols = block_columns(builder, table, row0, n, axes)
        v4 = ir.VectorType(_f64, TRIANGLES_PER_TEST)
        with _each_ray(builder, active, "packet_triangles_each") as r:

            def value(k):
                return _load_lane(builder, ln, k, r)

            origin = [_splat(builder, value(k), v4) for k in (OX, OY, OZ)]
            sx, sy, sz = (_splat(builder, value(k), v4) for k in (SX, SY, SZ))
            best = value(BEST_T)
            t, j, v, w, det = block_test(builder, cols, origin, sx, sy, sz, value(TMIN), best, n, undivided=True)
            with builder.if_then(builder.fcmp_ordered("<", t, best, flags=EXACT)):
                for k, x in ((BEST_T, t), (BEST_V, v), (BEST_W, w), (BEST_DET, det)):
                    builder.store(x, _lane_pointer(builder, ln, k, r))
                builder.store(builder.add(first, j), builder.gep(pr, [r], inbounds=True))
        return context.get_dummy_value()

    return types.void(tri, row, count, first, axes, lane, prim, active), codegen


# --- setting a packet up --------------------------------------------------------------------------


@inline_function
def uses_packets(G, X):
    """Whether rays of a scene may be traced in packets: its root is no leaf (module
    docstring), and it has no instances (X: the kernels' variant, variants.features)."""
    if _root_is_a_leaf(G.node_index):
        return False
    if X is not None:  # (pruned in the basic variant, which has no instances)
        return X.inverse.shape[0] == 0
    return True


@inline_function
def scene_extent(G):
    """The largest side of the root node's children's boxes (what "close together" is measured
    against)."""
    b = G.node_bounds
    e = 0.0
    for c in range(BVH_WIDTH):
        if b[0, 0, c] <= b[0, 3, c]:  # not an empty lane
            for k in range(3):
                side = np.float64(b[0, 3 + k, c] - b[0, k, c])
                e = side if side > e else e  # not max(): its overload for these types compiles apart
    return e


@inline_function
def packet_setup(origins, directions, start, n, tmin, tmax, extent, box, lane, prim):
    """Load rays start .. start + n - 1 (n <= PACKET) into the packet's scratch, their unused
    lanes copies of the first. Returns (taken, rows, axes): how many of the rays, from the
    first, are traced as the packet (module docstring: n when they all can, else the leading
    ones that can when they are at least _MIN_TAKEN, else 0), the packet's near-plane rows and
    its shear axes. The lanes' shear constants wait for packet_shear: a packet that reaches no
    leaf (most misses) never needs them."""
    d0 = (float(directions[start, 0]), float(directions[start, 1]), float(directions[start, 2]))
    axes = shear_axes(d0)
    limit = _ORIGIN_SPREAD * extent
    # A run of rays can turn at any ray, not only at the eighth: compacted hit rays of a frame
    # start the next row, camera rays cross into another octant. The leading rays that agree
    # go as a smaller packet, loaded again so that the lanes after them are copies of the first
    # (bumpy 1M hit rays: 3.4% of their packets of eight refused; benchmarks/ab_queries.py,
    # pinned: bumpy 1M and 40k hit rays 3% faster, the bunny's shadow rays 1%; measured unpinned
    # in an earlier session as no change). One call site, in a loop: the intrinsic's code is large.
    count = n
    while True:
        taken = packet_load(origins, directions, start, count, axes[2], tmin, tmax, limit, box, lane, prim)
        if taken == count:
            break
        if taken < _MIN_TAKEN:
            taken = 0
            break
        count = taken
    # the first lane's near rows, as box_ray gives them: row k where its 1 / d (box row 6 + k,
    # never 0) is positive, else k + 3
    rows = (0 if box[6, 0] > 0.0 else 3, 1 if box[7, 0] > 0.0 else 4, 2 if box[8, 0] > 0.0 else 5)
    return taken, rows, axes


@intrinsic
def packet_load(typingctx, origins, directions, start, n, kz0, tmin, tmax, limit, box, lane, prim):
    """packet_setup's work on the eight lanes at once (SIMD: the scalar loop over the lanes,
    with box_ray's three divisions a ray, cost 12 ns a ray, as much as a miss's traversal).
    Writes each lane's box_ray constants (wide_nodes.ray_axis_ir, the single ray's IR, so each
    ray's boxes are the single-ray traversal's), its ray, bounds and empty best hit, and marks
    the shear pending; returns how many of the first n lanes, from the first, are finite, in the
    first lane's octant, with dominant axis kz0, within 10 degrees of its direction and `limit`
    of its origin (n when all are)."""
    for name, a in (("origins", origins), ("directions", directions)):
        if not (isinstance(a, types.Array) and a.dtype == types.float64 and a.ndim == 2):
            raise TypingError(f"packet_load: {name} must be a float64 (N, 3) array")
    _check_array("packet_load", box, types.float32, 2)
    _check_array("packet_load", lane, types.float64, 2)
    _check_array("packet_load", prim, types.int64, 1)

    def codegen(context, builder, sig, args):
        arrays = [context.make_array(sig.args[i])(context, builder, args[i]) for i in (0, 1)]
        first, count, kz_first = (context.cast(builder, args[i], sig.args[i], types.int64) for i in (2, 3, 4))
        t_min, t_max, spread_limit = (context.cast(builder, args[i], sig.args[i], types.float64) for i in (5, 6, 7))
        bx = _array_data(context, builder, sig.args[8], args[8])
        ln = _array_data(context, builder, sig.args[9], args[9])
        pr = _array_data(context, builder, sig.args[10], args[10])
        undef = ir.Constant(_V8D, ir.Undefined)
        # lane i holds ray start + i, or the first ray where i >= n
        rays = [
            builder.select(
                builder.icmp_signed("<", ir.Constant(_i64, i), count), builder.add(first, ir.Constant(_i64, i)), first
            )
            for i in range(PACKET)
        ]

        def gather(array, c):  # column c of the lanes' rays, as a vector
            base = builder.ptrtoint(array.data, _i64)
            s0, s1 = (builder.extract_value(array.strides, k) for k in (0, 1))
            v = undef
            for i, k in enumerate(rays):
                at = builder.add(base, builder.add(builder.mul(k, s0), builder.mul(ir.Constant(_i64, c), s1)))
                x = builder.load(builder.inttoptr(at, _f64.as_pointer()), align=8)
                v = builder.insert_element(v, x, ir.Constant(_i32, i))
            return v

        O = [gather(arrays[0], c) for c in range(3)]
        D = [gather(arrays[1], c) for c in range(3)]
        zeros = ir.Constant(ir.VectorType(_i32, PACKET), [0] * PACKET)

        def first_lane(v):  # lane 0 in every lane
            return builder.shuffle_vector(v, ir.Constant(v.type, ir.Undefined), zeros)

        abs_fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V8D, [_V8D]), "llvm.fabs.v8f64")

        def vabs(v):
            return builder.call(abs_fn, [v])

        def const(x):
            return ir.Constant(_V8D, [x] * PACKET)

        ok = ir.Constant(ir.VectorType(_i1, PACKET), [1] * PACKET)
        for c in range(3):  # traverse.traceable
            ok = builder.and_(ok, builder.fcmp_ordered("<", vabs(O[c]), const(_F32_MAX)))
            ok = builder.and_(ok, builder.fcmp_ordered("<", vabs(D[c]), const(math.inf)))
        for c in range(3):  # box_ray's constants, lane by lane: the same IR as the single ray's
            near, far, inv32, positive = ray_axis_ir(builder, O[c], D[c])
            _store_row(builder, near, bx, c, _V8F)
            _store_row(builder, far, bx, 3 + c, _V8F)
            _store_row(builder, inv32, bx, 6 + c, _V8F)
            ok = builder.and_(ok, builder.icmp_unsigned("==", positive, first_lane(positive)))  # one octant
        # shape_triangle.shear_axes' dominant axis
        ax, ay, az = (vabs(v) for v in D)
        is_y = builder.and_(builder.fcmp_ordered(">", ay, ax), builder.fcmp_ordered(">=", ay, az))
        is_z = builder.and_(builder.fcmp_ordered(">", az, ax), builder.fcmp_ordered(">", az, ay))
        kz = builder.select(
            is_y,
            ir.Constant(_V8I64, [1] * PACKET),
            builder.select(is_z, ir.Constant(_V8I64, [2] * PACKET), ir.Constant(_V8I64, [0] * PACKET)),
        )
        ok = builder.and_(ok, builder.icmp_signed("==", kz, _splat(builder, kz_first, _V8I64)))
        # within 10 degrees of the first ray's direction, compared squared (dd >= 0)
        D0 = [first_lane(v) for v in D]
        dd = builder.fadd(builder.fadd(builder.fmul(D[0], D0[0]), builder.fmul(D[1], D0[1])), builder.fmul(D[2], D0[2]))
        nn = builder.fadd(builder.fadd(builder.fmul(D[0], D[0]), builder.fmul(D[1], D[1])), builder.fmul(D[2], D[2]))
        nn0 = builder.fmul(first_lane(nn), const(_MIN_COS * _MIN_COS))
        ok = builder.and_(ok, builder.fcmp_ordered(">=", dd, const(0.0)))
        ok = builder.and_(ok, builder.fcmp_ordered(">=", builder.fmul(dd, dd), builder.fmul(nn, nn0)))
        # origins within the limit of the first's
        for c in range(3):
            gap = vabs(builder.fsub(O[c], first_lane(O[c])))
            ok = builder.and_(ok, builder.fcmp_ordered("<=", gap, _splat(builder, spread_limit, _V8D)))
        for r, value in ((TMIN, t_min), (BEST_T, t_max), (BEST_V, 0.0), (BEST_W, 0.0), (BEST_DET, 1.0)):
            v = _splat(builder, value, _V8D) if isinstance(value, ir.Value) else const(value)
            _store_row(builder, v, ln, r, _V8D)
        vi = ir.VectorType(_i32, PACKET)
        for r in range(PACKET):  # packet_node's table of the rays' bits
            at = _row_pointer(builder, bx, ir.Constant(_i64, BOX_BITS + r), vi)
            builder.store(ir.Constant(vi, [1 << r] * PACKET), at, align=4)
        for c in range(3):
            _store_row(builder, O[c], ln, RAY_O + c, _V8D)
            _store_row(builder, D[c], ln, RAY_D + c, _V8D)
        builder.store(ir.Constant(_V8I64, [NO_HIT] * PACKET), builder.bitcast(pr, _V8I64.as_pointer()), align=8)
        # the shear pending (1 / d[kz] is never 0)
        builder.store(ir.Constant(_f64, 0.0), builder.gep(ln, [ir.Constant(_i64, SZ * PACKET)], inbounds=True))
        # the leading lanes that pass: the lowest failing lane's number (8 when none fails), at
        # most n (the lanes from n on are copies of the first: they pass where it does)
        failing = builder.or_(
            builder.zext(builder.not_(builder.bitcast(ok, ir.IntType(PACKET))), _i64), ir.Constant(_i64, 1 << PACKET)
        )
        passing = trailing_zeros(builder, failing)
        return builder.select(builder.icmp_signed("<", passing, count), passing, count)

    sig = types.int64(origins, directions, start, n, kz0, tmin, tmax, limit, box, lane, prim)
    return sig, codegen


@inline_function
def packet_shear(lane, axes):
    """The lanes' origins along the shear axes and shear constants (shape_triangle.ray_shear),
    from their rays, once per packet: before its first leaf or plane."""
    if lane[SZ, 0] != 0.0:
        return
    _packet_shear_lanes(lane, axes)


@intrinsic
def _packet_shear_lanes(typingctx, lane, axes):
    """packet_shear's work on the eight lanes at once: ray_shear's constants with the packet's
    axes (every lane's own: packet_load checked one octant and one dominant axis), its division
    and products operation for operation. As a scalar loop over the lanes, with each lane's
    axes found again, it cost ~100 instructions a lane (bumpy 1M hit rays: 7% of them)."""
    _check_array("_packet_shear_lanes", lane, types.float64, 2)

    def codegen(context, builder, sig, args):
        ln = _array_data(context, builder, sig.args[0], args[0])
        kx, ky, kz = (
            context.cast(builder, a, t, types.int64)
            for a, t in zip(cgutils.unpack_tuple(builder, args[1], 3), sig.args[1], strict=True)
        )
        _, _, fmul, _ = exact_ops(builder)

        def row(first, k):  # row first + k (k an i64 at run time)
            return _row_pointer(builder, ln, builder.add(ir.Constant(_i64, first), k), _V8D)

        dx, dy, dz = (builder.load(row(RAY_D, k), align=8) for k in (kx, ky, kz))
        sz = builder.fdiv(ir.Constant(_V8D, [1.0] * PACKET), dz, flags=EXACT_DIVISION)
        for r, value in ((SX, fmul(dx, sz)), (SY, fmul(dy, sz)), (SZ, sz)):
            _store_row(builder, value, ln, r, _V8D)
        for r, k in ((OX, kx), (OY, ky), (OZ, kz)):
            _store_row(builder, builder.load(row(RAY_O, k), align=8), ln, r, _V8D)
        return context.get_dummy_value()

    return types.void(lane, axes), codegen


@intrinsic
def packet_finish(typingctx, lane, prim):
    """Each lane's barycentrics from its best hit's (v, w, det): v / det and w / det clamped to
    [0, 1], into lane[BEST_V], lane[BEST_W] (0 for a miss), det 1. IEEE divisions, as the
    single-ray block test divides: the kernels' fast-math flags would turn them into
    multiplications by a reciprocal, an ulp off."""
    _check_array("packet_finish", lane, types.float64, 2)
    _check_array("packet_finish", prim, types.int64, 1)

    def codegen(context, builder, sig, args):
        ln = _array_data(context, builder, sig.args[0], args[0])
        pr = _array_data(context, builder, sig.args[1], args[1])
        _, _, _, lt = exact_ops(builder)
        found = builder.icmp_signed(
            "!=",
            builder.load(builder.bitcast(pr, _V8I64.as_pointer()), align=8),
            ir.Constant(_V8I64, [NO_HIT] * PACKET),
        )
        det = _load_row(builder, ln, BEST_DET, _V8D)
        zero, one = ir.Constant(_V8D, [0.0] * PACKET), ir.Constant(_V8D, [1.0] * PACKET)
        for r in (BEST_V, BEST_W):
            q = builder.fdiv(_load_row(builder, ln, r, _V8D), det, flags=EXACT_DIVISION)
            q = builder.select(builder.fcmp_ordered(">", q, zero, flags=EXACT), q, zero)
            q = builder.select(lt(q, one), q, one)
            _store_row(builder, builder.select(found, q, zero), ln, r, _V8D)
        _store_row(builder, one, ln, BEST_DET, _V8D)
        return context.get_dummy_value()

    return types.void(lane, prim), codegen


@inline_function
def packet_hit(lane, prim, i):
    """Lane i's result after packet_closest: (t, primitive, b1, b2), as closest_hit returns them."""
    return lane[BEST_T, i], prim[i], lane[BEST_V, i], lane[BEST_W, i]


# --- traversal ------------------------------------------------------------------------------------


@inline_function
def _lane_ray(lane, axes, i):
    """Lane i's ray as the single-ray functions take it: (o, d, shear)."""
    o = (lane[RAY_O, i], lane[RAY_O + 1, i], lane[RAY_O + 2, i])
    d = (lane[RAY_D, i], lane[RAY_D + 1, i], lane[RAY_D + 2, i])
    return o, d, (axes[0], axes[1], axes[2], lane[SX, i], lane[SY, i], lane[SZ, i])


@inline_function
def _set_lane_best(lane, prim, i, t, p, b1, b2):
    """Lane i's best hit from a single-ray function: its barycentrics kept with det 1, which
    packet_finish divides back exactly."""
    lane[BEST_T, i] = t
    lane[BEST_V, i] = b1
    lane[BEST_W, i] = b2
    lane[BEST_DET, i] = 1.0
    prim[i] = p


@inline_function
def _leaf_ray_by_ray(G, X, first, count, axes, lane, prim, active):
    """A leaf that is not a block of triangles, tested for each active ray with the single-ray
    leaf test. The lane's (v, w) stand for the barycentrics it carries (handed back unchanged
    when the ray finds nothing nearer)."""
    m = active
    while m != 0:
        i = lowest_bit(m)
        m &= m - 1
        o, d, shear = _lane_ray(lane, axes, i)
        t0, p0 = lane[BEST_T, i], prim[i]
        t, p, b1, b2 = intersect_leaf(
            G, X, first, count, o, d, shear, lane[TMIN, i], t0, p0, lane[BEST_V, i], lane[BEST_W, i], False
        )
        if p != p0 or t != t0:
            _set_lane_best(lane, prim, i, t, p, b1, b2)


@inline_function
def packet_unbounded(G, X, axes, lane, prim, n):
    """The unbounded shapes (planes, after the BVH's primitives in the table) against lanes
    0 .. n - 1 ray by ray, before the traversal, as closest_hit tests them first; their hits
    become the lanes' best."""
    packet_shear(lane, axes)
    for i in range(n):
        o, d, shear = _lane_ray(lane, axes, i)
        t, p, b1, b2 = _unbounded_hit(G, X, o, d, shear, lane[TMIN, i], lane[BEST_T, i])
        if p != NO_HIT:
            _set_lane_best(lane, prim, i, t, p, b1, b2)


@inline_function
def span_of(values, k):
    """Ray k's tmin or tmax: values[k], or values[0] where one value (an array of one) serves
    every ray."""
    return values[k] if values.shape[0] > 1 else values[0]


@inline_function
def packet_trace(G, X, root, origins, directions, start, n, extent, packets, node_stack, t_stack, spans):
    """Rays start .. start + n - 1 as one packet, when they are coherent (packet_setup): their
    nearest hits into the packet's lanes (read them with packet_hit), the unbounded shapes
    first, ray by ray, as closest_hit tests them. extent: scene_extent(G), root: root_box(G),
    packets: packet_scratch(); spans: None (each ray from 0 to infinity) or (tmin, tmax, k):
    arrays of one value for every ray or of one per ray, ray k the packet's first (a lane
    without a hit keeps its tmax as its t). Returns how many of the rays, from the first, were
    traced (packet_setup's `taken`: n, fewer, or 0); the caller traces the others."""
    box, lane, prim, mask_stack = packets
    t0, t1 = 0.0, math.inf
    if spans is not None:  # (pruned in the renders)
        t0, t1 = spans[0][0], spans[1][0]
    taken, rows, axes = packet_setup(origins, directions, start, n, t0, t1, extent, box, lane, prim)
    if taken > 0:
        if spans is not None:
            tmin, tmax, k = spans
            if tmin.shape[0] > 1 or tmax.shape[0] > 1:  # one per ray: the lanes' own (else set above)
                for i in range(taken):
                    lane[TMIN, i] = span_of(tmin, k + i)
                    lane[BEST_T, i] = span_of(tmax, k + i)
        if X is not None:  # (pruned in the basic variant, which has no unbounded shapes)
            if G.n_bounded < G.prims.shape[0]:
                packet_unbounded(G, X, axes, lane, prim, taken)
        active = (1 << taken) - 1
        packet_closest(G, X, root, rows, axes, active, box, lane, prim, node_stack, t_stack, mask_stack, None)
    return taken


@inline_function
def packet_blocked(
    G, X, root, origins, directions, tmin, tmax, k, start, n, need, extent, packets, node_stack, t_stack
):
    """Shadow rays start .. start + n - 1, lane i's ending at span_of(tmax, k + i) and starting
    at span_of(tmin, k + i) (tmin None: at 0), as one packet when they are coherent
    (packet_setup, origins up to _SHADOW_ORIGIN_SPREAD of the extent apart): only the lanes of
    the mask `need` are traced. Returns (taken, the mask of the lanes that something blocks in
    (tmin, tmax)): how many of the rays, from the first, the packet took (packet_setup; the
    caller traces the others), and any_hit's answers for those, found by the closest-hit
    traversal with each lane's best hit starting at its tmax (a hit nearer than tmax is one
    any_hit finds)."""
    box, lane, prim, mask_stack = packets
    spread = extent * (_SHADOW_ORIGIN_SPREAD / _ORIGIN_SPREAD)
    taken, rows, axes = packet_setup(origins, directions, start, n, 0.0, math.inf, spread, box, lane, prim)
    if taken == 0:
        return 0, 0
    for i in range(taken):
        lane[BEST_T, i] = span_of(tmax, k + i)
    if tmin is not None:  # (pruned where the rays start at 0: the wavefront's)
        for i in range(taken):
            lane[TMIN, i] = span_of(tmin, k + i)
    if X is not None:  # (pruned in the basic variant, which has no unbounded shapes)
        if G.n_bounded < G.prims.shape[0]:
            packet_unbounded(G, X, axes, lane, prim, taken)
    active = need & ((1 << taken) - 1)
    packet_closest(G, X, root, rows, axes, active, box, lane, prim, node_stack, t_stack, mask_stack, True)
    blocked = 0
    for i in range(taken):
        if (active >> i) & 1 and prim[i] != NO_HIT:
            blocked |= 1 << i
    return taken, blocked


@inline_function
def packet_closest(G, X, root, rows, axes, active, box, lane, prim, node_stack, t_stack, mask_stack, shadows):
    """The nearest hit of each active ray of the packet (set up by packet_setup) through the
    BVH, into lane[BEST_*] and prim (read them with packet_hit); root: root_box(G). Stack entries are
    traverse.py's, each with the mask of the rays that entered it, and the nearest of their entry
    distances: an entry is skipped when even that lies beyond the farthest best hit of its rays.
    shadows: None for camera rays, True for shadow rays (pruned at compile time): those test
    every leaf ray by ray, and a ray leaves the packet at the first hit it finds (its lane
    then holds a blocker, not necessarily the nearest): its bit is taken out of every entry
    popped after, and the traversal ends when every ray is blocked. Letting blocked rays run on
    until their best hits culled the rest had cost the bunny's, Nefertiti's and bumpy 1M's
    shadow rays 2-3% (benchmarks/ab_queries.py, pinned; bumpy 40k 1%)."""
    index = G.node_index
    bounds = G.node_bounds
    tri = G.triangles
    P = G.prims
    # Where a leaf's first triangle row is its first primitive (traverse.rows_in_leaf_order),
    # known before the primitive table is read, its triangles are prefetched as it is pushed
    # (bumpy 4M hit rays 5-12% faster; the primitive table's row is itself a cache miss there)
    direct_rows = rows_in_leaf_order(G)
    ref = 0
    # the root's box first (root: root_box(G)): most packets of a loosely framed frame miss it
    planes = (root[rows[0]], root[rows[1]], root[rows[2]], root[3 - rows[0]], root[5 - rows[1]], root[7 - rows[2]])
    mask = packet_box(planes, box, lane, active)
    top = 0
    blocked = 0  # shadow rays that have found a hit
    # A shadow ray's best hit stays its tmax until it is blocked and leaves: its entries are
    # culled against the packet's farthest tmax, found once, instead of a reduction over each
    # popped entry's rays (the bunny's shadow rays 1.5% faster, bumpy 40k's 1%)
    reach = packet_farthest(lane, active) if shadows is not None else 0.0
    while mask != 0:
        if ref >= 0:
            prefetch_child_rows(index, ref)
            # A shadow packet whose eight rays all enter the node tests its children across
            # the rays (packet_node_full): coherent shadow rays keep full packets deep into the
            # tree (benchmarks/ab_queries.py, pinned: shadow rays on the bunny 4.9% faster,
            # Nefertiti, bumpy 40k 3.6%, 4M 2.8%, 1M 1.1%). Camera packets gained 2-3% on the
            # scans and 40k but lost 1.4% at 4M, and keep packet_node.
            full = False
            if shadows is not None:  # (pruned at compile time for camera rays)
                full = mask == 0xFF
            if full:
                masks = packet_node_full(bounds, ref, box, rows, lane, t_stack, top)
            else:
                masks = packet_node(bounds, ref, box, rows, lane, mask, t_stack, top)
            k = 0
            # the nearest child stays in registers, visited next (push_children says why)
            nearest, nearest_t, nearest_mask = np.int32(0), np.float32(0.0), mask  # set by the first child
            # the lowest bit of each byte of `masks` set where that child has a ray: the loop
            # visits those children alone, in lane order
            some = masks | (masks >> 4)
            some |= some >> 2
            some |= some >> 1
            some &= 0x0101010101010101
            while some != 0:
                b = lowest_bit(some)
                some &= some - 1
                c = b >> 3
                m = (masks >> b) & 0xFF
                u = np.uint64(c)
                t = t_stack[np.uint64(top + c)]
                child = index[np.uint64(ref), NODE_REF, u]
                if child >= 0:  # an inner node
                    prefetch_child(bounds, child)
                else:  # a leaf
                    f0 = leaf_first(child)
                    if direct_rows:  # the leaf's triangles themselves, four rows
                        for r in range(4):
                            prefetch_row(tri, f0 + r)
                    else:
                        prefetch_row(P, f0)
                # sorted insertion of all but the nearest, the next nearest on top; slots top + c'
                # >= top + k are still unread entry distances of lanes after c, so the shift
                # stays below them
                if k == 0:
                    nearest, nearest_t, nearest_mask = child, t, m
                elif t <= nearest_t:  # the new nearest; the old one, nearer than all pushed, on top
                    t_stack[np.uint64(top + k - 1)] = nearest_t
                    node_stack[np.uint64(top + k - 1)] = nearest
                    mask_stack[np.uint64(top + k - 1)] = nearest_mask
                    nearest, nearest_t, nearest_mask = child, t, m
                else:
                    j = top + k - 1
                    while j > top and t_stack[np.uint64(j - 1)] < t:
                        t_stack[np.uint64(j)] = t_stack[np.uint64(j - 1)]
                        node_stack[np.uint64(j)] = node_stack[np.uint64(j - 1)]
                        mask_stack[np.uint64(j)] = mask_stack[np.uint64(j - 1)]
                        j -= 1
                    t_stack[np.uint64(j)] = t
                    node_stack[np.uint64(j)] = child
                    mask_stack[np.uint64(j)] = m
                k += 1
            if k > 0:
                top += k - 1
                ref = nearest
                mask = nearest_mask
                continue
        else:
            packet_shear(lane, axes)
            first = leaf_first(ref)
            count = leaf_count(ref)
            if -SPHERE_BLOCK <= count < 0:  # a block of triangles in consecutive rows
                row = block_row(G, first)
                if direct_rows:
                    prefetch_neighbours(tri, row, row - count)
                # A leaf that one to six rays reach is tested ray by ray, four triangles per
                # vector: the packet test computes all eight lanes in float64 (two ymm
                # registers on AVX2 and Intel's AVX-512 cores) however few are active. On a
                # mesh with several triangles under each pixel most leaves are reached by one
                # ray (bumpy 1M hit rays on a Zen 3: 91 -> 77 ms, 4M 149 -> 106; the same hits). Up to three rays until
                # a few-ray hit kept its barycentrics undivided; since, six (benchmarks/
                # ab_queries.py, pinned: hit rays 40k, 1M and the bunny 2-3% faster, 4M the
                # same; the bunny's shadow rays 2.5%, Nefertiti's and 4M's within 1%).
                # Shadow packets test every leaf ray by ray: their blocked rays leave (below),
                # and few of them reach a hit, which the block test's division waits for
                # (against the eight-lane test from seven rays on, with its division skipped
                # behind the origin: the bunny's, bumpy 40k's and 4M's shadow rays 1-2% faster,
                # Nefertiti's and 1M's within 1%).
                missing = ~mask & 0xFF  # the packet's lanes this leaf's entry does not have
                if shadows is not None or missing & (missing - 1) != 0:  # at most six rays
                    packet_triangles_each(tri, row, -count, first, axes, lane, prim, mask)
                else:
                    packet_triangles(tri, row, -count, first, axes, lane, prim, mask)
            else:
                if direct_rows:  # one triangle
                    prefetch_neighbours(tri, first, first + count)
                _leaf_ray_by_ray(G, X, first, count, axes, lane, prim, mask)
            if shadows is not None:
                left = mask
                while left != 0:
                    i = lowest_bit(left)
                    left &= left - 1
                    if prim[i] != NO_HIT:
                        blocked |= 1 << i
                if active & ~blocked == 0:
                    break
        found = False
        while top > 0:
            top -= 1
            m = mask_stack[np.uint64(top)] & ~blocked
            if shadows is not None:
                further = m != 0 and t_stack[np.uint64(top)] < reach
            else:
                further = t_stack[np.uint64(top)] < packet_farthest(lane, m)
            if further:
                found = True
                ref = node_stack[np.uint64(top)]
                mask = m
                break
        if not found:
            break
    packet_finish(lane, prim)
