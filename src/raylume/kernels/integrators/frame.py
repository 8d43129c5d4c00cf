"""The image loop: rows on threads, samples per pixel into the film, primary-hit AOVs.

Each pixel gathers its own `spp` camera samples: positions in the pixel from the sampler
(stratified, jittered), warped through the pixel filter (film.py) and, with an aperture, paired
with a stratified point on the lens. One sample per pixel is the pinhole ray through the pixel
centre. Samples are added to the film's running sums; samples first..first+spp-1 of a pass
continue from whatever earlier passes left there."""

from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.errors import TypingError
from numba.extending import intrinsic, overload

from ..film.camera import CAM_CONE_SPREAD, camera_ray, camera_sample, obliquity
from ..film.film import add_in_pixel_order, add_sample, next_sample, pixel_sums, store_sums
from ..geometry.packet import PACKET, packet_hit, packet_scratch, packet_trace, root_box, scene_extent, uses_packets
from ..geometry.shapes import NO_HIT, PRIM_LAST, instance_id, split_hit, surface
from ..geometry.traverse import closest_hit
from ..geometry.wide_nodes import prefetch_cells, scratch_array, traversal_stacks
from ..scene import emitters_of, environment_of, geometry_of, media_of, surfaces_of
from ..shading.alpha_map import past_holes
from ..shading.environment import environment_radiance
from ..shading.materials import albedo, aov_albedo
from ..shading.normal_map import mapped_normal
from ..vec import FAST, INLINE_OVERLOAD, dot, inline_function, kernel_function, madd, mul
from ..vector_width import ENTRY_PIPELINE
from .bdpt import MAX_SEGMENTS, bdpt_sample
from .bdpt_glint import glint_guide
from .bdpt_vertex import V_WIDTH, Context
from .path import finite_sample, path_ray
from .path_wavefront import path_wave_row, path_wave_scratch
from .trace import RAY_WIDTH, stack_rows, trace_ray
from .wavefront import wavefront_row, wavefront_scratch

INF = np.inf


@inline_function
def _cast_shade(G, F, X, Env, o, d, t, prim, b1, b2, spread, background):
    """A cast ray's colour from its closest hit: the albedo there, or the background."""
    if prim == NO_HIT:
        if Env.present:
            return environment_radiance(Env, d)
        return background
    p = madd(o, d, t)
    ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
    return albedo(G, F, X, m, prim, b1, b2, p, d, ng, spread * t)


# Entry points, one per kind of work, so a render compiles only what it runs. Each renders one
# lane of a window of the image: window = (x0, y0, x1, y1) holds columns x0..x1-1 and rows
# y0..y1-1 of the width x height image (the whole image, or a --crop). The Session runs the
# lanes on threads (the kernels release the GIL), and each lane claims the next row not yet
# claimed (`claim_row`, one counter per pass, control[counter]) until none is left. Rows differ
# widely in cost (sky against floor): contiguous blocks of rows left one thread the sky and two
# threads were only 1.4x faster than one on the seed scene. Every lane's n-th row had balanced
# the rows' costs but not the threads' speeds: a lane whose core the machine slowed (another
# process, a virtual CPU descheduled, a thread woken late) finished last while the others
# waited; claimed rows go to whichever lane is free. Which lane renders a row changes nothing
# in it. The film, the AOVs and rays_per_row cover the window:
# pixel (i, j) of the image is their element (j - y0, i - x0), and its samples are those of
# the full image (the same keys), so a window equals that part of the full render.
# `samples` is (first, count, total): this pass adds samples first..first+count-1 of total.
# X is None for scenes of spheres and opaque triangles only, and the scene's Instances otherwise
# (see shapes.py, "features"): with None, Numba compiles no code for the other shapes, planes,
# transparent shadows or instances.
# Every lane counts the rows it finished in rows_done[lane * PROGRESS_STRIDE] (counters a cache
# line apart, against false sharing) and checks control[STOP] before each row: the waiting
# thread shows progress from the counters and stops a render within a row's time.
# pipeline_class: machine code for the vector width the CPU prefers (vector_width.py).
LANE = dict(
    nogil=True, cache=True, fastmath=FAST, error_model="numpy", no_cfunc_wrapper=True, pipeline_class=ENTRY_PIPELINE
)


