"""A wide BVH node as traversal meets it: the per-thread stacks and scratch, the test of a ray
against all BVH_WIDTH child boxes of a node at once (explicit LLVM vector code), prefetching,
and the stack of nodes to visit (sorted entry distances). Shared by the traversal of one level
(traverse.py) and of instances (traverse_instances.py).

Stack entries are lanes' references (layout.py): an inner node's index (>= 0), or a leaf's
first primitive and count field in one negative int32 (leaf_first, leaf_count).
"""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import inline_function, kernel_function
from . import layout
from .layout import NODE_REF, NODE_ROWS

INF = math.inf

# Children per BVH node. 8 fills one AVX2 register (8 float32 lanes); measured against 4 with
# benchmarks/bench_bvh.py and path mode (docs/architecture.md).
BVH_WIDTH = 8

# A leaf reference's (stack entry's) first primitive and count field (layout.py)
leaf_first = inline_function(layout.leaf_first)
leaf_count = inline_function(layout.leaf_count)

# Size of per-thread traversal stacks. Closest-hit pushes at most BVH_WIDTH - 1 entries per
# level and writes a node's BVH_WIDTH entry distances above the top; compile/geometry.py rejects BVHs
# too deep for it (stack_needed).
TRAVERSAL_STACK = 1024
# Unused elements on either side of each thread's scratch arrays (at least 256 bytes: beyond a
# cache line and its prefetched neighbour). Small arrays allocated by two threads can lie back
# to back: without the gap one thread's stack ended in the cache line where another's began,
# and their writes fought over it (false sharing: the seed scene took 85 instead of 45 ms on
# 2 threads).
SCRATCH_PAD = 1024

_F32_MAX = float(np.finfo(np.float32).max)
_F32_TINY = float(np.finfo(np.float32).tiny)
# The box test takes each plane's distance as one multiply-add, plane * (1/d) + (-o/d), the
# offset -o/d rounded outward once per ray (box_ray, ray_axis_ir): against the exact
# (plane - o) / d, the result is off by the rounding of 1/d and of the multiply-add (relative),
# never by the offset's, which lies on the safe side. The slab interval is widened by a relative
# 2**-20 (the exit here, the entry where it is stored), which covers those roundings on both
# sides, so a box that the exact ray enters is never culled and its entry distance never
# overestimated (a popped entry is skipped when it lies beyond the best hit).
_NEAR_SCALE = 1.0 - 2.0**-20
_FAR_SCALE = 1.0 + 2.0**-20
_OFFSET_MARGIN = 2.0**-22  # the offset moved outward by so much of itself, then rounded to float32
# 1/d is clamped at _INV_MAX, and below 2**126 / |o| so that the offset stays a finite float32;
# the origin moves outward by at least _ORIGIN_PAD: a slab that a ray parallel to it lies in
# then spans at least 2**-72 * 2**100 = 2**28 (2.7e8) on either side of its origin.
_INV_MAX = 2.0**100
_OFFSET_MAX = 2.0**126
_ORIGIN_PAD = 2.0**-72
_LINE = 64  # bytes in a cache line
# prefetch_neighbours: lines on either side of a leaf's triangle rows, and the triangle count
# from which they are prefetched. 8 since a Zen 4 VM (benchmarks/ab_queries.py, pinned, against
# 4: hit rays 1M 1.018, 4M 1.021-1.024, 10M 1.039, shadow rays 4M 1.015; 12 gained less); on
# the Zen 3 before, 8 had gained no more than 4
NEIGHBOUR_LINES = 8
NEIGHBOURS_FROM = 1 << 18
# prefetch_child: the node count from which a pushed inner child's record is prefetched (2^15:
# bumpy 1M's 50k nodes take it since benchmarks/ab_queries.py measured it there, pinned: hit
# rays 1.1% and shadow rays 1.8% faster; at 2^17 it had been left out as slower there, measured
# in fresh processes alternating)
CHILDREN_PREFETCHED_FROM = 1 << 15


def stack_needed(depth: int) -> int:
    """Traversal stack entries a wide BVH of `depth` levels can need."""
    return (BVH_WIDTH - 1) * depth + BVH_WIDTH + 1


