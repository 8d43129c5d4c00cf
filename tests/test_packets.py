"""Ray packets (kernels/geometry/packet.py): eight coherent rays traced together give each ray the
single-ray traversal's hit to the last bit (t, barycentrics; the face too, except where two faces
are hit at exactly the same distance), and the brute force's distance. Incoherent rays are
refused as packets and traced ray by ray."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from test_intersect import assert_as_textbook_slabs, slab_box, slab_cases

import raylume
from raylume.compile import compile_scene
from raylume.kernels.film.camera import camera_frame
from raylume.kernels.geometry.packet import (
    BEST_T,
    BOX_BITS,
    PACKET,
    packet_blocked,
    packet_box,
    packet_closest,
    packet_finish,
    packet_hit,
    packet_load,
    packet_node,
    packet_node_full,
    packet_scratch,
    packet_setup,
    packet_shear,
    packet_triangles,
    root_box,
    scene_extent,
)
from raylume.kernels.geometry.query import CHUNK
from raylume.kernels.geometry.shape_triangle import INF, intersect_triangle, ray_shear
from raylume.kernels.geometry.traverse import any_hit, closest_hit
from raylume.kernels.geometry.wide_nodes import (
    BVH_WIDTH,
    CHILDREN_PREFETCHED_FROM,
    NEIGHBOURS_FROM,
    TRAVERSAL_STACK,
    box_entries,
    box_ray,
)
from raylume.kernels.scene import geometry_of
from raylume.kernels.variants import features
from raylume.kernels.vec import FAST
from raylume.query_lanes import intersect_rays
from raylume.scene.procedural import bumpy_sphere

# compiled in the test process; the tests that call them share one xdist worker
PACKET_WORKER = pytest.mark.xdist_group("packets")


# Both with the kernels' fast-math flags, as intersect_rays and the frame kernels compile them:
# the analytic shapes' tests (planes, quads) round alike only under the same flags.
@njit(fastmath=FAST, error_model="numpy")
def _single(S, origins, dirs, X=None):
    """closest_hit ray by ray: (t, prim, b1, b2) arrays; X the kernels' variant (None: basic)."""
    n = origins.shape[0]
    out = np.empty((n, 4))
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    for k in range(n):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = t, prim, b1, b2
    return out


