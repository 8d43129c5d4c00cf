"""Sphere: centre and radius. Row of the analytic shape table: centre (3), radius, whether it is
turned (1.0) or not (0.0), and when turned its object axes x, y, z in world space (9), which
orient its UVs."""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import dot, inline_function, kernel_function, normalize, row3, sub
from .shape_triangle import EXACT, EXACT_DIVISION, exact_ops, nearest_lane, splat_i64
from .transform import transform_point, uniform_scale

INF = math.inf
CENTER = 0
RADIUS = 3
TURNED = 4
AXES = 5  # the object's x, y, z axes in world space, unit vectors (a mirror's included)
BOUNDED = True


def pack(obj, m: np.ndarray) -> list[float]:
    """The sphere's row, its transform m (4x4, object to world, a similarity) applied."""
    if np.array_equal(m, np.eye(4)):  # as written, to the bit
        return [*obj.center, obj.radius, 0.0]
    scale = uniform_scale(m)
    axes = m[:3, :3] / scale  # orthonormal: columns are the object's axes
    turned = not np.array_equal(axes, np.eye(3))
    return [*transform_point(m, obj.center), obj.radius * scale, float(turned), *axes.T.ravel()]


def solid(row) -> tuple:
    """The sphere as a solid (compile/media.py): (point -> inside?, a point of its surface,
    its volume)."""
    centre, radius = np.asarray(row[CENTER : CENTER + 3]), float(row[RADIUS])

    def inside(p) -> bool:
        return float(np.sum((np.asarray(p) - centre) ** 2)) < radius * radius

    return inside, centre + (0.0, radius, 0.0), 4.0 / 3.0 * np.pi * radius**3


def bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return rows[:, CENTER : CENTER + 3] - rows[:, RADIUS : RADIUS + 1], rows[:, CENTER : CENTER + 3] + rows[
        :, RADIUS : RADIUS + 1
    ]


# No fastmath (as the triangle test; explicitly, or it would inherit its fast-math callers'):
# the four-at-once test below must round exactly as this one does, and fused multiply-adds
# chosen by the compiler would differ between the two.
@kernel_function(error_model="numpy", _nrt=False, fastmath=False)
def intersect_sphere(o, d, center, radius, tmin, tmax):
    """The seed's quadratic in a stable form (Ray Tracing Gems ch. 7): the discriminant is
    computed from the ray's closest approach, and the second root via Vieta, so neither a
    radius-5000 sphere nor a grazing ray loses precision to cancellation. Unit d; the hit
    distance in (tmin, tmax) or +inf."""
    cx = o[0] - center[0]
    cy = o[1] - center[1]
    cz = o[2] - center[2]
    b = cx * d[0] + cy * d[1] + cz * d[2]  # half the seed's b, with a = dot(D, D) = 1
    c = (cx * cx + cy * cy + cz * cz) - radius * radius
    if c > 0.0 and b > 0.0:
        return INF  # outside, moving away: both roots are negative (tmin >= 0 always)
    px = cx - b * d[0]
    py = cy - b * d[1]
    pz = cz - b * d[2]
    disc = radius * radius - (px * px + py * py + pz * pz)
    if disc < 0.0:
        return INF
    q = -b - math.copysign(math.sqrt(disc), b)
    if q == 0.0:
        return INF
    t0 = c / q
    t1 = q
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tmin and t0 < tmax:
        return t0
    if t1 > tmin and t1 < tmax:
        return t1
    return INF


@inline_function
def sphere_hides_point(center, radius, p, n, w):
    """Does the sphere hide its own point of outward normal n (any length) from p, which looks at
    it along w? A convex body hides the points that face away, unless p is inside it. (A ray
    test shortened by a fraction of its length misses a sphere smaller than that fraction:
    bdpt's connections to such a sphere's far side, and into it, shone through.)"""
    oc = sub(p, center)
    return dot(oc, oc) > radius * radius and dot(n, w) > 0.0