@kernel_function(_nrt=True)
def traversal_stacks():
    """One thread's (node_stack, t_stack) for closest_hit and any_hit."""
    # Entry distances as the box test computes them, float32: exactly the values (and order) a
    # float64 stack held, in half the memory (bumpy 1M hit rays: ~4% less time).
    return scratch_array(TRAVERSAL_STACK, np.int32), scratch_array(TRAVERSAL_STACK, np.float32)


@kernel_function(_nrt=True)
def scratch_array(n, dtype):
    """An array of n elements for one thread's scratch, with SCRATCH_PAD unused elements on
    either side against false sharing."""
    return np.empty(n + 2 * SCRATCH_PAD, dtype=dtype)[SCRATCH_PAD : SCRATCH_PAD + n]


# --- the wide box test ------------------------------------------------------------------------


def select_max(builder, a, b, flags=()):
    """The larger of a and b (floats or float vectors), as a compare and a select: b where
    either is NaN."""
    return builder.select(builder.fcmp_ordered(">", a, b, flags=flags), a, b)


def select_min(builder, a, b, flags=()):
    """The smaller of a and b, as select_max: b where either is NaN."""
    return builder.select(builder.fcmp_ordered("<", a, b, flags=flags), a, b)


def ray_axis_ir(builder, o, d):
    """One axis of box_ray's constants from the ray's float64 origin and direction component
    (scalars, or vectors of a packet's lanes): (near offset, far offset, 1/d as float32, whether
    1/d >= 0). In IR with explicit flags, for single rays (_ray_axis) and packets
    (packet.packet_load) alike, so that both get the same bits. The origin is rounded to
    float32 outward, so that the near distance can only shrink and the far one only grow: moved
    by |o| 2**-23 >= half a float32 ulp first, then rounded to nearest; and by at least
    _ORIGIN_PAD: for a ray parallel to a slab (1/d clamped), an origin 1.8e-38 inside a face at 0
    once put the slab's far end at 6.2, and the box was culled for the entry at 8 that the other
    axes gave (hypothesis found it). 1/d is clamped to [float32 tiny, _INV_MAX] in magnitude and
    so that the offsets stay below _OFFSET_MAX: a zero component gives parallel slabs, and no
    lane ever computes inf * 0 (an empty lane's box is +-inf)."""
    f64 = o.type
    vector = isinstance(f64, ir.VectorType)
    f32 = ir.VectorType(ir.FloatType(), f64.count) if vector else ir.FloatType()
    flags, division = ("arcp",), ("nsz",)  # shape_triangle.EXACT, EXACT_DIVISION

    def const(x):
        return ir.Constant(f64, [x] * f64.count) if vector else ir.Constant(f64, x)

    fabs = cgutils.get_or_insert_function(
        builder.module, ir.FunctionType(f64, [f64]), f"llvm.fabs.v{f64.count}f64" if vector else "llvm.fabs.f64"
    )

    def vabs(x):
        return builder.call(fabs, [x])

    def larger(a, b):
        return select_max(builder, a, b, flags)

    def offset(origin32, inv32, outward):
        # -origin * inv moved outward (down for a near plane, outward < 0): the product of two
        # float32 is exact in float64; moved by _OFFSET_MARGIN of itself and rounded to float32
        # once, it lies at least 2**-23 of itself on its side
        p = builder.fmul(builder.fpext(origin32, f64), builder.fpext(inv32, f64), flags=flags)
        margin = builder.fmul(vabs(p), const(_OFFSET_MARGIN), flags=flags)
        move = builder.fsub if outward < 0 else builder.fadd
        return builder.fptrunc(move(builder.fneg(p), margin, flags=flags), f32)

    pad = larger(builder.fmul(vabs(o), const(2.0**-23), flags=flags), const(_ORIGIN_PAD))
    down = builder.fptrunc(builder.fsub(o, pad, flags=flags), f32)
    up = builder.fptrunc(builder.fadd(o, pad, flags=flags), f32)
    inv = builder.select(
        builder.fcmp_unordered("!=", d, const(0.0), flags=flags),
        builder.fdiv(const(1.0), d, flags=division),
        const(_INV_MAX),
    )
    reach = larger(vabs(builder.fpext(down, f64)), vabs(builder.fpext(up, f64)))
    limit = builder.select(
        builder.fcmp_ordered(">", builder.fmul(reach, const(_INV_MAX), flags=flags), const(_OFFSET_MAX), flags=flags),
        builder.fdiv(const(_OFFSET_MAX), reach, flags=division),
        const(_INV_MAX),
    )
    mag = select_min(builder, larger(vabs(inv), const(_F32_TINY)), limit, flags)
    positive = builder.fcmp_ordered(">=", inv, const(0.0), flags=flags)
    inv32 = builder.fptrunc(builder.select(positive, mag, builder.fneg(mag)), f32)
    near = offset(builder.select(positive, up, down), inv32, -1)
    far = offset(builder.select(positive, down, up), inv32, 1)
    return near, far, inv32, positive