@njit(fastmath=FAST, error_model="numpy")
def _packets(S, origins, dirs, size, shadows=None):
    """The rays in packets of `size` (the last one may be smaller): (t, prim, b1, b2) arrays
    from packet_closest (shadows: None, or True for shadow rays, which test every leaf ray by
    ray and stop at the first hit they find), and for each packet how many of its rays, from the
    first, packet_setup took (the rays it left are left NaN)."""
    n = origins.shape[0]
    out = np.full((n, 4), np.nan)
    taken = np.zeros((n + size - 1) // size, np.int64)
    box, lane, prim, mask_stack = packet_scratch()
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    extent = scene_extent(G)
    root = root_box(G)
    for p in range(taken.shape[0]):
        start = p * size
        m = min(size, n - start)
        ok, rows, axes = packet_setup(origins, dirs, start, m, 0.0, INF, extent, box, lane, prim)
        taken[p] = ok
        if ok:
            packet_closest(
                G, None, root, rows, axes, (1 << ok) - 1, box, lane, prim, node_stack, t_stack, mask_stack, shadows
            )
            for i in range(ok):
                t, q, b1, b2 = packet_hit(lane, prim, i)
                out[start + i, 0], out[start + i, 1], out[start + i, 2], out[start + i, 3] = t, q, b1, b2
    return out, taken


def _whole(taken, n, size):
    """Of _packets' counts for n rays in packets of `size`: whether each packet was taken whole."""
    sizes = np.minimum(size, n - size * np.arange(len(taken)))
    return taken == sizes


@njit
def _brute(tris, origins, dirs):
    n = origins.shape[0]
    out_t = np.full(n, np.inf)
    for k in range(n):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        shear = ray_shear(d)
        for f in range(tris.shape[0]):
            t, _, _ = intersect_triangle(o, shear, tris, f, 0.0, out_t[k])
            out_t[k] = min(out_t[k], t)
    return out_t


def _compiled_mesh(tmp_path, v, f, extra=()):
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    objects = [*extra, {"type": "mesh", "file": str(tmp_path / "m.ply")}]
    return compile_scene(raylume.scene_from_dict({"objects": objects}))


def _camera_rays(center, radius, size):
    """Pixel-centre rays of the DESIGN.md camera, 2.4 radii in front of `center`, row by row."""
    position = np.asarray(center, float) - [0.0, 0.0, 2.4 * radius]
    cam = camera_frame(position, center, (0, 1, 0), 53.13, size, size)
    i, j = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    d = cam[3:6] + (i / size * 2 - 1).reshape(-1, 1) * cam[6:9] + (1 - j / size * 2).reshape(-1, 1) * cam[9:12]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.broadcast_to(position, d.shape).copy(), d


def _assert_same_hits(got, ref):
    """Bit-identical t and barycentrics; the same face except on exact ties of t."""
    np.testing.assert_array_equal(got[:, 0], ref[:, 0])
    same_prim = got[:, 1] == ref[:, 1]
    assert same_prim.mean() > 0.999
    np.testing.assert_array_equal(got[same_prim, 2:], ref[same_prim, 2:])


@PACKET_WORKER
@pytest.mark.parametrize("shadows", [None, True])
@pytest.mark.parametrize("kind", ["bumpy", "soup"])
def test_camera_packets_equal_single_rays_and_brute_force(tmp_path, kind, shadows):
    rng = np.random.default_rng(5)
    if kind == "soup":  # overlapping random triangles: packets split up at every level
        centers = rng.uniform(-1, 1, size=(4000, 1, 3))
        v = (centers + rng.normal(scale=0.08, size=(4000, 3, 3))).reshape(-1, 3)
        f = np.arange(len(v)).reshape(-1, 3)
    else:
        v, f = bumpy_sphere(20000)
    compiled = _compiled_mesh(tmp_path, v, f)
    o, d = _camera_rays(np.zeros(3), 1.2, 96)
    got, taken = _packets(compiled.kernel, o, d, PACKET, shadows)
    assert _whole(taken, len(o), PACKET).all()  # neighbouring pixels are coherent
    ref = _single(compiled.kernel, o, d)
    assert 0.2 < np.isfinite(ref[:, 0]).mean() < 0.95
    if shadows:
        # a shadow packet's ray stops at the first hit it finds: the same rays hit, none nearer
        # than its nearest hit
        hit = np.isfinite(ref[:, 0])
        np.testing.assert_array_equal(np.isfinite(got[:, 0]), hit)
        assert (got[hit, 0] >= ref[hit, 0]).all()
        return
    _assert_same_hits(got, ref)
    t_ref = _brute((v.astype(np.float32)[f]).reshape(-1, 9), o, d)
    np.testing.assert_array_equal(got[:, 0], t_ref)


@PACKET_WORKER
@pytest.mark.parametrize("size", [1, 3, 5, 7])
def test_partial_packets_leave_their_unused_lanes_out(tmp_path, size):
    v, f = bumpy_sphere(5000)
    compiled = _compiled_mesh(tmp_path, v, f)
    o, d = _camera_rays(np.zeros(3), 1.2, 64)
    got, taken = _packets(compiled.kernel, o, d, size)
    # cut short: packets that span two rows of the image, or the centre column (directions in
    # two octants), about two a row; their leading rays are traced where there are two or more
    whole = _whole(taken, len(o), size)
    assert whole.mean() > 0.75
    assert (whole | (taken == 0) | (taken >= 2)).all()
    packed = ~np.isnan(got[:, 0])
    assert packed.sum() == taken.sum()
    _assert_same_hits(got[packed], _single(compiled.kernel, o, d)[packed])


@PACKET_WORKER
@pytest.mark.parametrize("shadows", [None, True])
def test_packets_through_vertices_and_edges_leave_no_pinholes(tmp_path, shadows):
    """A grid of coplanar triangles under parallel rays straight down through its vertices and
    edge midpoints, eight at a time: every ray hits, at the brute force's distance."""
    n = 12
    g = np.linspace(-1, 1, n + 1)
    xs, ys = np.meshgrid(g, g)
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    q = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.concatenate([np.stack([q, q + 1, q + n + 2], 1), np.stack([q, q + n + 2, q + n + 1], 1)])
    compiled = _compiled_mesh(tmp_path, v, f)
    edge_mids = (v[f[:, 0]] + v[f[:, 1]]) / 2
    # a packet around each vertex and edge midpoint: the exact point and seven rays beside it
    # (2e-4 apart, within one packet's reach)
    offsets = np.arange(-3, 5)[:, None] * [2e-4, 1e-4, 0.0]
    targets = (np.concatenate([v, edge_mids])[:, None, :] + offsets).reshape(-1, 3)
    o = targets + [0.0, 0.0, 2.0]
    d = np.broadcast_to([0.0, 0.0, -1.0], o.shape).copy()
    got, taken = _packets(compiled.kernel, o, d, PACKET, shadows)
    assert _whole(taken, len(o), PACKET).all()
    inside = (np.abs(targets[:, :2]) <= 1).all(axis=1)
    assert (got[inside, 0] == 2.0).all()  # every ray over the grid hits, at exactly 2
    ref = _single(compiled.kernel, o, d)
    np.testing.assert_array_equal(got[:, 0], ref[:, 0])
    np.testing.assert_array_equal(got[:, 0], _brute(v.astype(np.float32)[f].reshape(-1, 9), o, d))


@PACKET_WORKER
def test_spheres_beside_triangles_in_packets(tmp_path):
    """Leaves of spheres are tested ray by ray inside a packet: the same hits as single rays."""
    rng = np.random.default_rng(8)
    v, f = bumpy_sphere(3000)
    spheres = [
        {"type": "sphere", "center": c.tolist(), "radius": float(r)}
        for c, r in zip(rng.uniform(-1.5, 1.5, size=(60, 3)), rng.uniform(0.05, 0.3, size=60), strict=True)
    ]
    compiled = _compiled_mesh(tmp_path, v, f, spheres)
    o, d = _camera_rays(np.zeros(3), 1.6, 80)
    got, taken = _packets(compiled.kernel, o, d, PACKET)
    assert _whole(taken, len(o), PACKET).all()
    ref = _single(compiled.kernel, o, d)
    kinds = compiled.kernel.prims[ref[np.isfinite(ref[:, 0]), 1].astype(int), 0]
    assert len(np.unique(kinds)) == 2  # both spheres and triangles are hit
    _assert_same_hits(got, ref)


@PACKET_WORKER
def test_incoherent_rays_are_refused_or_cut_short_as_packets(tmp_path):
    """Rays too far apart are refused as packets; a packet with an odd ray (NaN, another octant)
    takes the rays before it, and each ray it takes hits what it hits alone."""
    v, f = bumpy_sphere(2000)
    compiled = _compiled_mesh(tmp_path, v, f)
    rng = np.random.default_rng(1)
    o, d = _camera_rays(np.zeros(3), 1.2, 64)
    n = len(o)
    shuffled = rng.permutation(n)  # directions across the whole field of view
    spread = o + rng.normal(scale=0.5, size=o.shape)  # origins far apart
    odd = d.copy()
    odd[3::8] = [np.nan, 0.0, 1.0]  # one NaN ray in each packet
    flipped = d.copy()
    flipped[5::8, 0] *= -1  # one ray in each packet in another octant
    flipped[5::8, 0] += np.sign(flipped[5::8, 0]) * 0.01
    # a packet takes only the rays before its first odd one, and only two or more of them
    cases = ((o[shuffled], d[shuffled], None), (spread, d, None), (o, odd, 3), (o, flipped, 5))
    for origins, dirs, leading in cases:
        origins, dirs = np.ascontiguousarray(origins), np.ascontiguousarray(dirs)
        got, taken = _packets(compiled.kernel, origins, dirs, PACKET)
        if leading is None:  # rays each alone: seldom two in a row close enough
            assert (taken == 0).mean() > 0.8
        else:
            assert (taken == leading).all()
        packed = ~np.isnan(got[:, 0])
        assert packed.sum() == taken.sum()
        if packed.any():
            _assert_same_hits(got[packed], _single(compiled.kernel, origins, dirs)[packed])


@njit(fastmath=FAST, error_model="numpy")
def _setup_lanes(origins, dirs, n, extent):
    """packet_setup on rays 0 .. n - 1: (taken, the box scratch, each lane's box_ray
    constants (9, 8) and near rows (3, 8) from the single-ray function; the lanes are rays 0 ..
    n - 1, then copies of ray 0, except that the constants' lanes after a packet cut short are
    copies of ray 0 from the first ray it left)."""
    box, lane, prim, _ = packet_scratch()
    ok, rows, axes = packet_setup(origins, dirs, 0, n, 0.0, INF, extent, box, lane, prim)
    loaded = ok if ok > 0 else n  # a packet cut short is loaded again with the rays it takes
    single = np.empty((9, PACKET), np.float32)
    near_rows = np.empty((3, PACKET), np.int64)
    for i in range(PACKET):
        k = i if i < loaded else 0
        rf, _ = box_ray((origins[k, 0], origins[k, 1], origins[k, 2]), (dirs[k, 0], dirs[k, 1], dirs[k, 2]))
        for j in range(9):
            single[j, i] = rf[j]
        k = i if i < n else 0
        _, r = box_ray((origins[k, 0], origins[k, 1], origins[k, 2]), (dirs[k, 0], dirs[k, 1], dirs[k, 2]))
        for j in range(3):
            near_rows[j, i] = r[j]
    return ok, box.copy(), single, near_rows, rows


@PACKET_WORKER
@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, PACKET),
    scale=st.sampled_from([1e-30, 1e-3, 1.0, 1e6]),
    zero_axis=st.sampled_from([None, 0, 1, 2]),
)
def test_packet_setup_gives_each_lane_the_single_ray_box_constants(seed, n, scale, zero_axis):
    """The SIMD setup (packet_load) writes each lane's box-test constants exactly as box_ray
    computes them for that ray alone (directions with a zero component included): its 1 / d and
    slab offsets on either side of the exact -o / d, within a relative 2 ** -20 of it and the
    origin's outward move; and takes the rays exactly as the module's rules say: all, the
    leading two or more that pass, or none (checked with the single-ray functions: box_ray's
    octant rows and ray_shear's dominant axis, away from the limits' rounding)."""
    rng = np.random.default_rng(seed)
    d0 = rng.normal(size=3)
    d = d0 + rng.normal(scale=rng.choice([1e-4, 0.05, 0.5]), size=(PACKET, 3))
    if zero_axis is not None:
        d[:, zero_axis] = rng.choice([0.0, -0.0])
    o = scale * (rng.normal(size=3) + rng.normal(scale=rng.choice([1e-5, 0.1]), size=(PACKET, 3)))
    extent = scale
    ok, scratch, single, near_rows, rows = _setup_lanes(o, d, n, extent)
    box = scratch[:9]
    assert np.array_equal(box.view(np.uint32), single.view(np.uint32))
    # and packet_node's table of the rays' bits
    assert np.array_equal(
        scratch[BOX_BITS:].view(np.int32), np.repeat(1 << np.arange(PACKET), PACKET).reshape(PACKET, -1)
    )
    loaded = ok if ok > 0 else n
    held = [i if i < loaded else 0 for i in range(PACKET)]
    for i in range(PACKET):
        for k in range(3):
            exact = -Fraction(float(o[held[i], k])) * Fraction(float(box[6 + k, i]))
            near, far = Fraction(float(box[k, i])), Fraction(float(box[3 + k, i]))
            assert near <= exact <= far
            # the origin moves out by max(2 ** -23 |o|, 2 ** -72): so much of -o / d and more
            slack = abs(exact) * Fraction(1, 2**20) + Fraction(2.0**-71) * abs(Fraction(float(box[6 + k, i])))
            assert exact - near <= slack and far - exact <= slack
    lanes = [i if i < n else 0 for i in range(PACKET)]
    dl, ol = d[lanes], o[lanes]
    cos = dl @ dl[0] / (np.linalg.norm(dl, axis=1) * np.linalg.norm(dl[0]))
    gap = np.abs(ol - ol[0]).max(axis=1)
    if np.any(np.abs(cos - 0.985) < 1e-9) or np.any(np.abs(gap - 0.01 * extent) < 1e-9 * extent):
        return  # on a limit: rounding decides
    axes = np.array([ray_shear(tuple(x))[2] for x in dl])
    passing = (near_rows == near_rows[:, :1]).all(axis=0) & (axes == axes[0]) & (cos >= 0.985) & (gap <= 0.01 * extent)
    leading = PACKET if passing.all() else int(np.argmin(passing))
    expected = n if leading >= n else (leading if leading >= 2 else 0)
    assert ok == expected
    assert tuple(rows) == tuple(near_rows[:, 0])


