"""The sphere tests of a wavefront tile (kernels/integrators/wavefront.py): the live rays of a tile against
the spheres of a root leaf, eight rays per vector, in explicit LLVM IR.

A vector of eight rays is tested against one sphere at a time. Most rays of a tile miss most
spheres (the tile's rays are neighbours, so a small sphere lies far from all eight), and a
vector whose rays all miss a sphere is known to after a few multiplications: the square root and
the division are skipped for it. LLVM's loop vectoriser cannot make that choice: it computes
every step for every slot.

Closest hits are intersect_sphere's arithmetic, operation for operation, so every lane rounds
as the scalar test does and the hits are the same to the last bit.

Shadow rays need only whether a root lies in (0, tmax). The roots are q and c / q, q the one
found without cancellation. Towards a directional light tmax is infinite, and whether a positive
root exists is a matter of signs: q has the sign of -b, and c / q is positive when c has the sign
of q. So those tests take neither the square root nor the division, with the same answer as the
scalar test. Towards a point light, the same arithmetic as the scalar test decides.

The rays are rows of the wavefront's flat scratch (R float64, I int64), given by their offsets.
Lanes from m on (past the tile's live rays) are computed but never count as hits; their values
are whatever the scratch rows hold (rows have ROW_PAD slots beyond TILE, so a vector starting
below m stays inside the row).
"""

import math

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import kernel_function
from .packet import _array_data, _splat
from .shape_triangle import EXACT, EXACT_DIVISION, exact_ops

LANES = 8  # rays per vector: eight float64, one zmm register on Zen 4, two ymm elsewhere (vector_width.py)

# Columns of the sphere table (the wavefront's per-primitive sphere rows)
SX, SY, SZ, SR = 0, 1, 2, 3

_f64, _i1, _i32, _i64 = ir.DoubleType(), ir.IntType(1), ir.IntType(32), ir.IntType(64)
_VD = ir.VectorType(_f64, LANES)
_VI = ir.VectorType(_i64, LANES)


def _pointer(context, builder, arr_type, arr, at, vt):
    """Pointer to elements at..at+7 of the 1-D array `arr`, as a vector."""
    data = _array_data(context, builder, arr_type, arr)
    return builder.bitcast(builder.gep(data, [at], inbounds=True), vt.as_pointer())


class _Rows:
    """Slots i..i+7 of the rows of a flat scratch pair (R float64, I int64) whose offsets are
    given as a tuple of integers."""

    def __init__(self, context, builder, sig, args, i):
        self.context, self.builder, self.i = context, builder, i
        self.R, self.I = (sig.args[0], args[0]), (sig.args[1], args[1])
        self.rows = cgutils.unpack_tuple(builder, args[2], len(sig.args[2]))

    def pointer(self, n, ints=False):
        """Pointer to the slots of row number n of the tuple."""
        arr_type, arr = self.I if ints else self.R
        at = self.builder.add(self.rows[n], self.i)
        return _pointer(self.context, self.builder, arr_type, arr, at, _VI if ints else _VD)

    def load(self, n, ints=False):
        return self.builder.load(self.pointer(n, ints), align=8)


def _any(builder, mask):
    return builder.icmp_unsigned("!=", builder.bitcast(mask, ir.IntType(LANES)), ir.Constant(ir.IntType(LANES), 0))


def _call(builder, name, *args):
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VD, [_VD] * len(args)), name)
    return builder.call(fn, list(args))


class _Sphere:
    """The part of intersect_sphere every test needs, on eight rays: b, c, the discriminant
    and the candidates (lanes below m whose ray the sphere may meet ahead)."""

    def __init__(self, builder, o, d, centre, radius, live):
        fadd, fsub, fmul, lt = exact_ops(builder)
        self.builder = builder
        zero = ir.Constant(_VD, [0.0] * LANES)
        x, y, z = (fsub(o[a], centre[a]) for a in range(3))
        b = fadd(fadd(fmul(x, d[0]), fmul(y, d[1])), fmul(z, d[2]))
        rr = fmul(radius, radius)
        c = fsub(fadd(fadd(fmul(x, x), fmul(y, y)), fmul(z, z)), rr)
        px, py, pz = fsub(x, fmul(b, d[0])), fsub(y, fmul(b, d[1])), fsub(z, fmul(b, d[2]))
        disc = fsub(rr, fadd(fadd(fmul(px, px), fmul(py, py)), fmul(pz, pz)))
        away = builder.and_(lt(zero, c), lt(zero, b))  # outside and moving away
        reaches = builder.fcmp_ordered(">=", disc, zero, flags=EXACT)
        self.b, self.c, self.disc, self.zero = b, c, disc, zero
        self.candidates = builder.and_(live, builder.and_(reaches, builder.not_(away)))

    def q(self):
        """-b - copysign(sqrt(max(disc, 0)), b): the root found without cancellation."""
        builder = self.builder
        disc = builder.select(builder.fcmp_ordered(">", self.disc, self.zero, flags=EXACT), self.disc, self.zero)
        root = _call(builder, "llvm.copysign.v8f64", _call(builder, "llvm.sqrt.v8f64", disc), self.b)
        return builder.fsub(builder.fneg(self.b, flags=EXACT), root, flags=EXACT)


