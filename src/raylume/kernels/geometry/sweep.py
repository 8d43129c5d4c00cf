"""Small scenes without a BVH walk: every triangle against the ray at once, in float32, then the
exact test on the few that may be hit.

A scene of a few dozen triangles (the Cornell box: 30, and its light, a quad) and a few other
bounded primitives spends most of a ray's time in the BVH's bookkeeping: one node's slab test, the sort
of the leaves it enters, two or three leaf tests that each wait for the last one's distance.
`sweep_hit` instead tests all the triangles (SWEEP_LANES) as up to four groups of eight float32 lanes (as
many as the scene fills, one a pass of a loop), independent of each other (no distance carried
from one to the next), in a conservative form of the
watertight test (Woop, Benthin and Wald 2013): which side of each edge the ray passes, as the sign
of the permuted inner product of the ray's and the edge's Plücker coordinates (the watertight
test's sheared edge functions times -d_k, d_k the ray's largest direction component), may be off by at
most its rounding error bound, so a lane counts as a candidate unless two of its edges' sides are
of opposite signs beyond that bound or the ray's span lies certainly on one side of its plane.
Every triangle the exact float64 test hits is a candidate (the bounds are derived below and
checked by tests/test_sweep.py against the exact test on adversarial rays); a ray has one to
three candidates in a closed box (its hit, what lies beyond it along an edge), and those go
through the exact test (shape_triangle.triangles4_gathered, four at a time; one from the
column table). The hit is the exact test's, to the bit; on an exact tie (a ray through an edge
two triangles share) the lowest triangle row's. A ray that leaves a triangle, its origin offset
to the side it goes to (path mode's rays), leaves it out: the exact test cannot hit it, and it
would otherwise be a candidate of every such ray. Flat polygons (quads) take lanes as their
exact triangles (shapes.exact_triangles), their candidates tested by the shape's own test; the
scene's other bounded primitives (at most SWEEP_OTHERS) by theirs, for every ray.

The bound. With R = M + max |origin coordinate|, M = max |vertex coordinate| over all the
table's lanes (per lane would be tighter, but one R a ray saves each lane instructions), and D =
max |d_i|, an edge from p to q has the side d . m + e . w of the ray (o, d): m = p x q and
e = q - p are the table's (rows SWEEP_EDGES, lane_edges: float64 from the float32 vertices, each
rounded once, so off by u |m_j| and u |e_j|, u = 2^-24), w = o x d is the ray's moment (float64,
rounded once) and d is rounded to float32: each product off by 2 u of its size. The six terms
are summed by one product and five fused multiply-adds, each rounding within u of the sum of the
terms' sizes, T = sum |d_j| |m_j| + sum |e_j| |w_j| <= 6 D M^2 + 12 D M max|o| <= 6 D R^2 (|m_j|
<= 2 M^2, |e_j| <= 2 M, |w_j| <= 2 max|o| D). So a side is within 8 u T <= 48 u D R^2 = 2^-18.4
D R^2 (and float64's roundings of w, below 2^-48 D R^2) of its exact value for the lane's
triangle; a polygon's triangles, whose corners are rounded to float32 too, move it by at most 12
u D R^2 more. SWEEP_TOLERANCE is 2^-16 D R^2, ~4x the sum.
The exact test hits only where its float64 sheared edge functions, the exact sides over -d_k to
within float64 rounding, have no two of opposite signs, so every such lane is inside. The sides'
signs are tested on their least and greatest (selects that return one of them, so no test is
less conservative than comparing each). Against the sheared edge functions of the first version
(the vertices relative to the origin, sheared, three differences of products: 30 instructions a
group) the Plücker form is 18 (six fused multiply-adds an edge, the table's rows as memory
operands) and needs no shear: the mask ~36 ns a ray against ~41.

The distance is taken from each lane's plane (rows SWEEP_PLANE: a unit normal n and c = -n . v0,
computed in float64 from the float32 vertices and rounded once), not from the edge functions,
whose numerator and determinant are bounded only in R (the Cornell box's ceiling, 0.1 above its
light, was a candidate of every shadow ray with those bounds: 2^-6 R = 17 there). The plane
function g(x) = n . x + c is evaluated at the two ends of the ray's span, p0 = o + tmin d and
p1 = o + far d, far = min(tmax, 2 R B) with D = max |d_i| and B the power of two at or above 1 / D
(no point of any lane lies farther along the ray: |x - o| <= sqrt 3 R and |d| >= D; B, from D's
exponent bits, spares the ray a division), each point computed in float64 and rounded
once, g by three fused multiply-adds. At the exact test's hit point x* (on the exact primitive)
|g(x*)| <= 9.4 u R: the rounding of n (u |x - v0|_1 <= 6 u R), of c (sqrt 3 u R) and of a
polygon's corners (sqrt 3 u R). g computed at p = o + t d is within 12.1 u R + 6.9 u D |t| of g
exact there: p's rounding (sqrt 3 u (R + D |t|)) and the three fused multiply-adds (3 sqrt 3 u
(2 R + D |t|)). g is linear along the ray, so where both ends exceed the bound E =
SWEEP_PLANE_BOUND (R + D T) on the same side, T = max(|tmin|, far), g keeps that sign over the
whole span by more than 9.4 u R and the plane is crossed outside it: E is about six times the
21.5 u R + 6.9 u D T that needs, and its margin (~100 u R of g) is far beyond the exact test's
own float64 rounding of the distance. A ray along the plane needs no special case (both ends
have the same sign), and a degenerate triangle's zero normal gives g = 0 (a candidate). A lane
is a candidate unless its edge functions have opposite signs beyond their bound or its plane
function is beyond E with one sign at both ends of the span; unused lanes have n = 0 and c =
inf, and never are (but for a ray with a NaN, whose every comparison fails).
"""

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import inline_function
from .shape_triangle import exact_ops, intersect_triangle_block, ray_shear, triangles4_gathered, unit_normals
from .shapes import NO_HIT, PRIM_KIND, PRIM_ROW, TRIANGLE, Shape, exact_triangles, intersect
from .wide_nodes import lowest_bit