@njit(fastmath=FAST, error_model="numpy")
def _packet_entry(lo_hi, o, d, tmax):
    """A one-ray packet's (the ray copied to every lane) entry distance into a box in lane 0 of
    a wide node whose other lanes are empty, by packet_node; +inf where it misses. Also returns
    whether an empty lane was entered (never), and the packet box test's answer for lane 0."""
    box, lane, prim, _ = packet_scratch()
    origins, dirs = o.reshape((1, 3)), d.reshape((1, 3))
    ok, rows, _ = packet_setup(origins, dirs, 0, 1, 0.0, tmax, 1.0, box, lane, prim)
    bounds = np.empty((1, 7, BVH_WIDTH), np.float32)
    bounds[0, :3], bounds[0, 3:6] = np.inf, -np.inf
    bounds[0, :6, 0] = lo_hi
    t_out = np.empty(BVH_WIDTH, np.float32)
    masks = packet_node(bounds, 0, box, rows, lane, 1, t_out, 0)
    x, y, z = rows
    planes = (lo_hi[x], lo_hi[y], lo_hi[z], lo_hi[3 - x], lo_hi[5 - y], lo_hi[7 - z])
    whole = packet_box(planes, box, lane, 1)
    t = np.float64(t_out[0]) if masks & 1 else INF
    return ok, t, (masks >> 8) != 0, whole


