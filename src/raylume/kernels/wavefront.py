"""Trace mode for basic scenes (spheres and opaque triangles: X is None) as a wavefront: a
row's camera samples go through each stage of the Whitted loop together, TILE at a time, so
the stages that do the same arithmetic for every ray run SIMD across rays.

Per bounce: closest hits of all live rays; the rays that hit are compacted (misses see the sky
and end) and take their materials; the surfaces at their hits; for each light, the directions
and Phong factors towards it, then one shadow ray per point it lights; then each ray's local
colour and its reflection, and the rays that still matter are compacted again. In a basic
scene a ray never splits (nothing is transparent), so every live ray is at the same depth, and
each ray carries its sample's colour, which gathers its terms in the order of trace.py's
trace_ray: the images are the same bit for bit (tests/test_wavefront.py).

Scenes whose BVH root is one leaf of spheres (the seed's four) test every sphere against all
live rays in one vector loop (`_sphere_closest`, `_sphere_blocks`) and find the surfaces the
same way (`_sphere_surfaces`); other scenes traverse the BVH and find surfaces ray by ray and
share the rest. The vector loops are `vector_loop`s (vec.py): compiled and optimised on their
own, where LLVM's loop vectoriser sees each loop and its arrays alone (inlined into the row
function first, it did not vectorise them). They run 8 rays per AVX-512 register, 4 on AVX2;
tests/test_wavefront.py checks the machine code.
"""

import math

import numpy as np

from ..accel.wide import SPHERE_BLOCK
from .camera import (
    CAM_CONE_SPREAD,
    CAM_FORWARD,
    CAM_LENS_RADIUS,
    CAM_POSITION,
    CAM_RIGHT,
    CAM_UP,
    camera_sample,
    obliquity,
)
from .environment import environment_radiance
from .film import add_in_pixel_order, next_sample, pixel_sums, store_sums
from .lights import AMBIENT, DIRECTIONAL, LIGHT_DIRECTION, LIGHT_INTENSITY, LIGHT_POSITION, SPOT, spot_falloff
from .materials import MAT_COLOR, MAT_EMISSION, MAT_REFLECTIVE, MAT_SPECULAR, MAT_TEXTURE, albedo, beer_lambert
from .shape_sphere import CENTER, RADIUS
from .shapes import NO_HIT, PRIM_KIND, PRIM_MATERIAL, PRIM_ROW, SPHERE, offset_epsilon, surface
from .trace import MIN_WEIGHT
from .traverse import _root_is_a_leaf, any_hit, closest_hit, scratch_array
from .vec import FAST, dot, inline_function, kernel_function, length, madd, mul, normalize, row3, vector_loop

INF = math.inf
# Samples per wavefront: its ~45 rows of float64 (90 KB) stay in the L2 cache.
TILE = 256

# Rows of the float64 scratch (WAVE_ROWS, TILE + ROW_PAD): slot i of each holds ray i's state.
OX, OY, OZ, DX, DY, DZ, WR, WG, WB = range(9)  # origin, direction, weight (RGB)
CONE, SPREAD = 9, 10  # ray cone: its radius at the origin and growth per unit distance
CR, CG, CB = 11, 12, 13  # the colour its sample has gathered so far
T, B1, B2 = 14, 15, 16  # the closest hit
AR, AG, AB, ER, EG, EB, SPEC, REFL = range(17, 25)  # material: albedo, emission, Phong exponent, reflectivity
QX, QY, QZ = 25, 26, 27  # the hit point, offset off the surface (shadow and reflected rays start there)
NX, NY, NZ = 28, 29, 30  # shading normal, facing the incoming ray
IR, IG, IB = 31, 32, 33  # light gathered so far
LX, LY, LZ, TMAX, SCALE, COS_RV = range(34, 40)  # towards the light being gathered
S_R, S_G, S_B, S_W = range(40, 44)  # indexed by sample: its final colour and filter weight
WAVE_ROWS = 44
# Rows of the int64 scratch: the primitive hit, material and sample of a slot; whether its
# shadow ray is blocked; whether its highlight needs a power; whether it leaves a sphere, then
# whether its reflection goes on.
PRIM, MATERIAL, SAMPLE, BLOCKED, HIGHLIGHT, FLAG = range(6)
WAVE_INT_ROWS = 6
# The materials table (materials, M_WIDTH): a slot's material values in the order of its rows
# AR..REFL. (The vector loops do not gather from it: a loop that reads an array at indices it
# loads, and writes others, is not vectorised, LLVM being unable to bound what it reads.)
M_WIDTH = REFL - AR + 1
# Each row is padded by a cache line: rows 2 KB apart would put the same slot of every other
# row in one set of the L1 cache (4 KB per way), and a stage that touches 20 rows evicted its
# own lines (and loads waited on stores 4 KB away).
ROW_PAD = 8


