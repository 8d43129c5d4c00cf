"""Triangles, alone or from meshes: float32 vertices (T, 9) in BVH leaf order, optional
vertex normals (smooth shading) and UVs. The watertight ray-triangle test of Woop, Benthin
and Wald (2013)."""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import add, cross, dot, element, inline_function, kernel_function, mul, normalize, row3, stack_element, sub

INF = math.inf
BOUNDED = True


# Inlined: a call returned the six constants through memory (the Cornell box in path mode ~0.98x
# the time inlined, 6 alternating rounds against the call).
@inline_function
def ray_shear(d):
    """Per-ray constants of the watertight test."""
    kx, ky, kz = shear_axes(d)
    sz = 1.0 / _component(d, kz)
    return kx, ky, kz, _component(d, kx) * sz, _component(d, ky) * sz, sz


@inline_function
def _component(v, k):
    """v[k] for a runtime k in 0..2, without a branch (vec.element): as two selects it compiled
    to jumps on x86, and the dominant axis of diffuse bounces is random, so they were
    mispredicted every other ray (the shear took ~15 ns in a loop of random directions, ~4.5
    ns without)."""
    return element(v, k)


@inline_function
def shear_axes(d):
    """The watertight test's axis order for direction d: kz its dominant axis (the first of
    equal ones but y over z), (kx, ky) the other two in the order that keeps the triangles'
    winding. Without branches: the dominant axis and the sign of d along it are random for
    diffuse bounces, and as branches they were mispredicted every other ray."""
    ax, ay, az = abs(d[0]), abs(d[1]), abs(d[2])
    y_wins = (ay > ax) & (ay >= az)
    z_wins = (az > ax) & (az > ay)
    kz = np.int64(y_wins) + 2 * np.int64(z_wins)
    kx = kz + 1 - 3 * np.int64(kz == 2)  # (kz + 1) % 3, (kx + 1) % 3 without divisions
    ky = kx + 1 - 3 * np.int64(kx == 2)
    if _component(d, kz) < 0.0:
        return ky, kx, kz
    return kx, ky, kz


# Shear constants for rays in scenes without triangles (never used, but typed alike).
NO_SHEAR = (0, 1, 2, 0.0, 0.0, 1.0)


# No fastmath here: contracting a*b - c*d into a fused multiply-add would make the edge
# functions of two triangles sharing an edge differ, and rays through the edge could slip by.
# Said explicitly: a function that leaves fastmath unset inherits its caller's flags in Numba,
# and every caller is a fast-math kernel.
@kernel_function(error_model="numpy", _nrt=False, fastmath=False)
def intersect_triangle(o, shear, tri, i, tmin, tmax):
    """Watertight ray-triangle test against row i of tri (float32 (T, 9): v0, v1, v2).

    Returns (t, b1, b2): b1, b2 are the barycentric weights of v1 and v2. Edges shared by two
    triangles are evaluated identically from both sides, so closed meshes have no pinholes."""
    kx, ky, kz, sx, sy, sz = shear
    # the origin's components by _component: a tuple indexed at run time (o[kx]) compiles to a
    # switch over the index, jumps mispredicted on random rays
    ox, oy, oz = _component(o, kx), _component(o, ky), _component(o, kz)
    ax = tri[i, kx] - ox
    ay = tri[i, ky] - oy
    az = tri[i, kz] - oz
    bx = tri[i, 3 + kx] - ox
    by = tri[i, 3 + ky] - oy
    bz = tri[i, 3 + kz] - oz
    cx = tri[i, 6 + kx] - ox
    cy = tri[i, 6 + ky] - oy
    cz = tri[i, 6 + kz] - oz
    ax -= sx * az
    ay -= sy * az
    bx -= sx * bz
    by -= sy * bz
    cx -= sx * cz
    cy -= sy * cz
    u = cx * by - cy * bx
    v = ax * cy - ay * cx
    w = bx * ay - by * ax
    # Edge functions within a hair of zero count as inside: a margin beyond exact arithmetic
    # (a ray exactly through a shared edge must hit at least one of the two triangles, however
    # a future compiler rounds).
    tol = 1e-12 * (abs(u) + abs(v) + abs(w))
    if (u < -tol or v < -tol or w < -tol) and (u > tol or v > tol or w > tol):
        return INF, 0.0, 0.0
    det = u + v + w
    if det == 0.0:
        return INF, 0.0, 0.0
    t = (u * az + v * bz + w * cz) * sz / det
    if t > tmin and t < tmax:
        return t, min(max(v / det, 0.0), 1.0), min(max(w / det, 0.0), 1.0)
    return INF, 0.0, 0.0