@intrinsic
def _axis_constants(typingctx, o, d):
    """ray_axis_ir for one axis of one ray: (near offset, far offset, 1/d, 1/d >= 0)."""
    sig = types.Tuple((types.float32, types.float32, types.float32, types.boolean))(types.float64, types.float64)

    def codegen(context, builder, sig, args):
        return context.make_tuple(builder, sig.return_type, ray_axis_ir(builder, *args))

    return sig, codegen


def _fma_ir(builder, a, b, c):
    """a * b + c on float vectors, rounded once (llvm.fma: a vfmadd where the CPU has FMA)."""
    name = f"llvm.fma.v{a.type.count}f32"
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(a.type, [a.type] * 3), name)
    return builder.call(fn, [a, b, c])


def slab_test(builder, near, far, rf, tmax):
    """The widened slab test on float32 vectors, one lane per box or per ray: (entry distance,
    unscaled: multiply by _NEAR_SCALE for a lower bound; i1 vector of the lanes entered). near,
    far: the boxes' near and far planes per axis (box_ray's rows); rf: box_ray's nine
    constants (near offsets, far offsets, 1/d) as vectors; tmax: the rays' best hits. Shared by
    box_hits and the packets' packet_node, so a ray enters the same boxes either way."""
    vt = tmax.type

    def vmax(a, b):
        return select_max(builder, a, b)

    def vmin(a, b):
        return select_min(builder, a, b)

    tn = [_fma_ir(builder, near[k], rf[6 + k], rf[k]) for k in range(3)]
    tf = [_fma_ir(builder, far[k], rf[6 + k], rf[3 + k]) for k in range(3)]
    # Widened by the relative factor and by the smallest normal float32: a result in the
    # subnormal range rounds by a fixed step, which no relative factor covers (hypothesis found
    # an entry distance of 2.24e-45 computed as 2.8e-45). The entry is then clamped at 0, so an
    # origin inside the box enters at 0 exactly.
    tiny = ir.Constant(vt, [_F32_TINY] * vt.count)
    tnear = builder.fsub(vmax(vmax(tn[0], tn[1]), tn[2]), tiny)
    tnear = vmax(tnear, ir.Constant(vt, [0.0] * vt.count))
    tfar = vmin(vmin(tf[0], tf[1]), vmin(tf[2], tmax))
    tfar = builder.fadd(builder.fmul(tfar, ir.Constant(vt, [_FAR_SCALE] * vt.count)), tiny)
    return tnear, builder.fcmp_ordered("<=", tnear, tfar)


def node_planes(builder, data, node, rows, width=BVH_WIDTH):
    """The near and far plane rows of wide node `node` (an i64) for a ray or packet whose near
    rows are `rows` (box_ray's, i64s): two lists of three <width x float> loads from the node
    records at `data` (float32, C-contiguous)."""
    i64 = ir.IntType(64)
    vt = ir.VectorType(ir.FloatType(), width)
    base = builder.mul(node, ir.Constant(i64, NODE_ROWS * width))

    def row(r):
        p = builder.gep(data, [builder.add(base, builder.mul(r, ir.Constant(i64, width)))], inbounds=True)
        return builder.load(builder.bitcast(p, vt.as_pointer()), align=4)

    near = [row(rows[k]) for k in range(3)]
    far = [row(builder.sub(ir.Constant(i64, 2 * k + 3), rows[k])) for k in range(3)]
    return near, far