def _live(builder, i, m):
    """Lanes i..i+7 that are below m."""
    lanes = ir.Constant(_VI, list(range(LANES)))
    return builder.icmp_signed("<", lanes, _splat(builder, builder.sub(m, i), _VI))


def _check(name, R, I, rows, spheres, n_rows):
    for arr, dtype in ((R, types.float64), (I, types.int64), (spheres, types.float64)):
        if not (isinstance(arr, types.Array) and arr.layout == "C" and arr.dtype == dtype):
            raise TypingError(f"{name}: R, I and spheres must be C-contiguous float64, int64 and float64 arrays")
    if not (isinstance(rows, types.UniTuple) and len(rows) == n_rows and isinstance(rows.dtype, types.Integer)):
        raise TypingError(f"{name}: rows must be a tuple of {n_rows} integers")


def _sphere_row(context, builder, spheres_type, spheres, k):
    """The centre (three splats) and radius (a splat) of row k of the sphere table."""
    data = _array_data(context, builder, spheres_type, spheres)
    base = builder.mul(k, ir.Constant(_i64, 4))

    def column(c):
        p = builder.gep(data, [builder.add(base, ir.Constant(_i64, c))], inbounds=True)
        return _splat(builder, builder.load(p, align=8), _VD)

    return [column(SX), column(SY), column(SZ)], column(SR)


@intrinsic
def closest8(typingctx, R, I, rows, i, m, spheres, first, count):
    """Rays i..i+7 (those below m) against spheres first..first+count-1 of `spheres` (float64
    (n, 4): centre, radius), in order: a hit nearer than t replaces (t, prim) with (its
    distance, k). `rows` gives the offsets in the flat scratch of the rows ox, oy, oz, dx, dy,
    dz, t (in R) and prim (in I); intersect_sphere's result, to the last bit."""
    _check("closest8", R, I, rows, spheres, 8)

    def codegen(context, builder, sig, args):
        _, _, _, lt = exact_ops(builder)
        i, m, first, count = args[3], args[4], args[6], args[7]
        slots = _Rows(context, builder, sig, args, i)
        o, d = [slots.load(n) for n in range(3)], [slots.load(n) for n in range(3, 6)]
        live = _live(builder, i, m)
        t_ptr = slots.pointer(6)
        prim_ptr = slots.pointer(7, ints=True)
        # (t, prim) carried over the spheres in registers (stack slots LLVM promotes) and
        # stored once, plainly: stored sphere by sphere, `store(select(nearer, tk,
        # load(t)), t)` became a masked store (vmaskmovpd), which AMD's Zen 3 runs
        # microcoded at tens of cycles
        t_slot = cgutils.alloca_once_value(builder, builder.load(t_ptr, align=8))
        prim_slot = cgutils.alloca_once_value(builder, builder.load(prim_ptr, align=8))
        with cgutils.for_range(builder, count) as loop:
            k = builder.add(first, loop.index)
            centre, radius = _sphere_row(context, builder, sig.args[5], args[5], k)
            sphere = _Sphere(builder, o, d, centre, radius, live)
            with builder.if_then(_any(builder, sphere.candidates), likely=False):
                best = builder.load(t_slot)
                q = sphere.q()
                t0 = builder.fdiv(sphere.c, q, flags=EXACT_DIVISION)
                swap = lt(q, t0)
                near = builder.select(swap, q, t0)
                far = builder.select(swap, t0, q)
                zero = sphere.zero

                def ahead(s):
                    return builder.and_(lt(zero, s), lt(s, best))

                inf = ir.Constant(_VD, [math.inf] * LANES)
                tk = builder.select(ahead(near), near, builder.select(ahead(far), far, inf))
                found = builder.and_(sphere.candidates, builder.fcmp_unordered("!=", q, zero, flags=EXACT))
                tk = builder.select(found, tk, inf)
                nearer = lt(tk, best)
                builder.store(builder.select(nearer, tk, best), t_slot)
                builder.store(builder.select(nearer, _splat(builder, k, _VI), builder.load(prim_slot)), prim_slot)
        builder.store(builder.load(t_slot), t_ptr, align=8)
        builder.store(builder.load(prim_slot), prim_ptr, align=8)
        return context.get_dummy_value()

    sig = types.none(R, I, rows, types.int64, types.int64, spheres, types.int64, types.int64)
    return sig, codegen