# --- four triangles at once (BVH leaves) --------------------------------------------------------

TRIANGLES_PER_TEST = 4  # lanes of intersect_triangles: 4 float64 in one AVX2 register


def _triangles_codegen(context, builder, sig, args):
    """intersect_triangle's arithmetic on 4 consecutive rows as <4 x double> vectors, operation
    for operation (IEEE, no fast-math flags, no FMA contraction): each lane's t, b1, b2 are
    bit-identical to the scalar test's. The rows' columns gathered from the (T, 9) table."""
    return _block_codegen(context, builder, sig, args, columns=False)


def _columns_codegen(context, builder, sig, args):
    """The same test reading the rows from the (9, T + COLUMN_PAD) column table (triangle_columns):
    each of the nine columns is one vector load instead of four scalar loads and inserts."""
    return _block_codegen(context, builder, sig, args, columns=True)


def _gathered_codegen(context, builder, sig, args):
    """The same test on four rows given by index (sweep.py's candidates): a tuple of four rows in
    place of `first`, lanes past count masked."""
    return _block_codegen(context, builder, sig, args, columns=False, gathered=True)


def _block_codegen(context, builder, sig, args, columns, gathered=False):
    n = TRIANGLES_PER_TEST
    f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
    v4 = ir.VectorType(f64, n)
    undef = ir.Constant(v4, ir.Undefined)
    zero_idx = ir.Constant(ir.VectorType(i32, n), [0] * n)
    tri_t, first_t, count_t, o_t, shear_t, tmin_t, tmax_t = sig.args
    tri = context.make_array(tri_t)(context, builder, args[0])
    given = None
    if gathered:
        given = [
            context.cast(builder, r, t, types.int64)
            for r, t in zip(cgutils.unpack_tuple(builder, args[1], n), first_t, strict=True)
        ]
        first = ir.Constant(i64, 0)
    else:
        first = context.cast(builder, args[1], first_t, types.int64)
    count = context.cast(builder, args[2], count_t, types.int64)
    o = [
        context.cast(builder, x, t, types.float64)
        for x, t in zip(cgutils.unpack_tuple(builder, args[3], 3), o_t, strict=True)
    ]
    sh = cgutils.unpack_tuple(builder, args[4], 6)
    axes = [context.cast(builder, sh[i], shear_t[i], types.int64) for i in range(3)]
    sx, sy, sz = (context.cast(builder, sh[3 + i], shear_t[3 + i], types.float64) for i in range(3))
    tmin = context.cast(builder, args[5], tmin_t, types.float64)
    tmax = context.cast(builder, args[6], tmax_t, types.float64)

    def splat(x):
        return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(i32, 0)), undef, zero_idx)

    cols = block_columns(builder, tri, first, count, axes, columns, given)
    # o[k] for a runtime k in 0..2, without a branch (vec.stack_element)
    origin = [splat(stack_element(builder, o, k)) for k in axes]
    hit = block_test(builder, cols, origin, splat(sx), splat(sy), splat(sz), tmin, tmax, count)
    return context.make_tuple(builder, sig.return_type, hit)