def _box_codegen(width, store):
    f32 = ir.FloatType()
    f64 = ir.DoubleType()
    i32 = ir.IntType(32)
    i64 = ir.IntType(64)
    vt = ir.VectorType(f32, width)
    undef = ir.Constant(vt, ir.Undefined)
    broadcast = ir.Constant(ir.VectorType(i32, width), [0] * width)

    def codegen(context, builder, sig, args):
        bounds = context.make_array(sig.args[0])(context, builder, args[0])
        node = context.cast(builder, args[1], sig.args[1], types.int64)
        rf = cgutils.unpack_tuple(builder, args[2], 9)
        rows = [
            context.cast(builder, r, t, types.int64)
            for r, t in zip(cgutils.unpack_tuple(builder, args[3], 3), sig.args[3], strict=True)
        ]
        tmax = builder.fptrunc(context.cast(builder, args[4], sig.args[4], types.float64), f32)

        def splat(x):
            return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(i32, 0)), undef, broadcast)

        near, far = node_planes(builder, bounds.data, node, rows, width)
        tnear, hit = slab_test(builder, near, far, [splat(rf[k]) for k in range(9)], splat(tmax))
        mask = builder.zext(builder.bitcast(hit, ir.IntType(width)), i64)
        if store:
            # the entries scaled as they are stored (packet_node scales the minima of its rays'
            # entries instead: the same values)
            tnear = builder.fmul(tnear, ir.Constant(vt, [_NEAR_SCALE] * width))
            out = context.make_array(sig.args[5])(context, builder, args[5])
            at = context.cast(builder, args[6], sig.args[6], types.int64)
            p = builder.gep(out.data, [at], inbounds=True)
            if sig.args[5].dtype == types.float32:
                builder.store(tnear, builder.bitcast(p, vt.as_pointer()), align=4)
            else:
                dv = ir.VectorType(f64, width)
                builder.store(builder.fpext(tnear, dv), builder.bitcast(p, dv.as_pointer()), align=8)
        return mask

    return codegen


@intrinsic
def box_hits(typingctx, bounds, node, rf, rows, tmax, out, at):
    """Ray (box_ray's (rf, rows)) against the BVH_WIDTH child boxes of wide node `node`
    (bounds: the float32 node records (M, NODE_ROWS, BVH_WIDTH), C-contiguous; rows 0-5 the
    boxes), up to distance tmax: a bit mask of the lanes the ray enters. With an array `out`
    (float32 or float64, C-contiguous), the lanes' entry distances are written to out[at : at +
    BVH_WIDTH] (meaningful for hit lanes only; never beyond the exact entry distance); with out
    None, nothing is written."""
    if not (isinstance(bounds, types.Array) and bounds.ndim == 3 and bounds.dtype == types.float32):
        raise TypingError("box_hits: bounds must be a float32 (M, NODE_ROWS, W) array")
    if bounds.layout != "C":
        raise TypingError("box_hits: bounds must be C-contiguous")
    store = not isinstance(out, (types.NoneType, types.Omitted))
    if store and not (
        isinstance(out, types.Array) and out.dtype in (types.float32, types.float64) and out.layout == "C"
    ):
        raise TypingError("box_hits: out must be a C-contiguous float32 or float64 array or None")
    sig = types.int64(bounds, node, rf, rows, tmax, out, at)
    return sig, _box_codegen(BVH_WIDTH, store)


@intrinsic
def prefetch_row(typingctx, array, i):
    """Start loading the cache line of array[i] (its first element; a C-contiguous array), for a
    read soon: a hint, no result."""
    return _row_prefetches("prefetch_row", array, i, lambda builder, base, stride: [base])