SWEEP_LANES = 32  # up to four groups of eight float32 lanes
SWEEP_GROUP = 8  # lanes a group: one AVX2 vector of float32
SWEEP_OTHERS = 8  # bounded primitives other than triangles and quads a swept scene may have
# The table's rows: the Plücker coordinates of each lane's three edges (18 rows), the largest
# vertex coordinate magnitude of all the lanes (the same in each), each lane's primitive
# (as a float32: exact below 2^24; -1 in unused lanes), the other bounded primitives (-1
# after the last) and each lane's plane. Lanes 0 .. T - 1 are the scene's triangles (lane = triangle row: a swept
# scene has no instances, so its triangle table is its T triangles alone); the triangles of flat
# polygons follow (a quad's two, exactly the parallelogram, rounded to float32: the bound allows
# for that rounding), their candidates tested by the shape's own test.
SWEEP_EDGES = 0  # rows 0 .. 17: each lane's three edges, moment and direction (lane_edges)
SWEEP_MAGNITUDE, SWEEP_PRIM, SWEEP_OTHER = 18, 19, 20
SWEEP_PLANE = 21  # rows 21 .. 24: each lane's plane, a unit normal n and c = -n . v0 (float32)
SWEEP_ROWS = 25
# the number of groups of eight lanes in use, stored in the others' row's last lane (byte offset)
SWEEP_GROUPS_AT = 4 * (SWEEP_OTHER * SWEEP_LANES + SWEEP_LANES - 1)
SWEEP_TOLERANCE = 2.0**-16  # times D R^2: the edges' sides' error bound, ~4x
SWEEP_PLANE_BOUND = 2.0**-17  # times (R + D T): the plane function's bound at the span's ends, ~6x