@PACKET_WORKER
@slab_cases
def test_packet_box_test_agrees_with_the_textbook_slab_test(a, b, o, d, tmax):
    """The packet's slab test (packet_load's constants, packet_node's eight rays) against the
    textbook slabs with exact division, as test_intersect checks the single-ray one: a box the
    ray enters is never culled, its entry distance never overestimated, and short of it by no
    more than the rounding; no empty lane is entered; the root box test (packet_box) answers as
    packet_node does."""
    lo, hi = slab_box(a, b, o, d)
    lo_hi = np.concatenate([lo, hi]).astype(np.float32)
    ok, got, empty_entered, whole = _packet_entry(lo_hi, np.array(o, float), np.array(d, float), tmax)
    assert ok and not empty_entered
    assert whole == (got < INF)
    assert_as_textbook_slabs(got, lo, hi, o, d, tmax)


@njit(fastmath=FAST, error_model="numpy")
def _node_test(bounds, o, d, best, active, full):
    """packet_node on the rays o, d (one packet) with best hits `best`: (masks, entries); with
    `full`, packet_node_full (every ray active)."""
    box, lane, prim, _ = packet_scratch()
    _, rows, axes = packet_setup(o, d, 0, PACKET, 0.0, INF, 10.0, box, lane, prim)
    # every lane its own ray, whether or not the packet rules take them all: packet_setup loads
    # a packet it cuts short again, its lanes after the rays it takes copies of the first
    packet_load(o, d, 0, PACKET, axes[2], 0.0, INF, INF, box, lane, prim)
    for i in range(PACKET):
        lane[BEST_T, i] = best[i]
    t_out = np.empty(BVH_WIDTH, np.float32)
    if full:
        masks = packet_node_full(bounds, 0, box, rows, lane, t_out, 0)
    else:
        masks = packet_node(bounds, 0, box, rows, lane, active, t_out, 0)
    return masks, t_out


@PACKET_WORKER
@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), signs=st.tuples(*[st.sampled_from((-1.0, 1.0))] * 3), full=st.booleans())
def test_packet_node_answers_as_each_ray_alone(seed, signs, full):
    """packet_node's ray masks and nearest entries against box_hits (box_entries) ray by ray:
    eight different rays of one octant, each with its own best hit, some not active, against a
    node of random boxes (two lanes empty). Bit r of child c's byte is set exactly where ray r
    is active and enters c alone, and c's entry is the least of those rays' entries, to the bit.
    With `full`, packet_node_full (the rays in the lanes, for packets whose eight rays are all
    active) against the same reference."""
    rng = np.random.default_rng(seed)
    s = np.asarray(signs)
    lo = rng.uniform(-1, 1, size=(3, BVH_WIDTH))
    hi = lo + rng.uniform(0.1, 1.5, size=(3, BVH_WIDTH))
    bounds = np.empty((1, 7, BVH_WIDTH), np.float32)
    bounds[0, :3], bounds[0, 3:6] = lo, hi
    empty = rng.choice(BVH_WIDTH, 2, replace=False)
    bounds[0, :3, empty], bounds[0, 3:6, empty] = np.inf, -np.inf
    d = np.abs(rng.normal([1.0, 0.3, 0.2], 0.1, size=(PACKET, 3))) * s
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.uniform(-0.8, 0.8, size=(PACKET, 3)) - 4.0 * d  # each ray aimed into the boxes
    best = np.where(rng.random(PACKET) < 0.3, INF, rng.uniform(2.0, 6.0, PACKET))
    active = 0xFF if full else int(rng.integers(0, 256))
    masks, t_out = _node_test(bounds, o, d, best, active, full)
    want_masks, want_t = 0, np.full(BVH_WIDTH, np.inf, np.float32)
    for r in range(PACKET):
        entries = box_entries(bounds, 0, tuple(o[r]), tuple(d[r]), best[r], np.empty(BVH_WIDTH))
        for c in range(BVH_WIDTH):
            if (active >> r) & 1 and entries[c] < INF:
                want_masks |= 1 << (8 * c + r)
                want_t[c] = min(want_t[c], np.float32(entries[c]))
    assert masks & (2**64 - 1) == want_masks  # (packet_node returns the bytes as an int64)
    assert t_out.tobytes() == want_t.tobytes()


def _clear_dominant_axis(t):
    a = sorted(abs(x) for x in t)
    return a[2] > 0.1 and a[2] > 1.5 * a[1]


@PACKET_WORKER
@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    # a dominant axis that the jitter below cannot change
    direction=st.tuples(*[st.floats(-1, 1)] * 3).filter(_clear_dominant_axis),
    jitter=st.floats(1e-6, 0.01),  # up to ~2 degrees (three sigma) between rays
)
def test_random_coherent_packets_equal_single_rays(packet_soup, seed, direction, jitter):
    """Random packets (a random direction, jittered per ray, from nearby origins) into a soup of
    triangles: each ray's hit is the single-ray traversal's."""
    compiled = packet_soup
    rng = np.random.default_rng(seed)
    d0 = np.asarray(direction) / np.linalg.norm(direction)
    d = d0 + rng.normal(scale=jitter, size=(64, 3))
    d = np.abs(d) * np.where(d0 < 0, -1.0, 1.0)  # one octant
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = -2.5 * d0 + rng.normal(scale=0.3, size=(8, 1, 3)) + rng.normal(scale=1e-4, size=(8, 8, 3))
    o = o.reshape(-1, 3)
    got, taken = _packets(compiled.kernel, o, d, PACKET)
    assert _whole(taken, len(o), PACKET).all()
    _assert_same_hits(got, _single(compiled.kernel, o, d))


