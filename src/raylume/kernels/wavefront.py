"""Trace mode for basic scenes (spheres and opaque triangles: X is None) as a wavefront: a
row's camera samples go through each stage of the Whitted loop together, TILE at a time, so
the stages that do the same arithmetic for every ray run SIMD across rays.

Per bounce: closest hits of all live rays; the surfaces they hit (misses see the sky); for
each light, the directions and Phong factors towards it, then one shadow ray per ray it lights;
then the local colours and the reflected rays, compacted so dead rays cost nothing. In a basic
scene a ray never splits (nothing is transparent), so every live ray is at the same depth and a
sample's colour gathers its terms in the same order as trace.py's trace_ray: the images are
the same bit for bit (tests/test_wavefront.py).

Scenes whose BVH root is one leaf of spheres (the seed's four) test every sphere against all
live rays in one vector loop (`_sphere_closest`, `_sphere_blocks`), 8 rays per AVX-512
register (4 on AVX2); other scenes traverse the BVH ray by ray and share the rest. The vector
loops are `vector_loop`s: compiled and optimised on their own, where LLVM's loop vectoriser
sees each loop and its arrays alone (inlined into the row function first, it does not
vectorise them: tests/test_wavefront.py checks the machine code).
"""

import math

import numpy as np

from ..accel.wide import SPHERE_BLOCK
from .camera import CAM_CONE_SPREAD, camera_sample, obliquity
from .environment import environment_radiance
from .film import add_sample, pixel_sums, store_sums
from .lights import AMBIENT, DIRECTIONAL, LIGHT_DIRECTION, LIGHT_INTENSITY, LIGHT_POSITION, SPOT, spot_falloff
from .materials import MAT_EMISSION, MAT_REFLECTIVE, MAT_SPECULAR, MAT_TRANSPARENCY, albedo, beer_lambert
from .shape_sphere import CENTER, RADIUS
from .shapes import NO_HIT, PRIM_KIND, PRIM_ROW, SPHERE, offset_epsilon, surface
from .trace import MIN_WEIGHT
from .traverse import _root_is_a_leaf, any_hit, closest_hit, scratch_array
from .vec import FAST, add, dot, hadamard, inline_function, kernel_function, madd, mul, row3, vector_loop

INF = math.inf
# Samples per wavefront: its ~40 rows of float64 (80 KB) stay in the L2 cache.
TILE = 256

# Rows of the float64 scratch (WAVE_ROWS, TILE). A ray's slot i holds its state; sample rows
# (S_*) are indexed by the sample's place in the tile.
OX, OY, OZ, DX, DY, DZ, WR, WG, WB, CONE, T, B1, B2 = range(13)
QX, QY, QZ = 13, 14, 15  # the hit point, offset off the surface (shadow and reflected rays start there)
NX, NY, NZ = 16, 17, 18  # shading normal, facing the incoming ray
AR, AG, AB = 19, 20, 21  # albedo
IR, IG, IB = 22, 23, 24  # light gathered so far
LX, LY, LZ, TMAX, SCALE, COS_RV = 25, 26, 27, 28, 29, 30  # towards the light being gathered
SPEC = 31  # Phong exponent
S_R, S_G, S_B, S_W = 32, 33, 34, 35  # a sample's colour and filter weight
SPREAD = 36  # the ray cone's growth per unit distance (its camera sample's)
WAVE_ROWS = 37
# Rows of the int64 scratch: a slot's primitive hit, material, sample; whether its shadow ray is
# blocked; the slots whose highlight needs a power.
PRIM, MATERIAL, SAMPLE, BLOCKED, HIGHLIGHT = range(5)
WAVE_INT_ROWS = 5