@intrinsic
def prefetch_cells(typingctx, array, i, first, last):
    """Start loading the cache lines of array[i, first] .. array[i, last] (a C-contiguous 2-d
    array; first and last literal columns): the line of the first's first byte and of the last's
    last byte. A row of the primitive table (24 bytes) lies across two lines in a quarter of the
    rows, so its first byte's line may not hold the columns a caller reads."""
    if not (isinstance(first, types.IntegerLiteral) and isinstance(last, types.IntegerLiteral)):
        raise TypingError("prefetch_cells: the columns must be literals")
    if not (isinstance(array, types.Array) and array.ndim == 2):
        raise TypingError("prefetch_cells: a C-contiguous 2-d array")
    size = array.dtype.bitwidth // 8
    lo, hi = first.literal_value * size, (last.literal_value + 1) * size - 1

    def offsets(builder, base, stride):
        i64 = ir.IntType(64)
        return [builder.add(base, ir.Constant(i64, lo)), builder.add(base, ir.Constant(i64, hi))]

    _, codegen = _row_prefetches("prefetch_cells", array, i, offsets)
    return types.void(array, i, first, last), codegen


@intrinsic
def prefetch_record(typingctx, array, i):
    """prefetch_row for every cache line of array[i] (a C-contiguous array of records of at most
    four lines, as the wide nodes'): its first byte, every _LINE after it, and its last byte."""

    def offsets(builder, base, stride):
        i64 = ir.IntType(64)
        lines = [builder.add(base, ir.Constant(i64, _LINE * j)) for j in range(4)]
        # a record not aligned to a line touches up to 5
        return [*lines, builder.add(base, builder.sub(stride, ir.Constant(i64, 1)))]

    return _row_prefetches("prefetch_record", array, i, offsets)


def _row_prefetches(name, array, i, offsets):
    """(signature, codegen) of an intrinsic that prefetches the bytes offsets(builder, base,
    stride) of a C-contiguous array, base being the byte offset of array[i] and stride its
    rows' size."""
    if not (isinstance(array, types.Array) and array.layout == "C"):
        raise TypingError(f"{name}: a C-contiguous array")
    sig = types.void(array, i)

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        row = context.cast(builder, args[1], sig.args[1], types.int64)
        stride = builder.extract_value(arr.strides, 0)
        for offset in offsets(builder, builder.mul(row, stride), stride):
            _prefetch(builder, arr.data, offset)
        return context.get_dummy_value()

    return sig, codegen


def _prefetch(builder, data, offset):
    """llvm.prefetch (a read, kept in all cache levels) of the byte `offset` after `data`."""
    i32, i64 = ir.IntType(32), ir.IntType(64)
    addr = builder.inttoptr(builder.add(builder.ptrtoint(data, i64), offset), ir.IntType(8).as_pointer())
    fn = cgutils.get_or_insert_function(
        builder.module, ir.FunctionType(ir.VoidType(), [ir.IntType(8).as_pointer(), i32, i32, i32]), "llvm.prefetch"
    )
    builder.call(fn, [addr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])


@intrinsic
def prefetch_around(typingctx, array, first, end, lines):
    """Start loading the `lines` (a literal) cache lines before row `first` of array and as many
    from the start of row `end` on (a C-contiguous array): a hint, no result, harmless beyond
    either end of the array (prefetches never fault)."""
    if not (isinstance(array, types.Array) and array.layout == "C"):
        raise TypingError("prefetch_around: a C-contiguous array")
    if not isinstance(lines, types.IntegerLiteral):
        raise TypingError("prefetch_around: the number of lines must be a literal")
    sig = types.void(array, first, end, lines)
    n = lines.literal_value

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        stride = builder.extract_value(arr.strides, 0)
        lo = builder.mul(context.cast(builder, args[1], sig.args[1], types.int64), stride)
        hi = builder.mul(context.cast(builder, args[2], sig.args[2], types.int64), stride)
        i64 = ir.IntType(64)
        for j in range(n):
            _prefetch(builder, arr.data, builder.sub(lo, ir.Constant(i64, _LINE * (j + 1))))
            _prefetch(builder, arr.data, builder.add(hi, ir.Constant(i64, _LINE * j)))
        return context.get_dummy_value()

    return sig, codegen