def sweep_table(
    triangles: np.ndarray, prims: np.ndarray, shapes: np.ndarray, n_bounded: int, instanced: bool
) -> np.ndarray:
    """float32 (SWEEP_ROWS, SWEEP_LANES) for a scene that sweep_hit can take: no instances, more
    than four triangles, triangles and the triangles of flat polygons (quads: two each) within
    SWEEP_LANES, at most SWEEP_OTHERS other bounded primitives. Otherwise (SWEEP_ROWS, 0): the
    BVH walk."""
    tri = np.asarray(triangles, np.float32)
    n_tris = len(tri)
    kinds = prims[:n_bounded, PRIM_KIND]
    is_tri = kinds == TRIANGLE
    polygons, others, halves = [], [], []
    for k in np.flatnonzero(~is_tri):
        parts = exact_triangles(Shape(kinds[k]), shapes[prims[k, PRIM_ROW]])
        if parts is None:
            others.append(k)
        else:
            polygons += [k] * len(parts)
            halves.append(parts)
    lanes = n_tris + len(polygons)
    if instanced or n_tris <= 4 or lanes > SWEEP_LANES or len(others) > SWEEP_OTHERS or is_tri.sum() != n_tris:
        return np.zeros((SWEEP_ROWS, 0), np.float32)
    lane_tris = np.concatenate([tri] + [h.astype(np.float32) for h in halves])
    table = np.zeros((SWEEP_ROWS, SWEEP_LANES), np.float32)
    table[SWEEP_EDGES : SWEEP_EDGES + 18, :lanes] = lane_edges(lane_tris).T
    table[SWEEP_MAGNITUDE] = np.abs(lane_tris).max()  # exact: |x| of a float32 is one
    table[SWEEP_PRIM] = -1.0
    table[SWEEP_PRIM, prims[:n_bounded, PRIM_ROW][is_tri]] = np.flatnonzero(is_tri)
    table[SWEEP_PRIM, n_tris:lanes] = polygons
    table[SWEEP_OTHER] = -1.0
    table[SWEEP_OTHER, : len(others)] = others
    table[SWEEP_OTHER, SWEEP_LANES - 1] = -(-lanes // SWEEP_GROUP)  # the groups in use
    # unused lanes: n = 0 and c = inf, a plane function positive everywhere
    table[SWEEP_PLANE + 3] = np.inf
    table[SWEEP_PLANE : SWEEP_PLANE + 4, :lanes] = lane_planes(lane_tris).T
    return table


def lane_edges(triangles: np.ndarray) -> np.ndarray:
    """float32 (n, 18): each float32 triangle's edges v0 v1, v1 v2, v2 v0 (p to q) in Plücker
    coordinates, their moment p x q and direction q - p, from float64 arithmetic on the
    vertices, each rounded once."""
    v = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    p, q = v, np.roll(v, -1, axis=1)
    return np.concatenate([np.cross(p, q), q - p], axis=2).reshape(-1, 18).astype(np.float32)


def lane_planes(triangles: np.ndarray) -> np.ndarray:
    """float32 (n, 4): each float32 triangle's plane n . x + c = 0, its unit normal n and c = -n .
    v0, from float64 arithmetic on the vertices, each rounded once (zero for a degenerate
    triangle: its plane function is then 0 everywhere, within every bound)."""
    v = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    n = unit_normals(v).astype(np.float32)
    c = -np.einsum("ij,ij->i", n.astype(np.float64), v[:, 0])
    return np.column_stack([n, c]).astype(np.float32)


def _lanes_codegen(context, builder, sig, args):
    f32, f64, i32, i64 = ir.FloatType(), ir.DoubleType(), ir.IntType(32), ir.IntType(64)
    n = SWEEP_GROUP
    v8 = ir.VectorType(f32, n)
    vi = ir.VectorType(i32, n)
    undef = ir.Constant(v8, ir.Undefined)
    zeros = ir.Constant(vi, [0] * n)
    table_t, o_t, d_t, tmin_t, tmax_t, leaving_t, arriving_t = sig.args
    table = context.make_array(table_t)(context, builder, args[0])
    # IEEE arithmetic: no contraction, no reassociation (the bound assumes it)
    fadd, fsub, fmul, lt = exact_ops(builder)

    def doubles(value, tuple_t):
        return [
            context.cast(builder, x, t, types.float64)
            for x, t in zip(cgutils.unpack_tuple(builder, value, 3), tuple_t, strict=True)
        ]

    def splat(x):
        return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(i32, 0)), undef, zeros)

    fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(f32, [f32]), "llvm.fabs.f32")
    o64, d64 = doubles(args[1], o_t), doubles(args[2], d_t)
    o, d = [builder.fptrunc(x, f32) for x in o64], [builder.fptrunc(x, f32) for x in d64]

    def largest_magnitude(xs):
        out = builder.call(fabs, [xs[0]])
        for x in xs[1:]:
            ax = builder.call(fabs, [x])
            out = builder.select(builder.fcmp_unordered(">", ax, out), ax, out)  # NaN: every lane a candidate
        return out

    omax, dmax = largest_magnitude(o), largest_magnitude(d)
    # rows at constant offsets (the table is C-contiguous (SWEEP_ROWS, SWEEP_LANES) float32
    # whenever it is swept): each row's load then takes an immediate offset, where the strides'
    # products had been kept on the stack and reloaded into registers
    base = builder.ptrtoint(table.data, i64)

    def row_offset(row):
        return ir.Constant(i64, row * 4 * SWEEP_LANES)

    # R (the module docstring's) once per ray: the largest magnitude of all the lanes (the
    # table's row, lane 0) plus the origin's, the same for every lane (a looser bound than each
    # lane's own, for less arithmetic a lane)
    magnitude = builder.load(
        builder.inttoptr(builder.add(base, row_offset(SWEEP_MAGNITUDE)), f32.as_pointer()), align=4
    )
    r = fadd(magnitude, omax)
    tol = splat(fmul(fmul(fmul(r, r), dmax), ir.Constant(f32, SWEEP_TOLERANCE)))
    ntol = builder.fneg(tol)
    # the ray in Plücker coordinates: its direction and its moment o x d, in float64 rounded once
    moment = [
        builder.fptrunc(fsub(fmul(o64[i], d64[j]), fmul(o64[j], d64[i])), f32) for i, j in ((1, 2), (2, 0), (0, 1))
    ]
    ray_d, ray_m = [splat(x) for x in d], [splat(x) for x in moment]
    # The plane function at the ends of the ray's span (tmin, far), far = min(tmax, 2 R B): no
    # triangle point lies farther along the ray (module docstring). Per ray in float64, each
    # point rounded once.
    tmin64 = context.cast(builder, args[3], tmin_t, types.float64)
    tmax64 = context.cast(builder, args[4], tmax_t, types.float64)
    r64, dmax64 = builder.fpext(r, f64), builder.fpext(dmax, f64)
    reach = fmul(fmul(ir.Constant(f64, 2.0), r64), _reciprocal_bound(builder, dmax64))
    far = builder.select(lt(tmax64, reach), tmax64, reach)
    fabs64 = cgutils.get_or_insert_function(builder.module, ir.FunctionType(f64, [f64]), "llvm.fabs.f64")
    abs_tmin = builder.call(fabs64, [tmin64])
    longest = builder.select(lt(far, abs_tmin), abs_tmin, far)
    bound = splat(builder.fptrunc(fmul(ir.Constant(f64, SWEEP_PLANE_BOUND), fadd(r64, fmul(dmax64, longest))), f32))
    nbound = builder.fneg(bound)

    def point(t):
        return [splat(builder.fptrunc(fadd(oi, fmul(t, di)), f32)) for oi, di in zip(o64, d64, strict=True)]

    # a span from the origin (every path ray's) starts at o itself: the same point (0 d is 0 for
    # a finite d; an infinite one makes the far end NaN, a candidate), and after inlining LLVM
    # drops the multiply-adds and reuses o's float32 rounding
    from_origin = builder.fcmp_ordered("==", tmin64, ir.Constant(f64, 0.0))
    near_point = [
        splat(builder.select(from_origin, oi, builder.fptrunc(fadd(oi64, fmul(tmin64, di)), f32)))
        for oi, oi64, di in zip(o, o64, d64, strict=True)
    ]
    far_point = point(far)
    # the primitives a ray leaves and arrives at, as the table's float32 primitive row has them
    ends = [
        splat(builder.sitofp(context.cast(builder, args[i], t, types.int64), f32))
        for i, t in ((5, leaving_t), (6, arriving_t))
    ]
    edge_offsets = [row_offset(SWEEP_EDGES + i) for i in range(18)]
    plane_offsets = [row_offset(SWEEP_PLANE + i) for i in range(4)]
    prim_offset = row_offset(SWEEP_PRIM)
    vfma = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v8, [v8, v8, v8]), "llvm.fma.v8f32")

    def fma(a, b, c):  # a b + c rounded once: within the bound (one rounding, not two)
        return builder.call(vfma, [a, b, c])

    # minps / maxps: one of the two, b where either is NaN: never beyond the others (the tests
    # below stay as conservative as comparing each side)
    def smaller(a, b):
        return builder.select(lt(a, b), a, b)

    def larger(a, b):
        return builder.select(lt(b, a), a, b)

    # One group of eight lanes per pass of a loop (not unrolled: the table's group count is
    # read at run time). Unrolled, LLVM interleaved the four groups, and the ray's ~18 broadcast
    # values and the groups' partial sums outgrew the 16 vector registers: a third of the
    # mask's instructions were spills and reloads.
    groups = builder.fptosi(
        builder.load(builder.inttoptr(builder.add(base, ir.Constant(i64, SWEEP_GROUPS_AT)), f32.as_pointer()), align=4),
        i64,
    )
    entry = builder.block
    loop = builder.append_basic_block("sweep_group")
    done = builder.append_basic_block("sweep_done")
    builder.branch(loop)
    builder.position_at_end(loop)
    g = builder.phi(i64)
    mask_in = builder.phi(i64)
    at = builder.add(base, builder.mul(g, ir.Constant(i64, 4 * n)))

    def load(offset):
        return builder.load(builder.inttoptr(builder.add(at, offset), v8.as_pointer()), align=4)

    # each edge's side of the ray: d . (p x q) + (q - p) . (o x d)
    sides = []
    for e in range(3):
        rows = [load(off) for off in edge_offsets[6 * e : 6 * e + 6]]
        side = fmul(ray_m[2], rows[5])
        side = fma(ray_m[1], rows[4], side)
        side = fma(ray_m[0], rows[3], side)
        side = fma(ray_d[2], rows[2], side)
        side = fma(ray_d[1], rows[1], side)
        sides.append(fma(ray_d[0], rows[0], side))
    u, v, w = sides
    # inside unless one side is below -tol and another above tol (any NaN: inside)
    neg = lt(smaller(smaller(u, v), w), ntol)
    pos = lt(tol, larger(larger(u, v), w))
    inside = builder.not_(builder.and_(neg, pos))
    # the plane function n . x + c (c = -n . v0) at the span's ends: beyond the bound and of
    # one sign at both, the plane is crossed outside the span (any NaN: a candidate; unused
    # lanes, n = 0 and c = inf, never are)
    nx, ny, nz, c = (load(off) for off in plane_offsets)
    f0 = fma(nx, near_point[0], fma(ny, near_point[1], fma(nz, near_point[2], c)))
    f1 = fma(nx, far_point[0], fma(ny, far_point[1], fma(nz, far_point[2], c)))
    # both ends beyond the bound on one side: the nearer of the two to zero is. smaller / larger
    # return f1 where either is NaN, and f1 is NaN wherever f0 is (but for tmin = inf, an empty
    # span), so a NaN still fails both tests
    above = lt(bound, smaller(f0, f1))
    below = lt(larger(f0, f1), nbound)
    candidate = builder.and_(inside, builder.not_(builder.or_(above, below)))
    prims = load(prim_offset)
    an_end = builder.or_(*(builder.fcmp_ordered("==", prims, end) for end in ends))
    candidate = builder.and_(candidate, builder.not_(an_end))
    bits = builder.zext(builder.bitcast(candidate, ir.IntType(n)), i64)
    mask = builder.or_(mask_in, builder.shl(bits, builder.mul(g, ir.Constant(i64, n))))
    g_next = builder.add(g, ir.Constant(i64, 1))
    builder.cbranch(builder.icmp_signed("<", g_next, groups), loop, done)
    g.add_incoming(ir.Constant(i64, 0), entry)
    g.add_incoming(g_next, loop)
    mask_in.add_incoming(ir.Constant(i64, 0), entry)
    mask_in.add_incoming(mask, loop)
    builder.position_at_end(done)
    return mask


