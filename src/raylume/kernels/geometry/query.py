"""Batch ray queries over a compiled scene: closest hits and occlusion for arrays of rays
(benchmarks, tests, and users who want raylume as a ray-intersection library)."""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..frame_stack import roomy_njit
from ..scene import geometry_of
from ..vec import FAST, inline_function, kernel_function
from .packet import (
    PACKET,
    packet_blocked,
    packet_hit,
    packet_scratch,
    packet_trace,
    root_box,
    scene_extent,
    span_of,
    uses_packets,
)
from .shape_triangle import EXACT_DIVISION, exact_ops
from .shapes import NO_HIT, PRIM_FACE, PRIM_OBJECT, instance_id, split_hit
from .traverse import any_hit, closest_hit
from .wide_nodes import INF, prefetch_around, prefetch_cells, scratch_array, traversal_stacks

# How far ahead of the packet being traced its chunk's rays are prefetched (rays): two lines on
# either side of the ray RAYS_AHEAD on, each packet. On a large mesh the traversal's own misses
# keep the hardware's stream prefetcher from bringing the rays in on time: packet_setup's loads
# of them were among bumpy 4M's hottest instructions (tools/profile_kernels.py --hits 4M
# --instructions 40). benchmarks/ab_queries.py, pinned, 30 rounds, both ways round: hit rays 4M
# 1.8% and 2.1% faster, 40k 1.4% and 1.7%; shadow rays 4M 4.5% and 3.2%, 40k 1.9% (128 rays
# ahead: no faster).
RAYS_AHEAD = 64


@inline_function
def prefetch_rays(origins, directions, r):
    """Start loading the lines around ray r's origin and direction (RAYS_AHEAD says why): two on
    either side, harmless beyond the arrays' ends."""
    prefetch_around(origins, r, r, 2)
    prefetch_around(directions, r, r, 2)


# A call per chunk of rays, compiled without reference counting (KERNEL), as the frame kernels'
# row functions are: inlined into the lane's loop (then a parfor's), the traversal took and
# dropped references to the BVH arrays for every ray (4 calls with atomic operations a ray).
@kernel_function
def _intersect_chunk(G, X, origins, directions, base, spans, outputs, tiles, start, end, stacks, packets, hits):
    """Rays start .. end - 1 (at most CHUNK; ray k at origins[k - base], directions[k - base],
    its hits between span_of(spans[0], k) and span_of(spans[1], k)) into the outputs: traced
    first, each hit and distance kept in `hits` (chunk_hits: one of each per ray of the chunk),
    then stored with their ids (store_hits; tiles: the chunk's layout, load_chunk). A hit's
    object and face ids lie in its row of the primitive table, a cache miss of its own on a
    large mesh; the row is prefetched when the hit is found and read after the whole chunk is
    traced, when it has long arrived (bumpy 4M hit rays on a Zen 3 71.4 -> 67.5 ms, 1M 56.5 ->
    50.0, against the eight rows requested together after each packet). The prefetch asks for
    the lines of the two ids, not of the row's first byte: a quarter of the 24-byte rows cross
    a line, and their ids' line had waited to be read (bumpy 4M 2-3.5% faster, 1M 1%:
    benchmarks/ab_queries.py, pinned)."""
    extent = scene_extent(G)
    root = root_box(G)
    packets_here = uses_packets(G, X)
    k = start
    while k < end:
        n = min(PACKET, end - k)
        taken = 0
        prefetch_rays(origins, directions, k - base + RAYS_AHEAD)
        if packets_here:
            rays = (origins, directions, base, spans)
            taken = _packet_hits(G, X, rays, k, n, extent, root, hits, start, stacks, packets)
        if taken == 0:
            # one call site: the single-ray traversal is inlined once (a second copy cost ~1.5 s
            # of cold compile)
            _closest_hits_singly(G, X, origins, directions, base, spans, k, k + n, hits, start, stacks)
            taken = n
        k += taken  # after a packet that took fewer rays, the next starts at the first it left
    store_hits(G, X, tiles, start, end, hits, outputs)