@inline_function
def prefetch_child(bounds, child):
    """In a tree too large for the cache, the record of an inner child as it is pushed: the
    nearest is visited next, and the others that are visited (popped after a leaf missed) come
    back from memory meanwhile. Bumpy 4M hit rays, alternating processes: packets 58.2 against
    59.6 ms (medians of 6 rounds), single rays 65.0 against 66.9 (7 rounds); 10M packets 77.7
    against 78.4 (5), single rays 77.0 against 79.1 (2). Bumpy 1M (50k nodes): packets 43.0
    against 42.4 ms without it in fresh processes, but paired in warm ones, pinned, 1.1% faster
    with it (shadow rays 1.8%): below CHILDREN_PREFETCHED_FROM nodes the records stay in the
    cache."""
    if bounds.shape[0] >= CHILDREN_PREFETCHED_FROM:
        prefetch_record(bounds, child)


@inline_function
def prefetch_neighbours(tri, first, end):
    """On a large mesh, the triangle rows beside a leaf's (first .. end - 1, rows in leaf order):
    where several triangles lie under each pixel, every hit ray of a frame reads triangles no
    ray before it read (a miss of its own: benchmarks/cache_misses.py), and they lie next to
    the ones its neighbour in the frame read. NEIGHBOUR_LINES on either side (four cut the leaf
    visits that wait for memory on bumpy 4M from 1.05 to 0.35 a hit ray, 1M 0.32 -> 0.08,
    simulated); up to 100k triangles there is nothing to gain (0.04 a ray), so smaller meshes skip it."""
    if tri.shape[0] >= NEIGHBOURS_FROM:
        prefetch_around(tri, first, end, NEIGHBOUR_LINES)


@intrinsic
def prefetch_child_rows(typingctx, index, node):
    """prefetch_row for the cache line of node `node`'s child references (node_index[node,
    NODE_REF]): in the last of its record's lines, which the box test may not read."""
    if not (isinstance(index, types.Array) and index.layout == "C" and index.ndim == 3):
        raise TypingError("prefetch_child_rows: the C-contiguous node records")
    sig = types.void(index, node)

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        m = context.cast(builder, args[1], sig.args[1], types.int64)
        i64 = ir.IntType(64)
        strides = cgutils.unpack_tuple(builder, arr.strides, 3)
        offset = builder.add(builder.mul(m, strides[0]), builder.mul(ir.Constant(i64, NODE_REF), strides[1]))
        _prefetch(builder, arr.data, offset)
        return context.get_dummy_value()

    return sig, codegen


def trailing_zeros(builder, value):
    """IR: the number of trailing zero bits of the i64 `value` (llvm.cttz.i64; undefined for
    0), the index of its lowest set bit."""
    i64 = ir.IntType(64)
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i64, [i64, ir.IntType(1)]), "llvm.cttz.i64")
    return builder.call(fn, [value, ir.Constant(ir.IntType(1), 1)])


@intrinsic
def lowest_bit(typingctx, x):
    """Index of the lowest set bit of x (x != 0)."""
    sig = types.int64(x)

    def codegen(context, builder, sig, args):
        return trailing_zeros(builder, context.cast(builder, args[0], sig.args[0], types.int64))

    return sig, codegen


@inline_function
def _ray_axis(o, d, k):
    """Axis k of box_ray: (near offset, far offset, 1/d, near row); ray_axis_ir says how."""
    near, far, inv32, positive = _axis_constants(np.float64(o), np.float64(d))
    return near, far, inv32, k if positive else k + 3


# Inlined: called, each ray passed its origin and direction and got nine floats and three ints
# back through memory (Cornell path mode ~2.5% of its CPU time, alternating builds).
@inline_function
def box_ray(o, d):
    """Per-ray constants of box_hits: (near-plane offsets x, y, z, far-plane offsets, 1/d) as
    float32 (an offset: -o/d rounded outward, _ray_axis), and the near plane's row for each
    axis (the far one is the other)."""
    nx, fx, ix, rx = _ray_axis(o[0], d[0], 0)
    ny, fy, iy, ry = _ray_axis(o[1], d[1], 1)
    nz, fz, iz, rz = _ray_axis(o[2], d[2], 2)
    return (nx, ny, nz, fx, fy, fz, ix, iy, iz), (rx, ry, rz)