@intrinsic
def blocks8(typingctx, R, I, rows, i, m, spheres, k, directional):
    """Shadow rays i..i+7 (those below m whose `blocked` is 0) against sphere k of `spheres`:
    `blocked` becomes 1 where the sphere lies in (0, tmax) along the ray, as intersect_sphere
    finds it. `rows` gives the offsets of the rows ox, oy, oz, dx, dy, dz, tmax (in R) and
    blocked (in I). With `directional` every tmax is +inf, and signs alone decide (the module's
    docstring). Returns whether any of the eight rays is still unblocked (0)."""
    _check("blocks8", R, I, rows, spheres, 8)

    def codegen(context, builder, sig, args):
        _, _, _, lt = exact_ops(builder)
        i, m, k, directional = args[3], args[4], args[6], args[7]
        slots = _Rows(context, builder, sig, args, i)
        blocked_ptr = slots.pointer(7, ints=True)
        state = builder.load(blocked_ptr, align=8)
        open_ = builder.and_(_live(builder, i, m), builder.icmp_signed("==", state, ir.Constant(_VI, [0] * LANES)))
        pending = cgutils.alloca_once_value(builder, _any(builder, open_))
        with builder.if_then(builder.load(pending), likely=True):
            o, d = [slots.load(n) for n in range(3)], [slots.load(n) for n in range(3, 6)]
            centre, radius = _sphere_row(context, builder, sig.args[5], args[5], k)
            sphere = _Sphere(builder, o, d, centre, radius, open_)
            with builder.if_then(_any(builder, sphere.candidates), likely=False):
                zero = sphere.zero
                hit_slot = cgutils.alloca_once(builder, ir.VectorType(_i1, LANES))
                with builder.if_else(directional) as (towards_direction, towards_point):
                    with towards_direction:
                        # q = -copysign(|b| + sqrt(disc), b): nonzero unless b and disc are 0,
                        # positive where b's sign bit is set; c / q > 0 where c has q's sign.
                        nonzero = builder.or_(
                            builder.fcmp_unordered("!=", sphere.b, zero, flags=EXACT), lt(zero, sphere.disc)
                        )
                        negative_b = builder.icmp_signed(
                            "<", builder.bitcast(sphere.b, _VI), ir.Constant(_VI, [0] * LANES)
                        )
                        ahead = builder.or_(negative_b, lt(sphere.c, zero))
                        builder.store(builder.and_(sphere.candidates, builder.and_(nonzero, ahead)), hit_slot)
                    with towards_point:
                        far_end = slots.load(6)
                        q = sphere.q()
                        t0 = builder.fdiv(sphere.c, q, flags=EXACT_DIVISION)

                        def within(s):
                            return builder.and_(lt(zero, s), lt(s, far_end))

                        # intersect_sphere returns near if within, else far if within: either lies
                        # within exactly when q or c / q does
                        inside = builder.or_(within(q), within(t0))
                        found = builder.and_(sphere.candidates, builder.fcmp_unordered("!=", q, zero, flags=EXACT))
                        builder.store(builder.and_(found, inside), hit_slot)
                hit = builder.load(hit_slot)
                state = builder.select(hit, ir.Constant(_VI, [1] * LANES), state)
                builder.store(state, blocked_ptr, align=8)
                builder.store(_any(builder, builder.and_(open_, builder.not_(hit))), pending)
        return builder.load(pending)

    return types.boolean(R, I, rows, types.int64, types.int64, spheres, types.int64, types.boolean), codegen


@kernel_function
def tile_closest(R, I, rows, m, spheres, first, count):
    """Rays 0..m-1 against spheres first..first+count-1 of `spheres`: the nearest hit before t
    replaces (t, prim), as closest_hit's leaf test finds it (the lowest index on ties). `rows`:
    as closest8's."""
    for i in range(0, m, LANES):
        closest8(R, I, rows, i, m, spheres, first, count)


@kernel_function
def tile_blocks(R, I, rows, m, spheres, first, count, directional):
    """Shadow rays 0..m-1 whose `blocked` is 0 against spheres first..first+count-1: blocked
    becomes 1 where one of them lies in (0, tmax); the eight rays of a vector stop at once when
    all are blocked. `rows`: as blocks8's."""
    for i in range(0, m, LANES):
        for k in range(first, first + count):
            if not blocks8(R, I, rows, i, m, spheres, k, directional):
                break