def block_columns(builder, tri, first, count, axes, columns=False, given=None):
    """The vertex columns of rows first .. first + 3 of tri (an array structure: the (T, 9) row
    table, or with `columns` the (9, T + COLUMN_PAD) column table) for block_test: nine <4 x
    double>, a's, b's and c's coordinates in the axis order `axes` (kx, ky, kz, i64s at run
    time). From the row table each column is four scalar loads and inserts, the lanes past
    count repeating the last row; from the column table one load (lanes past count read the
    next rows or the table's padding). With `given` (four row indices, the caller repeating a
    row in the lanes past count), those rows instead of first .. first + 3."""
    n = TRIANGLES_PER_TEST
    f32, f64, i32, i64 = ir.FloatType(), ir.DoubleType(), ir.IntType(32), ir.IntType(64)
    v4 = ir.VectorType(f64, n)
    if columns:
        stride = builder.extract_value(tri.strides, 0)
        base = builder.add(builder.ptrtoint(tri.data, i64), builder.mul(first, ir.Constant(i64, 4)))
        v4f = ir.VectorType(f32, n)

        def column(c):
            address = builder.add(base, builder.mul(c, stride))
            return builder.fpext(builder.load(builder.inttoptr(address, v4f.as_pointer()), align=4), v4)

    else:
        last = builder.sub(count, ir.Constant(i64, 1))
        rows = []
        for j in range(n):
            jj = ir.Constant(i64, j)
            if given is not None:
                rows.append(builder.mul(given[j], ir.Constant(i64, 9)))
                continue
            lane = builder.select(builder.icmp_signed("<", jj, count), jj, last)
            rows.append(builder.mul(builder.add(first, lane), ir.Constant(i64, 9)))

        def column(c):
            vec = ir.Constant(ir.VectorType(f32, n), ir.Undefined)
            for j in range(n):
                p = builder.gep(tri.data, [builder.add(rows[j], c)], inbounds=True)
                vec = builder.insert_element(vec, builder.load(p, align=4), ir.Constant(i32, j))
            return builder.fpext(vec, v4)

    return [column(builder.add(k, ir.Constant(i64, vertex))) for vertex in (0, 3, 6) for k in axes]


def block_test(builder, cols, origin, sx, sy, sz, tmin, tmax, count, undivided=False):
    """The watertight test of one ray against the four triangles of a block, from their vertex
    columns `cols` (<4 x double>: a's, b's, c's coordinates in the shear's axis order kx, ky,
    kz; lanes past `count` masked), the origin in that order and the shear constants as splats,
    tmin and tmax scalars: (t, lane, b1, b2) of the nearest hit in (tmin, tmax), the lowest lane
    on ties; t = +inf, lane 0 and b1 = b2 = 0 when none. intersect_triangle's arithmetic
    operation for operation (IEEE, no contraction). With `undivided`, (t, lane, v, w, det): the
    nearest lane's barycentrics before their divisions by det (0, 0 and 1 when none), which the
    caller divides once its traversal is done (packet_finish, for packet_triangles_each)."""
    n = TRIANGLES_PER_TEST
    f64, i32, i64 = ir.DoubleType(), ir.IntType(32), ir.IntType(64)
    v4 = ir.VectorType(f64, n)
    undef = ir.Constant(v4, ir.Undefined)
    zero_idx = ir.Constant(ir.VectorType(i32, n), [0] * n)

    def splat(x):
        return builder.shuffle_vector(builder.insert_element(undef, x, ir.Constant(i32, 0)), undef, zero_idx)

    _, fsub, _, lt = exact_ops(builder)
    rel = tuple(fsub(cols[j], origin[j % 3]) for j in range(9))
    _, v, w, det, num, inside = watertight_edges(builder, rel, sx, sy)
    lanes = ir.Constant(ir.VectorType(i64, n), list(range(n)))
    inside = builder.and_(inside, builder.icmp_signed("<", lanes, splat_i64(builder, count, n)))
    zero, one = ir.Constant(f64, 0.0), ir.Constant(f64, 1.0)
    inf = ir.Constant(f64, float("inf"))
    # Most blocks a ray tests pass by all four triangles (a shadow ray's always, when it is
    # unblocked): the division for t and the barycentrics' two, a chain of ~40 cycles that the
    # next leaf's test waits for (its tmax), only where the ray passes inside one. Nor where it
    # passes inside only triangles behind its origin: a ray leaving a surface (a shadow ray, a
    # bounce) passes inside its own triangle, at t <= 0. The sign of t is the sign of the
    # numerator times the denominator's (a division never flips it, and a zero numerator gives
    # a zero t), so with tmin >= 0 those lanes fail `tmin < t` whatever the division rounds to.
    behind = behind_origin(builder, num, det, sz)
    bits = ir.IntType(n)
    none = ir.Constant(bits, 0)
    inside_ahead = builder.icmp_unsigned("!=", builder.bitcast(builder.and_(inside, builder.not_(behind)), bits), none)
    tmin_negative = builder.not_(builder.fcmp_ordered(">=", tmin, ir.Constant(f64, 0.0), flags=EXACT))
    entry = builder.block
    with builder.if_then(
        builder.and_(
            builder.icmp_unsigned("!=", builder.bitcast(inside, bits), none), builder.or_(inside_ahead, tmin_negative)
        )
    ):
        t, ok = watertight_distance(builder, num, det, inside, sz, splat(tmin), splat(tmax))
        tt = builder.select(ok, t, ir.Constant(v4, [float("inf")] * n))
        hit_t, hit_j = nearest_lane(builder, tt, n)
        vj = builder.extract_element(v, hit_j)
        wj = builder.extract_element(w, hit_j)
        dj = builder.extract_element(det, hit_j)
        # the barycentrics of the nearest lane, clamped to [0, 1] as the scalar test clamps them
        # (0 when nothing is hit)
        found = lt(hit_t, tmax)

        def barycentric(x):
            q = builder.fdiv(x, dj, flags=EXACT_DIVISION)
            q = builder.select(builder.fcmp_ordered(">", q, zero, flags=EXACT), q, zero)
            q = builder.select(lt(q, one), q, one)
            return builder.select(found, q, zero)

        if undivided:
            outputs = ((hit_t, inf), (hit_j, ir.Constant(i64, 0)), (vj, zero), (wj, zero), (dj, one))
        else:
            hit_b1, hit_b2 = barycentric(vj), barycentric(wj)
            outputs = ((hit_t, inf), (hit_j, ir.Constant(i64, 0)), (hit_b1, zero), (hit_b2, zero))
        tested = builder.block
    values = []
    for value, missed in outputs:
        phi = builder.phi(value.type)
        phi.add_incoming(value, tested)
        phi.add_incoming(missed, entry)
        values.append(phi)
    return values