@kernel_function(_nrt=True)
def wavefront_scratch(G, F):
    """One thread's wavefront arrays: float64 (WAVE_ROWS, TILE + ROW_PAD) and int64
    (WAVE_INT_ROWS, TILE + ROW_PAD), of which slots 0..TILE-1 are used (C-contiguous: a row
    is a contiguous array); the materials table (materials, M_WIDTH); and each primitive's
    sphere centre (primitives, 3) when the root is a leaf of spheres."""
    stride = TILE + ROW_PAD
    mat = F.materials
    M = np.empty((mat.shape[0], M_WIDTH))
    for m in range(mat.shape[0]):
        M[m, 0], M[m, 1], M[m, 2] = row3(mat, m, MAT_COLOR)
        M[m, 3], M[m, 4], M[m, 5] = row3(mat, m, MAT_EMISSION)
        M[m, SPEC - AR] = mat[m, MAT_SPECULAR]
        M[m, REFL - AR] = mat[m, MAT_REFLECTIVE]
    first, count = _sphere_leaf(G)
    C = np.zeros((G.prims.shape[0] if count > 0 else 1, 3))
    for k in range(first, first + count):
        C[k, 0], C[k, 1], C[k, 2] = row3(G.shapes, np.int64(G.prims[k, PRIM_ROW]), CENTER)
    return (
        scratch_array(WAVE_ROWS * stride, np.float64).reshape((WAVE_ROWS, stride)),
        scratch_array(WAVE_INT_ROWS * stride, np.int64).reshape((WAVE_INT_ROWS, stride)),
        M,
        C,
    )


# --- the vector loops ----------------------------------------------------------------------
# Exact arithmetic (no fast-math), in shape_sphere.intersect_sphere's order of operations, so
# each lane rounds as the scalar test does; the branches become selects.


@kernel_function(fastmath=False, error_model="numpy", _nrt=False, forceinline=True)
def _sphere_distance(ox, oy, oz, dx, dy, dz, cx, cy, cz, radius, tmax):
    """intersect_sphere with tmin 0, branch-free."""
    x = ox - cx
    y = oy - cy
    z = oz - cz
    b = x * dx + y * dy + z * dz
    c = (x * x + y * y + z * z) - radius * radius
    px = x - b * dx
    py = y - b * dy
    pz = z - b * dz
    disc = radius * radius - (px * px + py * py + pz * pz)
    q = -b - math.copysign(math.sqrt(max(disc, 0.0)), b)
    t0 = c / q
    near = q if t0 > q else t0
    far = t0 if t0 > q else q
    t = near if (near > 0.0) & (near < tmax) else (far if (far > 0.0) & (far < tmax) else INF)
    found = (disc >= 0.0) & (q != 0.0) & ~((c > 0.0) & (b > 0.0))
    return t if found else INF


@vector_loop
def _sphere_closest(ox, oy, oz, dx, dy, dz, t, prim, m, cx, cy, cz, radius, k):
    """Rays 0..m-1 against one sphere (primitive k): nearer hits replace (t, prim)."""
    for i in range(m):
        tk = _sphere_distance(ox[i], oy[i], oz[i], dx[i], dy[i], dz[i], cx, cy, cz, radius, t[i])
        nearer = tk < t[i]
        t[i] = tk if nearer else t[i]
        prim[i] = k if nearer else prim[i]


@vector_loop
def _sphere_blocks(ox, oy, oz, dx, dy, dz, tmax, blocked, m, cx, cy, cz, radius):
    """Shadow rays 0..m-1 against one sphere: blocked[i] goes from 0 to 1 when the sphere lies
    in (0, tmax) along the ray."""
    for i in range(m):
        tk = _sphere_distance(ox[i], oy[i], oz[i], dx[i], dy[i], dz[i], cx, cy, cz, radius, tmax[i])
        blocked[i] = 1 if (tk < INF) & (blocked[i] == 0) else blocked[i]