class LaneControl(NamedTuple):
    """A lane's place among the lanes: its number, the control array's counter it claims rows
    from, and the arrays it reports into (progress, rays per row, rejected path samples)."""

    lane: int
    counter: int
    rows_done: np.ndarray
    control: np.ndarray
    rays_per_row: np.ndarray
    rejected: np.ndarray


PROGRESS_STRIDE = 16
# The lanes' int64 control array: the stop flag, then a row counter per pass (a render with AOVs
# makes two passes), each in a cache line of its own.
STOP = 0
AOV_ROWS, PASS_ROWS = PROGRESS_STRIDE, 2 * PROGRESS_STRIDE
CONTROL_SIZE = 3 * PROGRESS_STRIDE


@intrinsic
def claim_row(typingctx, control, counter):
    """The number of the next row of a pass, counted from the window's first: counter `counter`
    of `control` (an int64 array), raised by one atomically, as it was before."""
    if not (isinstance(control, types.Array) and control.dtype == types.int64 and control.layout == "C"):
        raise TypingError("claim_row: control must be a C-contiguous int64 array")

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        at = context.cast(builder, args[1], sig.args[1], types.int64)
        p = builder.gep(arr.data, [at], inbounds=True)
        return builder.atomic_rmw("add", p, ir.Constant(ir.IntType(64), 1), "monotonic")

    return types.int64(control, counter), codegen


def _trace_stacks(B, max_depth):
    raise NotImplementedError("a Numba overload")


@overload(_trace_stacks, jit_options=INLINE_OVERLOAD)
def _trace_stacks_impl(B, max_depth):
    """trace_lane's (node_stack, t_stack, work): the BVH's traversal stacks and trace_ray's
    stack of rays; None each for B None, the seed's variant, which traverses no BVH and traces
    no ray by ray (chosen by B's type: a branch on `B is None` compiles both arms for B 0)."""
    if isinstance(B, types.NoneType):
        return lambda B, max_depth: (None, None, None)

    def impl(B, max_depth):
        node_stack, t_stack = traversal_stacks()
        slots = stack_rows(max_depth)
        return node_stack, t_stack, scratch_array(slots * RAY_WIDTH, np.float64).reshape((slots, RAY_WIDTH))

    return impl