def _reciprocal_bound(builder, x):
    """A power of two at least 1 / x for a float32 x >= 0 widened to float64 (+inf for 0, 0 for
    inf and NaN, as 2 R / D's uses want them), from the exponent's bits: x >= 2^e, so 1 / x <=
    2^-e, at most twice 1 / x. A division's ~13 cycles of latency sat on every ray's way to its
    mask (the span's far end waits for it)."""
    i64, f64 = ir.IntType(64), ir.DoubleType()
    exponent = builder.and_(builder.bitcast(x, i64), ir.Constant(i64, 0x7FF0000000000000))
    # 2^(1023 - E) has the biased exponent 2046 - E: exact for E in 1 .. 2045, which holds every
    # finite float32 but 0 (its subnormals are normal in float64)
    flipped = builder.bitcast(builder.sub(ir.Constant(i64, 0x7FE0000000000000), exponent), f64)
    zero = builder.icmp_unsigned("==", exponent, ir.Constant(i64, 0))
    special = builder.icmp_unsigned("==", exponent, ir.Constant(i64, 0x7FF0000000000000))
    out = builder.select(zero, ir.Constant(f64, float("inf")), flipped)
    return builder.select(special, ir.Constant(f64, 0.0), out)


@intrinsic
def sweep_candidates(typingctx, table, o, d, tmin, tmax, leaving, arriving):
    """Bit r set for each lane r of the sweep table that the exact test may hit in (tmin, tmax)
    (module docstring), but the lanes of primitives `leaving` and `arriving` (sweep_hit)."""
    if not (
        isinstance(table, types.Array) and table.dtype == types.float32 and table.ndim == 2 and table.layout == "C"
    ):
        raise TypingError("sweep_candidates: table must be a C-contiguous float32 (SWEEP_ROWS, SWEEP_LANES) array")
    return types.int64(table, o, d, tmin, tmax, leaving, arriving), _lanes_codegen