# --- the stages --------------------------------------------------------------------------


@inline_function
def _sphere_leaf(G):
    """(first, count) of the root leaf when the BVH root is one leaf of spheres alone, else
    (0, 0)."""
    index = G.node_index
    if not _root_is_a_leaf(index):
        return 0, 0
    first = index[0, 0, 0]
    count = index[0, 1, 0]
    if count < 0:  # a block (accel/wide.py): spheres when below -SPHERE_BLOCK, else triangles
        if G.prims[first, PRIM_KIND] != SPHERE:
            return 0, 0
        if count >= -SPHERE_BLOCK:
            return 0, 0
        count = -count - SPHERE_BLOCK
    for k in range(first, first + count):
        if G.prims[k, PRIM_KIND] != SPHERE:
            return 0, 0
    return first, count


@inline_function
def _closest_hits(G, X, R, I, m, leaf_first, leaf_count, node_stack, t_stack):
    """Closest hits of rays 0..m-1 into T, PRIM, B1, B2."""
    if leaf_count > 0:
        for i in range(m):
            R[T, i] = INF
            I[PRIM, i] = NO_HIT
            R[B1, i] = 0.0
            R[B2, i] = 0.0
        for k in range(leaf_first, leaf_first + leaf_count):
            r = np.int64(G.prims[k, PRIM_ROW])
            c = row3(G.shapes, r, CENTER)
            _sphere_closest(
                R[OX], R[OY], R[OZ], R[DX], R[DY], R[DZ], R[T], I[PRIM], m, c[0], c[1], c[2], G.shapes[r, RADIUS], k
            )
        return
    for i in range(m):
        o = (R[OX, i], R[OY, i], R[OZ, i])
        d = (R[DX, i], R[DY, i], R[DZ, i])
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        R[T, i] = t
        I[PRIM, i] = prim
        R[B1, i] = b1
        R[B2, i] = b2


@inline_function
def _move(R, i, k, a, b, c):
    """Rows a, b, c of slot i into slot k (k < i), loaded before any is stored."""
    va, vb, vc = R[a, i], R[b, i], R[c, i]
    R[a, k], R[b, k], R[c, k] = va, vb, vc


@inline_function
def _move_ray(R, I, i, k):
    """A ray's state (origin, direction, weight, colour, cone, sample) from slot i to k < i."""
    _move(R, i, k, OX, OY, OZ)
    _move(R, i, k, DX, DY, DZ)
    _move(R, i, k, WR, WG, WB)
    _move(R, i, k, CR, CG, CB)
    _move(R, i, k, CONE, SPREAD, SPREAD)
    I[SAMPLE, k] = I[SAMPLE, i]


@inline_function
def _finish_ray(R, I, i, col):
    """A ray that ends: its sample's colour is final."""
    s = I[SAMPLE, i]
    R[S_R, s], R[S_G, s], R[S_B, s] = col


@inline_function
def _compact_hits(G, Env, R, I, M, C, m, bg, spheres):
    """The rays that hit something move to slots 0..k-1 (in order) and take their hit's
    material (and, in a leaf of `spheres`, the sphere's centre into QX..QZ); the others add the
    sky (the environment, else the background) and end. Returns k."""
    k = 0
    for i in range(m):
        prim = I[PRIM, i]
        if prim == NO_HIT:
            d = (R[DX, i], R[DY, i], R[DZ, i])
            w = (R[WR, i], R[WG, i], R[WB, i])
            sky = environment_radiance(Env, d) if Env.present else bg
            _finish_ray(R, I, i, (R[CR, i] + w[0] * sky[0], R[CG, i] + w[1] * sky[1], R[CB, i] + w[2] * sky[2]))
            continue
        if k < i:
            _move_ray(R, I, i, k)
            _move(R, i, k, T, B1, B2)
            I[PRIM, k] = prim
        mm = np.int64(G.prims[prim, PRIM_MATERIAL])
        I[MATERIAL, k] = mm
        for c in range(M_WIDTH):
            R[AR + c, k] = M[mm, c]
        if spheres:
            R[QX, k], R[QY, k], R[QZ, k] = C[prim, 0], C[prim, 1], C[prim, 2]
        k += 1
    return k