@pytest.fixture(scope="module")
def packet_soup(tmp_path_factory):
    rng = np.random.default_rng(3)
    centers = rng.uniform(-1, 1, size=(3000, 1, 3))
    v = (centers + rng.normal(scale=0.1, size=(3000, 3, 3))).reshape(-1, 3)
    return _compiled_mesh(tmp_path_factory.mktemp("soup"), v, np.arange(len(v)).reshape(-1, 3))


@PACKET_WORKER
@pytest.mark.parametrize(("n", "lanes"), [(3 * CHUNK + 17, 1), (3 * CHUNK + 17, 3), (3 * CHUNK + 17, 7), (5, 4)])
def test_intersect_rays_writes_every_ray_once_whatever_the_lanes(packet_soup, n, lanes):
    """The batch query shares the rays' chunks among its lanes (threads): every output element
    is written, with the hits of the single-ray traversal and their ids (looked up after each
    chunk is traced), also with more lanes than chunks."""
    rng = np.random.default_rng(n + lanes)
    o = rng.uniform(-2, 2, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = np.full(n, np.nan)
    obj, prim, inst = (np.full(n, -7, np.int32) for _ in range(3))
    S = packet_soup.kernel
    intersect_rays(S, features(S), o, d, t, obj, prim, inst, lanes)
    ref = _single(S, o, d)
    np.testing.assert_array_equal(t, ref[:, 0])
    hit = np.isfinite(ref[:, 0])
    np.testing.assert_array_equal(prim, np.where(hit, S.prims[np.maximum(ref[:, 1], 0).astype(int), 4], -1))
    np.testing.assert_array_equal(obj, np.where(hit, 0, -1))
    np.testing.assert_array_equal(inst, np.where(hit, 0, -1))
    assert hit.any() and not hit.all()  # hits and misses both


@PACKET_WORKER
@pytest.mark.parametrize("threads", [1, 2])
def test_intersect_rays_takes_packets_and_matches_single_rays(tmp_path, threads):
    """The batch query (raylume.intersect's kernel) traces camera rays in packets: the same
    distances, objects and faces as ray by ray, on any number of threads."""
    v, f = bumpy_sphere(20000)
    compiled = _compiled_mesh(tmp_path, v, f)
    o, d = _camera_rays(np.zeros(3), 1.2, 128)
    n = len(o)
    out = np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
    S = compiled.kernel
    intersect_rays(S, features(S), o, d, *out, threads)
    ref = _single(S, o, d)
    np.testing.assert_array_equal(out[0], ref[:, 0])
    hit = np.isfinite(ref[:, 0])
    faces = np.where(hit, S.prims[np.maximum(ref[:, 1], 0).astype(int), 4], -1)
    assert (out[2] == faces).mean() > 0.999
    assert (out[1][hit] == 0).all() and (out[1][~hit] == -1).all()


def test_cast_mode_traces_packets_that_hit_what_single_rays_hit(tmp_path):
    """A cast render of two meshes (kernels/integrators/frame.py traces its camera rays in packets) against
    its own object AOV, which single rays trace: each pixel shows the colour of the object its
    pixel-centre ray hits, the background where it hits none."""
    colors = [[0.9, 0.2, 0.1], [0.1, 0.5, 0.9]]
    objects = []
    for k, x in enumerate((-0.6, 0.7)):
        v, f = bumpy_sphere(4000)
        trimesh.Trimesh(v * 0.6 + [x, 0.1 * k, 0.0], f, process=False).export(tmp_path / f"m{k}.ply")
        objects.append({"type": "mesh", "file": str(tmp_path / f"m{k}.ply"), "material": {"color": colors[k]}})
    scene = raylume.scene_from_dict(
        {
            "camera": {"position": [0, 0, -3.5], "look_at": [0, 0, 0], "fov": 50},
            "render": {"mode": "cast", "width": 96, "height": 64, "background": [0.25, 0.25, 0.25]},
            "objects": objects,
        }
    )
    image = raylume.render(scene)
    obj = image.aovs["object"]
    assert {-1, 0, 1} <= set(np.unique(obj).tolist())
    expected = np.where(obj[..., None] >= 0, np.asarray(colors)[np.maximum(obj, 0)], 0.25)
    np.testing.assert_allclose(image.rgb, expected, rtol=1e-6)


@PACKET_WORKER
def test_packet_tests_are_vector_code(tmp_path):
    """The packet's box test (8 rays per child box, float32) and triangle test (8 rays per
    triangle, float64) run as vector instructions: fails loudly if a change makes them
    scalar."""
    import re

    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features().flatten().split(",")
    if "+avx2" not in features or "+fma" not in features:
        pytest.skip("the CPU has no AVX2 and FMA: no 8-wide float32 registers or multiply-adds to check for")
    v, f = bumpy_sphere(500)
    compiled = _compiled_mesh(tmp_path, v, f)
    o, d = _camera_rays(np.zeros(3), 1.2, 16)
    _packets(compiled.kernel, o, d, PACKET)
    asm = "\n".join(_packets.inspect_asm().values())
    for op in ("vmaxps", "vminps", "vcmp[a-z]*ps", "vfmadd[0-9]*ps", "vmulps"):  # the box test
        assert re.search(rf"\b{op}\s+[^\n]*%ymm", asm), f"no 8-wide {op}: the packet box test is scalar"
    tris = np.random.default_rng(0).uniform(-1, 1, size=(8, 9)).astype(np.float32)
    _triangle_block(tris, 0, 4, o[:PACKET], d[:PACKET])
    asm = "\n".join(_triangle_block.inspect_asm().values())
    for op in ("vsubpd", "vmulpd", "vdivpd", "vcmp[a-z]*pd"):  # the triangle test alone: 8 doubles are
        # two ymm registers with AVX2, one zmm with AVX-512
        assert re.search(rf"\b{op}\s+[^\n]*%[yz]mm", asm), f"no vector {op}: the packet triangle test is scalar"


@njit
def _triangle_block(tris, row, count, origins, dirs):
    """packet_triangles on rows row .. row + count - 1 for a packet of eight rays: per ray
    (t, prim, b1, b2), or NaNs when packet_setup refuses the rays."""
    box, lane, prim, _ = packet_scratch()
    out = np.full((PACKET, 4), np.nan)
    ok, rows, axes = packet_setup(origins, dirs, 0, PACKET, 0.0, INF, 1e30, box, lane, prim)
    if ok == PACKET:
        packet_shear(lane, axes)
        packet_triangles(tris, row, count, 0, axes, lane, prim, (1 << PACKET) - 1)
        packet_finish(lane, prim)
        for i in range(PACKET):
            t, q, b1, b2 = packet_hit(lane, prim, i)
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = t, q, b1, b2
    return out


@njit
def _triangle_one_by_one(tris, row, count, origins, dirs):
    """intersect_triangle row by row for each ray: the nearest (t, row - first row, b1, b2)."""
    out = np.empty((origins.shape[0], 4))
    for k in range(origins.shape[0]):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        shear = ray_shear(d)
        best, j, u, v = INF, -1, 0.0, 0.0
        for r in range(row, row + count):
            t, b1, b2 = intersect_triangle(o, shear, tris, r, 0.0, best)
            if t < best:
                best, j, u, v = t, r - row, b1, b2
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = best, j, u, v
    return out


@PACKET_WORKER
@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), count=st.integers(1, 4), shared=st.booleans())
def test_packet_triangle_test_equals_the_scalar_test_to_the_bit(seed, count, shared):
    """packet_triangles against intersect_triangle, lane by lane: the same t, triangle and
    barycentrics to the last bit, the first triangle on ties; with `shared`, the rays aim at
    the triangles' vertices and edge midpoints and the triangles share vertices."""
    rng = np.random.default_rng(seed)
    # x, y in (0.2, 0.5) and z in (3, 3.5): every ray from near the origin points into one
    # octant, z its dominant axis, all within a few degrees: the packet is always taken
    tris = rng.uniform(0.2, 0.5, size=(4, 9)).astype(np.float32)
    tris[:, 2::3] = rng.uniform(3, 3.5, size=(4, 3))
    if shared:
        tris[1, 0:6] = tris[0, 3:9]  # an edge shared with triangle 0
        tris[2] = tris[1]  # a duplicate: the first of equal hits wins
    picks = tris[rng.integers(0, count, size=PACKET)].reshape(PACKET, 3, 3).astype(np.float64)
    if shared:
        w = rng.choice([0.0, 0.5, 1.0], size=(PACKET, 3))
        w[w.sum(axis=1) == 0, 0] = 1.0  # a vertex rather than no point at all
    else:
        w = rng.uniform(0.05, 1.0, size=(PACKET, 3))
    targets = (picks * (w / w.sum(axis=1, keepdims=True))[:, :, None]).sum(axis=1)
    origins = rng.normal(scale=1e-3, size=(PACKET, 3))
    d = targets - origins
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = _triangle_block(tris, 0, count, origins, d)
    assert not np.isnan(got).any()
    ref = _triangle_one_by_one(tris, 0, count, origins, d)
    ref[:, 1] = np.where(ref[:, 1] >= 0, ref[:, 1], -1)
    np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize(("spp", "aperture", "filt"), [(1, 0.0, "box"), (4, 0.0, "mitchell"), (4, 0.05, "gaussian")])