@inline_function
def _packet_hits(G, X, rays, k, n, extent, root, hits, start, stacks, packets):
    """Rays k .. k + n - 1 (at origins[k - base] ...) traced as a packet, their hits kept at
    k - start ... (extent: scene_extent(G), root: root_box(G)). Returns how many of them, from
    the first, the packet took (packet_trace); 0 when it refused them, and nothing kept.
    rays: (origins, directions, base, spans), as _intersect_chunk takes them."""
    origins, directions, base, spans = rays
    node_stack, t_stack = stacks
    _, lane, prim_lane, _ = packets
    taken = packet_trace(
        G, X, root, origins, directions, k - base, n, extent, packets, node_stack, t_stack, (spans[0], spans[1], k)
    )
    for i in range(taken):
        t, prim, _, _ = packet_hit(lane, prim_lane, i)
        _keep_hit(G, X, k + i - start, t, prim, hits)
    return taken


@inline_function
def _closest_hits_singly(G, X, origins, directions, base, spans, first, end, hits, start, stacks):
    """Rays first .. end - 1 (ray k at origins[k - base] ..., between span_of(spans[0], k) and
    span_of(spans[1], k)) ray by ray (closest_hit), their hits kept at k - start."""
    node_stack, t_stack = stacks
    tmin, tmax = spans[0], spans[1]
    for k in range(first, end):
        r = k - base
        o = (float(origins[r, 0]), float(origins[r, 1]), float(origins[r, 2]))
        d = (float(directions[r, 0]), float(directions[r, 1]), float(directions[r, 2]))
        t, prim, b1, b2 = closest_hit(G, X, o, d, span_of(tmin, k), span_of(tmax, k), node_stack, t_stack)
        _keep_hit(G, X, k - start, t, prim, hits)


@kernel_function(_nrt=True)
def chunk_hits():
    """One lane's hits of a chunk's rays, kept until they are stored: (primitive, distance)."""
    return scratch_array(CHUNK, np.int64), scratch_array(CHUNK, np.float64)


@inline_function
def _keep_hit(G, X, q, t, prim, hits):
    """The hit of the chunk's ray q and its distance (inf for a miss, which the traversal leaves
    at its tmax)."""
    hits[0][q] = prim
    if prim != NO_HIT:
        hits[1][q] = t
        prefetch_cells(G.prims, split_hit(X, prim)[0], PRIM_OBJECT, PRIM_FACE)
    else:
        hits[1][q] = INF


# A chunk's layout in the call's rays (load_chunk): (first, rows, width, groups, rest) for an
# image's chunk, rows of `width` rays, each of its `rows` rows with groups * TILE + rest of
# them from ray first + row * width on; all 0 for rays in their own order.
IN_ORDER = (0, 0, 0, 0, 0)


@inline_function
def store_hits(G, X, tiles, start, end, hits, outputs):
    """The distances, object, face and instance ids of rays start .. end - 1 from their hits
    (hits at k - start; -1 for a miss), into the outputs in their own order (tiles: the chunk's
    layout): an image's chunk is traced in packet order (_unit_rays), and its outputs written
    in that order, eight streams interleaved four elements at a time, had cost ~3 ns a ray more
    than rays in rows (bumpy 10k and 40k frames as images 5-7% slower than in rows)."""
    first, rows, width, groups, rest = tiles
    image = rows != 0
    count = groups * TILE + rest
    if not image:  # rays in their own order: one row of them
        first, rows, count = start, 1, end - start
    shift = rows + 1  # an image's whole group of rays: TILE a row, 1 << shift in all
    t_out, object_out, prim_out, instance_out = outputs
    for row in range(rows):
        for col in range(count):
            q = col  # where the ray is in the chunk
            if image:
                if col < groups * TILE:
                    q = ((col >> 2) << shift) + (row << 2) + (col & 3)
                else:
                    q = (groups << shift) + row * rest + col - groups * TILE
            at = first + row * width + col
            prim = hits[0][q]
            t_out[at] = hits[1][q]
            if prim == NO_HIT:
                object_out[at] = -1
                prim_out[at] = -1
                instance_out[at] = -1
            else:
                hit_row, _ = split_hit(X, prim)
                object_out[at] = G.prims[hit_row, PRIM_OBJECT]
                prim_out[at] = G.prims[hit_row, PRIM_FACE]
                instance_out[at] = instance_id(X, prim)