def watertight_edges(builder, rel, sx, sy):
    """The first half of watertight_lanes, without a division: (u, v, w, det, num, inside):
    the edge functions, their sum, t's numerator before the shear's scale, and the lanes where
    the ray passes inside the triangle (det nonzero)."""
    fadd, fsub, fmul, lt = exact_ops(builder)
    ax, ay, az, bx, by, bz, cx, cy, cz = rel
    vt = ax.type
    ax = fsub(ax, fmul(sx, az))
    ay = fsub(ay, fmul(sy, az))
    bx = fsub(bx, fmul(sx, bz))
    by = fsub(by, fmul(sy, bz))
    cx = fsub(cx, fmul(sx, cz))
    cy = fsub(cy, fmul(sy, cz))
    u = fsub(fmul(cx, by), fmul(cy, bx))
    v = fsub(fmul(ax, cy), fmul(ay, cx))
    w = fsub(fmul(bx, ay), fmul(by, ax))
    fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vt, [vt]), f"llvm.fabs.v{vt.count}f64")
    tol = fmul(
        ir.Constant(vt, [1e-12] * vt.count),
        fadd(fadd(builder.call(fabs, [u]), builder.call(fabs, [v])), builder.call(fabs, [w])),
    )
    ntol = builder.fneg(tol, flags=EXACT)
    neg = builder.or_(builder.or_(lt(u, ntol), lt(v, ntol)), lt(w, ntol))
    pos = builder.or_(builder.or_(lt(tol, u), lt(tol, v)), lt(tol, w))
    det = fadd(fadd(u, v), w)
    num = fadd(fadd(fmul(u, az), fmul(v, bz)), fmul(w, cz))
    inside = builder.and_(
        builder.not_(builder.and_(neg, pos)),
        builder.fcmp_unordered("!=", det, ir.Constant(vt, [0.0] * vt.count), flags=EXACT),
    )
    return u, v, w, det, num, inside


def behind_origin(builder, num, det, sz):
    """The lanes whose t (watertight_distance's num * sz / det) is at most 0, without the
    division: the product's sign and the denominator's differ, or the product is 0 (a division
    never flips a sign). With tmin >= 0 no such lane is a hit, whatever the division rounds to."""
    vt = num.type
    vi = ir.VectorType(ir.IntType(64), vt.count)
    num_sz = builder.fmul(num, sz, flags=EXACT)
    sign_differs = builder.icmp_signed(
        "<", builder.xor(builder.bitcast(num_sz, vi), builder.bitcast(det, vi)), ir.Constant(vi, [0] * vt.count)
    )
    return builder.or_(sign_differs, builder.fcmp_ordered("==", num_sz, ir.Constant(vt, [0.0] * vt.count), flags=EXACT))