@inline_function
def _compact_reflected(R, I, m):
    """The reflected rays that go on (FLAG) move to slots 0..k-1 (in order); the others end.
    Returns k."""
    k = 0
    for i in range(m):
        if I[FLAG, i] == 0:
            _finish_ray(R, I, i, (R[CR, i], R[CG, i], R[CB, i]))
            continue
        if k < i:
            _move_ray(R, I, i, k)
        k += 1
    return k


@inline_function
def _hit_point(R, i):
    o = (R[OX, i], R[OY, i], R[OZ, i])
    return madd(o, (R[DX, i], R[DY, i], R[DZ, i]), R[T, i])


@inline_function
def _surfaces(G, F, X, R, I, m):
    """trace_ray's steps from a hit to its albedo, ray by ray (any basic scene)."""
    mat = F.materials
    for i in range(m):
        d = (R[DX, i], R[DY, i], R[DZ, i])
        t = R[T, i]
        p = _hit_point(R, i)
        prim = I[PRIM, i]
        b1 = R[B1, i]
        b2 = R[B2, i]
        ng, ns, mm, obj, face = surface(G, X, prim, b1, b2, p)
        if not dot(ng, d) < 0.0:  # leaving: the segment lay inside this surface's medium
            R[WR, i], R[WG, i], R[WB, i] = beer_lambert(mat, mm, (R[WR, i], R[WG, i], R[WB, i]), t)
            ng = mul(ng, -1.0)
            ns = mul(ns, -1.0)
        if dot(ns, d) >= 0.0:
            ns = ng
        q = madd(p, ng, offset_epsilon(F.epsilon_floor, p))
        cone = R[CONE, i] + R[SPREAD, i] * t
        R[CONE, i] = cone
        R[QX, i], R[QY, i], R[QZ, i] = q
        R[NX, i], R[NY, i], R[NZ, i] = ns
        if mat[mm, MAT_TEXTURE] >= 0:
            R[AR, i], R[AG, i], R[AB, i] = albedo(G, F, X, mm, prim, b1, b2, p, d, ng, cone)


@vector_loop(fastmath=FAST)
def _sphere_surfaces(
    ox, oy, oz, dx, dy, dz, t, cone, spread, qx, qy, qz, nx, ny, nz, leaving, m, epsilon_floor
):  # fmt: skip
    """_surfaces for spheres, with their centres in (qx, qy, qz) (overwritten by the offset hit
    points): the normal, its flip for rays leaving the sphere (marked in `leaving`: their
    absorption and textures are left to _sphere_surface_extras), the offset point and the cone."""
    for i in range(m):
        px = ox[i] + dx[i] * t[i]
        py = oy[i] + dy[i] * t[i]
        pz = oz[i] + dz[i] * t[i]
        ax = px - qx[i]
        ay = py - qy[i]
        az = pz - qz[i]
        ux, uy, uz = normalize((ax, ay, az))
        out = not ux * dx[i] + uy * dy[i] + uz * dz[i] < 0.0
        if out:
            ux, uy, uz = ux * -1.0, uy * -1.0, uz * -1.0
        eps = 1e-7 * max(max(max(abs(px), abs(py)), abs(pz)), epsilon_floor)
        qx[i] = px + ux * eps
        qy[i] = py + uy * eps
        qz[i] = pz + uz * eps
        nx[i], ny[i], nz[i] = ux, uy, uz
        cone[i] = cone[i] + spread[i] * t[i]
        leaving[i] = 1 if out else 0


@inline_function
def _sphere_surface_extras(G, F, X, R, I, m):
    """What _sphere_surfaces leaves to rays one by one: absorption along the segment inside a
    sphere (a ray leaving it), and textures."""
    mat = F.materials
    for i in range(m):
        mm = I[MATERIAL, i]
        leaving = I[FLAG, i] != 0
        textured = mat[mm, MAT_TEXTURE] >= 0
        if not (leaving or textured):
            continue
        if leaving:
            R[WR, i], R[WG, i], R[WB, i] = beer_lambert(mat, mm, (R[WR, i], R[WG, i], R[WB, i]), R[T, i])
        if textured:
            d = (R[DX, i], R[DY, i], R[DZ, i])
            p = _hit_point(R, i)
            ng = (R[NX, i], R[NY, i], R[NZ, i])  # facing the ray, as trace_ray's after its flip
            prim = I[PRIM, i]
            R[AR, i], R[AG, i], R[AB, i] = albedo(G, F, X, mm, prim, R[B1, i], R[B2, i], p, d, ng, R[CONE, i])