@kernel_function(_nrt=True)
def wavefront_scratch():
    """One thread's wavefront arrays: float64 (WAVE_ROWS, TILE), int64 (WAVE_INT_ROWS, TILE)."""
    return (
        scratch_array(WAVE_ROWS * TILE, np.float64).reshape((WAVE_ROWS, TILE)),
        scratch_array(WAVE_INT_ROWS * TILE, np.int64).reshape((WAVE_INT_ROWS, TILE)),
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
def _surfaces(G, F, X, Env, R, I, m, bg):
    """The surfaces the rays 0..m-1 hit (trace_ray's steps from the hit to the albedo); misses
    add the sky to their samples. The rays that hit are compacted to slots 0..k-1; returns k."""
    mat = F.materials
    k = 0
    for i in range(m):
        s = I[SAMPLE, i]
        d = (R[DX, i], R[DY, i], R[DZ, i])
        w = (R[WR, i], R[WG, i], R[WB, i])
        prim = I[PRIM, i]
        if prim == NO_HIT:
            sky = environment_radiance(Env, d) if Env.present else bg
            R[S_R, s] += w[0] * sky[0]
            R[S_G, s] += w[1] * sky[1]
            R[S_B, s] += w[2] * sky[2]
            continue
        t = R[T, i]
        b1 = R[B1, i]
        b2 = R[B2, i]
        p = madd((R[OX, i], R[OY, i], R[OZ, i]), d, t)
        ng, ns, mm, obj, face = surface(G, X, prim, b1, b2, p)
        if not dot(ng, d) < 0.0:  # leaving: the segment lay inside this surface's medium
            w = beer_lambert(mat, mm, w, t)
            ng = mul(ng, -1.0)
            ns = mul(ns, -1.0)
        if dot(ns, d) >= 0.0:
            ns = ng
        eps = offset_epsilon(F.epsilon_floor, p)
        q = madd(p, ng, eps)
        cone = R[CONE, i] + R[SPREAD, i] * t
        a = albedo(G, F, X, mm, prim, b1, b2, p, d, ng, cone)
        R[DX, k], R[DY, k], R[DZ, k] = d
        R[WR, k], R[WG, k], R[WB, k] = w
        R[CONE, k] = cone
        R[SPREAD, k] = R[SPREAD, i]
        R[QX, k], R[QY, k], R[QZ, k] = q
        R[NX, k], R[NY, k], R[NZ, k] = ns
        R[AR, k], R[AG, k], R[AB, k] = a
        R[IR, k] = 0.0
        R[IG, k] = 0.0
        R[IB, k] = 0.0
        R[SPEC, k] = mat[mm, MAT_SPECULAR]
        I[MATERIAL, k] = mm
        I[SAMPLE, k] = s
        k += 1
    return k


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
        distance = math.sqrt(tx * tx + ty * ty + tz * tz)
        if distance == 0.0:
            ux, uy, uz = 0.0, 0.0, 0.0
        else:
            inv = 1.0 / distance
            ux, uy, uz = tx * inv, ty * inv, tz * inv
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


@inline_function
def _gather_light(L, R, I, m, j):
    """Light j's share at each slot (direct_lighting's sum), unless its ray was blocked
    (BLOCKED 1, transmittance 0) or it sends nothing (BLOCKED -1)."""
    intensity = row3(L.data, j, LIGHT_INTENSITY)
    for i in range(m):
        blocked = I[BLOCKED, i]
        if blocked >= 0:
            scale = R[SCALE, i]
            tr = 0.0 if blocked > 0 else 1.0
            R[IR, i] += intensity[0] * scale * tr
            R[IG, i] += intensity[1] * scale * tr
            R[IB, i] += intensity[2] * scale * tr


@inline_function
def _lighting(G, X, L, R, I, m, leaf_first, leaf_count, node_stack):
    """Ambient + diffuse + specular light at every slot from every light; returns the shadow
    rays traced."""
    rays = 0
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
        _gather_light(L, R, I, m, j)
    return rays


@inline_function
def _local_and_reflected(F, R, I, m, depth):
    """Each slot's local colour into its sample, weighted as trace_ray weighs it; the reflected
    rays that still matter are compacted to slots 0..k-1. Returns k."""
    mat = F.materials
    k = 0
    for i in range(m):
        mm = I[MATERIAL, i]
        s = I[SAMPLE, i]
        w = (R[WR, i], R[WG, i], R[WB, i])
        light = (R[IR, i], R[IG, i], R[IB, i])
        local = add(hadamard((R[AR, i], R[AG, i], R[AB, i]), light), row3(mat, mm, MAT_EMISSION))
        if depth <= 0:
            R[S_R, s] += w[0] * local[0]
            R[S_G, s] += w[1] * local[1]
            R[S_B, s] += w[2] * local[2]
            continue
        r = mat[mm, MAT_REFLECTIVE]
        transparency = mat[mm, MAT_TRANSPARENCY]  # 0 in a basic scene, kept for trace_ray's rounding
        k_local = (1.0 - transparency) * (1.0 - r)
        R[S_R, s] += w[0] * k_local * local[0]
        R[S_G, s] += w[1] * k_local * local[1]
        R[S_B, s] += w[2] * k_local * local[2]
        w_reflect = mul(w, (1.0 - transparency) * r + transparency * 0.0)
        if max(w_reflect[0], w_reflect[1], w_reflect[2]) > MIN_WEIGHT:
            d = (R[DX, i], R[DY, i], R[DZ, i])
            n = (R[NX, i], R[NY, i], R[NZ, i])
            reflected = madd(d, n, -2.0 * dot(d, n))  # optics.reflect
            R[OX, k], R[OY, k], R[OZ, k] = R[QX, i], R[QY, i], R[QZ, i]
            R[DX, k], R[DY, k], R[DZ, k] = reflected
            R[WR, k], R[WG, k], R[WB, k] = w_reflect
            R[CONE, k] = R[CONE, i]
            R[SPREAD, k] = R[SPREAD, i]
            I[SAMPLE, k] = s
            k += 1
    return k


@kernel_function
def wavefront_row(
    G, F, L, X, Env, cam, filt, j, window, width, height, samples, seed, max_depth, bg, film, scratch, node_stack,
    t_stack,
):  # fmt: skip
    """trace mode's _trace_row for a basic scene: the row's samples, in pixel order, through the
    Whitted loop TILE at a time, then into the film in order. Returns the rays traced."""
    R, I = scratch
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    leaf_first, leaf_count = _sphere_leaf(G)
    total_samples = (x1 - x0) * count
    rays = 0
    pixel = x0
    total = pixel_sums(film, j - y0, 0)
    i0, s0 = x0, first  # the pixel and sample number of the tile's first sample
    q = 0
    while q < total_samples:
        n = min(TILE, total_samples - q)
        pi, ps = i0, s0
        for k in range(n):
            o, d, w, _ = camera_sample(cam, filt, seed, pi, j, ps, total_spp, width, height)
            R[OX, k], R[OY, k], R[OZ, k] = o
            R[DX, k], R[DY, k], R[DZ, k] = d
            R[WR, k] = 1.0
            R[WG, k] = 1.0
            R[WB, k] = 1.0
            R[CONE, k] = 0.0
            R[S_R, k] = 0.0
            R[S_G, k] = 0.0
            R[S_B, k] = 0.0
            R[S_W, k] = w
            R[SPREAD, k] = spread * obliquity(cam, d)
            I[SAMPLE, k] = k
            ps += 1
            if ps == first + count:
                pi, ps = pi + 1, first
        m = n
        depth = max_depth
        while m > 0:
            _closest_hits(G, X, R, I, m, leaf_first, leaf_count, node_stack, t_stack)
            rays += m
            m = _surfaces(G, F, X, Env, R, I, m, bg)
            rays += _lighting(G, X, L, R, I, m, leaf_first, leaf_count, node_stack)
            m = _local_and_reflected(F, R, I, m, depth)
            depth -= 1
        for k in range(n):
            if i0 != pixel:
                store_sums(film, j - y0, pixel - x0, total)
                pixel = i0
                total = pixel_sums(film, j - y0, i0 - x0)
            total = add_sample(total, (R[S_R, k], R[S_G, k], R[S_B, k]), R[S_W, k])
            s0 += 1
            if s0 == first + count:
                i0, s0 = i0 + 1, first
        q += n
    store_sums(film, j - y0, pixel - x0, total)
    return rays