def watertight_distance(builder, num, det, inside, sz, tmin, tmax):
    """The second half of watertight_lanes: (t, ok), ok where the ray hits inside (tmin, tmax)."""
    _, _, fmul, lt = exact_ops(builder)
    t = builder.fdiv(fmul(num, sz), det, flags=EXACT_DIVISION)
    return t, builder.and_(inside, builder.and_(lt(tmin, t), lt(t, tmax)))


def watertight_lanes(builder, rel, sx, sy, sz, tmin, tmax):
    """intersect_triangle's arithmetic from the vertices relative to the origin onwards, on
    float64 vectors (one triangle and ray pair a lane; this test's four triangles against one
    ray, packet.py's one triangle against eight rays), in IEEE instructions that Numba's
    fast-math pass leaves alone. rel: (ax, ay, az, bx, by, bz, cx, cy, cz), the vertices minus
    the origin in the shear's axis order; sx, sy, sz, tmin, tmax vectors too. Returns
    (t, v, w, det, ok): ok where the ray hits inside (tmin, tmax); b1, b2 are v / det, w / det."""
    u, v, w, det, num, inside = watertight_edges(builder, rel, sx, sy)
    t, ok = watertight_distance(builder, num, det, inside, sz, tmin, tmax)
    return t, v, w, det, ok


# Flags that change nothing for these instructions: 'arcp' only matters to divisions, and
# 'nsz' on a division only to the sign of a zero result, which the callers never depend on.
# Numba's fast-math pass adds its flags (contraction into FMAs among them) only to float
# instructions that have none, so the block tests, inlined into fast-math kernels, round there
# exactly as the scalar tests they are checked against.
EXACT = ("arcp",)
EXACT_DIVISION = ("nsz",)


def exact_ops(builder):
    """(fadd, fsub, fmul, lt) emitting IEEE instructions that Numba's fast-math pass leaves alone."""

    def fadd(a, b):
        return builder.fadd(a, b, flags=EXACT)

    def fsub(a, b):
        return builder.fsub(a, b, flags=EXACT)

    def fmul(a, b):
        return builder.fmul(a, b, flags=EXACT)

    def lt(a, b):
        return builder.fcmp_ordered("<", a, b, flags=EXACT)

    return fadd, fsub, fmul, lt


def nearest_lane(builder, t, n):
    """(t, lane) of the smallest of the n lanes of vector t, the lowest lane on ties (as a scalar
    loop keeping the first of equal hits), in LLVM IR."""
    i32, i64 = ir.IntType(32), ir.IntType(64)
    best_t = builder.extract_element(t, ir.Constant(i32, 0))
    best_j = ir.Constant(i64, 0)
    for j in range(1, n):
        tj = builder.extract_element(t, ir.Constant(i32, j))
        nearer = builder.fcmp_ordered("<", tj, best_t, flags=EXACT)
        best_t = builder.select(nearer, tj, best_t)
        best_j = builder.select(nearer, ir.Constant(i64, j), best_j)
    return best_t, best_j


def splat_i64(builder, x, n):
    i32 = ir.IntType(32)
    vt = ir.VectorType(ir.IntType(64), n)
    undef = ir.Constant(vt, ir.Undefined)
    return builder.shuffle_vector(
        builder.insert_element(undef, x, ir.Constant(i32, 0)),
        undef,
        ir.Constant(ir.VectorType(i32, n), [0] * n),
    )


@intrinsic
def _triangles4(typingctx, tri, first, count, o, shear, tmin, tmax):
    if not (isinstance(tri, types.Array) and tri.dtype == types.float32 and tri.ndim == 2 and tri.layout == "C"):
        raise TypingError("_triangles4: tri must be a C-contiguous float32 (T, 9) array")
    ret = types.Tuple((types.float64, types.int64, types.float64, types.float64))
    return ret(tri, first, count, o, shear, tmin, tmax), _triangles_codegen