@inline_function
def intersect_singly(G, X, origins, directions, spans, outputs, start, end, stacks, hits):
    """intersect_lane's work for rays start .. end - 1 (at most CHUNK; spans: (tmin, tmax) as
    span_of reads them) without packets: the single-ray traversal alone
    (benchmarks/bench_hits.py; hits: as chunk_hits makes them)."""
    _closest_hits_singly(G, X, origins, directions, 0, spans, start, end, hits, start, stacks)
    store_hits(G, X, IN_ORDER, start, end, hits, outputs)


_F64 = ir.DoubleType()
_I32, _I64 = ir.IntType(32), ir.IntType(64)
# Directions whose largest component lies outside [_SMALL, _BIG] are scaled by _UP or _DOWN (powers
# of two: exact) before their length is taken: their squares would underflow (lose bits, or give a
# length of 0: "not a direction") or overflow (a length of inf: a unit vector of 0, every ray a miss).
_BIG, _SMALL = 2.0**500, 2.0**-500
_DOWN, _UP = 2.0**-600, 2.0**600
_V4D = ir.VectorType(_F64, 4)


@intrinsic
def _unit_rays4(typingctx, origins, directions, k, chunk_origins, chunk_directions, r):
    """Rays k .. k + 3 into rows r .. r + 3 of the chunk's scratch, four rays per vector
    (C-contiguous float64 (N, 3) arrays): the origins copied, the directions divided by their
    lengths, and the number of those rays _unit_rays counts as bad."""
    arrays = (("origins", origins), ("directions", directions), ("chunk", chunk_origins), ("chunk", chunk_directions))
    for name, a in arrays:
        if not (isinstance(a, types.Array) and a.dtype == types.float64 and a.ndim == 2 and a.layout == "C"):
            raise TypingError(f"_unit_rays4: {name} must be a C-contiguous float64 (N, 3) array")

    def codegen(context, builder, sig, args):
        fadd, _, fmul, lt = exact_ops(builder)
        data = [context.make_array(sig.args[i])(context, builder, args[i]).data for i in (0, 1, 3, 4)]
        k3 = builder.mul(context.cast(builder, args[2], sig.args[2], types.int64), ir.Constant(_I64, 3))
        r3 = builder.mul(context.cast(builder, args[5], sig.args[5], types.int64), ir.Constant(_I64, 3))

        def vectors(ptr, at):  # the 12 doubles at ptr[at:at + 12] as three <4 x double>
            return [
                builder.load(
                    builder.bitcast(builder.gep(ptr, [builder.add(at, ir.Constant(_I64, 4 * v))]), _V4D.as_pointer()),
                    align=8,
                )
                for v in range(3)
            ]

        def store(values, ptr, at):
            for v, value in enumerate(values):
                p = builder.gep(ptr, [builder.add(at, ir.Constant(_I64, 4 * v))])
                builder.store(value, builder.bitcast(p, _V4D.as_pointer()), align=8)

        def shuffle(a, b, lanes):
            return builder.shuffle_vector(a, b, ir.Constant(ir.VectorType(_I32, len(lanes)), lanes))

        # rays as rows x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3: lane j of x is element 3 j
        def to_xyz(v):
            ab = [shuffle(v[0], v[1], lanes) for lanes in ([0, 3, 6, 0], [1, 4, 7, 0], [2, 5, 0, 0])]
            return (
                shuffle(ab[0], v[2], [0, 1, 2, 5]),
                shuffle(ab[1], v[2], [0, 1, 2, 6]),
                shuffle(ab[2], v[2], [0, 1, 4, 7]),
            )

        def from_xyz(x, y, z):
            xy = shuffle(x, y, [0, 4, 1, 5])  # x0 y0 x1 y1
            zx = shuffle(z, x, [0, 6, 1, 7])  # z0 x2 z1 x3
            yz = shuffle(y, z, [2, 6, 3, 7])  # y2 z2 y3 z3
            return (
                shuffle(xy, zx, [0, 1, 4, 2]),  # x0 y0 z0 x1
                shuffle(xy, shuffle(zx, yz, [2, 1, 4, 0]), [3, 4, 5, 6]),  # y1 z1 x2 y2
                shuffle(yz, zx, [1, 7, 2, 3]),  # z2 x3 y3 z3
            )

        o = vectors(data[0], k3)
        store(o, data[2], r3)
        x, y, z = to_xyz(vectors(data[1], k3))
        fabs = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V4D, [_V4D]), "llvm.fabs.v4f64")
        # a direction whose squares would overflow or underflow is first scaled by a power of
        # two (exact); any other is scaled by 1, so its bits are numpy's
        fmax = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V4D, [_V4D, _V4D]), "llvm.maxnum.v4f64")
        m = builder.call(
            fmax, [builder.call(fmax, [builder.call(fabs, [x]), builder.call(fabs, [y])]), builder.call(fabs, [z])]
        )
        scale = builder.select(
            lt(ir.Constant(_V4D, [_BIG] * 4), m),
            ir.Constant(_V4D, [_DOWN] * 4),
            builder.select(
                lt(m, ir.Constant(_V4D, [_SMALL] * 4)), ir.Constant(_V4D, [_UP] * 4), ir.Constant(_V4D, [1.0] * 4)
            ),
        )
        x, y, z = (fmul(c, scale) for c in (x, y, z))
        sqrt = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V4D, [_V4D]), "llvm.sqrt.v4f64")
        n = builder.call(sqrt, [fadd(fadd(fmul(x, x), fmul(y, y)), fmul(z, z))])
        store(from_xyz(*(builder.fdiv(c, n, flags=EXACT_DIVISION) for c in (x, y, z))), data[3], r3)
        inf = ir.Constant(_V4D, [math.inf] * 4)
        ok = lt(ir.Constant(_V4D, [0.0] * 4), n)
        for c in (x, y, z, *to_xyz(o)):
            ok = builder.and_(ok, lt(builder.call(fabs, [c]), inf))
        i4 = ir.IntType(4)
        ctpop = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i4, [i4]), "llvm.ctpop.i4")
        good = builder.call(ctpop, [builder.bitcast(ok, i4)])
        return builder.sub(ir.Constant(_I64, 4), builder.zext(good, _I64))

    return types.int64(origins, directions, k, chunk_origins, chunk_directions, r), codegen