@inline_function
def _find_surfaces(G, F, X, R, I, m, leaf_count):
    """Albedo, offset point and normal at each slot's hit."""
    if leaf_count == 0:
        _surfaces(G, F, X, R, I, m)
        return
    _sphere_surfaces(
        R[OX], R[OY], R[OZ], R[DX], R[DY], R[DZ], R[T], R[CONE], R[SPREAD], R[QX], R[QY], R[QZ], R[NX], R[NY],
        R[NZ], I[FLAG], m, F.epsilon_floor,
    )  # fmt: skip
    _sphere_surface_extras(G, F, X, R, I, m)


@vector_loop(fastmath=FAST)
def _light_directions(
    qx, qy, qz, nx, ny, nz, dx, dy, dz, spec, lx, ly, lz, tmax, scale, cos_rv, highlight, m, directional, x, y, z
):  # fmt: skip
    """Towards a delta light at (x, y, z), or along (x, y, z) when `directional`, from points
    0..m-1: the unit direction and distance (sample_delta), the diffuse factor and cos(R, V) of
    materials.phong (with its fast-math rounding: these are trace_ray's operations), and
    whether the highlight is worth its power."""
    for i in range(m):
        if directional:
            tx, ty, tz = x, y, z
        else:
            tx, ty, tz = x - qx[i], y - qy[i], z - qz[i]
        distance = length((tx, ty, tz))
        ux, uy, uz = normalize((tx, ty, tz))  # the same square root, which LLVM computes once
        n_dot_l = nx[i] * ux + ny[i] * uy + nz[i] * uz
        twice = 2.0 * n_dot_l
        rx, ry, rz = nx[i] * twice - ux, ny[i] * twice - uy, nz[i] * twice - uz
        c = rx * (dx[i] * -1.0) + ry * (dy[i] * -1.0) + rz * (dz[i] * -1.0)
        s = spec[i]
        lx[i], ly[i], lz[i] = ux, uy, uz
        tmax[i] = INF if directional else distance
        scale[i] = max(n_dot_l, 0.0)
        cos_rv[i] = c
        highlight[i] = 1 if (s > 0.0) & (c > 0.0) & (c > 1.0 - 50.0 / s) else 0


@inline_function
def _towards_light(L, R, I, m, j):
    """direct_lighting's steps for delta light j up to its shadow ray: the unit direction l and
    distance towards it, and the Phong factor; BLOCKED starts as 'no ray needed' (-1) where the
    factor is 0, else 0."""
    directional = L.kind[j] == DIRECTIONAL
    x, y, z = row3(L.data, j, LIGHT_DIRECTION if directional else LIGHT_POSITION)
    _light_directions(
        R[QX], R[QY], R[QZ], R[NX], R[NY], R[NZ], R[DX], R[DY], R[DZ], R[SPEC], R[LX], R[LY], R[LZ], R[TMAX],
        R[SCALE], R[COS_RV], I[HIGHLIGHT], m, directional, x, y, z,
    )  # fmt: skip
    # The powers apart, slot by slot where they are needed: in a loop over every slot LLVM
    # computed the power for all of them (a call without side effects may be speculated), most
    # underflowing into libm's slow path (a quarter of the seed's time).
    for i in range(m):
        if I[HIGHLIGHT, i] != 0:
            R[SCALE, i] += R[COS_RV, i] ** R[SPEC, i]
    if L.kind[j] == SPOT:
        for i in range(m):
            R[SCALE, i] *= spot_falloff(L.data, j, (R[LX, i], R[LY, i], R[LZ, i]))
    for i in range(m):
        I[BLOCKED, i] = 0 if R[SCALE, i] > 0.0 else -1


@inline_function
def _shadows(G, X, R, I, m, leaf_first, leaf_count, node_stack):
    """Shadow rays of the slots that need one (BLOCKED 0): BLOCKED becomes 1 where something
    lies between the point and the light. Returns the rays traced."""
    rays = 0
    for i in range(m):
        rays += I[BLOCKED, i] + 1
    if leaf_count > 0:
        for k in range(leaf_first, leaf_first + leaf_count):
            r = np.int64(G.prims[k, PRIM_ROW])
            c = row3(G.shapes, r, CENTER)
            _sphere_blocks(
                R[QX], R[QY], R[QZ], R[LX], R[LY], R[LZ], R[TMAX], I[BLOCKED], m, c[0], c[1], c[2],
                G.shapes[r, RADIUS],
            )  # fmt: skip
        return rays
    for i in range(m):
        if I[BLOCKED, i] == 0:
            o = (R[QX, i], R[QY, i], R[QZ, i])
            d = (R[LX, i], R[LY, i], R[LZ, i])
            if any_hit(G, X, o, d, 0.0, R[TMAX, i], node_stack):
                I[BLOCKED, i] = 1
    return rays