@inline_function
def _next_row(mask, row):
    """(the lowest candidate row of mask, or `row` when none is left; mask without it; whether one was)."""
    if mask == 0:
        return row, mask, False
    return lowest_bit(mask), mask & (mask - 1), True


@inline_function
def sweep_hit(G, X, o, d, shear, lazy_shear, tmin, best_t, prim, b1, b2, stop_at_first, leaving, arriving):
    """The nearest hit in (tmin, best_t) among a swept scene's bounded primitives (module
    docstring), or (best_t, prim, b1, b2) unchanged; with stop_at_first, the first hit found.
    `leaving`: the primitive the ray leaves from (NO_HIT: none), its origin offset to the side
    it goes to, and `arriving`: the one a shadow ray is aimed at, ending short of it
    (shadow.shadow_ray): the exact test cannot hit either if it is flat (a triangle or a
    polygon's), so they are left out of the candidates (each such ray has them among them
    otherwise). With lazy_shear, `shear` is computed here, for a ray with primitives to test.
    The same hit as the exact test of every primitive in table order (the lowest triangle row
    on ties)."""
    S = G.sweep
    mask = sweep_candidates(S, o, d, tmin, best_t, leaving, arriving)
    if lazy_shear and (mask != 0 or S[SWEEP_OTHER, 0] >= 0.0):
        shear = ray_shear(d)  # the exact tests' constants, for a ray with something to test
    n_tris = np.int64(G.triangles.shape[0])  # the lanes before the polygons' (sweep_table)
    rest = mask >> n_tris  # candidate polygons' triangles
    mask &= (np.int64(1) << n_tris) - 1
    while mask != 0:
        r0 = lowest_bit(mask)
        mask &= mask - 1
        if mask == 0:  # one candidate (most rays): from the column table, one load a coordinate
            t, j, u, v = intersect_triangle_block(o, shear, G.triangles, G.triangle_columns, r0, 1, tmin, best_t)
            row = r0
        else:
            r1, mask, ok1 = _next_row(mask, r0)
            r2, mask, ok2 = _next_row(mask, r0)
            r3, mask, ok3 = _next_row(mask, r0)
            count = 1 + ok1 + ok2 + ok3
            t, j, u, v = triangles4_gathered(G.triangles, (r0, r1, r2, r3), count, o, shear, tmin, best_t)
            row = r0 if j == 0 else (r1 if j == 1 else (r2 if j == 2 else r3))
        if t < best_t:
            best_t, prim, b1, b2 = t, np.int64(S[SWEEP_PRIM, row]), u, v
            if stop_at_first:
                return best_t, prim, b1, b2
    last = NO_HIT
    while rest != 0:
        lane = n_tris + lowest_bit(rest)
        rest &= rest - 1
        k = np.int64(S[SWEEP_PRIM, lane])
        if k < 0:  # the unused lanes after the polygons' (a candidate only for a ray with a NaN)
            break
        if k == last:  # another triangle of the polygon just tested
            continue
        last = k
        t, u, v = intersect(G, X, k, o, d, shear, tmin, best_t)
        if t < best_t:
            best_t, prim, b1, b2 = t, k, u, v
            if stop_at_first:
                return best_t, prim, b1, b2
    for i in range(SWEEP_OTHERS):
        k = np.int64(S[SWEEP_OTHER, i])
        if k < 0:
            break
        t, u, v = intersect(G, X, k, o, d, shear, tmin, best_t)
        if t < best_t:
            best_t, prim, b1, b2 = t, k, u, v
            if stop_at_first:
                break
    return best_t, prim, b1, b2
