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

Scenes whose BVH root is one leaf of spheres (the seed's four) test the live rays against the
spheres eight at a time in explicit IR (wavefront_spheres.py: a vector of rays that misses a
sphere skips the square root and the division) and find the surfaces in a vector loop
(`_sphere_surfaces`); other scenes traverse the BVH and find surfaces ray by ray and share the
rest. The vector loops are `vector_loop`s (vec.py): compiled and optimised on their own, where
LLVM's loop vectoriser sees each loop alone (inlined into the row function first, it did not
vectorise them). They run 8 rays a register where LLVM's tuning for the CPU prefers 512-bit
vectors (AMD's Zen 4), 4 elsewhere (AVX2, and Intel's AVX-512 cores, tuned for 256-bit vectors);
tests/test_wavefront.py checks the machine code. The rays' state is one flat array with rows a
constant stride apart (below), so a loop over twenty rows is one pointer and constant offsets.
"""

import math

import numpy as np
from numba import types
from numba.extending import overload

from ..film.camera import (
    CAM_CONE_SPREAD,
    CAM_FORWARD,
    CAM_LENS_RADIUS,
    CAM_POSITION,
    CAM_RIGHT,
    CAM_UP,
    camera_sample,
    obliquity,
)
from ..film.film import FILM_WIDTH, add_in_pixel_order, add_one_each, next_sample, pixel_sums, store_sums
from ..geometry.layout import NODE_REF, SPHERE_BLOCK
from ..geometry.packet import (
    PACKET,
    packet_blocked,
    packet_hit,
    packet_scratch,
    packet_trace,
    root_box,
    scene_extent,
    uses_packets,
)
from ..geometry.shape_sphere import CENTER, RADIUS
from ..geometry.shapes import NO_HIT, PRIM_KIND, PRIM_MATERIAL, PRIM_ROW, SPHERE, offset_epsilon, surface
from ..geometry.traverse import _root_is_a_leaf, any_hit, closest_hit, prefetch_surface
from ..geometry.wavefront_spheres import SR, SX, SZ, tile_blocks, tile_closest
from ..geometry.wide_nodes import SCRATCH_PAD, leaf_count, leaf_first, prefetch_row, scratch_array
from ..shading.environment import environment_radiance
from ..shading.lights import LIGHT_INTENSITY, LIGHT_POSITION, at_infinity, has_falloff, is_everywhere, trace_falloff
from ..shading.materials import (
    MAT_COLOR,
    MAT_EMISSION,
    MAT_REFLECTIVE,
    MAT_SPECULAR,
    MAT_TEXTURE,
    albedo,
    beer_lambert,
)
from ..shading.materials.seed_response import highlight
from ..variants import sphere_leaf_range
from ..vec import (
    FAST,
    INLINE_OVERLOAD,
    at,
    count_up,
    dot,
    fill,
    inline_function,
    kernel_function,
    length,
    madd,
    mul,
    normalize,
    row3,
    vector_loop,
)
from .trace import MIN_WEIGHT

INF = math.inf
# Samples per wavefront: its ~45 rows of float64 (90 KB) stay in the L2 cache.
TILE = 256
# Each row is padded by a cache line: rows 2 KB apart would put the same slot of every other
# row in one set of the L1 cache (4 KB per way), and a stage that touches 20 rows evicted its
# own lines (and loads waited on stores 4 KB away). The sphere tests also read whole vectors of
# eight slots past the live ones.
ROW_PAD = 8
STRIDE = TILE + ROW_PAD  # slots a row


def _rows(first: int, n: int) -> tuple[int, ...]:
    return tuple((first + r) * STRIDE for r in range(n))


# The scratch is flat: row X of it starts at X (a multiple of STRIDE), and slot i of the row,
# ray i's value, is R[X + i]. A compile-time row stride makes every row's address a constant
# offset from one pointer: LLVM sees that no two rows overlap (a vector loop over twenty rows,
# each passed as an array, spent more time proving that at run time, pair by pair, than in the
# loop: the seed's reflection loop took 600 ns for 256 rays against 90 now), and the scalar
# loops keep one pointer in a register instead of one per row.
# Rows of the float64 scratch R (WAVE_ROWS rows):
OX, OY, OZ, DX, DY, DZ, WR, WG, WB = _rows(0, 9)  # origin, direction, weight (RGB)
CONE, SPREAD = _rows(9, 2)  # ray cone: its radius at the origin and growth per unit distance
CR, CG, CB = _rows(11, 3)  # the colour its sample has gathered so far
T, B1, B2 = _rows(14, 3)  # the closest hit
AR, AG, AB, ER, EG, EB, SPEC, REFL = _rows(17, 8)  # material: albedo, emission, Phong exponent, reflectivity
QX, QY, QZ = _rows(25, 3)  # the hit point, offset off the surface (shadow and reflected rays start there)
NX, NY, NZ = _rows(28, 3)  # shading normal, facing the incoming ray
IR, IG, IB = _rows(31, 3)  # light gathered so far
LX, LY, LZ, TMAX, SCALE, COS_RV = _rows(34, 6)  # towards the light being gathered
S_R, S_G, S_B, S_W = _rows(40, 4)  # indexed by sample: its final colour and filter weight
PX, PY, PZ = _rows(44, 3)  # the hit point itself (the lights' directions are taken from there)
WAVE_ROWS = 47
# Rows of the int64 scratch I (WAVE_INT_ROWS rows): the primitive hit, material and sample of
# a slot; whether its shadow ray is blocked; whether its highlight needs a power; whether it
# leaves a sphere, then whether its reflection goes on.
PRIM, MATERIAL, SAMPLE, BLOCKED, HIGHLIGHT, FLAG = _rows(0, 6)
WAVE_INT_ROWS = 6
# The materials table (materials, M_WIDTH): a slot's material values in the order of its rows
# AR..REFL. (The vector loops do not gather from it: a loop that reads an array at indices it
# loads, and writes others, is not vectorised, LLVM being unable to bound what it reads.)
M_WIDTH = (REFL - AR) // STRIDE + 1


def wavefront_tables(S) -> tuple[np.ndarray, np.ndarray]:
    """The scene's wavefront tables, made on the host (numpy) from the KernelScene S and read by
    every lane: the materials table (materials, M_WIDTH) and each primitive's sphere row
    (primitives, 4: centre, radius; wavefront_spheres.py) when the root is a leaf of spheres.
    Made in the kernel, with numpy's allocation, reshapes and fills compiled into it, they and
    the rows (wavefront_rows) had been ~10% of the seed's first compile."""
    mat = S.materials
    M = np.empty((mat.shape[0], M_WIDTH), np.float64)
    M[:, 0:3] = mat[:, MAT_COLOR : MAT_COLOR + 3]
    M[:, 3:6] = mat[:, MAT_EMISSION : MAT_EMISSION + 3]
    M[:, 6] = mat[:, MAT_SPECULAR]
    M[:, 7] = mat[:, MAT_REFLECTIVE]
    first, count = sphere_leaf_range(S.node_index, S.prims)
    C = np.zeros((S.prims.shape[0] if count > 0 else 1, 4), np.float64)
    rows = S.prims[first : first + count, PRIM_ROW].astype(np.int64)
    C[first : first + count, SX : SZ + 1] = S.shapes[rows, CENTER : CENTER + 3]
    C[first : first + count, SR] = S.shapes[rows, RADIUS]
    return M, C