def test_cast_packets_give_the_single_ray_image(tmp_path, spp, aperture, filt):
    """A cast render of meshes in packets, in both kernel variants: alone (the basic variant)
    and with a plane behind the camera, which the image never shows but which puts the render
    in the other variant, where the plane is tested ray by ray before each packet's traversal.
    Against the same scene with an instanced triangle behind the camera instead, which that
    variant traces one sample at a time: the same image (and AOVs) to the last bit, with
    several samples per pixel, a negative-lobed filter and a lens (whose samples are coherent
    or not, packet by packet)."""
    v, f = bumpy_sphere(6000)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    v2, f2 = bumpy_sphere(3000)
    trimesh.Trimesh(v2 * 0.5 + [1.2, 0.4, 0.5], f2, process=False).export(tmp_path / "m2.ply")
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False).export(tmp_path / "t.ply")
    np.save(tmp_path / "behind.npy", np.array([[[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -10]]]))
    objects = [
        {"type": "mesh", "file": str(tmp_path / "m.ply"), "material": {"color": [0.8, 0.3, 0.2]}},
        {"type": "mesh", "file": str(tmp_path / "m2.ply"), "material": {"color": [0.2, 0.6, 0.9]}},
    ]
    scene = {
        "camera": {"position": [0, 0, -3.5], "look_at": [0, 0, 0], "fov": 50, "aperture": aperture},
        "render": {"mode": "cast", "width": 80, "height": 60, "spp": spp, "filter": filt},
        "objects": objects,
    }
    plane = [{"type": "plane", "point": [0, 0, -10], "normal": [0, 0, 1]}]  # behind the camera
    instance = [{"type": "mesh", "file": str(tmp_path / "t.ply"), "instances": str(tmp_path / "behind.npy")}]
    single = raylume.render(raylume.scene_from_dict({**scene, "objects": objects + instance}))
    colours = len(np.unique(single.rgb.reshape(-1, 3), axis=0))
    assert colours >= 3 if spp == 1 else colours > 3  # both meshes and the background; mixed edges
    assert set(np.unique(single.aovs["object"]).tolist()) == {-1, 0, 1}
    for extra in ([], plane):
        packets = raylume.render(raylume.scene_from_dict({**scene, "objects": objects + extra}))
        np.testing.assert_array_equal(packets.rgb, single.rgb)
        # the AOV pass (single rays in both variants) agrees too
        for name in ("depth", "normal", "object", "prim", "albedo", "instance"):
            np.testing.assert_array_equal(packets.aovs[name], single.aovs[name], err_msg=name)