@intrinsic
def _triangles4_columns(typingctx, cols, first, count, o, shear, tmin, tmax):
    if not (isinstance(cols, types.Array) and cols.dtype == types.float32 and cols.ndim == 2 and cols.layout == "C"):
        raise TypingError("_triangles4_columns: cols must be a C-contiguous float32 (9, T + COLUMN_PAD) array")
    ret = types.Tuple((types.float64, types.int64, types.float64, types.float64))
    return ret(cols, first, count, o, shear, tmin, tmax), _columns_codegen


@intrinsic
def triangles4_gathered(typingctx, tri, rows, count, o, shear, tmin, tmax):
    """intersect_triangles on rows rows[0 .. count - 1] of tri (float32 (T, 9)), rows a tuple of
    four int64 (those past count repeat a valid row): (t, lane, b1, b2), each lane's numbers
    bit-identical to intersect_triangle's, the lowest lane on ties."""
    if not (isinstance(tri, types.Array) and tri.dtype == types.float32 and tri.ndim == 2 and tri.layout == "C"):
        raise TypingError("triangles4_gathered: tri must be a C-contiguous float32 (T, 9) array")
    ret = types.Tuple((types.float64, types.int64, types.float64, types.float64))
    return ret(tri, rows, count, o, shear, tmin, tmax), _gathered_codegen


@inline_function
def intersect_triangle_block(o, shear, tri, cols, first, count, tmin, tmax):
    """intersect_triangles, reading the rows from the column table where the scene has one
    (triangle_columns): the same result, to the bit."""
    if cols.shape[1] > COLUMN_PAD:
        return _triangles4_columns(cols, first, count, o, shear, tmin, tmax)
    return _triangles4(tri, first, count, o, shear, tmin, tmax)


COLUMN_PAD = TRIANGLES_PER_TEST  # zero columns after the last triangle: the last block's load stays inside
# Scenes up to this many triangles get the column table. Above it, where the triangles no longer
# stay in cache, a block's nine columns are nine cache lines against the rows' two or three:
# bumpy 1M single-ray hits took 15% more time with it, shadow rays 22%; bumpy 40k the same; the
# Cornell box (30 triangles) in path mode 7% less (alternating builds, CPU time).
COLUMNS_UP_TO = 4096


def triangle_columns(triangles):
    """The (T, 9) triangle table by columns, float32 (9, T + COLUMN_PAD), in scenes of at most
    COLUMNS_UP_TO triangles: column c of rows r .. r + 3 is one 16-byte load for the block test
    (a leaf's four rows are 36 scalar loads and inserts in the row table). Larger scenes get an
    empty (9, COLUMN_PAD) table, and their blocks are read from the rows (intersect_triangle_block)."""
    import numpy as np

    if len(triangles) > COLUMNS_UP_TO:
        return np.zeros((9, COLUMN_PAD), np.float32)
    cols = np.zeros((9, len(triangles) + COLUMN_PAD), np.float32)
    cols[:, : len(triangles)] = np.asarray(triangles, np.float32).T
    return cols


def face_normals(triangles):
    """Each triangle's unit face normal, (v1 - v0) x (v2 - v0) normalized in float64, as float64
    (T, 3), in scenes of at most COLUMNS_UP_TO triangles (empty (0, 3) above: `normals` then
    computes it at the hit). Read at a hit instead of computed there: the normalization's square
    root and division (~35 cycles) sat between every hit and its shading (the Cornell box in path
    mode, ~2% of its time)."""
    import numpy as np

    if len(triangles) > COLUMNS_UP_TO:
        return np.zeros((0, 3))
    return unit_normals(triangles)


def unit_normals(triangles):
    """float64 (T, 3): each triangle's (v1 - v0) x (v2 - v0) normalized in float64, zero for a
    degenerate one (face_normals' table, and the sweep's lane planes)."""
    import numpy as np

    v = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    length = np.sqrt(np.einsum("ij,ij->i", n, n))
    return np.divide(n, length[:, None], out=np.zeros_like(n), where=length[:, None] > 0.0)


# The KernelScene fields made from its triangle table: wherever the triangles change (compiling,
# unpickling, the rasterizer's flattened instances), all of them are made again together.
TRIANGLE_TABLES = ("triangle_columns", "triangle_face_normals")


def triangle_tables(triangles) -> dict:
    """The fields TRIANGLE_TABLES of a scene whose triangle table is `triangles`."""
    return {"triangle_columns": triangle_columns(triangles), "triangle_face_normals": face_normals(triangles)}