@kernel_function(error_model="numpy", _nrt=False, fastmath=False)
def _unit_rays(origins, directions, first, count, rows, width, chunk_origins, chunk_directions):
    """`rows` rows (1 or 2) of `count` rays each (row r's i-th: ray first + r * width + i)
    copied into the chunk's scratch in packet order: four rays of the first row, the four below
    them, and so on, then the rows' last few (one row: in its order; store_hits undoes the
    order). Each direction is divided by its length: numpy's d / np.linalg.norm(d, axis=1) to
    the bit (IEEE, (x^2 + y^2) + z^2, no FMA: fastmath off), after a power-of-two scale where
    its squares would overflow or underflow (_BIG, _SMALL), four rays per vector (a scalar
    loop took ~14 ns a ray, as much as a frame's miss, against ~5). Each row is read in turn,
    as one stream. Returns how many rays have a component that is not finite or a direction of
    length 0; they are traced all the same, as misses,
    and raylume.intersect refuses the call."""
    groups = count // TILE  # whole groups of TILE rays, then a narrower one
    rest = count - groups * TILE
    bad = 0
    for row in range(rows):
        k0 = first + row * width
        for g in range(groups):
            k, p = k0 + g * TILE, (g * rows + row) * TILE
            bad += _unit_rays4(origins, directions, k, chunk_origins, chunk_directions, p)
        for i in range(rest):
            k, r = k0 + groups * TILE + i, groups * rows * TILE + row * rest + i
            x, y, z = directions[k, 0], directions[k, 1], directions[k, 2]
            m = max(abs(x), abs(y), abs(z))
            scale = _DOWN if m > _BIG else (_UP if m < _SMALL else 1.0)  # as _unit_rays4
            x, y, z = x * scale, y * scale, z * scale
            n = math.sqrt(x * x + y * y + z * z)
            chunk_directions[r, 0] = x / n
            chunk_directions[r, 1] = y / n
            chunk_directions[r, 2] = z / n
            ok = n > 0.0 and abs(x) < math.inf and abs(y) < math.inf and abs(z) < math.inf
            for c in range(3):
                chunk_origins[r, c] = origins[k, c]
                ok = ok and abs(origins[k, c]) < math.inf
            if not ok:
                bad += 1
    return bad


