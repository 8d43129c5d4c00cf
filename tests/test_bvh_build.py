"""Tests for the binned-SAH BVH builder (raylume.accel.bvh).

The checks are independent of the builder's internals: structure and
containment are verified directly against the float64 input boxes, the SAH
quality against a naive object-median tree built here, and completeness by
comparing a BVH traversal with a brute-force slab test over all primitives.
"""

import itertools
import time
from unittest.mock import patch

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from raylume.accel import bvh as bvh_module
from raylume.accel.bvh import BVH, build_bvh, bvh_depth, bvh_nbytes, sah_cost

# ---------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------


def check_bvh(bvh, lo, hi, max_leaf):
    """Assert every structural and geometric invariant; vectorised so it
    also works for large N."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    n = lo.shape[0]
    nb, ni, na, order = bvh
    m = na.shape[0]
    assert isinstance(bvh, BVH)
    assert nb.dtype == np.float32 and nb.shape == (m, 6)
    assert ni.dtype == np.int32 and ni.shape == (m, 2)
    assert na.dtype == np.int8
    assert order.dtype == np.int32 and order.shape == (n,)
    assert np.array_equal(np.sort(order), np.arange(n))

    inner = np.flatnonzero(na >= 0)
    leaf = np.flatnonzero(na < 0)
    assert np.all(na[inner] <= 2)
    assert np.all(na[leaf] == -1)
    assert m <= max(1, 2 * n - 1)

    # Depth-first layout: left = m + 1, right beyond it, and every node other
    # than the root is the child of exactly one inner node (a tree, since
    # children always follow their parent).
    left = inner + 1
    right = ni[inner, 0].astype(np.int64)
    assert np.all(ni[inner, 1] == 0)
    assert np.all(right > left) and np.all(right < m)
    assert np.array_equal(np.sort(np.concatenate([left, right])), np.arange(1, m))

    # Leaves partition prim_order: disjoint, contiguous, covering [0, N).
    first = ni[leaf, 0].astype(np.int64)
    count = ni[leaf, 1].astype(np.int64)
    if n == 0:
        assert m == 1 and count[0] == 0
        assert np.all(nb[0, :3] == np.inf) and np.all(nb[0, 3:] == -np.inf)
        return
    assert np.all(count >= 1) and np.all(count <= max_leaf)
    by_first = np.argsort(first)
    ends = first[by_first] + count[by_first]
    assert first[by_first][0] == 0 and ends[-1] == n
    assert np.array_equal(first[by_first][1:], ends[:-1])

    # Conservativeness: leaf boxes (float32, compared in float64) contain
    # the float64 input boxes of their primitives ...
    box = nb.astype(np.float64)
    owner = np.repeat(leaf[by_first], count[by_first])  # leaf of each position
    prims = order
    assert np.all(box[owner, :3] <= lo[prims])
    assert np.all(box[owner, 3:] >= hi[prims])
    # ... and parents contain their children.
    for child in (left, right):
        assert np.all(box[inner, :3] <= box[child, :3])
        assert np.all(box[inner, 3:] >= box[child, 3:])


def subtree_prims(bvh, m):
    nb, ni, na, order = bvh
    stack, out = [m], []
    while stack:
        k = stack.pop()
        if na[k] < 0:
            out.extend(order[ni[k, 0] : ni[k, 0] + ni[k, 1]])
        else:
            stack += [k + 1, ni[k, 0]]
    return out


def ref_sah(bounds_of_nodes, leaf_counts, root_area, c_trav=1.0, c_isect=1.0, block=1):
    """SAH with a leaf of n primitives costing ceil(n / block) intersections."""
    e = np.maximum(bounds_of_nodes[:, 3:] - bounds_of_nodes[:, :3], 0.0)
    a = 2.0 * (e[:, 0] * e[:, 1] + e[:, 1] * e[:, 2] + e[:, 2] * e[:, 0])
    w = np.where(leaf_counts > 0, c_isect * np.ceil(leaf_counts / block), c_trav)
    return float((w * a).sum() / root_area)


def tree_sah_float64(bvh, lo, hi, c_trav=1.0, block=1):
    """SAH of a built tree with node boxes recomputed exactly from the
    float64 primitive boxes (independent of the stored float32 bounds)."""
    nb, ni, na, order = bvh
    boxes, counts = [], []
    for m in range(na.shape[0]):
        p = np.asarray(subtree_prims(bvh, m))
        boxes.append(np.concatenate([lo[p].min(0), hi[p].max(0)]))
        counts.append(ni[m, 1] if na[m] < 0 else 0)
    boxes = np.array(boxes)
    e = boxes[0, 3:] - boxes[0, :3]
    root = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    return ref_sah(boxes, np.array(counts), root, c_trav=c_trav, block=block)


def median_tree_sah(lo, hi, max_leaf):
    """Naive reference: object-median split on the widest centroid axis."""
    cen = 0.5 * (lo + hi)
    boxes, counts = [], []
    stack = [np.arange(lo.shape[0])]
    while stack:
        p = stack.pop()
        boxes.append(np.concatenate([lo[p].min(0), hi[p].max(0)]))
        if p.size <= max_leaf:
            counts.append(p.size)
            continue
        counts.append(0)
        c = cen[p]
        axis = np.argmax(c.max(0) - c.min(0))
        p = p[np.argsort(c[:, axis], kind="stable")]
        stack += [p[: p.size // 2], p[p.size // 2 :]]
    boxes = np.array(boxes)
    e = boxes[0, 3:] - boxes[0, :3]
    root = 2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    return ref_sah(boxes, np.array(counts), root)


def slab_hit(lo, hi, o, inv_d):
    """Vectorised slab test of one ray (t >= 0) against boxes lo/hi (K, 3)."""
    t0 = (lo - o) * inv_d
    t1 = (hi - o) * inv_d
    tnear = np.maximum(np.minimum(t0, t1).max(axis=-1), 0.0)
    tfar = np.maximum(t0, t1).min(axis=-1)
    return tnear <= tfar


def traverse(bvh, lo, hi, o, inv_d):
    """Plain stack traversal; returns primitives whose own boxes are hit."""
    nb, ni, na, order = bvh
    box = nb.astype(np.float64)
    hits, stack = set(), [0]
    while stack:
        m = stack.pop()
        if not slab_hit(box[m, :3], box[m, 3:], o, inv_d):
            continue
        if na[m] < 0:
            p = order[ni[m, 0] : ni[m, 0] + ni[m, 1]]
            hits.update(p[slab_hit(lo[p], hi[p], o, inv_d)].tolist())
        else:
            stack += [m + 1, int(ni[m, 0])]
    return hits


def clustered_boxes(rng, n, n_clusters=12):
    centers = rng.uniform(-10, 10, (n_clusters, 3))
    spread = rng.uniform(0.05, 2.0, n_clusters)
    which = rng.integers(0, n_clusters, n)
    c = centers[which] + rng.normal(size=(n, 3)) * spread[which, None]
    half = rng.uniform(0.001, 0.1, (n, 3))
    return c - half, c + half


# ---------------------------------------------------------------------------
# Small and degenerate inputs
# ---------------------------------------------------------------------------


def test_empty():
    bvh = build_bvh(np.zeros((0, 3)), np.zeros((0, 3)))
    check_bvh(bvh, np.zeros((0, 3)), np.zeros((0, 3)), 4)
    assert bvh_depth(bvh) == 1
    assert sah_cost(bvh) == 0.0


def test_single():
    lo = np.array([[0.1, 0.2, 0.3]])
    hi = np.array([[1.1, 1.2, 1.3]])
    bvh = build_bvh(lo, hi)
    check_bvh(bvh, lo, hi, 4)
    assert bvh.node_index.tolist() == [[0, 1]]
    assert bvh.node_axis.tolist() == [-1]
    assert bvh_depth(bvh) == 1


@pytest.mark.parametrize("max_leaf", [1, 4])
def test_two(max_leaf):
    lo = np.array([[0.0, 0, 0], [5.0, 0, 0]])
    hi = lo + 1.0
    bvh = build_bvh(lo, hi, max_leaf_size=max_leaf)
    check_bvh(bvh, lo, hi, max_leaf)
    # Far apart: splitting is cheaper than one leaf (and mandatory for 1).
    assert bvh.node_index.shape[0] == 3
    assert bvh.node_axis[0] == 0


@pytest.mark.parametrize("max_leaf", [1, 3, 4])
def test_identical_boxes_respect_max_leaf(max_leaf):
    n = 101
    lo = np.tile([0.5, -1.0, 2.0], (n, 1))
    hi = lo + [1.0, 0.0, 3.0]
    bvh = build_bvh(lo, hi, max_leaf_size=max_leaf)
    check_bvh(bvh, lo, hi, max_leaf)
    # Object-median splits keep the tree balanced.
    assert bvh_depth(bvh) <= int(np.ceil(np.log2(n))) + 2


def test_coincident_centroids_different_sizes():
    n = 50
    half = np.linspace(0.01, 3.0, n)[:, None] * [1.0, 2.0, 0.5]
    lo, hi = 1.0 - half, 1.0 + half
    bvh = build_bvh(lo, hi, max_leaf_size=2)
    check_bvh(bvh, lo, hi, 2)


def test_points_and_segments():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1, 1, (200, 3))
    check_bvh(build_bvh(pts, pts), pts, pts, 4)
    seg_lo = np.column_stack([np.zeros(300), np.arange(300.0), np.zeros(300)])
    seg_hi = seg_lo + [5.0, 0.0, 0.0]
    bvh = build_bvh(seg_lo, seg_hi)
    check_bvh(bvh, seg_lo, seg_hi, 4)
    assert bvh_depth(bvh) < 40  # the area padding keeps splits sensible


def test_deep_chain():
    # Exponentially spaced boxes with two bins: every split peels off the
    # rightmost primitive, so the tree is a left-leaning chain whose pending
    # right jobs outgrow the builder's initial work stack.
    x = 2.5 ** np.arange(96)  # ratio > 2: one primitive beyond the mid-plane
    lo = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    hi = lo + [0.0, 1.0, 1.0]
    bvh = build_bvh(lo, hi, max_leaf_size=1, n_bins=2)
    check_bvh(bvh, lo, hi, 1)
    assert bvh_depth(bvh) == 96


def test_conservative_rounding_and_float32_input():
    rng = np.random.default_rng(5)
    # Values that are not representable in float32, tiny boxes.
    c = rng.uniform(-1e3, 1e3, (500, 3)) + 0.1
    lo, hi = c - 1e-9, c + 1e-9
    bvh = build_bvh(lo, hi)
    check_bvh(bvh, lo, hi, 4)
    # Flat boxes: lo == hi in one dimension.
    hi2 = hi.copy()
    hi2[:, 1] = lo[:, 1]
    check_bvh(build_bvh(lo, hi2), lo, hi2, 4)
    lo32, hi32 = lo.astype(np.float32), np.maximum(hi.astype(np.float32), lo.astype(np.float32))
    check_bvh(build_bvh(lo32, hi32), lo32, hi32, 4)


def test_rejects_bad_input():
    with pytest.raises(ValueError):
        build_bvh(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError):
        build_bvh(np.ones((2, 3)), np.zeros((2, 3)))  # lo > hi
    lo = np.zeros((2, 3))
    lo[1, 2] = np.nan
    with pytest.raises(ValueError):
        build_bvh(lo, np.ones((2, 3)))
    with pytest.raises(ValueError):
        build_bvh(np.zeros((2, 3)), np.ones((2, 3)), leaf_block=0)


# ---------------------------------------------------------------------------
# Randomised structure checks
# ---------------------------------------------------------------------------

_coord = st.one_of(
    st.floats(-10.0, 10.0),
    st.floats(-1e30, 1e30),
    st.floats(-1e300, 1e300),  # beyond float32: bounds become +-inf / +-max
    st.floats(-1e-30, 1e-30),
    st.floats(-1e-300, 1e-300),  # float32 subnormal / zero territory
)


@st.composite
def box_sets(draw):
    n = draw(st.integers(0, 40))
    a = np.array(draw(st.lists(st.tuples(_coord, _coord, _coord), min_size=n, max_size=n)), dtype=np.float64).reshape(
        n, 3
    )
    b = np.array(draw(st.lists(st.tuples(_coord, _coord, _coord), min_size=n, max_size=n)), dtype=np.float64).reshape(
        n, 3
    )
    # Some boxes flat or points: copy a into b on random dimensions.
    flat = np.array(draw(st.lists(st.booleans(), min_size=3 * n, max_size=3 * n)), dtype=bool).reshape(n, 3)
    b[flat] = a[flat]
    if n and draw(st.booleans()):  # duplicate boxes
        k = draw(st.integers(0, n - 1))
        a[k:] = a[k]
        b[k:] = b[k]
    return np.minimum(a, b), np.maximum(a, b)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(boxes=box_sets(), max_leaf=st.integers(1, 6), n_bins=st.integers(2, 20))
def test_random_boxes_invariants(boxes, max_leaf, n_bins):
    lo, hi = boxes
    bvh = build_bvh(lo, hi, max_leaf_size=max_leaf, n_bins=n_bins)
    check_bvh(bvh, lo, hi, max_leaf)
    assert np.isfinite(sah_cost(bvh))
    assert bvh_depth(bvh) <= max(1, lo.shape[0])
    assert bvh_nbytes(bvh) == sum(a.nbytes for a in bvh)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 300))
def test_rays_reach_exactly_the_hit_boxes(seed, n):
    rng = np.random.default_rng(seed)
    lo, hi = clustered_boxes(rng, n, n_clusters=int(rng.integers(1, 6)))
    bvh = build_bvh(lo, hi, max_leaf_size=int(rng.integers(1, 6)))
    for _ in range(20):
        # Origins inside and around the scene, aimed at a random primitive
        # half of the time so that many rays hit something.
        o = rng.uniform(-15, 15, 3)
        target = 0.5 * (lo[rng.integers(n)] + hi[rng.integers(n)]) if rng.random() < 0.5 else rng.uniform(-15, 15, 3)
        d = target - o + rng.normal(scale=1e-3, size=3)
        d[d == 0.0] = 1e-12  # slab test needs non-zero components
        inv_d = 1.0 / d
        brute = set(np.flatnonzero(slab_hit(lo, hi, o, inv_d)).tolist())
        assert traverse(bvh, lo, hi, o, inv_d) == brute


# ---------------------------------------------------------------------------
# Quality and scale
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sah_beats_median_split(seed):
    rng = np.random.default_rng(seed)
    lo, hi = clustered_boxes(rng, 1500)
    bvh = build_bvh(lo, hi, max_leaf_size=4)
    check_bvh(bvh, lo, hi, 4)
    ours = tree_sah_float64(bvh, lo, hi)
    # sah_cost (from float32 bounds) agrees with the exact recomputation.
    assert sah_cost(bvh) == pytest.approx(ours, rel=1e-4)
    median = median_tree_sah(lo, hi, 4)
    print(f"seed {seed}: SAH binned {ours:.2f} vs object median {median:.2f}")
    assert ours < 0.95 * median


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_leaf_blocks_fill_leaves_and_lower_the_block_cost(seed):
    """With leaf_block=4 a leaf of 1 to 4 primitives costs one (vector) test. With c_isect <=
    c_trav no inner node then holds 4 primitives or fewer (a split costs at least one
    traversal), and the tree's SAH counted in blocks, recomputed here in float64, is lower than
    that of the tree built counting primitives."""
    rng = np.random.default_rng(seed)
    lo, hi = clustered_boxes(rng, 1500)
    plain = build_bvh(lo, hi, max_leaf_size=4, c_trav=2.0)
    blocks = build_bvh(lo, hi, max_leaf_size=4, c_trav=2.0, leaf_block=4)
    check_bvh(blocks, lo, hi, 4)

    def small_inner(bvh):
        return [m for m in np.flatnonzero(bvh.node_axis >= 0) if len(subtree_prims(bvh, m)) <= 4]

    assert small_inner(plain)  # counting primitives, such nodes are split
    assert not small_inner(blocks)
    ours, theirs = tree_sah_float64(blocks, lo, hi, 2.0, 4), tree_sah_float64(plain, lo, hi, 2.0, 4)
    print(f"seed {seed}: block SAH {ours:.2f} with leaf_block=4, {theirs:.2f} without")
    assert ours < theirs
    assert sah_cost(blocks, 2.0, leaf_block=4) == pytest.approx(ours, rel=1e-4)  # from the float32 bounds


def test_large_build_smoke():
    rng = np.random.default_rng(11)
    n = 200_000
    c = rng.uniform(0, 1, (n, 3))
    half = rng.uniform(0, 0.002, (n, 3))
    lo, hi = c - half, c + half
    build_bvh(lo[:10], hi[:10])  # compile outside the timing
    t = time.perf_counter()
    bvh = build_bvh(lo, hi)
    dt = time.perf_counter() - t
    check_bvh(bvh, lo, hi, 4)
    print(
        f"N={n}: build {dt:.3f}s, {bvh.node_axis.shape[0]} nodes, depth {bvh_depth(bvh)}, "
        f"SAH {sah_cost(bvh):.1f}, {bvh_nbytes(bvh) / 1e6:.1f} MB"
    )


def numpy_bins(c, cmin, scale, n_bins):
    """The bin of float32 centroids ``c`` as the binning pass defines it, in numpy."""
    t = (c.astype(np.float64) - cmin) * scale
    return np.where(t < n_bins, np.floor(np.minimum(t, n_bins)), n_bins - 1).astype(np.int64)


@settings(max_examples=300, deadline=None)
@given(
    cmin=st.one_of(st.floats(-10, 10), st.floats(-1e30, 1e30), st.floats(-1e-30, 1e-30), st.just(-3.4e38)),
    ext=st.one_of(st.floats(1e-6, 20), st.floats(1e-40, 1e-30), st.floats(1.0, 1e31), st.just(6.8e38)),
    n_bins=st.integers(2, 16),
    data=st.data(),
)
def test_partition_threshold_is_the_bin_test(cmin, ext, n_bins, data):
    # The partition sends a centroid left when it is below _threshold: exactly when its bin
    # is below the plane (including nodes whose bins span billions of float32 steps around 0).
    cmin = float(np.float32(cmin))
    cmax = float(np.float32(min(cmin + ext, 3.4e38)))
    assume(cmax > cmin)
    scale = n_bins / (cmax - cmin)
    plane = data.draw(st.integers(1, n_bins - 1))
    thr = np.float32(bvh_module._threshold(cmin, scale, plane, n_bins))
    below = np.nextafter(thr, np.float32(-np.inf))
    assert numpy_bins(np.array([thr]), cmin, scale, n_bins)[0] >= plane
    assert numpy_bins(np.array([below]), cmin, scale, n_bins)[0] < plane
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    # centroids spread over [cmin, cmax], drawn in float64 (a span past float32's range, -3.4e38 to
    # 3.4e38, overflowed float32 before the shift)
    c = (cmin + rng.uniform(0, 1, 200) * (cmax - cmin)).astype(np.float32)
    c = np.concatenate([c, [thr, below, np.float32(cmin), np.float32(cmax)]]).astype(np.float32)
    c = c[(c >= np.float32(cmin)) & (c <= np.float32(cmax))]
    np.testing.assert_array_equal(c < thr, numpy_bins(c, cmin, scale, n_bins) < plane)


# ---------------------------------------------------------------------------
# The parallel build (nodes above bvh._TOP primitives split over threads)
# ---------------------------------------------------------------------------


def build_on(threads, lo, hi, top=None, **kw):
    """build_bvh on `threads` Numba threads; with `top`, a smaller threshold for the top part
    (and blocks of 7 primitives in its partition), so that small inputs take the parallel path."""
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        with (
            patch.object(bvh_module, "_TOP", top if top is not None else bvh_module._TOP),
            patch.object(bvh_module, "_BLOCK", 7 if top is not None else bvh_module._BLOCK),
        ):
            return build_bvh(lo, hi, **kw)
    finally:
        numba.set_num_threads(before)


THREADS = min(2, numba.config.NUMBA_NUM_THREADS)


def same_tree(a, b):
    """Identical nodes and leaves; the primitives of each leaf may come in another order."""
    assert np.array_equal(a.node_bounds, b.node_bounds)
    assert np.array_equal(a.node_index, b.node_index)
    assert np.array_equal(a.node_axis, b.node_axis)
    for first, count in a.node_index[a.node_axis < 0]:
        assert set(a.prim_order[first : first + count]) == set(b.prim_order[first : first + count])


@pytest.mark.parametrize("top", [16, 200])
@pytest.mark.parametrize("leaf_block", [1, 4])
def test_parallel_build_is_the_serial_tree_on_any_thread_count(top, leaf_block):
    rng = np.random.default_rng(7)
    lo, hi = clustered_boxes(rng, 4000)
    kw = {"max_leaf_size": 4, "c_trav": 2.0, "leaf_block": leaf_block}
    serial = build_bvh(lo, hi, **kw)  # 4000 < _TOP: one serial subtree
    one = build_on(1, lo, hi, top, **kw)
    many = build_on(THREADS, lo, hi, top, **kw)
    check_bvh(one, lo, hi, 4)
    for a, b in zip(one, many, strict=True):  # bit for bit, prim_order included
        assert np.array_equal(a, b)
    # The split decisions depend only on which primitives a node holds: the same tree as the
    # serial build, so the same SAH (a stable partition only orders leaves differently).
    same_tree(one, serial)
    assert sah_cost(one, 2.0) == sah_cost(serial, 2.0)
    # More pieces than threads (the internal thread count) changes nothing either.
    box = np.empty((len(lo), 6), np.float32)
    cen = np.empty((len(lo), 3), np.float32)
    cb = np.empty(6)
    ids = np.empty(len(lo), np.int32)
    bvh_module._prepare(lo, hi, box, cen, ids, cb, 0, len(lo))
    with patch.object(bvh_module, "_TOP", top), patch.object(bvh_module, "_BLOCK", 7):
        nodes = bvh_module._build(box, cen, ids, cb, 4, 16, 2.0, 1.0, leaf_block, 5)
    for a, b in zip(nodes + (ids,), one, strict=True):
        assert np.array_equal(a, b)


def test_parallel_build_at_full_size():
    rng = np.random.default_rng(8)
    n = 2 * bvh_module._TOP + 1000  # two levels above the threshold
    lo, hi = clustered_boxes(rng, n)
    one = build_on(1, lo, hi)
    many = build_on(THREADS, lo, hi)
    check_bvh(many, lo, hi, 4)
    for a, b in zip(one, many, strict=True):
        assert np.array_equal(a, b)
    same_tree(one, build_on(1, lo, hi, top=10 * n))  # all of it one serial subtree


@pytest.mark.parametrize("max_leaf", [1, 4])
def test_parallel_build_degenerate(max_leaf):
    # All centroids equal (halved by position), then equal centroids of different sizes.
    n = 500
    lo = np.tile([0.5, -1.0, 2.0], (n, 1))
    hi = lo + [1.0, 0.0, 3.0]
    half = np.linspace(0.01, 3.0, n)[:, None] * [1.0, 2.0, 0.5]
    for a, b in ((lo, hi), (1.0 - half, 1.0 + half)):
        one = build_on(1, a, b, 16, max_leaf_size=max_leaf)
        many = build_on(THREADS, a, b, 16, max_leaf_size=max_leaf)
        check_bvh(many, a, b, max_leaf)
        for x, y in zip(one, many, strict=True):
            assert np.array_equal(x, y)
        if a is lo:  # identical boxes: halved, so balanced
            assert bvh_depth(many) <= int(np.ceil(np.log2(n))) + 2
    for n in (0, 1, 2):
        a = np.arange(3.0 * n).reshape(n, 3)
        check_bvh(build_on(THREADS, a, a + 1, 1), a, a + 1, 4)


def test_parallel_build_reports_the_first_bad_box():
    lo = np.zeros((1000, 3))
    hi = np.ones((1000, 3))
    lo[900, 0] = 2.0  # lo > hi
    lo[700, 1] = np.nan  # the first bad one, in another thread's piece
    with pytest.raises(ValueError, match="primitive 700 "):
        build_on(THREADS, lo, hi, 16)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(boxes=box_sets(), max_leaf=st.integers(1, 6), n_bins=st.integers(2, 20))
def test_random_boxes_parallel(boxes, max_leaf, n_bins):
    # Extreme coordinates (beyond float32, subnormal) through the parallel passes.
    lo, hi = boxes
    one = build_on(1, lo, hi, 2, max_leaf_size=max_leaf, n_bins=n_bins)
    many = build_on(THREADS, lo, hi, 2, max_leaf_size=max_leaf, n_bins=n_bins)
    check_bvh(many, lo, hi, max_leaf)
    for a, b in zip(one, many, strict=True):
        assert np.array_equal(a, b)


# ---------------------------------------------------------------------------
# The collapse into 8-wide nodes (accel/wide.py)
# ---------------------------------------------------------------------------


def _area(box):
    e = np.maximum(box[3:].astype(np.float64) - box[:3], 0.0)
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0]


def least_collapse_area(bvh, width, node_cost):
    """The least summed surface area of the wide nodes, each `node_cost` more, over every way to
    collapse the binary tree, by brute force: every subset of its inner nodes (the root always
    in) that leaves each chosen node at most `width` lanes (the leaves and chosen nodes first met
    below it)."""
    nb_, ni, na, _ = bvh
    inner = [n for n in range(len(na)) if na[n] >= 0]

    def lanes(n, chosen):
        out = []
        for c in (n + 1, int(ni[n, 0])):
            out += [c] if na[c] < 0 or c in chosen else lanes(c, chosen)
        return out

    best = np.inf
    for bits in itertools.product((False, True), repeat=len(inner) - 1):
        chosen = {0} | {n for n, keep in zip(inner[1:], bits, strict=True) if keep}
        if all(len(lanes(n, chosen)) <= width for n in chosen):
            best = min(best, sum(_area(nb_[n]) + node_cost for n in chosen))
    return best


@pytest.mark.parametrize("width", [2, 3, 4, 8])
@pytest.mark.parametrize("node_cost", [None, 0.0, 40.0])
def test_collapse_has_the_least_summed_node_area(width, node_cost, monkeypatch):
    """The optimal collapse against all collapses of small trees: its wide nodes' summed area
    (each node's box: the union of its lanes'), plus NODE_COST / leaves of the root's area per
    node, is the least possible (with the cost raylume uses, none, and a high one), and every
    lane, leaf or node, is used by exactly one parent."""
    from raylume.accel import wide

    if node_cost is not None:
        monkeypatch.setattr(wide, "NODE_COST", node_cost)
    rng = np.random.default_rng(width)
    for trial in range(6):
        n = int(rng.integers(9, 15))
        lo = rng.uniform(-1, 1, size=(n, 3)) * rng.uniform(0.1, 3, size=3)
        bvh = build_bvh(lo, lo + rng.uniform(0.01, 0.3, size=(n, 3)), max_leaf_size=1)
        got = wide.collapse(bvh, width)
        used = got.node_bounds[:, 0, :] <= got.node_bounds[:, 3, :]
        per_node = wide.NODE_COST / (bvh.node_axis < 0).sum() * _area(bvh.node_bounds[0])
        total = per_node * len(got.node_index)
        for m in range(len(got.node_index)):
            lanes = got.node_bounds[m, :6][:, used[m]]  # (6, lanes used)
            box = np.concatenate([lanes[:3].min(axis=1), lanes[3:].max(axis=1)])
            total += _area(box)
        assert total == pytest.approx(least_collapse_area(bvh, width, per_node), rel=1e-6), trial
        assert used.sum(axis=1).max() <= width
        assert used.sum() == (bvh.node_axis < 0).sum() + len(got.node_index) - 1


@pytest.mark.parametrize("kernel", [None, 16])
def test_triangle_bounds_are_numpys(kernel):
    rng = np.random.default_rng(3)
    tri = rng.normal(size=(1000, 9)).astype(np.float32)
    tri[7, 4] = np.nan
    lo, hi = np.empty((1000, 3)), np.empty((1000, 3))
    with (
        patch.object(bvh_module, "_TRI_KERNEL", kernel if kernel is not None else bvh_module._TRI_KERNEL),
        patch.object(bvh_module, "_TOP", 16 if kernel is not None else bvh_module._TOP),  # threads too
    ):
        bvh_module.triangle_bounds(tri, lo, hi)
    corners = tri.reshape(-1, 3, 3)
    np.testing.assert_array_equal(lo, corners.min(axis=1))
    np.testing.assert_array_equal(hi, corners.max(axis=1))