@njit(**LANE)
def trace_lane(G, F, L, Env, X, P, film, C, B, W):
    """Whitted-traced samples of the lane's rows of pass P into the film; rays traced per row
    into C.rays_per_row. B: None where X is None and the BVH root is one leaf of spheres (the
    seed; variants.sphere_leaf), which compiles the wavefront without the BVH's code; else 0.
    The scene comes as trace_views(S): its CPython wrapper unboxes only the arrays trace mode
    reads (a smaller kernel to compile than one taking the whole KernelScene); W, the lane's
    wavefront arrays made on the host: its rows (wavefront.wavefront_rows) and the scene's
    tables (wavefront.wavefront_tables)."""
    node_stack, t_stack, work = _trace_stacks(B, P.max_depth)
    wave = wavefront_scratch(W, B)  # (a branch on X would not type: Numba unifies both arms)
    x0, y0, x1, y1 = P.window
    while True:
        j = y0 + claim_row(C.control, C.counter)
        if j >= y1 or C.control[STOP] != 0:
            break
        C.rays_per_row[j - y0] += _trace_row(G, F, L, X, B, Env, P, j, film, work, wave, node_stack, t_stack)
        C.rows_done[C.lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def path_lane(S, X, P, film, C, strategy):
    """Path-traced samples of the lane's rows of pass P into the film; rays per row into
    C.rays_per_row, and samples rejected as NaN, infinite or negative into
    C.rejected[lane * PROGRESS_STRIDE]."""
    node_stack, t_stack = traversal_stacks()
    G, F, Em = geometry_of(S), surfaces_of(S), emitters_of(S)
    Env, Md = environment_of(S), media_of(S)
    x0, y0, x1, y1 = P.window
    while True:
        j = y0 + claim_row(C.control, C.counter)
        if j >= y1 or C.control[STOP] != 0:
            break
        rays, bad = _path_row(G, F, Em, Env, Md, X, P, j, film, node_stack, t_stack, strategy)
        C.rays_per_row[j - y0] += rays
        C.rejected[C.lane * PROGRESS_STRIDE] += bad
        C.rows_done[C.lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def path_wave_lane(S, X, P, film, C, strategy):
    """path_lane's samples by the wavefront (path_wavefront.py): the same in expectation."""
    node_stack, t_stack = traversal_stacks()
    wave = path_wave_scratch()
    G, F, Em = geometry_of(S), surfaces_of(S), emitters_of(S)
    Env, Md = environment_of(S), media_of(S)
    x0, y0, x1, y1 = P.window
    while True:
        j = y0 + claim_row(C.control, C.counter)
        if j >= y1 or C.control[STOP] != 0:
            break
        rays, bad = path_wave_row(G, F, Em, Env, Md, X, P, j, film, wave, node_stack, t_stack, strategy)
        C.rays_per_row[j - y0] += rays
        C.rejected[C.lane * PROGRESS_STRIDE] += bad
        C.rows_done[C.lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def cast_lane(S, X, P, film, C):
    """Ray-cast samples (the closest hit's albedo) of the lane's rows of pass P into the film."""
    node_stack, t_stack = traversal_stacks()
    packets = packet_scratch()
    rays = camera_packet_scratch()
    G, F = geometry_of(S), surfaces_of(S)
    x0, y0, x1, y1 = P.window
    # One sample a pixel in packets: rows are claimed in pairs and traced in packets of 4 x 2
    # pixels, more coherent than 8 x 1 (_cast_row)
    pairs = P.samples[1] == 1 and uses_packets(G, X)
    step = 2 if pairs else 1
    while True:
        j = y0 + step * claim_row(C.control, C.counter)
        if j >= y1 or C.control[STOP] != 0:
            break
        pair = pairs and j + 1 < y1  # a window's odd last row goes alone
        n = _cast_row(G, F, X, environment_of(S), P, j, pair, film, node_stack, t_stack, packets, rays)
        C.rays_per_row[j - y0] += n
        if pair:
            C.rays_per_row[j + 1 - y0] += n
        C.rows_done[C.lane * PROGRESS_STRIDE] += 2 if pair else 1


@njit(**LANE)
def aov_lane(S, X, P, A, C):
    """Primary-hit AOVs A (depth, normal, object, prim, albedo, instance) of the lane's rows of
    pass P's window."""
    node_stack, t_stack = traversal_stacks()
    G, F = geometry_of(S), surfaces_of(S)
    x0, y0, x1, y1 = P.window
    while True:
        j = y0 + claim_row(C.control, C.counter)
        if j >= y1 or C.control[STOP] != 0:
            break
        C.rays_per_row[j - y0] += _primary_aovs_row(G, F, X, P, j, A, node_stack, t_stack)
        C.rows_done[C.lane * PROGRESS_STRIDE] += 1


@kernel_function(_nrt=True)
def camera_packet_scratch():
    """One thread's buffer of a packet's camera samples: (origins, directions, weights)."""
    return (
        scratch_array(PACKET * 3, np.float64).reshape((PACKET, 3)),
        scratch_array(PACKET * 3, np.float64).reshape((PACKET, 3)),
        scratch_array(PACKET, np.float64),
    )


@kernel_function
def _cast_row(G, F, X, Env, P, j, pair, film, node_stack, t_stack, packets, rays):
    """Ray-cast samples of row j: the row's camera samples in pixel order (each pixel's samples
    in turn), traced eight at a time as a packet (kernels/geometry/packet.py) where they are coherent.
    Samples that are not (a wide lens) are traced one by one, and so are all in a scene whose
    root is a leaf and in one with instances. The film's sums are added in sample order, the
    pixel's sums kept while its samples last, so the image is the same bit for bit whichever
    way a sample was traced. With `pair` (a pass of one sample a pixel, in a scene that takes
    packets), rows j and j + 1 together in packets of 4 x 2 pixels: neighbours in both
    directions spread less than eight along a row (on a mesh with several triangles under each
    pixel they soon need leaves of their own); each pixel's one sample is added as alone.
    Returns the samples of one row."""
    cam, filt, width, height, window, samples, seed, _, bg = P
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    total_samples = (x1 - x0) * count
    if total_samples == 0:
        return 0
    spread = cam[CAM_CONE_SPREAD]
    _, lane, prim_lane, _ = packets
    origins, directions, weights = rays
    extent = scene_extent(G)
    root = root_box(G)
    packets_here = uses_packets(G, X)
    per_row = PACKET // 2 if pair else PACKET  # a packet's samples of each row
    pixel = x0  # the pixel whose sums are being added to
    total = pixel_sums(film, j - y0, 0)
    i = x0  # the next sample's pixel and sample number
    s = first
    q = 0
    while q < total_samples:
        m = min(per_row, total_samples - q)
        n = 2 * m if pair else m
        taken = 0  # the leading samples traced as a packet, the others ray by ray
        if packets_here:
            pi, ps = i, s
            for k in range(n):
                if k == m:  # the second row: the same pixels, one row down
                    pi, ps = i, s
                o, d, w, _ = camera_sample(cam, filt, seed, pi, j + k // m, ps, total_spp, width, height)
                for c in range(3):
                    origins[k, c] = o[c]
                    directions[k, c] = d[c]
                weights[k] = w
                pi, ps = next_sample(pi, ps, samples)
            taken = packet_trace(G, X, root, origins, directions, 0, n, extent, packets, node_stack, t_stack, None)
            # each hit's row of the primitive table, read first by its shading: on a large mesh
            # a cache miss of its own (the traversal reads the triangles, not the table),
            # requested for the whole packet before the first is shaded (bench_scaling.py's
            # scene, 1024 x 1024 cast renders, benchmarks/ab_queries.py --query cast: bumpy 4M
            # 8.5% faster, 1M 1.3%, 40k 0.8%). Its vertex normals too (prefetch_surface, as
            # trace mode asks) gained nothing more here: 4M 0.997, 1M 0.992 and 0.983.
            for k in range(taken):
                if prim_lane[k] != NO_HIT:
                    prefetch_cells(G.prims, split_hit(X, prim_lane[k])[0], 0, PRIM_LAST)
        for k in range(n):
            if packets_here:
                o = (origins[k, 0], origins[k, 1], origins[k, 2])
                d = (directions[k, 0], directions[k, 1], directions[k, 2])
                w = weights[k]
            else:
                o, d, w, _ = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
            if k < taken:
                t, prim, b1, b2 = packet_hit(lane, prim_lane, k)
            else:
                t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
            t, prim, b1, b2 = past_holes(G, F, X, o, d, t, prim, b1, b2, node_stack, t_stack)
            col = _cast_shade(G, F, X, Env, o, d, t, prim, b1, b2, spread * obliquity(cam, d), bg)
            if pair:  # one sample a pixel: pixel i + k % m of row j + k // m
                row, c = j + k // m - y0, i + k % m - x0
                store_sums(film, row, c, add_sample(pixel_sums(film, row, c), col, w))
            else:
                pixel, total = add_in_pixel_order(film, j - y0, x0, pixel, total, i, col, w)
                i, s = next_sample(i, s, samples)
        if pair:
            i += m
        q += m
    if not pair:
        store_sums(film, j - y0, pixel - x0, total)
    return total_samples


@kernel_function
def _trace_row(G, F, L, X, B, Env, P, j, film, work, wave, node_stack, t_stack):
    """Whitted-traced samples of row j into the film; returns the rays traced. Basic scenes go
    through the wavefront (wavefront.py), the others ray by ray (trace.py)."""
    if X is None:
        return wavefront_row(G, F, L, X, B, Env, P, j, film, wave, node_stack, t_stack)
    cam, filt, width, height, window, samples, seed, max_depth, bg = P
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    rays = 0
    for i in range(x0, x1):
        total = pixel_sums(film, j - y0, i - x0)
        for s in range(first, first + count):
            o, d, w, key = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
            col, used = trace_ray(
                G, F, L, X, Env, o, d, spread * obliquity(cam, d), max_depth, bg, work, node_stack, t_stack, key
            )
            rays += used
            total = add_sample(total, col, w)
        store_sums(film, j - y0, i - x0, total)
    return rays


@kernel_function
def _path_row(G, F, Em, Env, Md, X, P, j, film, node_stack, t_stack, strategy):
    """Path-traced samples of row j into the film; returns the rays traced and the samples
    rejected (not finite, or negative)."""
    cam, filt, width, height, window, samples, seed, max_depth, bg = P
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    rays = 0
    rejected = 0
    n = (x1 - x0) * count
    if n <= 0:
        return rays, rejected
    # The samples of the row in one loop, each one's camera ray made before the path of the one
    # before it: its square root and division (~35 cycles) had started every path, with nothing
    # else in the window to overlap them; made a path ahead, they run beside its first traversal.
    i, s = x0, first
    o, d, w, key = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
    total = pixel_sums(film, j - y0, i - x0)
    for k in range(n):
        next_i, next_s = (i, s + 1) if s + 1 < first + count else (i + 1, first)
        if k + 1 < n:
            next_o, next_d, next_w, next_key = camera_sample(
                cam, filt, seed, next_i, j, next_s, total_spp, width, height
            )
        else:
            next_o, next_d, next_w, next_key = o, d, w, key
        cone = spread * obliquity(cam, d)
        col, used = path_ray(G, F, X, Em, Env, Md, o, d, cone, max_depth, bg, key, node_stack, t_stack, strategy)
        rays += used
        if not finite_sample(col):
            rejected += 1
            col = (0.0, 0.0, 0.0)
        total = add_sample(total, col, w)
        if next_i != i:  # the pixel's last sample
            store_sums(film, j - y0, i - x0, total)
            if k + 1 < n:
                total = pixel_sums(film, j - y0, next_i - x0)
        i, s, o, d, w, key = next_i, next_s, next_o, next_d, next_w, next_key
    return rays, rejected


@kernel_function
def _primary_aovs_row(G, F, X, P, j, A, node_stack, t_stack):
    """Depth, normal, object, prim, albedo and instance (A) of the (pinhole) rays through the
    row's pixel centres. Returns rays traced."""
    cam, width, height = P.camera, P.width, P.height
    depth, normal, obj_id, prim_id, albedo_out, inst_id = A
    x0, y0, x1, y1 = P.window
    r = j - y0
    spread = cam[CAM_CONE_SPREAD]
    for i in range(x0, x1):
        o, d = camera_ray(cam, i + 0.5, j + 0.5, width, height)
        cone = spread * obliquity(cam, d)
        c0 = i - x0
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        t, prim, b1, b2 = past_holes(G, F, X, o, d, t, prim, b1, b2, node_stack, t_stack)
        if prim == NO_HIT:
            depth[r, c0] = INF
            obj_id[r, c0] = -1
            prim_id[r, c0] = -1
            inst_id[r, c0] = -1
            for c in range(3):
                normal[r, c0, c] = 0.0
                albedo_out[r, c0, c] = 0.0
        else:
            p = madd(o, d, t)
            ng, ns, m, obj, face = surface(G, X, prim, b1, b2, p)
            ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
            if dot(ns, d) > 0.0:
                ns = mul(ns, -1.0)
            a = aov_albedo(F.materials, m, albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone * t))
            depth[r, c0] = t
            obj_id[r, c0] = obj
            prim_id[r, c0] = face
            inst_id[r, c0] = instance_id(X, prim)
            for c in range(3):
                normal[r, c0, c] = ns[c]
                albedo_out[r, c0, c] = a[c]
    return x1 - x0


@njit(**LANE)
def bdpt_lane(S, X, P, film, C, bd):
    """Bidirectional path-traced samples (bdpt.py) of the lane's rows: rows of the whole image,
    since a light subpath of any pixel may land in the window (t = 1). Pixels in pass P's window
    get every strategy in the film; the others only trace their light subpaths for the splats.
    bd = (bounding sphere, splat sums, splat filter, strategy counts (lanes, n, n), strategy);
    rays per (image) row into C.rays_per_row, refused samples into C.rejected."""
    node_stack, t_stack = traversal_stacks()
    G, F, Em = geometry_of(S), surfaces_of(S), emitters_of(S)
    Env, Md = environment_of(S), media_of(S)
    bounds, splats, filt, counts, strategy, glint = bd
    Vc = np.zeros((MAX_SEGMENTS + 2, V_WIDTH))
    Vl = np.zeros((MAX_SEGMENTS + 2, V_WIDTH))
    saved = np.zeros((1, V_WIDTH))
    ctx = Context(G, F, X, Em, Env, Md, P.camera, bounds, P.width, P.height, P.background, glint, P.pixel_filter)
    lane_counts = counts[C.lane]
    while True:
        j = claim_row(C.control, C.counter)
        if j >= P.height or C.control[STOP] != 0:
            break
        rays, bad = _bdpt_row(ctx, P, j, film, Vc, Vl, saved, splats, filt, lane_counts, strategy, node_stack, t_stack)
        C.rays_per_row[j] += rays
        C.rejected[C.lane * PROGRESS_STRIDE] += bad
        C.rows_done[C.lane * PROGRESS_STRIDE] += 1


@njit(**LANE)
def bdpt_glint_guide(S, X, P, bounds, guide, rows):
    """The glint strategy's guide of pass P's image, rows rows[0] .. rows[1] - 1, into guide
    (float64 (height, width), bdpt_glint.glint_guide); returns the rays traced."""
    node_stack, t_stack = traversal_stacks()
    G, F, Em = geometry_of(S), surfaces_of(S), emitters_of(S)
    ctx = Context(G, F, X, Em, environment_of(S), media_of(S), P.camera, bounds, P.width, P.height,
                  P.background, np.zeros(1), P.pixel_filter)  # fmt: skip
    most = P.max_depth if P.max_depth >= 0 else MAX_SEGMENTS
    return glint_guide(ctx, P.seed, most, guide, rows, node_stack, t_stack)


@kernel_function
def _bdpt_row(ctx, P, j, film, Vc, Vl, saved, splats, filt, counts, strategy, node_stack, t_stack):
    """Row j of the image: every pixel's samples of this pass (bdpt_sample), those in the window
    into the film. Returns (rays traced, samples and splats refused)."""
    cam, pixel_filter, width, height, window, samples, seed, max_depth, bg = P
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    spread = cam[CAM_CONE_SPREAD]
    row_inside = j >= y0 and j < y1
    rays = 0
    rejected = 0
    for i in range(width):
        inside = row_inside and i >= x0 and i < x1
        total = pixel_sums(film, j - y0, i - x0) if inside else pixel_sums(film, 0, 0)
        for s in range(first, first + count):
            o, d, w, key = camera_sample(cam, pixel_filter, seed, i, j, s, total_spp, width, height)
            col, used, refused = bdpt_sample(
                ctx, Vc, Vl, saved, o, d, spread * obliquity(cam, d), key, inside, max_depth, strategy, splats,
                window, filt, counts, i, j, node_stack, t_stack,
            )  # fmt: skip
            rays += used
            rejected += refused
            if inside:
                if not finite_sample(col):
                    rejected += 1
                    col = (0.0, 0.0, 0.0)
                total = add_sample(total, col, w)
        if inside:
            store_sums(film, j - y0, i - x0, total)
    return rays, rejected