def _spheres_codegen(context, builder, sig, args):
    """intersect_sphere's arithmetic on four spheres at once, one per lane of a 4 x float64
    vector (one ymm register on AVX2), in the same order of operations, so every lane rounds
    as the scalar test does."""
    n = 4
    f64 = ir.DoubleType()
    i32 = ir.IntType(32)
    i64 = ir.IntType(64)
    v4 = ir.VectorType(f64, n)
    undef = ir.Constant(v4, ir.Undefined)
    shapes = context.make_array(sig.args[0])(context, builder, args[0])
    rows = [
        context.cast(builder, r, t, types.int64)
        for r, t in zip(cgutils.unpack_tuple(builder, args[1], n), sig.args[1], strict=True)
    ]
    count = context.cast(builder, args[2], sig.args[2], types.int64)
    o = cgutils.unpack_tuple(builder, args[3], 3)
    d = cgutils.unpack_tuple(builder, args[4], 3)
    tmin = context.cast(builder, args[5], sig.args[5], types.float64)
    tmax = context.cast(builder, args[6], sig.args[6], types.float64)
    columns = builder.extract_value(shapes.shape, 1)  # C-contiguous: row r starts at r * columns

    def splat(x):
        return builder.shuffle_vector(
            builder.insert_element(undef, x, ir.Constant(i32, 0)), undef, ir.Constant(ir.VectorType(i32, n), [0] * n)
        )

    def column(c):
        vec = undef
        for j in range(n):
            at = builder.add(builder.mul(rows[j], columns), ir.Constant(i64, c))
            p = builder.gep(shapes.data, [at], inbounds=True)
            vec = builder.insert_element(vec, builder.load(p, align=8), ir.Constant(i32, j))
        return vec

    fadd, fsub, fmul, lt = exact_ops(builder)  # inlined into fast-math kernels: kept exact
    dx, dy, dz = splat(d[0]), splat(d[1]), splat(d[2])
    radius = column(RADIUS)
    cx = fsub(splat(o[0]), column(CENTER))
    cy = fsub(splat(o[1]), column(CENTER + 1))
    cz = fsub(splat(o[2]), column(CENTER + 2))
    b = fadd(fadd(fmul(cx, dx), fmul(cy, dy)), fmul(cz, dz))
    rr = fmul(radius, radius)
    c = fsub(fadd(fadd(fmul(cx, cx), fmul(cy, cy)), fmul(cz, cz)), rr)
    zero = ir.Constant(v4, [0.0] * n)

    def gt(a, b_):
        return lt(b_, a)

    away = builder.and_(gt(c, zero), gt(b, zero))
    px = fsub(cx, fmul(b, dx))
    py = fsub(cy, fmul(b, dy))
    pz = fsub(cz, fmul(b, dz))
    disc = fsub(rr, fadd(fadd(fmul(px, px), fmul(py, py)), fmul(pz, pz)))
    missed = lt(disc, zero)
    lanes = ir.Constant(ir.VectorType(i64, n), list(range(n)))
    used = builder.icmp_signed("<", lanes, splat_i64(builder, count, n))
    candidates = builder.and_(used, builder.not_(builder.or_(away, missed)))
    best_t_slot = cgutils.alloca_once_value(builder, ir.Constant(f64, float("inf")))
    best_j_slot = cgutils.alloca_once_value(builder, ir.Constant(i64, 0))
    # Most rays miss every sphere of a leaf: they skip the square root and the division (tens
    # of cycles each, where the scalar test returned after a few multiplications).
    anything = builder.icmp_unsigned("!=", builder.bitcast(candidates, ir.IntType(n)), ir.Constant(ir.IntType(n), 0))
    with builder.if_then(anything, likely=False):
        sqrt = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v4, [v4]), "llvm.sqrt.v4f64")
        copysign = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v4, [v4, v4]), "llvm.copysign.v4f64")
        q = fsub(builder.fneg(b, flags=EXACT), builder.call(copysign, [builder.call(sqrt, [disc]), b]))
        flat = builder.fcmp_ordered("==", q, zero, flags=EXACT)
        t0 = builder.fdiv(c, q, flags=EXACT_DIVISION)
        swap = gt(t0, q)
        near = builder.select(swap, q, t0)
        far = builder.select(swap, t0, q)
        lo, hi = splat(tmin), splat(tmax)

        def inside(t):
            return builder.and_(gt(t, lo), lt(t, hi))

        inf = ir.Constant(v4, [float("inf")] * n)
        t = builder.select(inside(near), near, builder.select(inside(far), far, inf))
        t = builder.select(builder.and_(candidates, builder.not_(flat)), t, inf)
        best_t, best_j = nearest_lane(builder, t, n)
        builder.store(best_t, best_t_slot)
        builder.store(best_j, best_j_slot)
    best_t = builder.load(best_t_slot)
    best_j = builder.load(best_j_slot)
    return context.make_tuple(builder, sig.return_type, [best_t, best_j])