def wavefront_rows() -> tuple[np.ndarray, np.ndarray]:
    """One lane's rays, made on the host: float64 (WAVE_ROWS * STRIDE) and int64
    (WAVE_INT_ROWS * STRIDE), flat as the rows' offsets say. They start zeroed: the sphere
    tests compute whole vectors of eight slots, past the live ones too, and garbage there could
    be subnormal (slow) numbers."""
    return _padded(WAVE_ROWS * STRIDE, np.float64), _padded(WAVE_INT_ROWS * STRIDE, np.int64)


def _padded(n: int, dtype) -> np.ndarray:
    """n zeros starting on a 64-byte boundary (a cache line, an AVX-512 vector: the rows are
    STRIDE slots, a multiple of 64 bytes, so every row starts on one), with SCRATCH_PAD unused
    elements or more on either side against false sharing (as wide_nodes.scratch_array's)."""
    size = np.dtype(dtype).itemsize
    block = np.zeros(n + 2 * SCRATCH_PAD + 64 // size, dtype)
    first = SCRATCH_PAD + (-(block.ctypes.data + SCRATCH_PAD * size) % 64) // size
    return block[first : first + n]


def wavefront_scratch(tables, B):
    raise NotImplementedError("a Numba overload")


# with reference counting: it hands the host's arrays on, and its caller will release them
@overload(wavefront_scratch, jit_options=dict(INLINE_OVERLOAD, _nrt=True))
def _wavefront_scratch_impl(tables, B):
    """A lane's wavefront scratch in the kernel: the host's (R, I, M, C) (wavefront_rows and
    wavefront_tables), then
    the packets' scratch (packet.py) and eight rays' origins and directions as a packet takes
    them, (8, 3) each; None each with B None (a leaf of spheres: wavefront_row takes no
    packets, and none of their scratch is compiled; chosen by B's type, as frame._trace_stacks)."""
    if isinstance(B, types.NoneType):
        return lambda tables, B: (tables[0], tables[1], tables[2], tables[3], None, None)

    def impl(tables, B):
        origins = scratch_array(PACKET * 3, np.float64).reshape((PACKET, 3))
        directions = scratch_array(PACKET * 3, np.float64).reshape((PACKET, 3))
        return tables[0], tables[1], tables[2], tables[3], packet_scratch(), (origins, directions)

    return impl


# --- the stages --------------------------------------------------------------------------


@inline_function
def _sphere_leaf(G):
    """(first, count) of the root leaf when the BVH root is one leaf of spheres alone, else
    (0, 0)."""
    index = G.node_index
    if not _root_is_a_leaf(index):
        return 0, 0
    first = leaf_first(index[0, NODE_REF, 0])
    count = leaf_count(index[0, NODE_REF, 0])
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
def _closest_hits(G, X, B, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, scratch):
    """Closest hits of rays 0..m-1 into T, PRIM, B1, B2 (a sphere's barycentrics are 0, as the
    rows start). In a BVH that takes packets (packet.uses_packets), eight rays at a time where
    they are coherent (camera rays: neighbouring pixels), as cast mode traces them; others ray
    by ray. The hits are closest_hit's either way. B None: the root is a leaf of spheres, and
    the BVH's code is not compiled (see wavefront_row)."""
    if B is not None:
        if leaf_count == 0:
            _bvh_closest_hits(G, X, R, I, m, node_stack, t_stack, scratch)
            return
    fill(R[T : T + STRIDE], m, INF)
    fill(I[PRIM : PRIM + STRIDE], m, NO_HIT)
    tile_closest(R, I, (OX, OY, OZ, DX, DY, DZ, T, PRIM), m, C, leaf_first, leaf_count)


# Calls, not inlined, which find their packets' scratch and the root's box themselves: the
# scenes of the sphere tests (the seed) never take them, and the values they need, kept live
# through the row function, made its loops 3-5% slower.
@kernel_function
def _bvh_closest_hits(G, X, R, I, m, node_stack, t_stack, scratch):
    """_closest_hits through the BVH."""
    _, _, _, _, packets, (origins, directions) = scratch
    _, lane, prim_lane, _ = packets
    root, extent = _packet_bounds(G, X)
    i0 = 0
    while i0 < m:
        n = min(PACKET, m - i0)
        taken = 0  # the leading rays traced as a packet, the others ray by ray
        if extent > 0.0:
            _load_packet(R, i0, n, OX, DX, origins, directions)
            taken = packet_trace(G, X, root, origins, directions, 0, n, extent, packets, node_stack, t_stack, None)
        for k in range(n):
            i = i0 + k
            if k < taken:
                t, prim, b1, b2 = packet_hit(lane, prim_lane, k)
            else:
                o = (R[OX + i], R[OY + i], R[OZ + i])
                d = (R[DX + i], R[DY + i], R[DZ + i])
                t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
            R[T + i] = t
            I[PRIM + i] = prim
            R[B1 + i] = b1
            R[B2 + i] = b2
            if prim != NO_HIT:  # read once the row's hits are in: _compact_hits, _surfaces
                prefetch_surface(G, X, prim)  # (bumpy 4M trace renders 4.8% faster, 40k the same)
        i0 += n


@inline_function
def _packet_bounds(G, X):
    """(root_box, scene_extent) for the packets through the BVH; extent 0 where the scene
    takes none (packet.uses_packets)."""
    return root_box(G), scene_extent(G) if uses_packets(G, X) else 0.0


@inline_function
def _load_packet(R, i0, n, origin, direction, origins, directions):
    """Slots i0..i0+n-1's rays into the (8, 3) arrays a packet takes: their origins from the
    three rows from `origin` (x, y, z: OX or QX), their directions from those from `direction`."""
    for k in range(n):
        for c in range(3):
            origins[k, c] = R[origin + c * STRIDE + i0 + k]
            directions[k, c] = R[direction + c * STRIDE + i0 + k]


@inline_function
def _move(R, i, k, a, b, c):
    """Rows a, b, c of slot i into slot k (k < i), loaded before any is stored."""
    va, vb, vc = R[at(a, i)], R[at(b, i)], R[at(c, i)]
    R[at(a, k)], R[at(b, k)], R[at(c, k)] = va, vb, vc


@inline_function
def _move_ray(R, I, i, k, textured):
    """A ray's state (origin, direction, weight, colour, sample; the cone only for textures)
    from slot i to k < i."""
    _move(R, i, k, OX, OY, OZ)
    _move(R, i, k, DX, DY, DZ)
    _move(R, i, k, WR, WG, WB)
    _move(R, i, k, CR, CG, CB)
    if textured:
        _move(R, i, k, CONE, SPREAD, SPREAD)
    I[at(SAMPLE, k)] = I[at(SAMPLE, i)]


@inline_function
def _finish_ray(R, I, i, col):
    """A ray that ends: its sample's colour is final."""
    s = I[at(SAMPLE, i)]
    R[at(S_R, s)], R[at(S_G, s)], R[at(S_B, s)] = col


@inline_function
def _compact_hits(G, Env, B, R, I, M, C, m, bg, spheres, textured, emissive):
    """The rays that hit something move to slots 0..k-1 (in order) and take their hit's
    material (and, in a leaf of `spheres`, the sphere's centre into QX..QZ); the others add the
    sky (the environment, else the background) and end. Returns k. What no later stage reads is
    left: a sphere's barycentrics (always 0), the ray cone without textures, emission where no
    material emits (the rows stay 0)."""
    k = 0
    for i in range(m):
        prim = I[at(PRIM, i)]
        if prim == NO_HIT:
            d = (R[at(DX, i)], R[at(DY, i)], R[at(DZ, i)])
            w = (R[at(WR, i)], R[at(WG, i)], R[at(WB, i)])
            sky = bg
            if B is not None:  # (B None: no environment; see wavefront_row)
                if Env.present:
                    sky = environment_radiance(Env, d)
            _finish_ray(
                R, I, i, (R[at(CR, i)] + w[0] * sky[0], R[at(CG, i)] + w[1] * sky[1], R[at(CB, i)] + w[2] * sky[2])
            )
            continue
        if k < i:
            _move_ray(R, I, i, k, textured)
            if spheres:
                R[at(T, k)] = R[at(T, i)]
            else:
                _move(R, i, k, T, B1, B2)
            I[at(PRIM, k)] = prim
        mm = np.int64(G.prims[np.uint64(prim), PRIM_MATERIAL])
        I[at(MATERIAL, k)] = mm
        R[at(AR, k)], R[at(AG, k)], R[at(AB, k)] = M[np.uint64(mm), 0], M[np.uint64(mm), 1], M[np.uint64(mm), 2]
        if emissive:
            R[at(ER, k)], R[at(EG, k)], R[at(EB, k)] = M[np.uint64(mm), 3], M[np.uint64(mm), 4], M[np.uint64(mm), 5]
        R[at(SPEC, k)], R[at(REFL, k)] = M[np.uint64(mm), 6], M[np.uint64(mm), 7]
        if spheres:
            R[at(QX, k)], R[at(QY, k)], R[at(QZ, k)] = (
                C[np.uint64(prim), 0],
                C[np.uint64(prim), 1],
                C[np.uint64(prim), 2],
            )
        k += 1
    return k


@inline_function
def _compact_reflected(R, I, m, textured):
    """The reflected rays that go on (FLAG) move to slots 0..k-1 (in order); the others end.
    Returns k."""
    k = 0
    for i in range(m):
        if I[at(FLAG, i)] == 0:
            _finish_ray(R, I, i, (R[at(CR, i)], R[at(CG, i)], R[at(CB, i)]))
            continue
        if k < i:
            _move_ray(R, I, i, k, textured)
        k += 1
    return k


@inline_function
def _hit_point(R, i):
    o = (R[OX + i], R[OY + i], R[OZ + i])
    return madd(o, (R[DX + i], R[DY + i], R[DZ + i]), R[T + i])


@inline_function
def _surfaces(G, F, X, R, I, m):
    """trace_ray's steps from a hit to its albedo, ray by ray (any basic scene)."""
    mat = F.materials
    for i in range(m):
        d = (R[DX + i], R[DY + i], R[DZ + i])
        t = R[T + i]
        p = _hit_point(R, i)
        prim = I[PRIM + i]
        b1 = R[B1 + i]
        b2 = R[B2 + i]
        ng, ns, mm, obj, face = surface(G, X, prim, b1, b2, p)
        if not dot(ng, d) < 0.0:  # leaving: the segment lay inside this surface's medium
            R[WR + i], R[WG + i], R[WB + i] = beer_lambert(mat, mm, (R[WR + i], R[WG + i], R[WB + i]), t)
            ng = mul(ng, -1.0)
            ns = mul(ns, -1.0)
        if dot(ns, d) >= 0.0:
            ns = ng
        q = madd(p, ng, offset_epsilon(F.epsilon_floor, p))
        cone = R[CONE + i] + R[SPREAD + i] * t
        R[CONE + i] = cone
        R[QX + i], R[QY + i], R[QZ + i] = q
        R[PX + i], R[PY + i], R[PZ + i] = p
        R[NX + i], R[NY + i], R[NZ + i] = ns
        if mat[mm, MAT_TEXTURE] >= 0:
            R[AR + i], R[AG + i], R[AB + i] = albedo(G, F, X, mm, prim, b1, b2, p, d, ng, cone)


@vector_loop(fastmath=FAST)
def _sphere_surfaces(R, I, m, epsilon_floor):
    """_surfaces for spheres, with their centres in QX..QZ (overwritten by the offset hit
    points): the normal, its flip for rays leaving the sphere (marked in FLAG: their absorption
    and textures are left to _sphere_surface_extras), the offset point and the cone. Returns the
    number of rays leaving."""
    count = 0
    for i in range(m):
        dx, dy, dz, t = R[DX + i], R[DY + i], R[DZ + i], R[T + i]
        px = R[OX + i] + dx * t
        py = R[OY + i] + dy * t
        pz = R[OZ + i] + dz * t
        ax = px - R[QX + i]
        ay = py - R[QY + i]
        az = pz - R[QZ + i]
        ux, uy, uz = normalize((ax, ay, az))
        out = not ux * dx + uy * dy + uz * dz < 0.0
        if out:
            ux, uy, uz = ux * -1.0, uy * -1.0, uz * -1.0
        eps = 1e-7 * max(max(max(abs(px), abs(py)), abs(pz)), epsilon_floor)
        R[PX + i] = px
        R[PY + i] = py
        R[PZ + i] = pz
        R[QX + i] = px + ux * eps
        R[QY + i] = py + uy * eps
        R[QZ + i] = pz + uz * eps
        R[NX + i], R[NY + i], R[NZ + i] = ux, uy, uz
        R[CONE + i] = R[CONE + i] + R[SPREAD + i] * t
        I[FLAG + i] = 1 if out else 0
        count += 1 if out else 0
    return count


@inline_function
def _sphere_surface_extras(G, F, X, B, R, I, m):
    """What _sphere_surfaces leaves to rays one by one: absorption along the segment inside a
    sphere (a ray leaving it), and textures."""
    mat = F.materials
    for i in range(m):
        mm = I[MATERIAL + i]
        leaving = I[FLAG + i] != 0
        textured = mat[mm, MAT_TEXTURE] >= 0
        if not (leaving or textured):
            continue
        if leaving:
            R[WR + i], R[WG + i], R[WB + i] = beer_lambert(mat, mm, (R[WR + i], R[WG + i], R[WB + i]), R[T + i])
        if B is not None:  # (B None: no textures; see wavefront_row)
            if textured:
                d = (R[DX + i], R[DY + i], R[DZ + i])
                p = _hit_point(R, i)
                ng = (R[NX + i], R[NY + i], R[NZ + i])  # facing the ray, as trace_ray's after its flip
                prim = I[PRIM + i]
                uv = (R[B1 + i], R[B2 + i])
                R[AR + i], R[AG + i], R[AB + i] = albedo(G, F, X, mm, prim, uv[0], uv[1], p, d, ng, R[CONE + i])


@inline_function
def _find_surfaces(G, F, X, B, R, I, m, leaf_count, textured):
    """Albedo, offset point and normal at each slot's hit (`textured`: whether any material
    has a texture)."""
    if B is not None:
        if leaf_count == 0:
            _surfaces(G, F, X, R, I, m)
            return
    leaving = _sphere_surfaces(R, I, m, F.epsilon_floor)
    if B is None:  # (no texture and no absorbing material: _sphere_surface_extras would change nothing)
        return
    if leaving > 0 or textured:
        _sphere_surface_extras(G, F, X, B, R, I, m)


@vector_loop(fastmath=FAST)
def _light_directions(R, I, m, directional, x, y, z):
    """Towards a delta light at (x, y, z), or along (x, y, z) when `directional`, from points
    PX..PZ, the hit points: the unit direction and distance (sample_delta), the diffuse factor and cos(R, V) of
    seed_response.phong_response (with its fast-math rounding: these are trace_ray's operations), and
    whether the highlight is worth its power."""
    for i in range(m):
        if directional:
            tx, ty, tz = x, y, z
        else:
            tx, ty, tz = x - R[PX + i], y - R[PY + i], z - R[PZ + i]
        distance = length((tx, ty, tz))
        ux, uy, uz = normalize((tx, ty, tz))  # the same square root, which LLVM computes once
        nx, ny, nz = R[NX + i], R[NY + i], R[NZ + i]
        n_dot_l = nx * ux + ny * uy + nz * uz
        twice = 2.0 * n_dot_l
        rx, ry, rz = nx * twice - ux, ny * twice - uy, nz * twice - uz
        c = rx * (R[DX + i] * -1.0) + ry * (R[DY + i] * -1.0) + rz * (R[DZ + i] * -1.0)
        s = R[SPEC + i]
        R[LX + i], R[LY + i], R[LZ + i] = ux, uy, uz
        R[TMAX + i] = INF if directional else distance
        R[SCALE + i] = max(n_dot_l, 0.0)
        R[COS_RV + i] = c
        I[HIGHLIGHT + i] = 1 if (s > 0.0) & (c > 0.0) & (c > 1.0 - 50.0 / s) else 0


@inline_function
def _towards_light(L, B, R, I, m, k):
    """direct_lighting's steps for delta light row k up to its shadow ray: the unit direction l
    and distance towards it, and the Phong factor; BLOCKED starts as 'no ray needed' (-1) where
    the factor is 0, else 0. Returns the number of shadow rays."""
    directional = at_infinity(L.kind[k])
    # a delta light's first three columns: its position, or (at infinity) the unit vector to it
    x, y, z = row3(L.data, k, LIGHT_POSITION)
    _light_directions(R, I, m, directional, x, y, z)
    # The powers apart, slot by slot where they are needed: in a loop over every slot LLVM
    # computed the power for all of them (a call without side effects may be speculated), most
    # underflowing into libm's slow path (a quarter of the seed's time).
    for i in range(m):
        if I[HIGHLIGHT + i] != 0:
            R[SCALE + i] += highlight(R[COS_RV + i], R[SPEC + i])
    if B is None:  # (no spot light: variants.trace_features)
        return _needs_shadow(R, I, m)
    if has_falloff(L.kind[k]):
        for i in range(m):
            R[SCALE + i] *= trace_falloff(L, k, (R[LX + i], R[LY + i], R[LZ + i]))
    return _needs_shadow(R, I, m)


@vector_loop
def _needs_shadow(R, I, m):
    """BLOCKED: 0 (a shadow ray to trace) where the light's factor is positive, -1 (none)
    elsewhere. Returns the number of shadow rays."""
    rays = 0
    for i in range(m):
        needed = R[SCALE + i] > 0.0
        I[BLOCKED + i] = 0 if needed else -1
        rays += 1 if needed else 0
    return rays


@inline_function
def _shadows(G, X, B, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, directional, scratch):
    """Shadow rays of the slots that need one (BLOCKED 0): BLOCKED becomes 1 where something
    lies between the point and the light. In a BVH that takes packets, eight slots at a time
    where their rays are coherent (neighbouring points towards one light), others ray by ray;
    any_hit's answers either way."""
    if B is not None:
        if leaf_count == 0:
            _bvh_shadows(G, X, R, I, m, node_stack, t_stack, scratch)
            return
    tile_blocks(R, I, (QX, QY, QZ, LX, LY, LZ, TMAX, BLOCKED), m, C, leaf_first, leaf_count, directional)


@kernel_function
def _bvh_shadows(G, X, R, I, m, node_stack, t_stack, scratch):
    """_shadows through the BVH."""
    _, _, _, _, packets, (origins, directions) = scratch
    root, extent = _packet_bounds(G, X)
    i0 = 0
    while i0 < m:
        n = min(PACKET, m - i0)
        need = 0
        for k in range(n):
            if I[BLOCKED + i0 + k] == 0:
                need |= 1 << k
        taken = 0  # the leading rays traced as a packet, the others ray by ray
        if need != 0 and extent > 0.0:
            _load_packet(R, i0, n, QX, LX, origins, directions)
            taken, blocked = packet_blocked(
                G, X, root, origins, directions, None, R, TMAX + i0, 0, n, need, extent, packets, node_stack, t_stack
            )
            for k in range(taken):
                if (blocked >> k) & 1:
                    I[BLOCKED + i0 + k] = 1
        if taken < n:
            for k in range(taken, n):
                i = i0 + k
                if I[BLOCKED + i] == 0:
                    o = (R[QX + i], R[QY + i], R[QZ + i])
                    d = (R[LX + i], R[LY + i], R[LZ + i])
                    if any_hit(G, X, o, d, 0.0, R[TMAX + i], node_stack, t_stack):
                        I[BLOCKED + i] = 1
        i0 += n


@vector_loop(fastmath=FAST)
def _gather_light(R, I, m, r, g, b):
    """Light of intensity (r, g, b) at each slot (direct_lighting's sum), unless its ray was
    blocked (1: transmittance 0) or it sends nothing (-1)."""
    # Every slot's sum is stored, +0.0 added where no light arrives: a store of `sum + light
    # if add else sum` became a masked store (vmaskmovpd), microcoded and slow on AMD's Zen 3.
    # (Light sums are never -0.0, which adding +0.0 would change.) The product keeps the shape
    # r * scale * tr that trace_ray's sum has, so it rounds (and contracts) the same.
    for i in range(m):
        lit = I[BLOCKED + i] == 0  # neither blocked (1) nor sending nothing (-1)
        scale = R[SCALE + i]  # (read unconditionally: a conditional read kept the loop scalar)
        scale = scale if lit else 0.0
        tr = 1.0 if lit else 0.0
        R[IR + i] += r * scale * tr
        R[IG + i] += g * scale * tr
        R[IB + i] += b * scale * tr


@inline_function
def _lighting(G, X, B, L, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, scratch):
    """Ambient + diffuse + specular light at every slot from every light; returns the shadow
    rays traced."""
    # The ambient lights before any other are the same sum for every slot (in trace_ray's order:
    # from 0, light by light), which the rows start from.
    ambient = (0.0, 0.0, 0.0)
    first = 0
    while first < L.order.shape[0] and is_everywhere(L.kind[L.order[first]]):
        a = row3(L.data, L.order[first], LIGHT_INTENSITY)
        ambient = (ambient[0] + a[0], ambient[1] + a[1], ambient[2] + a[2])
        first += 1
    for c, row in enumerate((IR, IG, IB)):
        fill(R[row : row + STRIDE], m, ambient[c])
    rays = 0
    for j in range(first, L.order.shape[0]):
        k = L.order[j]
        if is_everywhere(L.kind[k]):
            intensity = row3(L.data, k, LIGHT_INTENSITY)
            for i in range(m):
                R[IR + i] += intensity[0]
                R[IG + i] += intensity[1]
                R[IB + i] += intensity[2]
            continue
        rays += _towards_light(L, B, R, I, m, k)
        directional = at_infinity(L.kind[k])
        _shadows(G, X, B, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, directional, scratch)
        r, g, b = row3(L.data, k, LIGHT_INTENSITY)
        _gather_light(R, I, m, r, g, b)
    return rays


@vector_loop(fastmath=FAST)
def _add_local_and_reflect(R, I, m, last):
    """Each ray's local colour (albedo x light + emission) into its colour, weighted as
    trace_ray weighs it: whole on the `last` bounce, else times 1 - reflectivity (trace_ray's
    factors 1 - transparency are exactly 1 here); then its reflection (from the offset point,
    in place), and whether it goes on (FLAG): not after the `last` bounce, nor once its weight
    cannot matter."""
    for i in range(m):
        lr = R[AR + i] * R[IR + i] + R[ER + i]
        lg = R[AG + i] * R[IG + i] + R[EG + i]
        lb = R[AB + i] * R[IB + i] + R[EB + i]
        r = R[REFL + i]
        k_local = 1.0 if last else 1.0 - r
        wr, wg, wb = R[WR + i], R[WG + i], R[WB + i]
        R[CR + i] = R[CR + i] + wr * k_local * lr
        R[CG + i] = R[CG + i] + wg * k_local * lg
        R[CB + i] = R[CB + i] + wb * k_local * lb
        R[OX + i], R[OY + i], R[OZ + i] = R[QX + i], R[QY + i], R[QZ + i]
        w0, w1, w2 = wr * r, wg * r, wb * r
        dx, dy, dz = R[DX + i], R[DY + i], R[DZ + i]
        nx, ny, nz = R[NX + i], R[NY + i], R[NZ + i]
        twice = -2.0 * (dx * nx + dy * ny + dz * nz)
        R[DX + i] = dx + nx * twice
        R[DY + i] = dy + ny * twice
        R[DZ + i] = dz + nz * twice
        R[WR + i], R[WG + i], R[WB + i] = w0, w1, w2
        I[FLAG + i] = 0 if last else (1 if max(max(w0, w1), w2) > MIN_WEIGHT else 0)


@vector_loop(fastmath=FAST)
def _pinhole_directions(R, n, cam, i0, j, width, height, spread):
    """camera.camera_ray's directions through the centres of pixels i0..i0+n-1 of row j into
    DX..DZ, and their cones' spread (camera.obliquity), as trace mode's row gives them."""
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
        R[DX + k], R[DY + k], R[DZ + k] = x, y, z
        R[SPREAD + k] = spread * abs(x * fx + y * fy + z * fz)


@inline_function
def _centre_rays(R, n, cam, i0, j, width, height, spread):
    """camera_sample's rays through the centres of pixels i0..i0+n-1 of row j (one sample per
    pixel, a pinhole), without the unused random key."""
    _pinhole_directions(R, n, cam, i0, j, width, height, spread)
    for c, row in enumerate((OX, OY, OZ)):
        fill(R[row : row + STRIDE], n, cam[CAM_POSITION + c])
    fill(R[S_W : S_W + STRIDE], n, 1.0)


@inline_function
def _sampled_rays(R, n, cam, filt, seed, i0, s0, j, samples, width, height, spread):
    """camera_sample's rays of the n samples from sample s0 of pixel i0 of row j on."""
    total_spp = samples[2]
    pi, ps = i0, s0
    for k in range(n):
        o, d, w, _ = camera_sample(cam, filt, seed, pi, j, ps, total_spp, width, height)
        R[DX + k], R[DY + k], R[DZ + k] = d
        R[SPREAD + k] = spread * obliquity(cam, d)
        R[OX + k], R[OY + k], R[OZ + k] = o
        R[S_W + k] = w
        pi, ps = next_sample(pi, ps, samples)


@kernel_function
def wavefront_row(G, F, L, X, B, Env, P, j, film, scratch, node_stack, t_stack):
    """trace mode's _trace_row for a basic scene: the row's samples of pass P (film/image_pass.py),
    in pixel order, through the Whitted loop TILE at a time, then into the film in order.
    Returns the rays traced. B is None for the seed's kind of picture (variants.trace_features):
    the BVH root one leaf of spheres (variants.sphere_leaf, the host's _sphere_leaf), no
    environment, texture, absorbing material or spot light, one sample at each pixel's centre through a pinhole
    into a film of signed sums only. That compiles the sphere tests alone, without BVH
    traversal, packets, triangles, environment, textures, spot lights, camera sampling and the
    film's running sums. Else B is 0, and the row takes whichever way _sphere_leaf finds."""
    cam, filt, width, height, window, samples, seed, max_depth, bg = P
    R, I, M, C, _, _ = scratch
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    leaf_first, leaf_count = _sphere_leaf(G)
    textured = False  # any material with a texture; any that emits
    emissive = False
    for mm in range(F.materials.shape[0]):
        textured = textured or F.materials[mm, MAT_TEXTURE] >= 0
        emissive = emissive or max(row3(F.materials, mm, MAT_EMISSION)) != 0.0
    pinhole_centres = total_spp == 1 and not cam[CAM_LENS_RADIUS] > 0.0
    total_samples = (x1 - x0) * count
    one_each = count == 1 and film.shape[2] == FILM_WIDTH  # one sample a pixel: film.add_one_each
    # (B None: pinhole_centres and one_each hold; the branches on `B is None` below leave the
    # other ways uncompiled)
    flat = film.reshape(film.size)
    rays = 0
    pixel = x0
    if B is None:  # (one sample a pixel: no running sums)
        total = ((0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))
    else:
        total = pixel_sums(film, j - y0, 0)
    i0, s0 = x0, first  # the pixel and sample number of the tile's first sample
    q = 0
    while q < total_samples:
        n = min(TILE, total_samples - q)
        film_at = ((j - y0) * film.shape[1] + i0 - x0) * FILM_WIDTH  # the tile's first pixel in flat
        if one_each:  # the film's pixels of this tile, fetched while the tile is traced
            for k in range(film_at, film_at + n * FILM_WIDTH, 8):
                prefetch_row(flat, k)
        if B is None:
            _centre_rays(R, n, cam, i0, j, width, height, spread)
        elif pinhole_centres:
            _centre_rays(R, n, cam, i0, j, width, height, spread)
        else:
            _sampled_rays(R, n, cam, filt, seed, i0, s0, j, samples, width, height, spread)
        for row in (WR, WG, WB):
            fill(R[row : row + STRIDE], n, 1.0)
        for row in (CONE, CR, CG, CB):
            fill(R[row : row + STRIDE], n, 0.0)
        count_up(I[SAMPLE : SAMPLE + STRIDE], n)
        m = n
        depth = max_depth
        while m > 0:
            _closest_hits(G, X, B, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, scratch)
            rays += m
            m = _compact_hits(G, Env, B, R, I, M, C, m, bg, leaf_count > 0, textured, emissive)
            _find_surfaces(G, F, X, B, R, I, m, leaf_count, textured)
            rays += _lighting(G, X, B, L, R, I, C, m, leaf_first, leaf_count, node_stack, t_stack, scratch)
            last = depth <= 0
            _add_local_and_reflect(R, I, m, last)
            m = _compact_reflected(R, I, m, textured)
            depth -= 1
        if B is None:
            add_one_each(flat, film_at, R, (S_R, S_G, S_B, S_W), n)
            i0 += n
        elif one_each:
            add_one_each(flat, film_at, R, (S_R, S_G, S_B, S_W), n)
            i0 += n
        else:
            for k in range(n):
                col = (R[S_R + k], R[S_G + k], R[S_B + k])
                pixel, total = add_in_pixel_order(film, j - y0, x0, pixel, total, i0, col, R[S_W + k])
                i0, s0 = next_sample(i0, s0, samples)
        q += n
    if B is not None:
        if not one_each:
            store_sums(film, j - y0, pixel - x0, total)
    return rays