# Inlined into the traversal (a call per leaf passed the arrays and spilled the ray's state: the
# hit rays of a 10k-triangle mesh took 6-9% longer); its arithmetic is protected from the
# caller's fast-math flags inside _triangles_codegen.
@inline_function
def intersect_triangles(o, shear, tri, first, count, tmin, tmax):
    """The watertight test against rows first .. first + count - 1 (count <= 4) of tri at once:
    (t, lane, b1, b2) of the nearest hit in (tmin, tmax), the lowest lane on ties; t = +inf
    when none. The same result as intersect_triangle row by row, to the last bit."""
    return _triangles4(tri, first, count, o, shear, tmin, tmax)


@inline_function
def normals(G, i, b1, b2):
    """(geometric normal, shading normal) of triangle i at barycentrics (b1, b2): the face
    normal by the winding (v1 - v0) x (v2 - v0), and the interpolated vertex normals when
    the mesh is smooth."""
    if i < G.triangle_face_normals.shape[0]:  # small scenes: made once (face_normals)
        ng = row3(G.triangle_face_normals, i, 0)
    else:
        tri = G.triangles
        v0 = row3(tri, i, 0)
        ng = normalize(cross(sub(row3(tri, i, 3), v0), sub(row3(tri, i, 6), v0)))
    ns = ng
    if G.triangle_smooth[i]:
        b0 = 1.0 - b1 - b2
        nrm = G.triangle_normals
        s = add(add(mul(row3(nrm, i, 0), b0), mul(row3(nrm, i, 3), b1)), mul(row3(nrm, i, 6), b2))
        if dot(s, s) > 0.0:
            ns = normalize(s)
    return ng, ns


@kernel_function
def uv(G, i, b1, b2):
    """The mesh's UVs interpolated; without UVs (and for a `triangle` object) the vertices sit
    at (0, 0), (1, 0), (0, 1)."""
    uvs = G.triangle_uvs
    if uvs.shape[0] <= i:
        return b1, b2
    b0 = 1.0 - b1 - b2
    return (b0 * uvs[i, 0] + b1 * uvs[i, 2] + b2 * uvs[i, 4], b0 * uvs[i, 1] + b1 * uvs[i, 3] + b2 * uvs[i, 5])


@kernel_function
def uv_change(G, i, a):
    """Change of the triangle's (u, v) along the vector a in its plane (texture filtering):
    a = e1 db1 + e2 db2 solved for the barycentric change by least squares."""
    tri = G.triangles
    v0 = row3(tri, i, 0)
    e1 = sub(row3(tri, i, 3), v0)
    e2 = sub(row3(tri, i, 6), v0)
    a11 = dot(e1, e1)
    a12 = dot(e1, e2)
    a22 = dot(e2, e2)
    det = a11 * a22 - a12 * a12
    if not (det > 0.0):  # degenerate: never hit, but no division by zero either
        return 0.0, 0.0
    r1 = dot(a, e1)
    r2 = dot(a, e2)
    db1 = (a22 * r1 - a12 * r2) / det
    db2 = (a11 * r2 - a12 * r1) / det
    uvs = G.triangle_uvs
    if uvs.shape[0] <= i:
        return db1, db2
    return (
        db1 * (uvs[i, 2] - uvs[i, 0]) + db2 * (uvs[i, 4] - uvs[i, 0]),
        db1 * (uvs[i, 3] - uvs[i, 1]) + db2 * (uvs[i, 5] - uvs[i, 1]),
    )


# --- emission (path mode samples emissive triangles) -------------------------------------------


@kernel_function
def sample(G, i, u1, u2):
    """A uniform point on triangle i for (u1, u2) in [0, 1)^2, and its face normal."""
    tri = G.triangles
    s = math.sqrt(u1)
    v0 = row3(tri, i, 0)
    e1 = sub(row3(tri, i, 3), v0)
    e2 = sub(row3(tri, i, 6), v0)
    return add(add(v0, mul(e1, 1.0 - s)), mul(e2, u2 * s)), normalize(cross(e1, e2))


def area(triangles):
    """One side's area of each of (T, 9) triangles."""
    import numpy as np

    v = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