@intrinsic
def intersect_spheres(typingctx, shapes, rows, count, o, d, tmin, tmax):
    """The ray against the spheres in rows[0 .. count-1] (count <= 4; unused rows must still be
    valid rows) of the analytic shape table `shapes` (float64, C-contiguous) at once:
    (t, lane) of the nearest hit in (tmin, tmax), the lowest lane on ties, t = +inf when none.
    The same result as intersect_sphere sphere by sphere, to the last bit."""
    if not (isinstance(shapes, types.Array) and shapes.dtype == types.float64 and shapes.ndim == 2):
        raise TypingError("intersect_spheres: shapes must be a float64 2-D array")
    if shapes.layout != "C":
        raise TypingError("intersect_spheres: shapes must be C-contiguous")
    if not (isinstance(rows, types.UniTuple) and len(rows) == 4 and isinstance(rows.dtype, types.Integer)):
        raise TypingError("intersect_spheres: rows must be a tuple of 4 integers")
    ret = types.Tuple((types.float64, types.int64))
    return ret(shapes, rows, count, o, d, tmin, tmax), _spheres_codegen


@inline_function
def intersect(rows, i, o, d, tmin, tmax):
    return intersect_sphere(o, d, row3(rows, i, CENTER), rows[i, RADIUS], tmin, tmax)


@inline_function
def normal(rows, i, p):
    return normalize(sub(p, row3(rows, i, CENTER)))


@kernel_function
def uv(rows, i, p):
    """u = 0.5 + atan2(n.x, -n.z) / 2pi (0.5 faces -z, the default camera; the seam is at the
    back, +z), v = 0.5 + asin(n.y) / pi (0 at the south pole, 1 at the north)."""
    n = normal(rows, i, p)
    if rows[i, TURNED] != 0.0:  # the normal in the object's own axes
        n = (dot(n, row3(rows, i, AXES)), dot(n, row3(rows, i, AXES + 3)), dot(n, row3(rows, i, AXES + 6)))
    u = 0.5 + math.atan2(n[0], -n[2]) * (0.5 / math.pi)
    v = 0.5 + math.asin(min(1.0, max(-1.0, n[1]))) / math.pi
    return u, v


# --- rasterizer tessellation ------------------------------------------------------------------

TOLERANCE_PX = 0.1
RINGS = (8, 1024)
SEGMENTS = (24, 2048)


def basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vector `axis` to an orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def tessellate(row: np.ndarray, view) -> np.ndarray:
    return sphere_cap(row[CENTER : CENTER + 3], float(row[RADIUS]), view.eye, view.px_per_rad)