@vector_loop(fastmath=FAST)
def _gather_light(ir, ig, ib, scale, blocked, m, r, g, b):
    """Light of intensity (r, g, b) at each slot (direct_lighting's sum), unless its ray was
    blocked (1: transmittance 0) or it sends nothing (-1)."""
    for i in range(m):
        tr = 0.0 if blocked[i] > 0 else 1.0
        add = blocked[i] >= 0
        ir[i] = ir[i] + r * scale[i] * tr if add else ir[i]
        ig[i] = ig[i] + g * scale[i] * tr if add else ig[i]
        ib[i] = ib[i] + b * scale[i] * tr if add else ib[i]


@inline_function
def _lighting(G, X, L, R, I, m, leaf_first, leaf_count, node_stack):
    """Ambient + diffuse + specular light at every slot from every light; returns the shadow
    rays traced."""
    rays = 0
    for i in range(m):
        R[IR, i] = 0.0
        R[IG, i] = 0.0
        R[IB, i] = 0.0
    for j in range(L.kind.shape[0]):
        if L.kind[j] == AMBIENT:
            intensity = row3(L.data, j, LIGHT_INTENSITY)
            for i in range(m):
                R[IR, i] += intensity[0]
                R[IG, i] += intensity[1]
                R[IB, i] += intensity[2]
            continue
        _towards_light(L, R, I, m, j)
        rays += _shadows(G, X, R, I, m, leaf_first, leaf_count, node_stack)
        r, g, b = row3(L.data, j, LIGHT_INTENSITY)
        _gather_light(R[IR], R[IG], R[IB], R[SCALE], I[BLOCKED], m, r, g, b)
    return rays


# Two loops, not one: with all their arrays in one, LLVM would need too many run-time checks
# that none overlaps another, and leaves the loop scalar.
@vector_loop(fastmath=FAST)
def _add_local(cr, cg, cb, wr, wg, wb, ar, ag, ab, er, eg, eb, ir, ig, ib, refl, m, last):
    """Each ray's local colour (albedo x light + emission) into its colour, weighted as
    trace_ray weighs it: whole on the `last` bounce, else times 1 - reflectivity (trace_ray's
    factors 1 - transparency are exactly 1 here)."""
    for i in range(m):
        lr = ar[i] * ir[i] + er[i]
        lg = ag[i] * ig[i] + eg[i]
        lb = ab[i] * ib[i] + eb[i]
        k_local = 1.0 if last else 1.0 - refl[i]
        cr[i] = cr[i] + wr[i] * k_local * lr
        cg[i] = cg[i] + wg[i] * k_local * lg
        cb[i] = cb[i] + wb[i] * k_local * lb


@vector_loop(fastmath=FAST)
def _reflect(ox, oy, oz, dx, dy, dz, qx, qy, qz, nx, ny, nz, wr, wg, wb, refl, goes_on, m, last):
    """The reflection of each ray (from the offset point, in place), and whether it goes on:
    not after the `last` bounce, nor once its weight cannot matter."""
    for i in range(m):
        r = refl[i]
        ox[i], oy[i], oz[i] = qx[i], qy[i], qz[i]
        w0, w1, w2 = wr[i] * r, wg[i] * r, wb[i] * r
        twice = -2.0 * (dx[i] * nx[i] + dy[i] * ny[i] + dz[i] * nz[i])
        dx[i] = dx[i] + nx[i] * twice
        dy[i] = dy[i] + ny[i] * twice
        dz[i] = dz[i] + nz[i] * twice
        wr[i], wg[i], wb[i] = w0, w1, w2
        goes_on[i] = 0 if last else (1 if max(max(w0, w1), w2) > MIN_WEIGHT else 0)