@inline_function
def traceable(o, d):
    """Rays with a NaN or infinite direction, or an origin beyond the float32 range of the
    BVH's boxes, hit nothing (an empty lane's box is only empty for finite rays)."""
    return (
        abs(o[0]) < _F32_MAX
        and abs(o[1]) < _F32_MAX
        and abs(o[2]) < _F32_MAX
        and abs(d[0]) < INF
        and abs(d[1]) < INF
        and abs(d[2]) < INF
    )


@kernel_function
def box_entries(bounds, node, o, d, tmax, out):
    """Entry distances of the ray into the children of `node`, +inf for the lanes it misses
    (for tests); out: float64 (BVH_WIDTH,) scratch."""
    rf, rows = box_ray(o, d)
    mask = box_hits(bounds, node, rf, rows, tmax, out, 0)
    for i in range(BVH_WIDTH):
        if (mask >> i) & 1 == 0:
            out[i] = INF
    return out


# --- the stack ----------------------------------------------------------------------------------


@inline_function
def push_children(bounds, index, leaf_rows, ref, rf, rows, best_t, node_stack, t_stack, top, tri, direct):
    """The children of node `ref` that the ray enters nearer than best_t: (k, nearest), how many
    and the nearest of them (to visit next); the other k - 1 are pushed onto the stacks from
    `top`, sorted farthest first (the next nearest on top), the stacks' order when the nearest
    was pushed on top and popped at once (of equal distances, the later lane first). The nearest
    stays in a register: as a store and the load that read it back, it put a store-to-load
    forwarding on every descent's chain (the next node's address). The node's child indices are
    prefetched beside its boxes, not loaded after the box test, so the two cache misses of a node
    overlap (hit rays on a 1M-triangle mesh: ~12% less time); a pushed leaf's first rows too, of
    what testing it reads first: its triangles (`tri`) where `direct` (rows_in_leaf_order), else
    its row of `leaf_rows` (bumpy 4M single-ray hit rays 2-4% less time than with the primitive
    table's row prefetched on every mesh). A prefetch past the table's end is harmless:
    prefetches never fault."""
    prefetch_child_rows(index, ref)
    # entry distances land at t_stack[top:]; the pushed ones are moved down to t_stack[top:top + k
    # - 1] (lane i >= k is read before slot top + k - 1 is written)
    mask = box_hits(bounds, ref, rf, rows, best_t, t_stack, top)
    k = 0
    nearest, nearest_t = np.int32(0), np.float32(0.0)  # set by the first child
    # Subscripts as unsigned (none is negative): Numba wraps every signed subscript around
    # (shift, and, add); without that, bumpy 10k hit rays took ~2% less time.
    while mask != 0:
        i = lowest_bit(mask)
        mask &= mask - 1
        u = np.uint64(i)
        t = t_stack[np.uint64(top + i)]
        child = index[np.uint64(ref), NODE_REF, u]
        if child >= 0:  # an inner node
            prefetch_child(bounds, child)
        else:  # a leaf
            first = leaf_first(child)
            if direct:
                prefetch_row(tri, first)
                prefetch_row(tri, first + 2)
                prefetch_row(tri, first + 3)
            else:
                prefetch_row(leaf_rows, first)
        if k == 0:
            nearest, nearest_t = child, t
        elif t <= nearest_t:  # the new nearest; the old one, nearer than all pushed, on top
            t_stack[np.uint64(top + k - 1)] = nearest_t
            node_stack[np.uint64(top + k - 1)] = nearest
            nearest, nearest_t = child, t
        else:
            j = top + k - 1
            while j > top and t_stack[np.uint64(j - 1)] < t:
                t_stack[np.uint64(j)] = t_stack[np.uint64(j - 1)]
                node_stack[np.uint64(j)] = node_stack[np.uint64(j - 1)]
                j -= 1
            t_stack[np.uint64(j)] = t
            node_stack[np.uint64(j)] = child
        k += 1
    return k, nearest


@inline_function
def pop_nearer(node_stack, t_stack, top, base, best_t):
    """The next entry above `base` still nearer than best_t: (found, new top, entry)."""
    while top > base:
        top -= 1
        if t_stack[np.uint64(top)] < best_t:  # unsigned: as in push_children
            return True, top, node_stack[np.uint64(top)]
    return False, top, node_stack[top]