def sphere_cap(center, radius: float, eye, px_per_rad: float) -> np.ndarray:
    """float64 (N, 9): the part of the sphere visible from `eye`.

    Tessellated around the axis from the centre towards the eye: a fan at the pole nearest the
    eye, then rings out to the silhouette (polar angle acos(r / D) for an eye at distance
    D > r; the whole sphere when the eye is inside). Rings are spaced by the angle a ring step
    subtends *at the eye* (an eye just above a huge sphere, like the seed's ground, gets fine
    rings under it and coarse ones far away); ring and segment counts keep every chord within
    TOLERANCE_PX of the true sphere on screen, clamped to RINGS and SEGMENTS."""
    center = np.asarray(center, dtype=np.float64)
    to_eye = np.asarray(eye, dtype=np.float64) - center
    dist = float(np.linalg.norm(to_eye))
    axis = to_eye / dist if dist > 1e-12 * radius else np.array([0.0, 1.0, 0.0])
    inside = dist <= radius
    theta_max = math.pi if inside else math.acos(radius / dist)

    # Eye-to-surface distance along the meridian, and u(theta) = integral of r dtheta / that:
    # the angle a meridian step subtends at the eye. Rings are spaced evenly in u.
    theta = np.linspace(0.0, theta_max, 4097)
    # |eye - point|^2 = (D - r)^2 + 4 D r sin^2(theta / 2): no cancellation when D ~ r
    reach = np.sqrt((dist - radius) ** 2 + 4.0 * dist * radius * np.sin(0.5 * theta) ** 2)
    reach = np.maximum(reach, 1e-9 * radius)
    du = radius / reach
    u = np.concatenate([[0.0], np.cumsum(0.5 * (du[1:] + du[:-1]) * np.diff(theta))])
    far = float(reach.max())
    # A chord over a step of theta strays radius * dtheta^2 / 8 from the sphere; seen from up
    # to `far` away that is (du^2 * far / (8 radius)) radians on screen.
    step_u = math.sqrt(8.0 * TOLERANCE_PX * radius / (far * px_per_rad))
    rings = int(np.clip(math.ceil(u[-1] / step_u), *RINGS))
    ring_theta = np.interp(np.linspace(0.0, u[-1], rings + 1)[1:], u, theta)
    if inside:
        ring_theta = ring_theta[:-1]  # the last "ring" is the antipode: a pole, below
    # Segments: the widest ring (the silhouette) must be polygonal by less than the tolerance.
    widest = float((np.sin(ring_theta) * radius / np.interp(ring_theta, theta, reach)).max())
    sag = TOLERANCE_PX / max(widest * px_per_rad, 1e-300)  # allowed 1 - cos(pi / n)
    segments = int(np.clip(math.ceil(math.pi / math.acos(max(1.0 - sag, -1.0))) if sag < 2 else 0, *SEGMENTS))

    e1, e2 = basis(axis)
    phi = 2.0 * math.pi * np.arange(segments) / segments
    st, ct = np.sin(ring_theta)[:, None, None], np.cos(ring_theta)[:, None, None]
    ring_dirs = ct * axis + st * (np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2)
    ring_pts = center + radius * ring_dirs  # (rings, segments, 3)
    pole = center + radius * axis
    nxt = np.roll(np.arange(segments), -1)
    tris = [np.stack([np.broadcast_to(pole, (segments, 3)), ring_pts[0], ring_pts[0, nxt]], axis=1)]
    if len(ring_pts) > 1:
        a, b = ring_pts[:-1], ring_pts[:-1, nxt]
        c, d = ring_pts[1:], ring_pts[1:, nxt]
        tris.append(np.stack([a, c, b], axis=2).reshape(-1, 3, 3))
        tris.append(np.stack([b, c, d], axis=2).reshape(-1, 3, 3))
    if inside:
        antipode = center - radius * axis
        last = ring_pts[-1]
        tris.append(np.stack([last, np.broadcast_to(antipode, (segments, 3)), last[nxt]], axis=1))
    return np.concatenate(tris).reshape(-1, 9)


def area(rows: np.ndarray) -> np.ndarray:
    """Surface areas (emission: path mode samples a sphere by the cone it subtends, shading/lights/)."""
    return 4.0 * math.pi * rows[:, RADIUS] ** 2