@vector_loop(fastmath=FAST)
def _pinhole_directions(dx, dy, dz, spread_out, n, cam, i0, j, width, height, spread):
    """camera.camera_ray's directions through the centres of pixels i0..i0+n-1 of row j, and
    their cones' spread (camera.obliquity), as trace mode's row gives them."""
    fx, fy, fz = cam[CAM_FORWARD], cam[CAM_FORWARD + 1], cam[CAM_FORWARD + 2]
    rx, ry, rz = cam[CAM_RIGHT], cam[CAM_RIGHT + 1], cam[CAM_RIGHT + 2]
    ux, uy, uz = cam[CAM_UP], cam[CAM_UP + 1], cam[CAM_UP + 2]
    b = 1.0 - (j + 0.5) / height * 2.0
    for k in range(n):
        a = ((i0 + k) + 0.5) / width * 2.0 - 1.0
        x = fx + rx * a + ux * b
        y = fy + ry * a + uy * b
        z = fz + rz * a + uz * b
        x, y, z = normalize((x, y, z))
        dx[k], dy[k], dz[k] = x, y, z
        spread_out[k] = spread * abs(x * fx + y * fy + z * fz)


@kernel_function
def wavefront_row(
    G, F, L, X, Env, cam, filt, j, window, width, height, samples, seed, max_depth, bg, film, scratch, node_stack,
    t_stack,
):  # fmt: skip
    """trace mode's _trace_row for a basic scene: the row's samples, in pixel order, through the
    Whitted loop TILE at a time, then into the film in order. Returns the rays traced."""
    R, I, M, C = scratch
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    leaf_first, leaf_count = _sphere_leaf(G)
    pinhole_centres = total_spp == 1 and not cam[CAM_LENS_RADIUS] > 0.0
    total_samples = (x1 - x0) * count
    rays = 0
    pixel = x0
    total = pixel_sums(film, j - y0, 0)
    i0, s0 = x0, first  # the pixel and sample number of the tile's first sample
    q = 0
    while q < total_samples:
        n = min(TILE, total_samples - q)
        if pinhole_centres:  # camera_sample's rays through pixels i0.., without the unused random key
            _pinhole_directions(R[DX], R[DY], R[DZ], R[SPREAD], n, cam, i0, j, width, height, spread)
        pi, ps = i0, s0
        for k in range(n):
            if pinhole_centres:
                o = (cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2])
                w = 1.0
            else:
                o, d, w, _ = camera_sample(cam, filt, seed, pi, j, ps, total_spp, width, height)
                R[DX, k], R[DY, k], R[DZ, k] = d
                R[SPREAD, k] = spread * obliquity(cam, d)
            R[OX, k], R[OY, k], R[OZ, k] = o
            R[WR, k] = 1.0
            R[WG, k] = 1.0
            R[WB, k] = 1.0
            R[CONE, k] = 0.0
            R[CR, k] = 0.0
            R[CG, k] = 0.0
            R[CB, k] = 0.0
            R[S_W, k] = w
            I[SAMPLE, k] = k
            pi, ps = next_sample(pi, ps, samples)
        m = n
        depth = max_depth
        while m > 0:
            _closest_hits(G, X, R, I, m, leaf_first, leaf_count, node_stack, t_stack)
            rays += m
            m = _compact_hits(G, Env, R, I, M, C, m, bg, leaf_count > 0)
            _find_surfaces(G, F, X, R, I, m, leaf_count)
            rays += _lighting(G, X, L, R, I, m, leaf_first, leaf_count, node_stack)
            last = depth <= 0
            _add_local(
                R[CR], R[CG], R[CB], R[WR], R[WG], R[WB], R[AR], R[AG], R[AB], R[ER], R[EG], R[EB], R[IR], R[IG],
                R[IB], R[REFL], m, last,
            )  # fmt: skip
            _reflect(
                R[OX], R[OY], R[OZ], R[DX], R[DY], R[DZ], R[QX], R[QY], R[QZ], R[NX], R[NY], R[NZ], R[WR], R[WG],
                R[WB], R[REFL], I[FLAG], m, last,
            )  # fmt: skip
            m = _compact_reflected(R, I, m)
            depth -= 1
        for k in range(n):
            col = (R[S_R, k], R[S_G, k], R[S_B, k])
            pixel, total = add_in_pixel_order(film, j - y0, x0, pixel, total, i0, col, R[S_W, k])
            i0, s0 = next_sample(i0, s0, samples)
        q += n
    store_sums(film, j - y0, pixel - x0, total)
    return rays