# Rays per chunk: a lane takes every lanes-th chunk (neighbouring rays cost alike, distant ones
# may not; see frame.py).
CHUNK = 256

# Rays that form an image (raylume.intersect's rays of shape (..., H, W, 3)) go in chunks of two
# rows of BAND rays, traced in packets of 4 x 2 neighbours instead of 8 along a row, as cast mode
# traces its pixels: neighbours in both directions spread less, so on a mesh with several
# triangles under each pixel they share more of their way down the tree (bench_hits.py's frame
# as an image on a Zen 3: bumpy 4M 83.2 -> 78.5 ms, 1M 64.8 -> 61.3, 40k 45.0 -> 45.1). Rows
# shorter than GRID_MIN_WIDTH keep their order.
BAND = CHUNK // 2
TILE = PACKET // 2  # a packet's rays along each of its two rows
GRID_MIN_WIDTH = 2 * TILE


def grid_width(shape: tuple[int, ...]) -> int:
    """The row length by which rays of leading shape `shape` are traced as an image (4 x 2
    packets): its last axis where there are at least two rows of at least GRID_MIN_WIDTH rays,
    else 0 (the rays in their own order)."""
    if len(shape) < 2 or shape[-1] < GRID_MIN_WIDTH or math.prod(shape) < 2 * shape[-1]:
        return 0
    return shape[-1]