@pytest.mark.parametrize(("width", "height", "crop"), [(83, 61, None), (64, 48, (5, 60, 3, 40)), (41, 3, None)])
def test_cast_rows_in_pairs_give_the_single_ray_image(tmp_path, width, height, crop):
    """At one sample a pixel cast mode claims rows in pairs and traces 4 x 2 pixel packets
    (frame._cast_row with pair); an odd last row of the window goes alone. The image and the ray
    count equal the single-ray render's (an instance behind the camera puts the scene in the
    variant without packets), also in a crop and a three-row image."""
    v, f = bumpy_sphere(6000)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False).export(tmp_path / "t.ply")
    np.save(tmp_path / "behind.npy", np.array([[[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -10]]]))
    mesh = {"type": "mesh", "file": str(tmp_path / "m.ply"), "material": {"color": [0.8, 0.3, 0.2]}}
    instance = {"type": "mesh", "file": str(tmp_path / "t.ply"), "instances": str(tmp_path / "behind.npy")}
    scene = {
        "camera": {"position": [0, 0, -3.2], "look_at": [0, 0, 0], "fov": 45},
        "render": {"mode": "cast", "width": width, "height": height, "spp": 1},
    }
    single = raylume.render(raylume.scene_from_dict({**scene, "objects": [mesh, instance]}), crop=crop, aovs=False)
    for threads in (1, 2):
        packets = raylume.render(
            raylume.scene_from_dict({**scene, "objects": [mesh]}), crop=crop, aovs=False, threads=threads
        )
        np.testing.assert_array_equal(packets.rgb, single.rgb)
        assert packets.stats["rays"] == single.stats["rays"] == single.rgb.shape[0] * single.rgb.shape[1]
    hit = single.rgb.any(axis=2)
    assert hit.any() and not hit.all()  # the mesh's outline is in the picture


def test_intersect_ignores_materials_and_lights_in_choosing_its_kernels(tmp_path):
    """raylume.intersect on a mesh of glass under an area light (the render kernels' full
    variant): the basic variant with its packets, since a hit depends on neither, and the same
    hits as the opaque mesh's."""
    from raylume.kernels.variants import features, geometry_features

    v, f = bumpy_sphere(5000)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    glass = {"transparency": 0.9, "ior": 1.5}
    fancy = {
        "lights": [{"type": "quad", "position": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1]}],
        "objects": [{"type": "mesh", "file": str(tmp_path / "m.ply"), "material": glass}],
    }
    plain = {"objects": [{"type": "mesh", "file": str(tmp_path / "m.ply")}]}
    S = compile_scene(raylume.scene_from_dict(fancy)).kernel
    assert features(S) is not None and geometry_features(S) is None
    o, d = _camera_rays(np.zeros(3), 1.2, 64)
    got = raylume.intersect(raylume.scene_from_dict(fancy), o, d)
    ref = raylume.intersect(raylume.scene_from_dict(plain), o, d)
    assert np.isfinite(got[0]).mean() > 0.2
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)


@PACKET_WORKER
def test_intersect_takes_packets_beside_planes_and_other_shapes(tmp_path):
    """raylume.intersect on a mesh with a ground plane, a quad and spheres (the full variant, no
    instances): packets there too, with the plane tested ray by ray first and the quad in its
    leaves; the same distances and objects as single rays."""
    from raylume.kernels.scene import instances_of

    v, f = bumpy_sphere(8000)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    scene = raylume.scene_from_dict(
        {
            "objects": [
                {"type": "mesh", "file": str(tmp_path / "m.ply")},
                {"type": "plane", "point": [0, -1.05, 0], "normal": [0, 1, 0]},
                {"type": "quad", "position": [1.3, 0.2, 0.4], "u": [0.5, 0, 0], "v": [0, 0.6, 0.2]},
                {"type": "sphere", "center": [-1.3, 0.3, 0.2], "radius": 0.3},
            ]
        }
    )
    from raylume.kernels.variants import geometry_features

    S = compile_scene(scene).kernel
    X = geometry_features(S)
    assert X is not None  # the full variant
    o, d = _camera_rays(np.array([0.0, -0.2, 0.0]), 1.5, 96)
    n = len(o)
    t, obj, prim, inst = np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
    intersect_rays(S, X, o, d, t, obj, prim, inst, 2)  # raylume.intersect's kernel
    ref = _single(S, o, d, instances_of(S))
    assert set(np.unique(obj).tolist()) == {-1, 0, 1, 2, 3}  # every object is seen, and the sky
    np.testing.assert_array_equal(t, ref[:, 0])
    hit = ref[:, 1] >= 0
    assert (obj[hit] == S.prims[ref[hit, 1].astype(int), 3]).mean() > 0.999


@njit(fastmath=FAST, error_model="numpy")
def _shadow_packets(S, origins, dirs, tmax, need):
    """Shadow rays in packets of eight (need[p]: the mask of packet p's rays to trace) through
    packet_blocked: (how many of each packet's rays it took, from the first; the blocked mask of
    each)."""
    n = origins.shape[0]
    packets = packet_scratch()
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    extent, root = scene_extent(G), root_box(G)
    count = (n + PACKET - 1) // PACKET
    taken = np.zeros(count, np.int64)
    blocked = np.zeros(count, np.int64)
    for p in range(count):
        start = p * PACKET
        m = min(PACKET, n - start)
        ok, mask = packet_blocked(
            G, None, root, origins, dirs, None, tmax, start, start, m, need[p], extent, packets,
            node_stack, t_stack,
        )  # fmt: skip
        taken[p], blocked[p] = ok, mask
    return taken, blocked


@njit(fastmath=FAST, error_model="numpy")
def _any_hits(S, origins, dirs, tmin, tmax):
    """any_hit ray by ray (unit directions), ray k in (tmin[k], tmax[k]): the single-ray answers
    the packets must give (test_query's occlusion tests use it too)."""
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    out = np.zeros(origins.shape[0], np.bool_)
    for k in range(origins.shape[0]):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        out[k] = any_hit(G, None, o, d, tmin[k], tmax[k], node_stack, t_stack)
    return out