def chunk_layout(n: int, width: int) -> tuple[int, int]:
    """How the lanes share n rays: (shares, chunks a share). Rays in their own order (width 0):
    chunks of CHUNK, one a share; an image's, in rows of `width` (grid_width): bands of two
    rows, each of them the chunks of BAND columns side by side (load_chunk)."""
    if width == 0:
        return (n + CHUNK - 1) // CHUNK, 1
    return (n // width + 1) // 2, (width + BAND - 1) // BAND


@kernel_function(_nrt=True)
def chunk_scratch():
    """One lane's copy of a chunk's rays: (origins, unit directions), (CHUNK, 3) each."""
    return (
        scratch_array(CHUNK * 3, np.float64).reshape((CHUNK, 3)),
        scratch_array(CHUNK * 3, np.float64).reshape((CHUNK, 3)),
    )


@kernel_function
def load_chunk(origins, directions, unit, width, share, segment, chunk_origins, chunk_directions):
    """Chunk `segment` of share `share` of the rays (chunk_layout) as intersect_lane traces it:
    returns (start, end, base, tiles, bad). Its rays are start .. end - 1, ray k read at row
    k - base of the caller's origins and directions, or with `unit` of the chunk's copy
    (chunk_origins ...), where _unit_rays makes their directions unit vectors and counts the
    bad ones (bad). tiles: the chunk's layout (store_hits). An image's chunk (width > 0, with
    `unit`) is two rows of up to BAND rays, copied in packet order."""
    n = origins.shape[0]
    if width == 0:
        start, end = share * CHUNK, min(n, (share + 1) * CHUNK)
        if not unit:
            return start, end, 0, IN_ORDER, 0
        bad = _unit_rays(origins, directions, start, end - start, 1, 0, chunk_origins, chunk_directions)
        return start, end, start, IN_ORDER, bad
    y0, x0 = 2 * share, segment * BAND
    rows, x1 = min(2, n // width - y0), min(width, x0 + BAND)
    first = y0 * width + x0
    bad = _unit_rays(origins, directions, first, x1 - x0, rows, width, chunk_origins, chunk_directions)
    return 0, rows * (x1 - x0), 0, (first, rows, width, (x1 - x0) // TILE, (x1 - x0) % TILE), bad


@roomy_njit(nogil=True, fastmath=FAST, cache=True, error_model="numpy")
def intersect_lane(S, X, origins, directions, spans, outputs, width, layout, lane, lanes, unit, bad):
    """Closest hits of lane `lane` of `lanes` between spans = (tmin, tmax) (span_of) into outputs
    = (t, object, prim, instance) (store_hits): the chunks of
    shares lane, lane + lanes, ... of the rays (layout: chunk_layout(n, width); width:
    grid_width or 0). With `unit`, directions of any length, made unit vectors chunk by chunk
    (_unit_rays), and the rays that cannot be (or have an origin that is not finite) counted in
    bad[lane]."""
    G = geometry_of(S)
    stacks = traversal_stacks()
    packets = packet_scratch()
    hits = chunk_hits()
    scratch = chunk_scratch()
    refused = 0
    # An image's lane takes whole bands (two rows) in turn, their chunks side by side: bumpy 4M
    # frames on 2 threads 3-4% faster than with the chunks dealt out one by one, as rays in
    # their own order are.
    shares, per_share = layout
    for share in range(lane, shares, lanes):
        for segment in range(per_share):
            # ray k at row k - base of o and d: the caller's arrays, or with `unit` the lane's
            # copy of the chunk (load_chunk). One call site, one signature: the traversal is
            # compiled once (a second cost ~2.5 s). (Not a helper that returns the arrays:
            # compiled without reference counting, its returned arrays would be released by
            # this function once too often.)
            start, end, base, tiles, bad_here = load_chunk(
                origins, directions, unit, width, share, segment, scratch[0], scratch[1]
            )
            refused += bad_here
            o, d = (scratch[0], scratch[1]) if unit else (origins, directions)
            _intersect_chunk(G, X, o, d, base, spans, outputs, tiles, start, end, stacks, packets, hits)
    bad[lane] = refused


@kernel_function
def _occluded_chunk(G, X, origins, directions, base, tmin, tmax, out, start, end, stacks, packets):
    """Rays start .. end - 1 (ray k at origins[k - base], directions[k - base]): out[k] whether
    anything lies along ray k between span_of(tmin, k) and span_of(tmax, k). Coherent runs of
    eight (neighbouring pixels' shadow rays) go as packets (packet_blocked), the others ray by
    ray (any_hit, which stops at the first blocker)."""
    extent = scene_extent(G)
    root = root_box(G)
    packets_here = uses_packets(G, X)
    node_stack, t_stack = stacks
    k = start
    while k < end:
        n = min(PACKET, end - k)
        taken = 0
        prefetch_rays(origins, directions, k - base + RAYS_AHEAD)
        if packets_here:
            taken, blocked = packet_blocked(
                G, X, root, origins, directions, tmin, tmax, k, k - base, n, (1 << n) - 1, extent, packets,
                node_stack, t_stack,
            )  # fmt: skip
            for i in range(taken):
                out[k + i] = (blocked >> i) & 1 != 0
        if taken == 0:
            for q in range(k, k + n):
                r = q - base
                o = (float(origins[r, 0]), float(origins[r, 1]), float(origins[r, 2]))
                d = (float(directions[r, 0]), float(directions[r, 1]), float(directions[r, 2]))
                out[q] = any_hit(G, X, o, d, span_of(tmin, q), span_of(tmax, q), node_stack, t_stack)
            taken = n
        k += taken


@roomy_njit(nogil=True, fastmath=FAST, cache=True, error_model="numpy")
def occluded_lane(S, X, origins, directions, tmin, tmax, out, lane, lanes, unit, bad):
    """Occlusion of lane `lane` of `lanes`'s chunks, as intersect_lane shares rays in their own
    order and makes their directions unit vectors."""
    n = origins.shape[0]
    G = geometry_of(S)
    stacks = traversal_stacks()
    packets = packet_scratch()
    scratch = chunk_scratch()
    refused = 0
    for c in range(lane, (n + CHUNK - 1) // CHUNK, lanes):
        start, end = c * CHUNK, min(n, (c + 1) * CHUNK)
        o, d, base = origins, directions, 0  # as in intersect_lane
        if unit:
            refused += _unit_rays(origins, directions, start, end - start, 1, 0, scratch[0], scratch[1])
            o, d, base = scratch[0], scratch[1], start
        _occluded_chunk(G, X, o, d, base, tmin, tmax, out, start, end, stacks, packets)
    bad[lane] = refused