@PACKET_WORKER
@pytest.mark.parametrize("light", ["point", "directional"])
def test_shadow_packets_block_what_any_hit_blocks(tmp_path, light):
    """Shadow rays from the hit points of rows of camera rays on a bumpy sphere, towards a point
    light (each ray its own tmax; a second sphere lies beyond the light) and along a directional
    one, eight neighbours a packet, some lanes not traced: the packets are taken, and each
    traced lane is blocked exactly when any_hit says so (the sphere shadows itself: both
    answers occur)."""
    v, f = bumpy_sphere(20_000)
    # a second sphere beyond the point light: a ray's hits past its own tmax must not count
    S = _compiled_mesh(tmp_path, np.concatenate([v, v + [6.0, 0.0, 0.0]]), np.concatenate([f, f + len(v)])).kernel
    cam = camera_frame(np.array([0.0, 0.0, -3.0]), np.zeros(3), (0, 1, 0), 53.13, 512, 512)
    a = (np.arange(512) + 0.5) / 512 * 2 - 1
    rows = []
    for b in np.linspace(-0.5, 0.5, 9):
        d = cam[3:6] + a[:, None] * cam[6:9] + b * cam[9:12]
        rows.append(d / np.linalg.norm(d, axis=1, keepdims=True))
    dirs = np.concatenate(rows)
    eye = np.broadcast_to([0.0, 0.0, -3.0], dirs.shape).copy()
    hits = _single(S, eye, dirs)
    hit = np.isfinite(hits[:, 0])
    points = eye[hit] + dirs[hit] * hits[hit, :1] * (1 - 1e-6)  # just above the surface, on the eye's side
    if light == "point":
        to_light = np.array([3.0, 0.3, -0.3]) - points
        tmax = np.linalg.norm(to_light, axis=1)
        ldirs = to_light / tmax[:, None]
    else:
        ldirs = np.broadcast_to(np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]), points.shape).copy()
        tmax = np.full(len(points), INF)
    count = (len(points) + PACKET - 1) // PACKET
    need = np.array([0xFF if p % 3 else 0b10110101 for p in range(count)], dtype=np.int64)
    _assert_shadow_packets_block_what_any_hit_blocks(S, points, ldirs, tmax, need)


def _assert_shadow_packets_block_what_any_hit_blocks(S, points, ldirs, tmax, need):
    """Shadow packets of eight neighbours (need[p]: the lanes of packet p to trace) are taken,
    and each traced lane is blocked exactly when any_hit says so, untraced lanes never; lit and
    shadowed points both occur."""
    expected = _any_hits(S, points, ldirs, np.zeros(len(points)), tmax)
    taken, blocked = _shadow_packets(S, points, ldirs, tmax, need)
    whole = _whole(taken, len(points), PACKET)
    assert whole.mean() > 0.9, whole.mean()
    assert 0.05 < expected.mean() < 0.95  # lit and shadowed points both
    for p in np.flatnonzero(taken):
        assert not blocked[p] >> taken[p]  # the rays it left are not answered
        for k in range(taken[p]):
            if (need[p] >> k) & 1:
                assert bool((blocked[p] >> k) & 1) == expected[p * PACKET + k], (p, k)
            else:
                assert not (blocked[p] >> k) & 1


@PACKET_WORKER
def test_the_largest_trees_hit_alike_with_their_children_prefetched(tmp_path):
    """From CHILDREN_PREFETCHED_FROM wide nodes on (2.8M triangles), the traversals prefetch the
    record of every inner child they push (wide_nodes.prefetch_child, a hint): packets, single
    rays and the brute force still agree on the camera rays."""
    v, f = bumpy_sphere(2_800_000)
    S = _compiled_mesh(tmp_path, v, f).kernel
    assert S.node_bounds.shape[0] >= CHILDREN_PREFETCHED_FROM
    _assert_camera_rays_hit_alike(S, v, f, 48, 48, seed=4)


def _assert_camera_rays_hit_alike(S, v, f, size, brute, seed):
    """Packets and single rays give the same hits on size x size camera rays of the mesh (v, f)
    compiled as S, a fifth to most of them hitting, and `brute` of them (drawn with `seed`) the
    brute force's distances."""
    o, d = _camera_rays(np.zeros(3), 1.2, size)
    got, taken = _packets(S, o, d, PACKET)
    assert _whole(taken, len(o), PACKET).all()
    ref = _single(S, o, d)
    assert 0.2 < np.isfinite(ref[:, 0]).mean() < 0.95
    _assert_same_hits(got, ref)
    sample = np.random.default_rng(seed).choice(len(o), brute, replace=False)
    np.testing.assert_array_equal(ref[sample, 0], _brute(v.astype(np.float32)[f].reshape(-1, 9), o[sample], d[sample]))


@PACKET_WORKER
def test_large_meshes_hit_alike_with_their_neighbours_prefetched(tmp_path):
    """From NEIGHBOURS_FROM triangles on, the traversals also prefetch the triangle rows beside
    each leaf they test (traverse.prefetch_neighbours: a hint, which at the table's first and
    last leaves reaches beyond its ends): no answer changes. Packets, single rays and the brute
    force agree on the camera rays, and shadow packets on what any_hit blocks."""
    v, f = bumpy_sphere(300_000)
    S = _compiled_mesh(tmp_path, v, f).kernel
    assert S.triangles.shape[0] >= NEIGHBOURS_FROM
    _assert_camera_rays_hit_alike(S, v, f, 64, 96, seed=3)
    # shadow rays from the hits of rows of 512 camera rays (neighbours close enough for packets)
    o, d = _camera_rays(np.zeros(3), 1.2, 512)
    o, d = o[200 * 512 : 203 * 512], d[200 * 512 : 203 * 512]
    t = _single(S, o, d)[:, :1]
    hit = np.isfinite(t[:, 0])
    points = o[hit] + d[hit] * t[hit] * (1 - 1e-6)  # just above the surface, on the eye's side
    to_light = np.array([3.0, 0.3, -0.3]) - points
    tmax = np.linalg.norm(to_light, axis=1)
    ldirs = to_light / tmax[:, None]
    need = np.full((len(points) + PACKET - 1) // PACKET, 0xFF, np.int64)
    _assert_shadow_packets_block_what_any_hit_blocks(S, points, ldirs, tmax, need)
